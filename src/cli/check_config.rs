//! `morphoid check-config`: validate a configuration file and name any
//! wrong key or value.

use super::common::ConfigFile;
use anyhow::{bail, Context, Result};
use morphoid::config::Config;
use std::process::ExitCode;

/// Arguments of `morphoid check-config` (the file is `--config`; without
/// it, the built-in defaults are checked).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Print the effective configuration as TOML.
    #[arg(long)]
    print: bool,
}

/// Check what the types cannot: the trigger regex, the baud rate, the
/// results folder.
fn check_runtime(config: &Config) -> Result<()> {
    if let Some(s) = &config.serial {
        regex::Regex::new(&s.trigger)
            .with_context(|| format!("serial.trigger {:?} is not a valid regex", s.trigger))?;
        if !morphoid::daemon::is_standard_baud(s.baud) {
            bail!("serial.baud {} is not a standard baud rate", s.baud);
        }
    }
    if let Some(dir) = &config.results.dir {
        if dir.exists() && !dir.is_dir() {
            bail!("results.dir {} exists and is not a folder", dir.display());
        }
    }
    for p in &config.watch.ignore {
        if p.is_empty() {
            bail!("watch.ignore contains an empty pattern");
        }
    }
    Ok(())
}

/// Run `morphoid check-config`.
pub fn run(args: Args, file: ConfigFile) -> Result<ExitCode> {
    let config = file.load()?;
    check_runtime(&config)?;
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
