//! Reports: one scan's report written (pictures rendered and encoded, the
//! page with its 3D data, thumbnail; the scene is computed during
//! identification and not counted here), and the overview `index.html`
//! updated with 10 000 scans in the database (older pages already
//! written, as after the first update).
//!
//! `cargo bench --bench report`

use criterion::{criterion_group, criterion_main, Criterion};
use morphoid_data::pipeline::{self, Settings};
use morphoid_service::classify::ResultFiles;
use morphoid_service::report::{Scene, SceneReference};
use morphoid_service::store::{Enqueued, Store};
use morphoid_synth::mesh::{self as synth, CROWN_GENERA};
use std::time::Instant;

// The integration tests' helpers (a filled store); a bench uses only some.
#[allow(dead_code)]
#[path = "../tests/it/support/mod.rs"]
mod support;

/// Scans in the database for the overview.
const SCANS: usize = 10_000;

/// A store with `n` identified scans (on tmpfs when there is one: the
/// fill commits each scan with fsync).
fn filled_store(dir: &std::path::Path, n: usize) -> Store {
    let mut store = Store::open(&dir.join("db.sqlite")).unwrap();
    support::store::register_references(&mut store, 20);
    for i in 0..n {
        let path = format!("/export/day{}/scan-{i:05}.ply", i / 100);
        let id = match store.enqueue(&path, &format!("{i:064x}"), 1000).unwrap() {
            Enqueued::New(id) => id,
            other => panic!("{other:?}"),
        };
        store.claim(id).unwrap();
        store
            .complete(id, &support::store::outcome(i as u64, 20))
            .unwrap();
    }
    store
}

/// A scan crown and its three nearest references at the working
/// resolution (5000 vertices), as a report draws them.
fn scene() -> Scene {
    let settings = Settings::default();
    let prepare = |g: usize, seed: u64| {
        let crown = synth::crown(&CROWN_GENERA[g], seed, 5000);
        pipeline::prepare_mesh(&crown, &format!("c{g}-{seed}"), &settings)
            .unwrap()
            .prepared
    };
    let scan = prepare(0, 1);
    let refs = [prepare(0, 2), prepare(1, 3), prepare(2, 4)];
    let names = ["r0", "r1", "r2"];
    let references: Vec<SceneReference<'_>> = refs
        .iter()
        .zip(names)
        .enumerate()
        .map(|(i, (p, name))| SceneReference {
            name,
            distance: 0.02 * (i + 1) as f64,
            prepared: p,
        })
        .collect();
    let t = Instant::now();
    let s = Scene::build(&scan, &references, &[], &settings.cp.compare);
    eprintln!(
        "scene of a 5000-vertex scan and 3 references (at identification): {:.0} ms",
        t.elapsed().as_secs_f64() * 1e3
    );
    s
}

fn bench(c: &mut Criterion) {
    let shm = std::path::Path::new("/dev/shm");
    let tmp = if shm.is_dir() {
        tempfile::tempdir_in(shm).unwrap()
    } else {
        tempfile::tempdir().unwrap()
    };
    let t = Instant::now();
    let mut store = filled_store(tmp.path(), SCANS);
    eprintln!(
        "filled the database with {SCANS} scans in {:.1} s",
        t.elapsed().as_secs_f64()
    );
    let out = tmp.path().join("results");
    let files = ResultFiles::new(out.clone(), Some("/export".into()));

    let t = Instant::now();
    files.write_index(&mut store).unwrap();
    eprintln!(
        "first overview (older pages written once): {:.2} s",
        t.elapsed().as_secs_f64()
    );
    c.bench_function("overview update, 10 000 scans", |b| {
        b.iter(|| files.write_index(&mut store).unwrap())
    });

    let scene = scene();
    let record = store.scan(SCANS as i64, 5).unwrap().unwrap();
    let path = files.write_report(&record, Some(&scene), None).unwrap();
    eprintln!("report: {} bytes", std::fs::metadata(&path).unwrap().len());
    c.bench_function("report of a 5000-vertex scan, 3 references", |b| {
        b.iter(|| files.write_report(&record, Some(&scene), None).unwrap())
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
