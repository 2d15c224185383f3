//! Conformal flattening of the 116 real teeth (needs the data set, see
//! `support::data`).

use morphoid_core::conformal::{
    conformal_factor, flatten_to_disk, flatten_to_disk_with, flipped_triangles, normalize,
    quasi_conformal_ratios, FlattenError, LaplacianWeights,
};
use morphoid_core::mesh::Mesh;
use std::path::{Path, PathBuf};

/// Teeth with a non-manifold edge, which only cleaning repairs.
const NEEDS_CLEANING: [&str; 2] = ["J12", "S09"];

/// A tooth as stored (the library's PLY reader).
fn read_tooth(path: &Path) -> Mesh {
    morphoid_data::mesh_io::load(path).unwrap().mesh
}

fn tooth_paths() -> Option<Vec<PathBuf>> {
    crate::support::data::tooth_paths()
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn all_teeth_flatten_without_flips() {
    let Some(paths) = tooth_paths() else {
        return;
    };
    assert_eq!(paths.len(), 116);
    let mut all_ratios = Vec::new();
    let mut done = 0;
    for path in &paths {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        let mesh = read_tooth(path);
        if NEEDS_CLEANING.contains(&name.as_str()) {
            assert!(matches!(
                flatten_to_disk(&mesh),
                Err(FlattenError::NonManifold { .. } | FlattenError::NotDisk { .. })
            ));
            continue;
        }
        let norm = normalize(&mesh).unwrap();
        let map = flatten_to_disk(&norm.mesh).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(flipped_triangles(&norm.mesh.faces, &map.uv), 0, "{name}");
        let on_boundary = boundary_vertices(&norm.mesh);
        for (v, z) in map.uv.iter().enumerate() {
            let r = z[0].hypot(z[1]);
            if on_boundary[v] {
                assert!(
                    (r - 1.0).abs() < 1e-6,
                    "{name}: boundary vertex {v} at |z| = {r}"
                );
            } else {
                assert!(r < 1.0, "{name}: interior vertex {v} at |z| = {r}");
            }
        }
        assert_eq!(map.uv[map.center as usize], [0.0, 0.0]);
        let f = conformal_factor(&norm.mesh, &map.uv);
        assert!(f.iter().all(|x| x.is_finite() && *x > 0.0), "{name}");
        let q = quasi_conformal_ratios(&norm.mesh, &map.uv);
        let mut sq = q.clone();
        sq.sort_by(f64::total_cmp);
        println!(
            "{name}: median {:.4} p95 {:.4} max {:.3}",
            percentile(&sq, 0.5),
            percentile(&sq, 0.95),
            sq[sq.len() - 1]
        );
        all_ratios.extend(q);
        done += 1;
    }
    all_ratios.sort_by(f64::total_cmp);
    println!(
        "{done} teeth, {} triangles: quasi-conformal ratio median {:.4}, 95th percentile {:.4}, 99th {:.4}",
        all_ratios.len(),
        percentile(&all_ratios, 0.5),
        percentile(&all_ratios, 0.95),
        percentile(&all_ratios, 0.99)
    );
    assert_eq!(done, 114);
    assert!(percentile(&all_ratios, 0.5) < 1.06);
    assert!(percentile(&all_ratios, 0.95) < 1.2);
}

fn boundary_vertices(mesh: &Mesh) -> Vec<bool> {
    let mut on = vec![false; mesh.vertices.len()];
    for lp in morphoid_core::mesh::boundary_loops(mesh) {
        for v in lp {
            on[v as usize] = true;
        }
    }
    on
}

/// Compares the two Laplacians on all teeth (prints; asserts only that each
/// method either succeeds or reports flips).
#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn compare_laplacians_on_teeth() {
    let Some(paths) = tooth_paths() else {
        return;
    };
    for method in [
        LaplacianWeights::IntrinsicDelaunay,
        LaplacianWeights::ClampedCotangent,
    ] {
        let mut ratios = Vec::new();
        let mut failed = Vec::new();
        for path in &paths {
            let name = path.file_stem().unwrap().to_string_lossy().to_string();
            if NEEDS_CLEANING.contains(&name.as_str()) {
                continue;
            }
            let mesh = normalize(&read_tooth(path)).unwrap().mesh;
            match flatten_to_disk_with(&mesh, method) {
                Ok(map) => ratios.extend(quasi_conformal_ratios(&mesh, &map.uv)),
                Err(FlattenError::Flipped { count }) => failed.push(format!("{name} ({count})")),
                Err(e) => panic!("{name}: {e}"),
            }
        }
        ratios.sort_by(f64::total_cmp);
        println!(
            "{method:?}: flipped on {} teeth {:?}; quasi-conformal ratio median {:.4}, p95 {:.4}, p99 {:.4}",
            failed.len(),
            failed,
            percentile(&ratios, 0.5),
            percentile(&ratios, 0.95),
            percentile(&ratios, 0.99)
        );
    }
}

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn rotated_and_scaled_teeth_flatten_identically() {
    let Some(paths) = tooth_paths() else {
        return;
    };
    // A rotation about the axis (1, 2, 2)/3 by 1 radian, scaling by 3.7 and
    // a translation.
    let (s, c) = 1f64.sin_cos();
    let k = [1.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0];
    let rot: [[f64; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let delta = if i == j { 1.0 } else { 0.0 };
            let cross = match (i, j) {
                (0, 1) => -k[2],
                (0, 2) => k[1],
                (1, 0) => k[2],
                (1, 2) => -k[0],
                (2, 0) => -k[1],
                (2, 1) => k[0],
                _ => 0.0,
            };
            c * delta + s * cross + (1.0 - c) * k[i] * k[j]
        })
    });
    let mut worst: f64 = 0.0;
    for path in paths.iter().step_by(10) {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        if NEEDS_CLEANING.contains(&name.as_str()) {
            continue;
        }
        let mesh = read_tooth(path);
        let moved = Mesh::new(
            mesh.vertices
                .iter()
                .map(|p| {
                    std::array::from_fn(|i| {
                        3.7 * (rot[i][0] * p[0] + rot[i][1] * p[1] + rot[i][2] * p[2])
                            + [10.0, -4.0, 2.5][i]
                    })
                })
                .collect(),
            mesh.faces.clone(),
        );
        let a = flatten_to_disk(&normalize(&mesh).unwrap().mesh).unwrap();
        let b = flatten_to_disk(&normalize(&moved).unwrap().mesh).unwrap();
        assert_eq!(a.center, b.center, "{name}");
        let d =
            a.uv.iter()
                .zip(&b.uv)
                .map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
                .fold(0.0, f64::max);
        worst = worst.max(d);
        assert!(d < 1e-6, "{name}: {d}");
    }
    println!("rigid motion + scaling: largest disk-coordinate change {worst:.2e}");
}
