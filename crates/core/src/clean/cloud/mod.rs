//! Surface reconstruction of a scanner point cloud (cleaning step 1).
//!
//! [`reconstruct_surface`] runs, in order:
//! 1. a degeneracy check (all points on a line or in one plane);
//! 2. outlier removal ([`outliers`]): isolated points, then points off the
//!    surface their neighbours sample;
//! 3. tangent planes by principal component analysis over the nearest
//!    neighbours and their consistent orientation along a minimum spanning
//!    tree ([`normals`]);
//! 4. the zero set of the blended signed distance to those planes, by
//!    surface nets on a sparse grid near the points, projected onto the
//!    zero set and trimmed to where the points are ([`reconstruct`]).
//!
//! The triangles need not form a disk yet: the rest of [`crate::clean`]
//! keeps the largest piece, repairs it and fills its holes.

mod neighbours;
mod normals;
mod outliers;
mod reconstruct;

use crate::mesh::principal_axes;
use crate::mesh::Mesh;
use crate::stats::upper_median;
use neighbours::{mean_neighbour_distances, Neighbours};
use normals::{local_plane, orient_by_propagation, LocalPlane};
use reconstruct::{band_nodes, surface_nets, Grid, OrientedSamples};

/// Neighbours for spacing, outlier statistics and tangent planes.
const NEIGHBOURS: usize = 12;
/// Grid spacing in median sample spacings.
const GRID_SPACING: f64 = 0.75;
/// The grid has at most this many cells along the bounding-box diagonal
/// (bounds time and memory for very dense clouds).
const MAX_CELLS_PER_DIAGONAL: f64 = 400.0;
/// Width of the blending weights in median sample spacings.
const BLEND_WIDTH: f64 = 1.0;
/// Newton steps that move the surface-nets vertices onto the zero set.
const PROJECTION_STEPS: usize = 2;
/// A triangle is kept if its nearest sample is within this many local
/// spacings ...
const TRIM_GAP: f64 = 2.0;
/// ... and its nearest samples' centroid within this many along its plane.
const TRIM_OFFSET: f64 = 0.6;
/// Spreads (variances) below this fraction of the largest are zero.
const DEGENERATE_SPREAD: f64 = 1e-10;

/// What the reconstruction did.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CloudReport {
    /// Points given.
    pub points_in: usize,
    /// Points dropped as outliers (isolated or off the surface).
    pub outliers_removed: usize,
    /// Triangles of the reconstructed surface (before the rest of the
    /// cleaning).
    pub triangles: usize,
}

/// Why a point cloud has no surface.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CloudError {
    /// All points on a line.
    #[error("all its points lie on one line")]
    Collinear,
    /// All points in one plane.
    #[error("all its points lie in one plane (a flat patch, not a scanned surface)")]
    Flat,
    /// Too few points left after the outliers went.
    #[error("only {left} of its {total} points are not outliers")]
    TooFewInliers {
        /// Points left.
        left: usize,
        /// Points given.
        total: usize,
    },
    /// The points sample no surface that the reconstruction could follow.
    #[error("no surface follows its points ({0} triangles)")]
    NoSurface(usize),
}

/// The points that are not `drop`ped.
fn kept(points: &[[f64; 3]], drop: &[bool]) -> Vec<[f64; 3]> {
    points
        .iter()
        .zip(drop)
        .filter(|(_, &d)| !d)
        .map(|(p, _)| *p)
        .collect()
}

/// Each point's `k` nearest other points.
fn neighbour_lists(nb: &Neighbours, k: usize) -> Vec<Vec<usize>> {
    use rayon::prelude::*;
    (0..nb.points().len())
        .into_par_iter()
        .map(|i| nb.of_point(i, k).into_iter().map(|(j, _)| j).collect())
        .collect()
}

/// Reconstruct the surface that a point cloud samples (see the module
/// documentation). `min_points` is the fewest inliers accepted.
pub(super) fn reconstruct_surface(
    points: &[[f64; 3]],
    min_points: usize,
) -> Result<(Mesh, CloudReport), CloudError> {
    let total = points.len();
    refuse_degenerate(points)?;
    let inliers = without_outliers(points, min_points)?;

    // Tangent planes, oriented consistently.
    let nb = Neighbours::new(&inliers);
    let spacing = mean_neighbour_distances(&nb, NEIGHBOURS);
    let lists = neighbour_lists(&nb, NEIGHBOURS);
    let planes = oriented_planes(&inliers, &lists);

    let samples = OrientedSamples {
        neighbours: &nb,
        planes: &planes,
        spacing: &spacing,
    };
    let (surface, h) = zero_set_surface(&inliers, &samples)?;
    let report = CloudReport {
        points_in: total,
        outliers_removed: total - inliers.len(),
        triangles: surface.faces.len(),
    };
    tracing::debug!(
        points = total,
        outliers = report.outliers_removed,
        triangles = report.triangles,
        grid = h,
        "point cloud reconstructed"
    );
    Ok((surface, report))
}

/// Refuses a cloud whose points lie on one line or in one plane, or that
/// has no principal axes (too few points).
fn refuse_degenerate(points: &[[f64; 3]]) -> Result<(), CloudError> {
    let total = points.len();
    let spreads = principal_axes(points)
        .ok_or(CloudError::TooFewInliers { left: total, total })?
        .spreads;
    if spreads[1] <= DEGENERATE_SPREAD * spreads[0] {
        return Err(CloudError::Collinear);
    }
    if spreads[2] <= DEGENERATE_SPREAD * spreads[0] {
        return Err(CloudError::Flat);
    }
    Ok(())
}

/// The points that are not outliers ([`outliers`]); refused when fewer
/// than `min_points` (or than a point's neighbourhood) are left.
fn without_outliers(points: &[[f64; 3]], min_points: usize) -> Result<Vec<[f64; 3]>, CloudError> {
    let total = points.len();
    let too_few = |left: usize| CloudError::TooFewInliers { left, total };
    // Isolated points first, so that they do not spoil the planes of the
    // off-surface test.
    let nb = Neighbours::new(points);
    let spacing = mean_neighbour_distances(&nb, NEIGHBOURS);
    let isolated = outliers::isolated_points(&spacing, &neighbour_lists(&nb, NEIGHBOURS));
    let stage1 = kept(points, &isolated);
    if stage1.len() < min_points.max(NEIGHBOURS + 1) {
        return Err(too_few(stage1.len()));
    }
    let nb = Neighbours::new(&stage1);
    let spacing = mean_neighbour_distances(&nb, NEIGHBOURS);
    let off = outliers::off_surface_points(&stage1, &spacing, &neighbour_lists(&nb, NEIGHBOURS));
    let inliers = kept(&stage1, &off);
    if inliers.len() < min_points.max(NEIGHBOURS + 1) {
        return Err(too_few(inliers.len()));
    }
    Ok(inliers)
}

/// Each point's tangent plane through its neighbourhood (`lists`), with
/// normals oriented consistently along a minimum spanning tree.
fn oriented_planes(points: &[[f64; 3]], lists: &[Vec<usize>]) -> Vec<LocalPlane> {
    let planes: Vec<LocalPlane> = lists
        .iter()
        .enumerate()
        .map(|(i, list)| {
            let mut around: Vec<[f64; 3]> = list.iter().map(|&j| points[j]).collect();
            around.push(points[i]);
            local_plane(&around).unwrap_or(LocalPlane {
                centroid: points[i],
                normal: [0.0, 0.0, 1.0],
                residual: 0.0,
            })
        })
        .collect();
    let normals: Vec<[f64; 3]> = planes.iter().map(|p| p.normal).collect();
    let oriented = orient_by_propagation(&normals, lists);
    planes
        .iter()
        .zip(&oriented)
        .map(|(p, &normal)| LocalPlane { normal, ..*p })
        .collect()
}

/// The zero set of the blended signed distance near the `inliers` (the
/// samples' positions), trimmed to where they are, and the grid spacing
/// it was extracted at.
fn zero_set_surface(
    inliers: &[[f64; 3]],
    samples: &OrientedSamples,
) -> Result<(Mesh, f64), CloudError> {
    let spacing = samples.spacing;
    let s = upper_median(spacing).unwrap_or(0.0);
    let diagonal = crate::mesh::bbox_diagonal(&Mesh::new(inliers.to_vec(), Vec::new()));
    let h = (GRID_SPACING * s).max(diagonal / MAX_CELLS_PER_DIAGONAL);
    if h <= 0.0 || !h.is_finite() {
        return Err(CloudError::NoSurface(0));
    }
    let low = [0, 1, 2].map(|d| inliers.iter().map(|p| p[d]).fold(f64::INFINITY, f64::min));
    let grid = Grid {
        origin: low.map(|x| x - 8.0 * h),
        h,
    };
    // Sparse places get a wider band, so that their cells exist.
    let nodes = band_nodes(inliers, &grid, |i| {
        (2.5 * h).max(2.0 * spacing[i]).min(6.0 * h)
    });
    let width = BLEND_WIDTH * s;
    let values = node_values(samples, &grid, &nodes, width);
    let nets = surface_nets(&grid, &nodes, &values);
    let projected = reconstruct::project_to_zero_set(samples, &nets, width, PROJECTION_STEPS);
    let among = reconstruct::among_samples(samples, &projected, TRIM_GAP, TRIM_OFFSET);
    let trimmed = reconstruct::trim_from_boundary(&projected, &among);
    let surface = reconstruct::drop_nonmanifold(&trimmed, 5);
    if surface.faces.len() < 3 {
        return Err(CloudError::NoSurface(surface.faces.len()));
    }
    Ok((surface, h))
}

/// The blended signed distance (blending width `width`) at each grid node.
fn node_values(samples: &OrientedSamples, grid: &Grid, nodes: &[[i32; 3]], width: f64) -> Vec<f64> {
    use rayon::prelude::*;
    nodes
        .par_iter()
        .map(|&n| {
            let x = [0, 1, 2].map(|d| grid.origin[d] + grid.h * n[d] as f64);
            reconstruct::signed_distance(samples, x, width).0
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::euler_characteristic;

    /// Points on a spherical cap on a jittered grid.
    fn cap() -> Vec<[f64; 3]> {
        let mut pts = Vec::new();
        for i in 0..31 {
            for j in 0..31 {
                let x = (i as f64 - 15.0) / 15.0 + 0.01 * ((i * 7 + j * 3) as f64).sin();
                let y = (j as f64 - 15.0) / 15.0 + 0.01 * ((i * 5 + j * 11) as f64).cos();
                if x * x + y * y <= 1.0 {
                    pts.push([x, y, (2.0 - x * x - y * y).sqrt()]);
                }
            }
        }
        pts
    }

    #[test]
    fn cloud_of_a_cap_becomes_a_surface_on_the_sphere() {
        let pts = cap();
        let (m, report) = reconstruct_surface(&pts, 20).expect("reconstruction");
        assert_eq!(report.points_in, pts.len());
        assert_eq!(report.outliers_removed, 0);
        assert_eq!(report.triangles, m.faces.len());
        for v in &m.vertices {
            let r = crate::mesh::norm(*v);
            assert!((r - 2f64.sqrt()).abs() < 0.01, "vertex at radius {r}");
        }
        let (piece, _) = crate::clean::components::largest_component_by_area(&m);
        assert_eq!(euler_characteristic(&piece), 1);
    }

    #[test]
    fn degenerate_clouds_are_refused() {
        let line: Vec<[f64; 3]> = (0..50).map(|i| [i as f64, 2.0 * i as f64, 0.0]).collect();
        assert_eq!(reconstruct_surface(&line, 20), Err(CloudError::Collinear));
        let flat: Vec<[f64; 3]> = cap().iter().map(|p| [p[0], p[1], 1.0]).collect();
        assert_eq!(reconstruct_surface(&flat, 20), Err(CloudError::Flat));
    }
}
