//! The search over disk automorphisms `m` for the smallest transport cost
//! between `m` applied to the first surface's samples and the second's:
//! candidate maps screened by entropic transport on a few samples, the
//! best solved exactly on all samples, the best of those refined.

use super::ground::{cost_matrix, truncated_hyperbolic_distance};
use super::sinkhorn::entropic_transport_cost;
use super::CwParams;
use crate::cp::{nelder_mead, Mobius};
use crate::cwn::{optimal_transport, TransportError, TransportPlan};

/// Weighted points of the disk: a surface's area measure at its samples.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct DiskMeasure {
    /// Disk positions.
    pub points: Vec<[f64; 2]>,
    /// Masses (sum 1).
    pub masses: Vec<f64>,
}

impl DiskMeasure {
    /// The measure on the first `k` points (the first farthest-point
    /// samples spread over the whole surface), each point's mass added to
    /// the nearest of them in the disk (the Euclidean distance, which
    /// unlike the hyperbolic one tells points on the rim apart).
    pub(super) fn coarse(&self, k: usize) -> DiskMeasure {
        let k = k.clamp(1, self.points.len().max(1));
        let points: Vec<[f64; 2]> = self.points.iter().take(k).copied().collect();
        let mut masses = vec![0.0; points.len()];
        for (z, &w) in self.points.iter().zip(&self.masses) {
            let nearest = points
                .iter()
                .enumerate()
                .map(|(i, c)| (i, (c[0] - z[0]).hypot(c[1] - z[1])))
                .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
                .map_or(0, |(i, _)| i);
            if let Some(m) = masses.get_mut(nearest) {
                *m += w;
            }
        }
        DiskMeasure { points, masses }
    }

    /// The points moved by `m`.
    fn moved(&self, m: &Mobius) -> Vec<[f64; 2]> {
        self.points.iter().map(|&z| m.apply(z)).collect()
    }
}

/// The exact transport between `a` moved by `m` and `b`.
pub(super) fn exact_transport(
    a: &DiskMeasure,
    b: &DiskMeasure,
    m: &Mobius,
    cap: f64,
) -> Result<TransportPlan, TransportError> {
    let cost = cost_matrix(&a.moved(m), &b.points, cap);
    optimal_transport(&a.masses, &b.masses, &cost)
}

/// The entropic transport cost between `a` moved by `m` and `b`.
fn screened_cost(a: &DiskMeasure, b: &DiskMeasure, m: &Mobius, params: &CwParams) -> f64 {
    let cost = cost_matrix(&a.moved(m), &b.points, params.cap);
    entropic_transport_cost(
        &a.masses,
        &b.masses,
        &cost,
        params.screen_epsilon,
        params.screen_iterations,
    )
}

/// The candidates ranked by screened cost, best first (ties by their
/// order): `(cost, index into maps)`.
pub(super) fn rank(
    a: &DiskMeasure,
    b: &DiskMeasure,
    maps: &[Mobius],
    params: &CwParams,
) -> Vec<(f64, usize)> {
    let mut ranked: Vec<(f64, usize)> = maps
        .iter()
        .enumerate()
        .map(|(k, m)| (screened_cost(a, b, m, params), k))
        .collect();
    ranked.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    ranked
}

/// `m ∘ φ` with φ the automorphism of parameters `(Re a, Im a, θ)`
/// (`z ↦ e^{iθ}(z − a)/(1 − āz)`); `None` far from the identity.
fn perturbed(m: &Mobius, x: [f64; 3]) -> Option<Mobius> {
    if x[0].hypot(x[1]) >= 0.9 || !x.iter().all(|v| v.is_finite()) {
        return None;
    }
    Some(m.compose(&Mobius::from_point_rotation([x[0], x[1]], x[2])))
}

/// The cost of the fixed plan `flows` when `a`'s points are moved by `m`.
fn plan_cost(
    a: &DiskMeasure,
    b: &DiskMeasure,
    m: &Mobius,
    flows: &[(u32, u32, f64)],
    cap: f64,
) -> f64 {
    flows
        .iter()
        .map(
            |&(i, j, f)| match (a.points.get(i as usize), b.points.get(j as usize)) {
                (Some(&z), Some(&w)) => f * truncated_hyperbolic_distance(m.apply(z), w, cap),
                _ => f64::MAX,
            },
        )
        .sum()
}

/// A map with its exact transport.
pub(super) struct Solved {
    /// The map from `a`'s disk to `b`'s.
    pub mobius: Mobius,
    /// The exact transport after the map.
    pub plan: TransportPlan,
    /// Exact transport problems solved on the way.
    pub solves: usize,
}

/// Lower the exact cost from `start` by alternating two steps that each
/// never raise it: for the current plan, the map that minimizes the
/// plan's cost (Nelder–Mead over nearby automorphisms, steps halved every
/// round), then the exact plan for that map. Stops after
/// `params.refine_rounds` rounds or when a round gains nothing.
pub(super) fn refine(
    a: &DiskMeasure,
    b: &DiskMeasure,
    start: Solved,
    params: &CwParams,
) -> Result<Solved, TransportError> {
    let mut best = start;
    let mut step = [0.05, 0.05, 0.2];
    for _ in 0..params.refine_rounds {
        let m0 = best.mobius;
        let flows = &best.plan.flows;
        let objective = |x: [f64; 3]| {
            perturbed(&m0, x).map_or(f64::MAX, |m| plan_cost(a, b, &m, flows, params.cap))
        };
        let (x, fx) = nelder_mead(objective, [0.0; 3], step, params.refine_evaluations);
        step = step.map(|s| 0.5 * s);
        let Some(m) = perturbed(&m0, x) else { break };
        if fx >= best.plan.cost {
            break;
        }
        let plan = exact_transport(a, b, &m, params.cap)?;
        best.solves += 1;
        // The plan's cost at m is an upper bound of the new exact cost, so
        // this holds up to rounding; a round that gains nothing ends it.
        if plan.cost < best.plan.cost * (1.0 - 1e-9) {
            best.mobius = m;
            best.plan = plan;
        } else {
            break;
        }
    }
    Ok(best)
}
