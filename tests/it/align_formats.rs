//! Landmark collections in and out (TPS, morphologika) through the files
//! users hand in, and the `evaluate` outputs that work from any matrix:
//! classical MDS (coordinates and plot) and the average-linkage tree
//! (Newick and dendrogram).

use morphoid_data::landmarks::{self, LandmarkError, Landmarks, NamedLandmarks};
use std::process::Command;

#[test]
fn tps_and_morphologika_files_round_trip_and_bad_ones_name_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let sets: Vec<NamedLandmarks> = (0..3)
        .map(|i| NamedLandmarks {
            name: format!("sp{i}"),
            landmarks: Landmarks::from_points(
                (0..5)
                    .map(|k| [i as f64, k as f64 * 0.1, 1.0 / 3.0])
                    .collect(),
            ),
        })
        .collect();
    for name in ["c.tps", "c.txt"] {
        let path = dir.path().join(name);
        landmarks::write_collection(&path, &sets).unwrap();
        assert_eq!(landmarks::read_collection(&path).unwrap(), sets, "{name}");
    }
    // A one-specimen TPS file is a landmark file like the others, with
    // its SCALE applied.
    let one = dir.path().join("one.tps");
    std::fs::write(&one, "LM3=2\n1 2 3\n4 5 6\nSCALE=2\nID=a\n").unwrap();
    assert_eq!(
        landmarks::read(&one, Some(2)).unwrap().points(),
        vec![[2.0, 4.0, 6.0], [8.0, 10.0, 12.0]]
    );
    let e = landmarks::read(&dir.path().join("c.tps"), None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("3 specimens"), "{e}");
    for (text, line, what) in [
        ("LM3=3\n1 2 3\n-999 -999 -999\n4 5 6\nID=a\n", 3, "missing"),
        ("LM3=2\n1 2 3\n4 5 6\n", 1, "without ID="),
        ("LM3=3\n1 2 3\n4 5 6\nID=a\n", 1, "LM3=3 but 2"),
    ] {
        let path = dir.path().join("bad.tps");
        std::fs::write(&path, text).unwrap();
        let e = landmarks::read_collection(&path).unwrap_err();
        assert!(
            matches!(e, LandmarkError::Syntax { line: l, .. } if l == line),
            "{e}"
        );
        let msg = e.to_string();
        assert!(msg.contains("bad.tps") && msg.contains(what), "{msg}");
    }
}

#[test]
fn evaluate_writes_mds_and_the_average_linkage_tree() {
    let dir = tempfile::tempdir().unwrap();
    // Two tight pairs far apart on a line.
    let x = [0.0f64, 1.0, 10.0, 10.5];
    let names = ["a", "b", "c", "d"];
    let mut csv = String::from("name,a,b,c,d\n");
    for (n, p) in names.iter().zip(&x) {
        let row: Vec<String> = x.iter().map(|q| format!("{:?}", (p - q).abs())).collect();
        csv.push_str(&format!("{n},{}\n", row.join(",")));
    }
    std::fs::write(dir.path().join("m.csv"), csv).unwrap();
    std::fs::write(
        dir.path().join("labels.csv"),
        "name,genus\na,G1\nb,G1\nc,G2\nd,G2\n",
    )
    .unwrap();
    let status = Command::new(env!("CARGO_BIN_EXE_morphoid"))
        .current_dir(dir.path())
        .args([
            "evaluate", "--matrix", "m.csv", "--mds", "mds.csv", "--tree", "tree.nwk",
        ])
        .args(["--labels", "labels.csv", "--group-rank", "genus"])
        .status()
        .unwrap();
    assert!(status.success());
    let nwk = std::fs::read_to_string(dir.path().join("tree.nwk")).unwrap();
    assert_eq!(nwk, "((a:0.5,b:0.5):4.375,(c:0.25,d:0.25):4.625);\n");
    let mds = std::fs::read_to_string(dir.path().join("mds.csv")).unwrap();
    let rows: Vec<Vec<f64>> = mds
        .lines()
        .skip(1)
        .map(|l| l.split(',').skip(1).map(|v| v.parse().unwrap()).collect())
        .collect();
    // Points on a line: one axis reproduces their distances.
    assert_eq!(rows[0].len(), 1, "{mds}");
    for i in 0..4 {
        for j in 0..4 {
            assert!(((rows[i][0] - rows[j][0]).abs() - (x[i] - x[j]).abs()).abs() < 1e-9);
        }
    }
    let svg = std::fs::read_to_string(dir.path().join("mds.svg")).unwrap();
    assert!(svg.contains("G2") && svg.contains("<circle"));
    assert!(std::fs::read_to_string(dir.path().join("tree.svg"))
        .unwrap()
        .contains("a (G1)"));
    assert!(image::open(dir.path().join("mds.png")).is_ok());
}
