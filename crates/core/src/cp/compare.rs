//! The cP distance between two prepared surfaces: both directed
//! comparisons (search, then the final descent) and the smaller distance.

use super::comparison::{Comparison, Directed};
use super::descent::procrustes_descent;
use super::params::CompareParams;
use super::prepared::Prepared;
use super::search::search_directed;

/// The directed comparison `S → S′`: the searched map (see
/// [`search_directed`]) lowered by the final descent.
pub fn compare_directed(s: &Prepared, t: &Prepared, params: &CompareParams) -> Directed {
    let mut d = search_directed(s, t, params);
    procrustes_descent(s, t, &mut d, params);
    d
}

/// The cP distance between two prepared surfaces: both directed
/// comparisons and the smaller of the two. Only the direction with the
/// smaller distance after the search goes through the final descent
/// (unless `descent_both_directions`); the other's distance is that of its
/// searched map, an upper bound.
pub fn compare(s: &Prepared, t: &Prepared, params: &CompareParams) -> Comparison {
    let mut forward = search_directed(s, t, params);
    let mut backward = search_directed(t, s, params);
    // The descent is the dearest final step, and it lowers both directions
    // by similar amounts: the direction that is better after the search is
    // the one the distance comes from, so by default only it is descended.
    let forward_better = forward.distance <= backward.distance;
    if params.descent_both_directions || forward_better {
        procrustes_descent(s, t, &mut forward, params);
    }
    if params.descent_both_directions || !forward_better {
        procrustes_descent(t, s, &mut backward, params);
    }
    let (distance, reflected) = if forward.distance <= backward.distance {
        (forward.distance, forward.reflected)
    } else {
        (backward.distance, backward.reflected)
    };
    Comparison {
        distance,
        forward,
        backward,
        reflected,
    }
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
    fn a_moved_copy_is_near_and_a_mirror_image_is_near_by_a_reflection() {
        let params = CompareParams::default();
        let m = synth::crown(&CROWN_GENERA[1], 3, 1500);
        let a = prepared(&m);
        let moved = prepared(&synth::scale(&synth::rigid_motion(&m, 5), 2.5));
        let c = compare(&a, &moved, &params);
        assert!(c.distance < 1e-3 && !c.reflected, "{}", c.distance);
        let mirrored = prepared(&synth::mirror(&m));
        let c = compare(&a, &mirrored, &params);
        assert!(c.distance < 1e-3 && c.reflected, "{}", c.distance);
        let without = CompareParams {
            reflections: false,
            ..params
        };
        assert!(compare(&a, &mirrored, &without).distance > 10.0 * c.distance);
    }

    #[test]
    fn the_distance_is_the_better_direction_and_only_that_one_is_descended() {
        let params = CompareParams::default();
        let a = prepared(&synth::crown(&CROWN_GENERA[0], 1, 1500));
        let b = prepared(&synth::crown(&CROWN_GENERA[2], 2, 1500));
        let c = compare(&a, &b, &params);
        assert_eq!(c.distance, c.forward.distance.min(c.backward.distance));
        assert_eq!(c.distance, compare(&b, &a, &params).distance, "symmetric");
        let (ab, ba) = (
            search_directed(&a, &b, &params),
            search_directed(&b, &a, &params),
        );
        let forward_first = ab.distance <= ba.distance;
        let other = |c: &Comparison| {
            if forward_first {
                c.backward.distance
            } else {
                c.forward.distance
            }
        };
        let searched_other = if forward_first { &ba } else { &ab };
        assert_eq!(other(&c), searched_other.distance, "not descended");
        let both = CompareParams {
            descent_both_directions: true,
            ..params.clone()
        };
        let d = compare(&a, &b, &both);
        assert!(other(&d) < other(&c), "descended when asked");
        assert_eq!(
            compare_directed(&a, &b, &params).distance,
            d.forward.distance
        );
    }
}
