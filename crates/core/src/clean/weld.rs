//! Welding of duplicate vertices.

use crate::mesh::{sub, Mesh};
use rustc_hash::FxHashMap as HashMap;

/// Width of a grid cell in tolerances.
const WELD_CELL: f64 = 8.0;

/// End of a grid cell's list.
const NONE: u32 = u32::MAX;

/// Merge vertices closer than `tolerance` (Euclidean), scanning vertices in
/// order: each vertex maps to the first earlier kept vertex within the
/// tolerance, found through a hash grid of cells a few tolerances
/// wide. A tolerance ≤ 0 merges only identical positions.
///
/// Returns the welded mesh (unreferenced vertices kept; faces remapped) and
/// the number of vertices merged away.
pub(super) fn weld_vertices(mesh: &Mesh, tolerance: f64) -> (Mesh, usize) {
    // Cells WELD_CELL tolerances wide: every vertex within the tolerance
    // of a point lies in the point's cell or, along an axis where the
    // point is within the tolerance of its cell's side, the neighbour on
    // that side. Most points are far from their cell's sides, so one or two
    // cells are searched per point instead of twenty-seven; the kept
    // vertices in a cell are more than the tolerance apart, so a cell holds
    // at most about WELD_CELL³ of them whatever the input.
    let cell = if tolerance > 0.0 {
        WELD_CELL * tolerance
    } else {
        0.0
    };
    // Each grid cell holds a linked list of kept vertices (`first` in the
    // cell, then `next`): one small map entry per cell instead of a vector
    // per cell, which matters for surfaces of millions of vertices.
    let mut first: HashMap<[i64; 3], u32> = HashMap::default();
    let mut next: Vec<u32> = Vec::new();
    let mut exact: HashMap<[u64; 3], u32> = HashMap::default();
    let mut remap = Vec::with_capacity(mesh.vertices.len());
    let mut kept: Vec<[f64; 3]> = Vec::new();
    let tol2 = tolerance * tolerance;
    let reach = 1.0 / WELD_CELL;
    for &p in &mesh.vertices {
        let target = if cell > 0.0 {
            let scaled = p.map(|x| x / cell);
            let key = scaled.map(|x| x.floor() as i64);
            // Per axis the neighbour offsets to search: 0, and -1 or +1 near a side.
            let offsets = [0, 1, 2].map(|d| {
                let f = scaled[d] - scaled[d].floor();
                if f <= reach {
                    [0, -1]
                } else if f >= 1.0 - reach {
                    [0, 1]
                } else {
                    [0, 0]
                }
            });
            let mut found: Option<u32> = None;
            for corner in 0..8usize {
                let pick = [0, 1, 2].map(|d| offsets[d][corner >> d & 1]);
                // Offsets repeat when an axis has only the cell itself.
                if (0..3).any(|d| corner >> d & 1 == 1 && offsets[d][1] == 0) {
                    continue;
                }
                let k = [0, 1, 2].map(|d| key[d] + pick[d]);
                let mut q = first.get(&k).copied().unwrap_or(NONE);
                while q != NONE {
                    let d = sub(kept[q as usize], p);
                    if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= tol2
                        && found.is_none_or(|f| q < f)
                    {
                        found = Some(q);
                    }
                    q = next[q as usize];
                }
            }
            match found {
                Some(q) => q,
                None => {
                    let id = kept.len() as u32;
                    kept.push(p);
                    let head = first.entry(key).or_insert(NONE);
                    next.push(*head);
                    *head = id;
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

    /// The definition, by brute force: each vertex maps to the first
    /// earlier kept vertex within the tolerance.
    fn weld_by_brute_force(points: &[[f64; 3]], tolerance: f64) -> Vec<[f64; 3]> {
        let mut kept: Vec<[f64; 3]> = Vec::new();
        for &p in points {
            let near = kept.iter().any(|&q| {
                let d = sub(q, p);
                d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= tolerance * tolerance
            });
            if !near {
                kept.push(p);
            }
        }
        kept
    }

    #[test]
    fn the_grid_finds_every_vertex_within_the_tolerance_across_cell_sides() {
        use rand::{Rng, SeedableRng};
        // Clusters of points within a few tolerances of each other, placed
        // at random against the grid, so that pairs straddle cell sides
        // and corners along every axis.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let tol = 1e-3;
        let mut points = Vec::new();
        for _ in 0..400 {
            let c: [f64; 3] = [0, 1, 2].map(|_| rng.gen_range(-1.0..1.0));
            for _ in 0..rng.gen_range(1..6) {
                points.push(c.map(|x| x + rng.gen_range(-1.5 * tol..1.5 * tol)));
            }
        }
        let mesh = Mesh::new(points.clone(), Vec::new());
        let (w, merged) = weld_vertices(&mesh, tol);
        let expected = weld_by_brute_force(&points, tol);
        assert_eq!(w.vertices, expected);
        assert_eq!(merged, points.len() - expected.len());
        assert!(merged > 100, "the clusters should merge: {merged}");
    }
}
