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

/// A breadth-first spanning forest of the graph `adjacency`: every vertex
/// once, as `[vertex, parent]`, the parent an earlier vertex adjacent to
/// it (a vertex is its own parent when it starts a component). Visiting
/// vertices in this order, each lies one edge from a visited one.
pub fn breadth_first_tree(adjacency: &[Vec<u32>]) -> Vec<[u32; 2]> {
    let n = adjacency.len();
    let mut seen = vec![false; n];
    let mut order: Vec<[u32; 2]> = Vec::with_capacity(n);
    for root in 0..n {
        if seen[root] {
            continue;
        }
        seen[root] = true;
        let mut head = order.len();
        order.push([root as u32, root as u32]);
        while head < order.len() {
            let v = order[head][0];
            head += 1;
            for &u in adjacency.get(v as usize).map_or(&[][..], |a| a) {
                if let Some(s) = seen.get_mut(u as usize) {
                    if !*s {
                        *s = true;
                        order.push([u, v]);
                    }
                }
            }
        }
    }
    order
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_breadth_first_tree_visits_each_vertex_after_a_neighbour() {
        // A path 0-1-2, a triangle 3-4-5 and a lone vertex 6.
        let adj = vec![
            vec![1],
            vec![0, 2],
            vec![1],
            vec![4, 5],
            vec![3, 5],
            vec![3, 4],
            vec![],
        ];
        let tree = breadth_first_tree(&adj);
        assert_eq!(tree.len(), 7);
        let mut position = [usize::MAX; 7];
        for (i, &[v, _]) in tree.iter().enumerate() {
            assert_eq!(position[v as usize], usize::MAX, "{v} twice");
            position[v as usize] = i;
        }
        for &[v, p] in &tree {
            assert!(
                p == v
                    || (adj[v as usize].contains(&p)
                        && position[p as usize] < position[v as usize])
            );
        }
        assert_eq!(tree.iter().filter(|[v, p]| v == p).count(), 3);
    }
}
