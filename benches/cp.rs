//! Benchmarks of the cP engine: preparing a tooth and comparing two.
//! Uses the PNAS teeth when present, else synthetic crowns of ~5k vertices.

#[path = "../tests/cp_support/mod.rs"]
mod cp_support;

use criterion::{criterion_group, criterion_main, Criterion};
use morphoid::cp::{self, CpParams};
use morphoid::mesh::Mesh;
use std::hint::black_box;

/// A crown-like disk: a polar grid over the unit disk lifted by Gaussian
/// cusps, about 5,000 vertices.
fn synthetic_crown(phase: f64) -> Mesh {
    let (rings, sectors) = (40usize, 125usize);
    let cusps = [
        (0.5, 0.3 + phase),
        (0.5, 1.9),
        (0.45, 3.4),
        (0.5, 4.9 - phase),
    ];
    let height = |x: f64, y: f64| -> f64 {
        let base = 0.4 * (1.0 - x * x - y * y);
        base + cusps
            .iter()
            .map(|&(r, t)| {
                let (cx, cy) = (r * f64::cos(t), r * f64::sin(t));
                0.3 * (-((x - cx).powi(2) + (y - cy).powi(2)) / 0.03).exp()
            })
            .sum::<f64>()
    };
    let mut v = vec![[0.0, 0.0, height(0.0, 0.0)]];
    for r in 1..=rings {
        for s in 0..sectors {
            let t = s as f64 / sectors as f64 * std::f64::consts::TAU;
            let rad = r as f64 / rings as f64;
            let (x, y) = (rad * t.cos(), rad * t.sin());
            v.push([x, y, height(x, y)]);
        }
    }
    let id = |r: usize, s: usize| -> u32 {
        if r == 0 {
            0
        } else {
            (1 + (r - 1) * sectors + s % sectors) as u32
        }
    };
    let mut f = Vec::new();
    for s in 0..sectors {
        f.push([id(0, 0), id(1, s), id(1, s + 1)]);
    }
    for r in 1..rings {
        for s in 0..sectors {
            f.push([id(r, s), id(r + 1, s), id(r + 1, s + 1)]);
            f.push([id(r, s), id(r + 1, s + 1), id(r, s + 1)]);
        }
    }
    Mesh::new(v, f)
}

fn meshes() -> (Mesh, Mesh, &'static str) {
    let dir = std::path::PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/data/pnas-teeth"
    ));
    if dir.join("meshes/H10.ply").exists() && dir.join("meshes/H16.ply").exists() {
        (
            cp_support::load_tooth(&dir, "H10"),
            cp_support::load_tooth(&dir, "H16"),
            "real teeth H10, H16",
        )
    } else {
        (
            synthetic_crown(0.0),
            synthetic_crown(0.2),
            "synthetic crowns (data not found)",
        )
    }
}

fn bench(c: &mut Criterion) {
    let (a, b, what) = meshes();
    eprintln!(
        "benchmarking on {what}: {} and {} vertices",
        a.vertex_count(),
        b.vertex_count()
    );
    let params = CpParams::default();
    c.bench_function("prepare", |bch| {
        bch.iter(|| cp::prepare(black_box(&a), &params).map(|p| p.samples.len()))
    });
    let (Ok(pa), Ok(pb)) = (cp::prepare(&a, &params), cp::prepare(&b, &params)) else {
        eprintln!("preparation failed; compare not benchmarked");
        return;
    };
    c.bench_function("compare", |bch| {
        bch.iter(|| cp::compare(black_box(&pa), black_box(&pb), &params).distance)
    });
    // The same comparison without the area correction χ, to show its cost.
    let plain = CpParams {
        area_correction: false,
        ..params.clone()
    };
    c.bench_function("compare without area correction", |bch| {
        bch.iter(|| cp::compare(black_box(&pa), black_box(&pb), &plain).distance)
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
