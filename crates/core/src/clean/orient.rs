//! Consistent face orientation and the choice of the outward side.

use crate::mesh::{
    dot, edge_face_map, has_directed_edge, reversed_winding, triangle_normal2, Mesh,
};
use std::collections::VecDeque;

/// Orientation could not be made consistent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct NonOrientable;

/// Make the orientation of the faces consistent: a breadth-first search over
/// faces linked by two-face edges decides for each face whether it must be
/// reversed so that neighbours run their shared edge in opposite directions.
/// Within each connected piece the smaller set of faces is reversed (so a
/// consistent input is left untouched).
///
/// Returns the mesh and the number of faces reversed, or [`NonOrientable`]
/// for a Möbius-type surface.
pub(super) fn orient_faces_consistently(mesh: &Mesh) -> Result<(Mesh, usize), NonOrientable> {
    let n = mesh.faces.len();
    let ef = edge_face_map(mesh);
    // Neighbour lists as (face, same_direction) via each face's edges.
    // At most three neighbours per face (one per edge).
    let mut nbrs: Vec<[(u32, bool); 3]> = vec![[(u32::MAX, false); 3]; n];
    let mut push = |f: u32, g: u32, same: bool| {
        if let Some(slot) = nbrs[f as usize].iter_mut().find(|s| s.0 == u32::MAX) {
            *slot = (g, same);
        }
    };
    for e in 0..ef.len() {
        let fs = ef.faces_of(e);
        if fs.len() != 2 {
            continue;
        }
        let (a, b) = ef.edge(e);
        let d0 = has_directed_edge(mesh.faces[fs[0] as usize], a, b);
        let d1 = has_directed_edge(mesh.faces[fs[1] as usize], a, b);
        let same = d0 == d1;
        push(fs[0], fs[1], same);
        push(fs[1], fs[0], same);
    }
    let mut flip: Vec<Option<bool>> = vec![None; n];
    let mut faces = mesh.faces.clone();
    let mut reversed = 0;
    let mut queue = VecDeque::new();
    for seed in 0..n {
        if flip[seed].is_some() {
            continue;
        }
        flip[seed] = Some(false);
        queue.push_back(seed as u32);
        let mut piece = vec![seed as u32];
        while let Some(f) = queue.pop_front() {
            let ff = flip[f as usize].unwrap_or(false);
            for &(g, same) in nbrs[f as usize].iter().filter(|s| s.0 != u32::MAX) {
                let want = ff ^ same;
                match flip[g as usize] {
                    None => {
                        flip[g as usize] = Some(want);
                        piece.push(g);
                        queue.push_back(g);
                    }
                    Some(h) if h != want => return Err(NonOrientable),
                    Some(_) => {}
                }
            }
        }
        let k = piece
            .iter()
            .filter(|&&f| flip[f as usize] == Some(true))
            .count();
        let invert = 2 * k > piece.len();
        for &f in &piece {
            if (flip[f as usize] == Some(true)) != invert {
                let t = &mut faces[f as usize];
                t.swap(1, 2);
                reversed += 1;
            }
        }
    }
    Ok((Mesh::new(mesh.vertices.clone(), faces), reversed))
}

/// The faces of `mesh` less those where a breadth-first orientation of
/// the faces meets a contradiction (both faces of each such edge): a
/// surface that decimation folded (two walls of a narrow tunnel collapsed
/// into a twisted strip) is cut open there, and the slit is filled like
/// any hole later. Returns the mesh and the number of faces dropped; a
/// consistent surface is returned whole.
pub(super) fn drop_orientation_conflicts(mesh: &Mesh) -> (Mesh, usize) {
    let n = mesh.faces.len();
    let ef = edge_face_map(mesh);
    let mut nbrs: Vec<Vec<(u32, bool)>> = vec![Vec::new(); n];
    for e in 0..ef.len() {
        let fs = ef.faces_of(e);
        if fs.len() != 2 {
            continue;
        }
        let (a, b) = ef.edge(e);
        let same = has_directed_edge(mesh.faces[fs[0] as usize], a, b)
            == has_directed_edge(mesh.faces[fs[1] as usize], a, b);
        nbrs[fs[0] as usize].push((fs[1], same));
        nbrs[fs[1] as usize].push((fs[0], same));
    }
    let mut flip: Vec<Option<bool>> = vec![None; n];
    let mut dropped = vec![false; n];
    let mut queue = VecDeque::new();
    for seed in 0..n {
        if flip[seed].is_some() {
            continue;
        }
        flip[seed] = Some(false);
        queue.push_back(seed);
        while let Some(f) = queue.pop_front() {
            if dropped[f] {
                continue;
            }
            let ff = flip[f].unwrap_or(false);
            for &(g, same) in &nbrs[f] {
                let g = g as usize;
                if dropped[g] {
                    continue;
                }
                let want = ff ^ same;
                match flip[g] {
                    None => {
                        flip[g] = Some(want);
                        queue.push_back(g);
                    }
                    Some(h) if h != want => {
                        dropped[f] = true;
                        dropped[g] = true;
                        break;
                    }
                    Some(_) => {}
                }
            }
        }
    }
    let count = dropped.iter().filter(|&&d| d).count();
    let faces = mesh
        .faces
        .iter()
        .zip(&dropped)
        .filter_map(|(f, &d)| (!d).then_some(*f))
        .collect();
    (Mesh::new(mesh.vertices.clone(), faces), count)
}

/// Reverse every face.
pub(super) fn reverse_faces(mesh: &Mesh) -> Mesh {
    Mesh::new(mesh.vertices.clone(), reversed_winding(&mesh.faces))
}

/// Orientation test of a consistently oriented surface with boundary
/// `boundary` (a vertex loop): `true` when the vector area Σ n·A points from
/// the centroid of the boundary loop towards the area centroid of the
/// surface, i.e. the normals point to the convex ("outer") side of a dome
/// such as a tooth crown with its cervical margin as boundary (`true` too
/// when the surface is flat to rounding: nothing to decide). The test is
/// invariant under rigid motions, scaling and mirroring (a mirrored input
/// yields the mirrored output with outward normals again).
pub(super) fn normals_point_outward(mesh: &Mesh, boundary: &[u32]) -> bool {
    let mut vector_area = [0.0; 3];
    let mut centroid = [0.0; 3];
    let mut area = 0.0;
    for f in &mesh.faces {
        let p = f.map(|v| mesh.vertices[v as usize]);
        let n2 = triangle_normal2(p[0], p[1], p[2]);
        let a = 0.5 * dot(n2, n2).sqrt();
        for d in 0..3 {
            vector_area[d] += 0.5 * n2[d];
            centroid[d] += a * (p[0][d] + p[1][d] + p[2][d]) / 3.0;
        }
        area += a;
    }
    if area <= 0.0 || boundary.is_empty() {
        return true;
    }
    let mut bc = [0.0; 3];
    for &v in boundary {
        for d in 0..3 {
            bc[d] += mesh.vertices[v as usize][d] / boundary.len() as f64;
        }
    }
    let offset = [0, 1, 2].map(|d| centroid[d] / area - bc[d]);
    // A flat (or perfectly balanced) surface has no outer side: keep the
    // orientation it has rather than follow rounding noise.
    let scale = area * crate::mesh::bbox_diagonal(mesh);
    let s = dot(vector_area, offset);
    s >= 0.0 || s.abs() <= 1e-9 * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn opposite_winding_is_made_consistent() {
        let v = vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
        // Face 0 runs the shared edge 2 → 0, face 1 runs 0 → 2: consistent.
        let good = Mesh::new(v.clone(), vec![[0, 1, 2], [2, 3, 0]]);
        assert_eq!(orient_faces_consistently(&good).map(|r| r.1), Ok(0));
        // Both faces run the shared edge 2 → 0: one must be reversed.
        let bad = Mesh::new(v, vec![[0, 1, 2], [2, 0, 3]]);
        assert!(has_directed_edge(bad.faces[1], 2, 0));
        let (fixed, n) = orient_faces_consistently(&bad).expect("orientable");
        assert_eq!(n, 1);
        assert_eq!(fixed.faces[0], [0, 1, 2]);
        assert!(has_directed_edge(fixed.faces[1], 0, 2));
    }

    #[test]
    fn mobius_strip_is_rejected() {
        let k = 6;
        let mut v = Vec::new();
        for i in 0..k {
            let t = i as f64 / k as f64 * std::f64::consts::TAU;
            let (c, s) = ((t / 2.0).cos(), (t / 2.0).sin());
            for w in [-0.3, 0.3] {
                v.push([(1.0 + w * c) * t.cos(), (1.0 + w * c) * t.sin(), w * s]);
            }
        }
        let mut f = Vec::new();
        for i in 0..k as u32 {
            let (a, b) = (2 * i, 2 * i + 1);
            let (c, d) = if i + 1 == k as u32 {
                (1, 0)
            } else {
                (2 * i + 2, 2 * i + 3)
            };
            f.push([a, c, b]);
            f.push([b, c, d]);
        }
        assert_eq!(
            orient_faces_consistently(&Mesh::new(v, f)),
            Err(NonOrientable)
        );
    }

    #[test]
    fn dome_normals_point_outward() {
        // A square pyramid without base: boundary at z = 0, apex up.
        let m = Mesh::new(
            vec![
                [0., 0., 0.],
                [1., 0., 0.],
                [1., 1., 0.],
                [0., 1., 0.],
                [0.5, 0.5, 1.],
            ],
            vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]],
        );
        assert!(normals_point_outward(&m, &[0, 1, 2, 3]));
        assert!(!normals_point_outward(&reverse_faces(&m), &[0, 3, 2, 1]));
    }
}
