//! What several subcommands share: the configuration with command-line
//! overrides, the cache location, progress bars.

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use morphoid::config::Config;
use morphoid::library::{self, Cache};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// `--config`, `--library`, `--db`: the options every library-using command takes.
#[derive(Debug, Clone, clap::Args)]
pub struct ConfigArgs {
    /// Configuration file (TOML; see config/morphoid.toml). Without it, the
    /// built-in defaults.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Reference library folder (overrides the configuration).
    #[arg(long, value_name = "DIR")]
    pub library: Option<PathBuf>,
    /// SQLite database file (overrides the configuration).
    #[arg(long, value_name = "FILE")]
    pub db: Option<PathBuf>,
}

impl ConfigArgs {
    /// The configuration with the command-line overrides applied.
    pub fn load(&self) -> Result<Config> {
        let mut config = match &self.config {
            Some(path) => Config::read(path)?,
            None => Config::default(),
        };
        if let Some(dir) = &self.library {
            config.library.dir = dir.clone();
        }
        if let Some(db) = &self.db {
            config.database.path = db.clone();
        }
        Ok(config)
    }
}

/// The cache folder of the configured library: the configured root (or
/// systemd's `$CACHE_DIRECTORY`, or the user's cache folder), then one
/// subfolder per library so that two libraries never evict each other.
pub fn open_cache(config: &Config) -> Result<Cache> {
    let root = config
        .library
        .cache
        .clone()
        .or_else(|| std::env::var_os("CACHE_DIRECTORY").map(PathBuf::from))
        .or_else(|| std::env::var_os("XDG_CACHE_HOME").map(|d| Path::new(&d).join("morphoid")))
        .or_else(|| std::env::var_os("HOME").map(|d| Path::new(&d).join(".cache/morphoid")))
        .unwrap_or_else(|| PathBuf::from(".morphoid-cache"));
    let lib = &config.library.dir;
    let canonical = std::fs::canonicalize(lib)
        .with_context(|| format!("{}: cannot open the library folder", lib.display()))?;
    let digest = Sha256::digest(canonical.to_string_lossy().as_bytes());
    let tag: String = digest[..6].iter().map(|b| format!("{b:02x}")).collect();
    let name = canonical
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "library".into());
    Ok(Cache::open(&root.join(format!("{name}-{tag}")))?)
}

/// Open the configured library with its rank columns.
pub fn open_library(config: &Config) -> Result<library::Library> {
    Ok(library::Library::open(&config.library.dir, config.ranks())?)
}

/// A progress bar on stderr; indicatif draws nothing when stderr is not a
/// terminal, so logs and CI output stay clean.
pub fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len} ({eta} left)")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(what.to_string());
    bar
}
