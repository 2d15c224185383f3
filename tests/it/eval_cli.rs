//! `morphoid matrix --shard`, `matrix merge` and `evaluate` from the
//! command line.

use morphoid_synth::mesh::{write_synthetic_library, LibrarySpec};
use std::path::Path;
use std::process::Command;

fn morphoid(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_morphoid"))
        .args(args)
        .output()
        .unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn sharded_cli_run_equals_unsharded_and_evaluate_reports_mantel() {
    let lib = tempfile::tempdir().unwrap();
    let spec = LibrarySpec {
        per_genus: 1,
        target_vertices: 1500,
        seed: 8,
        random_pose: false,
    };
    write_synthetic_library(lib.path(), &spec).unwrap();
    let out = tempfile::tempdir().unwrap();
    let full = out.path().join("full.csv");
    let o = morphoid(&["matrix", "--library", s(lib.path()), "--out", s(&full)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let mut shards = Vec::new();
    for k in 1..=3 {
        let p = out.path().join(format!("shard{k}.csv"));
        let spec = format!("{k}/3");
        let o = morphoid(&[
            "matrix",
            "--library",
            s(lib.path()),
            "--out",
            s(&p),
            "--shard",
            &spec,
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        shards.push(p);
    }
    let merged = out.path().join("merged.csv");
    let o = morphoid(&[
        "matrix",
        "merge",
        s(&shards[2]),
        s(&shards[0]),
        s(&shards[1]),
        "--out",
        s(&merged),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        std::fs::read_to_string(&merged).unwrap(),
        std::fs::read_to_string(&full).unwrap()
    );

    let o = morphoid(&[
        "matrix",
        "merge",
        s(&shards[0]),
        s(&shards[1]),
        "--out",
        s(&merged),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("missing shard(s) 3/3"),
        "{err}"
    );

    // With the prepared surfaces from a library build's cache (the cache
    // folder the user gives; the library picks its subfolder), a shard is
    // the same, byte for byte.
    let cache_dir = out.path().join("cache");
    let cache = morphoid_data::library::Cache::for_folder(Some(&cache_dir), lib.path()).unwrap();
    let library = morphoid_data::library::Library::open(lib.path(), None).unwrap();
    let settings = morphoid_data::pipeline::Settings::default();
    morphoid_data::library::build(&library, &cache, &settings, |_| {}).unwrap();
    let cached = out.path().join("cached2.csv");
    let o = morphoid(&[
        "matrix",
        "--library",
        s(lib.path()),
        "--out",
        s(&cached),
        "--shard",
        "2/3",
        "--cache",
        s(&cache_dir),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    // Shard 2/3 of 5 specimens: pairs 3..6 of 10, (0,4) (1,2) (1,3), involve all five.
    assert!(err.contains("(5 from the cache)"), "{err}");
    assert_eq!(
        std::fs::read_to_string(&cached).unwrap(),
        std::fs::read_to_string(&shards[1]).unwrap()
    );

    let png = out.path().join("h.png");
    let o = morphoid(&[
        "evaluate",
        "--matrix",
        s(&full),
        "--compare",
        s(&merged),
        "--permutations",
        "99",
        "--heatmap",
        s(&png),
        "--labels",
        s(&lib.path().join("labels.csv")),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["mantel"]["r"].as_f64(), Some(1.0));
    // Five specimens have only 120 relabelings: a few draws are the
    // identity again, so p is 1/100 plus a little.
    let p = v["mantel"]["p"].as_f64().unwrap();
    assert!((0.01..0.1).contains(&p), "{p}");
    assert_eq!(v["mantel"]["permutations"].as_u64(), Some(99));
    assert!(v["ranks"].as_array().is_some_and(|r| !r.is_empty()));
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));

    // Nothing to do is an error, not a silent success.
    let o = morphoid(&["evaluate", "--matrix", s(&full)]);
    assert!(!o.status.success());
}
