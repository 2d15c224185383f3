//! Timing of normalization, flattening and conformal factor on real teeth.
//! Prints, never asserts timing; run with
//! `cargo test --release --test conformal_timing -- --nocapture`.

use morphoid::conformal::{
    conformal_factor, flatten_to_disk_with, intrinsic_delaunay_weights, normalize, LaplacianWeights,
};
use morphoid::mesh::Mesh;
use std::path::Path;
use std::time::Instant;

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/pnas-teeth");

/// A tooth as stored (the library's PLY reader).
fn read_tooth(path: &Path) -> Option<Mesh> {
    morphoid::mesh::io::load(path).ok().map(|l| l.mesh)
}

#[test]
fn time_preparation_of_teeth() {
    let names = ["B03", "D09", "H10", "Q02", "T04"];
    let dir = Path::new(DATA).join("meshes");
    if !dir.is_dir() {
        println!("skipped: data not found");
        return;
    }
    for name in names {
        let Some(mesh) = read_tooth(&dir.join(format!("{name}.ply"))) else {
            println!("skipped: data not found");
            return;
        };
        // Best of a few runs, to leave out warm-up.
        let mut best = [f64::INFINITY; 4];
        for _ in 0..5 {
            let t0 = Instant::now();
            let norm = normalize(&mesh).unwrap();
            let t1 = Instant::now();
            let map = flatten_to_disk_with(&norm.mesh, LaplacianWeights::IntrinsicDelaunay);
            let t2 = Instant::now();
            let f = map.as_ref().map(|m| conformal_factor(&norm.mesh, &m.uv));
            let t3 = Instant::now();
            let _ = intrinsic_delaunay_weights(&norm.mesh);
            let t4 = Instant::now();
            assert!(f.is_ok());
            let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
            for (b, x) in best
                .iter_mut()
                .zip([ms(t0, t1), ms(t1, t2), ms(t2, t3), ms(t3, t4)])
            {
                *b = b.min(x);
            }
        }
        println!(
            "{name} ({} vertices): normalize {:.2} ms, flatten {:.2} ms (of which intrinsic Delaunay {:.2} ms), conformal factor {:.2} ms, total {:.2} ms",
            mesh.vertices.len(),
            best[0],
            best[1],
            best[3],
            best[2],
            best[0] + best[1] + best[2]
        );
    }
}

/// A `k × k` grid of the unit square lifted onto the paraboloid
/// z = x² + y² (a disk-type surface).
fn paraboloid_grid(k: usize) -> Mesh {
    let idx = |i: usize, j: usize| (j * (k + 1) + i) as u32;
    let mut vertices = Vec::new();
    for j in 0..=k {
        for i in 0..=k {
            let (x, y) = (
                -1.0 + 2.0 * i as f64 / k as f64,
                -1.0 + 2.0 * j as f64 / k as f64,
            );
            vertices.push([x, y, 0.5 * (x * x + y * y)]);
        }
    }
    let mut faces = Vec::new();
    for j in 0..k {
        for i in 0..k {
            faces.push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
            faces.push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
        }
    }
    Mesh::new(vertices, faces)
}

#[test]
fn time_preparation_by_size() {
    for k in [70, 140, 223] {
        let mesh = paraboloid_grid(k);
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let t0 = Instant::now();
            let norm = normalize(&mesh).unwrap();
            let map = morphoid::conformal::flatten_to_disk(&norm.mesh).unwrap();
            let f = conformal_factor(&norm.mesh, &map.uv);
            best = best.min(t0.elapsed().as_secs_f64() * 1e3);
            assert_eq!(f.len(), mesh.vertices.len());
        }
        println!(
            "paraboloid grid, {} vertices: normalize + flatten + conformal factor {best:.1} ms",
            mesh.vertices.len()
        );
    }
}
