//! What a slice stack costs, measured as users run it: a synthetic whole
//! tooth (crown, neck, roots, an enamel cap) voxelized, padded to a cube
//! and written as 16-bit TIFF stacks with noise, slice by slice (a 1024³
//! stack is 2 GB on disk and never in memory). `morphoid classify` then
//! runs on each as a whole process under `/usr/bin/time` against a small
//! synthetic library (built once beforehand), and prints wall time, CPU
//! time (user + system) and peak RSS:
//! - the 1024³ stack (target: peak RSS under 1 GB);
//! - a 160³ stack of the same tooth, and the tooth as a closed mesh: the
//!   difference is what reading and segmenting the stack adds (target:
//!   under 5 s).
//!
//! `cargo build --release && nice -n 10 cargo bench --bench big_volume`
//! (`BIG_VOLUME_SIZE=512` for a smaller big stack; the stacks are written
//! under `$TMPDIR`, 2.2 GB at the default size).

use morphoid_core::mesh::Grid;
use morphoid_data::mesh_io;
use morphoid_synth::mesh::{
    self as synth, whole_tooth, LibrarySpec, WholeToothParams, CROWN_GENERA,
};
use morphoid_synth::volume::{phantom, write_volume, PhantomParams, StackSpec, SynthFormat};
use std::path::Path;
use std::time::Instant;

#[allow(dead_code)] // library_config: big_volume writes its own
#[path = "../tests/it/support/measured.rs"]
mod measured;
use measured::{morphoid_binary, run_measured, Cost};

/// Run `morphoid ARGS` under GNU time (its figures in `figures`); what
/// it cost and its standard output.
fn timed(bin: &Path, args: &[&str], figures: &Path) -> (Cost, String) {
    run_measured(bin, args, figures).unwrap_or_else(|e| panic!("{e:#}"))
}

/// `grid` centred in a cube of background (its first sample's value), so
/// that writing it at n³ keeps the voxels cubic.
fn pad_to_cube(grid: &Grid) -> Grid {
    let n = grid.dims.iter().copied().max().unwrap_or(1);
    let shift = grid.dims.map(|d| (n - d) / 2);
    let origin = [0, 1, 2].map(|a| grid.origin[a] - shift[a] as f64 * grid.spacing[a]);
    let mut out = Grid::filled([n; 3], origin, grid.spacing, grid.values[0]);
    for z in 0..grid.dims[2] {
        for y in 0..grid.dims[1] {
            for x in 0..grid.dims[0] {
                let i = out.index(x + shift[0], y + shift[1], z + shift[2]);
                out.values[i] = grid.values[grid.index(x, y, z)];
            }
        }
    }
    out
}

fn folder_bytes(dir: &Path) -> u64 {
    std::fs::read_dir(dir)
        .map(|it| {
            it.flatten()
                .filter_map(|e| e.metadata().ok())
                .map(|m| m.len())
                .sum()
        })
        .unwrap_or(0)
}

/// The genus `classify --json` gave, for the printout.
fn genus_of(json: &str) -> String {
    serde_json::from_str::<serde_json::Value>(json.trim())
        .ok()
        .and_then(|v| v["ranks"]["genus"]["taxon"].as_str().map(String::from))
        .unwrap_or_else(|| "?".into())
}

fn report(what: &str, c: &Cost, json: &str) {
    println!(
        "{what:<24} wall {:6.2} s  cpu {:6.2} s  peak RSS {:6.0} MB  genus {}",
        c.wall,
        c.cpu,
        c.peak_rss_mb,
        genus_of(json)
    );
}

fn main() {
    // `cargo bench` passes `--bench`; nothing to parse.
    let big: usize = std::env::var("BIG_VOLUME_SIZE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1024);
    let bin = morphoid_binary();
    let tmp = tempfile::tempdir().expect("temp dir");
    let root = tmp.path();

    let genus = &CROWN_GENERA[1];
    let crown = synth::crown(genus, 7, 4000);
    let tooth = whole_tooth(&crown, &WholeToothParams::default(), 7).expect("whole tooth");
    let mesh_path = root.join("tooth.ply");
    mesh_io::save(&mesh_path, &tooth.mesh).expect("write the tooth");
    let params = PhantomParams {
        voxels_across: 148,
        margin: 6,
        ..Default::default()
    };
    let cube = pad_to_cube(&phantom(&tooth, &params));
    println!(
        "tooth: genus {}, {} triangles closed; phantom {}³",
        genus.name,
        tooth.mesh.face_count(),
        cube.dims[0]
    );

    let small = root.join("stack_small");
    let spec = StackSpec::default();
    write_volume(&cube, &small, SynthFormat::Tiff16, &spec).expect("small stack");
    let large = root.join("stack_large");
    let t = Instant::now();
    let big_spec = StackSpec {
        dims: Some([big; 3]),
        ..spec
    };
    write_volume(&cube, &large, SynthFormat::Tiff16, &big_spec).expect("big stack");
    println!(
        "wrote {big}³ 16-bit TIFF stack: {:.2} GB in {:.0} s",
        folder_bytes(&large) as f64 / 1e9,
        t.elapsed().as_secs_f64()
    );

    let lib = root.join("library");
    let spec = LibrarySpec {
        per_genus: 2,
        target_vertices: 1500,
        seed: 3,
        random_pose: true,
    };
    synth::write_synthetic_library(&lib, &spec).expect("library");
    let config = root.join("morphoid.toml");
    std::fs::write(
        &config,
        format!(
            "[database]\npath = {:?}\n[library]\ndir = {:?}\ncache = {:?}\n\
             [clean]\ntarget_vertices = 1500\ncrown = \"auto\"\n",
            root.join("scans.db"),
            lib,
            root.join("cache")
        ),
    )
    .expect("config");
    let config = config.to_string_lossy().into_owned();
    let figures = root.join("time.txt");
    // Prepare the library once, so classify measures the scan, not the build.
    timed(&bin, &["--config", &config, "library", "build"], &figures);

    let run = |what: &str, path: &Path| {
        let p = path.to_string_lossy().into_owned();
        let (c, out) = timed(
            &bin,
            &["--config", &config, "classify", "--json", &p],
            &figures,
        );
        report(what, &c, &out);
        c
    };
    let b = run(&format!("classify {big}³ stack"), &large);
    let s = run(&format!("classify {}³ stack", cube.dims[0]), &small);
    let m = run("classify closed mesh", &mesh_path);
    println!(
        "the {}³ stack adds {:.2} s wall, {:.2} s cpu to the mesh; {big}³ peak RSS {:.0} MB",
        cube.dims[0],
        s.wall - m.wall,
        s.cpu - m.cpu,
        b.peak_rss_mb
    );
}
