//! The cut along the margin loop: the faces on one side of it, grown from
//! a face across every edge that is not on the loop. Pockets left out
//! inside the crown are taken back.

use super::geometry::SurfaceGeometry;
use crate::mesh::{triangle_adjacency, Mesh, NO_TRIANGLE};

/// Faces of the part of the surface that holds `seed`, bounded by the
/// `cut` edges (vertex pairs in either order). Pockets left out inside it
/// are taken back.
pub(super) fn faces_bounded_by(
    mesh: &Mesh,
    geo: &SurfaceGeometry,
    cut: &std::collections::HashSet<(u32, u32)>,
    seed: usize,
) -> Vec<bool> {
    let adjacency = triangle_adjacency(&mesh.faces);
    let mut inside = vec![false; mesh.faces.len()];
    let mut stack = vec![seed];
    inside[seed] = true;
    while let Some(f) = stack.pop() {
        let face = mesh.faces[f];
        for k in 0..3 {
            let g = adjacency[f][k];
            if g == NO_TRIANGLE || inside[g as usize] {
                continue;
            }
            // adjacency[f][k] lies across the edge opposite corner k.
            let (a, b) = (face[(k + 1) % 3], face[(k + 2) % 3]);
            if cut.contains(&(a.min(b), a.max(b))) {
                continue;
            }
            inside[g as usize] = true;
            stack.push(g as usize);
        }
    }
    take_back_pockets(&adjacency, &mut inside, geo);
    inside
}

/// Components of the faces left out other than the largest one (the roots)
/// are pockets inside the crown: added to it.
fn take_back_pockets(adjacency: &[[u32; 3]], inside: &mut [bool], geo: &SurfaceGeometry) {
    let n = inside.len();
    let mut label = vec![u32::MAX; n];
    let mut areas: Vec<f64> = Vec::new();
    for s in 0..n {
        if inside[s] || label[s] != u32::MAX {
            continue;
        }
        let id = areas.len() as u32;
        let mut area = 0.0;
        let mut stack = vec![s];
        label[s] = id;
        while let Some(f) = stack.pop() {
            area += geo.areas[f];
            for &g in &adjacency[f] {
                if g != NO_TRIANGLE && !inside[g as usize] && label[g as usize] == u32::MAX {
                    label[g as usize] = id;
                    stack.push(g as usize);
                }
            }
        }
        areas.push(area);
    }
    let Some(roots) = (0..areas.len()).max_by(|&a, &b| areas[a].total_cmp(&areas[b])) else {
        return;
    };
    for f in 0..n {
        if !inside[f] && label[f] != roots as u32 {
            inside[f] = true;
        }
    }
}
