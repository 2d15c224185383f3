//! `morphoid check-config`: validate a configuration file and name any
//! wrong key or value.

use super::common::ConfigFile;
use anyhow::Result;
use std::process::ExitCode;

/// Arguments of `morphoid check-config` (the file is `--config`; without
/// it, the built-in defaults are checked).
#[derive(Debug, clap::Args)]
pub(super) struct Args {
    /// Print the effective configuration as TOML.
    #[arg(long)]
    print: bool,
}

/// Run `morphoid check-config`.
pub(super) fn run(args: Args, file: ConfigFile) -> Result<ExitCode> {
    let path = file
        .path()
        .unwrap_or(std::path::Path::new("(built-in defaults)"));
    let config = file.load()?;
    config.check_plausible(path)?;
    println!("ok");
    println!(
        "watch {} (recursive: {}, settle {} s, ignore {:?}{})",
        config.watch.dir.display(),
        config.watch.recursive,
        config.watch.settle_seconds,
        config.watch.ignore,
        config
            .watch
            .quarantine
            .as_ref()
            .map(|q| format!(", quarantine {}", q.display()))
            .unwrap_or_default()
    );
    println!(
        "library {} (ranks {:?}), database {}",
        config.library.dir.display(),
        config.library.ranks,
        config.database.path.display()
    );
    match &config.results.dir {
        Some(dir) => println!("result files in {}", dir.display()),
        None => println!("no result files (database only)"),
    }
    match &config.serial {
        Some(s) => println!(
            "serial {} at {} baud, trigger {:?}",
            s.port, s.baud, s.trigger
        ),
        None => println!("no serial trigger"),
    }
    if args.print {
        println!("{}", toml::to_string_pretty(&config)?);
    }
    Ok(ExitCode::SUCCESS)
}
