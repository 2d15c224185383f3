//! What every command decides the same way, so that the command line only
//! parses, calls and prints: where the configuration comes from, which
//! cache a folder of surfaces uses, and how a library is built (and
//! whether it is calibrated).

use crate::classify::Classifier;
use crate::config::{Config, ConfigError};
use crate::daemon::{LoadError, LoadedLibrary, Loader};
use crate::identify::{self, Calibration};
use morphoid_data::library::{self, BuildOutcome, Cache, CacheError, Library, LibraryError};
use morphoid_data::shard::Shard;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Where a command's configuration comes from: a file (`None`: the
/// built-in defaults) and the command line's overrides.
#[derive(Debug, Clone, Default)]
pub struct ConfigSource {
    /// The configuration file (`--config`).
    pub file: Option<PathBuf>,
    /// Overrides `[library] dir` (`--library`).
    pub library: Option<PathBuf>,
    /// Overrides `[database] path` (`--db`).
    pub db: Option<PathBuf>,
    /// Overrides `[watch] dir` (`morphoid run --watch`).
    pub watch: Option<PathBuf>,
}

impl ConfigSource {
    /// The configuration of the file (or the defaults) with the overrides
    /// applied.
    pub fn load(&self) -> Result<Config, ConfigError> {
        let mut config = match &self.file {
            Some(path) => Config::read(path)?,
            None => Config::default(),
        };
        if let Some(dir) = &self.library {
            config.library.dir = dir.clone();
        }
        if let Some(db) = &self.db {
            config.database.path = db.clone();
        }
        if let Some(dir) = &self.watch {
            config.watch.dir = dir.clone();
        }
        Ok(config)
    }
}

/// The daemon reads the same source again on SIGHUP, and the library it
/// names with its cache.
impl Loader for ConfigSource {
    fn config(&self) -> Result<Config, LoadError> {
        self.load().map_err(|e| LoadError::Config(e.into()))
    }

    fn library(&self, config: &Config) -> Result<LoadedLibrary, LoadError> {
        let failed = |source: Box<dyn std::error::Error + Send + Sync>| LoadError::Library {
            dir: config.library.dir.clone(),
            source,
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

/// Whether a library of `references` prepared references is calibrated:
/// when `[library] calibrate` is on and it has at least
/// [`identify::MIN_HELD`] of them.
pub fn calibrates(config: &Config, references: usize) -> bool {
    config.library.calibrate && identify::calibratable(references)
}

/// How far [`build_library`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Progress {
    /// `done` of `total` references prepared or taken from the cache.
    Preparing {
        /// References done.
        done: usize,
        /// All references.
        total: usize,
    },
    /// `done` of `total` comparisons among the references made or taken
    /// from the cache, for the calibration.
    Calibrating {
        /// Comparisons done.
        done: usize,
        /// All comparisons.
        total: usize,
    },
}

/// A library prepared into its cache, and its calibration.
#[derive(Debug)]
pub struct LibraryBuild {
    /// The library folder as opened.
    pub library: Library,
    /// Its cache.
    pub cache: Cache,
    /// What the preparation did.
    pub outcome: BuildOutcome,
    /// The calibration, when [`calibrates`] says so.
    pub calibration: Option<Calibration>,
}

/// Why a library could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The library folder cannot be used.
    #[error(transparent)]
    Library(#[from] LibraryError),
    /// The cache cannot be used.
    #[error(transparent)]
    Cache(#[from] CacheError),
    /// A calibration shard cannot be written, read or merged.
    #[error(transparent)]
    Shard(#[from] identify::CalibrationShardError),
    /// The configuration does not calibrate this library.
    #[error("{references} references and `[library] calibrate = {calibrate}`: this library is not calibrated (it needs calibrate = true and at least {min} references)")]
    NotCalibrated {
        /// References prepared.
        references: usize,
        /// The configuration's `[library] calibrate`.
        calibrate: bool,
        /// The fewest references a calibration holds out.
        min: usize,
    },
}

/// `morphoid library build --shard K/N`: only the references of part `K`
/// of `N` of the library prepared into its cache, for one task of a
/// cluster job array (see [`library::build_shard`]); no calibration.
pub fn build_library_shard(
    config: &Config,
    shard: Shard,
    progress: impl Fn(Progress) + Sync,
) -> Result<LibraryBuild, BuildError> {
    let lib = config.open_library()?;
    let cache = config.open_cache()?;
    let total = shard.range(lib.members().len()).len();
    let done = AtomicUsize::new(0);
    let outcome = library::build_shard(&lib, &cache, &config.settings(), shard, |_| {
        let done = done.fetch_add(1, Ordering::Relaxed) + 1;
        progress(Progress::Preparing { done, total });
    });
    Ok(LibraryBuild {
        library: lib,
        cache,
        outcome,
        calibration: None,
    })
}

/// `morphoid library calibrate --shard K/N`: the library opened (and any
/// reference not yet prepared, prepared), then part `K` of `N` of its
/// calibration's comparisons made, for one task of a cluster job array.
/// An error when the configuration does not calibrate this library.
pub fn calibration_shard(
    config: &Config,
    shard: Shard,
    progress: impl Fn(Progress) + Sync,
) -> Result<identify::CalibrationShard, BuildError> {
    let (_, cache, outcome) = open_prepared(config, &progress)?;
    let settings = config.settings();
    Ok(identify::calibration_shard(
        outcome.references(),
        &settings,
        Some(&cache),
        shard,
        |done, total| progress(Progress::Calibrating { done, total }),
    ))
}

/// `morphoid library calibrate merge FILE…`: the calibration of the
/// library assembled from the shard files of one job array, stored in its
/// cache exactly as `library build` stores a calibration computed on one
/// machine, and fitted.
pub fn merge_calibration(
    config: &Config,
    files: &[PathBuf],
    progress: impl Fn(Progress) + Sync,
) -> Result<LibraryBuild, BuildError> {
    let shards = files
        .iter()
        .map(|f| Ok((f.clone(), identify::CalibrationShard::read(f)?)))
        .collect::<Result<Vec<_>, identify::CalibrationShardError>>()?;
    let (lib, cache, outcome) = open_prepared(config, &progress)?;
    let distances = identify::merge_calibration_shards(
        outcome.references(),
        &config.settings(),
        &cache,
        &shards,
    )?;
    let calibration = Some(Calibration::fit(distances, lib.labels()));
    Ok(LibraryBuild {
        library: lib,
        cache,
        outcome,
        calibration,
    })
}

/// The configured library, its cache and every reference prepared (or
/// taken from the cache); an error when the configuration does not
/// calibrate it.
fn open_prepared(
    config: &Config,
    progress: &(impl Fn(Progress) + Sync),
) -> Result<(Library, Cache, BuildOutcome), BuildError> {
    let lib = config.open_library()?;
    let cache = config.open_cache()?;
    let total = lib.members().len();
    let done = AtomicUsize::new(0);
    let outcome = library::build(&lib, &cache, &config.settings(), |_| {
        let done = done.fetch_add(1, Ordering::Relaxed) + 1;
        progress(Progress::Preparing { done, total });
    })?;
    let n = outcome.references().len();
    if !calibrates(config, n) {
        return Err(BuildError::NotCalibrated {
            references: n,
            calibrate: config.library.calibrate,
            min: identify::MIN_HELD,
        });
    }
    Ok((lib, cache, outcome))
}

/// `morphoid library build`: every reference of the configured library
/// prepared into its cache (unchanged ones reused, removed ones dropped),
/// then the calibration fitted now, not at the first scan (its distances
/// are cached too), when [`calibrates`] says so.
pub fn build_library(
    config: &Config,
    progress: impl Fn(Progress) + Sync,
) -> Result<LibraryBuild, BuildError> {
    let lib = config.open_library()?;
    let cache = config.open_cache()?;
    let settings = config.settings();
    let total = lib.members().len();
    let done = AtomicUsize::new(0);
    let outcome = library::build(&lib, &cache, &settings, |_| {
        let done = done.fetch_add(1, Ordering::Relaxed) + 1;
        progress(Progress::Preparing { done, total });
    })?;
    let n = outcome.references().len();
    let calibration = calibrates(config, n).then(|| {
        let distances = identify::reference_distances(
            outcome.references(),
            &settings,
            Some(&cache),
            |done, total| progress(Progress::Calibrating { done, total }),
        );
        Calibration::fit(distances, lib.labels())
    });
    Ok(LibraryBuild {
        library: lib,
        cache,
        outcome,
        calibration,
    })
}
