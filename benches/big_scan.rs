//! What a µCT-resolution surface export costs, measured as users run it:
//! a real tooth (J12) subdivided four times (~2.5 M triangles) written as
//! binary STL (~128 MB), then `morphoid inspect` and `morphoid classify` (five times)
//! (against the 116-tooth library, prepared once beforehand so the cache
//! is warm) run as whole processes under `/usr/bin/time`: wall time, CPU
//! time (user + system) and peak RSS of each. Without the real teeth, a synthetic crown and a
//! synthetic library stand in.
//!
//! `cargo build --release && cargo bench --bench big_scan`

use morphoid_data::mesh_io;
use morphoid_synth::mesh::{self as synth, LibrarySpec, CROWN_GENERA};
use std::path::Path;

#[allow(dead_code)]
#[path = "../tests/it/support/mod.rs"]
mod support;
use support::measured::{library_config, morphoid_binary, run_measured, wall_summary};

/// Run `morphoid ARGS` under GNU time (its figures in `figures`); (wall
/// seconds, CPU seconds, peak RSS in MB).
fn timed(bin: &Path, args: &[&str], figures: &Path) -> (f64, f64, f64) {
    let (cost, _) = run_measured(bin, args, figures).unwrap_or_else(|e| panic!("{e:#}"));
    (cost.wall, cost.cpu, cost.peak_rss_mb)
}

fn main() {
    // `cargo bench` passes `--bench`; nothing to parse.
    let bin = morphoid_binary();
    let tmp = tempfile::tempdir().expect("temp dir");
    let (base, library) = match support::data::teeth_dir_if_present() {
        Some(dir) => (
            mesh_io::load(&dir.join("meshes").join("J12.ply"))
                .expect("J12 loads")
                .mesh,
            dir,
        ),
        None => {
            eprintln!("real teeth not found: synthetic crown and library");
            let lib = tmp.path().join("library");
            synth::write_synthetic_library(&lib, &LibrarySpec::default()).expect("library");
            (synth::crown(&CROWN_GENERA[0], 1, 5000), lib)
        }
    };
    let scan = tmp.path().join("big.stl");
    {
        let dense = synth::subdivide_midpoint(&base, 4);
        mesh_io::save(&scan, &dense).expect("write the big scan");
        println!(
            "scan: {} triangles, {:.0} MB binary STL",
            dense.face_count(),
            std::fs::metadata(&scan).map(|m| m.len()).unwrap_or(0) as f64 / 1e6
        );
    }
    let scan = scan.to_string_lossy().into_owned();
    let cache = tmp.path().join("cache");
    let config = library_config(tmp.path(), "build", &library, &cache);
    let figures = tmp.path().join("time.txt");
    // Prepare the library once, so classify measures the scan, not the build.
    timed(&bin, &["--config", &config, "library", "build"], &figures);
    let (t, cpu, rss) = timed(&bin, &["--config", &config, "inspect", &scan], &figures);
    println!("inspect  {t:6.2} s  CPU {cpu:6.2} s  peak RSS {rss:6.0} MB");
    // Five identifications, each into a database of its own (the same
    // content twice in one database is a duplicate, not identified again).
    let mut walls = Vec::new();
    for run in 0..RUNS {
        let config = library_config(tmp.path(), &run.to_string(), &library, &cache);
        let (t, cpu, rss) = timed(&bin, &["--config", &config, "classify", &scan], &figures);
        println!(
            "classify {t:6.2} s  CPU {cpu:6.2} s  peak RSS {rss:6.0} MB  (116 references from the cache)"
        );
        walls.push(t);
    }
    println!("classify wall: {}", wall_summary(&walls));
}

/// How many times the scan is identified.
const RUNS: usize = 5;
