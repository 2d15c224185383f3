//! What a µCT-resolution surface export costs, measured as users run it:
//! a real tooth (J12) subdivided four times (~2.5 M triangles) written as
//! binary STL (~128 MB), then `morphoid inspect` and `morphoid classify` (five times)
//! (against the 116-tooth library, prepared once beforehand so the cache
//! is warm) run as whole processes under `/usr/bin/time`: wall time, CPU
//! time (user + system) and peak RSS of each. Without the real teeth, a synthetic crown and a
//! synthetic library stand in.
//!
//! With the real teeth, then the exports the crown-extraction targets
//! name: two-rooted marching-cubes isosurfaces at 300 voxels across the
//! whole tooth (`support::exports`, as `clean_exports_two_rooted_300_all`
//! builds them), of the teeth whose export has 2 M faces or more (P30,
//! j14, ah14, k01, j18; `MORPHOID_BENCH_EXPORTS=NAME,…` names others),
//! each written as binary PLY and identified by `morphoid classify`
//! three times.
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
    if support::data::teeth_dir_if_present().is_some() {
        big_exports(&bin, tmp.path(), &library, &cache, &figures);
    }
}

/// Build the two-rooted 300-voxel exports of the named real teeth and
/// identify each [`EXPORT_RUNS`] times.
fn big_exports(bin: &Path, tmp: &Path, library: &Path, cache: &Path, figures: &Path) {
    use support::exports::{export_seed, exported_tooth, form_for, Placement};
    let names = support::cp::tooth_names(library);
    let wanted = std::env::var("MORPHOID_BENCH_EXPORTS")
        .unwrap_or_else(|_| "P30,j14,ah14,k01,j18".to_string());
    let mut medians = Vec::new();
    for name in wanted.split(',').map(str::trim).filter(|n| !n.is_empty()) {
        let Some(index) = names.iter().position(|n| n == name) else {
            eprintln!("{name}: not in the library, skipped");
            continue;
        };
        let crown = support::cp::load_tooth(library, name);
        let seed = export_seed(index);
        let form = form_for(seed, Some(2), None, 300);
        let Some(tooth) = exported_tooth(&crown, &form) else {
            eprintln!("{name}: no whole tooth could be built, skipped");
            continue;
        };
        let placement = Placement::for_seed(seed, morphoid_core::mesh::bbox_diagonal(&crown));
        let path = tmp.join(format!("{name}.ply"));
        mesh_io::write_ply(&path, &placement.apply(&tooth.mesh)).expect("write the export");
        let scan = path.to_string_lossy().into_owned();
        let mut walls = Vec::new();
        for run in 0..EXPORT_RUNS {
            let config = library_config(tmp, &format!("{name}-{run}"), library, cache);
            let (t, cpu, rss) = timed(bin, &["--config", &config, "classify", &scan], figures);
            println!(
                "two-rooted export {name} ({:.2} M faces): classify {t:6.2} s  CPU {cpu:6.2} s  peak RSS {rss:6.0} MB",
                tooth.mesh.faces.len() as f64 / 1e6
            );
            walls.push(t);
        }
        let summary = wall_summary(&walls);
        walls.sort_by(f64::total_cmp);
        medians.push(walls[walls.len() / 2]);
        println!("two-rooted export {name}: classify wall {summary}");
    }
    medians.sort_by(f64::total_cmp);
    if let (Some(lo), Some(hi)) = (medians.first(), medians.last()) {
        println!(
            "two-rooted exports: medians {lo:.2}-{hi:.2} s over {} exports",
            medians.len()
        );
    }
}

/// How many times each two-rooted export is identified.
const EXPORT_RUNS: usize = 3;

/// How many times the scan is identified.
const RUNS: usize = 5;
