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

use crate::atomic_write::{write_atomic, AtomicWriteError};
use crate::hash::hex;
use crate::pipeline::Settings;
use morphoid_core::clean::CleanReport;
use morphoid_core::cp::{shape_signature, Prepared, Signature};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Bumped whenever the cached layout or the meaning of `Prepared` changes,
/// so old entries are ignored instead of misread, and whenever cleaning
/// or preparation makes something else of some file under the same
/// settings, so no reference keeps what the old code made of it (3: a
/// nearly closed surface is told by its holes' extent, not their length;
/// 4: the margin of a whole tooth follows its neck's outline).
const CACHE_FORMAT: u32 = 4;

/// Extension of cache entries.
const EXTENSION: &str = "prep";

/// The file that marks a folder as one library's cache (it holds the
/// library's path, for people): given that folder instead of the cache
/// folder above it, [`Cache::for_folder`] uses it as it is.
const MARKER: &str = "LIBRARY";

/// A temporary file older than this was left by a process that died
/// while writing it; younger ones may be another process's write.
const STALE_TEMPORARY: std::time::Duration = std::time::Duration::from_secs(600);

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
    /// An entry cannot be written.
    #[error(transparent)]
    Write(#[from] AtomicWriteError),
    /// The folder of surfaces the cache belongs to cannot be found.
    #[error("{path}: cannot open the folder of surfaces: {source}")]
    Folder {
        /// The folder of surfaces.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// An entry cannot be read back.
    #[error("{path}: the prepared form of `{name}` cannot be read from the cache: {problem}")]
    Entry {
        /// The entry.
        path: PathBuf,
        /// The reference.
        name: String,
        /// What is wrong with it.
        #[source]
        problem: EntryProblem,
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

/// A prepared reference: its identity, what cleaning changed, its
/// screening signature, and its prepared form, held in memory or left in
/// its cache entry and read back each time it is compared (see
/// [`CachedReference::prepared`]). Cloning it never copies a prepared form.
#[derive(Debug, Clone)]
pub struct CachedReference {
    /// Reference name.
    name: String,
    /// Content hash of the surface file it was prepared from.
    content_hash: String,
    /// What cleaning changed.
    cleaning: CleanReport,
    /// Its screening signature (computed once, when it was prepared or
    /// first read from the cache).
    signature: Signature,
    /// The prepared form.
    held: Held,
}

/// Where a reference's prepared form is.
#[derive(Debug, Clone)]
enum Held {
    /// In memory.
    Resident(Arc<Prepared>),
    /// In the cache entry at `entry`, stored under `key`: a library of
    /// thousands is held at the size of its names and signatures.
    Stored { entry: PathBuf, key: String },
}

impl CachedReference {
    /// The reference `name`, prepared from the surface file with content
    /// hash `content_hash`, held in memory.
    pub fn new(
        name: String,
        content_hash: String,
        prepared: Prepared,
        cleaning: CleanReport,
    ) -> Self {
        Self {
            signature: shape_signature(&prepared),
            name,
            content_hash,
            cleaning,
            held: Held::Resident(Arc::new(prepared)),
        }
    }

    /// Reference name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Content hash of the surface file it was prepared from.
    pub fn content_hash(&self) -> &str {
        &self.content_hash
    }

    /// The prepared form: shared when held in memory, else read from its
    /// cache entry now (about a millisecond; the entry is checked as
    /// [`Cache`] checks every entry). An error when the entry is gone or
    /// damaged since the library was opened.
    pub fn prepared(&self) -> Result<Arc<Prepared>, CacheError> {
        match &self.held {
            Held::Resident(p) => Ok(Arc::clone(p)),
            Held::Stored { entry, key } => {
                read_entry(entry, &self.name, key).map(|stored| Arc::new(stored.prepared))
            }
        }
    }

    /// Whether the prepared form is held in memory (not read from the
    /// cache at each use).
    pub fn is_resident(&self) -> bool {
        matches!(self.held, Held::Resident(_))
    }

    /// The screening signature of the prepared form.
    pub fn signature(&self) -> &Signature {
        &self.signature
    }

    /// What cleaning changed.
    pub fn cleaning(&self) -> &CleanReport {
        &self.cleaning
    }

    /// The same reference, its prepared form left in `cache`'s entry under
    /// `key` (which must hold it: stored by [`Cache::put`] or read from
    /// there).
    pub(super) fn stored_in(self, cache: &Cache, key: &str) -> Self {
        Self {
            held: Held::Stored {
                entry: cache.path_of(&self.name, key),
                key: key.to_string(),
            },
            ..self
        }
    }

    /// A reference whose prepared form is in `cache` under `key`, known
    /// from the library's index (nothing is read).
    pub(super) fn indexed(
        cache: &Cache,
        key: &str,
        name: String,
        content_hash: String,
        cleaning: CleanReport,
        signature: Signature,
    ) -> Self {
        Self {
            held: Held::Stored {
                entry: cache.path_of(&name, key),
                key: key.to_string(),
            },
            name,
            content_hash,
            cleaning,
            signature,
        }
    }
}

/// A cache entry as written. Its layout (field order) is [`Entry`]'s.
#[derive(Serialize)]
struct EntryOut<'a> {
    format: u32,
    key: &'a str,
    reference: StoredOut<'a>,
}

#[derive(Serialize)]
struct StoredOut<'a> {
    name: &'a str,
    content_hash: &'a str,
    prepared: &'a Prepared,
    cleaning: &'a CleanReport,
}

/// A cache entry as read.
#[derive(Deserialize)]
struct Entry {
    format: u32,
    key: String,
    reference: Stored,
}

#[derive(Deserialize)]
struct Stored {
    name: String,
    content_hash: String,
    prepared: Prepared,
    cleaning: CleanReport,
}

/// Why a cache entry cannot be read back.
#[derive(Debug, thiserror::Error)]
pub enum EntryProblem {
    /// The file cannot be read (removed since the library was opened?).
    #[error(transparent)]
    Read(#[from] std::io::Error),
    /// The bytes do not decode.
    #[error("it does not decode: {0}")]
    Decode(#[from] postcard::Error),
    /// It holds another reference, format or preparation.
    #[error("it holds another reference, format or preparation")]
    Other,
    /// It decodes but its arrays do not fit together.
    #[error(transparent)]
    Inconsistent(#[from] morphoid_core::cp::CpError),
}

/// The entry at `path`, checked to be `name`'s under `key` in this
/// format and to hold a consistent prepared form.
fn read_entry(path: &Path, name: &str, key: &str) -> Result<Stored, CacheError> {
    let fail = |problem: EntryProblem| CacheError::Entry {
        path: path.to_path_buf(),
        name: name.to_string(),
        problem,
    };
    let bytes = std::fs::read(path).map_err(|e| fail(e.into()))?;
    let entry: Entry = postcard::from_bytes(&bytes).map_err(|e| fail(e.into()))?;
    if !(entry.format == CACHE_FORMAT && entry.key == key && entry.reference.name == name) {
        return Err(fail(EntryProblem::Other));
    }
    // A damaged entry can still decode; the engine indexes by what it
    // holds, so check it before use.
    entry
        .reference
        .prepared
        .validate()
        .map_err(|e| fail(e.into()))?;
    Ok(entry.reference)
}

/// A cache folder.
#[derive(Debug, Clone)]
pub struct Cache {
    dir: PathBuf,
}

/// The cache folder when none is configured: systemd's
/// `$CACHE_DIRECTORY`, else `$XDG_CACHE_HOME/morphoid`, else
/// `~/.cache/morphoid`, else `.morphoid-cache` in the working folder.
fn default_cache_root() -> PathBuf {
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
    /// when missing. A `root` that is itself a library's cache (the folder
    /// [`Cache::dir`] names, as commands print it) is used as it is, so
    /// either folder finds the entries, also where the library's path
    /// differs (a cluster node that mounts it elsewhere).
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
        if is_library_cache(&root) {
            return Self::open(&root);
        }
        let cache = Self::open(&root.join(sub))?;
        let marker = cache.dir.join(MARKER);
        if !marker.exists() {
            let text = format!(
                "prepared surfaces of {}\n(morphoid cache; safe to delete)\n",
                canonical.display()
            );
            write_atomic(&marker, text.as_bytes())?;
        }
        Ok(cache)
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
    /// `settings`: only what preparation reads (cleaning and the cP
    /// preparation parameters), so changing a comparison setting keeps
    /// every entry.
    pub(super) fn key(content_hash: &str, settings: &Settings) -> String {
        let params =
            serde_json::to_string(&(&settings.clean, &settings.cp.prepare)).unwrap_or_default();
        let mut h = Sha256::new();
        h.update(CACHE_FORMAT.to_le_bytes());
        h.update(content_hash.as_bytes());
        h.update(params.as_bytes());
        hex(&h.finalize()[..16])
    }

    pub(super) fn path_of(&self, name: &str, key: &str) -> PathBuf {
        self.dir.join(format!("{name}.{key}.{EXTENSION}"))
    }

    /// The cached entry of `name` under `key`, if present and readable,
    /// held in memory. An unreadable entry counts as absent (it will be
    /// prepared again).
    pub(super) fn get(&self, name: &str, key: &str) -> Option<CachedReference> {
        let path = self.path_of(name, key);
        if !path.exists() {
            return None;
        }
        match read_entry(&path, name, key) {
            Ok(stored) => Some(CachedReference::new(
                stored.name,
                stored.content_hash,
                stored.prepared,
                stored.cleaning,
            )),
            Err(e) => {
                tracing::warn!(reference = name, "ignoring a cache entry: {e}");
                None
            }
        }
    }

    /// Whether an entry of `name` under `key` is there (not read).
    pub(super) fn has(&self, name: &str, key: &str) -> bool {
        self.path_of(name, key).is_file()
    }

    /// Store an entry under `key`, atomically: processes sharing the cache
    /// may write the same entry at once.
    pub(super) fn put(&self, key: &str, reference: &CachedReference) -> Result<(), CacheError> {
        let prepared = reference.prepared()?;
        let entry = EntryOut {
            format: CACHE_FORMAT,
            key,
            reference: StoredOut {
                name: &reference.name,
                content_hash: &reference.content_hash,
                prepared: &prepared,
                cleaning: &reference.cleaning,
            },
        };
        let bytes = postcard::to_stdvec(&entry).map_err(|e| CacheError::Encode {
            name: reference.name.clone(),
            message: e.to_string(),
        })?;
        Ok(write_atomic(&self.path_of(&reference.name, key), &bytes)?)
    }

    /// Delete every entry whose (name, key) is not in `keep`, and the
    /// temporary files of writes that died; returns how many were deleted.
    pub(super) fn retain(&self, keep: &HashSet<(String, String)>) -> Result<usize, CacheError> {
        let io = |source| CacheError::Io {
            path: self.dir.clone(),
            source,
        };
        let wanted: HashSet<PathBuf> = keep.iter().map(|(n, k)| self.path_of(n, k)).collect();
        let mut removed = 0;
        for entry in std::fs::read_dir(&self.dir).map_err(io)? {
            let path = entry.map_err(io)?.path();
            let stale = match path.extension() {
                Some(e) if e == EXTENSION => !wanted.contains(&path),
                Some(e) if e == "tmp" => is_older_than(&path, STALE_TEMPORARY),
                _ => false,
            };
            if stale {
                std::fs::remove_file(&path).map_err(io)?;
                removed += 1;
            }
        }
        Ok(removed)
    }
}

/// Whether `dir` is one library's cache rather than the cache folder
/// above: it has the marker, or (a cache from before the marker) entries.
fn is_library_cache(dir: &Path) -> bool {
    if dir.join(MARKER).is_file() {
        return true;
    }
    std::fs::read_dir(dir).is_ok_and(|entries| {
        entries
            .flatten()
            .any(|e| e.path().extension().is_some_and(|x| x == EXTENSION))
    })
}

/// Whether the file at `path` was last modified more than `age` ago.
fn is_older_than(path: &Path, age: std::time::Duration) -> bool {
    std::fs::metadata(path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.elapsed().ok())
        .is_some_and(|elapsed| elapsed > age)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::library::{build, Library};
    use morphoid_synth::mesh::{self as synth, write_synthetic_library, LibrarySpec};

    #[test]
    fn concurrent_puts_of_one_entry_leave_it_readable_and_no_temporary_file() {
        let mut settings = Settings::default();
        settings.clean.target_vertices = 800;
        let mesh = synth::crown(&synth::CROWN_GENERA[0], 1, 800);
        let surface = crate::pipeline::prepare_mesh(&mesh, "r", &settings).unwrap();
        let reference = CachedReference::new(
            "r".into(),
            crate::hash::content_hash(b"r"),
            surface.prepared,
            surface.cleaning,
        );
        let dir = tempfile::tempdir().unwrap();
        let key = Cache::key(&reference.content_hash, &settings);
        std::thread::scope(|s| {
            for _ in 0..8 {
                // One `Cache` per thread, as two processes would have.
                let cache = Cache::open(dir.path()).unwrap();
                let (key, reference) = (&key, &reference);
                s.spawn(move || {
                    for _ in 0..4 {
                        cache.put(key, reference).unwrap();
                    }
                });
            }
        });
        let cache = Cache::open(dir.path()).unwrap();
        let hit = cache.get("r", &key).expect("a whole entry");
        assert_eq!(hit.content_hash, reference.content_hash);
        let names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, [format!("r.{key}.{EXTENSION}")]);
    }

    #[test]
    fn the_library_cache_folder_is_found_from_itself_or_the_folder_above() {
        let dir = tempfile::tempdir().unwrap();
        let spec = LibrarySpec {
            per_genus: 1,
            target_vertices: 600,
            ..LibrarySpec::default()
        };
        write_synthetic_library(&dir.path().join("lib"), &spec).unwrap();
        let library = Library::open(&dir.path().join("lib"), None).unwrap();
        let n = library.members.len();
        let root = dir.path().join("cache");
        let settings = Settings::default();
        let cache = Cache::for_folder(Some(&root), library.dir()).unwrap();
        assert_eq!(cache.dir().parent(), Some(root.as_path()));
        assert!(cache.dir().join(MARKER).is_file());
        build(&library, &cache, &settings, |_| {}).unwrap();
        // The folder a command prints, given back: no nested subfolder.
        let same = Cache::for_folder(Some(cache.dir()), library.dir()).unwrap();
        assert_eq!(same.dir(), cache.dir());
        // The library under another path (a node that mounts it
        // elsewhere): the printed folder still finds every entry.
        std::fs::rename(dir.path().join("lib"), dir.path().join("moved")).unwrap();
        let moved = Library::open(&dir.path().join("moved"), None).unwrap();
        let found = Cache::for_folder(Some(cache.dir()), moved.dir()).unwrap();
        let again = build(&moved, &found, &settings, |_| {}).unwrap();
        assert_eq!((again.prepared, again.reused), (0, n));
        // A cache from before the marker is recognised by its entries.
        std::fs::remove_file(cache.dir().join(MARKER)).unwrap();
        let old = Cache::for_folder(Some(cache.dir()), moved.dir()).unwrap();
        assert_eq!(old.dir(), cache.dir());
    }

    #[test]
    fn only_preparation_settings_key_the_cache() {
        let dir = tempfile::tempdir().unwrap();
        let spec = LibrarySpec {
            per_genus: 1,
            target_vertices: 1200,
            ..LibrarySpec::default()
        };
        write_synthetic_library(&dir.path().join("lib"), &spec).unwrap();
        let library = Library::open(&dir.path().join("lib"), None).unwrap();
        let cache = Cache::open(&dir.path().join("cache")).unwrap();
        let n = library.members.len();
        let mut settings = Settings::default();
        let first = build(&library, &cache, &settings, |_| {}).unwrap();
        assert!(first.failures.is_empty(), "{:?}", first.failures);
        assert_eq!((first.prepared, first.reused), (n, 0));
        // Comparison settings: every entry is still a hit.
        settings.cp.compare.descent_steps += 3;
        settings.cp.compare.angles += 1;
        settings.cp.compare.reflections = false;
        let second = build(&library, &cache, &settings, |_| {}).unwrap();
        assert_eq!((second.prepared, second.reused, second.removed), (0, n, 0));
        // A preparation setting: every surface is prepared again, and the
        // old entries go.
        settings.cp.prepare.samples += 10;
        let third = build(&library, &cache, &settings, |_| {}).unwrap();
        assert_eq!((third.prepared, third.reused, third.removed), (n, 0, n));
    }
}
