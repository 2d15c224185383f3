//! Malformed input: every failure is one line naming the file, never a panic.

use morphoid_data::mesh_io::{encode, load, load_bytes, Encoding, Format, LoadError};
use morphoid_synth::mesh::{crown, write_bad_inputs, CROWN_GENERA};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;

fn assert_one_line_naming(err: &LoadError, name: &str) {
    let msg = err.to_string();
    assert!(msg.contains(name), "message does not name {name}: {msg}");
    assert!(!msg.contains('\n'), "message is not one line: {msg}");
}

#[test]
fn bad_inputs_fail_to_load_or_load_as_expected() {
    let dir = tempfile::tempdir().unwrap();
    let files = write_bad_inputs(dir.path()).unwrap();
    assert_eq!(files.len(), 8);
    for (path, what) in &files {
        assert!(!what.is_empty());
        let name = path.file_name().unwrap().to_str().unwrap();
        let result = load(path);
        match name {
            "closed_sphere.ply" => {
                let m = result.unwrap().mesh;
                assert_eq!(morphoid_core::mesh::euler_characteristic(&m), 2);
            }
            "three_points.ply" => {
                let m = result.unwrap().mesh;
                assert!(m.is_point_cloud());
                assert_eq!(m.vertex_count(), 3);
            }
            _ => {
                let err = result.expect_err(name);
                assert_one_line_naming(&err, name);
                println!("{err}");
            }
        }
    }
}

#[test]
fn specific_problems_are_named() {
    let cases: [(&str, &[u8], &str); 12] = [
        ("a.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1.0 2.", "line 4"),
        ("b.obj", b"v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n", "line 3"),
        ("c.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "line 4"),
        ("d.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 inf 0\n3 0 1 2\n", "line 5"),
        ("e.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "line 6"),
        (
            "f.off",
            b"OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n# long enough for two faces\n",
            "end of file",
        ),
        ("g.ply", b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 NaN 0\n", "non-finite"),
        ("h.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0", "cannot fit"),
        ("i.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float q\nend_header\n", "no property 'y'"),
        ("j.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n", "end_header"),
        ("k.stl", b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n", "end of file"),
        ("l.stl", b"\x00\x01garbage that is not an stl at all", "not an STL"),
    ];
    for (name, bytes, expected) in cases {
        let format = Format::from_path(Path::new(name)).unwrap();
        let err = load_bytes(bytes, format, Path::new(name)).expect_err(name);
        assert_one_line_naming(&err, name);
        assert!(err.to_string().contains(expected), "{name}: {err}");
    }
}

#[test]
fn empty_files_and_unknown_extensions() {
    let dir = tempfile::tempdir().unwrap();
    for ext in ["obj", "ply", "stl", "off", "OBJ"] {
        let path = dir.path().join(format!("empty.{ext}"));
        std::fs::write(&path, b"").unwrap();
        let err = load(&path).unwrap_err();
        assert_one_line_naming(&err, &format!("empty.{ext}"));
        assert!(err.to_string().contains("empty"), "{err}");
    }
    let path = dir.path().join("mesh.xyz");
    std::fs::write(&path, b"0 0 0\n").unwrap();
    assert!(matches!(load(&path), Err(LoadError::UnknownFormat { .. })));
    let missing = dir.path().join("missing.ply");
    let err = load(&missing).unwrap_err();
    assert!(matches!(err, LoadError::Io { .. }));
    assert_one_line_naming(&err, "missing.ply");
}

/// Truncations and byte corruptions of valid files of every encoding:
/// loading returns (Ok or Err) and never panics; cut binary files fail.
#[test]
fn corrupted_files_never_panic() {
    let mesh = crown(&CROWN_GENERA[2], 5, 300);
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    for enc in [
        Encoding::PlyBinaryLe,
        Encoding::PlyBinaryBe,
        Encoding::PlyAscii,
        Encoding::StlBinary,
        Encoding::StlAscii,
        Encoding::Obj,
        Encoding::Off,
    ] {
        let bytes = encode(&mesh, enc).unwrap();
        let name = Path::new("corrupt");
        for _ in 0..150 {
            let cut = rng.gen_range(0..bytes.len());
            let result = load_bytes(&bytes[..cut], enc.format(), name);
            if matches!(
                enc,
                Encoding::PlyBinaryLe | Encoding::PlyBinaryBe | Encoding::StlBinary
            ) {
                assert!(result.is_err(), "{enc:?} cut at {cut} loaded");
            }
            let mut damaged = bytes.clone();
            for _ in 0..rng.gen_range(1..8) {
                let i = rng.gen_range(0..damaged.len());
                damaged[i] = rng.gen();
            }
            if let Ok(m) = load_bytes(&damaged, enc.format(), name) {
                let n = m.mesh.vertices.len();
                assert!(m.mesh.faces.iter().flatten().all(|&i| (i as usize) < n));
                assert!(m.mesh.vertices.iter().flatten().all(|c| c.is_finite()));
            }
        }
    }
    for _ in 0..200 {
        let len = rng.gen_range(0..400);
        let junk: Vec<u8> = (0..len).map(|_| rng.gen()).collect();
        for format in [Format::Obj, Format::Ply, Format::Stl, Format::Off] {
            let _ = load_bytes(&junk, format, Path::new("junk"));
        }
    }
}
