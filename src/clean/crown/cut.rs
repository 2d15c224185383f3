//! The cut along the margin: the crown's faces are grown from the top of
//! the tooth across edges, stopped by the crease edges near the margin
//! line (so the cut follows the actual enamel edge of the mesh, not the
//! line's discretisation) and, where the crease has gaps, by a floor a
//! little below the line. Pockets left out inside the crown are taken back.

use super::geometry::{Cylinder, SurfaceGeometry};
use super::margin::MarginLine;
use crate::mesh::{triangle_adjacency, Mesh, NO_TRIANGLE};

/// Where the growth stops.
pub(super) struct CutRule<'a> {
    pub margin: &'a MarginLine,
    pub cylinder: &'a Cylinder,
    /// Half-width of the band around the line in which crease edges stop
    /// the growth; also how far below the line the floor lies.
    pub tolerance: f64,
    /// Smallest convex turn (radians) of an edge that stops the growth.
    pub min_turn: f64,
}

/// Faces of the crown: grown from `seed` (a face at the top), see the
/// module documentation.
pub(super) fn crown_faces(
    mesh: &Mesh,
    geo: &SurfaceGeometry,
    rule: &CutRule<'_>,
    seed: usize,
) -> Vec<bool> {
    let adjacency = triangle_adjacency(&mesh.faces);
    let below_floor = |f: usize| {
        let p = geo.centroids[f];
        let (angle, _) = rule.cylinder.polar(p);
        rule.cylinder.height(p) < rule.margin.height_at(angle) - rule.tolerance
    };
    let stops = |a: u32, b: u32| {
        let Some(e) = geo.edges.find(a, b) else {
            return true;
        };
        if geo.turn[e] < rule.min_turn {
            return false;
        }
        let (pa, pb) = (mesh.vertices[a as usize], mesh.vertices[b as usize]);
        let mid = [0, 1, 2].map(|d| 0.5 * (pa[d] + pb[d]));
        let (angle, _) = rule.cylinder.polar(mid);
        (rule.cylinder.height(mid) - rule.margin.height_at(angle)).abs() <= rule.tolerance
    };
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
            let g = g as usize;
            // adjacency[f][k] lies across the edge opposite corner k.
            let (a, b) = (face[(k + 1) % 3], face[(k + 2) % 3]);
            if below_floor(g) || stops(a, b) {
                continue;
            }
            inside[g] = true;
            stack.push(g);
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
