//! The cache of prepared references: one file per reference, keyed by the
//! content hash of its surface file and by the preparation settings, so a
//! restart or a new scan never prepares a reference twice, and a changed
//! file or changed settings are prepared again.
//!
//! The user names a cache folder (or gets the default one,
//! the default cache folder); each folder of surfaces has its own subfolder
//! in it ([`Cache::for_folder`]), so that two libraries never evict each
//! other's entries and every command that prepares the same folder (the
//! library build, the daemon, `matrix`) finds the same entries.

use crate::clean::CleanReport;
use crate::cp::Prepared;
use crate::pipeline::Settings;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// Bumped whenever the cached layout or the meaning of `Prepared` changes,
/// so old entries are ignored instead of misread.
const CACHE_FORMAT: u32 = 2;

/// Extension of cache entries.
const EXTENSION: &str = "prep";

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Why the cache cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum CacheError {
    /// The folder or an entry cannot be written or listed.
    #[error("{path}: {source}")]
    Io {
        /// The folder or file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The folder of surfaces the cache belongs to cannot be found.
    #[error("{path}: cannot open the folder of surfaces: {source}")]
    Folder {
        /// The folder of surfaces.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// An entry cannot be encoded.
    #[error("cannot encode the prepared form of `{name}`: {message}")]
    Encode {
        /// The reference.
        name: String,
        /// The encoder's message.
        message: String,
    },
}

/// A prepared reference as kept in the cache.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CachedReference {
    /// Reference name.
    pub name: String,
    /// Content hash of the surface file it was prepared from.
    pub content_hash: String,
    /// The prepared form.
    pub prepared: Prepared,
    /// What cleaning changed.
    pub cleaning: CleanReport,
}

#[derive(Serialize, Deserialize)]
struct Entry {
    format: u32,
    key: String,
    reference: CachedReference,
}

/// A cache folder.
#[derive(Debug, Clone)]
pub struct Cache {
    dir: PathBuf,
}

/// The cache folder when none is configured: systemd's
/// `$CACHE_DIRECTORY`, else `$XDG_CACHE_HOME/morphoid`, else
/// `~/.cache/morphoid`, else `.morphoid-cache` in the working folder.
pub fn default_cache_root() -> PathBuf {
    std::env::var_os("CACHE_DIRECTORY")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("XDG_CACHE_HOME").map(|d| Path::new(&d).join("morphoid")))
        .or_else(|| std::env::var_os("HOME").map(|d| Path::new(&d).join(".cache/morphoid")))
        .unwrap_or_else(|| PathBuf::from(".morphoid-cache"))
}

impl Cache {
    /// The cache of the surfaces in `folder` (a library folder), inside
    /// the cache folder `root` (`None`: the default cache folder): the
    /// subfolder `<folder name>-<hash of its canonical path>`, created
    /// when missing.
    pub fn for_folder(root: Option<&Path>, folder: &Path) -> Result<Self, CacheError> {
        let canonical = std::fs::canonicalize(folder).map_err(|source| CacheError::Folder {
            path: folder.to_path_buf(),
            source,
        })?;
        let digest = Sha256::digest(canonical.to_string_lossy().as_bytes());
        let name = canonical
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "library".into());
        let sub = format!("{name}-{}", hex(&digest[..6]));
        let root = root.map_or_else(default_cache_root, Path::to_path_buf);
        Self::open(&root.join(sub))
    }

    /// Use (and create if needed) exactly the folder `dir`.
    pub fn open(dir: &Path) -> Result<Self, CacheError> {
        std::fs::create_dir_all(dir).map_err(|source| CacheError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
        Ok(Cache {
            dir: dir.to_path_buf(),
        })
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The key of a surface with content hash `content_hash` prepared with
    /// `settings`.
    pub(super) fn key(content_hash: &str, settings: &Settings) -> String {
        let params = serde_json::to_string(settings).unwrap_or_default();
        let mut h = Sha256::new();
        h.update(CACHE_FORMAT.to_le_bytes());
        h.update(content_hash.as_bytes());
        h.update(params.as_bytes());
        hex(&h.finalize()[..16])
    }

    fn path_of(&self, name: &str, key: &str) -> PathBuf {
        self.dir.join(format!("{name}.{key}.{EXTENSION}"))
    }

    /// The cached entry of `name` under `key`, if present and readable. An
    /// unreadable entry counts as absent (it will be prepared again).
    pub(super) fn get(&self, name: &str, key: &str) -> Option<CachedReference> {
        let bytes = std::fs::read(self.path_of(name, key)).ok()?;
        let entry: Entry = match postcard::from_bytes(&bytes) {
            Ok(e) => e,
            Err(e) => {
                tracing::warn!(reference = name, "ignoring an unreadable cache entry: {e}");
                return None;
            }
        };
        if !(entry.format == CACHE_FORMAT && entry.key == key && entry.reference.name == name) {
            return None;
        }
        // A damaged entry can still decode; the engine indexes by what it
        // holds, so check it before use.
        if let Err(e) = entry.reference.prepared.validate() {
            tracing::warn!(
                reference = name,
                "ignoring an inconsistent cache entry: {e}"
            );
            return None;
        }
        Some(entry.reference)
    }

    /// Store an entry under `key`, atomically (write, then rename).
    pub(super) fn put(&self, key: &str, reference: &CachedReference) -> Result<(), CacheError> {
        let entry = Entry {
            format: CACHE_FORMAT,
            key: key.to_string(),
            reference: reference.clone(),
        };
        let bytes = postcard::to_stdvec(&entry).map_err(|e| CacheError::Encode {
            name: reference.name.clone(),
            message: e.to_string(),
        })?;
        let path = self.path_of(&reference.name, key);
        let tmp = path.with_extension("tmp");
        let io = |source| CacheError::Io {
            path: path.clone(),
            source,
        };
        std::fs::write(&tmp, bytes).map_err(io)?;
        std::fs::rename(&tmp, &path).map_err(io)
    }

    /// Delete every entry whose (name, key) is not in `keep`; returns how
    /// many were deleted.
    pub(super) fn retain(&self, keep: &HashSet<(String, String)>) -> Result<usize, CacheError> {
        let io = |source| CacheError::Io {
            path: self.dir.clone(),
            source,
        };
        let wanted: HashSet<PathBuf> = keep.iter().map(|(n, k)| self.path_of(n, k)).collect();
        let mut removed = 0;
        for entry in std::fs::read_dir(&self.dir).map_err(io)? {
            let path = entry.map_err(io)?.path();
            let ours = path
                .extension()
                .is_some_and(|e| e == EXTENSION || e == "tmp");
            if ours && !wanted.contains(&path) {
                std::fs::remove_file(&path).map_err(io)?;
                removed += 1;
            }
        }
        Ok(removed)
    }
}
