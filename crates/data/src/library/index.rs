//! The library's index, one file in its cache folder: for each reference,
//! the stamp of its surface file when it was last read, its content hash
//! and cache key, what cleaning changed and its screening signature. A
//! library of thousands opens from this file and a `stat` of each surface
//! file, without reading the surfaces or their prepared forms.
//!
//! A stamp is the file's device, inode, size, modification and change
//! times. The change time cannot be set back by any user tool, and every
//! write moves it, so an unchanged stamp means unchanged bytes (as in
//! git's index). A stamp is recorded only when the file had not changed
//! for [`SETTLED`] before it was read and did not change while it was
//! read; any other file is hashed again at the next opening. The index
//! only saves time: a missing, damaged or foreign index is rebuilt from
//! the files.

use super::cache::{Cache, CacheError, CachedReference};
use crate::atomic_write::write_atomic;
use crate::pipeline::Settings;
use morphoid_core::clean::CleanReport;
use morphoid_core::cp::Signature;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::fs::Metadata;
use std::path::Path;
use std::time::Duration;

/// The index file, in the library's cache folder.
const INDEX: &str = "references.index";

/// Bumped when the index's layout or meaning changes.
const INDEX_FORMAT: u32 = 1;

/// How long a file must have been unchanged before it is read for its
/// stamp to be trusted: longer than the file system's time-stamp
/// granularity, so that a write in the same tick as the reading is never
/// mistaken for no write.
const SETTLED: Duration = Duration::from_secs(2);

/// The identity of a file's bytes without reading them (see the module
/// docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub(super) struct Stamp {
    device: u64,
    inode: u64,
    size: u64,
    modified_ns: i128,
    changed_ns: i128,
}

impl Stamp {
    /// The stamp of the file `metadata` describes, when its change time
    /// is at least [`SETTLED`] ago (`None` otherwise, and off Unix).
    pub(super) fn settled(metadata: &Metadata) -> Option<Stamp> {
        let stamp = Stamp::of(metadata)?;
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .ok()?
            .as_nanos() as i128;
        (now - stamp.changed_ns >= SETTLED.as_nanos() as i128).then_some(stamp)
    }

    #[cfg(unix)]
    fn of(metadata: &Metadata) -> Option<Stamp> {
        use std::os::unix::fs::MetadataExt;
        let ns = |s: i64, n: i64| i128::from(s) * 1_000_000_000 + i128::from(n);
        Some(Stamp {
            device: metadata.dev(),
            inode: metadata.ino(),
            size: metadata.size(),
            modified_ns: ns(metadata.mtime(), metadata.mtime_nsec()),
            changed_ns: ns(metadata.ctime(), metadata.ctime_nsec()),
        })
    }

    #[cfg(not(unix))]
    fn of(_: &Metadata) -> Option<Stamp> {
        None
    }

    /// The stamp of the file at `path` now, if it can be read.
    pub(super) fn now(path: &Path) -> Option<Stamp> {
        Stamp::of(&std::fs::metadata(path).ok()?)
    }
}

/// What the index knows of one reference.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct IndexEntry {
    name: String,
    stamp: Stamp,
    content_hash: String,
    key: String,
    cleaning: CleanReport,
    signature: Signature,
}

impl IndexEntry {
    /// The entry of `reference`, prepared from a file with `stamp` and
    /// stored in the cache under `key`.
    pub(super) fn of(reference: &CachedReference, stamp: Stamp, key: &str) -> Self {
        IndexEntry {
            name: reference.name().to_string(),
            stamp,
            content_hash: reference.content_hash().to_string(),
            key: key.to_string(),
            cleaning: reference.cleaning().clone(),
            signature: reference.signature().clone(),
        }
    }
}

#[derive(Serialize, Deserialize)]
struct IndexFile {
    format: u32,
    entries: Vec<IndexEntry>,
}

/// A library's index as read (empty when there is none).
#[derive(Debug, Default)]
pub(super) struct Index {
    by_name: HashMap<String, IndexEntry>,
}

impl Index {
    /// The index in `cache`; empty when it is missing, unreadable or of
    /// another format (then it is rebuilt).
    pub(super) fn read(cache: &Cache) -> Index {
        let path = cache.dir().join(INDEX);
        let Ok(bytes) = std::fs::read(&path) else {
            return Index::default();
        };
        match postcard::from_bytes::<IndexFile>(&bytes) {
            Ok(file) if file.format == INDEX_FORMAT => Index {
                by_name: file
                    .entries
                    .into_iter()
                    .map(|e| (e.name.clone(), e))
                    .collect(),
            },
            Ok(_) => Index::default(),
            Err(e) => {
                tracing::warn!("{}: ignoring the library index: {e}", path.display());
                Index::default()
            }
        }
    }

    /// The reference `name`, when the index knows its file under `stamp`,
    /// its entry is keyed for `settings` and that entry is in `cache`:
    /// held there, nothing read. `None` when the file must be read.
    pub(super) fn lookup(
        &self,
        name: &str,
        stamp: Stamp,
        cache: &Cache,
        settings: &Settings,
    ) -> Option<(CachedReference, IndexEntry)> {
        let e = self.by_name.get(name)?;
        let fits = e.stamp == stamp
            && e.key == Cache::key(&e.content_hash, settings)
            && cache.has(name, &e.key);
        fits.then(|| {
            let reference = CachedReference::indexed(
                cache,
                &e.key,
                e.name.clone(),
                e.content_hash.clone(),
                e.cleaning.clone(),
                e.signature.clone(),
            );
            (reference, e.clone())
        })
    }

    /// Whether the index holds exactly `entries` (by name, stamp and key):
    /// then it need not be written again.
    pub(super) fn holds(&self, entries: &[IndexEntry]) -> bool {
        entries.len() == self.by_name.len()
            && entries.iter().all(|e| {
                self.by_name
                    .get(&e.name)
                    .is_some_and(|o| o.stamp == e.stamp && o.key == e.key)
            })
    }

    /// Write `entries` as `cache`'s index, atomically (two processes may
    /// write it at once; either result is a true index).
    pub(super) fn write(cache: &Cache, entries: Vec<IndexEntry>) -> Result<(), CacheError> {
        let file = IndexFile {
            format: INDEX_FORMAT,
            entries,
        };
        let bytes = postcard::to_stdvec(&file).map_err(|e| CacheError::Encode {
            name: INDEX.into(),
            message: e.to_string(),
        })?;
        Ok(write_atomic(&cache.dir().join(INDEX), &bytes)?)
    }
}
