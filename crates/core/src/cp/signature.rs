//! The screening signature of a prepared surface: about 140 bytes that
//! rank a large library by likeness to a scan before the cP distance is
//! computed for the best few (see `docs/design.md`, "Screening").
//!
//! Two descriptions of the normalized surface (area 1) that do not depend
//! on its position, orientation, size, mesh or flattening:
//! - the distribution of its points' distances from its area centroid,
//!   held as the cumulative distribution at fixed points, so that the L1
//!   difference of two is the 1-Wasserstein (earth mover's) distance;
//! - its spread along its principal axes: the square roots of the
//!   eigenvalues of its area-weighted second moments.
//!
//! Chosen by measurement on the 116 real teeth, against the shape
//! distribution D2, heights and radii about the crown's axis, the margin's
//! length, the conformal density and the coarse cP search's best score:
//! these two, each divided by its median over the teeth's pairs and
//! summed, keep the exhaustive nearest reference of every tooth among
//! the best 32 of 115 (`docs/design.md` has the table).

use super::prepared::Prepared;
use nalgebra::{Matrix3, SymmetricEigen};
use serde::{Deserialize, Serialize};

/// Points at which the distribution of centroid distances is held.
const BINS: usize = 32;

/// Range of the distances from the centroid on a surface of area 1.
const RADIAL_RANGE: f64 = 1.0;

/// The median over the pairs of the 116 real teeth of each term of
/// [`signature_distance`], so that the two terms weigh alike.
const RADIAL_SCALE: f64 = 0.0143;
const SPREAD_SCALE: f64 = 0.0377;

/// A prepared surface's screening signature (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Signature {
    /// Cumulative distribution of the area-weighted distances from the
    /// centroid at `BINS` evenly spaced points of `(0, RADIAL_RANGE]`.
    radial: Vec<f32>,
    /// Square roots of the eigenvalues of the area-weighted second
    /// moments, largest first.
    spread: [f32; 3],
}

/// The screening signature of `p` (see the module docs).
pub fn shape_signature(p: &Prepared) -> Signature {
    Signature {
        radial: cumulative(&centroid_distances(p), BINS, RADIAL_RANGE),
        spread: principal_spreads(p),
    }
}

/// How unlike two signatures are: the 1-Wasserstein distance between
/// their distributions of centroid distances plus the L1 difference of
/// their principal spreads, each divided by its median over the real
/// teeth. Zero for equal signatures and symmetric; a screen, not a
/// distance an answer is read from.
pub fn signature_distance(a: &Signature, b: &Signature) -> f64 {
    let [radial, spread] = signature_terms(a, b);
    radial / RADIAL_SCALE + spread / SPREAD_SCALE
}

/// The two terms of [`signature_distance`] before scaling: the
/// 1-Wasserstein distance of the centroid distances and the L1 difference
/// of the spreads (for measuring the scales).
pub fn signature_terms(a: &Signature, b: &Signature) -> [f64; 2] {
    let l1 = |x: &[f32], y: &[f32]| -> f64 {
        x.iter()
            .zip(y)
            .map(|(&u, &v)| f64::from((u - v).abs()))
            .sum::<f64>()
    };
    [
        l1(&a.radial, &b.radial) * RADIAL_RANGE / BINS as f64,
        l1(&a.spread, &b.spread),
    ]
}

/// Each vertex's distance from the area centroid (the origin of the
/// normalized surface), weighted by its area.
fn centroid_distances(p: &Prepared) -> Vec<(f64, f64)> {
    p.vertices
        .iter()
        .zip(&p.vertex_areas)
        .map(|(v, &a)| ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt(), a))
        .collect()
}

/// Square roots of the eigenvalues of the area-weighted second moments
/// about the centroid, largest first.
fn principal_spreads(p: &Prepared) -> [f32; 3] {
    let mut m = Matrix3::<f64>::zeros();
    for (v, &a) in p.vertices.iter().zip(&p.vertex_areas) {
        for r in 0..3 {
            for c in 0..3 {
                m[(r, c)] += a * v[r] * v[c];
            }
        }
    }
    let mut e: Vec<f64> = SymmetricEigen::new(m)
        .eigenvalues
        .iter()
        .map(|&x: &f64| x.max(0.0).sqrt())
        .collect();
    e.sort_by(|a, b| b.total_cmp(a));
    [e[0] as f32, e[1] as f32, e[2] as f32]
}

/// The weighted cumulative distribution of `values` (value, weight) at
/// `bins` evenly spaced points of `(0, range]`, normalized by the total
/// weight (all zeros without weight).
fn cumulative(values: &[(f64, f64)], bins: usize, range: f64) -> Vec<f32> {
    let mut mass = vec![0.0f64; bins];
    let mut total = 0.0;
    for &(x, w) in values {
        if !(x.is_finite() && w.is_finite() && w > 0.0) {
            continue;
        }
        total += w;
        // The bin whose right end is the first point at or past x; values
        // beyond the range count at the last point.
        let k = ((x / range) * bins as f64).ceil().max(1.0) as usize - 1;
        mass[k.min(bins - 1)] += w;
    }
    let mut acc = 0.0;
    mass.iter()
        .map(|&m| {
            acc += m;
            if total > 0.0 {
                (acc / total) as f32
            } else {
                0.0
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cp::{prepare, PrepareParams};
    use crate::testing::synth::{self, CROWN_GENERA};

    fn prepared(m: &crate::mesh::Mesh) -> Prepared {
        prepare(m, &PrepareParams::default()).expect("prepare")
    }

    #[test]
    fn a_moved_scaled_copy_has_nearly_the_same_signature_and_another_genus_not() {
        let m = synth::crown(&CROWN_GENERA[1], 3, 1500);
        let a = shape_signature(&prepared(&m));
        let moved = shape_signature(&prepared(&synth::scale(&synth::rigid_motion(&m, 5), 2.5)));
        let other = shape_signature(&prepared(&synth::crown(&CROWN_GENERA[3], 3, 1500)));
        let near = signature_distance(&a, &moved);
        let unlike = signature_distance(&a, &other);
        assert!(
            near < unlike / 20.0,
            "moved copy {near}, other genus {unlike}"
        );
        assert_eq!(signature_distance(&a, &a), 0.0);
        assert_eq!(unlike, signature_distance(&other, &a));
    }

    #[test]
    fn the_cumulative_distribution_is_monotone_and_ends_at_one() {
        let c = cumulative(&[(0.1, 1.0), (0.5, 2.0), (9.0, 1.0)], 8, 1.0);
        assert!(c.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(c[7], 1.0);
        assert_eq!(c[0], 0.25);
        assert!(cumulative(&[], 4, 1.0).iter().all(|&x| x == 0.0));
    }
}
