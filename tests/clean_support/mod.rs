//! Helpers shared by the cleaning tests: the real-data location, a minimal
//! reader for the teeth (binary little-endian PLY, float32 xyz, uchar-count
//! int32 faces) and the distance from points to a surface.

#![allow(dead_code)]

use morphoid::clean::closest::TriangleGrid;
use morphoid::mesh::Mesh;
use std::path::{Path, PathBuf};

/// Folder of the real teeth, if present.
pub fn teeth_dir() -> Option<PathBuf> {
    let p = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/data/pnas-teeth/meshes"
    ));
    p.is_dir().then(|| p.to_path_buf())
}

/// Read one of the teeth (the exact format of the data set only).
pub fn read_tooth(path: &Path) -> Mesh {
    let bytes = std::fs::read(path).expect("read tooth");
    let end = b"end_header\n";
    let hdr_len = bytes
        .windows(end.len())
        .position(|w| w == end)
        .expect("header")
        + end.len();
    let header = std::str::from_utf8(&bytes[..hdr_len]).expect("utf8 header");
    let count = |el: &str| -> usize {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {el} ")))
            .and_then(|n| n.trim().parse().ok())
            .expect("element count")
    };
    let (nv, nf) = (count("vertex"), count("face"));
    let mut at = hdr_len;
    let f32_at =
        |i: usize| f32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    let mut vertices = Vec::with_capacity(nv);
    for _ in 0..nv {
        vertices.push([
            f32_at(at) as f64,
            f32_at(at + 4) as f64,
            f32_at(at + 8) as f64,
        ]);
        at += 12;
    }
    let mut faces = Vec::with_capacity(nf);
    for _ in 0..nf {
        assert_eq!(bytes[at], 3);
        at += 1;
        let i = |k: usize| {
            i32::from_le_bytes([bytes[k], bytes[k + 1], bytes[k + 2], bytes[k + 3]]) as u32
        };
        faces.push([i(at), i(at + 4), i(at + 8)]);
        at += 12;
    }
    Mesh::new(vertices, faces)
}

/// All teeth, sorted by name.
pub fn all_teeth() -> Option<Vec<(String, Mesh)>> {
    let dir = teeth_dir()?;
    let mut names: Vec<PathBuf> = std::fs::read_dir(&dir)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "ply"))
        .collect();
    names.sort();
    Some(
        names
            .iter()
            .map(|p| {
                let stem = p
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default();
                (stem, read_tooth(p))
            })
            .collect(),
    )
}

/// Mean and maximum distance from `points` to the surface of `mesh`.
pub fn mean_max_distance(points: &[[f64; 3]], mesh: &Mesh) -> (f64, f64) {
    let g = TriangleGrid::new(mesh).expect("surface");
    let d: Vec<f64> = points.iter().map(|&p| g.distance(p)).collect();
    let mean = d.iter().sum::<f64>() / d.len().max(1) as f64;
    (mean, d.iter().copied().fold(0.0, f64::max))
}

/// Median of a list.
pub fn median(xs: &[f64]) -> f64 {
    let mut v = xs.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}
