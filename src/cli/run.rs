//! `morphoid run`: the daemon (see `morphoid_service::daemon`).

use super::common::{ConfigArgs, ConfigFile};
use anyhow::Result;
use morphoid_service::app::ConfigSource;
use morphoid_service::daemon;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `morphoid run`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
    #[command(flatten)]
    config: ConfigArgs,
    /// Export folder to watch (overrides the configuration).
    #[arg(long, value_name = "DIR")]
    watch: Option<PathBuf>,
}

/// Run the daemon until SIGTERM/SIGINT; SIGHUP reloads the configuration
/// file with these overrides, and the library it names.
pub(super) fn run(args: Args, file: ConfigFile) -> Result<ExitCode> {
    let source = ConfigSource {
        watch: args.watch,
        ..args.config.source(file)
    };
    daemon::run(&source)?;
    Ok(ExitCode::SUCCESS)
}
