//! Degenerate, duplicate and unreferenced elements.

use crate::mesh::{norm, sub, triangle_area, Mesh};
use crate::union_find::UnionFind;

/// Remove faces with a repeated vertex index and collapse zero-area faces
/// (area ≤ `area_eps`): the shortest edge of such a sliver is contracted, its
/// two vertices merged, so the neighbours close the crack instead of leaving
/// a hole. Returns the mesh and the number of faces removed.
pub(super) fn remove_degenerate_faces(mesh: &Mesh, area_eps: f64) -> (Mesh, usize) {
    let n = mesh.vertices.len();
    let mut uf = UnionFind::new(n);
    let mut collapsed = false;
    for f in &mesh.faces {
        if f[0] == f[1] || f[1] == f[2] || f[0] == f[2] {
            continue;
        }
        let p = f.map(|v| mesh.vertices[v as usize]);
        if triangle_area(p[0], p[1], p[2]) > area_eps {
            continue;
        }
        let mut best = (f64::INFINITY, 0usize);
        for k in 0..3 {
            let l = norm(sub(p[k], p[(k + 1) % 3]));
            if l < best.0 {
                best = (l, k);
            }
        }
        uf.union(f[best.1], f[(best.1 + 1) % 3]);
        collapsed = true;
    }
    let faces: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .map(|f| if collapsed { f.map(|v| uf.find(v)) } else { *f })
        .filter(|f| f[0] != f[1] && f[1] != f[2] && f[0] != f[2])
        .collect();
    let removed = mesh.faces.len() - faces.len();
    (Mesh::new(mesh.vertices.clone(), faces), removed)
}

/// Remove faces that repeat the vertex set of an earlier face (whatever
/// their orientation); the first occurrence is kept. Returns the mesh and the
/// number removed.
pub(super) fn remove_duplicate_faces(mesh: &Mesh) -> (Mesh, usize) {
    let mut keyed: Vec<([u32; 3], usize)> = mesh
        .faces
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let mut k = *f;
            k.sort_unstable();
            (k, i)
        })
        .collect();
    // Distinct: each carries its face's index.
    crate::mesh::sort_distinct(&mut keyed);
    let mut keep = vec![true; mesh.faces.len()];
    for w in keyed.windows(2) {
        if w[0].0 == w[1].0 {
            keep[w[1].1] = false;
        }
    }
    let faces: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .zip(&keep)
        .filter_map(|(f, &k)| k.then_some(*f))
        .collect();
    let removed = mesh.faces.len() - faces.len();
    (Mesh::new(mesh.vertices.clone(), faces), removed)
}

/// Drop vertices that no face uses, keeping the order of the others.
/// A point cloud (no faces) is returned unchanged.
pub(super) fn remove_unreferenced_vertices(mesh: &Mesh) -> Mesh {
    referenced_vertices(&mesh.vertices, mesh.faces.clone())
}

/// The mesh of `faces` over those of `vertices` they use, in their order
/// ([`remove_unreferenced_vertices`] without first copying every vertex
/// into a mesh: decimation keeps a few of millions). Without faces, all
/// vertices (a point cloud).
pub(super) fn referenced_vertices(vertices: &[[f64; 3]], mut faces: Vec<[u32; 3]>) -> Mesh {
    if faces.is_empty() {
        return Mesh::new(vertices.to_vec(), faces);
    }
    let mut map = vec![u32::MAX; vertices.len()];
    for f in &faces {
        for &v in f {
            map[v as usize] = 0;
        }
    }
    let mut kept = Vec::new();
    for (i, m) in map.iter_mut().enumerate() {
        if *m == 0 {
            *m = kept.len() as u32;
            kept.push(vertices[i]);
        }
    }
    for f in &mut faces {
        *f = f.map(|v| map[v as usize]);
    }
    Mesh::new(kept, faces)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degenerate_and_duplicate_faces_go() {
        let m = Mesh::new(
            vec![
                [0., 0., 0.],
                [1., 0., 0.],
                [1., 1., 0.],
                [0., 1., 0.],
                [9., 9., 9.],
            ],
            vec![[0, 1, 2], [0, 2, 3], [0, 0, 1], [2, 1, 0], [0, 2, 3]],
        );
        let (m1, r1) = remove_degenerate_faces(&m, 1e-14);
        assert_eq!(r1, 1);
        let (m2, r2) = remove_duplicate_faces(&m1);
        assert_eq!(r2, 2);
        assert_eq!(m2.faces, vec![[0, 1, 2], [0, 2, 3]]);
        let m3 = remove_unreferenced_vertices(&m2);
        assert_eq!(m3.vertices.len(), 4);
    }

    #[test]
    fn collinear_sliver_is_collapsed_without_a_crack() {
        // Vertex 2 lies on edge 0–1: face [0,2,1]... the sliver [0,1,2] is
        // flat; its neighbours [0,3,1]... share the crack.
        let m = Mesh::new(
            vec![
                [0., 0., 0.],
                [2., 0., 0.],
                [1.0, 0., 0.],
                [1., 1., 0.],
                [1., -1., 0.],
            ],
            vec![[0, 1, 3], [0, 2, 1], [0, 4, 2], [2, 4, 1]],
        );
        let (c, removed) = remove_degenerate_faces(&m, 1e-14);
        assert_eq!(removed, 2);
        assert_eq!(c.faces.len(), 2);
        let e = crate::mesh::edge_face_map(&c);
        // The two remaining faces share an edge: no crack left.
        assert!(e.values().any(|fs| fs.len() == 2));
    }
}
