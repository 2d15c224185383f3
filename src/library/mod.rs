//! A reference library: a folder with `labels.csv` and one surface per
//! specimen (`<name>.{ply,obj,stl,off}`), optionally landmarks in
//! `landmarks/<name>.{csv,fcsv,mrk.json,pp}` (one file per specimen, any
//! supported format; see [`crate::landmarks::load_library`]).
//!
//! [`Library::open`] checks that labels and surfaces match one to one;
//! [`identify`] turns the distances of a scan to the references into the
//! nearest taxon at each rank.

mod cache;
mod identify;

pub use cache::{Cache, CacheError, CachedReference};
pub use identify::{
    identify, DistanceRow, Identification, LandmarkPoint, Nearest, RankResult, ScanLandmarks,
    ScanOutcome,
};

use crate::eval::{Labels, LabelsError};
use crate::hash::content_hash;
use crate::landmarks::LibraryLandmarks;
use crate::mesh::io::{self, Format};
use crate::pipeline::{self, Settings};
use rayon::prelude::*;
use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};

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
    Labels(#[from] LabelsError),
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
    /// The library has no specimen.
    #[error("{0}: the library has no specimen")]
    Empty(PathBuf),
}

/// One reference specimen.
#[derive(Debug, Clone, PartialEq)]
pub struct Member {
    /// Name (file stem, as in `labels.csv`).
    pub name: String,
    /// The surface file.
    pub path: PathBuf,
    /// Landmark file, when `landmarks/<name>.{csv,fcsv,mrk.json,pp}`
    /// exists (the first found; [`build`] reports a name with several).
    pub landmarks: Option<PathBuf>,
}

/// A reference library folder, checked.
#[derive(Debug, Clone)]
pub struct Library {
    /// The folder.
    pub dir: PathBuf,
    /// Labels at the configured ranks.
    pub labels: Labels,
    /// The specimens, sorted by name.
    pub members: Vec<Member>,
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
        let surfaces = surface_files(dir)?;
        let mut by_name: BTreeMap<String, PathBuf> = BTreeMap::new();
        for path in surfaces {
            let name = stem(&path);
            if let Some(first) = by_name.get(&name) {
                return Err(LibraryError::DuplicateName {
                    name,
                    first: first.clone(),
                    second: path,
                });
            }
            if !labels.names.contains(&name) {
                return Err(LibraryError::Unlabelled { path, name });
            }
            by_name.insert(name, path);
        }
        if let Some(name) = labels.names.iter().find(|n| !by_name.contains_key(*n)) {
            return Err(LibraryError::MissingSurface {
                labels: labels_path,
                dir: dir.to_path_buf(),
                name: name.clone(),
            });
        }
        if by_name.is_empty() {
            return Err(LibraryError::Empty(dir.to_path_buf()));
        }
        let members = by_name
            .into_iter()
            .map(|(name, path)| Member {
                landmarks: crate::landmarks::library_files(dir, &name)
                    .into_iter()
                    .next(),
                name,
                path,
            })
            .collect();
        Ok(Library {
            dir: dir.to_path_buf(),
            labels,
            members,
        })
    }
}

/// What [`build`] did.
#[derive(Debug, Clone, Default)]
pub struct BuildOutcome {
    /// The prepared references, in library order (failed ones left out).
    pub references: Vec<CachedReference>,
    /// References that could not be prepared: name and one-line reason.
    pub failures: Vec<(String, String)>,
    /// How many were prepared now.
    pub prepared: usize,
    /// How many came from the cache.
    pub reused: usize,
    /// Cache entries deleted (removed or changed references, old settings).
    pub removed: usize,
    /// The references' landmarks (read at every build, not cached) and
    /// the landmark files that could not be used, per reference.
    pub landmarks: LibraryLandmarks,
}

/// Whether a reference came from the cache.
enum Source {
    Cache,
    Prepared,
}

/// Prepare every reference of `library`, reusing the cache where the file
/// and the settings are unchanged, and drop cache entries no reference
/// uses any more. `progress` is called once per reference. A reference that
/// cannot be prepared is reported in `failures`; the others still build.
/// The landmark files are read too; one that cannot be used leaves its
/// reference without landmarks and is reported in `landmarks.problems`.
pub fn build(
    library: &Library,
    cache: &Cache,
    settings: &Settings,
    progress: impl Fn(&str) + Sync,
) -> Result<BuildOutcome, CacheError> {
    let results: Vec<Result<(CachedReference, String, Source), String>> = library
        .members
        .par_iter()
        .map(|m| {
            let r = prepare_member(m, cache, settings);
            progress(&m.name);
            r
        })
        .collect();
    let mut out = BuildOutcome::default();
    let mut keep = HashSet::new();
    for (m, r) in library.members.iter().zip(results) {
        match r {
            Ok((reference, key, source)) => {
                match source {
                    Source::Cache => out.reused += 1,
                    Source::Prepared => {
                        cache.put(&key, &reference)?;
                        out.prepared += 1;
                    }
                }
                keep.insert((m.name.clone(), key));
                out.references.push(reference);
            }
            Err(message) => out.failures.push((m.name.clone(), message)),
        }
    }
    out.removed = cache.retain(&keep)?;
    let names: Vec<String> = library.members.iter().map(|m| m.name.clone()).collect();
    out.landmarks = crate::landmarks::load_library(&library.dir, &names);
    Ok(out)
}

fn prepare_member(
    m: &Member,
    cache: &Cache,
    settings: &Settings,
) -> Result<(CachedReference, String, Source), String> {
    let _span = tracing::info_span!("reference", name = %m.name).entered();
    let bytes = std::fs::read(&m.path).map_err(|e| format!("{}: {e}", m.path.display()))?;
    let hash = content_hash(&bytes);
    let key = Cache::key(&hash, settings);
    if let Some(hit) = cache.get(&m.name, &key) {
        return Ok((hit, key, Source::Cache));
    }
    let format = Format::from_path(&m.path)
        .ok_or_else(|| format!("{}: unsupported file type", m.path.display()))?;
    let loaded = io::load_bytes(&bytes, format, &m.path).map_err(|e| e.to_string())?;
    let surface = pipeline::prepare_mesh(&loaded.mesh, &m.name, settings)
        .map_err(|e| format!("{}: {e}", m.path.display()))?;
    let reference = CachedReference {
        name: m.name.clone(),
        content_hash: hash,
        prepared: surface.prepared,
        cleaning: surface.cleaning,
    };
    Ok((reference, key, Source::Prepared))
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

fn stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
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
        assert_eq!(lib.labels.ranks, ["order", "genus"]);
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
