//! Repair of non-manifold edges and vertices.

use crate::mesh::{has_directed_edge, HalfEdges, Mesh};
use crate::union_find::UnionFind;
use rustc_hash::FxHashMap;

/// Make every edge have at most two faces. On an edge with more, the first
/// face (lowest index) is kept together with the first later face that runs
/// the edge in the opposite direction (a consistently oriented neighbour),
/// or failing that the second face; the other faces on the edge are
/// dropped (fins and flaps; a hole they leave is filled later).
///
/// Returns the mesh and the number of non-manifold edges repaired.
pub(super) fn repair_nonmanifold_edges(mesh: &Mesh) -> (Mesh, usize) {
    let mut removed = vec![false; mesh.faces.len()];
    let mut repaired = 0;
    HalfEdges::new(&mesh.faces).for_each_edge(|(a, b), half_edges| {
        // Nearly every edge has two faces or fewer: no list is made for it.
        if half_edges.len() <= 2 {
            return;
        }
        let live: Vec<u32> = half_edges
            .iter()
            .map(|&(_, h)| h / 3)
            .filter(|&f| !removed[f as usize])
            .collect();
        if live.len() <= 2 {
            return;
        }
        repaired += 1;
        let first = live[0];
        let dir = has_directed_edge(mesh.faces[first as usize], a, b);
        let partner = live[1..]
            .iter()
            .copied()
            .find(|&g| has_directed_edge(mesh.faces[g as usize], a, b) != dir)
            .unwrap_or(live[1]);
        for &g in &live {
            if g != first && g != partner {
                removed[g as usize] = true;
            }
        }
    });
    let faces = mesh
        .faces
        .iter()
        .zip(&removed)
        .filter_map(|(f, &r)| (!r).then_some(*f))
        .collect();
    (Mesh::new(mesh.vertices.clone(), faces), repaired)
}

/// Split non-manifold vertices: the faces around a vertex are grouped into
/// fans (faces linked across edges that have exactly two faces); a vertex
/// with several fans keeps the first and gets one new copy per further fan.
/// Expects every edge to have at most two faces.
///
/// Returns the mesh and the number of vertices that were split.
pub(super) fn split_nonmanifold_vertices(mesh: &Mesh) -> (Mesh, usize) {
    // Corner c = 3·face + k.
    let corner = |f: u32, v: u32| -> Option<u32> {
        let fc = mesh.faces[f as usize];
        (0..3).find(|&k| fc[k] == v).map(|k| 3 * f + k as u32)
    };
    let mut uf = UnionFind::new(mesh.faces.len() * 3);
    HalfEdges::new(&mesh.faces).for_each_edge(|(a, b), half_edges| {
        let &[(_, h0), (_, h1)] = half_edges else {
            return;
        };
        let (f0, f1) = (h0 / 3, h1 / 3);
        for v in [a, b] {
            if let (Some(c0), Some(c1)) = (corner(f0, v), corner(f1, v)) {
                uf.union(c0, c1);
            }
        }
    });
    let mut vertices = mesh.vertices.clone();
    let mut faces = mesh.faces.clone();
    // The fan root that owns each vertex; corners are visited in order.
    let mut owner = vec![u32::MAX; mesh.vertices.len()];
    let mut copies: FxHashMap<u32, u32> = Default::default();
    let mut split = vec![false; mesh.vertices.len()];
    for fi in 0..faces.len() {
        for k in 0..3 {
            let v = mesh.faces[fi][k];
            let root = uf.find((3 * fi + k) as u32);
            if owner[v as usize] == u32::MAX {
                owner[v as usize] = root;
            } else if owner[v as usize] != root {
                let id = *copies.entry(root).or_insert_with(|| {
                    vertices.push(mesh.vertices[v as usize]);
                    (vertices.len() - 1) as u32
                });
                faces[fi][k] = id;
                split[v as usize] = true;
            }
        }
    }
    let count = split.iter().filter(|&&s| s).count();
    (Mesh::new(vertices, faces), count)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_face_edge_keeps_two_faces() {
        // Edge 0–1 carries three faces; the third is a fin.
        let m = Mesh::new(
            vec![
                [0., 0., 0.],
                [1., 0., 0.],
                [0.5, 1., 0.],
                [0.5, -1., 0.],
                [0.5, 0., 1.],
            ],
            vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
        );
        let (r, n) = repair_nonmanifold_edges(&m);
        assert_eq!(n, 1);
        assert_eq!(r.faces, vec![[0, 1, 2], [1, 0, 3]]);
        assert!(crate::mesh::edge_face_map(&r)
            .values()
            .all(|f| f.len() <= 2));
    }

    #[test]
    fn bowtie_vertex_is_duplicated() {
        // Two triangles touching only at vertex 0.
        let m = Mesh::new(
            vec![
                [0., 0., 0.],
                [1., 0., 0.],
                [1., 1., 0.],
                [-1., 0., 0.],
                [-1., -1., 0.],
            ],
            vec![[0, 1, 2], [0, 3, 4]],
        );
        let (s, n) = split_nonmanifold_vertices(&m);
        assert_eq!(n, 1);
        assert_eq!(s.vertices.len(), 6);
        assert_eq!(s.faces, vec![[0, 1, 2], [5, 3, 4]]);
        assert_eq!(s.vertices[5], s.vertices[0]);
        // A manifold fan is left alone.
        let fan = Mesh::new(
            vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [-1., 0., 0.]],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        assert_eq!(split_nonmanifold_vertices(&fan).1, 0);
    }
}
