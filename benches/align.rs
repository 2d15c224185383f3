//! Benchmark of `morphoid align` on a whole library from a cold cache:
//! the 116 PNAS teeth when present (else a synthetic library of 10
//! crowns), 1024 pseudolandmarks, each consistency in turn; prints the wall
//! time and the CPU time (user + system) of the command.
//!
//! `cargo bench --bench align`
//!
//! Knobs (environment): `MORPHOID_BENCH_ALIGN_TEETH=N` aligns only the
//! first N teeth (by name); `MORPHOID_BENCH_ALIGN_CONSISTENT=mst,sync`
//! (the default) which `--consistent` values to time;
//! `MORPHOID_BENCH_ALIGN_THREADS` passes `--threads`.

#[allow(dead_code)]
#[path = "../tests/it/support/mod.rs"]
mod support;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// CPU time (user + system, seconds) of the children waited for so far:
/// `cutime` and `cstime` of `/proc/self/stat`, in Linux's fixed 100 ticks
/// per second (USER_HZ).
fn children_cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // The fields after the command name (which ends with the last `)`):
    // state is field 3, cutime and cstime are fields 16 and 17.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |k: usize| {
        fields
            .get(k - 3)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(16) + ticks(17)) / 100.0
}

/// A library folder to align: the teeth (all, or the first `limit` with
/// their labels, linked into `scratch`), else a synthetic library.
fn library(scratch: &Path) -> (PathBuf, String) {
    let limit: Option<usize> = std::env::var("MORPHOID_BENCH_ALIGN_TEETH")
        .ok()
        .and_then(|v| v.parse().ok());
    let teeth = support::data::teeth_dir_if_present()
        .map(|dir| (support::data::ply_files(&dir.join("meshes")), dir));
    match teeth {
        Some((paths, dir)) => match limit {
            None => (dir, format!("{} real teeth", paths.len())),
            Some(k) => {
                let lib = scratch.join("teeth");
                std::fs::create_dir_all(&lib).expect("scratch folder");
                let names: Vec<String> = paths
                    .iter()
                    .take(k)
                    .map(|p| {
                        let name = p.file_name().expect("file name");
                        std::os::unix::fs::symlink(p, lib.join(name)).expect("link");
                        morphoid_data::pipeline::specimen_name(p)
                    })
                    .collect();
                let labels = std::fs::read_to_string(dir.join("labels.csv")).expect("labels.csv");
                let mut lines = labels.lines();
                let mut kept: Vec<&str> = lines.next().into_iter().collect();
                kept.extend(lines.filter(|l| {
                    l.split(',')
                        .next()
                        .is_some_and(|n| names.iter().any(|m| m == n))
                }));
                std::fs::write(lib.join("labels.csv"), kept.join("\n") + "\n").expect("labels.csv");
                (lib, format!("{} real teeth", names.len()))
            }
        },
        _ => {
            let lib = scratch.join("synthetic");
            let spec = morphoid_synth::mesh::LibrarySpec {
                per_genus: 2,
                target_vertices: 2000,
                seed: 11,
                random_pose: true,
            };
            let n = morphoid_synth::mesh::write_synthetic_library(&lib, &spec)
                .expect("synthetic library")
                .len();
            (lib, format!("{n} synthetic crowns (teeth not found)"))
        }
    }
}

fn main() {
    let scratch = tempfile::tempdir().expect("temporary folder");
    let (lib, what) = library(scratch.path());
    let consistent =
        std::env::var("MORPHOID_BENCH_ALIGN_CONSISTENT").unwrap_or_else(|_| "mst,sync".to_string());
    let threads = std::env::var("MORPHOID_BENCH_ALIGN_THREADS").ok();
    for how in consistent
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
    {
        // A fresh cache each time: from cold, preparation included.
        let cache = scratch.path().join(format!("cache-{how}"));
        let out = scratch.path().join(format!("out-{how}"));
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_morphoid"));
        cmd.arg("align")
            .arg("--library")
            .arg(&lib)
            .arg("--out")
            .arg(&out)
            .arg("--cache")
            .arg(&cache)
            .args(["--pseudolandmarks", "1024", "--consistent", how]);
        if let Some(t) = &threads {
            cmd.args(["--threads", t]);
        }
        let cpu_before = children_cpu_seconds();
        let started = Instant::now();
        let output = cmd.output().expect("morphoid align runs");
        let wall = started.elapsed().as_secs_f64();
        let cpu = children_cpu_seconds() - cpu_before;
        if !output.status.success() {
            eprintln!("{}", String::from_utf8_lossy(&output.stderr));
            panic!("align --consistent {how} failed");
        }
        println!(
            "align {what}, 1024 pseudolandmarks, --consistent {how}, cold cache: wall {wall:.1} s, CPU {cpu:.1} s (user + system), {:.2} cores busy",
            cpu / wall.max(1e-9)
        );
    }
}
