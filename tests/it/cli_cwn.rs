//! `distance --method cwn` and `matrix --method cwn` through the real
//! binary on synthetic crowns.

use std::process::Command;

fn morphoid() -> Command {
    Command::new(env!("CARGO_BIN_EXE_morphoid"))
}

#[test]
fn distance_and_matrix_with_method_cwn() {
    let dir = tempfile::tempdir().expect("temporary folder");
    for (name, seed) in [("a", "1"), ("b", "2"), ("c", "3")] {
        let out = dir.path().join(format!("{name}.ply"));
        let st = morphoid()
            .args(["synth", "--seed", seed, "--out"])
            .arg(&out)
            .status()
            .expect("run synth");
        assert!(st.success());
    }
    let a = dir.path().join("a.ply");
    let b = dir.path().join("b.ply");
    let out = morphoid()
        .args(["distance", "--method", "cwn", "--json"])
        .arg(&a)
        .arg(&b)
        .output()
        .expect("run distance");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(v["method"], "cwn");
    let d = v["distance"].as_f64().expect("distance");
    assert!(d.is_finite() && d > 0.0);
    assert!(v["timings_ms"]["compare"].as_f64().is_some());

    // Without mirror images the distance cannot be smaller.
    let out = morphoid()
        .args([
            "distance",
            "--method",
            "cwn",
            "--json",
            "--cwn-no-reflections",
        ])
        .arg(&a)
        .arg(&b)
        .output()
        .expect("run distance");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert!(v["distance"].as_f64().expect("distance") >= d - 1e-12);

    // A bad radius and --map are clear errors.
    let out = morphoid()
        .args(["distance", "--method", "cwn", "--cwn-radius", "1.2"])
        .arg(&a)
        .arg(&b)
        .output()
        .expect("run distance");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("radius"));

    let csv = dir.path().join("m.csv");
    let out = morphoid()
        .args(["matrix", "--method", "cwn", "--library"])
        .arg(dir.path())
        .arg("--out")
        .arg(&csv)
        .output()
        .expect("run matrix");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&csv).expect("matrix file");
    assert!(text.starts_with("name,a,b,c\n"), "{text}");
    let ab: f64 = text
        .lines()
        .nth(1)
        .expect("row a")
        .split(',')
        .nth(2)
        .expect("a,b")
        .parse()
        .expect("number");
    assert!((ab - d).abs() < 1e-9, "{ab} vs {d}");

    let out = morphoid()
        .args(["matrix", "--method", "cwn", "--shard", "1/2", "--library"])
        .arg(dir.path())
        .arg("--out")
        .arg(dir.path().join("s.csv"))
        .output()
        .expect("run matrix");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--shard"));
}
