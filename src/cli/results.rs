//! `morphoid results`: what has been identified, newest first.

use super::common::{ConfigArgs, ConfigFile};
use anyhow::Result;
use morphoid_service::store::Store;
use std::process::ExitCode;

/// Arguments of `morphoid results`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
    /// How many scans to show.
    #[arg(long, default_value_t = 20)]
    last: usize,
    /// One JSON object per scan (the form of `classify --json`).
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    config: ConfigArgs,
}

/// Run `morphoid results`.
pub(super) fn run(args: Args, file: ConfigFile) -> Result<ExitCode> {
    let config = args.config.load(file)?;
    let mut store = Store::open(&config.database.path)?;
    for record in store.recent(args.last)? {
        if args.json {
            println!("{}", serde_json::to_string(&record)?);
        } else {
            println!("{}", super::classify::summary(&record));
        }
    }
    Ok(ExitCode::SUCCESS)
}
