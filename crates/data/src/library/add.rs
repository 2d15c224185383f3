//! Growing a library by one reference: a scan's original file copied into
//! the folder beside the other surfaces and a row appended to
//! `labels.csv`, each written atomically (`atomic_write`), so a reader —
//! the daemon reloading, `library build`, a person — sees the folder before
//! or after, never half a file. A folder edited by hand keeps working: the
//! layout (surfaces directly or under `meshes/`) and the columns of
//! `labels.csv` are taken as they are.

use super::{Library, LibraryError};
use crate::atomic_write::{write_atomic, AtomicWriteError};
use crate::hash::content_hash;
use crate::mesh_io::Format;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A reference to add.
#[derive(Debug, Clone)]
pub struct NewReference<'a> {
    /// Its name (the file stem and the `name` column).
    pub name: &'a str,
    /// The surface file to copy.
    pub source: &'a Path,
    /// The SHA-256 the file must still have (the content identified).
    pub content_hash: &'a str,
    /// Its taxon per rank; the columns it lacks get `NA`.
    pub taxa: &'a BTreeMap<String, String>,
}

/// Why a reference was not added.
#[derive(Debug, thiserror::Error)]
pub enum AddError {
    /// The library folder is not usable as it is.
    #[error(transparent)]
    Library(#[from] LibraryError),
    /// The name is empty, too long or not a plain file stem.
    #[error("{0:?} is not a valid reference name (letters, digits, '.', '_', '-'; at most 100)")]
    InvalidName(String),
    /// The library holds that name already.
    #[error("the library has a reference {0:?} already")]
    Exists(String),
    /// The file is not a surface (a slice folder or volume cannot be a
    /// reference).
    #[error("{} is not a surface file (.ply, .obj, .stl, .off); only surfaces become references", .0.display())]
    NotASurface(PathBuf),
    /// The file cannot be read.
    #[error("cannot read {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file holds other content than the one identified.
    #[error("{} changed since it was identified (its content is not the one reviewed)", .0.display())]
    Changed(PathBuf),
    /// `labels.csv` cannot be read or parsed.
    #[error("{}: {message}", path.display())]
    Labels {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A file could not be written.
    #[error(transparent)]
    Write(#[from] AtomicWriteError),
    /// The library's lock file cannot be made or locked.
    #[error("{}: cannot lock the library for the addition", path.display())]
    Lock {
        /// The lock file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

/// The file whose exclusive lock serialises additions to one library.
const LABELS_LOCK: &str = ".labels.lock";

/// Whether `name` can name a reference: a plain file stem.
pub(crate) fn valid_reference_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 100
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-'))
}

/// A reference name made from a scan's file name (its stem, other
/// characters as `_`).
pub fn reference_name_for(path: &str) -> String {
    let file = path.rsplit(['/', '\\']).next().unwrap_or(path);
    let stem = Path::new(file)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or(file);
    let name: String = stem
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-') {
                c
            } else {
                '_'
            }
        })
        .take(100)
        .collect();
    name.trim_start_matches('.').to_string()
}

/// Add `new` to the library at `dir` (`ranks` as for [`Library::open`]):
/// the surface copied next to the others as `<name>.<ext>`, then its row
/// appended to `labels.csv`. Returns the new surface file. When the row
/// cannot be written, the copied surface is removed again.
///
/// Two additions at once (the console and `morphoid library add`, or two
/// curators) take turns on an exclusive lock of `.labels.lock` in the
/// folder, held from reading `labels.csv` to writing it: each sees the
/// other's row, and none is lost.
pub fn add_reference(
    dir: &Path,
    ranks: Option<&[String]>,
    new: &NewReference<'_>,
) -> Result<PathBuf, AddError> {
    if !valid_reference_name(new.name) {
        return Err(AddError::InvalidName(new.name.to_string()));
    }
    let lock_path = dir.join(LABELS_LOCK);
    let lock_error = |source| AddError::Lock {
        path: lock_path.clone(),
        source,
    };
    let lock = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .map_err(lock_error)?;
    // Released when `lock` is dropped, also on every early return.
    lock.lock().map_err(lock_error)?;
    let library = Library::open(dir, ranks)?;
    if library.labels().contains(new.name) {
        return Err(AddError::Exists(new.name.to_string()));
    }
    let format = Format::from_path(new.source)
        .filter(|_| new.source.is_file())
        .ok_or_else(|| AddError::NotASurface(new.source.to_path_buf()))?;
    let bytes = std::fs::read(new.source).map_err(|source| AddError::Read {
        path: new.source.to_path_buf(),
        source,
    })?;
    if content_hash(&bytes) != new.content_hash {
        return Err(AddError::Changed(new.source.to_path_buf()));
    }
    // Beside the other surfaces (the folder itself, or its `meshes/`).
    let folder = library
        .members()
        .first()
        .and_then(|m| m.path().parent())
        .unwrap_or(dir)
        .to_path_buf();
    let extension = match format {
        Format::Obj => "obj",
        Format::Ply => "ply",
        Format::Stl => "stl",
        Format::Off => "off",
    };
    let surface = folder.join(format!("{}.{extension}", new.name));
    if surface.exists() {
        return Err(AddError::Exists(new.name.to_string()));
    }
    let labels_path = dir.join("labels.csv");
    let labels_text = labels_with_row(&labels_path, new.name, new.taxa)?;
    write_atomic(&surface, &bytes)?;
    if let Err(e) = write_atomic(&labels_path, labels_text.as_bytes()) {
        let _ = std::fs::remove_file(&surface);
        return Err(e.into());
    }
    Ok(surface)
}

/// The text of `labels.csv` with a row for `name` appended: its taxa
/// under their columns, `NA` under the others.
fn labels_with_row(
    path: &Path,
    name: &str,
    taxa: &BTreeMap<String, String>,
) -> Result<String, AddError> {
    let bad = |message: String| AddError::Labels {
        path: path.to_path_buf(),
        message,
    };
    let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .from_reader(text.as_bytes());
    let header: Vec<String> = reader
        .headers()
        .map_err(|e| bad(e.to_string()))?
        .iter()
        .map(|h| h.trim().to_string())
        .collect();
    if let Some(rank) = taxa.keys().find(|r| !header.contains(r)) {
        return Err(bad(format!(
            "no column `{rank}` for the new reference's taxon"
        )));
    }
    let row: Vec<&str> = header
        .iter()
        .map(|column| match column.as_str() {
            "name" => name,
            rank => taxa.get(rank).map_or("NA", String::as_str),
        })
        .collect();
    let mut writer = csv::WriterBuilder::new()
        .terminator(csv::Terminator::Any(b'\n'))
        .from_writer(Vec::new());
    writer.write_record(&row).map_err(|e| bad(e.to_string()))?;
    let line = writer.into_inner().map_err(|e| bad(e.to_string()))?;
    let mut out = text;
    if !out.is_empty() && !out.ends_with('\n') {
        out.push('\n');
    }
    out.push_str(&String::from_utf8_lossy(&line));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eight additions at once, each on its own open file as separate
    /// processes would have: every row and every surface is there.
    #[test]
    fn concurrent_additions_lose_no_row() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("labels.csv"),
            "name,order,genus\nfirst,O,G\n",
        )
        .unwrap();
        std::fs::write(dir.path().join("first.ply"), b"ply\n").unwrap();
        let sources = tempfile::tempdir().unwrap();
        std::thread::scope(|scope| {
            for i in 0..8 {
                let (dir, sources) = (dir.path(), sources.path());
                scope.spawn(move || {
                    let source = sources.join(format!("s{i}.ply"));
                    let bytes = format!("ply\n{i}\n");
                    std::fs::write(&source, &bytes).unwrap();
                    let taxa = BTreeMap::from([("genus".to_string(), format!("G{i}"))]);
                    let hash = content_hash(bytes.as_bytes());
                    let new = NewReference {
                        name: &format!("added{i}"),
                        source: &source,
                        content_hash: &hash,
                        taxa: &taxa,
                    };
                    add_reference(dir, None, &new).unwrap();
                });
            }
        });
        let library = Library::open(dir.path(), None).unwrap();
        assert_eq!(library.members().len(), 9);
        for i in 0..8 {
            let name = format!("added{i}");
            assert_eq!(
                library.labels().get(&name, "genus"),
                Some(format!("G{i}").as_str())
            );
            assert_eq!(library.labels().get(&name, "order"), None);
        }
    }

    #[test]
    fn names_come_from_file_names() {
        assert_eq!(reference_name_for("export/a b/x#1.ply"), "x_1");
        assert_eq!(reference_name_for("scan.stl"), "scan");
        assert!(valid_reference_name("ateles-12.v2"));
        for bad in ["", ".hidden", "a/b", "a b", &"x".repeat(101)] {
            assert!(!valid_reference_name(bad), "{bad:?}");
        }
    }
}
