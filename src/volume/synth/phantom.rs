//! Voxelizing a closed whole tooth into a grey-value phantom.

use crate::clean::TriangleGrid;
use crate::mesh::synth::WholeTooth;
use crate::mesh::Grid;
use crate::mesh::{bbox_diagonal, bounding_box, Mesh};
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

/// Whether each sample centre of the grid lies inside the closed `mesh`:
/// the crossings of a ray along x through each row, in parity.
fn inside_mask(mesh: &Mesh, grid: &Grid) -> Vec<bool> {
    let [nx, ny, nz] = grid.dims;
    // Faces binned by the rows (y, z) their projection may cover.
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); ny * nz];
    let row = |p: f64, a: usize| (p - grid.origin[a]) / grid.spacing[a];
    for (fi, f) in mesh.faces.iter().enumerate() {
        let ps = f.map(|v| mesh.vertices[v as usize]);
        let (ylo, yhi) = span(ps.map(|p| row(p[1], 1)), ny);
        let (zlo, zhi) = span(ps.map(|p| row(p[2], 2)), nz);
        for z in zlo..zhi {
            for y in ylo..yhi {
                bins[y + ny * z].push(fi as u32);
            }
        }
    }
    let rows: Vec<Vec<bool>> = (0..ny * nz)
        .into_par_iter()
        .map(|r| {
            let (y, z) = (r % ny, r / ny);
            // A tiny irrational offset keeps the ray off edges and vertices.
            let py = grid.origin[1] + y as f64 * grid.spacing[1] + 1.234_567e-7 * grid.spacing[1];
            let pz = grid.origin[2] + z as f64 * grid.spacing[2] + 2.345_678e-7 * grid.spacing[2];
            let mut xs: Vec<f64> = bins[r]
                .iter()
                .filter_map(|&fi| {
                    let [a, b, c] = mesh.faces[fi as usize].map(|v| mesh.vertices[v as usize]);
                    ray_x_crossing([a, b, c], py, pz)
                })
                .collect();
            xs.sort_by(f64::total_cmp);
            let mut out = vec![false; nx];
            for pair in xs.chunks_exact(2) {
                let lo = ((pair[0] - grid.origin[0]) / grid.spacing[0])
                    .ceil()
                    .max(0.0) as usize;
                let hi = ((pair[1] - grid.origin[0]) / grid.spacing[0]).floor();
                if hi < 0.0 {
                    continue;
                }
                for v in out.iter_mut().take((hi as usize + 1).min(nx)).skip(lo) {
                    *v = true;
                }
            }
            out
        })
        .collect();
    rows.into_iter().flatten().collect()
}

fn span(c: [f64; 3], n: usize) -> (usize, usize) {
    let lo = c.iter().copied().fold(f64::MAX, f64::min).ceil().max(0.0) as usize;
    let hi =
        (c.iter().copied().fold(f64::MIN, f64::max).floor() + 1.0).clamp(0.0, n as f64) as usize;
    (lo.min(n), hi)
}

/// The x where the line {y = py, z = pz} crosses triangle `t`, if it does.
fn ray_x_crossing(t: [[f64; 3]; 3], py: f64, pz: f64) -> Option<f64> {
    let [a, b, c] = t;
    let d = (b[1] - a[1]) * (c[2] - a[2]) - (c[1] - a[1]) * (b[2] - a[2]);
    if d.abs() < 1e-300 {
        return None;
    }
    let u = ((py - a[1]) * (c[2] - a[2]) - (c[1] - a[1]) * (pz - a[2])) / d;
    let v = ((b[1] - a[1]) * (pz - a[2]) - (py - a[1]) * (b[2] - a[2])) / d;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then(|| a[0] + u * (b[0] - a[0]) + v * (c[0] - a[0]))
}

/// Separable Gaussian blur of `grid` with standard deviation `sigma` samples.
fn gaussian_blur(grid: &mut Grid, sigma: f64) {
    if sigma <= 0.0 {
        return;
    }
    let r = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f64 = kernel.iter().sum();
    let kernel: Vec<f64> = kernel.iter().map(|k| k / sum).collect();
    let dims = grid.dims;
    let strides = [1, dims[0], dims[0] * dims[1]];
    for axis in 0..3 {
        let n = dims[axis] as i64;
        let src = grid.values.clone();
        grid.values.par_iter_mut().enumerate().for_each(|(i, out)| {
            let pos = ((i / strides[axis]) % dims[axis]) as i64;
            let mut acc = 0.0;
            for (k, w) in kernel.iter().enumerate() {
                let j = (pos + k as i64 - r).clamp(0, n - 1);
                let idx = (i as i64 + (j - pos) * strides[axis] as i64) as usize;
                acc += w * f64::from(src[idx]);
            }
            *out = acc as f32;
        });
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
    let inside = inside_mask(mesh, &grid);
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
        if let Some(t) = &tri {
            let c = t.closest_point(p);
            if c.distance < thickness && tooth.crown_faces.get(c.face as usize) == Some(&true) {
                *v = l2;
            }
        }
    });
    let _ = l0;
    gaussian_blur(&mut grid, params.blur);
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
    use crate::mesh::synth::closed_sphere;

    #[test]
    fn a_voxelized_sphere_has_its_volume() {
        let s = closed_sphere(3000);
        let g = Grid::filled([40, 40, 40], [-1.3; 3], [2.6 / 39.0; 3], 0.0);
        let inside = inside_mask(&s, &g);
        let vol = inside.iter().filter(|&&b| b).count() as f64 * (2.6f64 / 39.0).powi(3);
        let r = s
            .vertices
            .iter()
            .map(|p| crate::mesh::norm(*p))
            .sum::<f64>()
            / s.vertices.len() as f64;
        let expected = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
        assert!((vol / expected - 1.0).abs() < 0.03, "{vol} vs {expected}");
    }
}
