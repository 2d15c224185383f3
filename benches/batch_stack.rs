//! What a batch scan costs (issue #29's speed target): three real teeth,
//! each in its own foam and tube, standing side by side in one stack of
//! at least 300³ voxels (16-bit TIFF slices, `morphoid_synth::volume::mounting`), then
//! `morphoid classify` of the stack against the 116-tooth library
//! (prepared once beforehand, so the cache is warm) run three times as a
//! whole process under GNU time: wall time, CPU time and peak RSS, and
//! each specimen's answer. Without the real teeth, synthetic crowns and a
//! synthetic library stand in.
//!
//! ```sh
//! cargo build --release && cargo bench --bench batch_stack
//! ```
//!
//! `MORPHOID_BENCH_ACROSS` sets the voxels across each crown (default 64,
//! which puts the row of three mounts in about 300 voxels);
//! `MORPHOID_BENCH_WORK=DIR` works in `DIR` and keeps the stack, the
//! library's cache and the databases there for a closer look.

use morphoid_data::mesh_io;
use morphoid_synth::mesh::{self as synth, LibrarySpec, Mesh, CROWN_GENERA};
use std::path::PathBuf;

#[allow(dead_code)]
#[path = "../tests/it/support/mod.rs"]
mod support;
use morphoid_synth::volume::mounting::{batch_mounts, write_batch_in};
use support::measured::{library_config, morphoid_binary, run_measured, wall_summary};

/// Identifications measured.
const RUNS: usize = 3;
/// The smallest stack, in voxels along each axis.
const STACK: usize = 300;
/// The real teeth scanned together (three genera).
const TEETH: [&str; 3] = ["H10", "J12", "x15"];

fn main() {
    // `cargo bench` passes `--bench`; the knobs are in the environment.
    let across: usize = std::env::var("MORPHOID_BENCH_ACROSS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(64);
    let bin = morphoid_binary();
    let tmp = tempfile::tempdir().expect("temp dir");
    let work = std::env::var_os("MORPHOID_BENCH_WORK")
        .map_or_else(|| tmp.path().to_path_buf(), PathBuf::from);
    std::fs::create_dir_all(&work).expect("work folder");
    let (crowns, library): (Vec<Mesh>, PathBuf) = match support::data::teeth_dir_if_present() {
        Some(dir) => (
            TEETH
                .iter()
                .map(|n| {
                    mesh_io::load(&dir.join("meshes").join(format!("{n}.ply")))
                        .unwrap_or_else(|e| panic!("{n}: {e}"))
                        .mesh
                })
                .collect(),
            dir,
        ),
        None => {
            eprintln!("real teeth not found: synthetic crowns and library");
            let lib = work.join("library");
            synth::write_synthetic_library(&lib, &LibrarySpec::default()).expect("library");
            (
                (0..3)
                    .map(|k| synth::crown(&CROWN_GENERA[k], 7 + k as u64, 5000))
                    .collect(),
                lib,
            )
        }
    };
    let stack = work.join("batch");
    let teeth: Vec<(&Mesh, _)> = crowns.iter().zip(batch_mounts(7, across, 3)).collect();
    let truth = write_batch_in(&teeth, 3, [STACK; 3], &stack).expect("batch stack written");
    let dims = truth.first().map_or([0; 3], |t| t.dims);
    println!(
        "stack: {}×{}×{} voxels ({:.1} M), three teeth {across} voxels across",
        dims[0],
        dims[1],
        dims[2],
        (dims[0] * dims[1] * dims[2]) as f64 / 1e6
    );
    let cache = work.join("cache");
    let figures = work.join("time.txt");
    let config = |run: usize| library_config(&work, &run.to_string(), &library, &cache);
    // Prepare the library once, so classify measures the scan, not the build.
    let build = config(0);
    run_measured(&bin, &["--config", &build, "library", "build"], &figures)
        .unwrap_or_else(|e| panic!("{e:#}"));
    let stack = stack.to_string_lossy().into_owned();
    let mut walls = Vec::new();
    for run in 1..=RUNS {
        // Each into a database of its own: the same content twice in one
        // database is a duplicate, not identified again.
        let config = config(run);
        let (cost, out) = run_measured(&bin, &["--config", &config, "classify", &stack], &figures)
            .unwrap_or_else(|e| panic!("{e:#}"));
        println!(
            "classify {:6.2} s  CPU {:6.2} s  peak RSS {:5.0} MB",
            cost.wall, cost.cpu, cost.peak_rss_mb
        );
        if run == 1 {
            print!("{out}");
        }
        walls.push(cost.wall);
    }
    println!("classify wall: {}", wall_summary(&walls));
}
