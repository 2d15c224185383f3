//! Where the real teeth are: `MORPHOID_TEETH` names the folder, else
//! `../shared/data/pnas-teeth` beside the repository (`labels.csv` and
//! `meshes/`). A test that needs them fails when they are missing, with a
//! message that says how to provide them; `MORPHOID_SKIP_DATA=1` skips
//! such tests instead, each printing `skipped: …` on stderr (see
//! [`super::missing`]). `MORPHOID_REQUIRE_DATA=1`, the former switch, is
//! still accepted: it overrides the opt-out.

use std::path::{Path, PathBuf};

/// Where the real teeth are looked for: `MORPHOID_TEETH`, else
/// `../shared/data/pnas-teeth` beside the repository.
pub(crate) fn teeth_location() -> PathBuf {
    std::env::var_os("MORPHOID_TEETH")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../shared/data/pnas-teeth"
            ))
        })
}

/// The real-data folder when it is there, else `None` without a word: for
/// the benchmarks, which fall back to synthetic data.
pub(crate) fn teeth_dir_if_present() -> Option<PathBuf> {
    let dir = teeth_location();
    (dir.join("labels.csv").is_file() && dir.join("meshes").is_dir()).then_some(dir)
}

/// The real-data folder (`labels.csv` and `meshes/`) for a test that needs
/// it. When it is missing the test fails, unless `MORPHOID_SKIP_DATA=1`:
/// then this prints `skipped: …` on stderr and gives `None`, and the test
/// returns early.
#[track_caller]
pub(crate) fn teeth_dir() -> Option<PathBuf> {
    if let Some(dir) = teeth_dir_if_present() {
        return Some(dir);
    }
    super::missing(
        &format!(
            "the real teeth are not at {} (labels.csv and meshes/)",
            teeth_location().display()
        ),
        "put the 116 PNAS teeth there, or name their folder in MORPHOID_TEETH",
        "MORPHOID_SKIP_DATA",
        "MORPHOID_REQUIRE_DATA",
    );
    None
}

/// The folder of the real teeth's surface files (see [`teeth_dir`]).
#[track_caller]
pub(crate) fn teeth_meshes() -> Option<PathBuf> {
    teeth_dir().map(|d| d.join("meshes"))
}

/// The real teeth's surface files, sorted by name (see [`teeth_dir`]).
#[track_caller]
pub(crate) fn tooth_paths() -> Option<Vec<PathBuf>> {
    teeth_meshes().map(|dir| ply_files(&dir))
}

/// The `.ply` files in `dir`, sorted by name.
pub(crate) fn ply_files(dir: &Path) -> Vec<PathBuf> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "ply"))
        .collect();
    paths.sort();
    paths
}
