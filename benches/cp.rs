//! Benchmarks of the cP engine: preparing a tooth and comparing two.
//! Uses the PNAS teeth when present, else synthetic crowns of ~5k vertices.

// The integration tests' helpers (real-data location, loading as users do);
// a bench uses only some of them.
#[allow(dead_code)]
#[path = "../tests/it/support/mod.rs"]
mod support;

use criterion::{criterion_group, criterion_main, Criterion};
use morphoid_core::cp::{self, CpParams};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let (a, b, what) = support::cp::benchmark_pair();
    eprintln!(
        "benchmarking on {what}: {} and {} vertices",
        a.vertex_count(),
        b.vertex_count()
    );
    let params = CpParams::default();
    c.bench_function("prepare", |bch| {
        bch.iter(|| cp::prepare(black_box(&a), &params.prepare).map(|p| p.samples().len()))
    });
    let (Ok(pa), Ok(pb)) = (
        cp::prepare(&a, &params.prepare),
        cp::prepare(&b, &params.prepare),
    ) else {
        eprintln!("preparation failed; compare not benchmarked");
        return;
    };
    c.bench_function("compare", |bch| {
        bch.iter(|| cp::compare(black_box(&pa), black_box(&pb), &params.compare).distance)
    });
    // The same comparison without the final descent, to show its cost.
    let mut searched_only = params.clone();
    searched_only.compare.descent_steps = 0;
    c.bench_function("compare without final descent", |bch| {
        bch.iter(|| cp::compare(black_box(&pa), black_box(&pb), &searched_only.compare).distance)
    });
    // The same comparison without the area correction χ (and so without
    // the descent, which needs it), to show its cost.
    let mut plain = params.clone();
    plain.compare.area_correction = false;
    c.bench_function("compare without area correction", |bch| {
        bch.iter(|| cp::compare(black_box(&pa), black_box(&pb), &plain.compare).distance)
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
