//! The final descent of a directed comparison: Gauss–Newton steps over
//! the images of the source's vertices that lower the Procrustes residual
//! of the area-preserving map the search found, each step smoothed over
//! the source and made area preserving again.

use super::comparison::{Correspondence, Directed};
use super::evaluate::{boundary_tapered_areas, evaluate_images, handedness};
use super::moser::area_preserving_correction;
use super::params::CompareParams;
use super::prepared::Prepared;
use super::procrustes::RigidFit;

/// Flow steps of the area correction after a descent step: the step moves
/// an area-preserving map only a little, so the flow that undoes its area
/// change is short.
const DESCENT_FLOW_STEPS: usize = 1;

/// Lower the distance of a directed comparison by up to
/// `params.descent_steps` Gauss–Newton steps over the images of `s`'s
/// vertices, each made area preserving again by χ and kept only when it
/// lowers the residual. The cP distance is an infimum over area-preserving
/// maps; the corrected map of the search is one such map, not the best, and
/// this moves it towards a better one.
pub(super) fn procrustes_descent(
    s: &Prepared,
    t: &Prepared,
    d: &mut Directed,
    params: &CompareParams,
) {
    if !params.area_correction || d.correspondence.len() != s.vertices.len() {
        return;
    }
    let target = t.disk_measure();
    let weights =
        boundary_tapered_areas(s, params.boundary_taper_from, params.boundary_taper_weight);
    let h = handedness(&d.mobius);
    let mut fit = RigidFit {
        rotation: d.rotation,
        translation: d.translation,
        residual: d.distance * d.distance,
    };
    for _ in 0..params.descent_steps {
        let Some(moved) = gauss_newton_step(s, t, &fit, &d.correspondence, params) else {
            break;
        };
        let Some(corrected) = target.as_deref().and_then(|target| {
            area_preserving_correction(
                target,
                &moved,
                &s.vertex_areas,
                &s.sweep,
                DESCENT_FLOW_STEPS,
            )
        }) else {
            break;
        };
        match evaluate_images(s, t, &corrected, h, &weights, Some(&d.correspondence)) {
            Some((f, corr)) if f.residual < fit.residual => {
                fit = f;
                d.correspondence = corr;
            }
            _ => break,
        }
    }
    d.distance = fit.residual.max(0.0).sqrt();
    d.rotation = fit.rotation;
    d.translation = fit.translation;
}

/// The images of `s`'s vertices after one Gauss–Newton step of the
/// residual `Σ a |R x + t − S′(y)|²` in the images y (points of `t`'s disk,
/// given by the correspondence `corr`), with the rigid motion `fit` held
/// fixed. Each vertex's step solves the linearized problem in its image's
/// triangle; the step field is then smoothed over `s` and damped, so that
/// the map stays regular. `None` if the correspondence is inconsistent.
fn gauss_newton_step(
    s: &Prepared,
    t: &Prepared,
    fit: &RigidFit,
    corr: &Correspondence,
    params: &CompareParams,
) -> Option<Vec<[f64; 2]>> {
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut images = Vec::with_capacity(corr.len());
    let mut step = Vec::with_capacity(corr.len());
    for (&x, &(f, b)) in s.vertices.iter().zip(corr) {
        let f = t.faces.get(f as usize)?;
        let mut p = [[0.0; 3]; 3];
        let mut u = [[0.0; 2]; 3];
        for k in 0..3 {
            p[k] = *t.vertices.get(f[k] as usize)?;
            u[k] = *t.uv.get(f[k] as usize)?;
        }
        let y: [f64; 3] = [0, 1, 2].map(|d| b[0] * p[0][d] + b[1] * p[1][d] + b[2] * p[2][d]);
        images.push([0, 1].map(|d| b[0] * u[0][d] + b[1] * u[1][d] + b[2] * u[2][d]));
        let r = fit.rotation;
        let e: [f64; 3] = [0, 1, 2].map(|d| dot(r[d], x) + fit.translation[d] - y[d]);
        // The residual's least-squares step in the triangle's barycentric
        // directions, carried into the disk.
        let e1: [f64; 3] = [0, 1, 2].map(|d| p[1][d] - p[0][d]);
        let e2: [f64; 3] = [0, 1, 2].map(|d| p[2][d] - p[0][d]);
        let (g11, g12, g22) = (dot(e1, e1), dot(e1, e2), dot(e2, e2));
        let det = g11 * g22 - g12 * g12;
        if det <= f64::MIN_POSITIVE {
            step.push([0.0; 2]);
            continue;
        }
        let (b1, b2) = (dot(e1, e), dot(e2, e));
        let c1 = (g22 * b1 - g12 * b2) / det;
        let c2 = (g11 * b2 - g12 * b1) / det;
        step.push([0, 1].map(|d| c1 * (u[1][d] - u[0][d]) + c2 * (u[2][d] - u[0][d])));
    }
    let step = smooth_on_faces(&s.faces, &s.vertex_areas, step, params.descent_smoothing);
    Some(
        images
            .iter()
            .zip(&step)
            .map(|(z, d)| {
                let w = [0, 1].map(|k| z[k] + params.descent_damping * d[k]);
                let r = w[0].hypot(w[1]);
                if r > 1.0 {
                    [w[0] / r, w[1] / r]
                } else {
                    w
                }
            })
            .collect(),
    )
}

/// `iterations` steps of averaging a vector field over the faces around
/// each vertex, weighted by face area (vertex areas summed).
fn smooth_on_faces(
    faces: &[[u32; 3]],
    areas: &[f64],
    mut field: Vec<[f64; 2]>,
    iterations: usize,
) -> Vec<[f64; 2]> {
    let n = field.len();
    // Faces with their weights, and each vertex's total weight, once.
    let weighted: Vec<([usize; 3], f64)> = faces
        .iter()
        .map(|f| f.map(|v| v as usize))
        .filter(|idx| idx.iter().all(|&v| v < n && v < areas.len()))
        .map(|idx| (idx, idx.iter().map(|&v| areas[v]).sum::<f64>() / 3.0))
        .collect();
    let mut weight = vec![0.0; n];
    for (idx, a) in &weighted {
        for &v in idx {
            weight[v] += 3.0 * a;
        }
    }
    let mut sum = vec![[0.0; 2]; n];
    for _ in 0..iterations {
        sum.fill([0.0; 2]);
        for (idx, a) in &weighted {
            // The face's area times the mean of its three values.
            let m = [0, 1].map(|d| a * (field[idx[0]][d] + field[idx[1]][d] + field[idx[2]][d]));
            for &v in idx {
                sum[v][0] += m[0];
                sum[v][1] += m[1];
            }
        }
        for ((f, s), w) in field.iter_mut().zip(&sum).zip(&weight) {
            if *w > 0.0 {
                *f = [s[0] / w, s[1] / w];
            }
        }
    }
    field
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cp::mobius::Mobius;
    use crate::cp::search::search_directed;

    use crate::cp::test_crown as crown;

    #[test]
    fn smoothing_keeps_constant_fields_and_flattens_a_spike() {
        let p = crown(0, 1);
        let n = p.vertices.len();
        let constant = smooth_on_faces(&p.faces, &p.vertex_areas, vec![[0.25, -1.0]; n], 5);
        assert!(constant
            .iter()
            .all(|v| (v[0] - 0.25).abs() < 1e-12 && (v[1] + 1.0).abs() < 1e-12));
        let mut spike = vec![[0.0; 2]; n];
        spike[n / 2] = [1.0, 0.0];
        let total =
            |f: &[[f64; 2]]| -> f64 { f.iter().zip(&p.vertex_areas).map(|(v, a)| v[0] * a).sum() };
        let smoothed = smooth_on_faces(&p.faces, &p.vertex_areas, spike.clone(), 3);
        assert!(smoothed[n / 2][0] < 0.5, "{}", smoothed[n / 2][0]);
        assert!(smoothed.iter().filter(|v| v[0] > 0.0).count() > 5);
        // Averaging over faces weighted by area moves mass, it does not
        // create it (up to the one-third split of face areas).
        assert!((total(&smoothed) - total(&spike)).abs() < 0.5 * total(&spike));
        let none = smooth_on_faces(&p.faces, &p.vertex_areas, spike.clone(), 0);
        assert_eq!(none, spike);
    }

    #[test]
    fn an_exact_correspondence_takes_no_step() {
        let p = crown(1, 4);
        let fit = RigidFit {
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation: [0.0; 3],
            residual: 0.0,
        };
        let (_, corr) = crate::cp::evaluate::evaluate_map(
            &p,
            &p,
            |z| z,
            handedness(&Mobius::identity()),
            &p.vertex_areas,
        )
        .expect("identity");
        let moved =
            gauss_newton_step(&p, &p, &fit, &corr, &CompareParams::default()).expect("a step");
        let worst = moved
            .iter()
            .zip(&p.uv)
            .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "moved by {worst}");
        let bad: Correspondence = vec![(p.faces.len() as u32, [1.0, 0.0, 0.0]); p.vertices.len()];
        assert!(gauss_newton_step(&p, &p, &fit, &bad, &CompareParams::default()).is_none());
    }

    #[test]
    fn the_descent_never_raises_the_distance_and_lowers_it_between_different_crowns() {
        let (s, t) = (crown(0, 2), crown(2, 3));
        let params = CompareParams::default();
        let searched = search_directed(&s, &t, &params);
        let mut descended = searched.clone();
        procrustes_descent(&s, &t, &mut descended, &params);
        assert!(descended.distance < searched.distance);
        assert_eq!(descended.correspondence.len(), s.vertices.len());
        let mut off = searched.clone();
        let no_steps = CompareParams {
            descent_steps: 0,
            ..params
        };
        procrustes_descent(&s, &t, &mut off, &no_steps);
        assert!((off.distance - searched.distance).abs() <= 1e-12 * searched.distance);
    }
}
