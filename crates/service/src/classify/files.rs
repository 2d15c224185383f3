//! Result files: for each identified scan, `<name>.json` (the `classify
//! --json` line) and, when landmarks were carried onto it, `<name>.fcsv`
//! (3D Slicer markups in the scan file's coordinates), in a results
//! folder; beside them the report `<name>.html` with its thumbnail
//! `<name>.png`, and the folder's overview `index.html` (older scans on
//! `index-NNNNNN.html` pages written once).
//!
//! `<name>` is the scan's path relative to the export folder, file
//! extension included: `<export>/a/x.ply` gives `<results>/a/x.ply.json`.
//! Two different scan files thus never share a result file, whether they
//! differ in folder (`a/x.ply`, `b/x.ply`) or in format (`x.ply`,
//! `x.stl`). A scan outside the export folder (`morphoid classify` on any
//! file) is named by its path as given when that is relative and does not
//! climb out with `..`, otherwise by its absolute path.

use crate::report::{self, IndexRow, PageLink, Scene, INDEX_PAGE, INDEX_RECENT};
use crate::store::{ScanRecord, Store, StoreError};
use morphoid_data::atomic_write::{write_atomic, AtomicWriteError};
use morphoid_data::landmarks::{self, Landmarks};
use std::ffi::OsString;
use std::path::{Component, Path, PathBuf};

/// Why the result files of a scan could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ResultsError {
    /// A folder could not be created or a stale file removed.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A result file could not be written.
    #[error(transparent)]
    Write(#[from] AtomicWriteError),
    /// The scans for the overview could not be read.
    #[error("cannot read the scans for the overview: {0}")]
    Store(#[from] StoreError),
    /// The record could not be turned into JSON.
    #[error("cannot encode the result of {scan} as JSON: {source}")]
    Json {
        /// The scan.
        scan: String,
        /// serde_json's error.
        source: serde_json::Error,
    },
}

/// Where result files go and what they are named after.
#[derive(Debug, Clone, PartialEq)]
pub struct ResultFiles {
    dir: PathBuf,
    export_dir: Option<PathBuf>,
}

impl ResultFiles {
    /// Result files in `dir`, named after each scan's path relative to
    /// `export_dir` (the watched folder) when the scan lies in it.
    pub fn new(dir: PathBuf, export_dir: Option<PathBuf>) -> Self {
        ResultFiles { dir, export_dir }
    }

    /// Result files for scans given on a command line: named relative to
    /// `export_dir` when every scan lies in it, else relative to the
    /// deepest folder holding them all (a single scan: its file name), so
    /// that an absolute path is not mirrored whole under `dir`.
    pub fn for_scans(dir: PathBuf, export_dir: &Path, scans: &[PathBuf]) -> Self {
        let export = absolute_lexical(export_dir);
        let absolute: Vec<PathBuf> = scans.iter().map(|s| absolute_lexical(s)).collect();
        if absolute.iter().all(|a| a.starts_with(&export)) {
            return ResultFiles::new(dir, Some(export_dir.to_path_buf()));
        }
        let mut common: Option<PathBuf> = absolute
            .first()
            .and_then(|a| a.parent())
            .map(Path::to_path_buf);
        for a in &absolute {
            while let Some(c) = &common {
                if a.starts_with(c) && a != c {
                    break;
                }
                common = c.parent().map(Path::to_path_buf);
            }
        }
        ResultFiles::new(dir, common)
    }

    /// The results folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The name of `record`'s result files, relative to the folder.
    fn name(&self, record: &ScanRecord) -> PathBuf {
        result_name(Path::new(&record.path), self.export_dir.as_deref())
            .unwrap_or_else(|| PathBuf::from(format!("scan-{}", record.id)))
    }

    /// `<name><ext>` of `record`, relative to the folder.
    fn relative(&self, record: &ScanRecord, ext: &str) -> PathBuf {
        let mut p = OsString::from(self.name(record));
        p.push(ext);
        PathBuf::from(p)
    }

    /// The result files of `record`: `<name>.json` and `<name>.fcsv`.
    pub fn paths(&self, record: &ScanRecord) -> (PathBuf, PathBuf) {
        (
            self.dir.join(self.relative(record, ".json")),
            self.dir.join(self.relative(record, ".fcsv")),
        )
    }

    /// The report of `record` and its thumbnail: `<name>.html`, `<name>.png`.
    pub fn report_paths(&self, record: &ScanRecord) -> (PathBuf, PathBuf) {
        (
            self.dir.join(self.relative(record, ".html")),
            self.dir.join(self.relative(record, ".png")),
        )
    }

    /// The overview page, `index.html` in the folder.
    fn index_path(&self) -> PathBuf {
        self.dir.join("index.html")
    }

    /// Write the report of a recorded scan (and, with a scene, its
    /// thumbnail), folders created as needed, each file replaced
    /// atomically; `note` says on the page why something is missing.
    /// Returns the report's path.
    pub fn write_report(
        &self,
        record: &ScanRecord,
        scene: Option<&Scene>,
        note: Option<&str>,
    ) -> Result<PathBuf, ResultsError> {
        let _span = tracing::info_span!("report", scan = %record.path).entered();
        let (html_path, png_path) = self.report_paths(record);
        create_parent(&html_path)?;
        if let Some(png) = scene.and_then(|s| report::thumbnail(s).to_png()) {
            write_atomic(&png_path, &png)?;
        }
        let html = report::report_html(record, scene, note);
        write_atomic(&html_path, html.as_bytes())?;
        Ok(html_path)
    }

    /// Rewrite the overview `index.html` from the database: the most
    /// recent scans, newest first, and links to pages of older scans;
    /// an older page is written when its scans have all left the overview
    /// and it does not exist yet (not again), so the cost does not grow
    /// with the database.
    pub fn write_index(&self, store: &mut Store) -> Result<PathBuf, ResultsError> {
        let _span = tracing::info_span!("index").entered();
        std::fs::create_dir_all(&self.dir).map_err(|source| ResultsError::Io {
            path: self.dir.clone(),
            source,
        })?;
        let recent = store.recent(INDEX_RECENT)?;
        let oldest_shown = recent.last().map_or(1, |r| r.id);
        // Page k holds ids (k·P, (k+1)·P]; it is complete once all of
        // them are older than the overview's oldest scan.
        let complete_pages = (oldest_shown - 1).max(0) / INDEX_PAGE;
        let mut pages = Vec::new();
        for k in (0..complete_pages).rev() {
            let name = report::page_name(k);
            let path = self.dir.join(&name);
            if !path.exists() {
                self.write_page(store, k, &path)?;
            }
            pages.push(PageLink {
                href: report::href_of(&name),
                label: format!("scans {}–{}", k * INDEX_PAGE + 1, (k + 1) * INDEX_PAGE),
            });
        }
        let html = self.overview(&recent, "scans, newest first", &pages);
        let path = self.index_path();
        write_atomic(&path, html.as_bytes())?;
        Ok(path)
    }

    /// The older page `k` of the overview, written to `path`.
    fn write_page(&self, store: &Store, k: i64, path: &Path) -> Result<(), ResultsError> {
        let mut records = Vec::new();
        for id in ((k * INDEX_PAGE + 1)..=((k + 1) * INDEX_PAGE)).rev() {
            // A specimen's row is shown under its scan's.
            if let Some(r) = store.scan(id, crate::store::DEFAULT_NEAREST)? {
                if r.parent.is_none() {
                    records.push(r);
                }
            }
        }
        let back = [PageLink {
            href: "index.html".into(),
            label: "recent scans".into(),
        }];
        let title = format!(
            "scans {}–{}, newest first",
            k * INDEX_PAGE + 1,
            (k + 1) * INDEX_PAGE
        );
        write_atomic(path, self.overview(&records, &title, &back).as_bytes())?;
        Ok(())
    }

    /// An overview page of `records`, linking each to its report (and
    /// thumbnail, when one was written).
    fn overview(&self, records: &[ScanRecord], title: &str, pages: &[PageLink]) -> String {
        // A scan of several specimens is followed by its specimens' rows.
        let records: Vec<&ScanRecord> = records
            .iter()
            .flat_map(|r| std::iter::once(r).chain(&r.specimens))
            .collect();
        let links: Vec<(String, Option<String>)> = records
            .iter()
            .map(|r| {
                let href = |p: PathBuf| report::href_of(&p.to_string_lossy().replace('\\', "/"));
                let thumb = self.relative(r, ".png");
                let thumb = self.dir.join(&thumb).exists().then(|| href(thumb));
                (href(self.relative(r, ".html")), thumb)
            })
            .collect();
        let rows: Vec<IndexRow<'_>> = records
            .iter()
            .zip(&links)
            .map(|(record, (report, thumbnail))| IndexRow {
                record,
                report,
                thumbnail: thumbnail.as_deref(),
            })
            .collect();
        report::index_html(title, &rows, pages)
    }

    /// Write the result files of a recorded scan (folders created as
    /// needed): the JSON always, the landmarks when the scan has some; a
    /// stale `.fcsv` of an earlier result without landmarks is removed.
    /// Each file is replaced atomically. Returns the files written.
    pub fn write(&self, record: &ScanRecord) -> Result<Vec<PathBuf>, ResultsError> {
        let (json_path, fcsv_path) = self.paths(record);
        create_parent(&json_path)?;
        let mut json = serde_json::to_string(record).map_err(|source| ResultsError::Json {
            scan: record.path.clone(),
            source,
        })?;
        json.push('\n');
        write_atomic(&json_path, json.as_bytes())?;
        let mut written = vec![json_path];
        match &record.landmarks {
            Some(lm) if !lm.points.is_empty() => {
                let mut points = Landmarks::default();
                for p in &lm.points {
                    points.push([p.x, p.y, p.z], p.label.clone());
                }
                let text = landmarks::format(&points, landmarks::Format::Fcsv);
                write_atomic(&fcsv_path, text.as_bytes())?;
                written.push(fcsv_path);
            }
            _ => match std::fs::remove_file(&fcsv_path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(ResultsError::Io {
                        path: fcsv_path,
                        source: e,
                    })
                }
                _ => {}
            },
        }
        Ok(written)
    }
}

/// Create the folder `file` goes into.
fn create_parent(file: &Path) -> Result<(), ResultsError> {
    match file.parent() {
        Some(folder) => std::fs::create_dir_all(folder).map_err(|source| ResultsError::Io {
            path: folder.to_path_buf(),
            source,
        }),
        None => Ok(()),
    }
}

/// The name (a relative path, extension of the scan file kept) of the
/// result files of the scan at `scan`: relative to `export_dir` when the
/// scan lies in it, else the path as given when relative without `..`,
/// else the absolute path without its root. `None` for a path with no
/// file name (the export folder itself). Paths are compared after `.` and
/// `..` are resolved in the text, without following links.
pub(crate) fn result_name(scan: &Path, export_dir: Option<&Path>) -> Option<PathBuf> {
    let absolute = absolute_lexical(scan);
    let inside = export_dir.and_then(|d| absolute.strip_prefix(absolute_lexical(d)).ok());
    let as_given = scan.is_relative() && !scan.components().any(|c| c == Component::ParentDir);
    let relative = match inside {
        Some(r) => r,
        None if as_given => scan,
        None => &absolute,
    };
    let name: PathBuf = relative
        .components()
        .filter(|c| matches!(c, Component::Normal(_)))
        .collect();
    (!name.as_os_str().is_empty()).then_some(name)
}

/// `path` made absolute against the working directory, with `.` and `..`
/// resolved in the text.
fn absolute_lexical(path: &Path) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut out = PathBuf::new();
    for c in absolute.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::ScanStatus;
    use std::collections::{BTreeMap, HashSet};

    fn name(scan: &str, export: Option<&str>) -> Option<String> {
        result_name(Path::new(scan), export.map(Path::new)).map(|p| p.display().to_string())
    }

    #[test]
    fn names_follow_the_path_in_the_export_folder() {
        let export = Some("/data/export");
        assert_eq!(name("/data/export/x.ply", export).unwrap(), "x.ply");
        assert_eq!(name("/data/export/a/x.ply", export).unwrap(), "a/x.ply");
        assert_eq!(
            name("/data/export/./b/../a/x.ply", export).unwrap(),
            "a/x.ply"
        );
        assert_eq!(name("/data/export/", export), None);
        // Outside the export folder: as given when relative, else absolute.
        assert_eq!(name("scans/x.ply", export).unwrap(), "scans/x.ply");
        assert_eq!(name("./x.ply", None).unwrap(), "x.ply");
        assert_eq!(
            name("/data/other/x.ply", export).unwrap(),
            "data/other/x.ply"
        );
        let up = name("../x.ply", None).unwrap();
        assert!(up.ends_with("x.ply") && !up.contains(".."), "{up}");
        assert_ne!(up, "x.ply");
    }

    #[test]
    fn scans_that_share_a_stem_get_different_names() {
        let export = Some("/e");
        let scans = [
            "/e/a/x.ply",
            "/e/b/x.ply",
            "/e/x.stl",
            "/e/x.ply",
            "/e/a/x.stl",
        ];
        let names: HashSet<String> = scans.iter().map(|s| name(s, export).unwrap()).collect();
        assert_eq!(names.len(), scans.len(), "{names:?}");
    }

    fn record(id: i64, path: &str) -> ScanRecord {
        ScanRecord {
            id,
            path: path.into(),
            content_hash: format!("{id:064x}"),
            size: 1,
            status: ScanStatus::Error,
            error: Some(format!("error of {path}")),
            attempts: 1,
            created_at_ms: 0,
            started_at_ms: None,
            finished_at_ms: Some(1),
            timings_ms: BTreeMap::new(),
            cleaning: serde_json::Value::Null,
            ranks: Vec::new(),
            nearest: Vec::new(),
            landmarks: None,
            duplicate_of: None,
            files_error: None,
            calibrating: false,
            superseded_by: None,
            parent: None,
            specimen: None,
            position: None,
            specimen_count: None,
            specimens: Vec::new(),
        }
    }

    #[test]
    fn each_scan_keeps_its_own_result_file() {
        let out = tempfile::tempdir().unwrap();
        let files = ResultFiles::new(out.path().to_path_buf(), Some("/e".into()));
        let scans = ["/e/a/x.ply", "/e/b/x.ply", "/e/x.stl"];
        for (i, s) in scans.iter().enumerate() {
            files.write(&record(i as i64 + 1, s)).unwrap();
        }
        for (i, s) in scans.iter().enumerate() {
            let (json, fcsv) = files.paths(&record(i as i64 + 1, s));
            let text = std::fs::read_to_string(&json).unwrap();
            assert!(
                text.contains(&format!("error of {s}")),
                "{}: {text}",
                json.display()
            );
            assert!(!fcsv.exists());
        }
        assert!(out.path().join("a/x.ply.json").is_file());
        assert!(out.path().join("x.stl.json").is_file());
        let unnamed = record(9, "/e");
        assert_eq!(files.paths(&unnamed).0, out.path().join("scan-9.json"));
    }
}
