//! Farthest-point sampling over the surface, with Voronoi-cell weights.

use crate::mesh::{farthest_point_order, norm, sub, HeapItem, Mesh};
use std::collections::BinaryHeap;

/// Samples: vertex indices and the area of their (graph-)Voronoi cells.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Sampling {
    /// The sampled vertices, in the order they were chosen.
    pub vertices: Vec<u32>,
    /// Area of each sample's Voronoi cell (sums to the surface area).
    pub weights: Vec<f64>,
}

/// Farthest-point sampling of `count` vertices by edge-path distance,
/// seeded at `seeds` (then, if none is a vertex, at vertex 0); each sample
/// is weighted by the total `vertex_areas` of the vertices nearest to it.
pub(super) fn farthest_point_samples(
    mesh: &Mesh,
    adjacency: &[Vec<u32>],
    vertex_areas: &[f64],
    seeds: &[u32],
    count: usize,
) -> Sampling {
    let n = mesh.vertices.len();
    let mut owner = vec![u32::MAX; n];
    let mut heap = BinaryHeap::new();
    let edge = |a: u32, b: u32| norm(sub(mesh.vertices[a as usize], mesh.vertices[b as usize]));
    let seeds: Vec<usize> = seeds.iter().map(|&s| s as usize).collect();
    let chosen = farthest_point_order(n, &seeds, count, |id, s, dist| {
        let (id, s) = (id as u32, s as u32);
        dist[s as usize] = 0.0;
        owner[s as usize] = id;
        heap.push(HeapItem(0.0, s));
        // Incremental Dijkstra: only vertices that get closer are visited,
        // and each is owned by the sample that reached it closest.
        while let Some(HeapItem(d, v)) = heap.pop() {
            if d > dist[v as usize] {
                continue;
            }
            for &u in &adjacency[v as usize] {
                let nd = d + edge(v, u);
                if nd < dist[u as usize] {
                    dist[u as usize] = nd;
                    owner[u as usize] = id;
                    heap.push(HeapItem(nd, u));
                }
            }
        }
    });
    let mut weights = vec![0.0; chosen.len()];
    for (i, &o) in owner.iter().enumerate() {
        if let Some(w) = weights.get_mut(o as usize) {
            *w += vertex_areas[i];
        }
    }
    Sampling {
        vertices: chosen.into_iter().map(|v| v as u32).collect(),
        weights,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(k: usize) -> Mesh {
        let mut v = Vec::new();
        for y in 0..=k {
            for x in 0..=k {
                v.push([x as f64 / k as f64, y as f64 / k as f64, 0.0]);
            }
        }
        let id = |x: usize, y: usize| (y * (k + 1) + x) as u32;
        let mut f = Vec::new();
        for y in 0..k {
            for x in 0..k {
                f.push([id(x, y), id(x + 1, y), id(x + 1, y + 1)]);
                f.push([id(x, y), id(x + 1, y + 1), id(x, y + 1)]);
            }
        }
        Mesh::new(v, f)
    }

    #[test]
    fn samples_are_spread_and_weights_sum_to_area() {
        let m = grid(20);
        let adj = crate::mesh::vertex_adjacency(&m);
        let areas = crate::mesh::vertex_areas(&m);
        let s = farthest_point_samples(&m, &adj, &areas, &[220], 30);
        assert_eq!(s.vertices.len(), 30);
        assert_eq!(s.vertices[0], 220);
        let total: f64 = s.weights.iter().sum();
        assert!((total - 1.0).abs() < 1e-12);
        // The second sample is a corner (farthest from the centre).
        let c = m.vertices[s.vertices[1] as usize];
        assert!((c[0] == 0.0 || c[0] == 1.0) && (c[1] == 0.0 || c[1] == 1.0));
        // No cell is empty.
        assert!(s.weights.iter().all(|&w| w > 0.0));
    }
}
