//! Synthetic crowns: disk-type, well shaped, deterministic, and the
//! configurations differ more than individuals of one configuration.

use morphoid_core::mesh::{
    boundary_loops, bounding_box, edge_face_map, euler_characteristic, norm, sub, triangle_normal2,
    Mesh,
};
use morphoid_synth::mesh::{crown, crown_genus, CROWN_GENERA};

/// Smallest interior angle of a triangle (degrees).
fn min_angle(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let ang = |p: [f64; 3], q: [f64; 3], r: [f64; 3]| {
        let (u, v) = (sub(q, p), sub(r, p));
        let cos = morphoid_core::mesh::dot(u, v) / (norm(u) * norm(v));
        cos.clamp(-1.0, 1.0).acos().to_degrees()
    };
    ang(a, b, c).min(ang(b, c, a)).min(ang(c, a, b))
}

#[test]
fn crowns_are_clean_disks() {
    for genus in &CROWN_GENERA {
        for seed in [1, 2] {
            let m = crown(genus, seed, 3000);
            assert_eq!(euler_characteristic(&m), 1, "{}", genus.name);
            assert_eq!(boundary_loops(&m).len(), 1, "{}", genus.name);
            // Manifold: every edge has one or two faces.
            assert!(edge_face_map(&m).values().all(|f| f.len() <= 2));
            // A height field over the plane, consistently oriented upward.
            let mut worst: f64 = 90.0;
            for f in &m.faces {
                let p = |i: usize| m.vertices[f[i] as usize];
                assert!(triangle_normal2(p(0), p(1), p(2))[2] > 0.0);
                worst = worst.min(min_angle(p(0), p(1), p(2)));
            }
            assert!(worst > 15.0, "{}: smallest angle {worst}", genus.name);
            assert!(m.vertices.iter().flatten().all(|c| c.is_finite()));
        }
    }
}

#[test]
fn crowns_are_deterministic_per_seed() {
    let g = crown_genus("quadricuspis").unwrap();
    assert_eq!(crown(g, 42, 1500), crown(g, 42, 1500));
    assert_ne!(crown(g, 42, 1500), crown(g, 43, 1500));
}

/// The height field sampled on a fixed polar grid of the footprint, after
/// normalizing by the footprint's half-width.
fn descriptor(m: &Mesh) -> Vec<f64> {
    let (lo, hi) = bounding_box(m).unwrap();
    let s = 0.5 * (hi[1] - lo[1]);
    let a = 0.5 * (hi[0] - lo[0]) / s;
    let mut out = Vec::new();
    for ri in 1..=6 {
        let r = 0.85 * ri as f64 / 6.0;
        for ti in 0..24 {
            let t = std::f64::consts::TAU * ti as f64 / 24.0;
            let q = [r * a * t.cos() * s, r * t.sin() * s];
            let nearest = m
                .vertices
                .iter()
                .min_by(|p, w| {
                    let d = |v: &&[f64; 3]| (v[0] - q[0]).powi(2) + (v[1] - q[1]).powi(2);
                    d(p).total_cmp(&d(w))
                })
                .unwrap();
            out.push(nearest[2] / s);
        }
    }
    out
}

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Largest (`max = true`) or smallest distance between members of two sets.
fn extreme(a: &[Vec<f64>], b: &[Vec<f64>], max: bool) -> f64 {
    let all = a.iter().flat_map(|x| b.iter().map(move |y| distance(x, y)));
    if max {
        all.fold(0.0, f64::max)
    } else {
        all.fold(f64::INFINITY, f64::min)
    }
}

#[test]
fn configurations_differ_more_than_individuals() {
    let seeds = [1u64, 2, 3, 4];
    let d: Vec<Vec<Vec<f64>>> = CROWN_GENERA
        .iter()
        .map(|g| {
            seeds
                .iter()
                .map(|&s| descriptor(&crown(g, s, 2000)))
                .collect()
        })
        .collect();
    let within: Vec<f64> = d.iter().map(|a| extreme(a, a, true)).collect();
    for (i, a) in d.iter().enumerate() {
        assert!(within[i] > 0.0, "individuals of {i} do not vary");
        for (j, b) in d.iter().enumerate().skip(i + 1) {
            let between = extreme(a, b, false);
            let spread = within[i].max(within[j]);
            println!("{i}-{j}: between {between:.2}, within {spread:.2}");
            assert!(
                between > 2.0 * spread,
                "{} vs {}: between {between}, within {spread}",
                CROWN_GENERA[i].name,
                CROWN_GENERA[j].name
            );
        }
    }
}

#[test]
fn synthetic_library_is_complete_and_reproducible() {
    use morphoid_synth::mesh::{write_synthetic_library, LibrarySpec};
    let spec = LibrarySpec {
        per_genus: 2,
        target_vertices: 400,
        seed: 5,
        random_pose: false,
    };
    let a = tempfile::tempdir().unwrap();
    let b = tempfile::tempdir().unwrap();
    let lib = write_synthetic_library(a.path(), &spec).unwrap();
    write_synthetic_library(b.path(), &spec).unwrap();
    assert_eq!(lib.len(), 2 * CROWN_GENERA.len());
    let labels = std::fs::read_to_string(a.path().join("labels.csv")).unwrap();
    let rows: Vec<&str> = labels.lines().collect();
    assert_eq!(rows[0], "name,order,family,genus");
    assert_eq!(rows.len(), 1 + lib.len());
    let mut names = std::collections::HashSet::new();
    for (s, row) in lib.iter().zip(&rows[1..]) {
        assert!(names.insert(s.name.clone()));
        assert_eq!(
            *row,
            format!(
                "{},{},{},{}",
                s.name, s.genus.order, s.genus.family, s.genus.name
            )
        );
        let m = morphoid_data::mesh_io::load(&s.path).unwrap().mesh;
        assert_eq!(euler_characteristic(&m), 1);
        let other = b.path().join(s.path.file_name().unwrap());
        assert_eq!(
            std::fs::read(&s.path).unwrap(),
            std::fs::read(other).unwrap()
        );
    }
    // Posed specimens are the same surfaces, moved and scaled.
    let posed = LibrarySpec {
        random_pose: true,
        ..spec
    };
    let g = &CROWN_GENERA[0];
    let plain = morphoid_synth::mesh::specimen_mesh(g, 9, &spec);
    let moved = morphoid_synth::mesh::specimen_mesh(g, 9, &posed);
    assert_eq!(plain.faces, moved.faces);
    let ratio =
        morphoid_core::mesh::surface_area(&moved) / morphoid_core::mesh::surface_area(&plain);
    assert!((0.25 - 1e-9..=4.0 + 1e-9).contains(&ratio), "{ratio}");
    let edge = |m: &Mesh, i: usize| norm(sub(m.vertices[i], m.vertices[0]));
    let s0 = edge(&moved, 1) / edge(&plain, 1);
    for i in 2..50 {
        assert!((edge(&moved, i) / edge(&plain, i) - s0).abs() < 1e-9);
    }
}
