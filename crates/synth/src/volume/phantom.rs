//! Voxelizing a closed whole tooth into a grey-value phantom.

use crate::mesh::WholeTooth;
use morphoid_core::clean::TriangleGrid;
use morphoid_core::mesh::{bbox_diagonal, bounding_box};
use morphoid_core::mesh::{inside_by_parity, Grid};
use rayon::prelude::*;

/// How a whole tooth becomes a phantom.
#[derive(Debug, Clone, PartialEq)]
pub struct PhantomParams {
    /// Samples across the tooth's largest extent.
    pub voxels_across: usize,
    /// Empty samples around the tooth on every side.
    pub margin: usize,
    /// Enamel thickness under the crown faces, fraction of the tooth's
    /// bounding-box diagonal.
    pub enamel_thickness: f64,
    /// Grey values of air, dentine and enamel (0..1).
    pub levels: [f32; 3],
    /// Gaussian blur, standard deviation in samples (the scanner's point
    /// spread).
    pub blur: f64,
}

impl Default for PhantomParams {
    fn default() -> Self {
        PhantomParams {
            voxels_across: 160,
            margin: 6,
            enamel_thickness: 0.025,
            levels: [0.1, 0.5, 0.85],
            blur: 1.0,
        }
    }
}

/// A blurred grey-value phantom of `tooth`: air outside, dentine inside,
/// enamel within `enamel_thickness` of the crown faces.
pub fn phantom(tooth: &WholeTooth, params: &PhantomParams) -> Grid {
    let mesh = &tooth.mesh;
    let (lo, hi) = bounding_box(mesh).unwrap_or(([0.0; 3], [1.0; 3]));
    let extent = (0..3)
        .map(|a| hi[a] - lo[a])
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let across = params.voxels_across.max(4);
    let h = extent / (across - 1) as f64;
    let m = params.margin as f64;
    let dims = [0, 1, 2].map(|a| ((hi[a] - lo[a]) / h).ceil() as usize + 1 + 2 * params.margin);
    let origin = [0, 1, 2].map(|a| lo[a] - m * h);
    let mut grid = Grid::filled(dims, origin, [h; 3], params.levels[0]);
    let inside = inside_by_parity(mesh, &grid, 0);
    let thickness = params.enamel_thickness * bbox_diagonal(mesh);
    // Only samples within the enamel thickness of the outside can be
    // enamel: find them by a breadth-first depth from the outside.
    let shell = (thickness / h * 3f64.sqrt()).ceil() as usize + 1;
    let depth = depth_from_outside(&inside, dims, shell);
    let tri = TriangleGrid::new(mesh);
    let [l0, l1, l2] = params.levels;
    grid.values.par_iter_mut().enumerate().for_each(|(i, v)| {
        if !inside[i] {
            return;
        }
        *v = l1;
        if depth[i] as usize > shell {
            return;
        }
        let (x, y, z) = (
            i % dims[0],
            (i / dims[0]) % dims[1],
            i / (dims[0] * dims[1]),
        );
        let p = [0, 1, 2].map(|a| origin[a] + [x, y, z][a] as f64 * h);
        // Only a surface nearer than the enamel's thickness matters, and
        // most samples of the shell have none (the search stops there).
        if let Some(c) = tri
            .as_ref()
            .and_then(|t| t.closest_point_within(p, thickness))
        {
            if tooth.crown_faces.get(c.face as usize) == Some(&true) {
                *v = l2;
            }
        }
    });
    let _ = l0;
    grid.gaussian_blur(params.blur);
    grid
}

/// Steps (6-connected) from each inside sample to the nearest outside one,
/// counted up to `limit + 1`.
fn depth_from_outside(inside: &[bool], dims: [usize; 3], limit: usize) -> Vec<u16> {
    let cap = (limit + 1).min(u16::MAX as usize) as u16;
    let mut depth: Vec<u16> = inside.iter().map(|&i| if i { cap } else { 0 }).collect();
    let plane = dims[0] * dims[1];
    for d in 1..cap {
        let prev = depth.clone();
        depth.par_iter_mut().enumerate().for_each(|(i, v)| {
            if *v != cap {
                return;
            }
            let x = i % dims[0];
            let y = (i / dims[0]) % dims[1];
            let z = i / plane;
            let near = (x > 0 && prev[i - 1] == d - 1)
                || (x + 1 < dims[0] && prev[i + 1] == d - 1)
                || (y > 0 && prev[i - dims[0]] == d - 1)
                || (y + 1 < dims[1] && prev[i + dims[0]] == d - 1)
                || (z > 0 && prev[i - plane] == d - 1)
                || (z + 1 < dims[2] && prev[i + plane] == d - 1);
            if near {
                *v = d;
            }
        });
    }
    depth
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::closed_sphere;

    #[test]
    fn a_voxelized_sphere_has_its_volume() {
        let s = closed_sphere(3000);
        let g = Grid::filled([40, 40, 40], [-1.3; 3], [2.6 / 39.0; 3], 0.0);
        let inside = inside_by_parity(&s, &g, 0);
        let vol = inside.iter().filter(|&&b| b).count() as f64 * (2.6f64 / 39.0).powi(3);
        let r = s
            .vertices
            .iter()
            .map(|p| morphoid_core::mesh::norm(*p))
            .sum::<f64>()
            / s.vertices.len() as f64;
        let expected = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
        assert!((vol / expected - 1.0).abs() < 0.03, "{vol} vs {expected}");
    }
}
