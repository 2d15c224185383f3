//! A reference library: a folder with `labels.csv` and one surface per
//! specimen (`<name>.{ply,obj,stl,off}`), optionally landmarks in
//! `landmarks/<name>.{csv,fcsv,mrk.json,pp}` (one file per specimen, any
//! supported format; see [`crate::landmarks::load_library`]).
//!
//! [`Library::open`] checks that labels and surfaces match one to one;
//! [`members`] lists any folder of surfaces; [`Preparation`] takes their
//! prepared forms from the [`Cache`] or prepares them; [`build`] prepares
//! a whole library; [`identify`] turns the distances of a scan to the
//! references into the nearest taxon at each rank, and [`Calibration`]
//! (learnt from the library's own leave-one-out) into a probability and a
//! "no close match" flag.

mod add;
mod cache;
mod index;

pub use add::{add_reference, reference_name_for, AddError, NewReference};
pub use cache::{Cache, CacheError, CachedReference, EntryProblem};

use crate::hash::content_hash;
use crate::landmarks::{Landmarks, LibraryLandmarks};
use crate::mesh_io::{self, Format, LoadError};
use crate::pipeline::{self, MeshError, Settings};
use crate::table::{Labels, TableError};
use index::{Index, IndexEntry, Stamp};
use morphoid_core::cp::Prepared;
use rayon::prelude::*;
use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// Why a library folder cannot be used; each message names the folder or file.
#[derive(Debug, thiserror::Error)]
pub enum LibraryError {
    /// The folder cannot be read.
    #[error("{path}: cannot read the library folder: {source}")]
    Io {
        /// The folder.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// `labels.csv` is missing.
    #[error("{0}: no labels.csv in the library folder")]
    NoLabels(PathBuf),
    /// `labels.csv` is malformed or lacks a rank column.
    #[error(transparent)]
    Labels(#[from] TableError),
    /// A surface file has no row in `labels.csv`.
    #[error("{path}: no row for `{name}` in labels.csv")]
    Unlabelled {
        /// The surface file.
        path: PathBuf,
        /// Its name (file stem).
        name: String,
    },
    /// A row of `labels.csv` has no surface file.
    #[error(
        "{labels}: `{name}` has a label row but no surface file (.ply, .obj, .stl, .off) in {dir}"
    )]
    MissingSurface {
        /// The labels file.
        labels: PathBuf,
        /// The library folder.
        dir: PathBuf,
        /// The specimen name.
        name: String,
    },
    /// Two surface files share a name.
    #[error("{first} and {second}: two surfaces named `{name}`")]
    DuplicateName {
        /// The specimen name.
        name: String,
        /// One file.
        first: PathBuf,
        /// The other.
        second: PathBuf,
    },
    /// The folder holds no surface file.
    #[error("{0}: no surface files (.obj, .ply, .stl, .off)")]
    NoSurfaces(PathBuf),
}

/// One reference specimen.
#[derive(Debug, Clone, PartialEq)]
pub struct Member {
    /// Name (file stem, as in `labels.csv`).
    name: String,
    /// The surface file.
    path: PathBuf,
    /// Landmark file, when `landmarks/<name>.{csv,fcsv,mrk.json,pp}`
    /// exists (the first found; [`build`] reports a name with several).
    landmarks: Option<PathBuf>,
}

impl Member {
    /// Name (file stem, as in `labels.csv`).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The surface file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Landmark file, when `landmarks/<name>.{csv,fcsv,mrk.json,pp}`
    /// exists (the first found; [`build`] reports a name with several).
    pub fn landmarks(&self) -> Option<&Path> {
        self.landmarks.as_deref()
    }
}

/// A reference library folder, checked: every surface has a label row
/// and every label row a surface.
#[derive(Debug, Clone)]
pub struct Library {
    dir: PathBuf,
    labels: Labels,
    members: Vec<Member>,
}

impl Library {
    /// Open a library folder, with `ranks` as the rank columns of
    /// `labels.csv` (broadest first; `None`: every column but `name`).
    pub fn open(dir: &Path, ranks: Option<&[String]>) -> Result<Self, LibraryError> {
        let labels_path = dir.join("labels.csv");
        if !labels_path.is_file() {
            return Err(LibraryError::NoLabels(dir.to_path_buf()));
        }
        let labels = Labels::read(&labels_path, ranks)?;
        let members = members(dir)?;
        if let Some(m) = members.iter().find(|m| !labels.contains(&m.name)) {
            return Err(LibraryError::Unlabelled {
                path: m.path.clone(),
                name: m.name.clone(),
            });
        }
        if let Some(name) = labels
            .names()
            .iter()
            .find(|n| members.binary_search_by(|m| m.name.cmp(n)).is_err())
        {
            return Err(LibraryError::MissingSurface {
                labels: labels_path,
                dir: dir.to_path_buf(),
                name: name.clone(),
            });
        }
        Ok(Library {
            dir: dir.to_path_buf(),
            labels,
            members,
        })
    }
}

/// Why one surface file could not be prepared; the message names the file.
#[derive(Debug, thiserror::Error)]
pub enum PrepareError {
    /// The file cannot be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is not a readable surface (the message names the file).
    #[error(transparent)]
    Load(#[from] LoadError),
    /// The surface cannot be cleaned or prepared.
    #[error("{path}: {source}")]
    Mesh {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        #[source]
        source: MeshError,
    },
    /// Its prepared form cannot be read back from the cache.
    #[error(transparent)]
    Cache(#[from] CacheError),
}

/// One reference that [`build`] left out, and why.
#[derive(Debug)]
pub struct Failure {
    /// The reference.
    name: String,
    /// Why it could not be prepared.
    error: PrepareError,
}

impl Failure {
    /// The reference `name` could not be prepared because of `error`.
    pub fn new(name: String, error: PrepareError) -> Self {
        Self { name, error }
    }

    /// The reference.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Why it failed.
    pub fn error(&self) -> &PrepareError {
        &self.error
    }
}

/// Where a prepared surface came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Origin {
    /// An entry of the cache (the file and the settings are unchanged).
    Cache,
    /// Prepared now.
    Prepared,
}

/// A prepared surface, the cache key it belongs under, where it came
/// from, and the stamp of its file when that is to be trusted (see
/// [`index`]).
struct Loaded {
    reference: CachedReference,
    key: String,
    origin: Origin,
    stamp: Option<Stamp>,
}

/// The prepared form of `member`'s surface: the entry of `cache` for its
/// content and `settings` when there is one, else prepared now (not yet
/// stored).
fn load_or_prepare(
    member: &Member,
    cache: Option<&Cache>,
    settings: &Settings,
) -> Result<Loaded, PrepareError> {
    let _span = tracing::info_span!("reference", name = %member.name).entered();
    let path = &member.path;
    let read_error = |source| PrepareError::Read {
        path: path.clone(),
        source,
    };
    let before = std::fs::metadata(path).map_err(read_error)?;
    let bytes = std::fs::read(path).map_err(read_error)?;
    // Trusted only if the file had settled and did not change meanwhile.
    let stamp = Stamp::settled(&before).filter(|&s| Stamp::now(path) == Some(s));
    let hash = content_hash(&bytes);
    let key = Cache::key(&hash, settings);
    if let Some(hit) = cache.and_then(|c| c.get(&member.name, &key)) {
        return Ok(Loaded {
            reference: hit,
            key,
            origin: Origin::Cache,
            stamp,
        });
    }
    let format =
        Format::from_path(path).ok_or_else(|| LoadError::UnknownFormat { path: path.clone() })?;
    let loaded = mesh_io::load_bytes(&bytes, format, path)?;
    let surface =
        pipeline::prepare_mesh(&loaded.mesh, &member.name, settings).map_err(|source| {
            PrepareError::Mesh {
                path: path.clone(),
                source,
            }
        })?;
    Ok(Loaded {
        reference: CachedReference::new(
            member.name.clone(),
            hash,
            surface.prepared,
            surface.cleaning,
        ),
        key,
        origin: Origin::Prepared,
        stamp,
    })
}

/// Prepared surfaces taken from a cache where the file and the settings
/// are unchanged and prepared otherwise (then stored in the cache, so the
/// next run finds them); counts each. Without a cache, every surface is
/// prepared. Safe to share between threads.
#[derive(Debug)]
pub struct Preparation<'a> {
    cache: Option<&'a Cache>,
    settings: &'a Settings,
    reused: AtomicUsize,
    prepared: AtomicUsize,
    stored: AtomicUsize,
}

impl<'a> Preparation<'a> {
    /// Prepare with `settings`, reading and filling `cache` if given.
    pub fn new(cache: Option<&'a Cache>, settings: &'a Settings) -> Self {
        Preparation {
            cache,
            settings,
            reused: AtomicUsize::new(0),
            prepared: AtomicUsize::new(0),
            stored: AtomicUsize::new(0),
        }
    }

    /// The prepared form of `member`'s surface, named after it.
    pub fn prepare(&self, member: &Member) -> Result<Prepared, PrepareError> {
        Ok(self.prepare_hashed(member)?.0)
    }

    /// The prepared form of `member`'s surface and the content hash of its
    /// file (what a matrix shard records of each specimen).
    pub fn prepare_hashed(&self, member: &Member) -> Result<(Prepared, String), PrepareError> {
        let loaded = load_or_prepare(member, self.cache, self.settings)?;
        match loaded.origin {
            Origin::Cache => {
                self.reused.fetch_add(1, Ordering::Relaxed);
            }
            Origin::Prepared => {
                self.prepared.fetch_add(1, Ordering::Relaxed);
                // The cache only saves time: a surface that cannot be
                // stored is still good for this run.
                match self.cache.map(|c| c.put(&loaded.key, &loaded.reference)) {
                    Some(Ok(())) => {
                        self.stored.fetch_add(1, Ordering::Relaxed);
                    }
                    Some(Err(e)) => {
                        tracing::warn!(reference = %member.name, "not stored in the cache: {e}")
                    }
                    None => {}
                }
            }
        }
        let prepared = loaded.reference.prepared()?;
        let prepared = Arc::try_unwrap(prepared).unwrap_or_else(|shared| (*shared).clone());
        Ok((prepared, loaded.reference.content_hash().to_string()))
    }

    /// The prepared forms of all `members`, in their order, in parallel;
    /// `progress` is called once per member. The first failure stops it.
    pub fn prepare_all(
        &self,
        members: &[Member],
        progress: impl Fn(&str) + Sync,
    ) -> Result<Vec<Prepared>, PrepareError> {
        members
            .par_iter()
            .map(|m| {
                let p = self.prepare(m);
                progress(&m.name);
                p
            })
            .collect()
    }

    /// The cache folder, if any.
    pub fn cache_dir(&self) -> Option<&Path> {
        self.cache.map(Cache::dir)
    }

    /// How many surfaces came from the cache so far.
    pub fn reused(&self) -> usize {
        self.reused.load(Ordering::Relaxed)
    }

    /// How many surfaces were prepared so far.
    pub fn prepared(&self) -> usize {
        self.prepared.load(Ordering::Relaxed)
    }

    /// How many of the prepared surfaces were stored in the cache (a
    /// failure to store one is logged and does not stop the run).
    pub fn stored(&self) -> usize {
        self.stored.load(Ordering::Relaxed)
    }
}

impl Library {
    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The labels at the configured ranks.
    pub fn labels(&self) -> &Labels {
        &self.labels
    }

    /// The specimens, sorted by name.
    pub fn members(&self) -> &[Member] {
        &self.members
    }
}

/// What [`build`] did.
#[derive(Debug, Default)]
pub struct BuildOutcome {
    /// The prepared references, in library order (failed ones left out).
    references: Vec<CachedReference>,
    /// References that could not be prepared.
    failures: Vec<Failure>,
    /// How many were prepared now.
    prepared: usize,
    /// How many came from the cache.
    reused: usize,
    /// Cache entries deleted (removed or changed references, old settings).
    removed: usize,
    /// The references' landmarks (read at every build, not cached) and
    /// the landmark files that could not be used, per reference.
    landmarks: LibraryLandmarks,
}

impl BuildOutcome {
    /// The prepared references, in library order (failed ones left out;
    /// empty once a [`Classifier`](morphoid_service::classify::Classifier) took them).
    pub fn references(&self) -> &[CachedReference] {
        &self.references
    }

    /// References that could not be prepared.
    pub fn failures(&self) -> &[Failure] {
        &self.failures
    }

    /// How many were prepared now.
    pub fn prepared(&self) -> usize {
        self.prepared
    }

    /// How many came from the cache.
    pub fn reused(&self) -> usize {
        self.reused
    }

    /// Cache entries deleted (removed or changed references, old settings).
    pub fn removed(&self) -> usize {
        self.removed
    }

    /// The references' landmarks and the landmark files that could not be used.
    pub fn landmarks(&self) -> &LibraryLandmarks {
        &self.landmarks
    }

    /// Move out the prepared references and their usable landmarks (by
    /// name), leaving the counts, failures and landmark problems: the
    /// classifier keeps one copy of the references, not two.
    pub fn take_references(&mut self) -> (Vec<CachedReference>, BTreeMap<String, Landmarks>) {
        (
            std::mem::take(&mut self.references),
            self.landmarks.take_by_name(),
        )
    }
}

/// Prepare every reference of `library`, reusing the cache where the file
/// and the settings are unchanged, and drop cache entries no reference
/// uses any more. `progress` is called once per reference. A reference that
/// cannot be prepared is reported in `failures`; the others still build.
/// The landmark files are read too; one that cannot be used leaves its
/// reference without landmarks and is reported in `landmarks.problems`.
///
/// The references come back with their prepared forms left in the cache
/// (read back at each comparison), except those the cache could not take;
/// a reference whose file is unchanged since the last build is known from
/// the library's index without reading the file or its entry.
pub fn build(
    library: &Library,
    cache: &Cache,
    settings: &Settings,
    progress: impl Fn(&str) + Sync,
) -> Result<BuildOutcome, CacheError> {
    let index = Index::read(cache);
    let results: Vec<Result<Built, PrepareError>> = library
        .members
        .par_iter()
        .map(|m| {
            let r = build_member(m, &index, cache, settings);
            progress(&m.name);
            r
        })
        .collect();
    let mut out = BuildOutcome::default();
    let mut keep = HashSet::new();
    let mut entries = Vec::new();
    for (m, r) in library.members.iter().zip(results) {
        match r {
            Ok(built) => {
                match built.origin {
                    Origin::Cache => out.reused += 1,
                    Origin::Prepared => out.prepared += 1,
                }
                keep.insert((m.name.clone(), built.key));
                entries.extend(built.index);
                out.references.push(built.reference);
            }
            Err(error) => out.failures.push(Failure {
                name: m.name.clone(),
                error,
            }),
        }
    }
    out.removed = cache.retain(&keep).unwrap_or_else(|e| {
        tracing::warn!("stale cache entries not removed: {e}");
        0
    });
    if !index.holds(&entries) {
        // The index only saves time at the next opening.
        if let Err(e) = Index::write(cache, entries) {
            tracing::warn!("the library index not written: {e}");
        }
    }
    let names: Vec<String> = library.members.iter().map(|m| m.name.clone()).collect();
    out.landmarks = crate::landmarks::load_library(&library.dir, &names);
    Ok(out)
}

/// Prepare only the references of `shard` (a contiguous part of the
/// library's sorted members) into `cache`, for a cluster job array whose
/// tasks share the cache: nothing else in the cache is touched (no stale
/// entry removed, no index written), so tasks never undo each other's
/// work. A `build` of the whole library afterwards finds every entry.
pub fn build_shard(
    library: &Library,
    cache: &Cache,
    settings: &Settings,
    shard: crate::shard::Shard,
    progress: impl Fn(&str) + Sync,
) -> BuildOutcome {
    let members = &library.members[shard.range(library.members.len())];
    let no_index = Index::default();
    let results: Vec<Result<Built, PrepareError>> = members
        .par_iter()
        .map(|m| {
            let r = build_member(m, &no_index, cache, settings);
            progress(&m.name);
            r
        })
        .collect();
    let mut out = BuildOutcome::default();
    for (m, r) in members.iter().zip(results) {
        match r {
            Ok(built) => match built.origin {
                Origin::Cache => out.reused += 1,
                Origin::Prepared => out.prepared += 1,
            },
            Err(error) => out.failures.push(Failure {
                name: m.name.clone(),
                error,
            }),
        }
    }
    out
}

/// One member as [`build`] made it: the reference, its cache key, where
/// it came from, and its index entry (none when its file's stamp is not
/// to be trusted or its entry is not in the cache).
struct Built {
    reference: CachedReference,
    key: String,
    origin: Origin,
    index: Option<IndexEntry>,
}

/// `member` known from `index` when its file is unchanged, else read (and
/// prepared unless the cache has it); held in the cache when it is there.
fn build_member(
    member: &Member,
    index: &Index,
    cache: &Cache,
    settings: &Settings,
) -> Result<Built, PrepareError> {
    let known = std::fs::metadata(&member.path)
        .ok()
        .and_then(|m| Stamp::settled(&m))
        .and_then(|stamp| index.lookup(&member.name, stamp, cache, settings));
    if let Some((reference, entry)) = known {
        return Ok(Built {
            key: Cache::key(reference.content_hash(), settings),
            reference,
            origin: Origin::Cache,
            index: Some(entry),
        });
    }
    let loaded = load_or_prepare(member, Some(cache), settings)?;
    let in_cache = match loaded.origin {
        Origin::Cache => true,
        // The cache only saves time: a full or failing disk must not stop
        // the library from loading (the reference stays in memory).
        Origin::Prepared => match cache.put(&loaded.key, &loaded.reference) {
            Ok(()) => true,
            Err(e) => {
                tracing::warn!(reference = %member.name, "not stored in the cache: {e}");
                false
            }
        },
    };
    let (reference, index) = if in_cache {
        let entry = loaded
            .stamp
            .map(|stamp| IndexEntry::of(&loaded.reference, stamp, &loaded.key));
        (loaded.reference.stored_in(cache, &loaded.key), entry)
    } else {
        (loaded.reference, None)
    };
    Ok(Built {
        reference,
        key: loaded.key,
        origin: loaded.origin,
        index,
    })
}

/// Whether each member of `library` has an entry in `cache` for its
/// current content and `settings`; `None` when its file cannot be read.
pub fn cached_members(library: &Library, cache: &Cache, settings: &Settings) -> Vec<Option<bool>> {
    library
        .members
        .iter()
        .map(|m| {
            let bytes = std::fs::read(&m.path).ok()?;
            let key = Cache::key(&content_hash(&bytes), settings);
            Some(cache.get(&m.name, &key).is_some())
        })
        .collect()
}

/// The specimens of a folder of surfaces, sorted by name: each surface
/// file (by extension) named by its stem, with its landmark file if the
/// folder has one (`landmarks/<name>.{csv,fcsv,mrk.json,pp}`). When the
/// folder holds no surface but has a `meshes/` subfolder, that one is used
/// (the layout of the PNAS data set). No surface at all and two surfaces
/// with one name are errors.
pub fn members(dir: &Path) -> Result<Vec<Member>, LibraryError> {
    let mut by_name: BTreeMap<String, PathBuf> = BTreeMap::new();
    for path in surface_files(dir)? {
        let name = pipeline::specimen_name(&path);
        if let Some(first) = by_name.get(&name) {
            return Err(LibraryError::DuplicateName {
                name,
                first: first.clone(),
                second: path,
            });
        }
        by_name.insert(name, path);
    }
    if by_name.is_empty() {
        return Err(LibraryError::NoSurfaces(dir.to_path_buf()));
    }
    Ok(by_name
        .into_iter()
        .map(|(name, path)| Member {
            landmarks: crate::landmarks::library_files(dir, &name)
                .into_iter()
                .next(),
            name,
            path,
        })
        .collect())
}

/// The surface files of a folder (by extension), sorted. When the folder
/// holds none but has a `meshes/` subfolder, that one is used (the layout
/// of the PNAS data set).
pub fn surface_files(dir: &Path) -> Result<Vec<PathBuf>, LibraryError> {
    let mut files = list_surfaces(dir)?;
    let sub = dir.join("meshes");
    if files.is_empty() && sub.is_dir() {
        files = list_surfaces(&sub)?;
    }
    Ok(files)
}

fn list_surfaces(dir: &Path) -> Result<Vec<PathBuf>, LibraryError> {
    let io = |source| LibraryError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        if path.is_file() && Format::from_path(&path).is_some() {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder(labels: &str, files: &[&str]) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("labels.csv"), labels).unwrap();
        for f in files {
            std::fs::write(dir.path().join(f), b"ply\n").unwrap();
        }
        dir
    }

    const LABELS: &str = "name,order,genus\na,O,G\nb,O,NA\n";

    #[test]
    fn opens_a_matching_folder() {
        let d = folder(LABELS, &["a.ply", "b.obj", "notes.txt"]);
        let lib = Library::open(d.path(), None).unwrap();
        let names: Vec<&str> = lib.members.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["a", "b"]);
        assert_eq!(lib.labels().ranks(), ["order", "genus"]);
    }

    #[test]
    fn members_of_a_plain_folder() {
        let d = folder("", &["b.ply", "a.obj", "notes.txt"]);
        let m = members(d.path()).unwrap();
        assert_eq!(
            m.iter().map(|m| m.name.as_str()).collect::<Vec<_>>(),
            ["a", "b"]
        );
        let d = folder("", &["a.ply", "a.stl"]);
        let e = members(d.path()).unwrap_err().to_string();
        assert!(e.contains("two surfaces named `a`"), "{e}");
        let d = folder("", &["notes.txt"]);
        let e = members(d.path()).unwrap_err().to_string();
        assert!(e.contains("no surface files"), "{e}");
    }

    /// The library index spares reading files that have not changed and
    /// never hides a change: a file rewritten in place with the same size
    /// is read, hashed and prepared again.
    #[test]
    fn the_index_knows_unchanged_files_and_never_hides_a_change() {
        let lib = tempfile::tempdir().unwrap();
        let spec = morphoid_synth::mesh::LibrarySpec {
            per_genus: 1,
            target_vertices: 600,
            seed: 11,
            random_pose: false,
        };
        morphoid_synth::mesh::write_synthetic_library(lib.path(), &spec).unwrap();
        let cache_dir = tempfile::tempdir().unwrap();
        let cache = Cache::open(cache_dir.path()).unwrap();
        let settings = Settings::default();
        let library = Library::open(lib.path(), None).unwrap();
        let n = library.members.len();
        let settle = || std::thread::sleep(std::time::Duration::from_millis(2100));
        settle();

        let first = build(&library, &cache, &settings, |_| {}).unwrap();
        assert_eq!((first.prepared, first.reused), (n, 0));
        assert!(first.references.iter().all(|r| !r.is_resident()));
        let index = Index::read(&cache);
        for m in &library.members {
            let stamp = Stamp::now(&m.path).unwrap();
            assert!(index.lookup(&m.name, stamp, &cache, &settings).is_some());
        }
        // The second opening: the same references, signatures and
        // prepared forms, known from the index.
        let second = build(&library, &cache, &settings, |_| {}).unwrap();
        assert_eq!((second.prepared, second.reused), (0, n));
        for (a, b) in first.references.iter().zip(&second.references) {
            assert_eq!((a.name(), a.content_hash()), (b.name(), b.content_hash()));
            assert_eq!(a.signature(), b.signature());
            let (pa, pb) = (a.prepared().unwrap(), b.prepared().unwrap());
            assert_eq!(pa.vertices(), pb.vertices());
            assert_eq!(pa.samples(), pb.samples());
        }

        // One coordinate's lowest bit flipped in place: same size, same
        // inode, new bytes.
        let path = library.members[0].path.clone();
        let before = Stamp::now(&path).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        let header = b"end_header\n";
        let body = bytes
            .windows(header.len())
            .position(|w| w == header)
            .unwrap()
            + header.len();
        bytes[body] ^= 1;
        std::fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .and_then(|mut f| std::io::Write::write_all(&mut f, &bytes))
            .unwrap();
        assert_ne!(Stamp::now(&path).unwrap(), before);
        let third = build(&library, &cache, &settings, |_| {}).unwrap();
        assert_eq!((third.prepared, third.reused), (1, n - 1));
        assert_eq!(third.references[0].content_hash(), content_hash(&bytes));
        // Settled, it is indexed under its new stamp and hash.
        settle();
        let fourth = build(&library, &cache, &settings, |_| {}).unwrap();
        assert_eq!((fourth.prepared, fourth.reused), (0, n));
        assert_eq!(fourth.references[0].content_hash(), content_hash(&bytes));
        let stamp = Stamp::now(&path).unwrap();
        let (known, _) = Index::read(&cache)
            .lookup(&library.members[0].name, stamp, &cache, &settings)
            .unwrap();
        assert_eq!(known.content_hash(), content_hash(&bytes));
    }

    /// A reference whose cache entry disappears after the build says so,
    /// naming the entry, instead of answering with anything else.
    #[test]
    fn a_stored_reference_whose_entry_is_gone_names_it() {
        let lib = tempfile::tempdir().unwrap();
        let spec = morphoid_synth::mesh::LibrarySpec {
            per_genus: 1,
            target_vertices: 600,
            seed: 12,
            random_pose: false,
        };
        morphoid_synth::mesh::write_synthetic_library(lib.path(), &spec).unwrap();
        let cache_dir = tempfile::tempdir().unwrap();
        let cache = Cache::open(cache_dir.path()).unwrap();
        let library = Library::open(lib.path(), None).unwrap();
        let built = build(&library, &cache, &Settings::default(), |_| {}).unwrap();
        let r = &built.references[0];
        assert!(r.prepared().is_ok());
        let entry = std::fs::read_dir(cache.dir())
            .unwrap()
            .map(|e| e.unwrap().path())
            .find(|p| {
                p.file_name()
                    .is_some_and(|f| f.to_string_lossy().starts_with(&format!("{}.", r.name())))
            })
            .unwrap();
        std::fs::write(&entry, b"not an entry").unwrap();
        let e = r.prepared().unwrap_err().to_string();
        assert!(
            e.contains(&entry.display().to_string()) && e.contains("does not decode"),
            "{e}"
        );
        std::fs::remove_file(&entry).unwrap();
        assert!(r.prepared().is_err());
    }

    /// The bug this guards against: the library build and `matrix
    /// --cache` chose different folders inside the cache, so a matrix
    /// never found what the build had prepared.
    #[test]
    fn build_and_preparation_share_the_cache_of_a_folder() {
        let lib = tempfile::tempdir().unwrap();
        let spec = morphoid_synth::mesh::LibrarySpec {
            per_genus: 1,
            target_vertices: 600,
            seed: 5,
            random_pose: false,
        };
        morphoid_synth::mesh::write_synthetic_library(lib.path(), &spec).unwrap();
        let root = tempfile::tempdir().unwrap();
        let settings = Settings::default();
        let library = Library::open(lib.path(), None).unwrap();
        let n = library.members.len();

        // The cache folder the user gives is the root; the library's
        // subfolder is chosen here, the same for every caller.
        let cache = Cache::for_folder(Some(root.path()), lib.path()).unwrap();
        assert_eq!(cache.dir().parent(), Some(root.path()));
        let built = build(&library, &cache, &settings, |_| {}).unwrap();
        assert_eq!((built.prepared, built.reused), (n, 0));
        assert!(built.failures.is_empty());

        let again = Cache::for_folder(Some(root.path()), lib.path()).unwrap();
        let preparation = Preparation::new(Some(&again), &settings);
        let prepared = preparation.prepare_all(&library.members, |_| {}).unwrap();
        assert_eq!((preparation.reused(), preparation.prepared()), (n, 0));
        let names: Vec<&str> = prepared.iter().map(|p| p.name()).collect();
        let expected: Vec<&str> = library.members.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, expected);
        assert!(cached_members(&library, &again, &settings)
            .iter()
            .all(|c| *c == Some(true)));

        // Another folder has its own subfolder; preparing there stores
        // what it prepared, so the next run finds it.
        let other = tempfile::tempdir().unwrap();
        let copy = other
            .path()
            .join(format!("{}.ply", library.members[0].name));
        std::fs::copy(&library.members[0].path, &copy).unwrap();
        let other_cache = Cache::for_folder(Some(root.path()), other.path()).unwrap();
        assert_ne!(other_cache.dir(), cache.dir());
        let first = members(other.path()).unwrap();
        let p = Preparation::new(Some(&other_cache), &settings);
        p.prepare_all(&first, |_| {}).unwrap();
        assert_eq!((p.reused(), p.prepared(), p.stored()), (0, 1, 1));
        let p = Preparation::new(Some(&other_cache), &settings);
        p.prepare_all(&first, |_| {}).unwrap();
        assert_eq!((p.reused(), p.prepared()), (1, 0));
        // Without a cache, everything is prepared.
        let p = Preparation::new(None, &settings);
        p.prepare_all(&first, |_| {}).unwrap();
        assert_eq!((p.reused(), p.prepared()), (0, 1));
    }

    #[test]
    fn a_failing_reference_is_reported_with_its_file() {
        let d = folder("name,genus\na,G\n", &["a.ply"]);
        let root = tempfile::tempdir().unwrap();
        let library = Library::open(d.path(), None).unwrap();
        let cache = Cache::for_folder(Some(root.path()), d.path()).unwrap();
        let out = build(&library, &cache, &Settings::default(), |_| {}).unwrap();
        assert_eq!(out.failures.len(), 1);
        let f = &out.failures[0];
        assert_eq!(f.name, "a");
        assert!(matches!(f.error, PrepareError::Load(_)), "{:?}", f.error);
        assert!(f.error.to_string().contains("a.ply"), "{}", f.error);
        let e = Cache::for_folder(Some(root.path()), &d.path().join("missing")).unwrap_err();
        assert!(matches!(e, CacheError::Folder { .. }), "{e}");
    }

    #[test]
    fn names_each_mismatch() {
        let d = folder(LABELS, &["a.ply", "b.ply", "c.stl"]);
        let e = Library::open(d.path(), None).unwrap_err().to_string();
        assert!(e.contains("c.stl") && e.contains("no row for `c`"), "{e}");

        let d = folder(LABELS, &["a.ply"]);
        let e = Library::open(d.path(), None).unwrap_err().to_string();
        assert!(e.contains("`b` has a label row but no surface"), "{e}");

        let d = folder(LABELS, &["a.ply", "a.off", "b.ply"]);
        let e = Library::open(d.path(), None).unwrap_err().to_string();
        assert!(e.contains("two surfaces named `a`"), "{e}");

        let d = folder(LABELS, &["a.ply", "b.ply"]);
        let ranks = vec!["family".to_string()];
        let e = Library::open(d.path(), Some(&ranks))
            .unwrap_err()
            .to_string();
        assert!(e.contains("family"), "{e}");

        let d = tempfile::tempdir().unwrap();
        let e = Library::open(d.path(), None).unwrap_err().to_string();
        assert!(e.contains("no labels.csv"), "{e}");
    }
}
