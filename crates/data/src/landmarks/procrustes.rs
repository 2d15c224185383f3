//! The discrete Procrustes distance between two landmark sets: the
//! paper's observer-determined landmark Procrustes (ODLP) distance.
//!
//! The paper (section 2) defines `d_P(X, Y) = min_R (Σ |R(X_n) − Y_n|²)^½`
//! over rigid motions `R`. Landmark files come in arbitrary units (mm, µm)
//! and the cP distance compares surfaces scaled to area 1, so, as is usual
//! in geometric morphometrics, each set is first centred and scaled to unit
//! centroid size (`Σ |X_n − X̄|² = 1`); the translation is then optimal
//! and the minimum is taken over rotations (proper only unless reflections
//! are allowed). The result is in `[0, 2]`.

use morphoid_core::cp::{Handedness, Moments};

/// Why two landmark sets cannot be compared.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProcrustesError {
    /// The sets have different numbers of landmarks.
    #[error("{left} landmarks against {right}")]
    CountMismatch {
        /// Landmarks of the first set.
        left: usize,
        /// Landmarks of the second set.
        right: usize,
    },
    /// Fewer than two landmarks, or all at one point: no shape to compare.
    #[error("the landmarks have no extent (fewer than two distinct points)")]
    Degenerate,
    /// A coordinate is NaN or infinite.
    #[error("a landmark coordinate is not finite")]
    NonFinite,
}

/// The set centred at its centroid and scaled to unit centroid size.
fn standardize(points: &[[f64; 3]]) -> Result<Vec<[f64; 3]>, ProcrustesError> {
    if points.iter().flatten().any(|v| !v.is_finite()) {
        return Err(ProcrustesError::NonFinite);
    }
    let n = points.len() as f64;
    let mut c = [0.0; 3];
    for p in points {
        for d in 0..3 {
            c[d] += p[d] / n;
        }
    }
    let centred: Vec<[f64; 3]> = points
        .iter()
        .map(|p| [p[0] - c[0], p[1] - c[1], p[2] - c[2]])
        .collect();
    let size = centred
        .iter()
        .map(|p| p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
        .sum::<f64>()
        .sqrt();
    if points.len() < 2 || !(size.is_finite() && size > 0.0) {
        return Err(ProcrustesError::Degenerate);
    }
    Ok(centred.iter().map(|p| p.map(|v| v / size)).collect())
}

/// The Procrustes distance between the landmark sets `a` and `b` (paired
/// by index): both centred and scaled to unit centroid size, then the
/// square root of the residual sum of squares after the optimal rotation
/// of `a` onto `b` (a rotation combined with a reflection too when
/// `allow_reflection`). Symmetric, and 0 exactly when the sets differ by a
/// similarity transformation.
pub fn procrustes_distance(
    a: &[[f64; 3]],
    b: &[[f64; 3]],
    allow_reflection: bool,
) -> Result<f64, ProcrustesError> {
    if a.len() != b.len() {
        return Err(ProcrustesError::CountMismatch {
            left: a.len(),
            right: b.len(),
        });
    }
    let (x, y) = (standardize(a)?, standardize(b)?);
    let mut m = Moments::default();
    for (p, q) in x.iter().zip(&y) {
        m.add(*p, *q, 1.0);
    }
    let mut rss = m.residual(Handedness::Proper);
    if allow_reflection {
        rss = rss.min(m.residual(Handedness::Improper));
    }
    Ok(rss.max(0.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square against a rhombus, worked by hand: unit centroid size
    /// gives X = (±½, 0), (0, ±½) and Y = (±2, 0)/√10, (0, ±1)/√10; the
    /// cross-covariance is diag(2/√10, 1/√10, 0), the identity is the best
    /// rotation and RSS = 1 + 1 − 2·3/√10.
    #[test]
    fn square_against_rhombus_by_hand() {
        let x = [[1., 0., 0.], [0., 1., 0.], [-1., 0., 0.], [0., -1., 0.]];
        let y = [[2., 0., 0.], [0., 1., 0.], [-2., 0., 0.], [0., -1., 0.]];
        let want = (2.0 - 6.0 / 10f64.sqrt()).sqrt();
        let d = procrustes_distance(&x, &y, false).unwrap();
        assert!((d - want).abs() < 1e-12, "{d} vs {want}");
        assert!((want - 0.320_364_486).abs() < 1e-9);
        // Symmetric, and blind to translation, scale and rotation.
        assert!((procrustes_distance(&y, &x, false).unwrap() - want).abs() < 1e-12);
        let moved: Vec<[f64; 3]> = y
            .iter()
            .map(|p| {
                [
                    -1000.0 * p[1] + 5.0,
                    1000.0 * p[0] - 3.0,
                    1000.0 * p[2] + 7.0,
                ]
            })
            .collect();
        assert!((procrustes_distance(&x, &moved, false).unwrap() - want).abs() < 1e-12);
    }

    #[test]
    fn mirror_images_only_match_with_reflection() {
        let x = [[0., 0., 0.], [1., 0., 0.], [0., 2., 0.], [0., 0., 3.]];
        let m: Vec<[f64; 3]> = x.iter().map(|p| [-p[0], p[1], p[2]]).collect();
        assert!(procrustes_distance(&x, &m, true).unwrap() < 1e-12);
        assert!(procrustes_distance(&x, &m, false).unwrap() > 0.1);
        assert!(procrustes_distance(&x, &x, false).unwrap() < 1e-12);
    }

    #[test]
    fn bad_sets_are_errors() {
        let x = [[0., 0., 0.], [1., 0., 0.]];
        assert_eq!(
            procrustes_distance(&x, &x[..1], false),
            Err(ProcrustesError::CountMismatch { left: 2, right: 1 })
        );
        let same = [[1., 1., 1.], [1., 1., 1.]];
        assert_eq!(
            procrustes_distance(&same, &x, false),
            Err(ProcrustesError::Degenerate)
        );
        let nan = [[f64::NAN, 0., 0.], [1., 0., 0.]];
        assert_eq!(
            procrustes_distance(&nan, &x, false),
            Err(ProcrustesError::NonFinite)
        );
    }
}
