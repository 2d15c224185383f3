//! Volumes on a regular grid to the surfaces of their specimens: pure
//! functions over samples already read (the readers are in `morphoid-data`).
//!
//! Stages, each its own submodule: `reduce` averages slices into blocks
//! (memory is the working grid plus one slice), `threshold` proposes
//! levels (multi-level Otsu) and finds the enamel level, `specimen` takes
//! the densest large objects that are not mounting material (foam, a tube,
//! wax, a pin: `shape` holds the shape rules), `split` separates touching
//! specimens at thin necks, `segment` labels components and fills internal
//! cavities, `refine` rebuilds a batch's specimens from a finer grid, and
//! `mesh::isosurface` extracts each closed surface (marching tetrahedra).
//! With `[volume] enamel = true`, `enamel` cuts the crown where the surface
//! lies over enamel.

mod enamel;
mod reduce;
mod refine;
mod segment;
mod shape;
mod specimen;
mod split;
mod threshold;

pub(crate) use enamel::{cut_at_zero_level, largest_part};
pub use reduce::{reduction_factor, BlockAverage};
pub use refine::detail_factor;
pub use segment::SegmentReport;
pub(crate) use specimen::{find_specimen, SpecimenError};
pub use specimen::{DropReason, Specimen};
pub(crate) use threshold::enamel_threshold;
pub use threshold::Thresholds;

use crate::mesh::{isosurface, surface_area, Grid, Mesh};
use rayon::prelude::*;
use refine::refined_surface;
use std::time::Instant;

/// The `[volume]` settings.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VolumeOptions {
    /// Samples across the largest dimension after block averaging.
    pub working_voxels: usize,
    /// Cut the crown where the surface lies over brighter enamel, when the
    /// scan shows three materials, instead of leaving the closed surface
    /// to the cleaning's crown extraction (the default: the enamel thins
    /// to nothing towards the cervical margin, and a cut over it stops a
    /// few voxels short; on twelve real teeth mounted in foam, genus right
    /// 6/10 over enamel against 10/10 from the closed surface).
    pub enamel: bool,
}

impl Default for VolumeOptions {
    fn default() -> Self {
        VolumeOptions {
            working_voxels: 200,
            enamel: false,
        }
    }
}

/// Why a working grid gave no surface (the caller names the file).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SegmentError {
    /// No specimen (the error says what was found instead).
    #[error(transparent)]
    Specimen(#[from] SpecimenError),
    /// The specimen is too small to give a surface.
    #[error("the specimen has only {0} voxels at the working resolution")]
    TooSmall(usize),
}

/// The surfaces of the specimens in a working grid, and how they were found.
#[derive(Debug, Clone)]
pub struct GridSurfaces {
    /// Each specimen's surface with its box in working samples (first and
    /// last sample along x, y, z), in order along the grid's longest axis.
    pub specimens: Vec<(Mesh, [[usize; 3]; 2])>,
    /// The levels found, in the grid's grey values.
    pub thresholds: Thresholds,
    /// The objects found and dropped.
    pub segmentation: SegmentReport,
    /// Sizes and times of the stages.
    pub report: GridSurfaceReport,
}

/// The surfaces of the specimens in `grid` (see the module documentation;
/// several in a batch scan), each with its box in working samples, with
/// the thresholds and what segmentation and the crown cut did. `detail`,
/// a finer grid of the same volume, gives a batch's specimens their own
/// resolution.
pub fn grid_surface(
    grid: &Grid,
    detail: Option<&Grid>,
    opts: &VolumeOptions,
) -> Result<GridSurfaces, SegmentError> {
    let t = Instant::now();
    let Specimen {
        masks,
        level: fg,
        report: seg,
    } = find_specimen(&grid.values, grid.dims)?;
    if seg.kept_voxels < 8 {
        return Err(SegmentError::TooSmall(seg.kept_voxels));
    }
    let boxes: Vec<[[usize; 3]; 2]> = seg
        .objects
        .iter()
        .filter(|o| o.kept)
        .map(|o| o.bbox)
        .collect();
    let interior: Vec<f32> = masks
        .iter()
        .flat_map(|m| interior_samples(m, grid.dims, 2))
        .map(|i| grid.values[i])
        .collect();
    let th = Thresholds {
        foreground: fg,
        enamel: enamel_threshold(&interior),
    };
    let mut report = GridSurfaceReport {
        segment_ms: ms(t),
        ..Default::default()
    };
    // Each specimen's surface on its own (a batch's side by side), in
    // order; the report adds them up in that order.
    let several = masks.len() > 1;
    let made: Vec<SpecimenSurface> = masks
        .par_iter()
        .zip(boxes)
        .map(|(mask, bbox)| {
            specimen_surface(grid, detail.filter(|_| several), mask, bbox, &th, opts)
        })
        .collect();
    let mut out = Vec::with_capacity(made.len());
    for m in made {
        report.isosurface_ms += m.isosurface_ms;
        report.isosurface_faces += m.isosurface_faces;
        report.isosurface_area += m.isosurface_area;
        if let Some((area, parts)) = m.enamel {
            report.enamel_found = true;
            report.crown_area += area;
            report.enamel_regions += parts;
        }
        report.crown_ms += m.crown_ms;
        out.push((m.mesh, m.bbox));
    }
    Ok(GridSurfaces {
        specimens: out,
        thresholds: th,
        segmentation: seg,
        report,
    })
}

/// One specimen's surface and what making it took, for
/// [`GridSurfaceReport`].
struct SpecimenSurface {
    mesh: Mesh,
    bbox: [[usize; 3]; 2],
    isosurface_ms: f64,
    isosurface_faces: usize,
    isosurface_area: f64,
    /// The crown's area and regions, when it was cut over enamel.
    enamel: Option<(f64, usize)>,
    crown_ms: f64,
}

/// The surface of the specimen `mask` (its box `bbox`) on `grid`: from
/// `detail` when given (a batch's specimens, each at its own resolution),
/// else the working grid's isosurface; cut over enamel when `opts` ask.
fn specimen_surface(
    grid: &Grid,
    detail: Option<&Grid>,
    mask: &[bool],
    bbox: [[usize; 3]; 2],
    th: &Thresholds,
    opts: &VolumeOptions,
) -> SpecimenSurface {
    let t = Instant::now();
    let fg = th.foreground as f32;
    let refined =
        detail.and_then(|d| refined_surface(d, grid, mask, f64::from(fg), opts.working_voxels));
    let closed = refined.unwrap_or_else(|| masked_isosurface(grid, mask, fg));
    let isosurface_ms = ms(t);
    let t = Instant::now();
    let (isosurface_faces, isosurface_area) = (closed.faces.len(), surface_area(&closed));
    let mut enamel = None;
    let mesh = match th.enamel.filter(|_| opts.enamel) {
        Some(level) => {
            let step = grid.spacing.iter().copied().fold(f64::MAX, f64::min);
            let normals = crate::mesh::vertex_normals(&closed.vertices, &closed.faces);
            let depths = [1.0, 1.5, 2.0, 2.5, 3.0].map(|d| d * step);
            let values = enamel::density_below_surface(&closed, &normals, grid, &depths, level);
            let values = enamel::smooth_vertex_values(&closed, &values);
            let (crown, parts) = largest_part(&cut_at_zero_level(&closed, &values));
            if crown.faces.is_empty() {
                closed
            } else {
                enamel = Some((surface_area(&crown), parts));
                crown
            }
        }
        None => closed,
    };
    SpecimenSurface {
        mesh,
        bbox,
        isosurface_ms,
        isosurface_faces,
        isosurface_area,
        enamel,
        crown_ms: ms(t),
    }
}

/// The closed surface of the samples of `mask` on `grid`: the grey values
/// give it its sub-voxel position around `level`, the mask decides which
/// side of it each sample is on.
pub(crate) fn masked_isosurface(grid: &Grid, mask: &[bool], level: f32) -> Mesh {
    let margin = 1e-3
        * (grid.values.iter().copied().fold(f32::MIN, f32::max) - level)
            .abs()
            .max(1e-6);
    let mut field = grid.clone();
    for (v, &m) in field.values.iter_mut().zip(mask) {
        *v = if m {
            v.max(level + margin)
        } else {
            v.min(level - margin)
        };
    }
    isosurface(&field, level)
}

/// The samples of `mask` at least `depth` steps (6-connected) from any
/// sample outside it.
fn interior_samples(mask: &[bool], dims: [usize; 3], depth: usize) -> Vec<usize> {
    let mut inner = mask.to_vec();
    let plane = dims[0] * dims[1];
    for _ in 0..depth {
        let prev = inner.clone();
        for (i, v) in inner.iter_mut().enumerate() {
            if !*v {
                continue;
            }
            let (x, y, z) = (i % dims[0], (i / dims[0]) % dims[1], i / plane);
            let border = x == 0
                || y == 0
                || z == 0
                || x + 1 == dims[0]
                || y + 1 == dims[1]
                || z + 1 == dims[2];
            *v = !border
                && prev[i - 1]
                && prev[i + 1]
                && prev[i - dims[0]]
                && prev[i + dims[0]]
                && prev[i - plane]
                && prev[i + plane];
        }
    }
    (0..inner.len()).filter(|&i| inner[i]).collect()
}

/// What [`grid_surface`] measured.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GridSurfaceReport {
    /// Triangles of the closed isosurface.
    pub isosurface_faces: usize,
    /// Its area.
    pub isosurface_area: f64,
    /// Whether the crown was cut over enamel.
    pub enamel_found: bool,
    /// Area of the crown kept.
    pub crown_area: f64,
    /// Regions over enamel.
    pub enamel_regions: usize,
    /// Milliseconds spent segmenting.
    pub segment_ms: f64,
    /// Milliseconds spent on the isosurface.
    pub isosurface_ms: f64,
    /// Milliseconds spent cutting the crown.
    pub crown_ms: f64,
}

/// Milliseconds since `t`.
fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
