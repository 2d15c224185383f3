//! Edge-based topology: boundary loops and the Euler characteristic.

use super::Mesh;
use std::collections::HashMap;

/// An undirected edge, smaller index first.
pub type EdgeKey = (u32, u32);

/// Normalized key of the edge `a`–`b`.
#[inline]
fn edge_key(a: u32, b: u32) -> EdgeKey {
    if a < b {
        (a, b)
    } else {
        (b, a)
    }
}

/// Map from each undirected edge to the faces that contain it.
pub fn edge_face_map(mesh: &Mesh) -> HashMap<EdgeKey, Vec<u32>> {
    let mut map: HashMap<EdgeKey, Vec<u32>> = HashMap::with_capacity(mesh.faces.len() * 3 / 2);
    for (fi, f) in mesh.faces.iter().enumerate() {
        for k in 0..3 {
            map.entry(edge_key(f[k], f[(k + 1) % 3]))
                .or_default()
                .push(fi as u32);
        }
    }
    map
}

/// Boundary loops of a manifold, consistently oriented mesh: each loop is the
/// ordered list of vertices along the boundary, following the direction of
/// the boundary half-edges. Loops are sorted longest first.
///
/// On a non-manifold boundary (a vertex where two loops touch) the walk still
/// terminates; the loops then share that vertex.
pub fn boundary_loops(mesh: &Mesh) -> Vec<Vec<u32>> {
    let edges = edge_face_map(mesh);
    // Directed boundary half-edges: from -> list of to.
    let mut next: HashMap<u32, Vec<u32>> = HashMap::new();
    let mut count = 0usize;
    for f in &mesh.faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            if edges.get(&edge_key(a, b)).map_or(0, |v| v.len()) == 1 {
                next.entry(a).or_default().push(b);
                count += 1;
            }
        }
    }
    let mut loops = Vec::new();
    let mut used = 0usize;
    let mut starts: Vec<u32> = next.keys().copied().collect();
    starts.sort_unstable();
    for s in starts {
        while next.get(&s).is_some_and(|v| !v.is_empty()) {
            let mut lp = vec![s];
            let mut cur = s;
            while let Some(n) = next.get_mut(&cur).and_then(|v| v.pop()) {
                used += 1;
                if n == s {
                    break;
                }
                lp.push(n);
                cur = n;
                if used > count {
                    break;
                }
            }
            loops.push(lp);
        }
    }
    loops.sort_by_key(|l| std::cmp::Reverse(l.len()));
    loops
}

/// Euler characteristic V − E + F, counting only vertices used by a face.
pub fn euler_characteristic(mesh: &Mesh) -> i64 {
    let mut used = vec![false; mesh.vertices.len()];
    for f in &mesh.faces {
        for &v in f {
            if let Some(u) = used.get_mut(v as usize) {
                *u = true;
            }
        }
    }
    let v = used.iter().filter(|&&u| u).count() as i64;
    let e = edge_face_map(mesh).len() as i64;
    v - e + mesh.faces.len() as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Mesh {
        // Two triangles forming a unit square: a disk.
        Mesh::new(
            vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    #[test]
    fn square_is_a_disk() {
        let m = square();
        assert_eq!(euler_characteristic(&m), 1);
        let loops = boundary_loops(&m);
        assert_eq!(loops.len(), 1);
        assert_eq!(loops[0].len(), 4);
    }

    #[test]
    fn tetrahedron_is_closed() {
        let m = Mesh::new(
            vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]],
            vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
        );
        assert_eq!(euler_characteristic(&m), 2);
        assert!(boundary_loops(&m).is_empty());
    }
}
