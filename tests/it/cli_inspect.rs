//! The real `morphoid` binary on real files: `inspect` on good surfaces and
//! on the eight bad inputs the product must survive.

use morphoid_data::mesh_io;
use morphoid_synth::mesh::{self as synth, CROWN_GENERA};
use std::path::Path;
use std::process::{Command, Output};

fn morphoid(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphoid"))
        .args(args)
        .output()
        .expect("the morphoid binary runs")
}

/// `morphoid args` run to its end, with its own peak resident memory in
/// MB.
fn morphoid_with_peak_rss(args: &[&str]) -> (Output, f64) {
    // The peak is measured by GNU time, not by wait4 here: a child forked
    // from this test process carries the process's own peak memory (that
    // of the other tests running in it) across exec into its ru_maxrss;
    // one forked from `time` starts small.
    const MARK: &str = "morphoid-peak-kb ";
    let out = Command::new("/usr/bin/time")
        .arg("-q")
        .arg("-f")
        .arg(format!("{MARK}%M"))
        .arg(env!("CARGO_BIN_EXE_morphoid"))
        .args(args)
        .output()
        .expect("/usr/bin/time runs (Debian package `time`; .ci/run installs it)");
    let text = String::from_utf8_lossy(&out.stderr).into_owned();
    let (rest, peak) = text
        .rsplit_once(MARK)
        .unwrap_or_else(|| panic!("no peak from /usr/bin/time in: {text}"));
    let kb: f64 = peak.trim().parse().expect("a peak in kilobytes");
    let output = Output {
        status: out.status,
        stdout: out.stdout,
        stderr: rest.as_bytes().to_vec(),
    };
    (output, kb / 1024.0)
}

fn json_of(out: &Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON object")
}

#[test]
fn every_bad_input_fails_with_one_line_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let bad = synth::write_bad_inputs(dir.path()).unwrap();
    assert_eq!(bad.len(), 8);
    let mut peak: f64 = 0.0;
    for (path, what) in &bad {
        let p = path.to_str().unwrap();
        let (out, rss) = morphoid_with_peak_rss(&["inspect", p]);
        peak = peak.max(rss);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{what}: exit status was success");
        assert_eq!(out.status.code(), Some(1), "{what}: {stderr}");
        assert!(!stderr.contains("panicked"), "{what}: panicked: {stderr}");
        let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
        assert_eq!(lines.len(), 1, "{what}: not one line: {stderr}");
        assert!(lines[0].contains(p), "{what}: file not named: {stderr}");
        eprintln!("{what}: {}", lines[0]);

        let out = morphoid(&["inspect", "--json", p]);
        assert!(!out.status.success());
        let v = json_of(&out);
        assert_eq!(v["status"], "error");
        assert!(v["error"].as_str().unwrap().contains(p));
    }
    eprintln!("peak memory of the inspect runs: {peak:.1} MB");
    assert!(peak < 200.0, "peak memory {peak:.1} MB");
}

#[test]
fn inspect_reports_a_disk_for_a_soup_with_debris() {
    let dir = tempfile::tempdir().unwrap();
    let crown = synth::crown(&CROWN_GENERA[1], 3, 3000);
    let messy = synth::triangle_soup(&synth::add_debris(&crown, 3, 5));
    // ASCII STL: a soup as stored, which cleaning welds (binary STL shares
    // identical corners as it is read).
    let path = dir.path().join("messy.stl");
    mesh_io::write_stl_ascii(&path, &messy).unwrap();
    let clean_path = dir.path().join("clean.ply");
    let out = morphoid(&[
        "inspect",
        "--json",
        path.to_str().unwrap(),
        "--write-clean",
        clean_path.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = json_of(&out);
    assert_eq!(v["status"], "ok");
    assert_eq!(v["input"]["format"], "stl");
    assert_eq!(v["output"]["boundary_loops"], 1);
    assert_eq!(v["output"]["euler_characteristic"], 1);
    assert_eq!(v["dropped_components"], 3);
    assert!(v["welded_vertices"].as_u64().unwrap() > 0);
    let n = v["output"]["vertices"].as_f64().unwrap();
    assert!((n - 5000.0).abs() <= 500.0, "{n} vertices");
    for key in ["removed_faces", "filled_holes", "area", "bbox_diagonal"] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    // The written surface is the cleaned one.
    let written = mesh_io::load(Path::new(&clean_path)).unwrap().mesh;
    assert_eq!(written.vertex_count() as f64, n);
    assert_eq!(morphoid_core::mesh::boundary_loops(&written).len(), 1);
}
