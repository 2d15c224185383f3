//! `morphoid library add SCAN_ID`: a reviewed scan becomes a reference
//! (the same as the web console's `add-to-library`).

use super::common::{ConfigArgs, ConfigFile};
use anyhow::{Context, Result};
use morphoid_service::http::add_scan_to_library;
use morphoid_service::store::Store;
use std::process::ExitCode;

/// Arguments of `morphoid library add`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
    /// The scan's id (as `morphoid results` shows it).
    scan_id: i64,
    /// The reference's name (default: the scan's file name without its
    /// extension).
    #[arg(long)]
    name: Option<String>,
    #[command(flatten)]
    config: ConfigArgs,
}

/// Run `morphoid library add`.
pub(super) fn run(args: Args, file: ConfigFile) -> Result<ExitCode> {
    let config = args.config.load(file)?;
    let db = &config.database.path;
    let store = Store::open(db).with_context(|| format!("opening {}", db.display()))?;
    let added = add_scan_to_library(
        &store,
        &config.library.dir,
        &config.library.ranks,
        args.scan_id,
        args.name.as_deref(),
    )
    .with_context(|| format!("adding scan {} to the library", args.scan_id))?;
    let labels: Vec<String> = added
        .labels
        .iter()
        .map(|(r, t)| format!("{r}: {t}"))
        .collect();
    println!(
        "scan {} added as reference {} ({}): {}",
        added.scan_id,
        added.reference,
        labels.join(", "),
        added.file.display()
    );
    eprintln!("a running daemon uses it after a reload (systemctl reload morphoid)");
    Ok(ExitCode::SUCCESS)
}
