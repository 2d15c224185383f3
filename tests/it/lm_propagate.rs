//! Landmark propagation accuracy: landmarks of a tooth carried to a
//! rigidly moved (rotation, translation, ×1000), remeshed copy of itself
//! land near their true positions (the same rigid motion applied to the
//! original landmarks). Measured on real teeth when the data set is
//! present, always on synthetic crowns, through the library and through
//! the command line.

use morphoid_core::cp;
use morphoid_core::mesh::{bbox_diagonal, norm, sub, Mesh};
use morphoid_data::landmarks::{self, Landmarks, Surface};
use morphoid_data::mesh_io;
use morphoid_data::pipeline::{self, PreparedSurface, Settings};
use morphoid_synth::mesh::{self as synth, RigidMotion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;

/// Scale of the copy (file units change, e.g. mm to µm).
const SCALE: f64 = 1000.0;

/// Ten landmarks on a prepared surface: its feature points (cusp tips),
/// then random points inside random triangles (seeded).
fn choose_landmarks(s: &PreparedSurface, seed: u64) -> Landmarks {
    let mut lm = Landmarks::default();
    for (k, &v) in s.prepared.features().iter().take(5).enumerate() {
        lm.push(s.cleaned.vertices[v as usize], Some(format!("cusp{k}")));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    while lm.len() < 10 {
        let f = s.prepared.faces()[rng.gen_range(0..s.prepared.faces().len())];
        let (u, v): (f64, f64) = (rng.gen(), rng.gen());
        let (u, v) = if u + v > 1.0 {
            (1.0 - u, 1.0 - v)
        } else {
            (u, v)
        };
        let c = f.map(|i| s.cleaned.vertices[i as usize]);
        let p = [0, 1, 2].map(|d| c[0][d] + u * (c[1][d] - c[0][d]) + v * (c[2][d] - c[0][d]));
        lm.push(p, Some(format!("point{}", lm.len())));
    }
    lm
}

/// The copy: subdivided once (new vertices), scaled, optionally mirrored,
/// rigidly moved; cleaning then resamples it back to the working size.
fn moved_copy(mesh: &Mesh, motion: &RigidMotion, mirrored: bool) -> Mesh {
    let fine = synth::scale(&synth::subdivide_midpoint(mesh, 1), SCALE);
    let fine = if mirrored { synth::mirror(&fine) } else { fine };
    motion.apply(&fine)
}

fn true_position(p: [f64; 3], motion: &RigidMotion, mirrored: bool) -> [f64; 3] {
    let q = p.map(|x| x * SCALE);
    let q = if mirrored { [-q[0], q[1], q[2]] } else { q };
    motion.apply_point(q)
}

/// Mean and max distance between propagated and true landmarks, relative
/// to the target's bounding-box diagonal; also checks that the results lie
/// on the target surface.
fn errors(got: &Landmarks, truth: &[[f64; 3]], target: &Mesh) -> (f64, f64) {
    let diag = bbox_diagonal(target);
    let on = morphoid_core::clean::point_to_surface_distances(got.points(), target);
    for d in on {
        assert!(
            d <= 1e-9 * diag,
            "a propagated landmark is off the surface by {d}"
        );
    }
    let e: Vec<f64> = got
        .points()
        .iter()
        .zip(truth)
        .map(|(a, b)| norm(sub(*a, *b)) / diag)
        .collect();
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    (mean, e.iter().copied().fold(0.0, f64::max))
}

/// Propagate from `mesh` to its moved copy; returns (mean, max) relative
/// errors.
fn self_propagation(mesh: &Mesh, seed: u64, mirrored: bool) -> (f64, f64) {
    let settings = Settings::default();
    let source = pipeline::prepare_mesh(mesh, "source", &settings).expect("source prepares");
    let lm = choose_landmarks(&source, seed);
    let motion = RigidMotion::random(seed, 3.0 * SCALE * bbox_diagonal(&source.cleaned));
    let copy = moved_copy(&source.cleaned, &motion, mirrored);
    let target = pipeline::prepare_mesh(&copy, "target", &settings).expect("copy prepares");
    let map = cp::compare_directed(&source.prepared, &target.prepared, &settings.cp.compare);
    assert_eq!(map.reflected, mirrored);
    let (s, t) = (
        Surface::from_prepared(&source).unwrap(),
        Surface::from_prepared(&target).unwrap(),
    );
    let out = landmarks::propagate(&lm, &s, &t, &map.correspondence).unwrap();
    assert_eq!(out.landmarks.labels(), lm.labels());
    assert!(out
        .source_offsets
        .iter()
        .all(|&d| d < 1e-9 * bbox_diagonal(&source.cleaned)));
    let truth: Vec<[f64; 3]> = lm
        .points()
        .iter()
        .map(|&p| true_position(p, &motion, mirrored))
        .collect();
    errors(&out.landmarks, &truth, &target.cleaned)
}

#[test]
fn synthetic_crown_to_moved_remeshed_copy() {
    let genus = synth::crown_genus("Quadricuspis").expect("genus");
    let mesh = synth::crown(genus, 11, 5000);
    let (mean, max) = self_propagation(&mesh, 5, false);
    println!("synthetic crown: landmark error / diagonal: mean {mean:.5}, max {max:.5}");
    assert!(mean < 0.01, "mean error {mean}");
    let (mean, max) = self_propagation(&mesh, 6, true);
    println!("synthetic crown, mirrored copy: mean {mean:.5}, max {max:.5}");
    assert!(mean < 0.01, "mean error (mirrored) {mean}");
}

#[test]
fn synthetic_crown_through_an_intermediate() {
    let settings = Settings::default();
    let genus = synth::crown_genus("Tricuspis").expect("genus");
    let source = pipeline::prepare_mesh(&synth::crown(genus, 3, 5000), "a", &settings).unwrap();
    let lm = choose_landmarks(&source, 9);
    let diag = bbox_diagonal(&source.cleaned);
    let m1 = RigidMotion::random(21, 2.0 * diag);
    let m2 = RigidMotion::random(22, 2.0 * SCALE * SCALE * diag);
    // B = m1(1000·A); C = m2(1000·B), both remeshed.
    let b =
        pipeline::prepare_mesh(&moved_copy(&source.cleaned, &m1, false), "b", &settings).unwrap();
    let c = pipeline::prepare_mesh(&moved_copy(&b.cleaned, &m2, false), "c", &settings).unwrap();
    let ab = cp::compare_directed(&source.prepared, &b.prepared, &settings.cp.compare);
    let bc = cp::compare_directed(&b.prepared, &c.prepared, &settings.cp.compare);
    let surfaces: Vec<Surface> = [&source, &b, &c]
        .iter()
        .map(|s| Surface::from_prepared(s).unwrap())
        .collect();
    let out = landmarks::propagate_along(
        &lm,
        &[&surfaces[0], &surfaces[1], &surfaces[2]],
        &[&ab.correspondence, &bc.correspondence],
    )
    .unwrap();
    let truth: Vec<[f64; 3]> = lm
        .points()
        .iter()
        .map(|&p| true_position(true_position(p, &m1, false), &m2, false))
        .collect();
    let (mean, max) = errors(&out.landmarks, &truth, &c.cleaned);
    println!("synthetic crown via an intermediate: mean {mean:.5}, max {max:.5}");
    assert!(mean < 0.015, "mean error {mean}");
}

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn real_teeth_to_moved_remeshed_copies() {
    let Some(files) = crate::support::data::tooth_paths() else {
        return;
    };
    let (mut sum, mut worst, mut count) = (0.0, 0.0f64, 0);
    // Every 20th tooth: six teeth across the taxa.
    for (k, f) in files.iter().step_by(20).enumerate() {
        let mesh = mesh_io::load(f).expect("tooth loads").mesh;
        let (mean, max) = self_propagation(&mesh, 100 + k as u64, false);
        println!(
            "{}: landmark error / diagonal: mean {mean:.5}, max {max:.5}",
            f.display()
        );
        assert!(mean < 0.01, "{}: mean error {mean}", f.display());
        sum += mean;
        worst = worst.max(max);
        count += 1;
    }
    println!(
        "real teeth ({count}): mean of means {:.5}, max {:.5}",
        sum / count as f64,
        worst
    );
}

#[test]
fn command_line_propagates_to_a_moved_copy() {
    let settings = Settings::default();
    let genus = synth::crown_genus("Quinquecuspis").expect("genus");
    let source = pipeline::prepare_mesh(&synth::crown(genus, 4, 5000), "ref", &settings).unwrap();
    let lm = choose_landmarks(&source, 17);
    let motion = RigidMotion::random(17, 2.0 * SCALE * bbox_diagonal(&source.cleaned));
    let copy = moved_copy(&source.cleaned, &motion, false);
    let dir = tempfile::tempdir().unwrap();
    let (ref_path, mesh_path) = (dir.path().join("ref.ply"), dir.path().join("scan.ply"));
    mesh_io::save(&ref_path, &source.cleaned).unwrap();
    mesh_io::save(&mesh_path, &copy).unwrap();
    let lm_path = dir.path().join("ref.fcsv");
    landmarks::write(&lm_path, &lm).unwrap();
    let out_path = dir.path().join("scan.mrk.json");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_morphoid"))
        .args(["propagate", "--from"])
        .arg(&ref_path)
        .arg("--to")
        .arg(&mesh_path)
        .arg("--landmarks")
        .arg(&lm_path)
        .arg("--out")
        .arg(&out_path)
        .status()
        .unwrap();
    assert!(status.success());
    let got = landmarks::read(&out_path, Some(lm.len())).unwrap();
    assert_eq!(got.labels(), lm.labels());
    let truth: Vec<[f64; 3]> = lm
        .points()
        .iter()
        .map(|&p| true_position(p, &motion, false))
        .collect();
    let target = pipeline::prepare_file(&mesh_path, &settings).unwrap();
    let (mean, max) = errors(&got, &truth, &target.cleaned);
    println!("command line: landmark error / diagonal: mean {mean:.5}, max {max:.5}");
    assert!(mean < 0.01, "mean error {mean}");

    // A landmark file with the wrong content is a clear error.
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "1,2,3\n4,5\n").unwrap();
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_morphoid"))
        .args(["propagate", "--from"])
        .arg(&ref_path)
        .arg("--to")
        .arg(&mesh_path)
        .arg("--landmarks")
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!output.status.success());
    let err = String::from_utf8_lossy(&output.stderr);
    assert!(err.contains("bad.csv:2"), "{err}");

    // So is one with another number of landmarks than asked for.
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_morphoid"))
        .args(["propagate", "--count", "11", "--from"])
        .arg(&ref_path)
        .arg("--to")
        .arg(&mesh_path)
        .arg("--landmarks")
        .arg(&lm_path)
        .output()
        .unwrap();
    assert!(!output.status.success());
    let err = String::from_utf8_lossy(&output.stderr);
    assert!(err.contains("ref.fcsv: 10 landmarks, expected 11"), "{err}");
}

#[test]
fn command_line_follows_the_spanning_tree_of_a_given_matrix() {
    let settings = Settings::default();
    let genus = synth::crown_genus("Lophodon").expect("genus");
    let source = pipeline::prepare_mesh(&synth::crown(genus, 8, 5000), "ref", &settings).unwrap();
    let lm = choose_landmarks(&source, 31);
    let dir = tempfile::tempdir().unwrap();
    let lib = dir.path().join("lib");
    std::fs::create_dir(&lib).unwrap();
    mesh_io::save(&lib.join("ref.ply"), &source.cleaned).unwrap();
    // b, c and scan: moved remeshed copies; the matrix makes the tree the
    // chain ref – c – b – scan.
    let diag = bbox_diagonal(&source.cleaned);
    let mut motions = Vec::new();
    for (k, name) in ["b", "c"].iter().enumerate() {
        let m = RigidMotion::random(46 + k as u64, 2.0 * SCALE * diag);
        mesh_io::save(
            &lib.join(format!("{name}.ply")),
            &moved_copy(&source.cleaned, &m, false),
        )
        .unwrap();
        motions.push(m);
    }
    let motion = RigidMotion::random(52, 2.0 * SCALE * diag);
    let scan = dir.path().join("scan.ply");
    mesh_io::save(&scan, &moved_copy(&source.cleaned, &motion, false)).unwrap();
    let matrix = dir.path().join("m.csv");
    std::fs::write(
        &matrix,
        "name,ref,b,c,scan\nref,0,0.9,0.1,0.9\nb,0.9,0,0.1,0.1\nc,0.1,0.1,0,0.9\nscan,0.9,0.1,0.9,0\n",
    )
    .unwrap();
    let lm_path = dir.path().join("ref.pp");
    landmarks::write(&lm_path, &lm).unwrap();
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_morphoid"))
        .args(["propagate", "--from"])
        .arg(lib.join("ref.ply"))
        .arg("--to")
        .arg(&scan)
        .arg("--landmarks")
        .arg(&lm_path)
        .arg("--via-mst")
        .arg(&lib)
        .arg("--matrix")
        .arg(&matrix)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{err}");
    assert!(err.contains("ref → c → b → scan"), "{err}");
    assert!(
        err.contains("0 cP distances computed"),
        "no distance should be computed: {err}"
    );
    let got = landmarks::parse(
        &String::from_utf8_lossy(&output.stdout),
        landmarks::Format::Csv,
        Path::new("stdout"),
    )
    .unwrap();
    assert_eq!(got.labels(), lm.labels());
    let truth: Vec<[f64; 3]> = lm
        .points()
        .iter()
        .map(|&p| true_position(p, &motion, false))
        .collect();
    let target = pipeline::prepare_file(&scan, &settings).unwrap();
    let (mean, max) = errors(&got, &truth, &target.cleaned);
    println!("command line, spanning-tree path: mean {mean:.5}, max {max:.5}");
    assert!(mean < 0.015, "mean error {mean}");
}

/// Two moved, remeshed copies of one synthetic crown (Lophodon, seed 8;
/// motions 41 and 40) are matched by the right map (about 0.0011), not as
/// mirror images (0.0046, what the search found when it refined only the
/// two best candidates overall, both mirror images here).
#[test]
fn two_moved_remeshed_copies_are_matched_without_reflection() {
    let settings = Settings::default();
    let genus = synth::crown_genus("Lophodon").expect("genus");
    let source = pipeline::prepare_mesh(&synth::crown(genus, 8, 5000), "ref", &settings).unwrap();
    let diag = bbox_diagonal(&source.cleaned);
    let copy = |seed: u64| {
        let motion = RigidMotion::random(seed, 2.0 * SCALE * diag);
        let mesh = moved_copy(&source.cleaned, &motion, false);
        pipeline::prepare_mesh(&mesh, &format!("copy{seed}"), &settings).unwrap()
    };
    let (c, b) = (copy(41), copy(40));
    let map = morphoid_core::cp::compare_directed(&c.prepared, &b.prepared, &settings.cp.compare);
    println!(
        "copy41 -> copy40: {:.5}, reflected {}",
        map.distance, map.reflected
    );
    assert!(
        !map.reflected,
        "matched as mirror images at {}",
        map.distance
    );
    assert!(map.distance < 0.002, "distance {}", map.distance);
}

/// Between different teeth of one genus there are no observer landmarks
/// here. Asserted: landmarks carried A → B → A (forward, then backward
/// correspondence) come back near where they started. Printed only: how
/// far A's feature points (conformal-factor peaks, mostly cusps) land from
/// the nearest feature point of B; the features themselves are not stable
/// landmarks between specimens, so this is a loose indication.
#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn real_teeth_of_one_genus_cusps_and_round_trips() {
    let Some(dir) = crate::support::data::teeth_meshes() else {
        return;
    };
    let settings = Settings::default();
    let (mut cusp_errors, mut trip_errors) = (Vec::new(), Vec::new());
    for (a, b) in [
        ("j01", "j06"),
        ("i14", "i15"),
        ("x07", "x09"),
        ("V01", "V02"),
        ("U13", "V08"),
    ] {
        let load = |n: &str| {
            let m = mesh_io::load(&dir.join(format!("{n}.ply")))
                .expect("tooth loads")
                .mesh;
            pipeline::prepare_mesh(&m, n, &settings).expect("tooth prepares")
        };
        let (sa, sb) = (load(a), load(b));
        let c = cp::compare(&sa.prepared, &sb.prepared, &settings.cp.compare);
        let (ta, tb) = (
            Surface::from_prepared(&sa).unwrap(),
            Surface::from_prepared(&sb).unwrap(),
        );
        let lm = choose_landmarks(&sa, 77);
        let there = landmarks::propagate(&lm, &ta, &tb, &c.forward.correspondence).unwrap();
        let back =
            landmarks::propagate(&there.landmarks, &tb, &ta, &c.backward.correspondence).unwrap();
        let (da, db) = (bbox_diagonal(&sa.cleaned), bbox_diagonal(&sb.cleaned));
        let trip: Vec<f64> = lm
            .points()
            .iter()
            .zip(back.landmarks.points())
            .map(|(p, q)| norm(sub(*p, *q)) / da)
            .collect();
        // The first landmarks are A's cusp tips (features).
        let cusps = sa.prepared.features().len().min(5);
        let cusp: Vec<f64> = there.landmarks.points()[..cusps]
            .iter()
            .map(|p| {
                sb.prepared
                    .features()
                    .iter()
                    .map(|&v| norm(sub(*p, sb.cleaned.vertices[v as usize])) / db)
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        println!(
            "{a} → {b} (cP {:.4}): feature to nearest feature / diagonal {:?}; round trip mean {:.4}",
            c.distance,
            cusp.iter().map(|x| (x * 1e4).round() / 1e4).collect::<Vec<_>>(),
            trip.iter().sum::<f64>() / trip.len() as f64
        );
        cusp_errors.extend(cusp);
        trip_errors.extend(trip);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (mc, mt) = (median(&mut cusp_errors), median(&mut trip_errors));
    println!("median feature error {mc:.4}, median round-trip error {mt:.4} (of the diagonal)");
    assert!(mt < 0.01, "median round-trip error {mt}");
    assert!(
        trip_errors.iter().all(|&e| e < 0.1),
        "a landmark came back far away"
    );
}
