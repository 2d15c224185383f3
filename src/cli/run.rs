//! `morphoid run`: the daemon (see `morphoid::daemon`).

use super::common::{open_cache, open_library, ConfigArgs};
use anyhow::Result;
use morphoid::classify::Classifier;
use morphoid::config::Config;
use morphoid::daemon::{self, Loader};
use morphoid::library::BuildOutcome;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `morphoid run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArgs,
    /// Export folder to watch (overrides the configuration).
    #[arg(long, value_name = "DIR")]
    watch: Option<PathBuf>,
}

impl Loader for Args {
    fn config(&self) -> Result<Config, String> {
        let mut config = self.config.load().map_err(|e| format!("{e:#}"))?;
        if let Some(dir) = &self.watch {
            config.watch.dir = dir.clone();
        }
        Ok(config)
    }

    fn library(&self, config: &Config) -> Result<(Classifier, BuildOutcome), String> {
        let lib = open_library(config).map_err(|e| format!("{e:#}"))?;
        let cache = open_cache(config).map_err(|e| format!("{e:#}"))?;
        Classifier::build(&lib, &cache, &config.settings(), |_| {})
            .map(|(c, o)| (c.with_results_dir(config.results.dir.clone()), o))
            .map_err(|e| e.to_string())
    }
}

/// Run the daemon until SIGTERM/SIGINT.
pub fn run(args: Args) -> Result<ExitCode> {
    daemon::run(&args)?;
    Ok(ExitCode::SUCCESS)
}
