//! Midpoint subdivision.

use super::{edge_face_map, Mesh};

/// Midpoint subdivision, `levels` times: every edge gets a vertex at its
/// midpoint and every triangle becomes four, so each level multiplies the
/// face count by 4. The surface (as a point set) and the orientation are
/// unchanged; the original vertices keep their indices and the new ones
/// follow in the order of their (sorted) edges.
pub fn subdivide_midpoint(mesh: &Mesh, levels: u32) -> Mesh {
    let mut m = mesh.clone();
    for _ in 0..levels {
        m = subdivide_once(&m);
    }
    m
}

/// One level of [`subdivide_midpoint`].
fn subdivide_once(mesh: &Mesh) -> Mesh {
    let edges = edge_face_map(mesh);
    let base = mesh.vertices.len() as u32;
    let mut vertices = mesh.vertices.clone();
    for &(a, b) in edges.edges() {
        let (p, q) = (mesh.vertices[a as usize], mesh.vertices[b as usize]);
        vertices.push([0, 1, 2].map(|d| 0.5 * (p[d] + q[d])));
    }
    // Every face edge is in the map, so the lookup cannot miss.
    let mid = |a: u32, b: u32| base + edges.find(a, b).unwrap_or(0) as u32;
    let mut faces = Vec::with_capacity(mesh.faces.len() * 4);
    for f in &mesh.faces {
        let (ab, bc, ca) = (mid(f[0], f[1]), mid(f[1], f[2]), mid(f[2], f[0]));
        faces.push([f[0], ab, ca]);
        faces.push([ab, f[1], bc]);
        faces.push([ca, bc, f[2]]);
        faces.push([ab, bc, ca]);
    }
    Mesh::new(vertices, faces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{boundary_loops, euler_characteristic, surface_area, unit_disk};

    use crate::testing::synth::square_grid as grid;

    #[test]
    fn one_level_splits_every_edge_and_keeps_area_and_topology() {
        let m = grid(3);
        let s = subdivide_midpoint(&m, 1);
        assert_eq!(s.faces.len(), 4 * m.faces.len());
        // 16 vertices and 33 edges.
        assert_eq!(s.vertices.len(), 49);
        assert!((surface_area(&s) - surface_area(&m)).abs() < 1e-12);
        assert_eq!(euler_characteristic(&s), 1);
        // The first edge (0, 1) gets the first new vertex.
        assert_eq!(s.vertices[16], [0.5, 0.0, 0.0]);
        assert_eq!(subdivide_midpoint(&m, 0), m);
    }

    #[test]
    fn two_levels_quadruple_twice_and_keep_a_disk() {
        let m = unit_disk(100);
        let s = subdivide_midpoint(&m, 2);
        assert_eq!(s.faces.len(), 16 * m.faces.len());
        assert_eq!(euler_characteristic(&s), 1);
        assert_eq!(boundary_loops(&s).len(), 1);
        assert!((surface_area(&s) - surface_area(&m)).abs() < 1e-12);
        assert_eq!(&s.vertices[..m.vertices.len()], &m.vertices[..]);
        assert_eq!(s, subdivide_midpoint(&subdivide_midpoint(&m, 1), 1));
    }
}
