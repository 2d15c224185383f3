//! Scanner-like point clouds and a crown whose walls overhang, to test the
//! point-cloud reconstruction.

use super::{crown, CrownGenus};
use morphoid_core::mesh::{bbox_diagonal, bounding_box, cross, face_areas, norm, sub, Mesh};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// How a simulated scanner samples a surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScannerCloud {
    /// Points on the surface (before outliers are added).
    pub points: usize,
    /// Standard deviation of the noise along the surface normal, as a
    /// fraction of the bounding-box diagonal.
    pub noise: f64,
    /// Outliers as a fraction of `points`: half uniform in the bounding
    /// box, half 1–5 % of the diagonal off the surface along its normal.
    pub outliers: f64,
    /// Seed of the sampling.
    pub seed: u64,
}

impl Default for ScannerCloud {
    /// 10,000 points, noise 0.2 % of the diagonal, 2 % outliers.
    fn default() -> Self {
        ScannerCloud {
            points: 10_000,
            noise: 0.002,
            outliers: 0.02,
            seed: 1,
        }
    }
}

/// A standard normal sample (Box–Muller).
fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let u: f64 = rng.gen_range(f64::MIN_POSITIVE..1.0);
    let v: f64 = rng.gen();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// A point uniform on the surface (faces chosen by area) and the unit
/// normal of its face.
fn surface_point(mesh: &Mesh, cumulative: &[f64], rng: &mut ChaCha8Rng) -> ([f64; 3], [f64; 3]) {
    let total = cumulative.last().copied().unwrap_or(0.0);
    let t = rng.gen_range(0.0..total.max(f64::MIN_POSITIVE));
    let f = cumulative
        .partition_point(|&c| c <= t)
        .min(mesh.faces.len() - 1);
    let [a, b, c] = mesh.faces[f].map(|i| mesh.vertices[i as usize]);
    let (mut r1, mut r2): (f64, f64) = (rng.gen(), rng.gen());
    if r1 + r2 > 1.0 {
        (r1, r2) = (1.0 - r1, 1.0 - r2);
    }
    let p = [0, 1, 2].map(|d| a[d] + r1 * (b[d] - a[d]) + r2 * (c[d] - a[d]));
    let n = cross(sub(b, a), sub(c, a));
    let len = norm(n).max(f64::MIN_POSITIVE);
    (p, n.map(|x| x / len))
}

/// A point cloud as a scanner gives it (see [`ScannerCloud`]): points
/// spread uniformly over the surface's area, each moved along its normal
/// by Gaussian noise, then the outliers, in random order. A mesh without
/// faces gives an empty cloud.
pub fn scanner_cloud(mesh: &Mesh, spec: &ScannerCloud) -> Mesh {
    if mesh.faces.is_empty() {
        return Mesh::new(Vec::new(), Vec::new());
    }
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let diag = bbox_diagonal(mesh);
    let mut cumulative = face_areas(mesh);
    for i in 1..cumulative.len() {
        cumulative[i] += cumulative[i - 1];
    }
    let mut points = Vec::with_capacity(spec.points);
    for _ in 0..spec.points {
        let (p, n) = surface_point(mesh, &cumulative, &mut rng);
        let e = spec.noise * diag * gaussian(&mut rng);
        points.push([0, 1, 2].map(|d| p[d] + e * n[d]));
    }
    let outliers = (spec.outliers.max(0.0) * spec.points as f64).round() as usize;
    let (lo, hi) = bounding_box(mesh).unwrap_or(([0.0; 3], [0.0; 3]));
    for k in 0..outliers {
        if k % 2 == 0 {
            points.push([0, 1, 2].map(|d| rng.gen_range(lo[d]..=hi[d])));
        } else {
            let (p, n) = surface_point(mesh, &cumulative, &mut rng);
            let side = if rng.gen::<bool>() { 1.0 } else { -1.0 };
            let e = side * diag * rng.gen_range(0.01..0.05);
            points.push([0, 1, 2].map(|d| p[d] + e * n[d]));
        }
    }
    // Scanners write points in no particular order relative to outliers.
    for i in (1..points.len()).rev() {
        let j = rng.gen_range(0..=i);
        points.swap(i, j);
    }
    Mesh::new(points, Vec::new())
}

/// A crown wrapped over a ball so that its walls overhang: the synthetic
/// crown's footprint (radius about 1) is mapped to the sphere of radius 1
/// by polar angle `0.62 π ·` radius (past the equator, about 112°, at the
/// margin), and its heights are added along the sphere's normal. The
/// occlusal surface faces +z; seen along z, the walls fold under.
pub fn overhanging_crown(genus: &CrownGenus, seed: u64, target_vertices: usize) -> Mesh {
    let flat = crown(genus, seed, target_vertices);
    let reach = flat
        .vertices
        .iter()
        .map(|v| v[0].hypot(v[1]))
        .fold(0.0f64, f64::max)
        .max(f64::MIN_POSITIVE);
    let vertices = flat
        .vertices
        .iter()
        .map(|v| {
            let rho = v[0].hypot(v[1]) / reach;
            let phi = v[1].atan2(v[0]);
            let theta = 0.62 * std::f64::consts::PI * rho;
            let n = [
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ];
            // Heights are small next to the ball; 0.6 keeps cusps distinct.
            let r = 1.0 + 0.6 * v[2];
            n.map(|c| r * c)
        })
        .collect();
    Mesh::new(vertices, flat.faces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::CROWN_GENERA;

    #[test]
    fn scanner_cloud_has_the_points_and_outliers_asked_for() {
        let m = crown(&CROWN_GENERA[0], 3, 2000);
        let spec = ScannerCloud {
            points: 3000,
            noise: 0.0,
            outliers: 0.02,
            seed: 5,
        };
        let c = scanner_cloud(&m, &spec);
        assert!(c.is_point_cloud());
        assert_eq!(c.vertices.len(), 3060);
        assert_eq!(c, scanner_cloud(&m, &spec));
        let d = morphoid_core::clean::point_to_surface_distances(&c.vertices, &m);
        let diag = bbox_diagonal(&m);
        let on = d.iter().filter(|&&x| x < 1e-9 * diag).count();
        let off = d.iter().filter(|&&x| x > 0.005 * diag).count();
        assert!(on >= 3000 && off >= 30, "on {on}, off {off}");
        let noisy = scanner_cloud(
            &m,
            &ScannerCloud {
                noise: 0.002,
                ..spec
            },
        );
        let d = morphoid_core::clean::point_to_surface_distances(&noisy.vertices, &m);
        let mut sorted = d.clone();
        sorted.sort_by(f64::total_cmp);
        let med = sorted[sorted.len() / 2] / diag;
        // Median of |N(0, σ)| is 0.674 σ (a little less where the closest
        // point is not straight down).
        assert!(med > 0.0008 && med < 0.0016, "median distance {med}");
    }

    #[test]
    fn overhanging_crown_folds_under() {
        let m = overhanging_crown(&CROWN_GENERA[1], 2, 3000);
        let (lo, _) = bounding_box(&m).expect("box");
        assert!(lo[2] < -0.2);
        assert_eq!(morphoid_core::mesh::euler_characteristic(&m), 1);
        // The widest ring is above the margin: the wall overhangs.
        let margin = m
            .vertices
            .iter()
            .filter(|v| v[2] < lo[2] + 0.05)
            .map(|v| v[0].hypot(v[1]))
            .fold(0.0f64, f64::max);
        let widest = m
            .vertices
            .iter()
            .map(|v| v[0].hypot(v[1]))
            .fold(0.0f64, f64::max);
        assert!(widest > margin + 0.05, "widest {widest}, margin {margin}");
    }
}
