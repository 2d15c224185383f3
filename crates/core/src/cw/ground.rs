//! The ground cost of cW: the hyperbolic distance of the disk, truncated.

/// `min(d(u, v), cap)` with `d` the hyperbolic distance of the unit disk
/// (the metric `4|dz|² / (1 − |z|²)²`, curvature −1, so
/// `d(0, z) = ln((1 + |z|)/(1 − |z|))`):
/// `cosh d = 1 + 2|u − v|² / ((1 − |u|²)(1 − |v|²))`.
///
/// Why truncated: a flattening puts the surface's rim on the circle
/// `|z| = 1`, at infinite hyperbolic distance from everything, and
/// samples lie there. `min(d, cap)` is still a metric and still invariant
/// under every disk automorphism (both properties cW inherits), and it
/// equals `d` wherever two points are closer than `cap`.
#[inline]
pub(crate) fn truncated_hyperbolic_distance(u: [f64; 2], v: [f64; 2], cap: f64) -> f64 {
    let q = 2.0 * ((u[0] - v[0]).powi(2) + (u[1] - v[1]).powi(2));
    if q == 0.0 {
        return 0.0;
    }
    let den = ((1.0 - u[0] * u[0] - u[1] * u[1]) * (1.0 - v[0] * v[0] - v[1] * v[1])).max(0.0);
    // d ≥ cap exactly when q ≥ den (cosh cap − 1); no division by 0.
    if q >= den * (cap.cosh() - 1.0) {
        cap
    } else {
        (1.0 + q / den).acosh()
    }
}

/// The row-major matrix `min(d(uᵢ, vⱼ), cap)`.
pub(super) fn cost_matrix(us: &[[f64; 2]], vs: &[[f64; 2]], cap: f64) -> Vec<f64> {
    let mut c = Vec::with_capacity(us.len() * vs.len());
    for &u in us {
        c.extend(vs.iter().map(|&v| truncated_hyperbolic_distance(u, v, cap)));
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cp::Mobius;

    #[test]
    fn distance_from_the_centre_is_the_closed_form_and_the_cap_holds() {
        for r in [0.1, 0.5, 0.9] {
            let d = truncated_hyperbolic_distance([0.0, 0.0], [r, 0.0], 100.0);
            let want = ((1.0 + r) / (1.0 - r)).ln();
            assert!((d - want).abs() < 1e-12, "{d} vs {want}");
        }
        assert_eq!(
            truncated_hyperbolic_distance([0.0, 0.0], [0.9, 0.0], 1.0),
            1.0
        );
        // The rim is infinitely far: the cap, never NaN.
        assert_eq!(
            truncated_hyperbolic_distance([1.0, 0.0], [0.0, 1.0], 3.0),
            3.0
        );
        assert_eq!(
            truncated_hyperbolic_distance([1.0, 0.0], [1.0, 0.0], 3.0),
            0.0
        );
    }

    #[test]
    fn the_distance_is_invariant_under_disk_automorphisms_and_a_metric() {
        let pts = [[0.1, 0.2], [-0.5, 0.3], [0.7, -0.6], [0.0, -0.95]];
        for reflect in [false, true] {
            let m = Mobius::sending([0.2, -0.1], [-0.3, 0.4], 1.1, reflect);
            for &u in &pts {
                for &v in &pts {
                    let a = truncated_hyperbolic_distance(u, v, 50.0);
                    let b = truncated_hyperbolic_distance(m.apply(u), m.apply(v), 50.0);
                    assert!((a - b).abs() < 1e-9 * a.max(1.0), "{a} vs {b}");
                    for &w in &pts {
                        for cap in [1.5, 50.0] {
                            let d = |x, y| truncated_hyperbolic_distance(x, y, cap);
                            assert!(d(u, w) <= d(u, v) + d(v, w) + 1e-12);
                        }
                    }
                }
            }
        }
    }
}
