//! The residual of a disk map between two prepared surfaces: on the
//! weighted samples (cheap, for the search) or on every vertex weighted by
//! its area (the distance, with the optimal rigid motion and the
//! correspondence).

use super::comparison::Correspondence;
use super::locate::{Location, NO_TRIANGLE};
use super::mobius::Mobius;
use super::prepared::Prepared;
use super::procrustes::{Handedness, Moments, RigidFit};

/// The handedness of the rigid motion that goes with a disk map: improper
/// for an orientation-reversing map (a mirror-image match).
#[inline]
pub(super) fn handedness(m: &Mobius) -> Handedness {
    if m.reverses_orientation() {
        Handedness::Improper
    } else {
        Handedness::Proper
    }
}

/// Locate `z` in `t`'s disk, walking from the triangle `hint` (see
/// [`LocateGrid::locate_near`](super::locate::LocateGrid::locate_near)),
/// and interpolate the 3D position there.
#[inline]
fn image(t: &Prepared, z: [f64; 2], hint: u32) -> Option<(Location, [f64; 3])> {
    let loc = t.locate_near(z, hint)?;
    let f = t.faces.get(loc.face as usize)?;
    let mut y = [0.0; 3];
    for (k, &v) in f.iter().enumerate() {
        let p = t.vertices.get(v as usize)?;
        for d in 0..3 {
            y[d] += loc.bary[k] * p[d];
        }
    }
    Some((loc, y))
}

/// Weighted Procrustes residual of the first `hints.len()` samples of `s`
/// and their images in `t` under the disk map `map` (of the given
/// handedness). `hints[i]` is a triangle of `t` near
/// the image of sample `i` (or [`NO_TRIANGLE`]); each is replaced by the
/// triangle found, so that a search moving the map a little locates the
/// next images cheaply.
pub(super) fn sample_residual(
    s: &Prepared,
    t: &Prepared,
    map: impl Fn([f64; 2]) -> [f64; 2],
    handedness: Handedness,
    hints: &mut [u32],
) -> f64 {
    let mut mom = Moments::default();
    for ((&v, &w), hint) in s.samples.iter().zip(&s.sample_weights).zip(hints) {
        let (Some(&z), Some(&x)) = (s.uv.get(v as usize), s.vertices.get(v as usize)) else {
            return f64::MAX;
        };
        match image(t, map(z), *hint) {
            Some((loc, y)) => {
                *hint = loc.face;
                mom.add(x, y, w)
            }
            None => return f64::MAX,
        }
    }
    mom.residual(handedness)
}

/// The weights of the distance over the vertices of `s`: each vertex's
/// area times a factor that is 1 up to `from` from the disk's centre and
/// falls linearly to `rim` at its edge, all scaled to add up to the
/// surface's area. The rim is the crop line, and where a crown is cut
/// varies most between two crops of one tooth (the crowns cut from whole
/// teeth most of all); a weight of 1 leaves the areas as they are.
pub(super) fn boundary_tapered_areas(s: &Prepared, from: f64, rim: f64) -> Vec<f64> {
    let factor = |z: [f64; 2]| {
        let r = (z[0] * z[0] + z[1] * z[1]).sqrt();
        if r <= from {
            1.0
        } else {
            1.0 - (1.0 - rim) * ((r - from) / (1.0 - from)).min(1.0)
        }
    };
    let factors: Vec<f64> = s.uv.iter().map(|&z| factor(z)).collect();
    let total: f64 = s.vertex_areas.iter().sum();
    let tapered: f64 = s
        .vertex_areas
        .iter()
        .zip(&factors)
        .map(|(a, f)| a * f)
        .sum();
    let scale = if tapered > 0.0 { total / tapered } else { 1.0 };
    s.vertex_areas
        .iter()
        .zip(&factors)
        .map(|(a, f)| a * f * scale)
        .collect()
}

/// Evaluate a disk map (`map`, of the given handedness) on all vertices of
/// `s` with the given `weights` (one per vertex): the optimal rigid
/// motion, its residual and the correspondence.
pub(super) fn evaluate_map(
    s: &Prepared,
    t: &Prepared,
    map: impl Fn([f64; 2]) -> [f64; 2],
    handedness: Handedness,
    weights: &[f64],
) -> Option<(RigidFit, Correspondence)> {
    let images: Vec<[f64; 2]> = s.uv.iter().map(|&z| map(z)).collect();
    evaluate_images(s, t, &images, handedness, weights, None)
}

/// Evaluate given images (points of `t`'s disk, one per vertex of `s`) as
/// in [`evaluate_map`]. `near`, when given, is a correspondence whose
/// images lie near these (the map these were moved from): each vertex's
/// image is searched from its triangle there.
pub(super) fn evaluate_images(
    s: &Prepared,
    t: &Prepared,
    images: &[[f64; 2]],
    handedness: Handedness,
    weights: &[f64],
    near: Option<&Correspondence>,
) -> Option<(RigidFit, Correspondence)> {
    let mut mom = Moments::default();
    let mut corr: Correspondence = vec![(NO_TRIANGLE, [0.0; 3]); s.vertices.len()];
    // Each vertex's image is searched from its triangle under the map these
    // images were moved from (a small move: a step or none), else from its
    // sweep parent's triangle, one edge away (three steps on average).
    for &[v, parent] in &s.sweep {
        let hint = match near.and_then(|n| n.get(v as usize)) {
            Some(&(f, _)) if f != NO_TRIANGLE => f,
            _ => corr.get(parent as usize).map_or(NO_TRIANGLE, |c| c.0),
        };
        let (Some(&w), Some(&x), Some(&a)) = (
            images.get(v as usize),
            s.vertices.get(v as usize),
            weights.get(v as usize),
        ) else {
            return None;
        };
        let (loc, y) = image(t, w, hint)?;
        mom.add(x, y, a);
        *corr.get_mut(v as usize)? = (loc.face, loc.bary);
    }
    if corr.iter().any(|c| c.0 == NO_TRIANGLE) {
        return None;
    }
    Some((mom.fit(handedness), corr))
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::cp::test_crown as crown;

    #[test]
    fn the_identity_map_has_no_residual_and_maps_each_vertex_to_itself() {
        let s = crown(0, 1);
        let (fit, corr) =
            evaluate_map(&s, &s, |z| z, Handedness::Proper, &s.vertex_areas).expect("evaluated");
        assert!(fit.residual < 1e-12, "{}", fit.residual);
        assert_eq!(corr.len(), s.vertices.len());
        for (v, &(f, b)) in corr.iter().enumerate() {
            let face = s.faces[f as usize];
            let y: f64 = (0..3)
                .map(|k| b[k] * if face[k] as usize == v { 1.0 } else { 0.0 })
                .sum();
            assert!(y > 1.0 - 1e-9, "vertex {v} not mapped onto itself");
        }
        let mut hints = vec![NO_TRIANGLE; s.samples.len()];
        assert!(sample_residual(&s, &s, |z| z, Handedness::Proper, &mut hints) < 1e-12);
        assert!(
            hints.iter().all(|&h| h != NO_TRIANGLE),
            "hints are filled in"
        );
    }

    #[test]
    fn a_turned_map_costs_more_and_the_sample_residual_tracks_the_full_one() {
        let (s, t) = (crown(0, 1), crown(0, 1));
        let turn = Mobius::rotation(0.8);
        let mut hints = vec![NO_TRIANGLE; s.samples.len()];
        let sampled = sample_residual(&s, &t, |z| turn.apply(z), handedness(&turn), &mut hints);
        let (fit, _) = evaluate_map(
            &s,
            &t,
            |z| turn.apply(z),
            handedness(&turn),
            &s.vertex_areas,
        )
        .expect("evaluated");
        assert!(fit.residual > 1e-3, "{}", fit.residual);
        // Samples carry Voronoi-area weights: both estimate the same
        // integral.
        assert!(
            (sampled / fit.residual - 1.0).abs() < 0.3,
            "samples {sampled} vs all vertices {}",
            fit.residual
        );
    }

    #[test]
    fn orientation_reversing_maps_go_with_improper_motions() {
        assert_eq!(handedness(&Mobius::conjugation()), Handedness::Improper);
        assert_eq!(handedness(&Mobius::rotation(0.3)), Handedness::Proper);
        let m = Mobius::sending([0.1, 0.2], [-0.3, 0.0], 1.0, true);
        assert_eq!(handedness(&m), Handedness::Improper);
    }

    #[test]
    fn the_taper_lowers_the_rims_weight_and_keeps_the_total_area() {
        let s = crown(0, 1);
        let total: f64 = s.vertex_areas.iter().sum();
        // A weight of 1 at the rim leaves the areas exactly as they are.
        assert_eq!(boundary_tapered_areas(&s, 0.7, 1.0), s.vertex_areas);
        let w = boundary_tapered_areas(&s, 0.7, 0.2);
        assert!((w.iter().sum::<f64>() / total - 1.0).abs() < 1e-12);
        // Relative to its area, a vertex within 0.7 of the centre weighs
        // one common factor (above 1: the rim gave weight away), one on
        // the rim a fifth of it, and none more nor less than those.
        let ratio = |v: usize| w[v] / s.vertex_areas[v];
        let radius = |v: usize| s.uv[v][0].hypot(s.uv[v][1]);
        let inner = (0..w.len())
            .find(|&v| radius(v) <= 0.7)
            .expect("a central vertex");
        let rim = (0..w.len())
            .find(|&v| radius(v) > 1.0 - 1e-9)
            .expect("a rim vertex");
        assert!(ratio(inner) > 1.0);
        assert!((ratio(rim) / ratio(inner) - 0.2).abs() < 1e-9);
        for v in 0..w.len() {
            let r = ratio(v) / ratio(inner);
            assert!((0.2 - 1e-9..=1.0 + 1e-9).contains(&r), "vertex {v}: {r}");
            if radius(v) <= 0.7 {
                assert!((r - 1.0).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn images_for_fewer_vertices_are_refused() {
        let s = crown(0, 1);
        let short = &s.uv[..s.uv.len() - 1];
        assert!(
            evaluate_images(&s, &s, short, Handedness::Proper, &s.vertex_areas, None).is_none()
        );
    }
}
