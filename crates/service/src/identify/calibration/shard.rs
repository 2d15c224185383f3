//! The calibration of a large library as a cluster job array: task `K` of
//! `N` computes part `K` of the calibration's pair list (the pairs of
//! [`reference_distances`](super::reference_distances), in their order)
//! into a shard file; [`merge_calibration_shards`] checks that the `N`
//! files belong to this library and settings, each once, and stores
//! exactly the distances one machine would have stored.
//!
//! A shard file is binary (postcard): a format number, the key of the
//! references (names and content) and settings, `K` and `N`, and the
//! distances of its pairs. Written whole or not at all.

use super::cached::{self, CalibrationPlan};
use super::ReferenceDistances;
use morphoid_data::atomic_write::{write_atomic, AtomicWriteError};
use morphoid_data::library::{Cache, CachedReference};
use morphoid_data::pipeline::Settings;
use morphoid_data::shard::Shard;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Bumped when the shard file's layout or meaning changes.
const SHARD_FORMAT: u32 = 1;

/// The first bytes of every shard file, so that any other file is told
/// apart before it is decoded.
const MAGIC: &str = "morphoid calibration shard";

/// Why a calibration shard cannot be written, read or merged; each
/// message names the file.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationShardError {
    /// The file cannot be written.
    #[error(transparent)]
    Write(#[from] AtomicWriteError),
    /// The file cannot be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The distances cannot be encoded.
    #[error("the calibration distances cannot be encoded: {0}")]
    Encode(#[source] postcard::Error),
    /// The file is not a calibration shard of this morphoid.
    #[error("{0}: not a calibration shard of this version of morphoid (`morphoid library calibrate --shard K/N` writes them)")]
    Foreign(PathBuf),
    /// The shard is of other references or settings.
    #[error("{0}: a shard of another library, other reference files or other settings: compute it again")]
    OtherLibrary(PathBuf),
    /// The shard is one of another number of shards.
    #[error("{path}: shard {shard}, but the others are of {count} shards")]
    OtherCount {
        /// The file.
        path: PathBuf,
        /// Its shard.
        shard: Shard,
        /// The number of shards of the first file.
        count: usize,
    },
    /// Two files hold the same shard.
    #[error("{first} and {second}: both hold shard {shard}")]
    Twice {
        /// The shard.
        shard: Shard,
        /// One file.
        first: PathBuf,
        /// The other.
        second: PathBuf,
    },
    /// A shard is missing.
    #[error("shard {0} is missing")]
    Missing(Shard),
    /// The shard holds another number of distances than its part.
    #[error("{path}: {found} distances where shard {shard} has {expected} pairs")]
    Length {
        /// The file.
        path: PathBuf,
        /// Its shard.
        shard: Shard,
        /// Pairs of the shard's part.
        expected: usize,
        /// Distances in the file.
        found: usize,
    },
    /// No shard files were given.
    #[error("no calibration shard files given")]
    Empty,
}

/// Part `K` of `N` of a library's calibration distances.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationShard {
    magic: String,
    format: u32,
    /// The key of the references and settings (as the calibration file's).
    key: String,
    index: usize,
    count: usize,
    /// The distance of each pair of the part, in the pair list's order.
    distances: Vec<f64>,
}

impl CalibrationShard {
    /// Which shard this is.
    pub fn shard(&self) -> Shard {
        Shard {
            index: self.index,
            count: self.count,
        }
    }

    /// How many pairs it holds.
    pub fn pairs(&self) -> usize {
        self.distances.len()
    }

    /// Write it to `path`, whole or not at all.
    pub fn write(&self, path: &Path) -> Result<(), CalibrationShardError> {
        let bytes = postcard::to_stdvec(self).map_err(CalibrationShardError::Encode)?;
        Ok(write_atomic(path, &bytes)?)
    }

    /// Read the shard at `path`.
    pub fn read(path: &Path) -> Result<Self, CalibrationShardError> {
        let bytes = std::fs::read(path).map_err(|source| CalibrationShardError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        match postcard::from_bytes::<CalibrationShard>(&bytes) {
            Ok(s) if s.magic == MAGIC && s.format == SHARD_FORMAT => Ok(s),
            _ => Err(CalibrationShardError::Foreign(path.to_path_buf())),
        }
    }
}

/// Shard `shard` of the calibration of `references` (prepared and
/// compared with `settings`): the distances of its part of the pair list,
/// those an earlier calibration file in `cache` holds taken from it;
/// `progress` gets the pairs done and to compute.
pub fn calibration_shard(
    references: &[CachedReference],
    settings: &Settings,
    cache: Option<&Cache>,
    shard: Shard,
    progress: impl Fn(usize, usize) + Sync,
) -> CalibrationShard {
    let plan = CalibrationPlan::of(references, settings);
    let part = &plan.pairs[shard.range(plan.pairs.len())];
    let known = cache.map_or_else(Default::default, |c| cached::known_distances(c, settings));
    let distances = cached::pair_distances(references, part, settings, &known, None, &progress);
    CalibrationShard {
        magic: MAGIC.into(),
        format: SHARD_FORMAT,
        key: cached::key(references, settings),
        index: shard.index,
        count: shard.count,
        distances,
    }
}

/// The calibration distances of `references` from all the shards of one
/// job array (any order), checked to be this library's under `settings`,
/// each shard once; stored in `cache` as
/// [`reference_distances`](super::reference_distances) stores them, so
/// that the library's next build or daemon start finds them.
pub(crate) fn merge_calibration_shards(
    references: &[CachedReference],
    settings: &Settings,
    cache: &Cache,
    shards: &[(PathBuf, CalibrationShard)],
) -> Result<ReferenceDistances, CalibrationShardError> {
    let key = cached::key(references, settings);
    let (_, first) = shards.first().ok_or(CalibrationShardError::Empty)?;
    let count = first.count;
    let mut by_index: Vec<Option<&(PathBuf, CalibrationShard)>> = vec![None; count];
    for entry in shards {
        let (path, s) = entry;
        if s.key != key {
            return Err(CalibrationShardError::OtherLibrary(path.clone()));
        }
        if s.count != count || s.index == 0 || s.index > count {
            return Err(CalibrationShardError::OtherCount {
                path: path.clone(),
                shard: s.shard(),
                count,
            });
        }
        if let Some((other, _)) = by_index[s.index - 1] {
            return Err(CalibrationShardError::Twice {
                shard: s.shard(),
                first: other.clone(),
                second: path.clone(),
            });
        }
        by_index[s.index - 1] = Some(entry);
    }
    let plan = CalibrationPlan::of(references, settings);
    let mut values = Vec::with_capacity(plan.pairs.len());
    for (k, entry) in by_index.iter().enumerate() {
        let shard = Shard {
            index: k + 1,
            count,
        };
        let (path, s) = entry.ok_or(CalibrationShardError::Missing(shard))?;
        let expected = shard.range(plan.pairs.len()).len();
        if s.distances.len() != expected {
            return Err(CalibrationShardError::Length {
                path: path.clone(),
                shard,
                expected,
                found: s.distances.len(),
            });
        }
        values.extend_from_slice(&s.distances);
    }
    let distances = cached::distance_table(references, plan, &values);
    cached::store(cache, references, settings, &distances)?;
    Ok(distances)
}
