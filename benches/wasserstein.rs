//! Benchmarks of the two conformal Wasserstein distances on one core, on
//! one pair: cW (screening, exact transports, refinement) and cWn
//! (building a landscape; cost matrix + transport). Uses the PNAS teeth
//! H10 and H16 when present, else two synthetic crowns.
//!
//! `cargo bench --bench wasserstein` (`-- cw` or `-- cwn` for one of them)

// The integration tests' helpers (real-data location, loading as users do);
// a bench uses only some of them.
#[allow(dead_code)]
#[path = "../tests/it/support/mod.rs"]
mod support;

use criterion::{criterion_group, criterion_main, Criterion};
use morphoid_core::cp::{self, CpParams, Prepared};
use morphoid_core::cw::{self, CwParams};
use morphoid_core::cwn::{self, CwnParams};
use rayon::ThreadPool;
use std::hint::black_box;

/// The prepared benchmark pair and a one-worker pool: the figures are the
/// time per pair on one core (matrices run pairs in parallel, one per
/// core).
fn setup() -> Option<(Prepared, Prepared, ThreadPool)> {
    let (a, b, what) = support::cp::benchmark_pair();
    eprintln!("benchmarking on {what}, one thread");
    let params = CpParams::default();
    let (Ok(pa), Ok(pb)) = (
        cp::prepare(&a, &params.prepare),
        cp::prepare(&b, &params.prepare),
    ) else {
        eprintln!("preparation failed; nothing benchmarked");
        return None;
    };
    let Ok(pool) = rayon::ThreadPoolBuilder::new().num_threads(1).build() else {
        eprintln!("cannot start a thread pool");
        return None;
    };
    Some((pa, pb, pool))
}

fn bench(c: &mut Criterion) {
    let Some((pa, pb, pool)) = setup() else {
        return;
    };

    let params = CwParams::default();
    if let Ok(r) = pool.install(|| cw::distance(&pa, &pb, &params)) {
        eprintln!(
            "cW distance {:.6}: {} maps screened in {:.1} ms, {} exact transports and refinement {:.1} ms",
            r.distance, r.screened, r.screen_ms, r.exact_solves, r.exact_ms
        );
    }
    c.bench_function("cw distance", |bch| {
        bch.iter(|| {
            pool.install(|| cw::distance(black_box(&pa), black_box(&pb), &params))
                .map(|r| r.distance)
        })
    });

    let params = CwnParams::default();
    c.bench_function("cwn landscape", |bch| {
        bch.iter(|| pool.install(|| cwn::prepare(black_box(&pa), &params).map(|l| l.len())))
    });
    let (Ok(la), Ok(lb)) = (cwn::prepare(&pa, &params), cwn::prepare(&pb, &params)) else {
        eprintln!("landscape failed; cWn distance not benchmarked");
        return;
    };
    if let Ok(r) = pool.install(|| cwn::distance(&la, &lb, &params)) {
        eprintln!(
            "cWn distance {:.6}: cost matrix {:.1} ms, transport {:.1} ms ({} pivots)",
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
