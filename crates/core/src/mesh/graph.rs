//! Distances and traversal orders along the edges of a mesh.

use super::{norm, sub, vertex_adjacency, Mesh};
use std::collections::BinaryHeap;

/// Edge-path (graph-geodesic) distance from the nearest of `sources` to
/// every vertex, along edges weighted by their Euclidean length (Dijkstra).
/// Unreachable vertices get infinity; out-of-range sources are ignored.
pub(crate) fn graph_distance(mesh: &Mesh, sources: &[u32]) -> Vec<f64> {
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
            let nd = d + norm(sub(mesh.vertices[v as usize], mesh.vertices[u as usize]));
            if nd < dist[u as usize] {
                dist[u as usize] = nd;
                heap.push(HeapItem(nd, u));
            }
        }
    }
    dist
}

/// A breadth-first spanning forest of the graph `adjacency`: every vertex
/// once, as `[vertex, parent]`, the parent an earlier vertex adjacent to
/// it (a vertex is its own parent when it starts a component). Visiting
/// vertices in this order, each lies one edge from a visited one.
pub(crate) fn breadth_first_tree(adjacency: &[Vec<u32>]) -> Vec<[u32; 2]> {
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

/// Min-heap entry (distance, vertex) for Dijkstra: the smallest distance
/// pops first, ties by the smallest vertex.
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
    fn distances_follow_the_shortest_edge_path() {
        // A unit square split along 0–2: 0 → 2 is one diagonal edge, 1 → 3
        // must go round.
        let m = Mesh::new(
            vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let d = graph_distance(&m, &[0]);
        assert_eq!(d, vec![0.0, 1.0, 2f64.sqrt(), 1.0]);
        assert_eq!(graph_distance(&m, &[1])[3], 2.0);
        assert_eq!(graph_distance(&m, &[1, 3]), vec![1.0, 0.0, 1.0, 0.0]);
        // An unused vertex is unreachable; a missing source is ignored.
        let mut lone = m.clone();
        lone.vertices.push([5., 5., 5.]);
        assert_eq!(graph_distance(&lone, &[0, 99])[4], f64::INFINITY);
    }

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
