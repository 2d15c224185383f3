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

/// How close an extracted crown is to the crop it stands for: the mean
/// distance both ways as a fraction of the crop's diagonal, and the ratio
/// of their areas.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CropFit {
    pub(crate) mean: f64,
    pub(crate) area_ratio: f64,
}

impl CropFit {
    /// The crown-extraction target: mean distance under 1 % of the
    /// diagonal, area within 10 %.
    pub(crate) fn on_target(&self) -> bool {
        self.mean < 0.01 && (0.9..1.1).contains(&self.area_ratio)
    }
}

/// The fit of `extracted` to `crop` (any common units).
#[allow(dead_code)] // used by some of the test modules only
pub(crate) fn crop_fit(extracted: &Mesh, crop: &Mesh) -> CropFit {
    let (m1, _) = mean_max_distance(&extracted.vertices, crop);
    let (m2, _) = mean_max_distance(&crop.vertices, extracted);
    CropFit {
        mean: 0.5 * (m1 + m2) / morphoid_core::mesh::bbox_diagonal(crop),
        area_ratio: morphoid_core::mesh::surface_area(extracted)
            / morphoid_core::mesh::surface_area(crop),
    }
}

/// Each crown as identified (after the cuts along the references' lines)
/// and its fit, then how many are on target of `total` (refused count as
/// off).
#[allow(dead_code)] // used by some of the test modules only
pub(crate) fn print_identified_fits(fits: &[(String, CropFit)], total: usize) {
    for (name, f) in fits {
        println!(
            "{name} as identified: mean {:.4} area {:.3}",
            f.mean, f.area_ratio
        );
    }
    let off: Vec<&str> = fits
        .iter()
        .filter(|(_, f)| !f.on_target())
        .map(|(n, _)| n.as_str())
        .collect();
    println!(
        "crowns as identified: {} of {total} on target; off: {off:?}",
        fits.len() - off.len(),
    );
}
