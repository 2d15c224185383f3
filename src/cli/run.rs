//! `morphoid run`: the daemon (see `morphoid::daemon`).

use super::common::{ConfigArgs, ConfigFile};
use anyhow::Result;
use morphoid::classify::Classifier;
use morphoid::config::Config;
use morphoid::daemon::{self, LoadError, LoadedLibrary, Loader};
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

/// What the daemon reloads on SIGHUP: the configuration file with the
/// command-line overrides, and the library it names.
struct Daemon<'a> {
    args: Args,
    file: ConfigFile<'a>,
}

impl Loader for Daemon<'_> {
    fn config(&self) -> Result<Config, LoadError> {
        let mut config = self
            .args
            .config
            .load(self.file)
            .map_err(|e| LoadError::Config(e.into()))?;
        if let Some(dir) = &self.args.watch {
            config.watch.dir = dir.clone();
        }
        Ok(config)
    }

    fn library(&self, config: &Config) -> Result<LoadedLibrary, LoadError> {
        let failed = |source: anyhow::Error| LoadError::Library {
            dir: config.library.dir.clone(),
            source: source.into(),
        };
        let lib = config.open_library().map_err(|e| failed(e.into()))?;
        let cache = config.open_cache().map_err(|e| failed(e.into()))?;
        let (classifier, outcome, calibration) =
            Classifier::build_deferred(&lib, &cache, config, |_| {})
                .map_err(|e| failed(e.into()))?;
        Ok(LoadedLibrary {
            classifier,
            outcome,
            calibration,
        })
    }
}

/// Run the daemon until SIGTERM/SIGINT.
pub fn run(args: Args, file: ConfigFile) -> Result<ExitCode> {
    daemon::run(&Daemon { args, file })?;
    Ok(ExitCode::SUCCESS)
}
