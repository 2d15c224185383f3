//! `morphoid run` with `[results] dir`: a scan dropped into the export
//! folder gets `<name>.json` and, since its nearest reference has
//! landmarks, `<name>.fcsv` with those landmarks carried onto it (`<name>`:
//! the path in the export folder, `tooth_7.ply`).

use crate::support::daemon::*;
use crate::support::lm::{moved_copy, relative_errors, true_position, write_library_landmarks};
use morphoid_data::landmarks;
use morphoid_data::mesh_io;
use std::time::Duration;

#[test]
fn the_daemon_writes_the_carried_landmarks_next_to_the_json() {
    let results = "RESULTS_DIR";
    let env = env(0.5, "", &format!("[results]\ndir = {results:?}\n"));
    let out_dir = env.root.join("results");
    let config = std::fs::read_to_string(&env.config)
        .unwrap()
        .replace(results, &out_dir.display().to_string());
    std::fs::write(&env.config, config).unwrap();
    let lib = env.root.join("library");
    let names: Vec<String> = std::fs::read_to_string(lib.join("labels.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').next().map(str::to_string))
        .collect();
    assert_eq!(names.len(), 10);
    write_library_landmarks(&lib, &names);
    let d = Daemon::start(&env);

    // A moved, remeshed, rescaled copy of one reference.
    let source = lib.join(format!("{}.ply", names[5]));
    let (copy, motion) = moved_copy(&mesh_io::load(&source).unwrap().mesh, 81);
    let tmp = env.root.join("staging.ply");
    mesh_io::save(&tmp, &copy).unwrap();
    std::fs::rename(&tmp, env.export.join("tooth_7.ply")).unwrap();

    let fcsv = out_dir.join("tooth_7.ply.fcsv");
    let json = out_dir.join("tooth_7.ply.json");
    assert!(
        wait_until(Duration::from_secs(240), || fcsv.is_file()
            && json.is_file()),
        "no result files in {}: {:?}\n{}",
        out_dir.display(),
        std::fs::read_dir(&out_dir).map(|r| r.count()),
        d.log_text()
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["status"], "ok");
    assert_eq!(v["landmarks_reference"], names[5].as_str());
    let got = landmarks::read(&fcsv, Some(10)).unwrap();
    let truth: Vec<[f64; 3]> = crate::support::lm::landmarks_of(&source)
        .points()
        .iter()
        .map(|&p| true_position(p, &motion))
        .collect();
    let (mean, max) = relative_errors(got.points(), &truth, &copy);
    println!("daemon: error / diagonal mean {mean:.5}, max {max:.5}");
    assert!(mean < 0.01, "mean error {mean}");
    let r = rows(&env.db);
    assert_eq!(r.len(), 1);
    let lm = r[0].landmarks.as_ref().expect("landmarks in the database");
    assert_eq!(lm.points.len(), 10);
    assert_eq!(lm.reference, names[5]);
}

/// `check-config` on `[results] dir`: an empty path and a path that is a
/// file are errors naming the key; a folder (existing or not) is fine.
#[test]
fn check_config_validates_the_results_folder() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("m.toml");
    let file = dir.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let check = |results: &str| {
        std::fs::write(&config, format!("[results]\ndir = {results:?}\n")).unwrap();
        let out = std::process::Command::new(BIN)
            .args(["check-config", "--config"])
            .arg(&config)
            .output()
            .unwrap();
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        (out.status.success(), text)
    };
    let (ok, text) = check("");
    assert!(!ok && text.contains("results.dir"), "{text}");
    let (ok, text) = check(&file.display().to_string());
    assert!(
        !ok && text.contains("results.dir") && text.contains("not a folder"),
        "{text}"
    );
    let target = dir.path().join("results");
    let (ok, text) = check(&target.display().to_string());
    assert!(ok && text.contains("result files in"), "{text}");
}
