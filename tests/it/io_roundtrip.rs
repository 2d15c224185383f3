//! Write then read back every format and variant.

use morphoid_core::mesh::Mesh;
use morphoid_data::mesh_io::{encode, load, load_bytes, save, save_as, Encoding, Format};
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
                // Float32 corners: a triangle soup in ASCII, shared
                // corners in binary.
                let expected = if enc == Encoding::StlAscii {
                    3 * m.face_count()
                } else {
                    m.vertex_count()
                };
                assert_eq!(back.mesh.vertex_count(), expected, "{enc:?}");
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

/// Big-endian binary PLY with mixed scalar types, properties in an unusual
/// order, an extra list property and an extra element.
#[test]
fn ply_with_any_property_layout() {
    let mut b = b"ply\nformat binary_big_endian 1.0\ncomment mixed\n\
        element vertex 4\nproperty uchar red\nproperty double z\nproperty float x\n\
        property short y\nproperty list uchar float extra\n\
        element edge 1\nproperty int a\nproperty int b\n\
        element face 1\nproperty uint flags\nproperty list ushort uint vertex_index\n\
        end_header\n"
        .to_vec();
    let verts = [
        (0.5f64, 1.0f32, 2i16),
        (1.5, -1.0, 3),
        (2.5, 4.0, -4),
        (3.5, 0.25, 5),
    ];
    for (i, (z, x, y)) in verts.iter().enumerate() {
        b.push(200);
        b.extend_from_slice(&z.to_be_bytes());
        b.extend_from_slice(&x.to_be_bytes());
        b.extend_from_slice(&y.to_be_bytes());
        b.push(i as u8);
        for k in 0..i {
            b.extend_from_slice(&(k as f32).to_be_bytes());
        }
    }
    b.extend_from_slice(&0i32.to_be_bytes());
    b.extend_from_slice(&1i32.to_be_bytes());
    b.extend_from_slice(&7u32.to_be_bytes());
    b.extend_from_slice(&4u16.to_be_bytes());
    for i in [0u32, 1, 2, 3] {
        b.extend_from_slice(&i.to_be_bytes());
    }
    let m = load_bytes(&b, Format::Ply, Path::new("mixed.ply"))
        .unwrap()
        .mesh;
    assert_eq!(
        m.vertices,
        vec![
            [1.0, 2.0, 0.5],
            [-1.0, 3.0, 1.5],
            [4.0, -4.0, 2.5],
            [0.25, 5.0, 3.5]
        ]
    );
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3]]);
    // One byte short: an error naming the file, not a partial mesh.
    let err = load_bytes(&b[..b.len() - 1], Format::Ply, Path::new("mixed.ply")).unwrap_err();
    assert!(err.to_string().starts_with("mixed.ply: "), "{err}");
}

/// STL: binary is recognized by its size even when its header begins
/// with "solid"; ASCII by its content.
#[test]
fn stl_binary_and_ascii_detection() {
    let m = square_pyramid();
    let mut binary = encode(&m, Encoding::StlBinary).unwrap();
    binary[..12].copy_from_slice(b"solid fooled");
    let back = load_bytes(&binary, Format::Stl, Path::new("b.stl")).unwrap();
    assert_close(&corners(&back.mesh), &corners(&m), 1e-6);
    let ascii = encode(&m, Encoding::StlAscii).unwrap();
    assert!(ascii.starts_with(b"solid"));
    let back = load_bytes(&ascii, Format::Stl, Path::new("a.stl")).unwrap();
    assert_close(&corners(&back.mesh), &corners(&m), 1e-12);
    // A binary file with one byte too many is neither.
    binary.push(0);
    assert!(load_bytes(&binary, Format::Stl, Path::new("b.stl")).is_err());
}

/// A realistic mesh survives every encoding.
#[test]
fn synthetic_crown_round_trips() {
    let m = morphoid_synth::mesh::crown(&morphoid_synth::mesh::CROWN_GENERA[1], 8, 5000);
    for enc in ALL {
        let back = load_bytes(&encode(&m, enc).unwrap(), enc.format(), Path::new("c")).unwrap();
        assert_eq!(back.mesh.face_count(), m.face_count());
        if enc.format() == Format::Stl {
            assert_close(&corners(&back.mesh), &corners(&m), 1e-6);
        } else {
            assert_eq!(back.mesh, m, "{enc:?}");
        }
    }
}
