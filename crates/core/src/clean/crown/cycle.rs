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
//! the vertices where an edge crosses that half-plane forwards (in
//! parallel; each search serves as a search from both ends, the cover
//! looking the same from each copy of `s`), each cut off at the best
//! loop found so far, so most of them stop after a few steps.

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
/// the step's cost and its change of winding count, all vertices' lists
/// in one array (the searches read them millions of times).
pub(super) struct WindingGraph {
    /// Where each vertex's list starts in `steps`; one more entry at the end.
    offsets: Vec<u32>,
    steps: Vec<(u32, f64, i8)>,
}

impl WindingGraph {
    /// The graph of `edges` (vertex pairs with their cost, finite and
    /// positive) over vertices at `angles` about the axis (radians in
    /// (−π, π]). Only edges between two `allowed` vertices are kept.
    pub(super) fn new(angles: &[f64], edges: &[(u32, u32, f64)], allowed: &[bool]) -> Self {
        let kept = |&&(a, b, cost): &&(u32, u32, f64)| {
            allowed[a as usize] && allowed[b as usize] && cost > 0.0 && cost.is_finite()
        };
        let mut offsets = vec![0u32; angles.len() + 1];
        for &(a, b, _) in edges.iter().filter(kept) {
            offsets[a as usize + 1] += 1;
            offsets[b as usize + 1] += 1;
        }
        for v in 0..angles.len() {
            offsets[v + 1] += offsets[v];
        }
        // Each list in the order of `edges`.
        let mut fill: Vec<u32> = offsets[..angles.len()].to_vec();
        let mut steps = vec![(0u32, 0.0f64, 0i8); offsets[angles.len()] as usize];
        let mut put = |v: u32, step: (u32, f64, i8)| {
            steps[fill[v as usize] as usize] = step;
            fill[v as usize] += 1;
        };
        for &(a, b, cost) in edges.iter().filter(kept) {
            let w = winding_step(angles[a as usize], angles[b as usize]);
            put(a, (b, cost, w));
            put(b, (a, cost, -w));
        }
        Self { offsets, steps }
    }

    /// Number of vertices.
    fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// The neighbours of `v`: (vertex, cost, change of winding count).
    fn neighbours(&self, v: usize) -> &[(u32, f64, i8)] {
        &self.steps[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }

    /// Vertices with an edge across the half-plane `angle = π`: every
    /// winding loop passes through one of them.
    pub(super) fn seam_vertices(&self) -> Vec<u32> {
        (0..self.len())
            .filter(|&v| self.neighbours(v).iter().any(|n| n.2 != 0))
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
        let mut uf = crate::union_find::UnionFind::new(self.len() * LAYERS);
        for v in 0..self.len() {
            let list = self.neighbours(v);
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
    // Every loop that winds once steps forward across the half-plane
    // somewhere, and the step's tail is on it: the searches from those
    // tails alone (about half the sources) find the cheapest loop. Each
    // keeps its position among all the sources for the order of ties.
    let tails: Vec<(usize, u32)> = sources
        .iter()
        .copied()
        .enumerate()
        .filter(|&(_, s)| graph.crosses_forward(s))
        .collect();
    let n = graph.len();
    let popped = AtomicUsize::new(0);
    // The best loop so far and its source's position.
    let best: Mutex<Option<(usize, WindingCycle)>> = Mutex::new(None);
    tails.par_iter().for_each_init(
        || Scratch::new(n),
        |scratch, &(position, s)| {
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
        searched = tails.len(),
        popped = popped.into_inner(),
        "winding loop search"
    );
    best.into_inner()
        .unwrap_or_else(|p| p.into_inner())
        .map(|(at, cycle)| graph.started_as_searched_in_order(cycle, at, &sources))
}

impl WindingGraph {
    /// Whether `v` has an edge that crosses the half-plane `angle = π`
    /// counter-clockwise (winding +1).
    fn crosses_forward(&self, v: u32) -> bool {
        self.neighbours(v as usize).iter().any(|n| n.2 > 0)
    }

    /// The cost of the edge from `a` to `b`, if there is one.
    fn edge_cost(&self, a: u32, b: u32) -> Option<f64> {
        self.neighbours(a as usize)
            .iter()
            .find(|n| n.0 == b)
            .map(|n| n.1)
    }

    /// `cycle`, found from `sources[at]`, started at the vertex a search
    /// from every source in order would have returned it from: of its
    /// vertices among `sources`, the one from which its edges' costs,
    /// added up in order round the loop, are least, then the earliest.
    /// (The searches from every source find this loop from each of its
    /// vertices, each summing the same costs in its own order.)
    fn started_as_searched_in_order(
        &self,
        cycle: WindingCycle,
        at: usize,
        sources: &[u32],
    ) -> WindingCycle {
        // The loop's vertices from its start: `ring[i] → ring[i + 1]`.
        let k = cycle.vertices.len();
        if k == 0 {
            return cycle;
        }
        let ring: Vec<u32> = (0..k).map(|i| cycle.vertices[(i + k - 1) % k]).collect();
        let Some(costs) = (0..k)
            .map(|i| self.edge_cost(ring[i], ring[(i + 1) % k]))
            .collect::<Option<Vec<f64>>>()
        else {
            return cycle;
        };
        let position: std::collections::HashMap<u32, usize> =
            sources.iter().enumerate().map(|(p, &s)| (s, p)).collect();
        let mut chosen = (cycle.cost, at, 0);
        for (j, v) in ring.iter().enumerate() {
            let Some(&p) = position.get(v) else {
                continue;
            };
            let cost = (0..k).fold(0.0, |sum, i| sum + costs[(j + i) % k]);
            if (cost, p) < (chosen.0, chosen.1) {
                chosen = (cost, p, j);
            }
        }
        let (cost, _, j) = chosen;
        if j == 0 {
            return cycle;
        }
        WindingCycle {
            vertices: (1..=k).map(|i| ring[(j + i) % k]).collect(),
            cost,
        }
    }
}

/// One search's distances and predecessors in the cover, from `s`'s copy
/// at winding 0, reset between searches by the entries it touched.
struct Scratch {
    dist: Vec<f64>,
    prev: Vec<u32>,
    touched: Vec<usize>,
}

/// The cheapest join of the two halves of a loop found so far: its cost,
/// the node the first half ends at (reached from the start) and the node
/// the second half begins at (a copy one winding up of a node reached
/// from the start).
#[derive(Clone, Copy)]
struct Meeting {
    cost: f64,
    from_start: usize,
    from_target: usize,
}

/// The node one winding up (`+1`) or down (`-1`) from `node`, if the
/// cover holds it.
fn shifted(node: usize, by: i64) -> Option<usize> {
    let l = (node % LAYERS) as i64 + by;
    (0..LAYERS as i64)
        .contains(&l)
        .then(|| node - node % LAYERS + l as usize)
}

impl Scratch {
    fn new(vertices: usize) -> Self {
        let nodes = vertices * LAYERS;
        Scratch {
            dist: vec![f64::INFINITY; nodes],
            prev: vec![u32::MAX; nodes],
            touched: Vec::new(),
        }
    }

    fn reset(&mut self) {
        for &i in &self.touched {
            self.dist[i] = f64::INFINITY;
            self.prev[i] = u32::MAX;
        }
        self.touched.clear();
    }

    /// The distance from the target (`s`'s copy at winding 1) to `node`:
    /// the cover looks the same from each copy of `s`, one winding apart,
    /// so it is the distance from the start to the node one winding down.
    fn dist_to_target(&self, node: usize) -> f64 {
        shifted(node, -1).map_or(f64::INFINITY, |n| self.dist[n])
    }

    /// The cheapest loop through `s` that winds once, if it beats `bound`
    /// (the best loop's cost and its source's position; a tie beats it
    /// when `position` comes first), and the nodes popped.
    ///
    /// A loop is a path from `s`'s copy at winding 0 to its copy at
    /// winding 1. The cover's edges go both ways at the same cost and
    /// the cover looks the same from each copy, so the search from the
    /// target is the search from the start moved one winding up: one
    /// search serves as both sides of a two-sided one, reaching half the
    /// loop's cost out. The loop's cost is then summed along it from `s`,
    /// as a search from one end adds it up.
    fn cheapest_loop_through(
        &mut self,
        graph: &WindingGraph,
        s: u32,
        bound: Option<(f64, usize)>,
        position: usize,
    ) -> (Option<WindingCycle>, usize) {
        self.reset();
        let cut_off = |d: f64| match bound {
            None => false,
            Some((cost, at)) if position < at => d > cost,
            Some((cost, _)) => d >= cost,
        };
        let start = s as usize * LAYERS + START;
        self.dist[start] = 0.0;
        self.touched.push(start);
        let mut heap = BinaryHeap::from([HeapItem(0.0, start as u32)]);
        let mut meeting: Option<Meeting> = None;
        let mut popped = 0usize;
        loop {
            // No path not yet seen is cheaper than twice the nearest
            // unsettled node: each half of it has one.
            let unseen = 2.0 * heap.peek().map_or(f64::INFINITY, |i| i.0);
            if meeting.is_some_and(|m| unseen >= m.cost) {
                break;
            }
            if cut_off(unseen) && meeting.is_none_or(|m| cut_off(m.cost)) {
                return (None, popped);
            }
            let Some(HeapItem(d, node)) = heap.pop() else {
                break;
            };
            popped += 1;
            let node = node as usize;
            if d > self.dist[node] {
                continue;
            }
            // A path through a node reached at `nd` costs at least `nd`
            // and `d` more: beyond the best join or the bound, the node
            // need not be queued.
            let limit = meeting
                .map_or(f64::INFINITY, |m| m.cost)
                .min(bound.map_or(f64::INFINITY, |b| b.0));
            self.relax(graph, node, d, limit - d, &mut heap, &mut meeting);
        }
        let Some(m) = meeting else {
            return (None, popped);
        };
        let found = self.joined_loop(graph, start, m);
        if found.as_ref().is_none_or(|c| cut_off(c.cost)) {
            return (None, popped);
        }
        (found, popped)
    }

    /// Relax the edges out of `node` (settled at `d`), noting the cheapest
    /// join of the two halves: the edge ends a first half, or, one
    /// winding up, begins a second; nodes reached beyond `reach` are not
    /// queued (no path through them can be the loop).
    fn relax(
        &mut self,
        graph: &WindingGraph,
        node: usize,
        d: f64,
        reach: f64,
        heap: &mut BinaryHeap<HeapItem>,
        meeting: &mut Option<Meeting>,
    ) {
        let (v, layer) = (node / LAYERS, node % LAYERS);
        for &(w, cost, step) in graph.neighbours(v) {
            let l = layer as i64 + step as i64;
            if !(0..LAYERS as i64).contains(&l) {
                continue;
            }
            let next = w as usize * LAYERS + l as usize;
            let nd = d + cost;
            let best = meeting.map_or(f64::INFINITY, |m| m.cost);
            // First half to `node`, the edge, second half from `next`.
            let ahead = nd + self.dist_to_target(next);
            // Moved one winding up: second half from `node` (up), the edge
            // reversed, first half to `next` (up).
            let up_next = shifted(next, 1);
            let behind = up_next.map_or(f64::INFINITY, |n| nd + self.dist[n]);
            if ahead < best && ahead <= behind {
                *meeting = Some(Meeting {
                    cost: ahead,
                    from_start: node,
                    from_target: next,
                });
            } else if behind < best {
                if let (Some(up_next), Some(up_node)) = (up_next, shifted(node, 1)) {
                    *meeting = Some(Meeting {
                        cost: behind,
                        from_start: up_next,
                        from_target: up_node,
                    });
                }
            }
            if nd < self.dist[next] && nd <= reach {
                if self.dist[next].is_infinite() {
                    self.touched.push(next);
                }
                self.dist[next] = nd;
                self.prev[next] = node as u32;
                heap.push(HeapItem(nd, next as u32));
            }
        }
    }

    /// The loop through the join `m`: the path from `start` to its first
    /// node, the edge, and the path from its second node to the target
    /// (the path from `start` to the node one winding down, walked back);
    /// `None` if an edge is missing (it cannot be).
    fn joined_loop(&self, graph: &WindingGraph, start: usize, m: Meeting) -> Option<WindingCycle> {
        let mut nodes = Vec::new();
        let mut at = m.from_start;
        while at != start {
            nodes.push(at);
            at = *self.prev.get(at)? as usize;
        }
        nodes.reverse();
        let mut at = shifted(m.from_target, -1)?;
        nodes.push(at);
        while at != start {
            at = *self.prev.get(at)? as usize;
            nodes.push(at);
        }
        let vertices: Vec<u32> = nodes.iter().map(|&n| (n / LAYERS) as u32).collect();
        let mut cost = 0.0;
        let mut from = (start / LAYERS) as u32;
        for &v in &vertices {
            cost += graph.edge_cost(from, v)?;
            from = v;
        }
        Some(WindingCycle { vertices, cost })
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

    /// The cheapest loop through each source by a plain one-sided search
    /// in the cover, the least (cost, position) of them: what a search
    /// from every source in order gives.
    fn searched_in_order(graph: &WindingGraph, sources: &[u32]) -> Option<WindingCycle> {
        let mut best: Option<WindingCycle> = None;
        for &s in sources {
            let n = graph.len() * LAYERS;
            let (mut dist, mut prev) = (vec![f64::INFINITY; n], vec![usize::MAX; n]);
            let (start, target) = (s as usize * LAYERS + START, s as usize * LAYERS + START + 1);
            dist[start] = 0.0;
            let mut heap = BinaryHeap::from([HeapItem(0.0, start as u32)]);
            while let Some(HeapItem(d, node)) = heap.pop() {
                let node = node as usize;
                if d > dist[node] || node == target {
                    continue;
                }
                for &(w, cost, step) in graph.neighbours(node / LAYERS) {
                    let l = (node % LAYERS) as i64 + i64::from(step);
                    if !(0..LAYERS as i64).contains(&l) {
                        continue;
                    }
                    let next = w as usize * LAYERS + l as usize;
                    if d + cost < dist[next] {
                        dist[next] = d + cost;
                        prev[next] = node;
                        heap.push(HeapItem(d + cost, next as u32));
                    }
                }
            }
            if best.as_ref().is_some_and(|b| b.cost <= dist[target]) || dist[target].is_infinite() {
                continue;
            }
            let mut vertices = Vec::new();
            let mut at = target;
            while at != start {
                vertices.push((at / LAYERS) as u32);
                at = prev[at];
            }
            vertices.reverse();
            best = Some(WindingCycle {
                vertices,
                cost: dist[target],
            });
        }
        best
    }

    #[test]
    fn the_searches_from_both_ends_find_the_loop_a_search_from_every_source_finds() {
        let (m, rings) = (30, 12);
        let (angles, mut edges) = cylinder(m, rings, rings);
        // Costs of no pattern (a fixed linear congruential sequence).
        let mut x = 12345u64;
        for e in &mut edges {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            e.2 *= 0.05 + (x >> 11) as f64 / (1u64 << 53) as f64;
        }
        let graph = WindingGraph::new(&angles, &edges, &vec![true; angles.len()]);
        for reverse in [false, true] {
            let mut sources = graph.seam_vertices();
            if reverse {
                sources.reverse();
            }
            let found = cheapest_winding_cycle(&graph, &sources).unwrap();
            let expected = searched_in_order(&graph, &sources).unwrap();
            assert_eq!(found.cost.to_bits(), expected.cost.to_bits());
            assert_eq!(found.vertices, expected.vertices);
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
