//! Benchmark of the cW distance on one core: one pair (screening, exact
//! transports, refinement). Uses the PNAS teeth H10 and H16 when present,
//! else two synthetic crowns.
//!
//! `cargo bench --bench cw`

// The integration tests' helpers (real-data location, loading as users do);
// a bench uses only some of them.
#[allow(dead_code)]
#[path = "../tests/it/support/mod.rs"]
mod support;

use criterion::{criterion_group, criterion_main, Criterion};
use morphoid::cp::{self, CpParams};
use morphoid::cw::{self, CwParams};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let (a, b, what) = support::cp::benchmark_pair();
    eprintln!("benchmarking cW on {what}, one thread");
    let cp_params = CpParams::default();
    let params = CwParams::default();
    let (Ok(pa), Ok(pb)) = (
        cp::prepare(&a, &cp_params.prepare),
        cp::prepare(&b, &cp_params.prepare),
    ) else {
        eprintln!("preparation failed; nothing benchmarked");
        return;
    };
    // One worker: the figure is the time per pair on one core (matrices
    // run pairs in parallel, one per core).
    let Ok(pool) = rayon::ThreadPoolBuilder::new().num_threads(1).build() else {
        eprintln!("cannot start a thread pool");
        return;
    };
    if let Ok(r) = pool.install(|| cw::distance(&pa, &pb, &params)) {
        eprintln!(
            "distance {:.6}: {} maps screened in {:.1} ms, {} exact transports and refinement {:.1} ms",
            r.distance, r.screened, r.screen_ms, r.exact_solves, r.exact_ms
        );
    }
    c.bench_function("cw distance", |bch| {
        bch.iter(|| {
            pool.install(|| cw::distance(black_box(&pa), black_box(&pb), &params))
                .map(|r| r.distance)
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
