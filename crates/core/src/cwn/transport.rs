//! Exact discrete optimal transport (the Kantorovich problem) by the
//! network simplex method.
//!
//! The problem: given masses `a_i ≥ 0` (rows) and `b_j ≥ 0` (columns) of
//! equal total and a cost `c_ij`, find a plan `π_ij ≥ 0` with row sums `a`
//! and column sums `b` that minimizes `Σ π_ij c_ij`.
//!
//! Why our own solver: no maintained Rust crate offered an exact
//! min-cost-flow solver, and the problem here is small (a few hundred
//! nodes, tens of thousands of arcs).
//!
//! Design choices, each for robustness:
//! - Masses are scaled to a common integer total ([`MASS_UNITS`]) with
//!   largest-remainder rounding, so flows are exact integers: the ratio
//!   test, ties and the final feasibility check involve no rounding, and
//!   both marginals sum to exactly the same total. The rounding changes
//!   each mass by less than `2⁻⁴⁰` of the total, far below what matters.
//! - The spanning-tree basis is kept *strongly feasible* (Cunningham's
//!   rule for the leaving arc), which rules out cycling on the degenerate
//!   pivots that transport problems are full of (an assignment problem is
//!   degenerate at every vertex).
//! - The start is the all-artificial tree (every node hangs from an extra
//!   root by an arc of prohibitive cost), which is strongly feasible; real
//!   arcs enter by block search for the most negative reduced cost.
//! - Node potentials are updated only in the subtree that moves at each
//!   pivot; costs stay in `f64`.

/// Total of each marginal after scaling to integers (2⁴⁰).
const MASS_UNITS: i64 = 1 << 40;

/// One side of the transport problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marginal {
    /// The row masses (the first surface's samples).
    Rows,
    /// The column masses (the second surface's samples).
    Columns,
}

impl std::fmt::Display for Marginal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Marginal::Rows => "row",
            Marginal::Columns => "column",
        })
    }
}

/// Why a transport problem could not be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TransportError {
    /// One side has no mass points.
    #[error("empty marginal ({rows} rows, {columns} columns)")]
    Empty {
        /// Number of row masses.
        rows: usize,
        /// Number of column masses.
        columns: usize,
    },
    /// The cost matrix does not have `rows × columns` entries.
    #[error("cost matrix has {got} entries, expected {expected}")]
    CostShape {
        /// Entries given.
        got: usize,
        /// `rows × columns`.
        expected: usize,
    },
    /// A mass is negative or not finite.
    #[error("invalid masses: {side} mass {index} is {mass} (negative or not finite)")]
    InvalidMass {
        /// The side it is on.
        side: Marginal,
        /// Its index on that side.
        index: usize,
        /// The mass.
        mass: f64,
    },
    /// A side's masses do not sum to a positive finite total.
    #[error("invalid masses: the {side} masses sum to {total}")]
    NoMass {
        /// The side.
        side: Marginal,
        /// Their sum.
        total: f64,
    },
    /// A cost is not finite.
    #[error("a transport cost is not finite")]
    InvalidCost,
    /// The simplex did not finish (should not happen: a guard against
    /// numerical trouble in the costs).
    #[error("the network simplex did not converge after {0} pivots")]
    NoConvergence(usize),
}

/// An optimal transport plan.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct TransportPlan {
    /// `Σ π_ij c_ij` with both marginals normalized to total 1.
    pub cost: f64,
    /// The cells with positive mass: `(row, column, mass)`, masses
    /// summing to 1, in row-major order.
    pub flows: Vec<(u32, u32, f64)>,
    /// Simplex pivots that were needed.
    pub pivots: usize,
}

/// Scale non-negative masses to integers summing exactly to
/// [`MASS_UNITS`] (largest remainder; ties to the lower index so the
/// result is deterministic).
fn integer_masses(masses: &[f64], side: Marginal) -> Result<Vec<i64>, TransportError> {
    if let Some(index) = masses.iter().position(|&m| !(m.is_finite() && m >= 0.0)) {
        return Err(TransportError::InvalidMass {
            side,
            index,
            mass: masses[index],
        });
    }
    let total: f64 = masses.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return Err(TransportError::NoMass { side, total });
    }
    let scaled: Vec<f64> = masses
        .iter()
        .map(|&m| m / total * MASS_UNITS as f64)
        .collect();
    let mut units: Vec<i64> = scaled.iter().map(|&s| s.floor() as i64).collect();
    let missing = MASS_UNITS - units.iter().sum::<i64>();
    let mut order: Vec<usize> = (0..masses.len()).collect();
    order.sort_by(|&i, &j| {
        let (ri, rj) = (scaled[i] - scaled[i].floor(), scaled[j] - scaled[j].floor());
        rj.total_cmp(&ri).then(i.cmp(&j))
    });
    // `missing` is below the number of masses (each floor loses < 1), but
    // float rounding of huge counts could push it past: spread cyclically.
    for k in 0..missing.max(0) as usize {
        units[order[k % order.len()]] += 1;
    }
    Ok(units)
}

/// The network: row nodes `0..n`, column nodes `n..n+m`, the artificial
/// root `n+m`. Real arc `i*m + j` goes from row `i` to column `j`;
/// artificial arc `n*m + v` joins node `v` and the root. The basic arcs
/// form a spanning tree hanging from the root.
struct Network<'a> {
    n: usize,
    m: usize,
    cost: &'a [f64],
    artificial_cost: f64,
    /// Source and target of the artificial arcs (real arcs are implicit).
    art_ends: Vec<(usize, usize)>,
    flow: Vec<i64>,
    basic: Vec<bool>,
    /// Basic arcs at each node.
    tree_arcs: Vec<Vec<u32>>,
    parent: Vec<usize>,
    pred: Vec<u32>,
    /// Whether `pred[v]` points from `v` to its parent.
    pred_up: Vec<bool>,
    depth: Vec<u32>,
    potential: Vec<f64>,
}

/// The cycle an entering arc closes in the tree: the arc from `first` to
/// `second`, then the tree path from `second` up to `join`, then down to
/// `first`.
struct Cycle {
    arc: u32,
    first: usize,
    second: usize,
    join: usize,
}

/// The arc that leaves the basis on a cycle: the tree arc above `node`,
/// whether it is on the `second` side of the cycle, and the flow `delta`
/// that the pivot pushes around the cycle.
struct Leaving {
    node: usize,
    on_second_side: bool,
    delta: i64,
}

impl<'a> Network<'a> {
    /// The all-artificial tree (every node hangs from the root by its
    /// artificial arc, which carries the node's supply or demand): a
    /// strongly feasible start. The artificial cost exceeds every real
    /// path, so the simplex drives artificial flow out.
    fn initial_feasible_tree(supply: &[i64], demand: &[i64], cost: &'a [f64]) -> Self {
        let (n, m) = (supply.len(), demand.len());
        let nodes = n + m + 1;
        let root = n + m;
        let max_cost = cost.iter().fold(0.0f64, |a, &c| a.max(c.abs()));
        // Any tree path has fewer than `nodes` arcs, so one artificial arc
        // costs more than every real path: artificial flow is driven out.
        let artificial_cost = (max_cost + 1.0) * nodes as f64;
        let real = n * m;
        let mut art_ends = Vec::with_capacity(n + m);
        let mut flow = vec![0i64; real + n + m];
        for (i, &s) in supply.iter().enumerate() {
            // Positive supply flows up to the root; a zero-supply row gets an
            // arc pointing away from the root (strong feasibility).
            art_ends.push(if s > 0 { (i, root) } else { (root, i) });
            flow[real + i] = s;
        }
        for (j, &d) in demand.iter().enumerate() {
            art_ends.push((root, n + j));
            flow[real + n + j] = d;
        }
        let mut net = Network {
            n,
            m,
            cost,
            artificial_cost,
            art_ends,
            flow,
            basic: vec![false; real + n + m],
            tree_arcs: vec![Vec::new(); nodes],
            parent: vec![root; nodes],
            pred: vec![u32::MAX; nodes],
            pred_up: vec![false; nodes],
            depth: vec![0; nodes],
            potential: vec![0.0; nodes],
        };
        for v in 0..n + m {
            let e = (real + v) as u32;
            net.basic[e as usize] = true;
            net.tree_arcs[v].push(e);
            net.tree_arcs[root].push(e);
            let (s, _) = net.ends(e);
            net.parent[v] = root;
            net.pred[v] = e;
            net.pred_up[v] = s == v;
            net.depth[v] = 1;
            net.potential[v] = net.potential_below(root, e, s == v);
        }
        net
    }

    fn real_arcs(&self) -> usize {
        self.n * self.m
    }

    fn nodes(&self) -> usize {
        self.n + self.m + 1
    }

    fn ends(&self, arc: u32) -> (usize, usize) {
        let a = arc as usize;
        if a < self.n * self.m {
            (a / self.m, self.n + a % self.m)
        } else {
            self.art_ends[a - self.n * self.m]
        }
    }

    fn arc_cost(&self, arc: u32) -> f64 {
        let a = arc as usize;
        if a < self.n * self.m {
            self.cost[a]
        } else {
            self.artificial_cost
        }
    }

    /// The potential of a node hung from `parent` by the basic `arc`
    /// (pointing up to the parent when `up`): basic arcs have zero reduced
    /// cost.
    fn potential_below(&self, parent: usize, arc: u32, up: bool) -> f64 {
        let c = self.arc_cost(arc);
        if up {
            self.potential[parent] - c
        } else {
            self.potential[parent] + c
        }
    }

    /// Reduced cost `c + π(source) − π(target)` of a real arc.
    #[inline]
    fn reduced_cost(&self, arc: usize) -> f64 {
        let (i, j) = (arc / self.m, arc % self.m);
        self.cost[arc] + self.potential[i] - self.potential[self.n + j]
    }

    /// The entering arc by block search: from the arc after the last one
    /// scanned (`next`, advanced cyclically), blocks of `block` arcs, the
    /// most negative reduced cost below `-tolerance` in the first block
    /// that has one. `None` when no arc has one: the tree is optimal.
    fn entering_arc(&self, next: &mut usize, block: usize, tolerance: f64) -> Option<u32> {
        let real = self.real_arcs();
        let mut entering: Option<(usize, f64)> = None;
        let mut scanned = 0usize;
        let mut in_block = 0usize;
        while scanned < real {
            let a = *next;
            *next += 1;
            if *next == real {
                *next = 0;
            }
            scanned += 1;
            in_block += 1;
            if !self.basic[a] {
                let rc = self.reduced_cost(a);
                if rc < -tolerance && entering.is_none_or(|(_, best)| rc < best) {
                    entering = Some((a, rc));
                }
            }
            if in_block == block {
                if entering.is_some() {
                    break;
                }
                in_block = 0;
            }
        }
        entering.map(|(a, _)| a as u32)
    }

    /// The cycle that `arc` closes: its ends and their nearest common
    /// ancestor in the tree.
    fn cycle(&self, arc: u32) -> Cycle {
        let (first, second) = self.ends(arc);
        let (mut u, mut v) = (first, second);
        while u != v {
            if self.depth[u] >= self.depth[v] {
                u = self.parent[u];
            } else {
                v = self.parent[v];
            }
        }
        Cycle {
            arc,
            first,
            second,
            join: u,
        }
    }

    /// The leaving arc (strongly feasible rule): the last blocking arc met
    /// going around the cycle from the join in the flow's direction —
    /// strict comparison on the first side, non-strict on the second.
    /// `None` if nothing blocks (an unbounded problem, impossible here).
    fn leaving_arc(&self, cycle: &Cycle) -> Option<Leaving> {
        let mut delta = i64::MAX;
        let mut leaving: Option<usize> = None;
        let mut u = cycle.first;
        while u != cycle.join {
            // Flow runs parent → u here: it decreases on arcs u → parent.
            if self.pred_up[u] {
                let d = self.flow[self.pred[u] as usize];
                if d < delta {
                    delta = d;
                    leaving = Some(u);
                }
            }
            u = self.parent[u];
        }
        let mut on_second_side = false;
        let mut u = cycle.second;
        while u != cycle.join {
            // Flow runs u → parent: it decreases on arcs parent → u.
            if !self.pred_up[u] {
                let d = self.flow[self.pred[u] as usize];
                if d <= delta {
                    delta = d;
                    leaving = Some(u);
                    on_second_side = true;
                }
            }
            u = self.parent[u];
        }
        leaving.map(|node| Leaving {
            node,
            on_second_side,
            delta,
        })
    }

    /// Push `delta` units around the cycle, in the direction of its arc.
    fn augment(&mut self, cycle: &Cycle, delta: i64) {
        if delta <= 0 {
            return;
        }
        self.flow[cycle.arc as usize] += delta;
        let mut u = cycle.first;
        while u != cycle.join {
            let e = self.pred[u] as usize;
            self.flow[e] += if self.pred_up[u] { -delta } else { delta };
            u = self.parent[u];
        }
        let mut u = cycle.second;
        while u != cycle.join {
            let e = self.pred[u] as usize;
            self.flow[e] += if self.pred_up[u] { delta } else { -delta };
            u = self.parent[u];
        }
    }

    /// Re-hang the subtree containing `start` below `new_parent` through
    /// `arc`, updating parent, depth and potential of its nodes only.
    fn rehang(&mut self, start: usize, new_parent: usize, arc: u32) {
        let mut stack = vec![(start, new_parent, arc)];
        while let Some((v, p, e)) = stack.pop() {
            let (s, _) = self.ends(e);
            let up = s == v;
            self.parent[v] = p;
            self.pred[v] = e;
            self.pred_up[v] = up;
            self.depth[v] = self.depth[p] + 1;
            self.potential[v] = self.potential_below(p, e, up);
            for &f in &self.tree_arcs[v] {
                if f == e {
                    continue;
                }
                let (a, b) = self.ends(f);
                let w = if a == v { b } else { a };
                stack.push((w, v, f));
            }
        }
    }

    /// One pivot: push flow around the cycle of the entering arc, swap the
    /// entering and the leaving arc in the basis and re-hang the subtree
    /// the leaving arc cut off. `None` if no arc can leave.
    fn pivot(&mut self, in_arc: u32) -> Option<()> {
        let cycle = self.cycle(in_arc);
        let leaving = self.leaving_arc(&cycle)?;
        self.augment(&cycle, leaving.delta);
        let out_arc = self.pred[leaving.node];
        let (oa, ob) = self.ends(out_arc);
        for v in [oa, ob] {
            if let Some(k) = self.tree_arcs[v].iter().position(|&e| e == out_arc) {
                self.tree_arcs[v].swap_remove(k);
            }
        }
        self.basic[out_arc as usize] = false;
        self.basic[in_arc as usize] = true;
        self.tree_arcs[cycle.first].push(in_arc);
        self.tree_arcs[cycle.second].push(in_arc);
        // The subtree below the leaving arc contains `first` when that arc
        // is on the first side, else `second`; it hangs on the other end.
        if leaving.on_second_side {
            self.rehang(cycle.second, cycle.first, in_arc);
        } else {
            self.rehang(cycle.first, cycle.second, in_arc);
        }
        Some(())
    }

    /// Pivot until no arc has a negative reduced cost; returns the number
    /// of pivots.
    fn optimize(&mut self) -> Result<usize, TransportError> {
        let (real, nodes) = (self.real_arcs(), self.nodes());
        // Reduced costs above −tolerance count as optimal: potentials are sums
        // of up to `nodes` costs of size ≤ artificial_cost.
        let tolerance = 1e-12 * self.artificial_cost * nodes as f64;
        let block = ((real as f64).sqrt().ceil() as usize).clamp(16, real.max(16));
        let max_pivots = 200 * (real + nodes) + 10_000;
        let mut next = 0usize;
        let mut pivots = 0usize;
        while let Some(in_arc) = self.entering_arc(&mut next, block, tolerance) {
            pivots += 1;
            if pivots > max_pivots {
                return Err(TransportError::NoConvergence(pivots));
            }
            // Unbounded cannot happen: no directed cycle exists in this
            // network. Treat as a solver failure rather than loop.
            self.pivot(in_arc)
                .ok_or(TransportError::NoConvergence(pivots))?;
        }
        Ok(pivots)
    }

    /// The plan of the optimal tree's flows (masses back to total 1).
    fn plan(&self, pivots: usize) -> Result<TransportPlan, TransportError> {
        let real = self.real_arcs();
        if self.flow[real..].iter().any(|&f| f != 0) {
            // Equal integer totals make the problem feasible; artificial flow
            // left means the costs defeated the simplex.
            return Err(TransportError::NoConvergence(pivots));
        }
        let scale = MASS_UNITS as f64;
        let mut total = 0.0;
        let mut flows = Vec::new();
        for (a, &f) in self.flow[..real].iter().enumerate() {
            if f > 0 {
                let mass = f as f64 / scale;
                total += mass * self.cost[a];
                flows.push(((a / self.m) as u32, (a % self.m) as u32, mass));
            }
        }
        Ok(TransportPlan {
            cost: total,
            flows,
            pivots,
        })
    }
}

/// Solve the transport problem exactly. `cost` is row-major
/// (`cost[i * columns + j]`); masses are normalized to total 1 on each
/// side. Deterministic: the same input gives the same plan.
pub(crate) fn optimal_transport(
    rows: &[f64],
    columns: &[f64],
    cost: &[f64],
) -> Result<TransportPlan, TransportError> {
    let (n, m) = (rows.len(), columns.len());
    if n == 0 || m == 0 {
        return Err(TransportError::Empty {
            rows: n,
            columns: m,
        });
    }
    if cost.len() != n * m {
        return Err(TransportError::CostShape {
            got: cost.len(),
            expected: n * m,
        });
    }
    if cost.iter().any(|c| !c.is_finite()) {
        return Err(TransportError::InvalidCost);
    }
    let supply = integer_masses(rows, Marginal::Rows)?;
    let demand = integer_masses(columns, Marginal::Columns)?;
    let mut net = Network::initial_feasible_tree(&supply, &demand, cost);
    let pivots = net.optimize()?;
    net.plan(pivots)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn rng(seed: u64) -> rand_chacha::ChaCha8Rng {
        rand_chacha::ChaCha8Rng::seed_from_u64(seed)
    }

    /// Minimum over all permutations of `Σ c[i][σ(i)] / n`.
    fn best_permutation(n: usize, cost: &[f64]) -> f64 {
        fn rec(k: usize, n: usize, used: &mut [bool], acc: f64, cost: &[f64], best: &mut f64) {
            if k == n {
                *best = best.min(acc);
                return;
            }
            for j in 0..n {
                if !used[j] {
                    used[j] = true;
                    rec(k + 1, n, used, acc + cost[k * n + j], cost, best);
                    used[j] = false;
                }
            }
        }
        let mut best = f64::INFINITY;
        rec(0, n, &mut vec![false; n], 0.0, cost, &mut best);
        best / n as f64
    }

    /// Brute force over all bases: every set of `n + m − 1` cells that
    /// forms a spanning tree of the bipartite graph determines a unique
    /// flow; the best non-negative one is optimal (an LP optimum is attained
    /// at a vertex, and every vertex is such a basic solution).
    fn best_basic_solution(a: &[f64], b: &[f64], cost: &[f64]) -> f64 {
        let (n, m) = (a.len(), b.len());
        let cells = n * m;
        let k = n + m - 1;
        let mut best = f64::INFINITY;
        for mask in 0u32..(1 << cells) {
            if mask.count_ones() as usize != k {
                continue;
            }
            let chosen: Vec<usize> = (0..cells).filter(|c| mask & (1 << c) != 0).collect();
            // Leaf elimination: repeatedly settle a node with one open cell.
            let mut row_left = a.to_vec();
            let mut col_left = b.to_vec();
            let mut open = chosen.clone();
            let mut x = vec![0.0; cells];
            let mut ok = true;
            while !open.is_empty() {
                let mut progressed = false;
                for v in 0..n + m {
                    let here: Vec<usize> = open
                        .iter()
                        .copied()
                        .filter(|&c| if v < n { c / m == v } else { c % m == v - n })
                        .collect();
                    if here.len() == 1 {
                        let c = here[0];
                        let val = if v < n { row_left[v] } else { col_left[v - n] };
                        x[c] = val;
                        row_left[c / m] -= val;
                        col_left[c % m] -= val;
                        open.retain(|&d| d != c);
                        progressed = true;
                        break;
                    }
                }
                if !progressed {
                    // A cycle: not a tree.
                    ok = false;
                    break;
                }
            }
            let balanced = row_left.iter().chain(&col_left).all(|r| r.abs() < 1e-12);
            if ok && balanced && x.iter().all(|&v| v >= -1e-12) {
                let c: f64 = chosen.iter().map(|&c| x[c] * cost[c]).sum();
                best = best.min(c);
            }
        }
        best
    }

    fn check_plan(plan: &TransportPlan, a: &[f64], b: &[f64], cost: &[f64]) {
        let (n, m) = (a.len(), b.len());
        let (ta, tb): (f64, f64) = (a.iter().sum(), b.iter().sum());
        let mut rs = vec![0.0; n];
        let mut cs = vec![0.0; m];
        let mut c = 0.0;
        for &(i, j, f) in &plan.flows {
            assert!(f > 0.0);
            rs[i as usize] += f;
            cs[j as usize] += f;
            c += f * cost[i as usize * m + j as usize];
        }
        for i in 0..n {
            assert!((rs[i] - a[i] / ta).abs() < 1e-9, "row {i}");
        }
        for j in 0..m {
            assert!((cs[j] - b[j] / tb).abs() < 1e-9, "column {j}");
        }
        assert!((c - plan.cost).abs() < 1e-12);
    }

    #[test]
    fn equal_masses_match_the_best_permutation() {
        let mut r = rng(1);
        for n in 1..=6 {
            for trial in 0..40 {
                // Integer costs give many ties and degenerate pivots.
                let cost: Vec<f64> = (0..n * n)
                    .map(|_| {
                        if trial % 2 == 0 {
                            r.gen_range(0..4) as f64
                        } else {
                            r.gen::<f64>()
                        }
                    })
                    .collect();
                let w = vec![1.0; n];
                let plan = optimal_transport(&w, &w, &cost).unwrap();
                check_plan(&plan, &w, &w, &cost);
                let want = best_permutation(n, &cost);
                assert!(
                    (plan.cost - want).abs() < 1e-9,
                    "n={n} trial={trial}: {} vs {want}",
                    plan.cost
                );
            }
        }
    }

    #[test]
    fn unequal_masses_match_brute_force() {
        let mut r = rng(2);
        for &(n, m) in &[
            (1, 3),
            (2, 2),
            (2, 3),
            (3, 2),
            (3, 3),
            (2, 4),
            (4, 2),
            (3, 4),
        ] {
            for trial in 0..25 {
                let mut a: Vec<f64> = (0..n).map(|_| r.gen_range(1..6) as f64).collect();
                let mut b: Vec<f64> = (0..m).map(|_| r.gen_range(1..6) as f64).collect();
                if trial % 2 == 0 {
                    // Same integer total on both sides: partial sums tie
                    // often, so pivots are degenerate.
                    let total = (n + m) as u32 * 2;
                    let split = |k: usize, r: &mut rand_chacha::ChaCha8Rng| {
                        let mut v = vec![1.0; k];
                        for _ in 0..total as usize - k {
                            v[r.gen_range(0..k)] += 1.0;
                        }
                        v
                    };
                    a = split(n, &mut r);
                    b = split(m, &mut r);
                }
                let (ta, tb): (f64, f64) = (a.iter().sum(), b.iter().sum());
                a.iter_mut().for_each(|x| *x /= ta);
                b.iter_mut().for_each(|x| *x /= tb);
                let cost: Vec<f64> = (0..n * m)
                    .map(|_| {
                        if trial % 3 == 0 {
                            r.gen_range(0..3) as f64
                        } else {
                            r.gen::<f64>()
                        }
                    })
                    .collect();
                let plan = optimal_transport(&a, &b, &cost).unwrap();
                check_plan(&plan, &a, &b, &cost);
                let want = best_basic_solution(&a, &b, &cost);
                assert!(
                    (plan.cost - want).abs() < 1e-9,
                    "{n}×{m} trial {trial}: {} vs {want}",
                    plan.cost
                );
            }
        }
    }

    #[test]
    fn zero_masses_and_constant_costs_are_handled() {
        let a = [0.5, 0.0, 0.5];
        let b = [0.0, 1.0];
        let cost = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let plan = optimal_transport(&a, &b, &cost).unwrap();
        check_plan(&plan, &a, &b, &cost);
        assert!((plan.cost - 4.0).abs() < 1e-12);
        // All costs equal: every plan is optimal; the value is that cost.
        let plan = optimal_transport(&[1.0; 5], &[2.0; 4], &[0.7; 20]).unwrap();
        assert!((plan.cost - 0.7).abs() < 1e-12);
    }

    #[test]
    fn larger_problems_agree_with_their_transpose_and_beat_north_west() {
        // Beyond brute force: the transposed problem (a different pivot
        // path) reaches the same value, and no simple feasible plan does
        // better.
        let mut r = rng(3);
        for &(n, m) in &[(30, 40), (60, 60)] {
            let a: Vec<f64> = (0..n).map(|_| r.gen_range(0.1..1.0)).collect();
            let b: Vec<f64> = (0..m).map(|_| r.gen_range(0.1..1.0)).collect();
            let cost: Vec<f64> = (0..n * m).map(|_| r.gen::<f64>()).collect();
            let plan = optimal_transport(&a, &b, &cost).unwrap();
            check_plan(&plan, &a, &b, &cost);
            // Feasible alternative: the north-west corner plan.
            let (ta, tb): (f64, f64) = (a.iter().sum(), b.iter().sum());
            let mut ra: Vec<f64> = a.iter().map(|x| x / ta).collect();
            let mut rb: Vec<f64> = b.iter().map(|x| x / tb).collect();
            let (mut i, mut j, mut nw) = (0, 0, 0.0);
            while i < n && j < m {
                let f = ra[i].min(rb[j]);
                nw += f * cost[i * m + j];
                ra[i] -= f;
                rb[j] -= f;
                if ra[i] <= 1e-15 {
                    i += 1;
                } else {
                    j += 1;
                }
            }
            assert!(plan.cost <= nw + 1e-12);
            let transposed: Vec<f64> = (0..m * n).map(|k| cost[(k % n) * m + k / n]).collect();
            let back = optimal_transport(&b, &a, &transposed).unwrap();
            assert!((back.cost - plan.cost).abs() < 1e-12);
            // Basic solutions have at most n + m − 1 positive cells.
            assert!(plan.flows.len() < n + m);
            // Same input, same plan.
            assert_eq!(optimal_transport(&a, &b, &cost).unwrap(), plan);
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        assert!(matches!(
            optimal_transport(&[], &[1.0], &[]),
            Err(TransportError::Empty { .. })
        ));
        assert!(matches!(
            optimal_transport(&[1.0], &[1.0], &[1.0, 2.0]),
            Err(TransportError::CostShape { .. })
        ));
        assert_eq!(
            optimal_transport(&[1.0], &[2.0, -1.0], &[1.0, 2.0]),
            Err(TransportError::InvalidMass {
                side: Marginal::Columns,
                index: 1,
                mass: -1.0
            })
        );
        assert!(matches!(
            optimal_transport(&[0.0], &[1.0], &[1.0]),
            Err(TransportError::NoMass {
                side: Marginal::Rows,
                ..
            })
        ));
        assert!(matches!(
            optimal_transport(&[1.0], &[1.0], &[f64::NAN]),
            Err(TransportError::InvalidCost)
        ));
    }
}
