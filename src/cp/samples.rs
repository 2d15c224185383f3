//! Farthest-point sampling over the surface, with Voronoi-cell weights.

use crate::mesh::Mesh;
use std::collections::BinaryHeap;

use crate::mesh::HeapItem;

/// Samples: vertex indices and the area of their (graph-)Voronoi cells.
#[derive(Debug, Clone, PartialEq)]
pub struct Sampling {
    /// The sampled vertices, in the order they were chosen.
    pub vertices: Vec<u32>,
    /// Area of each sample's Voronoi cell (sums to the surface area).
    pub weights: Vec<f64>,
}

/// Farthest-point sampling of `count` vertices by edge-path distance,
/// seeded at `seeds` (then, if empty, at vertex 0); each sample is weighted
/// by the total `vertex_areas` of the vertices nearest to it.
pub fn farthest_point_samples(
    mesh: &Mesh,
    adjacency: &[Vec<u32>],
    vertex_areas: &[f64],
    seeds: &[u32],
    count: usize,
) -> Sampling {
    let n = mesh.vertices.len();
    let mut dist = vec![f64::INFINITY; n];
    let mut owner = vec![u32::MAX; n];
    let mut chosen: Vec<u32> = Vec::new();
    let mut heap = BinaryHeap::new();
    let edge = |a: u32, b: u32| {
        crate::mesh::norm(crate::mesh::sub(
            mesh.vertices[a as usize],
            mesh.vertices[b as usize],
        ))
    };
    let mut add = |s: u32, dist: &mut Vec<f64>, owner: &mut Vec<u32>, chosen: &mut Vec<u32>| {
        let id = chosen.len() as u32;
        chosen.push(s);
        dist[s as usize] = 0.0;
        owner[s as usize] = id;
        heap.push(HeapItem(0.0, s));
        // Incremental Dijkstra: only vertices that get closer are visited.
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
    };
    let count = count.min(n);
    for &s in seeds {
        if chosen.len() >= count {
            break;
        }
        if (s as usize) < n && !chosen.contains(&s) {
            add(s, &mut dist, &mut owner, &mut chosen);
        }
    }
    if chosen.is_empty() && n > 0 {
        add(0, &mut dist, &mut owner, &mut chosen);
    }
    while chosen.len() < count {
        // Farthest vertex; ties by smallest index.
        let mut best: Option<(f64, usize)> = None;
        for (i, &d) in dist.iter().enumerate() {
            if d.is_finite() && best.is_none_or(|(bd, _)| d > bd) {
                best = Some((d, i));
            }
        }
        match best {
            Some((d, i)) if d > 0.0 => add(i as u32, &mut dist, &mut owner, &mut chosen),
            _ => break,
        }
    }
    let mut weights = vec![0.0; chosen.len()];
    for (i, &o) in owner.iter().enumerate() {
        if let Some(w) = weights.get_mut(o as usize) {
            *w += vertex_areas[i];
        }
    }
    Sampling {
        vertices: chosen,
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
