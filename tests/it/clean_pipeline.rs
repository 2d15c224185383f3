//! The whole cleaning pipeline on synthetic surfaces (no outside data).

use crate::support::clean::mean_max_distance;
use morphoid_core::clean::{clean, CleanError, CleanOptions};
use morphoid_core::mesh::{
    bbox_diagonal, boundary_loops, edge_face_map, euler_characteristic, Mesh,
};
use morphoid_synth::mesh as synth;

fn crown(n: usize) -> Mesh {
    let g = synth::crown_genus("Quadricuspis").expect("genus");
    synth::crown(g, 7, n)
}

/// Sum of area-weighted normals.
fn vector_area(m: &Mesh) -> [f64; 3] {
    let mut s = [0.0; 3];
    for f in &m.faces {
        let p = f.map(|v| m.vertices[v as usize]);
        let n = morphoid_core::mesh::triangle_normal2(p[0], p[1], p[2]);
        for d in 0..3 {
            s[d] += n[d];
        }
    }
    s
}

fn assert_disk_on(m: &Mesh, original: &Mesh, target: usize) {
    assert_eq!(boundary_loops(m).len(), 1);
    assert_eq!(euler_characteristic(m), 1);
    assert!(edge_face_map(m).values().all(|f| f.len() <= 2));
    let nv = m.vertices.len() as f64;
    assert!(
        (nv - target as f64).abs() <= 0.1 * target as f64,
        "{nv} vertices"
    );
    let (mean, _) = mean_max_distance(&m.vertices, original);
    assert!(
        mean < 0.005 * bbox_diagonal(original),
        "mean distance {mean}"
    );
    assert!(m.vertices.iter().flatten().all(|x| x.is_finite()));
}

#[test]
fn sphere_is_rejected_as_closed() {
    // With crown extraction off, the sphere is refused for being closed,
    // with what to do; with it on (the default), no tooth crown is found.
    let sphere = synth::closed_sphere(642);
    let off = CleanOptions {
        crown: morphoid_core::clean::CrownMode::Off,
        ..CleanOptions::default()
    };
    let err = clean(&sphere, &off).unwrap_err();
    assert_eq!(err, CleanError::Closed);
    assert!(err.to_string().contains("crown = \"auto\""), "{err}");
    let err = clean(&sphere, &CleanOptions::default()).unwrap_err();
    assert!(matches!(err, CleanError::Crown(_)), "{err:?}");
    assert!(err.to_string().contains("closed surface"));
}

/// A torus grid with a block of `along` × 2 faces removed (of 16 × 8):
/// one boundary loop, one handle.
fn torus_with_hole(along: u32) -> Mesh {
    let (n, m) = (16u32, 8u32);
    let mut v = Vec::new();
    for i in 0..n {
        for j in 0..m {
            let (u, w) = (
                i as f64 / n as f64 * std::f64::consts::TAU,
                j as f64 / m as f64 * std::f64::consts::TAU,
            );
            let r = 2.0 + 0.6 * w.cos();
            v.push([r * u.cos(), r * u.sin(), 0.6 * w.sin()]);
        }
    }
    let id = |i: u32, j: u32| (i % n) * m + (j % m);
    let mut f = Vec::new();
    for i in 0..n {
        for j in 0..m {
            if i < along && j < 2 {
                continue;
            }
            f.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            f.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Mesh::new(v, f)
}

#[test]
fn torus_patch_with_a_handle_is_rejected() {
    // An open patch (its rim spans most of the torus): refused for its
    // handle.
    let t = torus_with_hole(6);
    assert_eq!(euler_characteristic(&t), -1);
    let err = clean(&t, &CleanOptions::default()).unwrap_err();
    assert_eq!(err, CleanError::Handles(1, -1));
    assert!(err.to_string().starts_with("the surface has 1 handle"));
    // A closed torus with a small hole is nearly closed: not a tooth.
    let t = torus_with_hole(2);
    assert_eq!(euler_characteristic(&t), -1);
    let err = clean(&t, &CleanOptions::default()).unwrap_err();
    assert!(matches!(err, CleanError::Crown(_)), "{err:?}");
}

#[test]
fn three_points_are_too_few() {
    let m = Mesh::new(vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]], vec![]);
    let err = clean(&m, &CleanOptions::default()).unwrap_err();
    assert_eq!(err, CleanError::TooFewPoints(3));
    assert_eq!(err.to_string(), "too few points (3) to form a surface");
    let tri = Mesh::new(m.vertices.clone(), vec![[0, 1, 2]]);
    assert!(clean(&tri, &CleanOptions::default()).is_err());
}

#[test]
fn bad_indices_and_nan_are_errors() {
    let c = crown(500);
    let mut bad = c.clone();
    bad.faces[3][1] = 1_000_000;
    assert!(matches!(
        clean(&bad, &CleanOptions::default()),
        Err(CleanError::BadIndex { face: 3, .. })
    ));
    let mut nan = c;
    nan.vertices[5][2] = f64::NAN;
    assert_eq!(
        clean(&nan, &CleanOptions::default()).unwrap_err(),
        CleanError::NonFinite(5)
    );
}

#[test]
fn crown_with_defects_cleans_to_a_disk() {
    let base = crown(5000);
    let opts = CleanOptions::default();
    let clean_base = clean(&base, &opts).expect("clean crown");
    assert_disk_on(&clean_base.mesh, &base, 5000);
    // The crown faces +z: outward normals point up.
    assert!(vector_area(&clean_base.mesh)[2] > 0.0);
    assert!(!clean_base.report.reversed_orientation);

    // Soup + debris + some reversed faces + a hole.
    let holed = synth::punch_hole(&base, base.vertices[base.vertices.len() / 3], 0.08);
    let soup = synth::triangle_soup(&synth::add_debris(&synth::flip_faces(&holed, 0.3, 3), 3, 5));
    let c = clean(&soup, &opts).expect("clean soup");
    assert_disk_on(&c.mesh, &base, 5000);
    assert!(c.report.welded_vertices > 2 * base.vertices.len());
    assert_eq!(c.report.dropped_components, 3);
    assert_eq!(c.report.filled_holes, 1);
    assert!(c.report.flipped_faces > 0);
    assert!(vector_area(&c.mesh)[2] > 0.0);

    // Fully reversed and mirrored copies come out outward again.
    let rev = synth::flip_faces(&base, 1.0, 1);
    let c = clean(&rev, &opts).expect("reversed");
    assert!(c.report.reversed_orientation);
    assert!(vector_area(&c.mesh)[2] > 0.0);
    let c = clean(&synth::mirror(&base), &opts).expect("mirrored");
    assert!(vector_area(&c.mesh)[2] > 0.0);
}

#[test]
fn coarse_dense_and_cloud_crowns_reach_the_target() {
    let opts = CleanOptions::default();
    let coarse = crown(900);
    let c = clean(&coarse, &opts).expect("coarse");
    assert_disk_on(&c.mesh, &coarse, 5000);

    let dense = crown(20000);
    let c = clean(&dense, &opts).expect("dense");
    assert_disk_on(&c.mesh, &dense, 5000);

    let base = crown(5000);
    let c = clean(&synth::to_point_cloud(&base), &opts).expect("cloud");
    assert!(c.report.triangulated_point_cloud);
    assert_disk_on(&c.mesh, &base, 5000);
    assert!(vector_area(&c.mesh)[2] > 0.0);

    let small = CleanOptions {
        target_vertices: 1500,
        ..CleanOptions::default()
    };
    let c = clean(&base, &small).expect("small target");
    assert_disk_on(&c.mesh, &base, 1500);
}

#[test]
fn flat_disk_keeps_its_orientation() {
    let disk = synth::unit_disk(4000);
    for m in [disk.clone(), synth::flip_faces(&disk, 1.0, 1)] {
        let up = vector_area(&m)[2] > 0.0;
        let c = clean(&m, &CleanOptions::default()).expect("disk");
        assert!(!c.report.reversed_orientation);
        assert_eq!(vector_area(&c.mesh)[2] > 0.0, up);
        assert_disk_on(&c.mesh, &m, 5000);
    }
}

#[test]
fn cleaning_is_deterministic() {
    let m = synth::flip_faces(&crown(12000), 0.2, 9);
    let a = clean(&m, &CleanOptions::default()).expect("a");
    let b = clean(&m, &CleanOptions::default()).expect("b");
    assert_eq!(a.mesh, b.mesh);
    assert_eq!(a.report, b.report);
    let cloud = synth::to_point_cloud(&crown(5000));
    let a = clean(&cloud, &CleanOptions::default()).expect("a");
    let b = clean(&cloud, &CleanOptions::default()).expect("b");
    assert_eq!(a.mesh, b.mesh);
}

#[test]
fn report_round_trips_through_json() {
    let c = clean(&crown(3000), &CleanOptions::default()).expect("clean");
    let json = serde_json::to_string(&c.report).expect("json");
    let mut back: morphoid_core::clean::CleanReport = serde_json::from_str(&json).expect("parse");
    // JSON floats may differ in the last bit.
    assert!((back.area - c.report.area).abs() <= 1e-12 * c.report.area);
    assert!((back.bbox_diagonal - c.report.bbox_diagonal).abs() <= 1e-12 * c.report.bbox_diagonal);
    back.area = c.report.area;
    back.bbox_diagonal = c.report.bbox_diagonal;
    assert_eq!(back, c.report);
    assert_eq!(c.report.output_vertices, c.mesh.vertices.len());
    assert!(c.report.area > 0.0 && c.report.bbox_diagonal > 0.0);
}

#[test]
fn a_surface_far_above_the_working_resolution_is_decimated_first_and_stays_on_the_surface() {
    let original = crown(5000);
    // Two midpoint subdivisions: ~80k vertices, 160k faces; with a working
    // resolution of 500 vertices that is twenty times the early target.
    let dense = synth::subdivide_midpoint(&original, 2);
    let opts = CleanOptions {
        target_vertices: 500,
        ..CleanOptions::default()
    };
    let c = clean(&dense, &opts).expect("dense crown cleans");
    assert_eq!(c.report.predecimated_faces, dense.faces.len());
    assert_disk_on(&c.mesh, &original, 500);
    // The same as a binary STL: the corners are shared as the file is read,
    // so the early decimation comes before welding.
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("dense.stl");
    morphoid_data::mesh_io::save(&path, &dense).expect("write stl");
    let loaded = morphoid_data::mesh_io::load(&path).expect("load stl").mesh;
    assert_eq!(loaded.vertices.len(), dense.vertices.len());
    let c = clean(&loaded, &opts).expect("dense stl cleans");
    assert_eq!(c.report.predecimated_faces, dense.faces.len());
    assert_disk_on(&c.mesh, &original, 500);
    // A working resolution near the input's: no early decimation.
    let c = clean(&original, &CleanOptions::default()).expect("crown cleans");
    assert_eq!(c.report.predecimated_faces, 0);
}
