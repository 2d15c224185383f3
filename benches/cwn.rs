//! Benchmarks of the cWn distance on one core: building a landscape and
//! one pair (cost matrix + transport). Uses the PNAS teeth H10 and H16
//! when present, else two synthetic crowns.
//!
//! `cargo bench --bench cwn`

// The integration tests' helpers (real-data location, loading as users do);
// a bench uses only some of them.
#[allow(dead_code)]
#[path = "../tests/it/support/mod.rs"]
mod support;

use criterion::{criterion_group, criterion_main, Criterion};
use morphoid::cp::{self, CpParams};
use morphoid::cwn::{self, CwnParams};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let (a, b, what) = support::cp::benchmark_pair();
    eprintln!("benchmarking cWn on {what}, one thread");
    let cp_params = CpParams::default();
    let params = CwnParams::default();
    let (Ok(pa), Ok(pb)) = (cp::prepare(&a, &cp_params), cp::prepare(&b, &cp_params)) else {
        eprintln!("preparation failed; nothing benchmarked");
        return;
    };
    // One worker: the figure is the time per pair on one core (matrices
    // run pairs in parallel, one per core).
    let Ok(pool) = rayon::ThreadPoolBuilder::new().num_threads(1).build() else {
        eprintln!("cannot start a thread pool");
        return;
    };
    c.bench_function("cwn landscape", |bch| {
        bch.iter(|| pool.install(|| cwn::prepare(black_box(&pa), &params).map(|l| l.len())))
    });
    let (Ok(la), Ok(lb)) = (cwn::prepare(&pa, &params), cwn::prepare(&pb, &params)) else {
        eprintln!("landscape failed; distance not benchmarked");
        return;
    };
    if let Ok(r) = pool.install(|| cwn::distance(&la, &lb, &params)) {
        eprintln!(
            "distance {:.6}: cost matrix {:.1} ms, transport {:.1} ms ({} pivots)",
            r.distance, r.cost_ms, r.transport_ms, r.pivots
        );
    }
    c.bench_function("cwn distance", |bch| {
        bch.iter(|| {
            pool.install(|| cwn::distance(black_box(&la), black_box(&lb), &params))
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
