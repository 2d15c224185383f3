//! What several subcommands share: the configuration with command-line
//! overrides, progress bars.

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use morphoid_service::app::ConfigSource;
use morphoid_service::config::Config;
use std::path::{Path, PathBuf};

/// The configuration file every command reads (`--config`): without one,
/// the built-in defaults.
#[derive(Debug, Clone, Copy)]
pub(super) struct ConfigFile<'a>(pub Option<&'a Path>);

impl ConfigFile<'_> {
    /// The file, or `None` for the built-in defaults.
    pub(super) fn path(&self) -> Option<&Path> {
        self.0
    }

    /// The configuration: the file's, or the defaults.
    pub(super) fn load(self) -> Result<Config> {
        Ok(self.source().load()?)
    }

    /// The file as a configuration source without overrides.
    pub(super) fn source(self) -> ConfigSource {
        ConfigSource {
            file: self.0.map(Path::to_path_buf),
            ..ConfigSource::default()
        }
    }
}

/// `--library`, `--db`: overrides of the configuration that every
/// library-using command takes.
#[derive(Debug, Clone, clap::Args)]
pub(super) struct ConfigArgs {
    /// Reference library folder (overrides the configuration).
    #[arg(long, value_name = "DIR")]
    pub library: Option<PathBuf>,
    /// SQLite database file (overrides the configuration).
    #[arg(long, value_name = "FILE")]
    pub db: Option<PathBuf>,
}

impl ConfigArgs {
    /// The configuration of `file` with the command-line overrides applied.
    pub(super) fn load(&self, file: ConfigFile) -> Result<Config> {
        Ok(self.source(file).load()?)
    }

    /// `file` with these overrides, as the service takes it.
    pub(super) fn source(&self, file: ConfigFile) -> ConfigSource {
        ConfigSource {
            library: self.library.clone(),
            db: self.db.clone(),
            ..file.source()
        }
    }
}

/// Write an output file whole or not at all (a run stopped midway leaves
/// no half file), naming it in the error.
pub(super) fn write_output(path: &Path, bytes: impl AsRef<[u8]>) -> Result<()> {
    morphoid_data::atomic_write::write_atomic(path, bytes.as_ref())
        .with_context(|| format!("writing {}", path.display()))
}

/// A progress bar on stderr; indicatif draws nothing when stderr is not a
/// terminal, so logs and CI output stay clean.
pub(super) fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len} ({eta} left)")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(what.to_string());
    bar
}
