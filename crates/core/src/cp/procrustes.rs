//! Weighted Procrustes (Kabsch) alignment of corresponding point sets.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Whether the rigid motion may be a reflection.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Handedness {
    /// A rotation (determinant +1).
    Proper,
    /// A rotation composed with a reflection (determinant −1).
    Improper,
}

/// The optimal rigid motion `x ↦ R x + t` and the weighted residual
/// `Σ wᵢ |R xᵢ + t − yᵢ|²`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RigidFit {
    /// The orthogonal matrix R, row-major.
    pub rotation: [[f64; 3]; 3],
    /// The translation t.
    pub translation: [f64; 3],
    /// The weighted sum of squared residuals (never negative).
    pub residual: f64,
}

/// Second moments of weighted point pairs: all that the optimal rigid
/// motion and its residual depend on. Accumulate with [`Moments::add`].
#[derive(Debug, Clone, Copy, Default)]
pub struct Moments {
    w: f64,
    sx: [f64; 3],
    sy: [f64; 3],
    sxx: f64,
    syy: f64,
    sxy: [[f64; 3]; 3],
}

impl Moments {
    /// Add the pair `(x, y)` with weight `w`.
    #[inline]
    pub fn add(&mut self, x: [f64; 3], y: [f64; 3], w: f64) {
        self.w += w;
        for i in 0..3 {
            self.sx[i] += w * x[i];
            self.sy[i] += w * y[i];
            self.sxx += w * x[i] * x[i];
            self.syy += w * y[i] * y[i];
            for (sxy, yj) in self.sxy[i].iter_mut().zip(y) {
                *sxy += w * x[i] * yj;
            }
        }
    }

    /// Weighted centroids `(x̄, ȳ)`; zero for zero total weight.
    fn centroids(&self) -> ([f64; 3], [f64; 3]) {
        if self.w <= 0.0 {
            return ([0.0; 3], [0.0; 3]);
        }
        (self.sx.map(|v| v / self.w), self.sy.map(|v| v / self.w))
    }

    /// Centred cross-covariance `Σ w (x − x̄)(y − ȳ)ᵀ` and the centred
    /// spreads `Σ w |x − x̄|²`, `Σ w |y − ȳ|²`.
    fn centred(&self) -> (Matrix3<f64>, f64, f64) {
        let (cx, cy) = self.centroids();
        let h = Matrix3::from_fn(|i, j| self.sxy[i][j] - self.w * cx[i] * cy[j]);
        let n2 = |v: [f64; 3]| v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
        (h, self.sxx - self.w * n2(cx), self.syy - self.w * n2(cy))
    }

    /// The minimal residual over rigid motions of the given handedness,
    /// without forming the motion.
    pub fn residual(&self, handedness: Handedness) -> f64 {
        let (h, vx, vy) = self.centred();
        let sv = h.singular_values();
        let mut s = [sv[0], sv[1], sv[2]];
        s.sort_by(|a, b| b.total_cmp(a));
        let sign = if h.determinant() >= 0.0 { 1.0 } else { -1.0 };
        let d = match handedness {
            Handedness::Proper => sign,
            Handedness::Improper => -sign,
        };
        let r = vx + vy - 2.0 * (s[0] + s[1] + d * s[2]);
        if r.is_finite() {
            r.max(0.0)
        } else {
            f64::MAX
        }
    }

    /// The optimal rigid motion of the given handedness and its residual.
    pub fn fit(&self, handedness: Handedness) -> RigidFit {
        let (h, _, _) = self.centred();
        let (cx, cy) = self.centroids();
        let svd = h.svd(true, true);
        let rot = match (svd.u, svd.v_t) {
            (Some(u), Some(vt)) => {
                let v = vt.transpose();
                let det = (v * u.transpose()).determinant();
                let want = match handedness {
                    Handedness::Proper => 1.0,
                    Handedness::Improper => -1.0,
                };
                // Flip the axis of the smallest singular value if needed.
                let mut k = 0;
                for i in 1..3 {
                    if svd.singular_values[i] < svd.singular_values[k] {
                        k = i;
                    }
                }
                let mut dg = Vector3::new(1.0, 1.0, 1.0);
                if det * want < 0.0 {
                    dg[k] = -1.0;
                }
                v * Matrix3::from_diagonal(&dg) * u.transpose()
            }
            _ => match handedness {
                Handedness::Proper => Matrix3::identity(),
                Handedness::Improper => Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0)),
            },
        };
        let rc = rot * Vector3::from(cx);
        let t = Vector3::from(cy) - rc;
        let rotation = [0, 1, 2].map(|i| [0, 1, 2].map(|j| rot[(i, j)]));
        RigidFit {
            rotation,
            translation: [t[0], t[1], t[2]],
            residual: self.residual(handedness),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Weighted Procrustes: the rigid motion of the given handedness that best
    /// maps `x` onto `y` (pairs by index) with weights `w`.
    fn weighted_procrustes(
        x: &[[f64; 3]],
        y: &[[f64; 3]],
        w: &[f64],
        handedness: Handedness,
    ) -> RigidFit {
        let mut m = Moments::default();
        for ((a, b), &wi) in x.iter().zip(y).zip(w) {
            m.add(*a, *b, wi);
        }
        m.fit(handedness)
    }

    /// Apply a rigid motion to a point.
    fn apply_rigid(fit: &RigidFit, x: [f64; 3]) -> [f64; 3] {
        let r = &fit.rotation;
        [0, 1, 2].map(|i| r[i][0] * x[0] + r[i][1] * x[1] + r[i][2] * x[2] + fit.translation[i])
    }

    fn rot(ax: f64, ay: f64) -> Matrix3<f64> {
        let rx = nalgebra::Rotation3::from_euler_angles(ax, ay, 0.3);
        *rx.matrix()
    }

    fn cloud() -> Vec<[f64; 3]> {
        (0..20)
            .map(|i| {
                let t = i as f64;
                [(t * 0.7).sin(), (t * 1.3).cos(), (t * 0.29).sin() * 0.5]
            })
            .collect()
    }

    #[test]
    fn recovers_a_rotation_and_translation() {
        let x = cloud();
        let r = rot(0.4, -1.1);
        let y: Vec<[f64; 3]> = x
            .iter()
            .map(|p| {
                let q = r * Vector3::from(*p) + Vector3::new(1.0, -2.0, 0.5);
                [q[0], q[1], q[2]]
            })
            .collect();
        let w: Vec<f64> = (0..x.len()).map(|i| 1.0 + i as f64 * 0.1).collect();
        let fit = weighted_procrustes(&x, &y, &w, Handedness::Proper);
        assert!(fit.residual < 1e-18 * 1e6);
        for (p, q) in x.iter().zip(&y) {
            let z = apply_rigid(&fit, *p);
            assert!((0..3).all(|k| (z[k] - q[k]).abs() < 1e-9));
        }
        // A reflection cannot do as well.
        assert!(weighted_procrustes(&x, &y, &w, Handedness::Improper).residual > 1e-3);
    }

    #[test]
    fn recovers_a_reflection_and_residual_matches_motion() {
        let x = cloud();
        let r = rot(1.0, 0.2) * Matrix3::from_diagonal(&Vector3::new(-1.0, 1.0, 1.0));
        let y: Vec<[f64; 3]> = x
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let q = r * Vector3::from(*p);
                [q[0] + 0.01 * (i as f64).sin(), q[1], q[2]]
            })
            .collect();
        let w = vec![0.5; x.len()];
        let fit = weighted_procrustes(&x, &y, &w, Handedness::Improper);
        let m = Matrix3::from_fn(|i, j| fit.rotation[i][j]);
        assert!((m.determinant() + 1.0).abs() < 1e-9);
        let direct: f64 = x
            .iter()
            .zip(&y)
            .map(|(p, q)| {
                let z = apply_rigid(&fit, *p);
                0.5 * (0..3).map(|k| (z[k] - q[k]).powi(2)).sum::<f64>()
            })
            .sum();
        assert!((direct - fit.residual).abs() < 1e-10);
        assert!(fit.residual < 1e-3);
    }
}
