//! `morphoid classify` and `results` as a user runs them, and the promise
//! that a kill at any moment leaves each scan with its whole result or none.

use morphoid_data::mesh_io;
use morphoid_synth::mesh::{self as synth, LibrarySpec, RigidMotion, CROWN_GENERA};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

const BIN: &str = env!("CARGO_BIN_EXE_morphoid");

/// A small synthetic library, scans of new individuals, and a config that
/// keeps everything (cache, database) inside `root`.
struct Setup {
    _tmp: tempfile::TempDir,
    config: PathBuf,
    db: PathBuf,
    scans: Vec<(PathBuf, &'static str)>,
    references: usize,
}

fn setup(scans_per_genus: usize) -> Setup {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let spec = LibrarySpec {
        per_genus: 2,
        target_vertices: 1500,
        seed: 3,
        random_pose: true,
    };
    let lib = synth::write_synthetic_library(&root.join("library"), &spec).unwrap();
    std::fs::create_dir_all(root.join("export")).unwrap();
    let mut scans = Vec::new();
    for (g, genus) in CROWN_GENERA.iter().enumerate() {
        for k in 0..scans_per_genus {
            let seed = 500 + (g * 10 + k) as u64;
            let crown = synth::crown(genus, seed, 1500);
            let posed = RigidMotion::random(seed, 20.0).apply(&crown);
            let path = root.join("export").join(format!("s{g}{k}.ply"));
            mesh_io::save(&path, &posed).unwrap();
            scans.push((path, genus.name));
        }
    }
    let db = root.join("db.sqlite");
    let config = root.join("morphoid.toml");
    std::fs::write(
        &config,
        format!(
            "[library]\ndir = {:?}\nranks = [\"order\", \"family\", \"genus\"]\ncache = {:?}\n\
             [database]\npath = {:?}\n[clean]\ntarget_vertices = 1500\n",
            root.join("library"),
            root.join("cache"),
            db
        ),
    )
    .unwrap();
    Setup {
        config,
        db,
        scans,
        references: lib.len(),
        _tmp: tmp,
    }
}

fn classify(s: &Setup, scans: &[PathBuf], json: bool) -> Output {
    let mut cmd = Command::new(BIN);
    cmd.arg("classify").arg("--config").arg(&s.config);
    if json {
        cmd.arg("--json");
    }
    cmd.args(scans).output().unwrap()
}

#[test]
fn classify_identifies_records_and_reports_each_scan() {
    let s = setup(1);
    let mut files: Vec<PathBuf> = s.scans.iter().map(|(p, _)| p.clone()).collect();
    let broken = s.db.with_file_name("broken.ply");
    std::fs::write(&broken, b"ply\nformat ascii 1.0\nelement vertex 3\n").unwrap();
    files.push(broken.clone());
    let out = classify(&s, &files, true);
    assert_eq!(
        out.status.code(),
        Some(1),
        "a bad scan makes the exit non-zero"
    );
    let stdout = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<serde_json::Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), files.len());
    for ((path, genus), v) in s.scans.iter().zip(&lines) {
        assert_eq!(v["status"], "ok", "{v}");
        assert_eq!(v["scan"], path.display().to_string());
        assert_eq!(v["ranks"]["genus"]["taxon"], *genus, "{v}");
        assert!(v["ranks"]["genus"]["distance"].as_f64().unwrap() >= 0.0);
        assert!(v["ranks"]["genus"]["margin"].as_f64().unwrap() > 0.0);
        assert_eq!(v["nearest"].as_array().unwrap().len(), 5);
        assert!(v["cleaning"]["boundary_loops"] == 1);
        assert!(v["timings_ms"]["compare"].as_f64().unwrap() > 0.0);
    }
    let bad = lines.last().unwrap();
    assert_eq!(bad["status"], "error");
    assert!(bad["error"]
        .as_str()
        .unwrap()
        .contains(&broken.display().to_string()));

    // The same content again is not identified twice: results shows one row each.
    let again = classify(&s, &files[..1], true);
    assert!(again.status.success());
    let out = Command::new(BIN)
        .args(["results", "--json", "--last", "100", "--config"])
        .arg(&s.config)
        .output()
        .unwrap();
    assert!(out.status.success());
    let n = String::from_utf8(out.stdout).unwrap().lines().count();
    assert_eq!(n, files.len());
}

/// Scan id with its numbers of result and distance rows.
type RowCounts = (i64, i64, i64);

/// Number of result and distance rows of every `ok` scan, and the number of
/// scans in each status.
fn audit(db: &Path) -> (Vec<RowCounts>, Vec<(String, i64)>) {
    let conn = rusqlite::Connection::open(db).unwrap();
    let check: String = conn
        .query_row("PRAGMA integrity_check", [], |r| r.get(0))
        .unwrap();
    assert_eq!(check, "ok");
    // A run killed before its first migration committed leaves a file
    // without tables (or none at all): no scans yet, which is whole.
    let tables: i64 = conn
        .query_row(
            "SELECT COUNT(*) FROM sqlite_schema WHERE type = 'table' AND name = 'scan'",
            [],
            |r| r.get(0),
        )
        .unwrap();
    if tables == 0 {
        let any: i64 = conn
            .query_row("SELECT COUNT(*) FROM sqlite_schema", [], |r| r.get(0))
            .unwrap();
        assert_eq!(any, 0, "a half-made schema was committed");
        return (Vec::new(), Vec::new());
    }
    let mut stmt = conn
        .prepare(
            "SELECT s.id,
                    (SELECT COUNT(*) FROM result r WHERE r.scan_id = s.id),
                    (SELECT COUNT(*) FROM distance d WHERE d.scan_id = s.id)
             FROM scan s WHERE s.status = 'ok'",
        )
        .unwrap();
    let ok = stmt
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
        .unwrap()
        .collect::<Result<Vec<_>, _>>()
        .unwrap();
    let mut stmt = conn
        .prepare("SELECT status, COUNT(*) FROM scan GROUP BY status")
        .unwrap();
    let counts = stmt
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
        .unwrap()
        .collect::<Result<Vec<_>, _>>()
        .unwrap();
    // Rows that belong to a scan without a result must not exist at all.
    let orphans: i64 = conn
        .query_row(
            "SELECT (SELECT COUNT(*) FROM result r JOIN scan s ON s.id = r.scan_id WHERE s.status <> 'ok')
                  + (SELECT COUNT(*) FROM distance d JOIN scan s ON s.id = d.scan_id WHERE s.status <> 'ok')",
            [],
            |r| r.get(0),
        )
        .unwrap();
    assert_eq!(orphans, 0, "rows of an unfinished scan were committed");
    (ok, counts)
}

#[test]
fn a_killed_classify_leaves_whole_results_or_none() {
    let s = setup(2);
    let files: Vec<PathBuf> = s.scans.iter().map(|(p, _)| p.clone()).collect();
    // Prepare the library once so that the kills land during identification.
    let warm = Command::new(BIN)
        .args(["library", "build", "--config"])
        .arg(&s.config)
        .output()
        .unwrap();
    assert!(
        warm.status.success(),
        "{}",
        String::from_utf8_lossy(&warm.stderr)
    );

    // Kills at pseudo-random moments, early enough to land while the
    // scans are identified even on an idle machine (a warm run of these
    // ten scans takes about 0.2 s there), until three runs were cut short.
    let mut rng_state = 0x2545_F491_4F6C_DD1Du64;
    let mut kills = 0;
    let mut round = 0;
    while kills < 3 && round < 40 {
        round += 1;
        let mut child = Command::new(BIN)
            .arg("classify")
            .arg("--config")
            .arg(&s.config)
            .args(&files)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        rng_state ^= rng_state << 13;
        rng_state ^= rng_state >> 7;
        rng_state ^= rng_state << 17;
        let delay = 5 + rng_state % 200;
        std::thread::sleep(Duration::from_millis(delay));
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap(); // SIGKILL
            kills += 1;
        }
        let _ = child.wait();
        let (ok, counts) = audit(&s.db);
        for &(id, ranks, distances) in &ok {
            assert_eq!(ranks, 3, "round {round}: scan {id} has {ranks} rank rows");
            assert_eq!(
                distances, s.references as i64,
                "round {round}: scan {id} has {distances} distance rows"
            );
        }
        eprintln!("round {round}: killed after {delay} ms; {counts:?}");
    }
    assert!(kills >= 3, "only {kills} of {round} runs were interrupted");
    // Running classify again finishes what the kills interrupted (a scan
    // left running is taken over): exactly one whole result per scan.
    let done = classify(&s, &files, false);
    let (ok, _) = audit(&s.db);
    let conn = rusqlite::Connection::open(&s.db).unwrap();
    let scans: i64 = conn
        .query_row("SELECT COUNT(*) FROM scan", [], |r| r.get(0))
        .unwrap();
    assert_eq!(scans as usize, files.len(), "one row per scan content");
    assert!(
        done.status.success(),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    assert_eq!(ok.len(), files.len(), "every scan ends with one result");
}
