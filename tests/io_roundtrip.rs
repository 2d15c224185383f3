//! Write then read back every format and variant.

use morphoid::mesh::io::{encode, load, load_bytes, save, save_as, Encoding, Format};
use morphoid::mesh::Mesh;
use std::path::Path;

fn square_pyramid() -> Mesh {
    Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.25, 0.0, 0.1],
            [1.0, 1.0, -0.3],
            [0.0, 1.0, 0.2],
            [0.5, 0.5, 0.707_106_781_186_547_1],
        ],
        vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]],
    )
}

const ALL: [Encoding; 7] = [
    Encoding::PlyBinaryLe,
    Encoding::PlyBinaryBe,
    Encoding::PlyAscii,
    Encoding::StlBinary,
    Encoding::StlAscii,
    Encoding::Obj,
    Encoding::Off,
];

/// Coordinates of every face corner, for comparing soups with indexed meshes.
fn corners(m: &Mesh) -> Vec<[f64; 3]> {
    m.faces
        .iter()
        .flat_map(|f| f.iter().map(|&i| m.vertices[i as usize]))
        .collect()
}

fn assert_close(a: &[[f64; 3]], b: &[[f64; 3]], tol: f64) {
    assert_eq!(a.len(), b.len());
    for (p, q) in a.iter().zip(b) {
        for k in 0..3 {
            assert!((p[k] - q[k]).abs() <= tol, "{p:?} vs {q:?}");
        }
    }
}

#[test]
fn every_encoding_round_trips_in_memory() {
    let m = square_pyramid();
    for enc in ALL {
        let bytes = encode(&m, enc).unwrap();
        let back = load_bytes(&bytes, enc.format(), Path::new("mem")).unwrap();
        assert_eq!(back.format, enc.format());
        assert_eq!(back.mesh.face_count(), m.face_count(), "{enc:?}");
        match enc.format() {
            Format::Stl => {
                // A triangle soup in float32.
                assert_eq!(back.mesh.vertex_count(), 3 * m.face_count());
                assert_close(&corners(&back.mesh), &corners(&m), 1e-6);
            }
            _ => {
                // Indexed formats keep vertex order and are exact.
                assert_eq!(back.mesh, m, "{enc:?}");
            }
        }
    }
}

#[test]
fn save_chooses_by_extension_and_load_reads_it_back() {
    let dir = tempfile::tempdir().unwrap();
    let m = square_pyramid();
    for ext in ["ply", "PLY", "obj", "Obj", "stl", "off"] {
        let path = dir.path().join(format!("mesh.{ext}"));
        save(&path, &m).unwrap();
        let back = load(&path).unwrap();
        assert_eq!(back.mesh.face_count(), 4);
        assert_close(&corners(&back.mesh), &corners(&m), 1e-6);
    }
    // No temporary files are left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 6);
}

#[test]
fn point_clouds_round_trip_except_in_stl() {
    let dir = tempfile::tempdir().unwrap();
    let mut m = square_pyramid();
    m.faces.clear();
    for enc in [
        Encoding::PlyBinaryLe,
        Encoding::PlyBinaryBe,
        Encoding::PlyAscii,
        Encoding::Obj,
        Encoding::Off,
    ] {
        let bytes = encode(&m, enc).unwrap();
        let back = load_bytes(&bytes, enc.format(), Path::new("cloud")).unwrap();
        assert!(back.mesh.is_point_cloud());
        assert_eq!(back.mesh, m, "{enc:?}");
    }
    assert!(encode(&m, Encoding::StlBinary).is_err());
    let path = dir.path().join("cloud.stl");
    let err = save_as(&path, &m, Encoding::StlAscii)
        .unwrap_err()
        .to_string();
    assert!(err.contains("cloud.stl"), "{err}");
}

#[test]
fn writers_refuse_invalid_meshes() {
    let mut m = square_pyramid();
    m.faces.push([0, 1, 9]);
    for enc in ALL {
        assert!(encode(&m, enc).is_err(), "{enc:?}");
    }
    let mut m = square_pyramid();
    m.vertices[2][1] = f64::NAN;
    assert!(encode(&m, Encoding::PlyAscii).is_err());
}
