//! A smooth deformation ϱ of the disk that moves a few points onto given
//! targets: a Gaussian radial-basis displacement field, which is the
//! identity away from the points (and so near the boundary).

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// `z ↦ z + Σᵢ cᵢ exp(−|z − zᵢ|² / σ²)`, clamped to the closed unit disk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DiskWarp {
    /// Centres zᵢ (the points that are moved).
    pub centers: Vec<[f64; 2]>,
    /// Displacement coefficients cᵢ.
    pub coefficients: Vec<[f64; 2]>,
    /// Width σ of the Gaussian kernel.
    pub width: f64,
}

/// Hyperbolic distance between two points of the unit disk.
#[cfg(test)]
fn hyperbolic_distance(z: [f64; 2], w: [f64; 2]) -> f64 {
    let r = pseudo_hyperbolic_squared(z, w).sqrt().min(1.0 - 1e-15);
    2.0 * r.atanh()
}

/// The squared pseudo-hyperbolic distance `|z − w|² / |1 − z̄ w|²` of two
/// points of the unit disk: the hyperbolic distance is `2 atanh` of its
/// square root, so it orders pairs as that does, without the square root
/// and the logarithm (a comparison's search asks for it millions of times).
fn pseudo_hyperbolic_squared(z: [f64; 2], w: [f64; 2]) -> f64 {
    let (dx, dy) = (z[0] - w[0], z[1] - w[1]);
    let re = 1.0 - (z[0] * w[0] + z[1] * w[1]);
    let im = -(z[0] * w[1] - z[1] * w[0]);
    let den = re * re + im * im;
    if den <= 0.0 {
        return f64::INFINITY;
    }
    (dx * dx + dy * dy) / den
}

/// Pairs `(i, j)` such that `a[i]` and `b[j]` are each other's nearest
/// point (hyperbolic distance) and closer than `max_distance`.
pub(super) fn mutually_nearest(
    a: &[[f64; 2]],
    b: &[[f64; 2]],
    max_distance: f64,
) -> Vec<(usize, usize)> {
    let nearest = |p: [f64; 2], set: &[[f64; 2]]| -> Option<(usize, f64)> {
        let mut best: Option<(usize, f64)> = None;
        for (k, &q) in set.iter().enumerate() {
            let d = pseudo_hyperbolic_squared(p, q);
            if best.is_none_or(|(_, bd)| d < bd) {
                best = Some((k, d));
            }
        }
        best
    };
    // The same bound on the squared pseudo-hyperbolic distance.
    let bound = (0.5 * max_distance).tanh().powi(2);
    let within = |d: f64| max_distance > 0.0 && (max_distance.is_infinite() || d < bound);
    let mut out = Vec::new();
    for (i, &p) in a.iter().enumerate() {
        if let Some((j, d)) = nearest(p, b) {
            if within(d) && nearest(b[j], a).map(|(k, _)| k) == Some(i) {
                out.push((i, j));
            }
        }
    }
    out
}

impl DiskWarp {
    /// The warp with kernel width `width` moving each `from[i]` exactly to
    /// `to[i]`; `None` if there are no points or the system is singular.
    pub fn interpolating(from: &[[f64; 2]], to: &[[f64; 2]], width: f64) -> Option<Self> {
        let n = from.len();
        if n == 0 || to.len() != n || width.is_nan() || width <= 0.0 {
            return None;
        }
        let k = DMatrix::from_fn(n, n, |i, j| kernel(from[i], from[j], width));
        let lu = k.lu();
        let mut coefficients = vec![[0.0; 2]; n];
        for d in 0..2 {
            let rhs = DVector::from_fn(n, |i, _| to[i][d] - from[i][d]);
            let c = lu.solve(&rhs)?;
            for i in 0..n {
                if !c[i].is_finite() {
                    return None;
                }
                coefficients[i][d] = c[i];
            }
        }
        Some(Self {
            centers: from.to_vec(),
            coefficients,
            width,
        })
    }

    /// Image of `z`.
    #[inline]
    pub fn apply(&self, z: [f64; 2]) -> [f64; 2] {
        let mut w = z;
        for (c, k) in self.centers.iter().zip(&self.coefficients) {
            let g = kernel(z, *c, self.width);
            w[0] += g * k[0];
            w[1] += g * k[1];
        }
        let r2 = w[0] * w[0] + w[1] * w[1];
        if r2 > 1.0 {
            let r = r2.sqrt();
            [w[0] / r, w[1] / r]
        } else {
            w
        }
    }
}

#[inline]
fn kernel(a: [f64; 2], b: [f64; 2], width: f64) -> f64 {
    let d2 = (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2);
    (-d2 / (width * width)).exp()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The proxy orders pairs as the hyperbolic distance does, and its
    /// bound keeps the same pairs, on scattered points of the disk.
    #[test]
    fn the_squared_pseudo_distance_orders_and_bounds_as_the_distance() {
        let point = |k: usize| {
            let t = k as f64 * 2.399;
            let r = 0.97 * ((k * 7919) % 1000) as f64 / 1000.0;
            [r * t.cos(), r * t.sin()]
        };
        let points: Vec<[f64; 2]> = (0..60).map(point).collect();
        for &z in &points {
            for (&a, &b) in points.iter().zip(points.iter().skip(1)) {
                let (da, db) = (hyperbolic_distance(z, a), hyperbolic_distance(z, b));
                let (pa, pb) = (
                    pseudo_hyperbolic_squared(z, a),
                    pseudo_hyperbolic_squared(z, b),
                );
                if (da - db).abs() > 1e-9 {
                    assert_eq!(da < db, pa < pb, "{z:?} {a:?} {b:?}");
                }
            }
            for max in [0.1, 0.5, 1.0, 3.0] {
                let bound = (0.5f64 * max).tanh().powi(2);
                for &a in &points {
                    let d = hyperbolic_distance(z, a);
                    if (d - max).abs() > 1e-9 {
                        assert_eq!(d < max, pseudo_hyperbolic_squared(z, a) < bound);
                    }
                }
            }
        }
        // No pair at all under a bound that is not positive.
        assert!(mutually_nearest(&points, &points, 0.0).is_empty());
        assert!(mutually_nearest(&points, &points, -1.0).is_empty());
        assert_eq!(mutually_nearest(&points, &points, f64::INFINITY).len(), 60);
    }

    #[test]
    fn interpolates_and_is_identity_far_away() {
        let from = [[0.1, 0.2], [-0.3, 0.0], [0.2, -0.4]];
        let to = [[0.12, 0.22], [-0.31, 0.02], [0.2, -0.38]];
        let w = DiskWarp::interpolating(&from, &to, 0.2).unwrap();
        for (f, t) in from.iter().zip(&to) {
            let g = w.apply(*f);
            assert!((g[0] - t[0]).abs() < 1e-12 && (g[1] - t[1]).abs() < 1e-12);
        }
        let far = w.apply([0.95, 0.0]);
        assert!((far[0] - 0.95).abs() < 1e-6 && far[1].abs() < 1e-6);
    }

    #[test]
    fn hyperbolic_distance_from_origin_and_mutual_pairs() {
        let d = hyperbolic_distance([0.0, 0.0], [0.5, 0.0]);
        assert!((d - (1.5f64 / 0.5).ln()).abs() < 1e-12);
        let a = [[0.0, 0.0], [0.5, 0.0]];
        let b = [[0.05, 0.0], [0.6, 0.0], [-0.5, 0.0]];
        assert_eq!(mutually_nearest(&a, &b, 10.0), vec![(0, 0), (1, 1)]);
        assert_eq!(mutually_nearest(&a, &b, 0.2), vec![(0, 0)]);
    }
}
