//! `morphoid run`: the daemon (see `morphoid::daemon`).

use super::common::{open_cache, open_library, ConfigArgs};
use anyhow::Result;
use morphoid::classify::Classifier;
use morphoid::config::Config;
use morphoid::daemon::{self, LoadError, Loader};
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
    fn config(&self) -> Result<Config, LoadError> {
        let mut config = self
            .config
            .load()
            .map_err(|e| LoadError::Config(e.into()))?;
        if let Some(dir) = &self.watch {
            config.watch.dir = dir.clone();
        }
        Ok(config)
    }

    fn library(&self, config: &Config) -> Result<(Classifier, BuildOutcome), LoadError> {
        let failed = |source: anyhow::Error| LoadError::Library {
            dir: config.library.dir.clone(),
            source: source.into(),
        };
        let lib = open_library(config).map_err(failed)?;
        let cache = open_cache(config).map_err(failed)?;
        Classifier::build(&lib, &cache, &config.settings(), |_| {}).map_err(|e| failed(e.into()))
    }
}

/// Run the daemon until SIGTERM/SIGINT.
pub fn run(args: Args) -> Result<ExitCode> {
    daemon::run(&args)?;
    Ok(ExitCode::SUCCESS)
}
