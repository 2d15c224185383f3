//! Every command reads the configuration file, and the cache of prepared
//! surfaces is one place for every command: `library build` fills it,
//! `matrix --cache` finds and fills the same entries.

use morphoid_data::mesh_io;
use morphoid_synth::mesh::{self as synth, write_synthetic_library, LibrarySpec};
use std::path::Path;
use std::process::{Command, Output};

fn morphoid(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphoid"))
        .args(args)
        .output()
        .unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn small_library(dir: &Path) -> usize {
    let spec = LibrarySpec {
        per_genus: 1,
        target_vertices: 800,
        seed: 21,
        random_pose: false,
    };
    write_synthetic_library(dir, &spec).unwrap().len()
}

#[test]
fn matrix_finds_what_library_build_and_earlier_runs_prepared() {
    let lib = tempfile::tempdir().unwrap();
    let n = small_library(lib.path());
    let work = tempfile::tempdir().unwrap();
    let root = work.path().join("cache");
    let config = work.path().join("morphoid.toml");
    std::fs::write(
        &config,
        format!(
            "[library]\ndir = {:?}\ncache = {:?}\nranks = [\"genus\"]\n",
            s(lib.path()),
            s(&root)
        ),
    )
    .unwrap();
    let o = morphoid(&["library", "build", "--config", s(&config)]);
    assert!(o.status.success(), "{}", stderr(&o));

    // The user names the cache folder of the configuration; the library's
    // own subfolder in it is found without being named.
    let out = work.path().join("m.csv");
    let args = ["matrix", "--library", s(lib.path()), "--out", s(&out)];
    let o = morphoid(&[&args[..], &["--cache", s(&root)]].concat());
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains(&format!("({n} from the cache)")), "{err}");
    assert!(
        err.contains(&format!("{n} of {n} prepared surfaces found")) && err.contains(s(&root)),
        "{err}"
    );

    // A fresh cache folder: the first run prepares and stores, the second
    // finds every surface; the matrices are the same bytes.
    let fresh = work.path().join("fresh");
    let first = morphoid(&[&args[..], &["--cache", s(&fresh)]].concat());
    let err = stderr(&first);
    assert!(first.status.success(), "{err}");
    assert!(
        err.contains(&format!("0 of {n} prepared surfaces found, {n} stored")),
        "{err}"
    );
    let before = std::fs::read(&out).unwrap();
    let second = morphoid(&[&args[..], &["--cache", s(&fresh)]].concat());
    let err = stderr(&second);
    assert!(second.status.success(), "{err}");
    assert!(
        err.contains(&format!("{n} of {n} prepared surfaces found, 0 stored")),
        "{err}"
    );
    assert_eq!(std::fs::read(&out).unwrap(), before);
}

#[test]
fn distance_reads_the_configuration() {
    let dir = tempfile::tempdir().unwrap();
    let genus = synth::crown_genus("Tricuspis").unwrap();
    let crown = synth::crown(genus, 4, 1500);
    let a = dir.path().join("a.ply");
    let b = dir.path().join("b.ply");
    mesh_io::save(&a, &crown).unwrap();
    mesh_io::save(&b, &synth::mirror(&crown)).unwrap();
    let json = |extra: &[&str]| {
        let o = morphoid(&[&["distance", s(&a), s(&b), "--json"], extra].concat());
        assert!(o.status.success(), "{}", stderr(&o));
        serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()
    };
    // Mirror images: by default a reflected map matches them.
    let default = json(&[]);
    assert_eq!(default["reflected"], true, "{default}");

    // `[cp] reflections = false` in the file: no reflected map is tried.
    let config = dir.path().join("no-reflections.toml");
    std::fs::write(&config, "[cp]\nreflections = false\n").unwrap();
    let proper = json(&["--config", s(&config)]);
    assert_eq!(proper["reflected"], false, "{proper}");
    let (d0, d1) = (
        default["distance"].as_f64().unwrap(),
        proper["distance"].as_f64().unwrap(),
    );
    assert!(d1 > d0, "rotations only {d1}, with reflections {d0}");

    // A wrong key is named, as for `classify` and `run`.
    std::fs::write(&config, "[cp]\nreflection = false\n").unwrap();
    for args in [
        vec!["distance", s(&a), s(&b)],
        vec!["matrix", "--library", s(dir.path()), "--out", "unused.csv"],
        vec!["inspect", s(&a)],
    ] {
        let o = morphoid(&[&args[..], &["--config", s(&config)]].concat());
        let err = stderr(&o);
        assert!(
            !o.status.success() && err.contains("reflection") && err.contains(s(&config)),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn names_with_commas_quotes_and_line_breaks_round_trip() {
    let lib = tempfile::tempdir().unwrap();
    let names = ["a,b", "q\"uote", "new\nline"];
    let mut labels = String::from("name,genus\n");
    for (i, name) in names.iter().enumerate() {
        let genus = &synth::CROWN_GENERA[i % 2];
        let mesh = synth::crown(genus, 30 + i as u64, 900);
        mesh_io::save(&lib.path().join(format!("{name}.ply")), &mesh).unwrap();
        labels.push_str(&format!(
            "\"{}\",{}\n",
            name.replace('"', "\"\""),
            genus.name
        ));
    }
    std::fs::write(lib.path().join("labels.csv"), labels).unwrap();
    let work = tempfile::tempdir().unwrap();
    let full = work.path().join("full.csv");
    let o = morphoid(&["matrix", "--library", s(lib.path()), "--out", s(&full)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let m = morphoid_data::table::DistanceMatrix::read_csv(&full).unwrap();
    let mut sorted = names.map(String::from).to_vec();
    sorted.sort();
    assert_eq!(m.names(), sorted);

    let mut shards = Vec::new();
    for k in 1..=2 {
        let p = work.path().join(format!("s{k}.csv"));
        let which = format!("{k}/2");
        let o = morphoid(&[
            "matrix",
            "--library",
            s(lib.path()),
            "--out",
            s(&p),
            "--shard",
            &which,
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        shards.push(p);
    }
    let merged = work.path().join("merged.csv");
    let o = morphoid(&[
        "matrix",
        "merge",
        s(&shards[1]),
        s(&shards[0]),
        "--out",
        s(&merged),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(&merged).unwrap(),
        std::fs::read(&full).unwrap()
    );

    let o = morphoid(&[
        "evaluate",
        "--matrix",
        s(&merged),
        "--labels",
        s(&lib.path().join("labels.csv")),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["specimens"], 3, "{v}");
    assert_eq!(v["ranks"][0]["total"], 3, "{v}");
}

/// `library build` calibrates the confidence as the classifier does: not
/// with `[library] calibrate = false`.
#[test]
fn library_build_calibrates_only_when_the_configuration_says_so() {
    let lib = tempfile::tempdir().unwrap();
    let spec = LibrarySpec {
        per_genus: 2,
        target_vertices: 600,
        seed: 22,
        random_pose: false,
    };
    write_synthetic_library(lib.path(), &spec).unwrap();
    let work = tempfile::tempdir().unwrap();
    for calibrate in [false, true] {
        let config = work.path().join(format!("{calibrate}.toml"));
        std::fs::write(
            &config,
            format!(
                "[library]\ndir = {:?}\ncache = {:?}\nranks = [\"genus\"]\ncalibrate = {calibrate}\n",
                s(lib.path()),
                s(&work.path().join("cache"))
            ),
        )
        .unwrap();
        let o = morphoid(&["library", "build", "--config", s(&config)]);
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(o.status.success(), "{}", stderr(&o));
        assert_eq!(
            out.contains("calibration genus"),
            calibrate,
            "calibrate = {calibrate}: {out}"
        );
    }
}
