//! Helpers shared by the cp tests: the real-data folder and a minimal
//! reader for its binary PLY files.
#![allow(dead_code)]

use morphoid::mesh::{edge_face_map, Mesh};
use std::path::PathBuf;

/// The PNAS teeth folder, if present.
pub fn data_dir() -> Option<PathBuf> {
    let p = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/data/pnas-teeth"
    ));
    if p.join("labels.csv").exists() {
        Some(p)
    } else {
        println!("skipped: data not found");
        None
    }
}

/// Read a binary little-endian PLY with float xyz and uchar/int faces.
pub fn read_ply(path: &std::path::Path) -> Mesh {
    let bytes = std::fs::read(path).expect("readable PLY");
    let end = b"end_header\n";
    let hend = bytes
        .windows(end.len())
        .position(|w| w == end)
        .expect("PLY header")
        + end.len();
    let header = String::from_utf8_lossy(&bytes[..hend]);
    let mut nv = 0usize;
    let mut nf = 0usize;
    for line in header.lines() {
        let t: Vec<&str> = line.split_whitespace().collect();
        if t.len() == 3 && t[0] == "element" && t[1] == "vertex" {
            nv = t[2].parse().expect("count");
        }
        if t.len() == 3 && t[0] == "element" && t[1] == "face" {
            nf = t[2].parse().expect("count");
        }
    }
    let mut o = hend;
    let f32at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes")) as f64;
    let mut vertices = Vec::with_capacity(nv);
    for _ in 0..nv {
        vertices.push([f32at(o), f32at(o + 4), f32at(o + 8)]);
        o += 12;
    }
    let i32at = |o: usize| i32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes")) as u32;
    let mut faces = Vec::with_capacity(nf);
    for _ in 0..nf {
        assert_eq!(bytes[o], 3);
        faces.push([i32at(o + 1), i32at(o + 5), i32at(o + 9)]);
        o += 13;
    }
    Mesh::new(vertices, faces)
}

/// Drop every face incident to a non-manifold edge (J12 and S09 have one),
/// standing in for the cleaning stage.
pub fn drop_nonmanifold_faces(mesh: &Mesh) -> Mesh {
    let map = edge_face_map(mesh);
    let mut bad = vec![false; mesh.faces.len()];
    for faces in map.values() {
        if faces.len() > 2 {
            for &f in faces {
                bad[f as usize] = true;
            }
        }
    }
    let faces = mesh
        .faces
        .iter()
        .zip(&bad)
        .filter(|(_, &b)| !b)
        .map(|(f, _)| *f)
        .collect();
    Mesh::new(mesh.vertices.clone(), faces)
}

/// Load a tooth by name, ready for preparation.
pub fn load_tooth(dir: &std::path::Path, name: &str) -> Mesh {
    drop_nonmanifold_faces(&read_ply(&dir.join("meshes").join(format!("{name}.ply"))))
}

/// Names in labels.csv order.
pub fn tooth_names(dir: &std::path::Path) -> Vec<String> {
    let text = std::fs::read_to_string(dir.join("labels.csv")).expect("labels");
    text.lines()
        .skip(1)
        .filter_map(|l| l.split(',').next())
        .filter(|s| !s.is_empty())
        .map(|s| s.to_string())
        .collect()
}
