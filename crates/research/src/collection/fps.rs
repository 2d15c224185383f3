//! Pseudolandmarks on a template: points spread evenly over its area by
//! farthest-point sampling of a dense area-uniform sample.

use morphoid_core::mesh::{face_areas, farthest_point_order, Mesh};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A point of a mesh: a triangle and barycentric coordinates in it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshPoint {
    /// Triangle index.
    pub face: u32,
    /// Barycentric coordinates (non-negative, sum 1).
    pub bary: [f64; 3],
}

impl MeshPoint {
    /// The position of this point on a mesh with the given corner
    /// positions (`vertices` may be the template's own or its images on
    /// another specimen); `None` when the face or a corner is missing.
    pub fn position(&self, vertices: &[[f64; 3]], faces: &[[u32; 3]]) -> Option<[f64; 3]> {
        let f = faces.get(self.face as usize)?;
        let mut p = [0.0; 3];
        for (k, &v) in f.iter().enumerate() {
            let q = vertices.get(v as usize)?;
            for d in 0..3 {
                p[d] += self.bary[k] * q[d];
            }
        }
        Some(p)
    }
}

/// `count` points of `mesh` distributed uniformly by area (a triangle is
/// drawn with probability proportional to its area, then a uniform point
/// in it), reproducibly from `seed`. Empty when the mesh has no area.
pub(crate) fn area_uniform_points(mesh: &Mesh, count: usize, seed: u64) -> Vec<MeshPoint> {
    let areas = face_areas(mesh);
    let mut cumulative = Vec::with_capacity(areas.len());
    let mut total = 0.0;
    for a in &areas {
        total += a.max(0.0);
        cumulative.push(total);
    }
    if !(total > 0.0 && total.is_finite()) {
        return Vec::new();
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .map(|_| {
            let t = rng.gen::<f64>() * total;
            let face = cumulative.partition_point(|&c| c <= t).min(areas.len() - 1);
            // Uniform in the triangle: fold the unit square onto it.
            let (mut u, mut v) = (rng.gen::<f64>(), rng.gen::<f64>());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            MeshPoint {
                face: face as u32,
                bary: [1.0 - u - v, u, v],
            }
        })
        .collect()
}

/// Indices of `n` of `points` chosen by farthest-point sampling
/// ([`farthest_point_order`]): first the point nearest the centroid, then
/// repeatedly the point farthest (Euclidean) from all chosen ones; ties go
/// to the lower index. Fewer when there are fewer distinct points.
pub(crate) fn farthest_point_sampling(points: &[[f64; 3]], n: usize) -> Vec<usize> {
    if points.is_empty() || n == 0 {
        return Vec::new();
    }
    let m = points.len() as f64;
    let mut c = [0.0; 3];
    for p in points {
        for d in 0..3 {
            c[d] += p[d] / m;
        }
    }
    let d2 = |a: [f64; 3], b: [f64; 3]| (0..3).map(|d| (a[d] - b[d]).powi(2)).sum::<f64>();
    // Nearest the centroid, the first on ties (NaN never wins).
    let mut first = (0, f64::INFINITY);
    for (k, &p) in points.iter().enumerate() {
        let d = d2(p, c);
        if d < first.1 {
            first = (k, d);
        }
    }
    // Squared distances order the points as the distances do.
    farthest_point_order(points.len(), &[first.0], n, |_, s, nearest| {
        for (k, p) in points.iter().enumerate() {
            nearest[k] = nearest[k].min(d2(*p, points[s]));
        }
    })
}

/// `n` pseudolandmarks of `mesh` spread evenly over its area: farthest-
/// point sampling of an area-uniform sample of `max(16 n, 4096)` points
/// (seed `seed`).
pub fn pseudolandmarks(mesh: &Mesh, n: usize, seed: u64) -> Vec<MeshPoint> {
    let dense = area_uniform_points(mesh, (16 * n).max(4096), seed);
    let positions: Vec<[f64; 3]> = dense
        .iter()
        .filter_map(|p| p.position(&mesh.vertices, &mesh.faces))
        .collect();
    farthest_point_sampling(&positions, n)
        .into_iter()
        .map(|k| dense[k])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use morphoid_synth::mesh::square_grid;

    #[test]
    fn farthest_points_on_a_line_bisect() {
        let pts: Vec<[f64; 3]> = (0..=8).map(|i| [i as f64, 0.0, 0.0]).collect();
        // Centre first, then an end, then the other end, then the quarters.
        assert_eq!(farthest_point_sampling(&pts, 5), vec![4, 0, 8, 2, 6]);
        assert_eq!(farthest_point_sampling(&pts, 50).len(), 9);
        assert!(farthest_point_sampling(&[], 3).is_empty());
    }

    #[test]
    fn area_uniform_points_fill_halves_equally() {
        let mesh = square_grid(8);
        let pts = area_uniform_points(&mesh, 20000, 7);
        let xs: Vec<[f64; 3]> = pts
            .iter()
            .map(|p| p.position(&mesh.vertices, &mesh.faces).unwrap())
            .collect();
        let (lo, hi) = bounds(&mesh);
        let mid = 0.5 * (lo + hi);
        let left = xs.iter().filter(|p| p[0] < mid).count() as f64;
        assert!((left / 20000.0 - 0.5).abs() < 0.02, "{left}");
        assert_eq!(
            area_uniform_points(&mesh, 10, 7),
            area_uniform_points(&mesh, 10, 7)
        );
    }

    fn bounds(mesh: &Mesh) -> (f64, f64) {
        let xs = mesh.vertices.iter().map(|v| v[0]);
        let lo = xs.clone().fold(f64::INFINITY, f64::min);
        (lo, xs.fold(f64::NEG_INFINITY, f64::max))
    }

    #[test]
    fn pseudolandmarks_are_spread_out() {
        let mesh = square_grid(16);
        let pl = pseudolandmarks(&mesh, 64, 1);
        assert_eq!(pl.len(), 64);
        let xs: Vec<[f64; 3]> = pl
            .iter()
            .map(|p| p.position(&mesh.vertices, &mesh.faces).unwrap())
            .collect();
        // The closest pair is not much closer than a 8×8 grid spacing.
        let (lo, hi) = bounds(&mesh);
        let spacing = (hi - lo) / 8.0;
        let mut min = f64::INFINITY;
        for i in 0..xs.len() {
            for j in i + 1..xs.len() {
                let d = (0..3)
                    .map(|d| (xs[i][d] - xs[j][d]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                min = min.min(d);
            }
        }
        assert!(min > 0.5 * spacing, "{min} vs {spacing}");
    }
}
