//! Where the real teeth are. The folder is optional: `MORPHOID_TEETH`
//! names it, else `../shared/data/pnas-teeth` beside the repository.
//! Without it a real-data test prints `skipped: data not found` and
//! passes, unless `MORPHOID_REQUIRE_DATA=1` (set by `.ci/run`), which makes
//! a missing folder a failure.

use std::path::PathBuf;

/// The real-data folder (`labels.csv` and `meshes/`), or `None` when it is
/// missing and not required.
pub fn teeth_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("MORPHOID_TEETH")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../shared/data/pnas-teeth"
            ))
        });
    if dir.join("labels.csv").is_file() && dir.join("meshes").is_dir() {
        return Some(dir);
    }
    if std::env::var("MORPHOID_REQUIRE_DATA").is_ok_and(|v| v == "1") {
        panic!(
            "MORPHOID_REQUIRE_DATA=1 but the real teeth are not at {} (labels.csv and meshes/)",
            dir.display()
        );
    }
    println!("skipped: data not found ({})", dir.display());
    None
}

/// The folder of the real teeth's surface files.
pub fn teeth_meshes() -> Option<PathBuf> {
    teeth_dir().map(|d| d.join("meshes"))
}

/// The real teeth's surface files, sorted by name.
pub fn tooth_paths() -> Option<Vec<PathBuf>> {
    let dir = teeth_meshes()?;
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "ply"))
        .collect();
    paths.sort();
    Some(paths)
}
