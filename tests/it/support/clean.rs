//! Helpers shared by the cleaning tests: the real-data location, loading
//! the teeth and the distance from points to a surface.

use morphoid_core::clean::TriangleGrid;
use morphoid_core::mesh::Mesh;
use std::path::{Path, PathBuf};

/// Folder of the real teeth's surface files; see
/// [`super::data::teeth_dir`] for when it is missing.
pub(crate) fn teeth_dir() -> Option<PathBuf> {
    super::data::teeth_meshes()
}

/// Read one of the teeth.
pub(crate) fn read_tooth(path: &Path) -> Mesh {
    morphoid_data::mesh_io::load(path)
        .expect("tooth loads")
        .mesh
}

/// All teeth, sorted by name.
pub(crate) fn all_teeth() -> Option<Vec<(String, Mesh)>> {
    let dir = teeth_dir()?;
    let mut names: Vec<PathBuf> = std::fs::read_dir(&dir)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "ply"))
        .collect();
    names.sort();
    Some(
        names
            .iter()
            .map(|p| {
                let stem = p
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default();
                (stem, read_tooth(p))
            })
            .collect(),
    )
}

/// Mean and maximum distance from `points` to the surface of `mesh`.
pub(crate) fn mean_max_distance(points: &[[f64; 3]], mesh: &Mesh) -> (f64, f64) {
    let g = TriangleGrid::new(mesh).expect("surface");
    let d: Vec<f64> = points.iter().map(|&p| g.distance(p)).collect();
    let mean = d.iter().sum::<f64>() / d.len().max(1) as f64;
    (mean, d.iter().copied().fold(0.0, f64::max))
}

/// Median of a list (the upper middle value; NaN when empty).
pub(crate) fn median(xs: &[f64]) -> f64 {
    morphoid_core::stats::upper_median(xs).unwrap_or(f64::NAN)
}
