//! What `morphoid inspect` costs: load + clean of a 5k-vertex surface, of
//! one 16 times denser (~80k vertices) and of a scanner cloud of it (10,000
//! points, noise 0.2 % of the diagonal, 2 % outliers: the reconstruction). Uses a PNAS tooth when the data is
//! beside the project, else a synthetic crown.
//!
//! `cargo bench --bench inspect`

use criterion::{criterion_group, criterion_main, Criterion};
use morphoid_core::clean::{clean, CleanOptions};
use morphoid_data::mesh_io;
use morphoid_synth::mesh::{self as synth, CROWN_GENERA};
use std::hint::black_box;

// The integration tests' helpers (real-data location, loading as users do);
// a bench uses only some of them.
#[allow(dead_code)]
#[path = "../tests/it/support/mod.rs"]
mod support;
use std::path::{Path, PathBuf};

fn source_surface() -> morphoid_core::mesh::Mesh {
    match support::data::teeth_dir_if_present().map(|d| d.join("meshes")) {
        Some(dir) => mesh_io::load(&dir.join("J12.ply")).expect("J12 loads").mesh,
        None => {
            eprintln!("real teeth not found: using a synthetic crown");
            synth::crown(&CROWN_GENERA[0], 1, 5000)
        }
    }
}

fn inspect(path: &Path) -> usize {
    let loaded = mesh_io::load(path).expect("bench input loads");
    let cleaned = clean(&loaded.mesh, &CleanOptions::default()).expect("bench input cleans");
    cleaned.mesh.vertex_count()
}

fn bench(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("morphoid-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let base = source_surface();
    let dense = synth::subdivide_midpoint(&base, 2);
    let cloud = synth::scanner_cloud(&base, &synth::ScannerCloud::default());
    let files: Vec<(String, PathBuf)> = [
        ("5k", &base),
        ("16x denser", &dense),
        ("scanner cloud", &cloud),
    ]
    .into_iter()
    .map(|(label, m)| {
        let p = dir.join(format!("{}.ply", label.replace(' ', "_")));
        mesh_io::save(&p, m).expect("write bench input");
        (
            format!("inspect {label} ({} vertices)", m.vertex_count()),
            p,
        )
    })
    .collect();
    let mut group = c.benchmark_group("inspect");
    group.sample_size(10);
    for (label, path) in &files {
        group.bench_function(label.as_str(), |b| b.iter(|| black_box(inspect(path))));
    }
    group.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
criterion_main!(benches);
