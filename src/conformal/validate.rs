//! Checks that a mesh is a clean, consistently oriented topological disk.

use super::FlattenError;
use crate::mesh::Mesh;
use std::collections::HashMap;

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

    // Directed half-edges; a repeated one means either more than two faces on
    // an edge or two faces with opposite orientation.
    let mut half: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.faces.len() * 3);
    let mut undirected: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.faces.len() * 2);
    for f in &mesh.faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            let key = (a.min(b), a.max(b));
            let c = undirected.entry(key).or_insert(0);
            *c += 1;
            if *c > 2 {
                return Err(FlattenError::NonManifold {
                    reason: format!("edge {a}-{b} is shared by more than two faces"),
                });
            }
            if half.insert((a, b), 1).is_some() {
                return Err(FlattenError::InconsistentOrientation { a, b });
            }
        }
    }

    // Boundary half-edges: those whose twin is missing.
    let mut next: HashMap<u32, u32> = HashMap::new();
    let mut boundary_edges: Vec<(u32, u32)> = half
        .keys()
        .filter(|&&(a, b)| !half.contains_key(&(b, a)))
        .copied()
        .collect();
    boundary_edges.sort_unstable();
    for &(a, b) in &boundary_edges {
        if next.insert(a, b).is_some() {
            return Err(FlattenError::NonManifold {
                reason: format!("boundary loops touch at vertex {a}"),
            });
        }
    }
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
            match next.get(&cur) {
                Some(&nx) => cur = nx,
                None => {
                    return Err(FlattenError::NonManifold {
                        reason: format!("boundary is not closed at vertex {cur}"),
                    })
                }
            }
        }
        if cur != start {
            return Err(FlattenError::NonManifold {
                reason: format!("boundary loop through vertex {cur} is not simple"),
            });
        }
        loops.push(lp);
    }
    let euler = n as i64 - undirected.len() as i64 + mesh.faces.len() as i64;
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
