//! Welding of duplicate vertices.

use crate::mesh::{sub, Mesh};
use rustc_hash::FxHashMap as HashMap;

/// Merge vertices closer than `tolerance` (Euclidean), scanning vertices in
/// order: each vertex maps to the first earlier kept vertex within the
/// tolerance, found through a hash grid of cell size `tolerance` (27
/// neighbouring cells). A tolerance ≤ 0 merges only identical positions.
///
/// Returns the welded mesh (unreferenced vertices kept; faces remapped) and
/// the number of vertices merged away.
pub fn weld_vertices(mesh: &Mesh, tolerance: f64) -> (Mesh, usize) {
    let cell = if tolerance > 0.0 { tolerance } else { 0.0 };
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::default();
    let mut exact: HashMap<[u64; 3], u32> = HashMap::default();
    let mut remap = Vec::with_capacity(mesh.vertices.len());
    let mut kept: Vec<[f64; 3]> = Vec::with_capacity(mesh.vertices.len());
    let tol2 = tolerance * tolerance;
    for &p in &mesh.vertices {
        let target = if cell > 0.0 {
            let key = p.map(|x| (x / cell).floor() as i64);
            let mut found: Option<u32> = None;
            for di in -1..=1 {
                for dj in -1..=1 {
                    for dk in -1..=1 {
                        let k = [key[0] + di, key[1] + dj, key[2] + dk];
                        if let Some(list) = grid.get(&k) {
                            for &q in list {
                                let d = sub(kept[q as usize], p);
                                if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= tol2
                                    && found.is_none_or(|f| q < f)
                                {
                                    found = Some(q);
                                }
                            }
                        }
                    }
                }
            }
            match found {
                Some(q) => q,
                None => {
                    let id = kept.len() as u32;
                    kept.push(p);
                    grid.entry(key).or_default().push(id);
                    id
                }
            }
        } else {
            let bits = p.map(|x| if x == 0.0 { 0u64 } else { x.to_bits() });
            *exact.entry(bits).or_insert_with(|| {
                kept.push(p);
                (kept.len() - 1) as u32
            })
        };
        remap.push(target);
    }
    let merged = mesh.vertices.len() - kept.len();
    let faces = mesh
        .faces
        .iter()
        .map(|f| f.map(|v| remap.get(v as usize).copied().unwrap_or(v)))
        .collect();
    (Mesh::new(kept, faces), merged)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn soup_of_two_triangles_welds_to_four_vertices() {
        let m = Mesh::new(
            vec![
                [0., 0., 0.],
                [1., 0., 0.],
                [1., 1., 0.],
                [0., 0., 1e-9],
                [1., 1., 0.],
                [0., 1., 0.],
            ],
            vec![[0, 1, 2], [3, 4, 5]],
        );
        let (w, merged) = weld_vertices(&m, 1e-6);
        assert_eq!(merged, 2);
        assert_eq!(w.vertices.len(), 4);
        assert_eq!(w.faces, vec![[0, 1, 2], [0, 2, 3]]);
        // Far-apart points are never merged.
        let (w, merged) = weld_vertices(&m, 0.0);
        assert_eq!(merged, 1);
        assert_eq!(w.vertices.len(), 5);
    }
}
