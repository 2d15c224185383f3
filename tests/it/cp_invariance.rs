//! Invariance of the cP distance on real teeth: rigid motions, uniform
//! scalings, mirror images and remeshing.

use morphoid_core::clean::{clean, CleanOptions};
use morphoid_core::cp::{self, CpParams};
use morphoid_core::mesh::Mesh;
use morphoid_synth::mesh::subdivide_midpoint;
use nalgebra::{Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

fn transformed(m: &Mesh, rng: &mut rand_chacha::ChaCha8Rng) -> Mesh {
    let r = Rotation3::from_euler_angles(
        rng.gen_range(-3.1..3.1),
        rng.gen_range(-1.5..1.5),
        rng.gen_range(-3.1..3.1),
    );
    let s: f64 = rng.gen_range(0.2..5.0);
    let t = Vector3::new(
        rng.gen_range(-10.0..10.0),
        rng.gen_range(-10.0..10.0),
        rng.gen_range(-10.0..10.0),
    );
    let vertices = m
        .vertices
        .iter()
        .map(|p| {
            let q = r * Vector3::from(*p) * s + t;
            [q[0], q[1], q[2]]
        })
        .collect();
    Mesh::new(vertices, m.faces.clone())
}

fn mirrored(m: &Mesh) -> Mesh {
    // Mirror through the plane x = 0 and keep the normals outward.
    let vertices = m.vertices.iter().map(|p| [-p[0], p[1], p[2]]).collect();
    let faces = m.faces.iter().map(|f| [f[0], f[2], f[1]]).collect();
    Mesh::new(vertices, faces)
}

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn rigid_motions_scalings_and_mirrors_are_at_distance_zero() {
    let Some(dir) = crate::support::cp::data_dir() else {
        return;
    };
    let params = CpParams::default();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let names = crate::support::cp::tooth_names(&dir);
    let mut worst_rigid: f64 = 0.0;
    let mut worst_mirror: f64 = 0.0;
    for name in names.iter().step_by(12).take(10) {
        let mesh = crate::support::cp::load_tooth(&dir, name);
        let a = cp::prepare(&mesh, &params.prepare).expect("prepare");
        let b = cp::prepare(&transformed(&mesh, &mut rng), &params.prepare).expect("prepare");
        let c = cp::compare(&a, &b, &params.compare);
        assert!(!c.reflected, "{name}: rigid copy matched as a mirror image");
        worst_rigid = worst_rigid.max(c.distance);
        let mir = cp::prepare(&transformed(&mirrored(&mesh), &mut rng), &params.prepare)
            .expect("prepare");
        let c = cp::compare(&a, &mir, &params.compare);
        assert!(c.reflected, "{name}: mirror image not matched as reflected");
        worst_mirror = worst_mirror.max(c.distance);
        // A mirror image is also found when the mirrored copy's faces are
        // wound the other way (orientation is made canonical).
        let raw = Mesh::new(mirrored(&mesh).vertices, mesh.faces.clone());
        let c = cp::compare(
            &a,
            &cp::prepare(&raw, &params.prepare).expect("prepare"),
            &params.compare,
        );
        assert!(c.reflected && c.distance < 1e-3, "{name}: {}", c.distance);
    }
    println!("worst d(S, R(S)) = {worst_rigid:.2e}, worst d(S, mirror(S)) = {worst_mirror:.2e}");
    assert!(worst_rigid < 1e-3);
    assert!(worst_mirror < 1e-3);
}

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn distance_is_symmetric_and_positive_between_different_teeth() {
    let Some(dir) = crate::support::cp::data_dir() else {
        return;
    };
    let params = CpParams::default();
    let names = crate::support::cp::tooth_names(&dir);
    let a = cp::prepare(
        &crate::support::cp::load_tooth(&dir, &names[2]),
        &params.prepare,
    )
    .expect("prepare");
    let b = cp::prepare(
        &crate::support::cp::load_tooth(&dir, &names[40]),
        &params.prepare,
    )
    .expect("prepare");
    let ab = cp::compare(&a, &b, &params.compare);
    let ba = cp::compare(&b, &a, &params.compare);
    assert_eq!(ab.distance, ba.distance);
    assert!(ab.distance > 0.01 && ab.distance.is_finite());
    assert_eq!(ab.forward.correspondence.len(), a.vertices().len());
    assert_eq!(ab.backward.correspondence.len(), b.vertices().len());
    assert!(ab.forward.correspondence.iter().all(
        |(f, l)| (*f as usize) < b.faces().len() && (l.iter().sum::<f64>() - 1.0).abs() < 1e-9
    ));
}

/// The surface again, with no vertex in common: refined, then brought back
/// to the working resolution by the cleaning stage's remesher.
fn remeshed(m: &Mesh) -> Mesh {
    let opts = CleanOptions {
        target_vertices: 4500,
        ..CleanOptions::default()
    };
    clean(&subdivide_midpoint(m, 1), &opts)
        .expect("a refined tooth cleans")
        .mesh
}

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn remeshing_moves_a_tooth_less_than_a_quarter_of_the_nearest_neighbour_distance() {
    let Some(dir) = crate::support::cp::data_dir() else {
        return;
    };
    let params = CpParams::default();
    let names = crate::support::cp::tooth_names(&dir);
    let prepared = crate::support::cp::prepare_teeth(&dir, &names, &params);
    // The library's median nearest-neighbour distance, from six teeth
    // spread over it (each against all 115 others).
    let mut nearest: Vec<f64> = (0..names.len())
        .step_by(20)
        .map(|i| {
            (0..names.len())
                .into_par_iter()
                .filter(|&j| j != i)
                .map(|j| cp::compare(&prepared[i], &prepared[j], &params.compare).distance)
                .reduce(|| f64::INFINITY, f64::min)
        })
        .collect();
    nearest.sort_by(f64::total_cmp);
    let median_nn = nearest[nearest.len() / 2];

    let worst = (0..names.len())
        .step_by(12)
        .take(10)
        .collect::<Vec<_>>()
        .par_iter()
        .map(|&i| {
            let mesh = crate::support::cp::load_tooth(&dir, &names[i]);
            let other = cp::prepare(&remeshed(&mesh), &params.prepare).expect("prepare");
            let d = cp::compare(&prepared[i], &other, &params.compare).distance;
            println!("{}: d(S, remeshed S) = {d:.5}", names[i]);
            d
        })
        .reduce(|| 0.0, f64::max);
    println!(
        "worst d(S, remeshed S) = {worst:.5}, median nearest-neighbour distance = {median_nn:.5}, ratio {:.3}",
        worst / median_nn
    );
    assert!(worst < 0.25 * median_nn);
}
