//! `morphoid demo`, as a new user runs it: no data, no configuration; every
//! scan it writes (cropped crowns in four formats, a closed whole tooth, a
//! folder of TIFF slices, a two-rooted isosurface, three teeth in foam in
//! one stack) identified to the genus it was made as, and the broken file
//! recorded as an error.

use crate::support::daemon::BIN;
use std::process::Command;

#[test]
fn demo_identifies_a_closed_tooth_and_a_slice_stack_among_its_scans() {
    let home = tempfile::tempdir().unwrap();
    let out = Command::new(BIN)
        .arg("demo")
        .env("HOME", home.path())
        .env("TMPDIR", home.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stdout}\n{stderr}");
    for scan in [
        "scan06_whole_tooth.stl",
        "scan07_slices",
        "scan09_two_rooted_isosurface.stl",
        "scan10_batch_of_three#1",
        "scan10_batch_of_three#2",
        "scan10_batch_of_three#3",
    ] {
        let line = stdout
            .lines()
            .find(|l| l.contains(scan))
            .unwrap_or_else(|| panic!("{scan} not shown:\n{stdout}"));
        assert!(
            line.contains(" genus ") && !line.contains("error"),
            "{line}"
        );
    }
    assert!(
        stdout.contains("11 of 11 specimens identified to the right genus"),
        "{stdout}"
    );
    assert!(
        stdout.contains("cut short on purpose: recorded as an error"),
        "{stdout}"
    );
    // The temporary folder is gone unless --keep is given.
    let left: Vec<_> = std::fs::read_dir(home.path()).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
}
