//! The conformal Wasserstein distance (cW) of Boyer et al. (PNAS 2011,
//! section 2), after Lipman & Daubechies: the optimal-transport distance
//! between the conformal densities of two surfaces, minimized over the
//! disk automorphisms (Möbius maps) `m` that relate their flattenings,
//!
//! `cW(S, S′) = min_m min_{π ∈ Π(m_* μ, μ′)} ∫ d(z, z′) dπ(z, z′)`,
//!
//! with `μ` the surface's area carried to its disk by the flattening and
//! `d` the hyperbolic distance (truncated, see
//! [`truncated_hyperbolic_distance`]). Discretely, `μ` is the cP samples
//! with their Voronoi areas (`Prepared::samples`, `sample_weights`):
//! pushing `μ` forward by `m` moves the points and keeps the masses.
//!
//! The search ([`distance`]), for one direction `S → S′`:
//! 1. the maps cP's search starts from (feature pairs × rotation angles,
//!    both orientations unless reflections are off);
//! 2. each screened by the entropic (Sinkhorn) transport cost between the
//!    first [`CwParams::screen_samples`] samples (with the masses of the
//!    others added to their nearest) — cheap and approximate;
//! 3. the best [`CwParams::exact_candidates`] solved exactly on all
//!    samples (cWn's network simplex);
//! 4. the best [`CwParams::refine_candidates`] of those refined by
//!    alternating the map minimizing the current plan's cost (Nelder–Mead
//!    over the three-dimensional group near it) with the exact plan for
//!    the new map; neither step raises the cost.
//!
//! The value returned is the exact transport cost of the best map found:
//! an upper bound of the discrete cW, as the minimum over maps is
//! searched. Everything is sequential and deterministic; matrices
//! parallelize over pairs.

mod ground;
mod measure;
mod search;
mod sinkhorn;

use crate::cp::{self, CpError, Directed, Mobius, ParamError, Prepared, Requirement};
use crate::cwn::TransportError;
use search::{exact_transport, rank, refine, DiskMeasure, Solved};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Parameters of the cW distance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CwParams {
    /// Rotation angles tried for each feature pair.
    pub angles: usize,
    /// Whether orientation-reversing maps (mirror images) are searched.
    pub reflections: bool,
    /// The ground cost's cap `min(d, cap)` (hyperbolic units; the distance
    /// from the centre to `|z| = tanh(cap/2)`).
    pub cap: f64,
    /// Samples (the first, farthest-point ones) of the screening.
    pub screen_samples: usize,
    /// Entropic regularization of the screening, relative to the mean
    /// ground cost.
    pub screen_epsilon: f64,
    /// Sinkhorn sweeps of the screening.
    pub screen_iterations: usize,
    /// Best screened maps solved exactly on all samples.
    pub exact_candidates: usize,
    /// Best exactly solved maps that are refined.
    pub refine_candidates: usize,
    /// Rounds (plan → map → plan) of the refinement of each.
    pub refine_rounds: usize,
    /// Nelder–Mead evaluations per round.
    pub refine_evaluations: usize,
}

impl Default for CwParams {
    fn default() -> Self {
        Self {
            angles: 12,
            reflections: true,
            cap: 4.0,
            screen_samples: 30,
            screen_epsilon: 0.05,
            screen_iterations: 20,
            exact_candidates: 6,
            refine_candidates: 1,
            refine_rounds: 4,
            refine_evaluations: 60,
        }
    }
}

impl CwParams {
    /// Check the values; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ParamError> {
        for (key, value) in [("cap", self.cap), ("screen_epsilon", self.screen_epsilon)] {
            cp::check(
                key,
                value,
                Requirement::Positive,
                value.is_finite() && value > 0.0,
            )?;
        }
        for (key, value, min, max) in [
            ("angles", self.angles, 1, 720),
            ("screen_samples", self.screen_samples, 1, 100_000),
            ("screen_iterations", self.screen_iterations, 1, 100_000),
            ("exact_candidates", self.exact_candidates, 1, 100_000),
            ("refine_candidates", self.refine_candidates, 0, 100_000),
            ("refine_rounds", self.refine_rounds, 0, 1000),
            ("refine_evaluations", self.refine_evaluations, 0, 100_000),
        ] {
            cp::check_count(key, value, min, max)?;
        }
        Ok(())
    }
}

/// Why a cW distance could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CwError {
    /// Invalid parameters.
    #[error("invalid cW parameters: {0}")]
    Params(#[from] ParamError),
    /// A prepared surface is inconsistent.
    #[error("`{name}`: {source}")]
    Prepared {
        /// The surface.
        name: String,
        /// What is wrong with it.
        #[source]
        source: CpError,
    },
    /// A transport problem failed.
    #[error("transport between `{a}` and `{b}`: {source}")]
    Transport {
        /// The first surface.
        a: String,
        /// The second surface.
        b: String,
        /// Why.
        #[source]
        source: TransportError,
    },
}

/// The cW distance of two surfaces and the map it was found at.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CwResult {
    /// `Σ πᵢⱼ min(d(m(zᵢ), z′ⱼ), cap)` for the best map `m` found and its
    /// exact optimal plan `π` (masses sum to 1).
    pub distance: f64,
    /// The best map, from the first surface's disk to the second's.
    pub mobius: Mobius,
    /// Whether it reverses orientation (a mirror-image match).
    pub reflected: bool,
    /// The optimal plan at that map: `(sample of A, sample of B, mass)`.
    pub plan: Vec<(u32, u32, f64)>,
    /// Candidate maps screened.
    pub screened: usize,
    /// Exact transport problems solved.
    pub exact_solves: usize,
    /// Milliseconds spent screening.
    pub screen_ms: f64,
    /// Milliseconds spent on exact transport and refinement.
    pub exact_ms: f64,
}

/// The area measure of a prepared surface in its disk (see
/// `measure::area_measure`), after checking the surface.
fn sample_measure(p: &Prepared) -> Result<DiskMeasure, CwError> {
    p.validate().map_err(|source| CwError::Prepared {
        name: p.name().to_string(),
        source,
    })?;
    Ok(measure::area_measure(p))
}

/// The maps the search starts from: cP's (feature pairs × angles ×
/// orientations), or rotations about the centre if there are none.
fn starting_maps(a: &Prepared, b: &Prepared, params: &CwParams) -> Vec<Mobius> {
    let maps = cp::candidate_maps(a, b, params.angles, params.reflections);
    if !maps.is_empty() {
        return maps;
    }
    let orientations: &[bool] = if params.reflections {
        &[false, true]
    } else {
        &[false]
    };
    let angles = params.angles.max(1);
    orientations
        .iter()
        .flat_map(|&r| {
            (0..angles).map(move |k| {
                let th = k as f64 / angles as f64 * std::f64::consts::TAU;
                Mobius::sending([0.0, 0.0], [0.0, 0.0], th, r)
            })
        })
        .collect()
}

/// The cW distance from `a` to `b` (the steps in the module doc).
pub fn distance(a: &Prepared, b: &Prepared, params: &CwParams) -> Result<CwResult, CwError> {
    params.validate()?;
    let _span = tracing::debug_span!("cw", a = %a.name(), b = %b.name()).entered();
    let transport = |source| CwError::Transport {
        a: a.name().to_string(),
        b: b.name().to_string(),
        source,
    };
    let (ma, mb) = (sample_measure(a)?, sample_measure(b)?);
    let t = Instant::now();
    let maps = starting_maps(a, b, params);
    let (ca, cb) = (
        ma.coarse(params.screen_samples),
        mb.coarse(params.screen_samples),
    );
    let ranked = rank(&ca, &cb, &maps, params);
    let screen_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let mut solved = Vec::new();
    for &(_, k) in ranked.iter().take(params.exact_candidates.max(1)) {
        let mobius = maps[k];
        let plan = exact_transport(&ma, &mb, &mobius, params.cap).map_err(transport)?;
        solved.push(Solved {
            mobius,
            plan,
            solves: 1,
        });
    }
    // Stable: ties keep the screening order.
    solved.sort_by(|x, y| x.plan.cost.total_cmp(&y.plan.cost));
    let mut solves = solved.len();
    let mut best: Option<Solved> = None;
    for (rank, s) in solved.into_iter().enumerate() {
        let s = if rank < params.refine_candidates {
            let r = refine(&ma, &mb, s, params).map_err(transport)?;
            solves += r.solves - 1;
            r
        } else {
            s
        };
        if best.as_ref().is_none_or(|b| s.plan.cost < b.plan.cost) {
            best = Some(s);
        }
    }
    let exact_ms = t.elapsed().as_secs_f64() * 1e3;
    let best = best.ok_or_else(|| {
        transport(TransportError::Empty {
            rows: ma.points.len(),
            columns: mb.points.len(),
        })
    })?;
    Ok(CwResult {
        distance: best.plan.cost,
        reflected: best.mobius.reverses_orientation(),
        mobius: best.mobius,
        plan: best.plan.flows,
        screened: maps.len(),
        exact_solves: solves,
        screen_ms,
        exact_ms,
    })
}

/// The correspondence of cW's map from `a` to `b`, as cP returns its own
/// (`Directed::correspondence`, for `--map` and landmark propagation):
/// the Möbius map evaluated on every vertex of `a`, with the optimal
/// rigid motion; its `distance` is that map's Procrustes residual (not
/// cW). `None` only for a target without triangles.
pub fn correspondence(a: &Prepared, b: &Prepared, result: &CwResult) -> Option<Directed> {
    cp::directed_for_mobius(a, b, result.mobius)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cp::PrepareParams;
    use crate::testing::synth::{self, CROWN_GENERA};

    fn crown(
        genus: usize,
        seed: u64,
        edit: impl Fn(crate::mesh::Mesh) -> crate::mesh::Mesh,
    ) -> Prepared {
        let m = edit(synth::crown(&CROWN_GENERA[genus], seed, 1500));
        cp::prepare(&m, &PrepareParams::default()).expect("a synthetic crown prepares")
    }

    fn no_reflections() -> CwParams {
        CwParams {
            reflections: false,
            ..CwParams::default()
        }
    }

    #[test]
    fn a_mobius_moved_copy_of_the_density_is_at_distance_zero() {
        let params = CwParams::default();
        let a = crown(1, 3, |m| m);
        let other = crown(3, 4, |m| m);
        let apart = distance(&a, &other, &params).unwrap().distance;
        for reflect in [false, true] {
            let mob = Mobius::sending([0.05, 0.1], [-0.2, 0.15], 0.9, reflect);
            let b = a.reflattened(|z| mob.apply(z));
            let r = distance(&a, &b, &params).unwrap();
            println!(
                "moved copy ({reflect}): {} vs another crown {apart}",
                r.distance
            );
            // Zero up to the local refinement's tolerance.
            assert!(r.distance < 5e-3 * apart, "{} vs {apart}", r.distance);
            assert_eq!(r.reflected, reflect);
            // The map found is the one applied: the samples land on
            // themselves.
            for &v in a.samples() {
                let (z, w) = (r.mobius.apply(a.uv()[v as usize]), b.uv()[v as usize]);
                assert!((z[0] - w[0]).hypot(z[1] - w[1]) < 1e-2, "{z:?} vs {w:?}");
            }
        }
    }

    #[test]
    fn a_mirror_image_matches_through_a_reflection_only_when_reflections_are_on() {
        let a = crown(0, 1, |m| m);
        let b = crown(0, 1, |m| synth::mirror(&m));
        let other = crown(2, 9, |m| m);
        let apart = distance(&a, &other, &CwParams::default()).unwrap().distance;
        let with = distance(&a, &b, &CwParams::default()).unwrap();
        let without = distance(&a, &b, &no_reflections()).unwrap();
        println!(
            "mirror: with {} without {} apart {apart}",
            with.distance, without.distance
        );
        assert!(with.reflected && !without.reflected);
        assert!(with.distance < 0.05 * apart, "{} vs {apart}", with.distance);
        assert!(without.distance > 10.0 * with.distance.max(1e-6));
    }

    #[test]
    fn the_distance_is_symmetric_and_the_map_gives_a_correspondence() {
        let params = CwParams::default();
        let a = crown(0, 1, |m| m);
        let b = crown(2, 2, |m| m);
        let ab = distance(&a, &b, &params).unwrap();
        let ba = distance(&b, &a, &params).unwrap();
        println!(
            "ab {} ba {} solves {} screened {} ms {} {}",
            ab.distance, ba.distance, ab.exact_solves, ab.screened, ab.screen_ms, ab.exact_ms
        );
        assert!(
            (ab.distance - ba.distance).abs() < 0.02 * ab.distance,
            "{} vs {}",
            ab.distance,
            ba.distance
        );
        let total: f64 = ab.plan.iter().map(|f| f.2).sum();
        assert!((total - 1.0).abs() < 1e-9);
        let d = correspondence(&a, &b, &ab).expect("a correspondence");
        assert_eq!(d.correspondence.len(), a.vertices().len());
        assert_eq!(d.mobius, ab.mobius);
        assert!(d
            .correspondence
            .iter()
            .all(|&(f, _)| (f as usize) < b.faces().len()));
    }

    #[test]
    fn bad_parameters_are_errors_that_name_the_key() {
        let a = crown(0, 1, |m| m);
        for (bad, key) in [
            (
                CwParams {
                    cap: 0.0,
                    ..Default::default()
                },
                "cap",
            ),
            (
                CwParams {
                    angles: 0,
                    ..Default::default()
                },
                "angles",
            ),
            (
                CwParams {
                    exact_candidates: 0,
                    ..Default::default()
                },
                "exact_candidates",
            ),
            (
                CwParams {
                    screen_epsilon: f64::NAN,
                    ..Default::default()
                },
                "screen_epsilon",
            ),
        ] {
            assert_eq!(bad.validate().unwrap_err().key, key);
            assert!(matches!(distance(&a, &a, &bad), Err(CwError::Params(_))));
        }
    }
}
