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
fn hyperbolic_distance(z: [f64; 2], w: [f64; 2]) -> f64 {
    // |z − w| / |1 − z̄ w|
    let num = (z[0] - w[0]).hypot(z[1] - w[1]);
    let re = 1.0 - (z[0] * w[0] + z[1] * w[1]);
    let im = -(z[0] * w[1] - z[1] * w[0]);
    let den = re.hypot(im);
    if den <= 0.0 {
        return f64::INFINITY;
    }
    let r = (num / den).min(1.0 - 1e-15);
    2.0 * r.atanh()
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
            let d = hyperbolic_distance(p, q);
            if best.is_none_or(|(_, bd)| d < bd) {
                best = Some((k, d));
            }
        }
        best
    };
    let mut out = Vec::new();
    for (i, &p) in a.iter().enumerate() {
        if let Some((j, d)) = nearest(p, b) {
            if d < max_distance && nearest(b[j], a).map(|(k, _)| k) == Some(i) {
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
