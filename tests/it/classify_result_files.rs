//! Result files of scans that share a file stem: `a/x.ply`, `b/x.ply` and
//! `x.stl` in one export folder each get their own `<name>.json`, named
//! after the path in the export folder, from `classify --out-dir` and from
//! the daemon watching the folder recursively.

use crate::support::daemon::*;
use morphoid_data::mesh_io;
use morphoid_synth::mesh::{self as synth, RigidMotion, CROWN_GENERA};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// The scans, relative to the export folder, with the genus of each.
const SCANS: [(&str, usize); 3] = [("a/x.ply", 0), ("b/x.ply", 1), ("x.stl", 2)];

/// Put a new individual of genus `g` at `rel` in the export folder, in the
/// format its extension names.
fn put_scan(env: &Env, rel: &str, g: usize) -> PathBuf {
    let crown = synth::crown(&CROWN_GENERA[g], 40 + g as u64, 1500);
    let posed = RigidMotion::random(60 + g as u64, 20.0).apply(&crown);
    let staging = tempfile::tempdir().unwrap();
    let staged = staging.path().join(Path::new(rel).file_name().unwrap());
    mesh_io::save(&staged, &posed).unwrap();
    let path = env.export.join(rel);
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    put(env, &path, &std::fs::read(&staged).unwrap());
    path
}

/// The result JSON of the scan at `rel`, if written.
fn result_of(out: &Path, rel: &str) -> Option<serde_json::Value> {
    let text = std::fs::read_to_string(out.join(format!("{rel}.json"))).ok()?;
    serde_json::from_str(&text).ok()
}

/// Every `.json` file under `dir`, relative to it.
fn json_files(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "json") {
                out.push(p.strip_prefix(dir).unwrap().display().to_string());
            }
        }
    }
    out.sort();
    out
}

/// Each scan's own file holds that scan's result.
fn check_results(out: &Path, paths: &[PathBuf]) {
    assert_eq!(
        json_files(out),
        ["a/x.ply.json", "b/x.ply.json", "x.stl.json"],
        "result files in {}",
        out.display()
    );
    for ((rel, g), path) in SCANS.iter().zip(paths) {
        let v = result_of(out, rel).unwrap();
        assert_eq!(v["scan"], path.display().to_string().as_str(), "{rel}: {v}");
        assert_eq!(v["status"], "ok", "{rel}: {v}");
        assert_eq!(v["ranks"]["genus"]["taxon"], genus(*g), "{rel}: {v}");
    }
}

#[test]
fn classify_out_dir_keeps_one_result_per_scan() {
    let env = env(0.5, "recursive = true", "");
    let paths: Vec<PathBuf> = SCANS.iter().map(|(r, g)| put_scan(&env, r, *g)).collect();
    let out = env.root.join("results");
    let o = Command::new(BIN)
        .args(["classify", "--config"])
        .arg(&env.config)
        .arg("--out-dir")
        .arg(&out)
        .args(&paths)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    check_results(&out, &paths);
}

#[test]
fn the_daemon_keeps_one_result_per_scan_in_subfolders() {
    let results = "RESULTS_DIR";
    let env = env(
        0.5,
        "recursive = true",
        &format!("[results]\ndir = {results:?}\n"),
    );
    let out = env.root.join("results");
    let config = std::fs::read_to_string(&env.config)
        .unwrap()
        .replace(results, &out.display().to_string());
    std::fs::write(&env.config, config).unwrap();
    let d = Daemon::start(&env);
    let paths: Vec<PathBuf> = SCANS.iter().map(|(r, g)| put_scan(&env, r, *g)).collect();
    assert!(
        wait_until(Duration::from_secs(300), || SCANS
            .iter()
            .all(|(rel, _)| result_of(&out, rel).is_some())),
        "result files: {:?}\n{}",
        json_files(&out),
        d.log_text()
    );
    check_results(&out, &paths);
}
