//! Landmarks: named points on a surface, their file formats, and their
//! propagation from one surface to another through cP correspondences
//! (the paper's Figures 2 and 3).
//!
//! Formats, chosen by file extension ([`Format::from_path`]):
//! - `.csv`: `x,y,z` per line, optional header, optional `label` column;
//! - `.fcsv`: 3D Slicer markups fiducial CSV;
//! - `.mrk.json` (or `.json`): 3D Slicer markups JSON;
//! - `.pp`: MeshLab picked points (XML);
//! - `.tps`: TPS (geomorph, MorphoJ), `SCALE=` applied;
//! - morphologika (`.txt` whose first line is a `[section]`).
//!
//! TPS and morphologika files hold a collection ([`read_collection`],
//! [`write_collection`]); read as one specimen's file they must hold one.
//!
//! **Coordinate convention.** A [`Landmarks`] value holds points in the
//! coordinates of the surface file they belong to. Slicer writes surface
//! files (and, since version 4.11, markups) in LPS coordinates, so the
//! in-memory coordinates are taken to be **LPS**: a Slicer file declared
//! in RAS is converted on reading by `(x, y, z) → (−x, −y, z)`, and the
//! Slicer writers always declare LPS. Plain CSV and MeshLab files carry no
//! convention and are read and written unchanged.

mod chain;
mod matrix;
mod meshlab;
mod morphologika;
mod mst;
mod procrustes;
mod propagate;
mod slicer;
mod table;
mod tps;

pub use chain::{
    carry_along, complete_distances, correspondence_csv, far_landmarks, spanning_tree_route,
    with_ends, Carried, Specimens,
};
pub use matrix::procrustes_matrix;
pub(crate) use morphologika::is_morphologika;
pub use morphologika::{format_morphologika, parse_morphologika};
pub use mst::minimum_spanning_tree;
pub(crate) use mst::tree_path;
pub use procrustes::procrustes_distance;
pub(crate) use procrustes::ProcrustesError;
pub(crate) use propagate::Propagated;
pub use propagate::{propagate, propagate_along, surface_point, PropagateError, Surface};
pub use tps::{format_tps, parse_tps, NamedLandmarks};

use std::path::{Path, PathBuf};

/// Landmark points with optional labels (same length).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Landmarks {
    /// Positions, in the units and coordinates of their surface file.
    points: Vec<[f64; 3]>,
    /// One optional label per point; an empty label is stored as `None`.
    labels: Vec<Option<String>>,
}

impl Landmarks {
    /// Unlabelled landmarks.
    pub fn from_points(points: Vec<[f64; 3]>) -> Self {
        let labels = vec![None; points.len()];
        Self { points, labels }
    }

    /// Labelled landmarks: one label per point (an empty label counts as
    /// none); `None` when the lengths differ.
    pub fn with_labels(points: Vec<[f64; 3]>, labels: Vec<Option<String>>) -> Option<Self> {
        (points.len() == labels.len()).then(|| Self {
            points,
            labels: labels
                .into_iter()
                .map(|l| l.filter(|l| !l.is_empty()))
                .collect(),
        })
    }

    /// The positions, in the units and coordinates of their surface file.
    pub fn points(&self) -> &[[f64; 3]] {
        &self.points
    }

    /// One optional label per point.
    pub fn labels(&self) -> &[Option<String>] {
        &self.labels
    }

    /// Number of landmarks.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there is no landmark.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The label of landmark `i`, if any.
    pub fn label(&self, i: usize) -> Option<&str> {
        self.labels.get(i).and_then(|l| l.as_deref())
    }

    /// Whether any landmark has a label.
    pub fn has_labels(&self) -> bool {
        self.labels.iter().any(|l| l.is_some())
    }

    /// Add one landmark; an empty label counts as none.
    pub fn push(&mut self, point: [f64; 3], label: Option<String>) {
        self.points.push(point);
        self.labels.push(label.filter(|l| !l.is_empty()));
    }
}

/// Landmark file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Plain CSV, `x,y,z[,label]`.
    Csv,
    /// 3D Slicer markups fiducial CSV (`.fcsv`).
    Fcsv,
    /// 3D Slicer markups JSON (`.mrk.json`).
    MarkupsJson,
    /// MeshLab picked points (`.pp`).
    PickedPoints,
    /// TPS (`.tps`).
    Tps,
    /// Morphologika (a `.txt` starting with a `[section]`; see
    /// [`Format::from_path_and_text`]).
    Morphologika,
}

impl Format {
    /// The format named by the extension of `path` (case-insensitive).
    pub fn from_path(path: &Path) -> Option<Format> {
        let name = path.file_name()?.to_string_lossy().to_ascii_lowercase();
        let ext = name.rsplit_once('.').map(|(_, e)| e)?;
        match ext {
            "csv" | "txt" => Some(Format::Csv),
            "fcsv" => Some(Format::Fcsv),
            "json" => Some(Format::MarkupsJson),
            "pp" => Some(Format::PickedPoints),
            "tps" => Some(Format::Tps),
            _ => None,
        }
    }

    /// The format of a file from its extension and, for `.txt`, its text:
    /// morphologika when it starts with a `[section]`, else CSV.
    fn from_path_and_text(path: &Path, text: &str) -> Option<Format> {
        let fmt = Format::from_path(path)?;
        let txt = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("txt"));
        Some(if txt && is_morphologika(text) {
            Format::Morphologika
        } else {
            fmt
        })
    }
}

/// Why a landmark file cannot be read or written; every message names the
/// file and, for content errors, the line (or the JSON element).
#[derive(Debug, thiserror::Error)]
pub enum LandmarkError {
    /// The file cannot be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file cannot be written (the error names it and the step).
    #[error(transparent)]
    Write(#[from] crate::atomic_write::AtomicWriteError),
    /// The extension names no landmark format.
    #[error(
        "{0}: unknown landmark format (use .csv, .fcsv, .mrk.json, .pp, .tps or morphologika .txt)"
    )]
    UnknownFormat(PathBuf),
    /// Malformed content at a line.
    #[error("{path}:{line}: {message}")]
    Syntax {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A record the CSV reader cannot read.
    #[error("{path}:{line}: {source}")]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line number of the record.
        line: usize,
        /// The reader's error.
        source: crate::table::csv_text::RowError,
    },
    /// A coordinate (or a line of `x y z`) that cannot be read, at a line.
    #[error("{path}:{line}: {source}")]
    Coordinate {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with the value.
        source: CoordinateError,
    },
    /// A TPS `SCALE=` value that cannot be read, at a line.
    #[error("{path}:{line}: SCALE: {source}")]
    Scale {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with the value.
        source: CoordinateError,
    },
    /// Malformed content at an element of a JSON document.
    #[error("{path}: {element}: {message}")]
    Element {
        /// The file.
        path: PathBuf,
        /// Where in the document, e.g. `markups[0].controlPoints[3]`.
        element: String,
        /// What is wrong.
        message: String,
    },
    /// The file holds no landmark.
    #[error("{0}: no landmarks in the file")]
    Empty(PathBuf),
    /// The file holds another number of landmarks than expected.
    #[error("{path}: {found} landmarks, expected {expected}")]
    Count {
        /// The file.
        path: PathBuf,
        /// The number asked for.
        expected: usize,
        /// The number in the file.
        found: usize,
    },
}

/// Parse landmark text in `format`; `path` only names the source in errors.
/// A file without any landmark is an error.
pub fn parse(text: &str, format: Format, path: &Path) -> Result<Landmarks, LandmarkError> {
    let lm = match format {
        Format::Csv => table::parse_csv(text, path)?,
        Format::Fcsv => slicer::parse_fcsv(text, path)?,
        Format::MarkupsJson => slicer::parse_markups_json(text, path)?,
        Format::PickedPoints => meshlab::parse_picked_points(text, path)?,
        Format::Tps | Format::Morphologika => {
            let mut all = parse_collection(text, format, path)?;
            if all.len() != 1 {
                return Err(LandmarkError::Syntax {
                    path: path.to_path_buf(),
                    line: 1,
                    message: format!(
                        "{} specimens in the file; one specimen's landmarks were expected",
                        all.len()
                    ),
                });
            }
            all.remove(0).landmarks
        }
    };
    if lm.is_empty() {
        return Err(LandmarkError::Empty(path.to_path_buf()));
    }
    Ok(lm)
}

/// The text of `landmarks` in `format`.
pub fn format(landmarks: &Landmarks, format: Format) -> String {
    match format {
        Format::Csv => table::format_csv(landmarks),
        Format::Fcsv => slicer::format_fcsv(landmarks),
        Format::MarkupsJson => slicer::format_markups_json(landmarks),
        Format::PickedPoints => meshlab::format_picked_points(landmarks),
        Format::Tps | Format::Morphologika => {
            let one = [NamedLandmarks {
                name: "specimen".into(),
                landmarks: landmarks.clone(),
            }];
            if format == Format::Tps {
                format_tps(&one)
            } else {
                format_morphologika(&one)
            }
        }
    }
}

/// Parse a collection file (TPS or morphologika; any other format is read
/// as one specimen named `specimen`).
fn parse_collection(
    text: &str,
    format: Format,
    path: &Path,
) -> Result<Vec<NamedLandmarks>, LandmarkError> {
    match format {
        Format::Tps => parse_tps(text, path),
        Format::Morphologika => parse_morphologika(text, path),
        other => Ok(vec![NamedLandmarks {
            name: "specimen".into(),
            landmarks: parse(text, other, path)?,
        }]),
    }
}

/// Read a collection of named landmark sets from a TPS (`.tps`) or
/// morphologika (`.txt`) file.
pub fn read_collection(path: &Path) -> Result<Vec<NamedLandmarks>, LandmarkError> {
    let text = std::fs::read_to_string(path).map_err(|source| LandmarkError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    match Format::from_path_and_text(path, &text) {
        Some(f @ (Format::Tps | Format::Morphologika)) => parse_collection(&text, f, path),
        _ => Err(LandmarkError::UnknownFormat(path.to_path_buf())),
    }
}

/// Write a collection as TPS (`.tps`) or morphologika (`.txt`), through
/// an atomic replacement.
pub fn write_collection(path: &Path, specimens: &[NamedLandmarks]) -> Result<(), LandmarkError> {
    let text = match Format::from_path(path) {
        Some(Format::Tps) => format_tps(specimens),
        Some(Format::Csv)
            if path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("txt")) =>
        {
            format_morphologika(specimens)
        }
        _ => return Err(LandmarkError::UnknownFormat(path.to_path_buf())),
    };
    write_text(path, &text)
}

/// Replace `path` with `text` atomically.
fn write_text(path: &Path, text: &str) -> Result<(), LandmarkError> {
    Ok(crate::atomic_write::write_atomic(path, text.as_bytes())?)
}

/// Read a landmark file, in the format its extension names; with
/// `expected`, a file with another number of landmarks is an error.
pub fn read(path: &Path, expected: Option<usize>) -> Result<Landmarks, LandmarkError> {
    let fmt = Format::from_path(path).ok_or_else(|| LandmarkError::UnknownFormat(path.into()))?;
    let text = std::fs::read_to_string(path).map_err(|source| LandmarkError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let fmt = Format::from_path_and_text(path, &text).unwrap_or(fmt);
    let lm = parse(&text, fmt, path)?;
    check_count(&lm, expected, path)?;
    Ok(lm)
}

/// Error unless `landmarks` has `expected` points (when given).
fn check_count(
    landmarks: &Landmarks,
    expected: Option<usize>,
    path: &Path,
) -> Result<(), LandmarkError> {
    match expected {
        Some(n) if n != landmarks.len() => Err(LandmarkError::Count {
            path: path.to_path_buf(),
            expected: n,
            found: landmarks.len(),
        }),
        _ => Ok(()),
    }
}

/// Write a landmark file in the format its extension names, whole or not
/// at all.
pub fn write(path: &Path, landmarks: &Landmarks) -> Result<(), LandmarkError> {
    let fmt = Format::from_path(path).ok_or_else(|| LandmarkError::UnknownFormat(path.into()))?;
    write_text(path, &format(landmarks, fmt))
}

/// The extensions a library's landmark file may have, in the order they
/// are looked for: `landmarks/<name>.{csv,fcsv,mrk.json,pp,tps}`.
const LIBRARY_EXTENSIONS: [&str; 5] = ["csv", "fcsv", "mrk.json", "pp", "tps"];

/// The landmark files of specimen `name` in the library folder `dir`
/// (`dir/landmarks/<name>.<ext>` for each of `csv`, `fcsv`, `mrk.json`, `pp` that
/// exists). More than one is ambiguous; the caller reports it.
pub fn library_files(dir: &Path, name: &str) -> Vec<PathBuf> {
    let folder = dir.join("landmarks");
    // Most libraries have no landmarks: one look, not one per format.
    if !folder.is_dir() {
        return Vec::new();
    }
    LIBRARY_EXTENSIONS
        .iter()
        .map(|ext| folder.join(format!("{name}.{ext}")))
        .filter(|p| p.is_file())
        .collect()
}

/// Why a library specimen's landmark file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum LandmarkProblem {
    /// The file cannot be read or parsed.
    #[error(transparent)]
    Unreadable(LandmarkError),
    /// Several files hold the specimen's landmarks.
    #[error("{}: more than one landmark file for `{name}`; keep one", display_paths(.files))]
    Ambiguous {
        /// The specimen.
        name: String,
        /// Its landmark files.
        files: Vec<PathBuf>,
    },
    /// The file holds another number of landmarks than the library's other
    /// files.
    #[error("{0} (the library's other landmark files)")]
    Count(LandmarkError),
}

fn display_paths(files: &[PathBuf]) -> String {
    let list: Vec<String> = files.iter().map(|p| p.display().to_string()).collect();
    list.join(" and ")
}

/// The landmarks of a library's specimens, and why some could not be used.
#[derive(Debug, Default)]
pub struct LibraryLandmarks {
    /// Usable landmarks, by specimen name.
    by_name: std::collections::BTreeMap<String, Landmarks>,
    /// Specimens whose landmark file could not be used, by name (sorted).
    problems: Vec<(String, LandmarkProblem)>,
    /// The number of landmarks per specimen (the most common count among
    /// the readable files; on a tie, the larger).
    count: Option<usize>,
}

impl LibraryLandmarks {
    /// Usable landmarks, by specimen name.
    pub fn by_name(&self) -> &std::collections::BTreeMap<String, Landmarks> {
        &self.by_name
    }

    /// Specimens whose landmark file could not be used, by name (sorted).
    pub fn problems(&self) -> &[(String, LandmarkProblem)] {
        &self.problems
    }

    /// The number of landmarks per specimen (the most common count among
    /// the readable files; on a tie, the larger).
    pub fn count(&self) -> Option<usize> {
        self.count
    }

    /// Move out the usable landmarks, leaving the problems and the count.
    pub fn take_by_name(&mut self) -> std::collections::BTreeMap<String, Landmarks> {
        std::mem::take(&mut self.by_name)
    }
}

/// Read the landmark files of the specimens `names` of the library folder
/// `dir`. Each specimen is handled on its own: two files for one name, an
/// unreadable file or one with another number of landmarks than the
/// library's count is reported in `problems` and the others are kept.
pub fn load_library(dir: &Path, names: &[String]) -> LibraryLandmarks {
    let mut out = LibraryLandmarks::default();
    let mut read_ok: Vec<(String, PathBuf, Landmarks)> = Vec::new();
    for name in names {
        let files = library_files(dir, name);
        match files.as_slice() {
            [] => {}
            [path] => match read(path, None) {
                Ok(lm) => read_ok.push((name.clone(), path.clone(), lm)),
                Err(e) => out
                    .problems
                    .push((name.clone(), LandmarkProblem::Unreadable(e))),
            },
            several => out.problems.push((
                name.clone(),
                LandmarkProblem::Ambiguous {
                    name: name.clone(),
                    files: several.to_vec(),
                },
            )),
        }
    }
    let mut tally: std::collections::BTreeMap<usize, usize> = Default::default();
    for (_, _, lm) in &read_ok {
        *tally.entry(lm.len()).or_default() += 1;
    }
    out.count = tally
        .iter()
        .max_by_key(|&(&count, &n)| (n, count))
        .map(|(&count, _)| count);
    for (name, path, lm) in read_ok {
        match check_count(&lm, out.count, &path) {
            Ok(()) => {
                out.by_name.insert(name, lm);
            }
            Err(e) => out.problems.push((name, LandmarkProblem::Count(e))),
        }
    }
    out.problems.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// The non-blank lines of a collection file, trimmed (a byte-order mark
/// dropped), with their 1-based numbers.
fn content_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(k, raw)| (k + 1, raw.trim().trim_start_matches('\u{feff}')))
        .filter(|(_, t)| !t.is_empty())
}

/// Why a landmark coordinate, or a line of `x y z`, cannot be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CoordinateError {
    /// The text is not a number.
    #[error("`{text}` is not a number")]
    NotANumber {
        /// The text (trimmed).
        text: String,
    },
    /// The number is infinite or NaN.
    #[error("coordinate `{text}` is not finite")]
    NotFinite {
        /// The text (trimmed).
        text: String,
    },
    /// A line of `x y z` holds another number of values.
    #[error("{found} values; a 3D landmark has 3")]
    ValueCount {
        /// The number of values on the line.
        found: usize,
    },
}

/// The error for a record of the file `path` that the CSV reader cannot
/// read.
fn csv_error(path: &Path, source: crate::table::csv_text::RowError) -> LandmarkError {
    LandmarkError::Csv {
        path: path.to_path_buf(),
        line: source.line,
        source,
    }
}

/// The error for the coordinate error `source` at line `line` (1-based)
/// of the file `path`.
fn coordinate_error(path: &Path, line: usize, source: CoordinateError) -> LandmarkError {
    LandmarkError::Coordinate {
        path: path.to_path_buf(),
        line,
        source,
    }
}

/// One landmark written as `x y z` (whitespace-separated).
fn parse_xyz(line: &str) -> Result<[f64; 3], CoordinateError> {
    let fields: Vec<&str> = line.split_whitespace().collect();
    if fields.len() != 3 {
        return Err(CoordinateError::ValueCount {
            found: fields.len(),
        });
    }
    let mut q = [0.0; 3];
    for (d, f) in fields.iter().enumerate() {
        q[d] = parse_coordinate(f)?;
    }
    Ok(q)
}

/// The `x y z` line of one landmark, each value in the shortest form that
/// reads back exactly.
fn xyz_line(p: &[f64; 3]) -> String {
    format!("{:?} {:?} {:?}\n", p[0], p[1], p[2])
}

/// Parse one coordinate; non-finite values are rejected.
fn parse_coordinate(field: &str) -> Result<f64, CoordinateError> {
    let t = field.trim();
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(CoordinateError::NotFinite {
            text: t.to_string(),
        }),
        Err(_) => Err(CoordinateError::NotANumber {
            text: t.to_string(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Landmarks with awkward labels and values that test exact round trips.
    pub(super) fn sample() -> Landmarks {
        let mut lm = Landmarks::default();
        lm.push(
            [0.1, -2.5e-7, 1234.5678901234567],
            Some("protoconid".into()),
        );
        lm.push([-0.0, 3.0, 1.0 / 3.0], None);
        lm.push([1e10, -7.25, 0.2], Some("cusp, \"distal\" <&> 'x'".into()));
        lm
    }

    #[test]
    fn every_format_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let lm = sample();
        for name in ["a.csv", "a.fcsv", "a.mrk.json", "a.pp"] {
            let path = dir.path().join(name);
            write(&path, &lm).unwrap();
            let back = read(&path, Some(3)).unwrap();
            assert_eq!(back, lm, "{name}");
        }
        let unlabelled = Landmarks::from_points(vec![[1.0, 2.0, 3.0], [4.0, 5.5, 6.0]]);
        for name in ["b.csv", "b.fcsv", "b.mrk.json", "b.pp"] {
            let path = dir.path().join(name);
            write(&path, &unlabelled).unwrap();
            assert_eq!(read(&path, None).unwrap(), unlabelled, "{name}");
        }
    }

    #[test]
    fn wrong_count_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["c.csv", "c.fcsv", "c.mrk.json", "c.pp"] {
            let path = dir.path().join(name);
            write(&path, &sample()).unwrap();
            let e = read(&path, Some(4)).unwrap_err();
            assert!(matches!(
                e,
                LandmarkError::Count {
                    expected: 4,
                    found: 3,
                    ..
                }
            ));
            let msg = e.to_string();
            assert!(
                msg.contains(name) && msg.contains("3 landmarks, expected 4"),
                "{msg}"
            );
        }
    }

    #[test]
    fn garbage_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        for (name, text) in [
            ("g.csv", "\u{0}\u{1}garbage\n"),
            ("g.fcsv", "hello world\n"),
            ("g.mrk.json", "{ not json"),
            ("g.pp", "<PickedPoints><point x=\"1\" y=</PickedPoints>"),
            ("e.csv", ""),
            ("e.pp", "<PickedPoints></PickedPoints>"),
        ] {
            let path = dir.path().join(name);
            std::fs::write(&path, text).unwrap();
            let msg = read(&path, None).unwrap_err().to_string();
            assert!(msg.contains(name), "{msg}");
        }
        assert!(matches!(
            read(&dir.path().join("x.obj"), None),
            Err(LandmarkError::UnknownFormat(_))
        ));
        assert!(matches!(
            read(&dir.path().join("missing.csv"), None),
            Err(LandmarkError::Io { .. })
        ));
    }

    #[test]
    fn library_files_any_format_with_problems_per_specimen() {
        let dir = tempfile::tempdir().unwrap();
        let lm_dir = dir.path().join("landmarks");
        std::fs::create_dir(&lm_dir).unwrap();
        write(&lm_dir.join("a.fcsv"), &sample()).unwrap();
        write(&lm_dir.join("b.mrk.json"), &sample()).unwrap();
        write(&lm_dir.join("c.pp"), &sample()).unwrap();
        write(&lm_dir.join("c.csv"), &sample()).unwrap();
        std::fs::write(lm_dir.join("d.csv"), "1,2,3\nnot,a,number\n").unwrap();
        let mut short = sample();
        short.points.pop();
        short.labels.pop();
        write(&lm_dir.join("e.pp"), &short).unwrap();
        let names: Vec<String> = ["a", "b", "c", "d", "e", "f"].map(String::from).to_vec();
        let got = load_library(dir.path(), &names);
        assert_eq!(got.count, Some(3));
        assert_eq!(got.by_name.keys().collect::<Vec<_>>(), ["a", "b"]);
        assert_eq!(got.by_name["b"], sample());
        let problems: Vec<&str> = got.problems.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(problems, ["c", "d", "e"]);
        assert!(matches!(
            &got.problems[0].1,
            LandmarkProblem::Ambiguous { name, files } if name == "c" && files.len() == 2
        ));
        assert!(matches!(
            &got.problems[1].1,
            LandmarkProblem::Unreadable(LandmarkError::Coordinate {
                line: 2,
                source: CoordinateError::NotANumber { .. },
                ..
            })
        ));
        let why = got.problems[1].1.to_string();
        assert!(why.contains("d.csv:2"), "{why}");
        assert!(matches!(
            &got.problems[2].1,
            LandmarkProblem::Count(LandmarkError::Count {
                found: 2,
                expected: 3,
                ..
            })
        ));
        let why = got.problems[0].1.to_string();
        assert!(why.contains("more than one landmark file"), "{why}");
    }

    #[test]
    fn coordinate_errors_are_typed_and_read_as_before() {
        assert_eq!(
            parse_coordinate(" x1 ").unwrap_err(),
            CoordinateError::NotANumber { text: "x1".into() }
        );
        assert_eq!(
            parse_coordinate("inf").unwrap_err().to_string(),
            "coordinate `inf` is not finite"
        );
        assert_eq!(
            parse_coordinate("oops").unwrap_err().to_string(),
            "`oops` is not a number"
        );
        assert_eq!(
            parse_xyz("1 2").unwrap_err().to_string(),
            "2 values; a 3D landmark has 3"
        );
        let path = Path::new("t.tps");
        let e = parse("LM3=1\n1 2 3\nSCALE=x\nID=a\n", Format::Tps, path).unwrap_err();
        assert_eq!(e.to_string(), "t.tps:3: SCALE: `x` is not a number");
        assert!(matches!(e, LandmarkError::Scale { line: 3, .. }), "{e:?}");
        let e = parse("LM3=1\n1 NaN 3\nID=a\n", Format::Tps, path).unwrap_err();
        assert_eq!(e.to_string(), "t.tps:2: coordinate `NaN` is not finite");
        let source = std::error::Error::source(&e).map(ToString::to_string);
        assert_eq!(source.as_deref(), Some("coordinate `NaN` is not finite"));
    }

    #[test]
    fn formats_by_extension() {
        assert_eq!(Format::from_path(Path::new("a/B.CSV")), Some(Format::Csv));
        assert_eq!(Format::from_path(Path::new("x.fcsv")), Some(Format::Fcsv));
        assert_eq!(
            Format::from_path(Path::new("x.mrk.json")),
            Some(Format::MarkupsJson)
        );
        assert_eq!(
            Format::from_path(Path::new("x.pp")),
            Some(Format::PickedPoints)
        );
        assert_eq!(Format::from_path(Path::new("x.ply")), None);
        assert_eq!(Format::from_path(Path::new("noext")), None);
    }
}
