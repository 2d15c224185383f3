//! Automorphisms of the unit disk (Möbius transformations), both
//! orientation-preserving and orientation-reversing.

use nalgebra::Complex;
use serde::{Deserialize, Serialize};

/// A complex number as plain data.
pub(super) type C = Complex<f64>;

/// A disk automorphism `z ↦ (α w + β) / (β̄ w + ᾱ)` with `w = z̄` when
/// `reflect` is set and `w = z` otherwise (`|β| < |α|`).
///
/// Every orientation-preserving automorphism has this form, in particular
/// `e^{iθ} (z − a) / (1 − ā z)` (see [`Mobius::from_point_rotation`]);
/// composing with conjugation gives the orientation-reversing ones.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Mobius {
    /// Coefficient α as `[re, im]`.
    pub alpha: [f64; 2],
    /// Coefficient β as `[re, im]`.
    pub beta: [f64; 2],
    /// Whether the argument is conjugated first (orientation reversal).
    pub reflect: bool,
}

#[inline]
fn c(v: [f64; 2]) -> C {
    C::new(v[0], v[1])
}

#[inline]
fn arr(z: C) -> [f64; 2] {
    [z.re, z.im]
}

impl Mobius {
    /// The identity map.
    pub fn identity() -> Self {
        Self {
            alpha: [1.0, 0.0],
            beta: [0.0, 0.0],
            reflect: false,
        }
    }

    /// `z ↦ e^{iθ} (z − a) / (1 − ā z)`: sends `a` to 0, then rotates by θ.
    pub fn from_point_rotation(a: [f64; 2], theta: f64) -> Self {
        let h = C::from_polar(1.0, 0.5 * theta);
        Self {
            alpha: arr(h),
            beta: arr(-h * c(a)),
            reflect: false,
        }
    }

    /// The rotation `z ↦ e^{iθ} z`.
    pub fn rotation(theta: f64) -> Self {
        Self::from_point_rotation([0.0, 0.0], theta)
    }

    /// Complex conjugation `z ↦ z̄` (orientation reversal).
    pub fn conjugation() -> Self {
        Self {
            reflect: true,
            ..Self::identity()
        }
    }

    /// The map sending `p` to `q` whose derivative at `p`, after the
    /// normalizations `p ↦ 0` and `0 ↦ q`, is the rotation by θ:
    /// `m = T_q⁻¹ ∘ R_θ ∘ [conj] ∘ T_p` with `T_a(z) = (z − a)/(1 − ā z)`.
    /// With `reflect` the map reverses orientation.
    pub fn sending(p: [f64; 2], q: [f64; 2], theta: f64, reflect: bool) -> Self {
        let tp = Self::from_point_rotation(p, 0.0);
        let tq_inv = Self::from_point_rotation(q, 0.0).inverse();
        let mut m = Self::rotation(theta);
        if reflect {
            m = m.compose(&Self::conjugation());
        }
        tq_inv.compose(&m.compose(&tp))
    }

    /// Image of `z`.
    #[inline]
    pub fn apply(&self, z: [f64; 2]) -> [f64; 2] {
        let w = if self.reflect { c(z).conj() } else { c(z) };
        let (a, b) = (c(self.alpha), c(self.beta));
        arr((a * w + b) / (b.conj() * w + a.conj()))
    }

    /// `self ∘ other` (apply `other` first).
    pub fn compose(&self, other: &Self) -> Self {
        let (a1, b1) = (c(self.alpha), c(self.beta));
        // self ∘ conj = (self with conjugated coefficients) applied after conj.
        let (a2, b2) = if self.reflect {
            (c(other.alpha).conj(), c(other.beta).conj())
        } else {
            (c(other.alpha), c(other.beta))
        };
        let alpha = a1 * a2 + b1 * b2.conj();
        let beta = a1 * b2 + b1 * a2.conj();
        // Keep |α|² − |β|² = 1 so that coefficients do not drift.
        let det = (alpha.norm_sqr() - beta.norm_sqr())
            .max(f64::MIN_POSITIVE)
            .sqrt();
        Self {
            alpha: arr(alpha / det),
            beta: arr(beta / det),
            reflect: self.reflect != other.reflect,
        }
    }

    /// The inverse map.
    pub fn inverse(&self) -> Self {
        let (a, b) = (c(self.alpha), c(self.beta));
        // Inverse of the holomorphic part: (ᾱ z − β)/(−β̄ z + α).
        let g_inv = Self {
            alpha: arr(a.conj()),
            beta: arr(-b),
            reflect: false,
        };
        if self.reflect {
            // (g ∘ conj)⁻¹ = conj ∘ g⁻¹ = (conjugated g⁻¹) ∘ conj.
            Self::conjugation().compose(&g_inv)
        } else {
            g_inv
        }
    }

    /// Whether the map reverses orientation.
    pub fn reverses_orientation(&self) -> bool {
        self.reflect
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f64; 2], b: [f64; 2]) -> bool {
        (a[0] - b[0]).hypot(a[1] - b[1]) < 1e-12
    }

    fn pts() -> Vec<[f64; 2]> {
        vec![
            [0.0, 0.0],
            [0.3, -0.2],
            [-0.7, 0.5],
            [0.1, 0.9],
            [0.99, 0.0],
        ]
    }

    #[test]
    fn matches_closed_form() {
        let a = [0.3, -0.4];
        let th = 0.7;
        let m = Mobius::from_point_rotation(a, th);
        for z in pts() {
            let zc = c(z);
            let ac = c(a);
            let want = C::from_polar(1.0, th) * (zc - ac) / (C::new(1.0, 0.0) - ac.conj() * zc);
            assert!(close(m.apply(z), arr(want)));
        }
    }

    #[test]
    fn preserves_the_disk_and_its_boundary() {
        let m = Mobius::sending([0.2, 0.5], [-0.6, 0.1], 1.3, true);
        for k in 0..32 {
            let t = k as f64 * 0.2;
            let z = [t.cos(), t.sin()];
            let w = m.apply(z);
            assert!((w[0].hypot(w[1]) - 1.0).abs() < 1e-12);
            let z = [0.8 * t.cos(), 0.8 * t.sin()];
            let w = m.apply(z);
            assert!(w[0].hypot(w[1]) < 1.0);
        }
    }

    #[test]
    fn sending_maps_p_to_q_in_both_orientations() {
        for reflect in [false, true] {
            let p = [0.2, 0.5];
            let q = [-0.6, 0.1];
            let m = Mobius::sending(p, q, 0.4, reflect);
            assert!(close(m.apply(p), q));
            assert_eq!(m.reverses_orientation(), reflect);
        }
    }

    #[test]
    fn compose_and_inverse_agree_with_application() {
        let ms = [
            Mobius::from_point_rotation([0.3, 0.1], 0.5),
            Mobius::sending([0.2, -0.5], [0.1, 0.6], -1.0, true),
            Mobius::conjugation(),
            Mobius::sending([-0.4, 0.0], [0.0, 0.3], 2.0, true),
        ];
        for m1 in &ms {
            for m2 in &ms {
                let m = m1.compose(m2);
                let inv = m.inverse();
                for z in pts() {
                    assert!(close(m.apply(z), m1.apply(m2.apply(z))));
                    assert!(close(inv.apply(m.apply(z)), z));
                }
            }
        }
    }

    #[test]
    fn orientation_reversal_is_conjugation() {
        let m = Mobius::sending([0.0, 0.0], [0.0, 0.0], 0.0, true);
        assert!(close(m.apply([0.3, 0.4]), [0.3, -0.4]));
    }
}
