//! What a lab waits for: `library build` of the reference library (first
//! run and second run), then one new ~5k-vertex scan identified end to end
//! against the prepared library — read, hash, enqueue in SQLite, load,
//! clean, flatten, compare with every reference, identify, commit — the
//! path `morphoid classify` and the daemon take.
//!
//! Uses the 116 PNAS teeth when `../shared/data/pnas-teeth` is beside the
//! project, else a synthetic library of 116 crowns.
//!
//! `cargo bench --bench classify`

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use morphoid_core::mesh::Mesh;
use morphoid_data::hash::content_hash;
use morphoid_data::library::{BuildOutcome, Cache, Library};
use morphoid_data::mesh_io;
use morphoid_data::pipeline::Settings;
use morphoid_service::classify::{self, Classifier};
use morphoid_service::store::{Enqueued, ScanStatus, Store};
use morphoid_synth::mesh::{self as synth, LibrarySpec, RigidMotion};
use std::path::{Path, PathBuf};
use std::time::Instant;

// The integration tests' helpers (real-data location, loading as users do);
// a bench uses only some of them.
#[allow(dead_code)]
#[path = "../tests/it/support/mod.rs"]
mod support;

/// The library folder: the real teeth, or a synthetic one written to `tmp`.
fn library_dir(tmp: &Path) -> PathBuf {
    if let Some(real) = support::data::teeth_dir_if_present() {
        return real;
    }
    eprintln!("real teeth not found: using a synthetic library of 116 crowns");
    let dir = tmp.join("library");
    let genera = synth::CROWN_GENERA.len();
    let spec = LibrarySpec {
        per_genus: 116usize.div_ceil(genera),
        target_vertices: 5000,
        seed: 7,
        random_pose: true,
    };
    synth::write_synthetic_library(&dir, &spec).expect("write synthetic library");
    dir
}

/// Time one `library build` (prepare what the cache lacks).
fn timed_build(
    lib: &Library,
    cache: &Cache,
    settings: &Settings,
) -> (Classifier, BuildOutcome, f64) {
    let t = Instant::now();
    let (classifier, outcome) =
        Classifier::build(lib, cache, settings, |_| {}).expect("library builds");
    let secs = t.elapsed().as_secs_f64();
    eprintln!(
        "library build: {} references ({} prepared, {} from the cache, {} failed) in {secs:.2} s",
        classifier.references().len(),
        outcome.prepared(),
        outcome.reused(),
        outcome.failures().len()
    );
    (classifier, outcome, secs)
}

/// Identify one scan file as `morphoid classify` does; returns its status.
fn identify(store: &mut Store, classifier: &Classifier, path: &Path) -> ScanStatus {
    let bytes = std::fs::read(path).expect("scan file");
    let hash = content_hash(&bytes);
    let id = match store
        .enqueue(&path.display().to_string(), &hash, bytes.len() as u64)
        .expect("enqueue")
    {
        Enqueued::New(id) | Enqueued::Existing(id, _) | Enqueued::Duplicate { id, .. } => id,
    };
    let job = store
        .claim(id)
        .expect("claim")
        .expect("a new scan is pending");
    classify::run_job(store, classifier, &job).expect("database write")
}

fn bench(c: &mut Criterion) {
    let tmp = tempfile::tempdir().expect("temp dir");
    let dir = library_dir(tmp.path());
    let lib = Library::open(&dir, None).expect("library opens");
    let cache = Cache::open(&tmp.path().join("cache")).expect("cache");
    let settings = Settings::default();
    let (_, _, first) = timed_build(&lib, &cache, &settings);
    let (classifier, outcome, second) = timed_build(&lib, &cache, &settings);
    eprintln!("library build: first run {first:.2} s, second run {second:.3} s");

    let mut store = Store::open(&tmp.path().join("bench.sqlite")).expect("database");
    classifier
        .register(&mut store, &outcome)
        .expect("references recorded");
    let source = mesh_io::load(lib.members()[0].path())
        .expect("a library surface loads")
        .mesh;
    let mut seed = 0u64;
    let mut group = c.benchmark_group("classify");
    group.sample_size(10);
    let name = format!("new scan vs {} references", classifier.references().len());
    bench_identify(
        &mut group,
        &name,
        &mut store,
        &classifier,
        &source,
        tmp.path(),
        &mut seed,
    );
    // The same without the final descent of each comparison, to show its
    // cost (the references' preparation does not depend on it).
    let mut settings = classifier.settings().clone();
    settings.cp.compare.descent_steps = 0;
    let searched_only = classifier.clone().with_settings(settings);
    bench_identify(
        &mut group,
        &format!("{name}, without final descent"),
        &mut store,
        &searched_only,
        &source,
        tmp.path(),
        &mut seed,
    );
    group.finish();
}

/// Time one identification of a fresh pose of `source` (written to
/// `dir`) against `classifier`'s references, under `name`.
fn bench_identify(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    name: &str,
    store: &mut Store,
    classifier: &Classifier,
    source: &Mesh,
    dir: &Path,
    seed: &mut u64,
) {
    group.bench_function(name, |b| {
        b.iter_batched(
            || {
                // A scan the database has not seen: a fresh pose each time.
                *seed += 1;
                let scan = synth::scale(&RigidMotion::random(*seed, 5.0).apply(source), 1000.0);
                let path = dir.join(format!("scan{seed}.ply"));
                mesh_io::save(&path, &scan).expect("write scan");
                path
            },
            |path| {
                let status = identify(store, classifier, &path);
                assert_eq!(status, ScanStatus::Ok);
            },
            BatchSize::PerIteration,
        )
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
