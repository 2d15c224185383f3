//! The cervical margin as the cheapest closed edge path that winds once
//! around the tooth's axis.
//!
//! Every edge costs its length times a weight that is small on convex
//! creases (the enamel edge) and 1 on smooth surface, so the cheapest loop
//! around the tooth runs along the strongest crease that goes all the way
//! round. A loop "goes round" when it winds once about the axis: the search
//! runs in the winding cover of the surface (each vertex copied per winding
//! count, a step across the half-plane `angle = π` moving one copy up or
//! down), and a winding loop through a vertex `s` is a shortest path from
//! `s`'s copy at winding 0 to its copy at winding 1. Paths are searched from
//! every vertex next to that half-plane (in parallel), each search cut off
//! at the best loop found so far, so most of them stop after a few steps.

use crate::mesh::HeapItem;
use rayon::prelude::*;
use std::collections::BinaryHeap;
use std::f64::consts::PI;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// Winding counts kept apart in the cover: −1, 0, 1, 2 (a loop may cross
/// the half-plane back and forth where the margin runs steeply).
const LAYERS: usize = 4;
/// Cover index of winding 0.
const START: usize = 1;

/// The surface's edge graph for the search: per vertex, its neighbours with
/// the step's cost and its change of winding count.
pub(super) struct WindingGraph {
    neighbours: Vec<Vec<(u32, f64, i8)>>,
}

impl WindingGraph {
    /// The graph of `edges` (vertex pairs with their cost, finite and
    /// positive) over vertices at `angles` about the axis (radians in
    /// (−π, π]). Only edges between two `allowed` vertices are kept.
    pub(super) fn new(angles: &[f64], edges: &[(u32, u32, f64)], allowed: &[bool]) -> Self {
        let mut neighbours = vec![Vec::new(); angles.len()];
        for &(a, b, cost) in edges {
            if !(allowed[a as usize] && allowed[b as usize] && cost > 0.0 && cost.is_finite()) {
                continue;
            }
            let w = winding_step(angles[a as usize], angles[b as usize]);
            neighbours[a as usize].push((b, cost, w));
            neighbours[b as usize].push((a, cost, -w));
        }
        Self { neighbours }
    }

    /// Vertices with an edge across the half-plane `angle = π`: every
    /// winding loop passes through one of them.
    pub(super) fn seam_vertices(&self) -> Vec<u32> {
        (0..self.neighbours.len())
            .filter(|&v| self.neighbours[v].iter().any(|n| n.2 != 0))
            .map(|v| v as u32)
            .collect()
    }
}

/// How a step from angle `a` to angle `b` (the short way round) changes the
/// winding count: +1 when it crosses `angle = π` counter-clockwise, −1
/// clockwise, 0 otherwise.
fn winding_step(a: f64, b: f64) -> i8 {
    let d = b - a;
    if d < -PI {
        1
    } else if d > PI {
        -1
    } else {
        0
    }
}

/// A closed edge path: its vertices in order (the last one joins the
/// first) and its total cost.
#[derive(Debug, Clone)]
pub(super) struct WindingCycle {
    pub vertices: Vec<u32>,
    pub cost: f64,
}

impl WindingGraph {
    /// Of `sources`, those through which some loop winds once: whose copy
    /// at winding 0 and copy at winding 1 are connected in the cover (the
    /// cover's edges go both ways, so connected is reachable). A search
    /// from any other source explores everything it can reach and finds
    /// nothing; on a surface where nothing winds round, that would be
    /// every source over the whole surface (minutes on a 400k-face
    /// isosurface).
    fn sources_with_winding_loop(&self, sources: &[u32]) -> Vec<u32> {
        let mut uf = crate::clean::union_find::UnionFind::new(self.neighbours.len() * LAYERS);
        for (v, list) in self.neighbours.iter().enumerate() {
            // Each edge is listed from both ends: one of them is enough.
            for &(w, _, step) in list.iter().filter(|n| n.0 as usize > v) {
                for layer in 0..LAYERS as i64 {
                    let l = layer + i64::from(step);
                    if (0..LAYERS as i64).contains(&l) {
                        uf.union(
                            (v * LAYERS) as u32 + layer as u32,
                            (w as usize * LAYERS) as u32 + l as u32,
                        );
                    }
                }
            }
        }
        sources
            .iter()
            .copied()
            .filter(|&s| {
                let base = s * LAYERS as u32;
                uf.find(base + START as u32) == uf.find(base + START as u32 + 1)
            })
            .collect()
    }
}

/// The cheapest loop that winds once about the axis, searched from
/// `sources` (cheapest-looking first makes the cut-offs bite early);
/// `None` when no loop winds round. Of loops of equal cost, the one
/// through the earliest source is taken.
///
/// The sources are searched in parallel, each cut off at the best loop
/// found so far by any. The answer is the one a search in order would
/// give: that is the loop of least (cost, source position); a source
/// after the best one's must beat its cost, one before it may tie, and
/// the path a search finds does not depend on where it is cut off.
pub(super) fn cheapest_winding_cycle(
    graph: &WindingGraph,
    sources: &[u32],
) -> Option<WindingCycle> {
    let all = sources.len();
    let sources = graph.sources_with_winding_loop(sources);
    let n = graph.neighbours.len();
    let popped = AtomicUsize::new(0);
    // The best loop so far and its source's position.
    let best: Mutex<Option<(usize, WindingCycle)>> = Mutex::new(None);
    sources.par_iter().enumerate().for_each_init(
        || Scratch::new(n),
        |scratch, (position, &s)| {
            let bound = best
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .as_ref()
                .map(|(at, b)| (b.cost, *at));
            let (found, pops) = scratch.cheapest_loop_through(graph, s, bound, position);
            popped.fetch_add(pops, Ordering::Relaxed);
            if let Some(cycle) = found {
                let mut best = best.lock().unwrap_or_else(|p| p.into_inner());
                let better = best
                    .as_ref()
                    .is_none_or(|(at, b)| (cycle.cost, position) < (b.cost, *at));
                if better {
                    *best = Some((position, cycle));
                }
            }
        },
    );
    tracing::debug!(
        vertices = n,
        sources = all,
        winding = sources.len(),
        popped = popped.into_inner(),
        "winding loop search"
    );
    best.into_inner()
        .unwrap_or_else(|p| p.into_inner())
        .map(|(_, cycle)| cycle)
}

/// One search's distances and predecessors in the cover, reset between
/// searches by the entries it touched.
struct Scratch {
    dist: Vec<f64>,
    prev: Vec<u32>,
    touched: Vec<usize>,
}

impl Scratch {
    fn new(vertices: usize) -> Self {
        Scratch {
            dist: vec![f64::INFINITY; vertices * LAYERS],
            prev: vec![u32::MAX; vertices * LAYERS],
            touched: Vec::new(),
        }
    }

    /// The cheapest loop through `s` that winds once, if it beats `bound`
    /// (the best loop's cost and its source's position; a tie beats it
    /// when `position` comes first), and the nodes popped.
    fn cheapest_loop_through(
        &mut self,
        graph: &WindingGraph,
        s: u32,
        bound: Option<(f64, usize)>,
        position: usize,
    ) -> (Option<WindingCycle>, usize) {
        for &i in &self.touched {
            self.dist[i] = f64::INFINITY;
            self.prev[i] = u32::MAX;
        }
        self.touched.clear();
        let cut_off = |d: f64| match bound {
            None => false,
            Some((cost, at)) if position < at => d > cost,
            Some((cost, _)) => d >= cost,
        };
        let s = s as usize;
        let start = s * LAYERS + START;
        let target = s * LAYERS + START + 1;
        self.dist[start] = 0.0;
        self.touched.push(start);
        let mut heap = BinaryHeap::new();
        heap.push(HeapItem(0.0, start as u32));
        let mut popped = 0usize;
        while let Some(HeapItem(d, node)) = heap.pop() {
            popped += 1;
            let node = node as usize;
            if d > self.dist[node] {
                continue;
            }
            if cut_off(d) {
                break;
            }
            if node == target {
                let mut vertices = Vec::new();
                let mut at = target;
                while at != start {
                    vertices.push((at / LAYERS) as u32);
                    at = self.prev[at] as usize;
                }
                vertices.reverse();
                return (Some(WindingCycle { vertices, cost: d }), popped);
            }
            let (v, layer) = (node / LAYERS, node % LAYERS);
            for &(w, cost, step) in &graph.neighbours[v] {
                let l = layer as i64 + step as i64;
                if !(0..LAYERS as i64).contains(&l) {
                    continue;
                }
                let next = w as usize * LAYERS + l as usize;
                let nd = d + cost;
                if nd < self.dist[next] {
                    if self.dist[next].is_infinite() {
                        self.touched.push(next);
                    }
                    self.dist[next] = nd;
                    self.prev[next] = node as u32;
                    heap.push(HeapItem(nd, next as u32));
                }
            }
        }
        (None, popped)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// A cylinder grid: `rings` rings of `m` vertices; edge costs 1, except
    /// the ring edges of ring `cheap`, which cost 0.1.
    fn cylinder(m: usize, rings: usize, cheap: usize) -> (Vec<f64>, Vec<(u32, u32, f64)>) {
        let id = |r: usize, i: usize| (r * m + i % m) as u32;
        let angles: Vec<f64> = (0..rings * m)
            .map(|v| {
                let a = TAU * (v % m) as f64 / m as f64;
                if a > PI {
                    a - TAU
                } else {
                    a
                }
            })
            .collect();
        let mut edges = Vec::new();
        for r in 0..rings {
            for i in 0..m {
                let c = if r == cheap { 0.1 } else { 1.0 };
                edges.push((id(r, i), id(r, i + 1), c));
                if r + 1 < rings {
                    edges.push((id(r, i), id(r + 1, i), 1.0));
                    edges.push((id(r, i), id(r + 1, i + 1), 1.4));
                }
            }
        }
        (angles, edges)
    }

    #[test]
    fn the_cheap_ring_is_the_cheapest_winding_loop() {
        let (m, rings) = (24, 9);
        let (angles, edges) = cylinder(m, rings, 6);
        let graph = WindingGraph::new(&angles, &edges, &vec![true; angles.len()]);
        let cycle = cheapest_winding_cycle(&graph, &graph.seam_vertices()).unwrap();
        assert_eq!(cycle.vertices.len(), m);
        assert!((cycle.cost - 0.1 * m as f64).abs() < 1e-9, "{}", cycle.cost);
        assert!(cycle.vertices.iter().all(|&v| v as usize / m == 6));
    }

    #[test]
    fn of_equally_cheap_loops_the_one_through_the_earliest_source_is_taken() {
        // No cheap ring: every ring is a loop of cost m, the cheapest
        // through each of its vertices; the searches run in parallel.
        let (m, rings) = (24, 9);
        let (angles, edges) = cylinder(m, rings, rings);
        let graph = WindingGraph::new(&angles, &edges, &vec![true; angles.len()]);
        for order in [false, true] {
            let mut sources = graph.seam_vertices();
            if order {
                sources.reverse();
            }
            let cycle = cheapest_winding_cycle(&graph, &sources).unwrap();
            assert!((cycle.cost - m as f64).abs() < 1e-9, "{}", cycle.cost);
            let ring = sources[0] as usize / m;
            assert!(
                cycle.vertices.iter().all(|&v| v as usize / m == ring),
                "not the ring of the first source ({ring}): {:?}",
                cycle.vertices
            );
        }
    }

    #[test]
    fn without_a_way_round_there_is_no_loop() {
        let (m, rings) = (24, 5);
        let (angles, edges) = cylinder(m, rings, 2);
        // Forbid one column: nothing winds round any more.
        let allowed: Vec<bool> = (0..angles.len()).map(|v| v % m != 5).collect();
        let graph = WindingGraph::new(&angles, &edges, &allowed);
        assert!(cheapest_winding_cycle(&graph, &graph.seam_vertices()).is_none());
    }

    #[test]
    fn steps_across_the_half_plane_count_windings() {
        assert_eq!(winding_step(3.0, -3.0), 1);
        assert_eq!(winding_step(-3.0, 3.0), -1);
        assert_eq!(winding_step(0.1, -0.1), 0);
    }
}
