//! Connected components.

use crate::mesh::{face_areas, Mesh};
use crate::union_find::UnionFind;

/// Label of the connected component (faces linked through shared vertices)
/// of every face, labels numbered 0.. in order of each component's first
/// face. Returns `(labels, count)`.
pub(super) fn face_components(mesh: &Mesh) -> (Vec<u32>, usize) {
    let mut uf = UnionFind::new(mesh.vertices.len());
    for f in &mesh.faces {
        uf.union(f[0], f[1]);
        uf.union(f[1], f[2]);
    }
    let mut label_of_root = vec![u32::MAX; mesh.vertices.len()];
    let mut count = 0u32;
    let labels = mesh
        .faces
        .iter()
        .map(|f| {
            let r = uf.find(f[0]) as usize;
            if label_of_root[r] == u32::MAX {
                label_of_root[r] = count;
                count += 1;
            }
            label_of_root[r]
        })
        .collect();
    (labels, count as usize)
}

/// `mesh` without its closed components (those in which every edge has a
/// triangle on each side); unreferenced vertices dropped.
pub(super) fn without_closed_components(mesh: Mesh) -> Mesh {
    let (labels, count) = face_components(&mesh);
    if count < 2 {
        return mesh;
    }
    // A component is open where one of its faces has no triangle across
    // an edge.
    let mut open = vec![false; count];
    for (across, &l) in crate::mesh::triangle_adjacency(&mesh.faces)
        .iter()
        .zip(&labels)
    {
        if across.contains(&crate::mesh::NO_TRIANGLE) {
            open[l as usize] = true;
        }
    }
    let faces: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .zip(&labels)
        .filter_map(|(f, &l)| open[l as usize].then_some(*f))
        .collect();
    super::faces::remove_unreferenced_vertices(&Mesh::new(mesh.vertices, faces))
}

/// Keep the connected component of largest area (ties: the one met first);
/// unreferenced vertices are left for the caller to drop. Returns the mesh
/// and the number of components dropped.
pub(crate) fn largest_component_by_area(mesh: &Mesh) -> (Mesh, usize) {
    let (labels, count) = face_components(mesh);
    if count <= 1 {
        return (mesh.clone(), 0);
    }
    let mut area = vec![0.0; count];
    for (l, a) in labels.iter().zip(face_areas(mesh)) {
        area[*l as usize] += a;
    }
    let mut best = 0usize;
    for (i, &a) in area.iter().enumerate() {
        if a > area[best] {
            best = i;
        }
    }
    let faces = mesh
        .faces
        .iter()
        .zip(&labels)
        .filter_map(|(f, &l)| (l as usize == best).then_some(*f))
        .collect();
    (Mesh::new(mesh.vertices.clone(), faces), count - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn debris_is_dropped() {
        let m = Mesh::new(
            vec![
                [0., 0., 0.],
                [1., 0., 0.],
                [0., 1., 0.],
                [5., 5., 5.],
                [5.1, 5., 5.],
                [5., 5.1, 5.],
                [1., 1., 0.],
            ],
            vec![[3, 4, 5], [0, 1, 2], [1, 6, 2]],
        );
        let (labels, n) = face_components(&m);
        assert_eq!((labels, n), (vec![0, 1, 1], 2));
        let (k, dropped) = largest_component_by_area(&m);
        assert_eq!(dropped, 1);
        assert_eq!(k.faces, vec![[0, 1, 2], [1, 6, 2]]);
    }
}
