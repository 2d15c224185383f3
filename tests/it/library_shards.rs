//! A library built as a job array's tasks would build it: `library build
//! --shard K/N` into a shared cache, `library calibrate --shard K/N`, then
//! `library calibrate merge`: the same cache entries and the same
//! calibration file, byte for byte, as one `library build`; the merge
//! refuses shard sets that do not belong together, naming the file.

use morphoid_synth::mesh::{self as synth, LibrarySpec};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_morphoid");

fn morphoid(config: &Path, args: &[&str]) -> Output {
    Command::new(BIN)
        .arg("--config")
        .arg(config)
        .args(args)
        .output()
        .unwrap()
}

fn ok(out: Output) -> String {
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn failure(out: Output) -> String {
    assert!(
        !out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A configuration of `lib` with its own cache and database.
fn config(dir: &Path, name: &str, lib: &Path) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    let text = format!(
        "[library]\ndir = {:?}\ncache = {:?}\ncalibrate = true\n[database]\npath = {:?}\n[clean]\ntarget_vertices = 600\n",
        lib,
        dir.join(format!("cache-{name}")),
        dir.join(format!("{name}.sqlite"))
    );
    std::fs::write(&path, text).unwrap();
    path
}

/// The files of the library's cache folder (the one subfolder of the
/// cache folder), by name, with their bytes; the index left out (it
/// holds file stamps, not results).
fn cache_files(cache_root: &Path) -> Vec<(String, Vec<u8>)> {
    let sub = std::fs::read_dir(cache_root)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.is_dir())
        .unwrap();
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(&sub)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().is_some_and(|n| n != "references.index"))
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&p).unwrap())
        })
        .collect();
    files.sort();
    files
}

fn calibration_lines(stdout: &str) -> Vec<String> {
    stdout
        .lines()
        .filter(|l| l.starts_with("calibration "))
        .map(str::to_string)
        .collect()
}

#[test]
fn a_library_built_in_shards_equals_one_built_at_once() {
    let tmp = tempfile::tempdir().unwrap();
    let lib = tmp.path().join("library");
    let spec = LibrarySpec {
        per_genus: 2,
        target_vertices: 600,
        seed: 21,
        random_pose: true,
    };
    synth::write_synthetic_library(&lib, &spec).unwrap();
    let n = std::fs::read_dir(&lib)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "ply")
        })
        .count();

    let whole = config(tmp.path(), "whole", &lib);
    let at_once = ok(morphoid(&whole, &["library", "build"]));
    assert_eq!(calibration_lines(&at_once).len(), 3, "{at_once}");

    let sharded = config(tmp.path(), "sharded", &lib);
    let mut prepared = 0;
    for k in 1..=3 {
        let out = ok(morphoid(
            &sharded,
            &["library", "build", "--shard", &format!("{k}/3")],
        ));
        assert!(out.contains(&format!("shard {k}/3")), "{out}");
        assert!(
            calibration_lines(&out).is_empty(),
            "a shard does not calibrate: {out}"
        );
        prepared += out
            .split_once(" references (")
            .and_then(|(_, rest)| rest.split_once(" prepared"))
            .map(|(count, _)| count.parse::<usize>().unwrap())
            .unwrap();
    }
    assert_eq!(prepared, n, "each reference prepared by exactly one task");
    let parts: Vec<PathBuf> = (1..=2)
        .map(|k| tmp.path().join(format!("calibration-{k}-of-2.bin")))
        .collect();
    for (k, part) in parts.iter().enumerate() {
        let shard = format!("{}/2", k + 1);
        let out = ok(morphoid(
            &sharded,
            &[
                "library",
                "calibrate",
                "--shard",
                &shard,
                "--out",
                part.to_str().unwrap(),
            ],
        ));
        assert!(out.contains(&format!("calibration shard {shard}")), "{out}");
    }

    // Shard sets that do not belong together are refused, naming a file.
    let one = parts[0].to_str().unwrap();
    let two = parts[1].to_str().unwrap();
    let e = failure(morphoid(&sharded, &["library", "calibrate", "merge", one]));
    assert!(e.contains("shard 2/2 is missing"), "{e}");
    let e = failure(morphoid(
        &sharded,
        &["library", "calibrate", "merge", one, one],
    ));
    assert!(e.contains("both hold shard 1/2"), "{e}");
    let labels = lib.join("labels.csv");
    let e = failure(morphoid(
        &sharded,
        &[
            "library",
            "calibrate",
            "merge",
            one,
            labels.to_str().unwrap(),
        ],
    ));
    assert!(
        e.contains("labels.csv") && e.contains("not a calibration shard"),
        "{e}"
    );

    let merged = ok(morphoid(
        &sharded,
        &["library", "calibrate", "merge", two, one],
    ));
    assert_eq!(calibration_lines(&merged), calibration_lines(&at_once));
    let (a, b) = (
        cache_files(&tmp.path().join("cache-whole")),
        cache_files(&tmp.path().join("cache-sharded")),
    );
    let names = |files: &[(String, Vec<u8>)]| -> Vec<String> {
        files.iter().map(|(n, _)| n.clone()).collect()
    };
    assert_eq!(names(&a), names(&b));
    assert!(names(&a).iter().any(|n| n.starts_with("calibration-")));
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        assert!(x == y, "{name} differs");
    }
    // The library's next build finds the merged calibration: nothing is
    // compared again, the same figures are printed.
    let again = ok(morphoid(&sharded, &["library", "build"]));
    assert_eq!(calibration_lines(&again), calibration_lines(&at_once));

    // A reference changed after the shards were computed: they are of
    // another library now.
    let first = std::fs::read_dir(&lib)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|x| x == "ply"))
        .unwrap();
    let other = synth::crown(&synth::CROWN_GENERA[3], 77, 600);
    morphoid_data::mesh_io::save(&first, &other).unwrap();
    let e = failure(morphoid(
        &sharded,
        &["library", "calibrate", "merge", one, two],
    ));
    assert!(e.contains("another library"), "{e}");
}
