//! Checks that a mesh is a clean, consistently oriented topological disk.

use super::FlattenError;
use crate::mesh::{boundary_loops, edge_face_map, euler_characteristic, half_edge_ends, Mesh};

/// Check that `mesh` is a clean, consistently oriented, disk-type surface
/// with at least one interior vertex, and return its boundary loop.
///
/// The loop follows the boundary half-edges, so with counter-clockwise faces
/// the surface lies to the left of it, and starts at its smallest vertex
/// (see [`boundary_loops`]).
pub fn check_disk_topology(mesh: &Mesh) -> Result<Vec<u32>, FlattenError> {
    let n = mesh.vertices.len();
    if mesh.faces.is_empty() || n == 0 {
        return Err(FlattenError::Empty);
    }
    if let Some(vertex) = mesh.first_non_finite_vertex() {
        return Err(FlattenError::NonFinite { vertex });
    }
    let mut used = vec![false; n];
    for (fi, f) in mesh.faces.iter().enumerate() {
        if f.iter().any(|&v| v as usize >= n) {
            return Err(FlattenError::InvalidFace {
                face: fi,
                reason: format!("vertex index out of range (mesh has {n} vertices)"),
            });
        }
        if f[0] == f[1] || f[1] == f[2] || f[0] == f[2] {
            return Err(FlattenError::InvalidFace {
                face: fi,
                reason: "repeated vertex".into(),
            });
        }
        for &v in f {
            used[v as usize] = true;
        }
    }
    if let Some(vertex) = used.iter().position(|&u| !u) {
        return Err(FlattenError::UnreferencedVertex { vertex });
    }

    // Half-edges grouped by undirected edge: one is a boundary edge, two
    // must run in opposite directions, more is not a manifold.
    let edges = edge_face_map(mesh);
    let mut leaves_boundary = vec![false; n];
    for e in 0..edges.len() {
        let half = edges.half_edges_of(e);
        let (a, b) = half_edge_ends(&mesh.faces, half[0]);
        match half.len() {
            1 => {
                if std::mem::replace(&mut leaves_boundary[a as usize], true) {
                    return Err(FlattenError::NonManifold {
                        reason: format!("boundary loops touch at vertex {a}"),
                    });
                }
            }
            2 => {
                if half_edge_ends(&mesh.faces, half[1]) == (a, b) {
                    return Err(FlattenError::InconsistentOrientation { a, b });
                }
            }
            _ => {
                return Err(FlattenError::NonManifold {
                    reason: format!("edge {a}-{b} is shared by more than two faces"),
                })
            }
        }
    }
    // Now every edge has one or two faces, consistently oriented, and at most
    // one boundary half-edge leaves each vertex. Around a vertex, its faces
    // bring as many half-edges in as out and interior edges pair them, so as
    // many boundary half-edges enter it as leave it: the boundary is a set
    // of disjoint simple loops.
    let mut loops = boundary_loops(mesh);
    let euler = euler_characteristic(mesh);
    if loops.len() != 1 || euler != 1 {
        return Err(FlattenError::NotDisk {
            boundary_loops: loops.len(),
            euler_characteristic: euler,
        });
    }
    // The loop starts at its smallest vertex index: independent of any
    // rigid motion of the input.
    let boundary = loops.pop().unwrap_or_default();
    if boundary.len() >= n {
        return Err(FlattenError::Degenerate {
            reason: "no interior vertex".into(),
        });
    }
    Ok(boundary)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fan(closed: bool) -> Mesh {
        // Hexagon fan around vertex 0 (a disk), optionally capped below.
        let mut v = vec![[0.0, 0.0, 0.0]];
        for k in 0..6 {
            let t = k as f64 * std::f64::consts::PI / 3.0;
            v.push([t.cos(), t.sin(), 0.0]);
        }
        let mut f: Vec<[u32; 3]> = (0..6u32).map(|k| [0, 1 + k, 1 + (k + 1) % 6]).collect();
        if closed {
            v.push([0.0, 0.0, -1.0]);
            f.extend((0..6u32).map(|k| [7, 1 + (k + 1) % 6, 1 + k]));
        }
        Mesh::new(v, f)
    }

    #[test]
    fn hexagon_fan_is_a_disk() {
        let b = check_disk_topology(&fan(false)).unwrap();
        assert_eq!(b, vec![1, 2, 3, 4, 5, 6]);
    }

    #[test]
    fn closed_surface_is_rejected() {
        assert!(matches!(
            check_disk_topology(&fan(true)),
            Err(FlattenError::NotDisk {
                boundary_loops: 0,
                euler_characteristic: 2
            })
        ));
    }

    #[test]
    fn touching_loops_and_holes_are_rejected() {
        // A second hexagon fan whose leftmost rim vertex is the first fan's
        // vertex 1 at (1, 0, 0): two disks touching at one boundary vertex.
        let mut m = fan(false);
        let centre = m.vertices.len() as u32;
        m.vertices.push([2.0, 0.0, 0.0]);
        let rim: Vec<u32> = (0..6)
            .map(|k| {
                if k == 3 {
                    return 1;
                }
                let t = k as f64 * std::f64::consts::PI / 3.0;
                m.vertices.push([2.0 + t.cos(), t.sin(), 0.0]);
                m.vertices.len() as u32 - 1
            })
            .collect();
        m.faces
            .extend((0..6).map(|k| [centre, rim[k], rim[(k + 1) % 6]]));
        assert!(matches!(
            check_disk_topology(&m),
            Err(FlattenError::NonManifold { reason }) if reason.contains("touch at vertex 1")
        ));
        // An annulus between two hexagons: two loops, χ = 0.
        let mut v = vec![];
        let mut f = vec![];
        for ring in 0..2u32 {
            for k in 0..6u32 {
                let t = k as f64 * std::f64::consts::PI / 3.0;
                let r = 1.0 + ring as f64;
                v.push([r * t.cos(), r * t.sin(), 0.0]);
                let (a, b) = (k, (k + 1) % 6);
                if ring == 0 {
                    f.push([a, a + 6, b + 6]);
                    f.push([a, b + 6, b]);
                }
            }
        }
        assert_eq!(
            check_disk_topology(&Mesh::new(v, f)),
            Err(FlattenError::NotDisk {
                boundary_loops: 2,
                euler_characteristic: 0
            })
        );
    }

    #[test]
    fn inconsistent_orientation_is_rejected() {
        let mut m = fan(false);
        m.faces[2] = [m.faces[2][0], m.faces[2][2], m.faces[2][1]];
        assert!(matches!(
            check_disk_topology(&m),
            Err(FlattenError::InconsistentOrientation { .. })
        ));
    }

    #[test]
    fn bad_indices_and_values_are_rejected() {
        let mut m = fan(false);
        m.faces[0][1] = 99;
        assert!(matches!(
            check_disk_topology(&m),
            Err(FlattenError::InvalidFace { face: 0, .. })
        ));
        let mut m = fan(false);
        m.vertices[3][1] = f64::NAN;
        assert!(matches!(
            check_disk_topology(&m),
            Err(FlattenError::NonFinite { vertex: 3 })
        ));
        let mut m = fan(false);
        m.vertices.push([5.0, 5.0, 5.0]);
        assert!(matches!(
            check_disk_topology(&m),
            Err(FlattenError::UnreferencedVertex { vertex: 7 })
        ));
        assert_eq!(
            check_disk_topology(&Mesh::default()),
            Err(FlattenError::Empty)
        );
    }
}
