//! Which files of the export folder become jobs: surface and volume files
//! (a format morphoid reads, by extension) and subfolders holding slices
//! (a slice stack, one scan), whose name matches no `watch.ignore`
//! pattern, outside the quarantine folder; and, once such a file has
//! settled, its queueing in the store by content hash, so that the same
//! bytes are identified once whatever their name or how often they are
//! seen.

use super::glob;
use super::settle::Stamp;
use crate::store::{Enqueued, Store, StoreError};
use morphoid_data::completeness::Verdict;
use morphoid_data::hash::content_hash_file;
use morphoid_data::mesh_io::Format;
use std::path::{Path, PathBuf};

/// What decides whether a path is a candidate: the export folder and the
/// `[watch]` keys that filter it.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Filter {
    /// The export folder.
    pub dir: PathBuf,
    /// Whether subfolders count.
    pub recursive: bool,
    /// `watch.ignore` patterns (matched against the file name).
    pub ignore: Vec<String>,
    /// The quarantine folder, never entered (its files already failed).
    pub quarantine: Option<PathBuf>,
}

impl Filter {
    /// The filter of a configuration's `[watch]` section.
    /// The folder is made absolute (against the working directory), as
    /// the watcher reports absolute paths and a relative folder would
    /// match none of them.
    pub(super) fn from_config(watch: &crate::config::Watch) -> Self {
        Filter {
            dir: std::path::absolute(&watch.dir).unwrap_or_else(|_| watch.dir.clone()),
            recursive: watch.recursive,
            ignore: watch.ignore.clone(),
            quarantine: watch.quarantine.clone(),
        }
    }

    /// Whether `path` (reported by the watcher, so under the folder) is a
    /// surface file to consider. Checks the name and the place only; the
    /// caller `stat`s it.
    pub(super) fn is_candidate(&self, path: &Path) -> bool {
        let Some(name) = path.file_name() else {
            return false;
        };
        if glob::is_ignored(&self.ignore, &name.to_string_lossy()) {
            return false;
        }
        if !is_scan_file(path) {
            return false;
        }
        self.is_inside(path)
    }

    /// The scan a path reported by the watcher belongs to: a scan file
    /// itself, or, for a slice in a subfolder, that folder (a slice stack
    /// is one scan; its slices are never scans of their own).
    pub(super) fn scan_of(&self, path: &Path) -> Option<PathBuf> {
        if self.is_candidate(path) {
            return Some(path.to_path_buf());
        }
        morphoid_data::volume::slice_format(path)?;
        let folder = path.parent()?;
        self.is_candidate_folder(folder)
            .then(|| folder.to_path_buf())
    }

    /// Whether `dir` is a folder that may hold a slice stack: below the
    /// export folder (directly, unless recursive), not ignored, not the
    /// quarantine folder or inside it.
    fn is_candidate_folder(&self, dir: &Path) -> bool {
        if dir == self.dir.as_path() || !dir.starts_with(&self.dir) {
            return false;
        }
        if dir.file_name().is_none() {
            return false;
        }
        // The folder is checked as a file named inside itself would be:
        // every folder on the way, itself included, must pass.
        self.is_inside(&dir.join("slice"))
            && self.quarantine.as_deref().is_none_or(|q| !same_dir(q, dir))
    }

    /// Whether a file at `path` lies in the part of the export folder
    /// that is watched (depth, ignored and quarantine folders).
    fn is_inside(&self, path: &Path) -> bool {
        let Ok(rel) = path.strip_prefix(&self.dir) else {
            // Paths come from the watcher joined onto `dir`; anything else
            // is outside the export folder.
            return false;
        };
        let mut parent = self.dir.clone();
        let comps: Vec<_> = rel.components().collect();
        if comps.len() > 1 && !self.recursive {
            return false;
        }
        // An ignored or quarantine folder on the way hides the file, as in
        // a full listing.
        for c in &comps[..comps.len().saturating_sub(1)] {
            if glob::is_ignored(&self.ignore, &c.as_os_str().to_string_lossy()) {
                return false;
            }
            parent.push(c);
            if self
                .quarantine
                .as_deref()
                .is_some_and(|q| same_dir(q, &parent))
            {
                return false;
            }
        }
        true
    }

    /// Every candidate under the folder with its stamp, sorted by path.
    pub(super) fn list(&self) -> std::io::Result<Vec<(PathBuf, Stamp)>> {
        list_candidates(
            &self.dir,
            self.recursive,
            &self.ignore,
            self.quarantine.as_deref(),
        )
    }
}

/// The size and modification time of a regular file; for a folder, the
/// total size and latest modification time of its slices (a new or
/// growing slice changes it). `None` when it is gone, neither, or a
/// folder without slices.
pub(super) fn stamp_of(path: &Path) -> Option<Stamp> {
    let meta = std::fs::metadata(path).ok()?;
    if meta.is_dir() {
        return folder_stamp(path);
    }
    meta.is_file().then(|| Stamp {
        size: meta.len(),
        mtime: meta.modified().ok(),
    })
}

/// The stamp of a slice folder: total bytes and latest modification time
/// of its slices; `None` without slices.
fn folder_stamp(dir: &Path) -> Option<Stamp> {
    let slices = morphoid_data::volume::slice_paths(dir).ok()?;
    if slices.is_empty() {
        return None;
    }
    let mut stamp = Stamp {
        size: 0,
        mtime: None,
    };
    for p in &slices {
        // A slice gone between listing and stat is a change in progress:
        // counted as empty, the next look sees the difference.
        if let Ok(meta) = std::fs::metadata(p) {
            stamp.size += meta.len();
            stamp.mtime = stamp.mtime.max(meta.modified().ok());
        }
    }
    Some(stamp)
}

/// Whether `path` names a file morphoid reads as a scan: a surface format
/// or a single-file volume (NRRD, NIfTI), by extension.
fn is_scan_file(path: &Path) -> bool {
    Format::from_path(path).is_some()
        || (morphoid_data::volume::is_volume_path(path) && !path.is_dir())
}

/// Every non-ignored surface file (a format morphoid reads, by extension)
/// under `dir`, recursively if asked, with its stamp; `skip` (the
/// quarantine folder) is not entered. Other files (the scanner's logs,
/// reports, images) are left alone rather than recorded as errors.
fn list_candidates(
    dir: &Path,
    recursive: bool,
    ignore: &[String],
    skip: Option<&Path>,
) -> std::io::Result<Vec<(PathBuf, Stamp)>> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    let mut top = true;
    while let Some(d) = stack.pop() {
        let entries = match std::fs::read_dir(&d) {
            Ok(e) => e,
            // Only the export folder itself must be readable; a subfolder
            // may vanish between listing and reading.
            Err(e) if top => return Err(e),
            Err(_) => continue,
        };
        top = false;
        for entry in entries.flatten() {
            let name = entry.file_name();
            let name = name.to_string_lossy();
            if glob::is_ignored(ignore, &name) {
                continue;
            }
            let path = entry.path();
            let Ok(meta) = std::fs::metadata(&path) else {
                continue;
            };
            if meta.is_dir() {
                if skip.is_none_or(|s| !same_dir(s, &path)) {
                    // A folder holding slices is one scan (a slice stack).
                    if let Some(stamp) = folder_stamp(&path) {
                        out.push((path.clone(), stamp));
                    }
                    if recursive {
                        stack.push(path);
                    }
                }
            } else if meta.is_file() && is_scan_file(&path) {
                let stamp = Stamp {
                    size: meta.len(),
                    mtime: meta.modified().ok(),
                };
                out.push((path, stamp));
            }
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

fn same_dir(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

/// A word of a serial trigger line that names an existing file inside the
/// export folder, as given (absolute) or relative to the folder. Paths
/// outside the folder are ignored: the trigger must not make the daemon
/// read arbitrary files.
pub(super) fn named_file(line: &str, watch_dir: &Path) -> Option<PathBuf> {
    let root = std::fs::canonicalize(watch_dir).ok()?;
    line.split_whitespace().find_map(|word| {
        let p = Path::new(word);
        let candidate = if p.is_absolute() {
            p.to_path_buf()
        } else {
            watch_dir.join(p)
        };
        let real = std::fs::canonicalize(&candidate).ok()?;
        (real.starts_with(&root) && real.is_file()).then(|| {
            // Keep the folder's own spelling, so the recorded path matches
            // what the watcher reports for the same file.
            watch_dir.join(real.strip_prefix(&root).unwrap_or(&real))
        })
    })
}

/// Why a settled file could not be queued.
#[derive(Debug, thiserror::Error)]
pub(super) enum IntakeError {
    /// The file could not be read for hashing (it may have vanished).
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The database refused the job.
    #[error("{path}: cannot queue: {source}")]
    Queue {
        /// The file.
        path: PathBuf,
        /// The store error.
        source: StoreError,
    },
}

/// What a settled file came to at intake.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) enum Taken {
    /// Complete (or its format cannot tell): its content hash and size.
    Ready(String, u64),
    /// Its own format says more is to come: why.
    Incomplete(String),
}

/// Check a settled file's completeness by its format
/// ([`morphoid_data::completeness::check_path`]) and, when nothing is missing, hash
/// it (blocking: it reads the whole file, so callers on the async thread
/// run it with `spawn_blocking`).
pub(super) fn take(path: &Path) -> Result<Taken, IntakeError> {
    let read_err = |source| IntakeError::Read {
        path: path.to_path_buf(),
        source,
    };
    match morphoid_data::completeness::check_path(path).map_err(read_err)? {
        Verdict::Incomplete(problem) => Ok(Taken::Incomplete(problem)),
        Verdict::Complete | Verdict::Unknown => {
            let (hash, size) = self::hash(path)?;
            Ok(Taken::Ready(hash, size))
        }
    }
}

/// Hash a settled file (blocking: it reads the whole file, so callers on
/// the async thread run it with `spawn_blocking`).
pub(super) fn hash(path: &Path) -> Result<(String, u64), IntakeError> {
    content_hash_file(path).map_err(|source| IntakeError::Read {
        path: path.to_path_buf(),
        source,
    })
}

/// Queue a hashed file: a new scan, nothing when the file is already
/// recorded, or a `duplicate` row (with an INFO line naming the earlier
/// scan) when its content is another file's. Returns what the store did.
pub(super) fn enqueue(
    store: &mut Store,
    path: &Path,
    hash: &str,
    size: u64,
) -> Result<Enqueued, IntakeError> {
    let queued = store
        .enqueue(&path.display().to_string(), hash, size)
        .map_err(|source| IntakeError::Queue {
            path: path.to_path_buf(),
            source,
        })?;
    match queued {
        Enqueued::New(id) => tracing::debug!("{}: queued as scan {id}", path.display()),
        Enqueued::Existing(id, status) => tracing::debug!(
            "{}: already recorded as scan {id} ({})",
            path.display(),
            status.as_str()
        ),
        Enqueued::Duplicate { id, of } => {
            let earlier = store
                .scan(of, 0)
                .ok()
                .flatten()
                .map(|r| r.path)
                .unwrap_or_default();
            tracing::info!(
                "{}: same content as scan {of} ({earlier}); recorded as scan {id}, a duplicate",
                path.display()
            );
        }
    }
    Ok(queued)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candidates_are_surface_files_inside_the_folder() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().to_path_buf();
        let f = Filter {
            dir: root.clone(),
            recursive: true,
            ignore: vec!["*.part".into(), ".*".into()],
            quarantine: Some(root.join("q")),
        };
        std::fs::create_dir_all(root.join("q")).unwrap();
        assert!(f.is_candidate(&root.join("a.ply")));
        assert!(f.is_candidate(&root.join("sub/a.OBJ")));
        assert!(!f.is_candidate(&root.join("a.part")));
        assert!(!f.is_candidate(&root.join("a.txt")));
        assert!(!f.is_candidate(&root.join(".hidden/a.ply")));
        assert!(!f.is_candidate(&root.join("q/a.ply")));
        assert!(!f.is_candidate(Path::new("/elsewhere/a.ply")));
        let flat = Filter {
            recursive: false,
            ..f.clone()
        };
        assert!(!flat.is_candidate(&root.join("sub/a.ply")));

        std::fs::write(root.join("in.ply"), b"x").unwrap();
        let outside = tempfile::tempdir().unwrap();
        std::fs::write(outside.path().join("out.ply"), b"x").unwrap();
        assert_eq!(
            named_file("SCAN DONE in.ply", &root),
            Some(root.join("in.ply"))
        );
        let line = format!("SCAN DONE {}", outside.path().join("out.ply").display());
        assert_eq!(named_file(&line, &root), None);
        assert_eq!(named_file("SCAN DONE ../x.ply", &root), None);
    }
}
