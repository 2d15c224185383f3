//! Landmarks through `morphoid classify` as a user runs it: a synthetic
//! library whose references have landmark files (every format), a rigidly
//! moved, remeshed, rescaled copy of one reference identified, and the
//! nearest reference's landmarks carried onto it: in the JSON, in the
//! database, in `results --json` and as `<name>.fcsv` in the results
//! folder. Also `matrix --method landmarks` and the Mantel test between
//! the cP and the landmark matrices.

use crate::support::lm::{
    json_landmarks, moved_copy, relative_errors, true_position, write_library_landmarks,
};
use morphoid_data::landmarks::{self, Landmarks};
use morphoid_data::mesh_io;
use morphoid_synth::mesh::{self as synth, LibrarySpec, Specimen};
use rusqlite::Connection;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_morphoid");

struct Setup {
    _tmp: tempfile::TempDir,
    root: PathBuf,
    lib: PathBuf,
    config: PathBuf,
    db: PathBuf,
    specimens: Vec<Specimen>,
}

/// A library of 2 crowns per configuration (10), 1500 vertices, random
/// poses and scales, with landmark files for all; a config keeping the
/// cache and the database in the temporary folder, which is also the
/// export folder result files are named from.
fn setup() -> Setup {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().to_path_buf();
    let lib = root.join("library");
    let spec = LibrarySpec {
        per_genus: 2,
        target_vertices: 1500,
        seed: 3,
        random_pose: true,
    };
    let specimens = synth::write_synthetic_library(&lib, &spec).unwrap();
    let names: Vec<String> = specimens.iter().map(|s| s.name.clone()).collect();
    write_library_landmarks(&lib, &names);
    let db = root.join("db.sqlite");
    let config = root.join("morphoid.toml");
    std::fs::write(
        &config,
        format!(
            "[watch]\ndir = {:?}\n[library]\ndir = {:?}\nranks = [\"order\", \"family\", \"genus\"]\ncache = {:?}\n\
             [database]\npath = {:?}\n[clean]\ntarget_vertices = 1500\n",
            root,
            lib,
            root.join("cache"),
            db
        ),
    )
    .unwrap();
    Setup {
        _tmp: tmp,
        root,
        lib,
        config,
        db,
        specimens,
    }
}

fn morphoid(args: &[&str], extra: &[&Path]) -> Output {
    Command::new(BIN)
        .args(args)
        .args(extra)
        .output()
        .expect("morphoid runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The JSON lines of stdout, one per scan.
fn json_lines(o: &Output) -> Vec<serde_json::Value> {
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object per line"))
        .collect()
}

#[test]
fn classify_carries_the_nearest_references_landmarks() {
    let s = setup();
    let source = &s.specimens[0];
    let mesh = mesh_io::load(&source.path).unwrap().mesh;
    let (copy, motion) = moved_copy(&mesh, 71);
    let scan = s.root.join("scan_a.ply");
    mesh_io::save(&scan, &copy).unwrap();
    let reference_lm = crate::support::lm::landmarks_of(&source.path);
    let truth: Vec<[f64; 3]> = reference_lm
        .points()
        .iter()
        .map(|&p| true_position(p, &motion))
        .collect();
    let out_dir = s.root.join("results");

    let o = morphoid(
        &["classify", "--json", "--out-dir"],
        &[&out_dir, Path::new("--config"), &s.config, &scan],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let lines = json_lines(&o);
    assert_eq!(lines.len(), 1);
    let v = &lines[0];
    assert_eq!(v["status"], "ok");
    assert_eq!(v["nearest"][0]["reference"], source.name.as_str());
    assert_eq!(v["landmarks_reference"], source.name.as_str());
    let (points, labels) = json_landmarks(v);
    assert_eq!(
        labels,
        (1..=10).map(|k| format!("L{k}")).collect::<Vec<_>>()
    );
    let (mean, max) = relative_errors(&points, &truth, &copy);
    println!(
        "classify: landmarks of {} on its moved copy: error / diagonal mean {mean:.5}, max {max:.5}",
        source.name
    );
    assert!(mean < 0.01, "mean error {mean}");
    // On the scan surface (the cleaned one lies on the original within
    // resampling tolerance), not at the reference's place.
    let on = morphoid_core::clean::point_to_surface_distances(&points, &copy);
    let diag = morphoid_core::mesh::bbox_diagonal(&copy);
    assert!(on.iter().all(|&d| d < 0.01 * diag), "{on:?}");

    // The results folder: the JSON line and the Slicer markups.
    let json_file = std::fs::read_to_string(out_dir.join("scan_a.ply.json")).unwrap();
    let from_file: serde_json::Value = serde_json::from_str(&json_file).unwrap();
    assert_eq!(&from_file, v);
    let fcsv = landmarks::read(&out_dir.join("scan_a.ply.fcsv"), Some(10)).unwrap();
    assert_eq!(fcsv.points(), points);
    assert_eq!(fcsv.label(0), Some("L1"));
    let leftovers: Vec<_> = std::fs::read_dir(&out_dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");

    // The database: ten rows pointing at the reference, as in the JSON.
    let conn = Connection::open(&s.db).unwrap();
    let rows: Vec<(i64, Option<String>, f64, f64, f64, String)> = {
        let mut stmt = conn
            .prepare(
                "SELECT landmark.idx, landmark.label, landmark.x, landmark.y, landmark.z,
                        reference.name
                 FROM landmark JOIN reference ON reference.id = landmark.reference_id
                 WHERE landmark.scan_id = ?1 ORDER BY landmark.idx",
            )
            .unwrap();
        let id = v["id"].as_i64().unwrap();
        stmt.query_map([id], |r| {
            Ok((
                r.get(0)?,
                r.get(1)?,
                r.get(2)?,
                r.get(3)?,
                r.get(4)?,
                r.get(5)?,
            ))
        })
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap()
    };
    assert_eq!(rows.len(), 10);
    for (k, row) in rows.iter().enumerate() {
        assert_eq!(row.0, k as i64);
        assert_eq!(row.1.as_deref(), Some(format!("L{}", k + 1).as_str()));
        assert_eq!([row.2, row.3, row.4], points[k]);
        assert_eq!(row.5, source.name);
    }
    let version: i64 = conn
        .query_row("PRAGMA user_version", [], |r| r.get(0))
        .unwrap();
    assert_eq!(version, i64::from(morphoid_service::store::SCHEMA_VERSION));

    // `results --json` shows them too.
    let o = morphoid(&["results", "--json", "--config"], &[&s.config]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (again, _) = json_landmarks(&json_lines(&o)[0]);
    assert_eq!(again, points);

    // Second run: the first scan is already identified (its recorded
    // result and files come back); a copy of a reference whose landmark
    // file is gone gets none and no .fcsv; broken landmark files of other
    // references are reported, per reference, and do not stop anything.
    let second = &s.specimens[1];
    let lm_dir = s.lib.join("landmarks");
    for f in landmarks::library_files(&s.lib, &second.name) {
        std::fs::remove_file(f).unwrap();
    }
    let third = &s.specimens[2];
    for f in landmarks::library_files(&s.lib, &third.name) {
        std::fs::write(f, "garbage, not landmarks\n").unwrap();
    }
    let fourth = &s.specimens[3];
    landmarks::write(
        &lm_dir.join(format!("{}.csv", fourth.name)),
        &crate::support::lm::landmarks_of(&fourth.path),
    )
    .unwrap();
    assert_eq!(landmarks::library_files(&s.lib, &fourth.name).len(), 2);
    let (copy_b, _) = moved_copy(&mesh_io::load(&second.path).unwrap().mesh, 72);
    let scan_b = s.root.join("scan_b.ply");
    mesh_io::save(&scan_b, &copy_b).unwrap();
    std::fs::remove_file(out_dir.join("scan_a.ply.fcsv")).unwrap();
    let o = morphoid(
        &["classify", "--json", "--out-dir"],
        &[&out_dir, Path::new("--config"), &s.config, &scan, &scan_b],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("landmarks left out") && err.contains(&third.name),
        "{err}"
    );
    assert!(err.contains("more than one landmark file"), "{err}");
    let lines = json_lines(&o);
    assert_eq!(json_landmarks(&lines[0]).0, points);
    assert!(out_dir.join("scan_a.ply.fcsv").is_file());
    assert_eq!(lines[1]["status"], "ok");
    assert_eq!(lines[1]["nearest"][0]["reference"], second.name.as_str());
    assert!(lines[1].get("landmarks").is_none(), "{}", lines[1]);
    assert!(out_dir.join("scan_b.ply.json").is_file());
    assert!(!out_dir.join("scan_b.ply.fcsv").exists());

    // `library build` names each unusable landmark file and fails.
    let o = morphoid(&["library", "build", "--config"], &[&s.config]);
    assert!(!o.status.success());
    let err = stderr(&o);
    for name in [&third.name, &fourth.name] {
        assert!(
            err.contains(&format!("landmarks of reference {name}")),
            "{err}"
        );
    }
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("7 references with landmarks (10 each), 2 landmark files not usable"),
        "{out}"
    );
}

/// The 10-specimen library's cP and landmark Procrustes matrices, and the
/// Mantel test between them; errors for missing and mismatched landmarks.
#[test]
fn landmark_matrix_and_mantel_against_cp() {
    let s = setup();
    let (cp, lm, lm_refl) = (
        s.root.join("cp.csv"),
        s.root.join("lm.csv"),
        s.root.join("lm_refl.csv"),
    );
    let o = morphoid(&["matrix", "--library"], &[&s.lib, Path::new("--out"), &cp]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = morphoid(
        &["matrix", "--method", "landmarks", "--library"],
        &[&s.lib, Path::new("--out"), &lm],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("10 specimens, 10 landmarks each"));
    let o = morphoid(
        &[
            "matrix",
            "--method",
            "landmarks",
            "--allow-reflection",
            "--library",
        ],
        &[&s.lib, Path::new("--out"), &lm_refl],
    );
    assert!(o.status.success(), "{}", stderr(&o));

    let read = |p: &Path| morphoid_data::table::DistanceMatrix::read_csv(p).unwrap();
    let (mcp, mlm, mrefl) = (read(&cp), read(&lm), read(&lm_refl));
    assert_eq!(mcp.names(), mlm.names());
    for i in 0..mlm.names().len() {
        assert_eq!(mlm.get(i, i), 0.0);
        for j in 0..mlm.names().len() {
            assert_eq!(mlm.get(i, j), mlm.get(j, i));
            assert!(mrefl.get(i, j) <= mlm.get(i, j) + 1e-12);
            if i != j {
                assert!(mlm.get(i, j) > 0.0);
            }
        }
    }

    let o = morphoid(
        &["evaluate", "--json", "--matrix"],
        &[&cp, Path::new("--compare"), &lm],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let (r, p) = (
        v["mantel"]["r"].as_f64().unwrap(),
        v["mantel"]["p"].as_f64().unwrap(),
    );
    println!(
        "Mantel, cP against landmark Procrustes (10 synthetic crowns): r = {r:.4}, p = {p:.4}"
    );
    assert!(r > 0.0, "r = {r}");

    // A specimen without landmarks, and one with another count: errors
    // that name them.
    let names = mlm.names();
    let victim = landmarks::library_files(&s.lib, &names[4]);
    std::fs::rename(&victim[0], s.root.join("aside")).unwrap();
    let o = morphoid(
        &["matrix", "--method", "landmarks", "--library"],
        &[&s.lib, Path::new("--out"), &lm],
    );
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains("no landmark file") && err.contains(&names[4]),
        "{err}"
    );
    std::fs::rename(s.root.join("aside"), &victim[0]).unwrap();
    let short = &landmarks::library_files(&s.lib, &names[6])[0];
    let lm6 = landmarks::read(short, None).unwrap();
    let n6 = lm6.len() - 1;
    let lm6 =
        Landmarks::with_labels(lm6.points()[..n6].to_vec(), lm6.labels()[..n6].to_vec()).unwrap();
    landmarks::write(short, &lm6).unwrap();
    let o = morphoid(
        &["matrix", "--method", "landmarks", "--library"],
        &[&s.lib, Path::new("--out"), &lm],
    );
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains(&names[6]) && err.contains("9 landmarks, expected 10"),
        "{err}"
    );
}
