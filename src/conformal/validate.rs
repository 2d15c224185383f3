//! Checks that a mesh is a clean, consistently oriented topological disk.

use super::laplacian::half_edges_by_edge;
use super::FlattenError;
use crate::mesh::Mesh;

/// Check that `mesh` is a clean, consistently oriented, disk-type surface
/// with at least one interior vertex, and return its boundary loop.
///
/// The loop follows the boundary half-edges, so with counter-clockwise faces
/// the surface lies to the left of it.
pub fn check_disk_topology(mesh: &Mesh) -> Result<Vec<u32>, FlattenError> {
    let n = mesh.vertices.len();
    if mesh.faces.is_empty() || n == 0 {
        return Err(FlattenError::Empty);
    }
    if let Some(vertex) = mesh
        .vertices
        .iter()
        .position(|p| p.iter().any(|c| !c.is_finite()))
    {
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
    let half = half_edges_by_edge(&mesh.faces);
    let ends = |h: u32| {
        let (f, k) = (h as usize / 3, h as usize % 3);
        let face = mesh.faces[f];
        (face[k], face[(k + 1) % 3])
    };
    let mut next = vec![u32::MAX; n];
    let mut boundary_edges: Vec<(u32, u32)> = Vec::new();
    let mut edge_count = 0usize;
    let mut i = 0;
    while i < half.len() {
        let mut j = i + 1;
        while j < half.len() && half[j].0 == half[i].0 {
            j += 1;
        }
        edge_count += 1;
        let (a, b) = ends(half[i].1);
        match j - i {
            1 => {
                if next[a as usize] != u32::MAX {
                    return Err(FlattenError::NonManifold {
                        reason: format!("boundary loops touch at vertex {a}"),
                    });
                }
                next[a as usize] = b;
                boundary_edges.push((a, b));
            }
            2 => {
                if ends(half[i + 1].1) == (a, b) {
                    return Err(FlattenError::InconsistentOrientation { a, b });
                }
            }
            _ => {
                return Err(FlattenError::NonManifold {
                    reason: format!("edge {a}-{b} is shared by more than two faces"),
                })
            }
        }
        i = j;
    }
    boundary_edges.sort_unstable();
    let mut loops: Vec<Vec<u32>> = Vec::new();
    let mut visited = vec![false; n];
    for &(start, _) in &boundary_edges {
        if visited[start as usize] {
            continue;
        }
        let mut lp = Vec::new();
        let mut cur = start;
        loop {
            if std::mem::replace(&mut visited[cur as usize], true) {
                break;
            }
            lp.push(cur);
            match next[cur as usize] {
                u32::MAX => {
                    return Err(FlattenError::NonManifold {
                        reason: format!("boundary is not closed at vertex {cur}"),
                    })
                }
                nx => cur = nx,
            }
        }
        if cur != start {
            return Err(FlattenError::NonManifold {
                reason: format!("boundary loop through vertex {cur} is not simple"),
            });
        }
        loops.push(lp);
    }
    let euler = n as i64 - edge_count as i64 + mesh.faces.len() as i64;
    if loops.len() != 1 || euler != 1 {
        return Err(FlattenError::NotDisk {
            boundary_loops: loops.len(),
            euler_characteristic: euler,
        });
    }
    let boundary = loops.pop().unwrap_or_default();
    if boundary.len() >= n {
        return Err(FlattenError::Degenerate {
            reason: "no interior vertex".into(),
        });
    }
    // Start the loop at its smallest vertex index: independent of hashing and
    // of any rigid motion of the input.
    let start = boundary
        .iter()
        .enumerate()
        .min_by_key(|&(_, &v)| v)
        .map_or(0, |(i, _)| i);
    let mut rotated = boundary[start..].to_vec();
    rotated.extend_from_slice(&boundary[..start]);
    Ok(rotated)
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
