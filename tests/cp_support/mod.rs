//! Helpers shared by the cp tests: the real-data folder and a minimal
//! reader for its binary PLY files.
#![allow(dead_code)]

use morphoid::mesh::{boundary_loops, edge_face_map, euler_characteristic, Mesh};
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

/// Stand-in for the cleaning stage on J12 and S09 (one non-manifold edge
/// each): drop the one face of the offending edge whose removal leaves a
/// disk (one boundary loop, Euler characteristic 1), then unused vertices.
pub fn drop_nonmanifold_faces(mesh: &Mesh) -> Mesh {
    let map = edge_face_map(mesh);
    let mut keys: Vec<_> = map.iter().filter(|(_, f)| f.len() > 2).collect();
    keys.sort();
    let mut current = mesh.clone();
    for (_, faces) in keys {
        let mut best = None;
        for &f in faces {
            let candidate = without_faces(&current, &[f]);
            if euler_characteristic(&candidate) == 1 && boundary_loops(&candidate).len() == 1 {
                best = Some(candidate);
                break;
            }
        }
        current = match best {
            Some(c) => c,
            // Otherwise let the cleaning stage repair the edge.
            None => {
                morphoid::clean::clean(mesh, &morphoid::clean::CleanOptions::default())
                    .expect("clean")
                    .mesh
            }
        };
    }
    current
}

/// The mesh without the given faces and without unused vertices.
fn without_faces(mesh: &Mesh, drop: &[u32]) -> Mesh {
    let faces: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .enumerate()
        .filter(|(i, _)| !drop.contains(&(*i as u32)))
        .map(|(_, f)| *f)
        .collect();
    let mut new_index = vec![u32::MAX; mesh.vertices.len()];
    let mut vertices = Vec::new();
    for f in &faces {
        for &v in f {
            if new_index[v as usize] == u32::MAX {
                new_index[v as usize] = vertices.len() as u32;
                vertices.push(mesh.vertices[v as usize]);
            }
        }
    }
    let faces = faces
        .iter()
        .map(|f| f.map(|v| new_index[v as usize]))
        .collect();
    Mesh::new(vertices, faces)
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

/// Parameters from the JSON in the environment variable `var`, else the
/// defaults; printed, so a run's output says what it measured.
pub fn params_from_env<T>(var: &str) -> T
where
    T: serde::de::DeserializeOwned + serde::Serialize + Default,
{
    let params: T = match std::env::var(var) {
        Ok(json) => serde_json::from_str(&json)
            .unwrap_or_else(|e| panic!("{var} is not parameter JSON: {e}")),
        Err(_) => T::default(),
    };
    println!(
        "params: {}",
        serde_json::to_string(&params).unwrap_or_default()
    );
    params
}

/// Every tooth of `names` prepared with `params` (in parallel), each
/// carrying its name.
pub fn prepare_teeth(
    dir: &std::path::Path,
    names: &[String],
    params: &morphoid::cp::PrepareParams,
) -> Vec<morphoid::cp::Prepared> {
    use rayon::prelude::*;
    names
        .par_iter()
        .map(|n| {
            let mut p = morphoid::cp::prepare(&load_tooth(dir, n), params).expect("prepare");
            p.set_name(n.clone());
            p
        })
        .collect()
}

/// The pair the benchmarks compare: the real teeth H10 and H16 when the
/// data is present, else two synthetic crowns of about 5,000 vertices;
/// with a description of which.
pub fn benchmark_pair() -> (Mesh, Mesh, &'static str) {
    let dir = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/data/pnas-teeth"
    ));
    if dir.join("meshes/H10.ply").exists() && dir.join("meshes/H16.ply").exists() {
        (
            load_tooth(&dir, "H10"),
            load_tooth(&dir, "H16"),
            "real teeth H10, H16",
        )
    } else {
        use morphoid::mesh::synth::{crown, CROWN_GENERA};
        (
            crown(&CROWN_GENERA[0], 1, 5000),
            crown(&CROWN_GENERA[1], 2, 5000),
            "synthetic crowns (data not found)",
        )
    }
}
