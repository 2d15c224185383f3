//! Normals by local plane fitting (principal component analysis over the
//! nearest neighbours) and their consistent orientation by propagation
//! along a minimum spanning tree of the neighbourhood graph.

use crate::mesh::{dot, principal_axes, sub};
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// The least-squares plane of a few points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct LocalPlane {
    /// Mean of the points.
    pub centroid: [f64; 3],
    /// Unit normal: the direction of least spread (sign arbitrary).
    pub normal: [f64; 3],
    /// Root-mean-square distance of the points from the plane.
    pub residual: f64,
}

/// The least-squares plane of `points` (`None` for fewer than three).
pub(super) fn local_plane(points: &[[f64; 3]]) -> Option<LocalPlane> {
    let axes = principal_axes(points)?;
    Some(LocalPlane {
        centroid: axes.centroid,
        normal: axes.axes[2],
        residual: axes.spreads[2].sqrt(),
    })
}

/// Signed distance of `p` from a plane, positive on the normal's side.
pub(super) fn plane_distance(plane: &LocalPlane, p: [f64; 3]) -> f64 {
    dot(sub(p, plane.centroid), plane.normal)
}

/// Turn the normals so that neighbours agree (Hoppe et al. 1992): walk a
/// minimum spanning tree of the neighbourhood graph (`neighbours[i]` lists
/// the points next to `i`; the graph is made symmetric) whose edge costs
/// are `1 − |nᵢ·nⱼ|`, so the walk crosses flat regions before creases, and
/// give each point the sign that agrees with its parent's normal. Each
/// connected piece starts from its lowest-index point with the sign given.
pub(super) fn orient_by_propagation(
    normals: &[[f64; 3]],
    neighbours: &[Vec<usize>],
) -> Vec<[f64; 3]> {
    let n = normals.len();
    let mut graph: Vec<Vec<usize>> = neighbours.to_vec();
    for (i, list) in neighbours.iter().enumerate() {
        for &j in list {
            if j < n && j != i {
                graph[j].push(i);
            }
        }
    }
    for list in &mut graph {
        list.sort_unstable();
        list.dedup();
    }
    let mut out = normals.to_vec();
    let mut done = vec![false; n];
    // Costs are non-negative, so their bit patterns order like the values.
    let mut heap: BinaryHeap<Reverse<(u64, usize, usize)>> = BinaryHeap::new();
    for seed in 0..n {
        if done[seed] {
            continue;
        }
        done[seed] = true;
        push_edges(&mut heap, &graph, &out, &done, seed);
        while let Some(Reverse((_, from, to))) = heap.pop() {
            if done[to] {
                continue;
            }
            done[to] = true;
            if dot(out[from], out[to]) < 0.0 {
                out[to] = out[to].map(|x| -x);
            }
            push_edges(&mut heap, &graph, &out, &done, to);
        }
    }
    out
}

/// Queue the edges from `from` to the points not yet reached.
fn push_edges(
    heap: &mut BinaryHeap<Reverse<(u64, usize, usize)>>,
    graph: &[Vec<usize>],
    normals: &[[f64; 3]],
    done: &[bool],
    from: usize,
) {
    for &to in &graph[from] {
        if !done[to] {
            let cost = (1.0 - dot(normals[from], normals[to]).abs()).max(0.0);
            heap.push(Reverse((cost.to_bits(), from, to)));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_of_tilted_points() {
        let pts: Vec<[f64; 3]> = (0..25)
            .map(|k| {
                let (x, y) = ((k % 5) as f64, (k / 5) as f64);
                [x, y, 0.5 * x]
            })
            .collect();
        let p = local_plane(&pts).expect("plane");
        let expect = [-0.5, 0.0, 1.0].map(|x| x / 1.25f64.sqrt());
        assert!(dot(p.normal, expect).abs() > 1.0 - 1e-12);
        assert!(p.residual < 1e-12);
        assert!(plane_distance(&p, [0.0, 0.0, 1.0]).abs() > 0.8);
    }

    #[test]
    fn propagation_makes_a_sphere_consistent() {
        // Points on a circle of latitude band; normals radial with random signs.
        let mut normals = Vec::new();
        let mut neighbours = Vec::new();
        let n = 40;
        for i in 0..n {
            let t = i as f64 / n as f64 * std::f64::consts::TAU;
            let s = if (i * 7) % 3 == 0 { -1.0 } else { 1.0 };
            normals.push([s * t.cos(), s * t.sin(), 0.0]);
            neighbours.push(vec![(i + 1) % n]);
        }
        let out = orient_by_propagation(&normals, &neighbours);
        let sign = out[0][0].signum();
        for (i, v) in out.iter().enumerate() {
            let t = i as f64 / n as f64 * std::f64::consts::TAU;
            assert!((dot(*v, [t.cos(), t.sin(), 0.0]) * sign - 1.0).abs() < 1e-12);
        }
    }
}
