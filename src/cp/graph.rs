//! Graph distances along mesh edges and vertex adjacency.

use crate::mesh::Mesh;
use std::collections::BinaryHeap;

/// Geodesic (edge-path) distance from the sources to every vertex.
pub fn graph_distance(mesh: &Mesh, sources: &[u32]) -> Vec<f64> {
    let n = mesh.vertices.len();
    let adj = vertex_adjacency(mesh);
    let mut dist = vec![f64::INFINITY; n];
    let mut heap = BinaryHeap::new();
    for &s in sources {
        if let Some(d) = dist.get_mut(s as usize) {
            *d = 0.0;
            heap.push(HeapItem(0.0, s));
        }
    }
    while let Some(HeapItem(d, v)) = heap.pop() {
        if d > dist[v as usize] {
            continue;
        }
        for &u in &adj[v as usize] {
            let nd = d + crate::mesh::norm(crate::mesh::sub(
                mesh.vertices[v as usize],
                mesh.vertices[u as usize],
            ));
            if nd < dist[u as usize] {
                dist[u as usize] = nd;
                heap.push(HeapItem(nd, u));
            }
        }
    }
    dist
}

/// Sorted neighbour lists of every vertex.
pub fn vertex_adjacency(mesh: &Mesh) -> Vec<Vec<u32>> {
    let mut adj: Vec<Vec<u32>> = vec![Vec::new(); mesh.vertices.len()];
    for f in &mesh.faces {
        for k in 0..3 {
            let (a, b) = (f[k] as usize, f[(k + 1) % 3] as usize);
            if a < adj.len() && b < adj.len() {
                adj[a].push(b as u32);
                adj[b].push(a as u32);
            }
        }
    }
    for a in &mut adj {
        a.sort_unstable();
        a.dedup();
    }
    adj
}

/// Min-heap entry (distance, vertex), ties by vertex index.
#[derive(PartialEq)]
pub(crate) struct HeapItem(pub f64, pub u32);
impl Eq for HeapItem {}
impl PartialOrd for HeapItem {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for HeapItem {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}
