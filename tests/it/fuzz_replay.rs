//! The inputs the fuzz campaigns found (`tests/fuzz_regressions/<target>/`,
//! each one a crash, a hang or a huge allocation before its fix) and the
//! seeds, replayed through the fuzz targets' own entry points
//! (`fuzz/src/lib.rs`, included here), so that stable CI keeps them fixed
//! without a nightly toolchain: every input returns, accepted or refused,
//! without a panic.

// The harness is a crate of its own under `cargo fuzz`; here its public
// items are the test's.
#[allow(unreachable_pub)]
#[path = "../../fuzz/src/lib.rs"]
mod harness;

use crate::support::fuzz_seeds::seeds;
use std::path::Path;

fn target(name: &str) -> harness::Target {
    harness::TARGETS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|&(_, f)| f)
        .unwrap_or_else(|| panic!("no fuzz target {name}"))
}

#[test]
fn fuzz_regressions_return_without_panicking() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    let mut replayed = 0;
    for dir in std::fs::read_dir(&root).unwrap() {
        let dir = dir.unwrap().path();
        let name = dir.file_name().unwrap().to_string_lossy().into_owned();
        let run = target(&name);
        let mut files: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        files.sort();
        for file in files {
            let bytes = std::fs::read(&file).unwrap();
            let accepted = run(&bytes);
            println!(
                "{name}/{}: accepted {accepted}",
                file.file_name().unwrap().to_string_lossy()
            );
            replayed += 1;
        }
    }
    assert!(replayed > 0, "no inputs under {}", root.display());
}

/// Seeds that are refused on purpose: the bad inputs that do not load
/// (a closed sphere and three points load, and fail later), collections
/// read as one specimen's file, and one shard of two (an incomplete set).
fn refused(target: &str, name: &str) -> bool {
    (name.starts_with("bad_") && !matches!(name, "bad_closed_sphere.ply" | "bad_three_points.ply"))
        || (name.starts_with("collection.") && matches!(target, "tps" | "morphologika"))
        || name == "one_shard.csv"
}

#[test]
fn fuzz_seeds_are_read_as_written() {
    for (name, bytes) in seeds()
        .unwrap()
        .iter()
        .filter(|(t, _, _)| !matches!(*t, "clean" | "volume_pipeline"))
        .map(|(t, n, b)| ((*t, n.as_str()), b))
    {
        let accepted = target(name.0)(bytes);
        assert_eq!(accepted, !refused(name.0, name.1), "{name:?}");
    }
}

#[test]
fn fuzz_seeds_of_clean_and_the_volume_pipeline_return() {
    for (t, name, bytes) in seeds()
        .unwrap()
        .iter()
        .filter(|(t, _, _)| matches!(*t, "clean" | "volume_pipeline"))
    {
        let accepted = target(t)(bytes);
        println!("{t}/{name}: accepted {accepted}");
    }
}
