//! A surface file holding several specimens (a batch export), as a user
//! meets it: `classify` identifies each on its own, records `<scan>#n`
//! rows with their positions under the scan's row, and `results`,
//! `inspect`, the result files and the overview show them together; a
//! surface nested inside a specimen and small debris are not specimens.

use morphoid_core::mesh::Mesh;
use morphoid_data::mesh_io;
use morphoid_synth::mesh::{
    self as synth, whole_tooth, LibrarySpec, WholeToothParams, CROWN_GENERA,
};
use std::path::Path;
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_morphoid");

fn shifted(m: &Mesh, dx: f64) -> Mesh {
    Mesh::new(
        m.vertices.iter().map(|p| [p[0] + dx, p[1], p[2]]).collect(),
        m.faces.clone(),
    )
}

fn join(parts: &[Mesh]) -> Mesh {
    let mut out = Mesh::new(Vec::new(), Vec::new());
    for p in parts {
        let base = out.vertices.len() as u32;
        out.vertices.extend(&p.vertices);
        out.faces
            .extend(p.faces.iter().map(|f| f.map(|i| i + base)));
    }
    out
}

/// A closed ball (an icosahedron) of radius `r` around `c`.
fn ball(c: [f64; 3], r: f64) -> Mesh {
    let m = synth::closed_sphere(12);
    Mesh::new(
        m.vertices
            .iter()
            .map(|p| [0, 1, 2].map(|i| c[i] + r * p[i]))
            .collect(),
        m.faces,
    )
}

/// Three whole teeth of three genera in a row along x, a shrunken copy of
/// the middle one inside it (a pulp cavity exported as its own surface),
/// and 30 crumbs of debris.
fn batch_file(dir: &Path) -> (std::path::PathBuf, Vec<&'static str>) {
    let genera = [0usize, 2, 4];
    let mut parts = Vec::new();
    let mut names = Vec::new();
    let mut x = 0.0;
    for (k, &g) in genera.iter().enumerate() {
        let genus = &CROWN_GENERA[g];
        let crown = synth::crown(genus, 900 + k as u64, 1500);
        let tooth = whole_tooth(&crown, &WholeToothParams::default(), 40 + k as u64)
            .expect("a whole tooth")
            .mesh;
        let (lo, hi) = morphoid_core::mesh::bounding_box(&tooth).unwrap();
        let placed = shifted(&tooth, x - lo[0]);
        if k == 1 {
            // The cavity: the tooth shrunk by half about its centre.
            let (a, b) = morphoid_core::mesh::bounding_box(&placed).unwrap();
            let c = [0, 1, 2].map(|i| (a[i] + b[i]) / 2.0);
            let inner = Mesh::new(
                placed
                    .vertices
                    .iter()
                    .map(|p| [0, 1, 2].map(|i| c[i] + 0.4 * (p[i] - c[i])))
                    .collect(),
                placed.faces.iter().map(|f| [f[0], f[2], f[1]]).collect(),
            );
            parts.push(inner);
        }
        parts.push(placed);
        x += (hi[0] - lo[0]) * 1.3;
        names.push(genus.name);
    }
    for i in 0..30 {
        let t = i as f64;
        parts.push(ball([x * t / 30.0, -3.0 - (t * 0.37) % 1.0, 2.0], 0.05));
    }
    let path = dir.join("export").join("tray.ply");
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    mesh_io::save(&path, &join(&parts)).unwrap();
    (path, names)
}

#[test]
fn each_specimen_of_a_batch_file_gets_its_own_row_result_and_report() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let spec = LibrarySpec {
        per_genus: 2,
        target_vertices: 1500,
        seed: 3,
        random_pose: true,
    };
    synth::write_synthetic_library(&root.join("library"), &spec).unwrap();
    let (scan, genera) = batch_file(root);
    let db = root.join("db.sqlite");
    let out_dir = root.join("results");
    let config = root.join("morphoid.toml");
    std::fs::write(
        &config,
        format!(
            "[library]\ndir = {:?}\nranks = [\"order\", \"family\", \"genus\"]\ncache = {:?}\n\
             calibrate = false\n[database]\npath = {:?}\n[clean]\ntarget_vertices = 1500\n",
            root.join("library"),
            root.join("cache"),
            db
        ),
    )
    .unwrap();

    // inspect: three specimens, the cavity and the crumbs dropped.
    let out = Command::new(BIN)
        .args(["inspect", "--json"])
        .arg(&scan)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["specimens"].as_array().map(Vec::len), Some(3), "{v}");
    assert_eq!(v["split"]["nested"], 1, "{v}");
    assert_eq!(v["split"]["debris"], 30, "{v}");

    // classify: one JSON object with the three specimens, in order along x.
    let out = Command::new(BIN)
        .arg("classify")
        .arg("--config")
        .arg(&config)
        .arg("--json")
        .arg("--out-dir")
        .arg(&out_dir)
        .arg(&scan)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let specimens = v["specimens"].as_array().expect("specimens").clone();
    assert_eq!(specimens.len(), 3, "{v}");
    let mut right = 0;
    let mut last_x = f64::MIN;
    for (k, s) in specimens.iter().enumerate() {
        assert_eq!(
            s["scan"].as_str().unwrap(),
            format!("{}#{}", scan.display(), k + 1)
        );
        assert_eq!(s["specimen"], k + 1);
        assert_eq!(s["parent"], v["id"]);
        let x = s["position"]["bounds"][0][0].as_f64().unwrap();
        assert!(x > last_x, "specimens out of order: {v}");
        last_x = x;
        assert_eq!(s["status"], "ok", "{s}");
        if s["ranks"]["genus"]["taxon"] == genera[k] {
            right += 1;
        }
    }
    assert!(right >= 2, "genus right for {right} of 3: {v}");

    // The database: the scan's row and one row per specimen.
    let conn = rusqlite::Connection::open(&db).unwrap();
    let rows: Vec<(String, Option<i64>, Option<i64>)> = conn
        .prepare("SELECT path, parent_id, specimen FROM scan ORDER BY id")
        .unwrap()
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    assert_eq!(rows.len(), 4, "{rows:?}");
    assert_eq!(rows[0].1, None);
    assert!(rows[1..].iter().all(|r| r.1.is_some() && r.2.is_some()));

    // Again: nothing identified twice.
    let again = Command::new(BIN)
        .arg("classify")
        .arg("--config")
        .arg(&config)
        .arg(&scan)
        .output()
        .unwrap();
    assert!(again.status.success());
    let text = String::from_utf8_lossy(&again.stdout);
    assert!(
        text.contains("3 specimens") && text.contains("tray.ply#3"),
        "{text}"
    );
    let n: i64 = conn
        .query_row("SELECT count(*) FROM scan", [], |r| r.get(0))
        .unwrap();
    assert_eq!(n, 4);

    // results: the scan with its specimens.
    let out = Command::new(BIN)
        .args(["results", "--json", "--config"])
        .arg(&config)
        .output()
        .unwrap();
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 1);
    assert_eq!(lines[0]["specimens"].as_array().map(Vec::len), Some(3));

    // Result files for each specimen, linked from the scan's page and the
    // overview.
    for k in 1..=3 {
        for ext in ["json", "html"] {
            let f = out_dir.join(format!("tray.ply#{k}.{ext}"));
            assert!(f.is_file(), "{} missing", f.display());
        }
    }
    let page = std::fs::read_to_string(out_dir.join("tray.ply.html")).unwrap();
    assert!(page.contains("tray.ply%233.html"), "no link to specimen 3");
    let index = std::fs::read_to_string(out_dir.join("index.html")).unwrap();
    assert!(index.contains("3 specimens") && index.contains("tray.ply%232.html"));

    // `morphoid report` draws the pages again from the database, the
    // specimens' too.
    let again_dir = root.join("pages");
    let out = Command::new(BIN)
        .args(["report", "--last", "1", "--config"])
        .arg(&config)
        .arg("--out")
        .arg(&again_dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let listed = String::from_utf8_lossy(&out.stdout);
    for k in 1..=3 {
        assert!(listed.contains(&format!("tray.ply#{k}.html")), "{listed}");
    }
}

/// The daemon with a results folder: a batch file dropped into the export
/// folder gets its three specimens' rows, each with its own report, and
/// the overview lists them under the scan.
#[test]
fn the_daemon_identifies_each_specimen_of_a_batch_file() {
    use crate::support::daemon::{env, rows, wait_until, Daemon};
    let env = env(0.3, "", "");
    let out = env.root.join("results");
    let mut text = std::fs::read_to_string(&env.config).unwrap();
    text = text.replace("[library]\n", "[library]\ncalibrate = false\n");
    text.push_str(&format!("[results]\ndir = {out:?}\n"));
    std::fs::write(&env.config, text).unwrap();
    let d = Daemon::start(&env);
    let staging = env.root.join("staging");
    let (made, _) = batch_file(&staging);
    std::fs::rename(&made, env.export.join("tray.ply")).unwrap();
    let done = || {
        rows(&env.db).iter().any(|r| {
            r.specimens.len() == 3 && r.specimens.iter().all(|c| c.status.as_str() == "ok")
        }) && (1..=3).all(|k| out.join(format!("tray.ply#{k}.html")).is_file())
            && std::fs::read_to_string(out.join("index.html"))
                .is_ok_and(|i| i.contains("tray.ply%233.html"))
    };
    assert!(
        wait_until(std::time::Duration::from_secs(240), done),
        "{}",
        d.log_text()
    );
    d.log_once("3 specimens");
}
