//! The conformal Wasserstein neighbourhood dissimilarity distance (cWn) of
//! Boyer et al. (PNAS 2011, section 2), built on the cP preparation.
//!
//! A prepared surface carries its conformal flattening to the unit disk
//! and the *hyperbolic* density `𝐟 = (1 − |z|²)² f` of its area, which
//! changes by composition only when the flattening is changed by a disk
//! automorphism. cWn compares two surfaces through these densities:
//!
//! 1. [`prepare`]: for every sample `z` of the surface (the cP samples,
//!    with their Voronoi areas as masses), the density over the hyperbolic
//!    disc `N(z, R)` is moved to `N(0, R)` by the automorphism sending `z`
//!    to 0 and sampled on a fixed polar quadrature ([`Landscape`]).
//! 2. [`distance`]: the neighbourhood dissimilarity of sample `i` of A and
//!    `j` of B is the smallest `∫ |𝐟 − 𝐟′ ∘ m| dη` over `N(z_i, R)` among
//!    automorphisms `m` with `m(z_i) = z′_j` (rotations about the two
//!    points, and their mirror images unless reflections are off), see
//!    `landscape::neighbourhood_dissimilarity`; with these costs, one
//!    exact Kantorovich problem between the two sets of masses
//!    (`transport::optimal_transport`, a network simplex) gives the
//!    distance.
//!
//! Unlike cP, cWn is intrinsic (it sees only the conformal structure and
//! area), and needs no search over maps between the whole surfaces: the
//! optimization over automorphisms is local and a transport plan replaces
//! the global map. Everything here is pure; parallelism (rayon) never
//! changes a result.

mod landscape;
mod transport;

pub use landscape::Landscape;
pub(crate) use transport::TransportError;

use landscape::dissimilarity_matrix;
pub(crate) use transport::{optimal_transport, TransportPlan};

use crate::cp::{CpError, ParamError, Prepared, Requirement};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Parameters of the cWn distance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CwnParams {
    /// Euclidean radius `R` of the neighbourhood `N(0, R)` in the disk
    /// (hyperbolic radius `ln((1 + R)/(1 − R))`). The default 0.6 was
    /// tuned on the PNAS teeth (0.4, 0.5, 0.6 tried; see docs/design.md).
    pub radius: f64,
    /// Rings of the polar quadrature of the neighbourhood.
    pub rings: usize,
    /// Points per ring; rotations are searched in steps of `2π/angles`.
    pub angles: usize,
    /// Whether orientation-reversing automorphisms (mirror images) are
    /// included in the neighbourhood dissimilarity.
    pub reflections: bool,
}

impl Default for CwnParams {
    fn default() -> Self {
        Self {
            radius: 0.6,
            rings: 6,
            angles: 24,
            reflections: true,
        }
    }
}

impl CwnParams {
    /// Check the values: `0 < radius < 1`, 1 to 64 rings, 4 to 720 angles;
    /// the error names the first bad one.
    pub fn validate(&self) -> Result<(), ParamError> {
        let radius = self.radius;
        crate::cp::check(
            "radius",
            radius,
            Requirement::OpenUnitInterval,
            radius > 0.0 && radius < 1.0,
        )?;
        for (key, value, min, max) in [
            ("rings", self.rings, 1, 64),
            ("angles", self.angles, 4, 720),
        ] {
            crate::cp::check_count(key, value, min, max)?;
        }
        Ok(())
    }
}

/// Why a cWn landscape or distance could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CwnError {
    /// Invalid parameters.
    #[error("invalid cWn parameters: {0}")]
    Params(#[from] ParamError),
    /// The prepared surface is inconsistent.
    #[error(transparent)]
    Prepared(#[from] CpError),
    /// A point of the disk could not be located in the flattening (an
    /// empty triangulation).
    #[error("the flattened surface has no triangles to sample the density on")]
    Locate,
    /// Two landscapes were built with different quadratures.
    #[error(
        "landscapes of `{first}` and `{second}` use different quadratures (radius, rings, angles)"
    )]
    Mismatch {
        /// Name of the first landscape's surface.
        first: String,
        /// Name of the second landscape's surface.
        second: String,
    },
    /// The transport problem failed.
    #[error("transport: {0}")]
    Transport(#[from] TransportError),
}

/// The cWn distance of two surfaces and how it was obtained.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CwnResult {
    /// `Σ π_ij d^R(z_i, z′_j)` for the optimal plan `π` (masses sum to 1).
    pub distance: f64,
    /// Share of the transported mass whose neighbourhood match was
    /// orientation-reversing (near 1 for mirror images).
    pub reflected_share: f64,
    /// The optimal plan: `(sample of A, sample of B, mass)`.
    pub plan: Vec<(u32, u32, f64)>,
    /// Network simplex pivots.
    pub pivots: usize,
    /// Milliseconds spent on the dissimilarity (cost) matrix.
    pub cost_ms: f64,
    /// Milliseconds spent on the transport problem.
    pub transport_ms: f64,
}

/// The landscape of a prepared surface (step 1 above).
pub fn prepare(p: &Prepared, params: &CwnParams) -> Result<Landscape, CwnError> {
    landscape::landscape(p, params)
}

/// The cWn distance of two landscapes built with the same quadrature.
/// `params.reflections` decides whether mirror-image neighbourhoods count.
pub fn distance(a: &Landscape, b: &Landscape, params: &CwnParams) -> Result<CwnResult, CwnError> {
    if a.quadrature != b.quadrature {
        return Err(CwnError::Mismatch {
            first: a.name.clone(),
            second: b.name.clone(),
        });
    }
    let t = Instant::now();
    let (cost, mirrored) = dissimilarity_matrix(a, b, params.reflections);
    let cost_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let plan = optimal_transport(&a.masses, &b.masses, &cost)?;
    let transport_ms = t.elapsed().as_secs_f64() * 1e3;
    let m = b.len();
    let reflected_share = plan
        .flows
        .iter()
        .filter(|&&(i, j, _)| mirrored[i as usize * m + j as usize])
        .map(|&(_, _, f)| f)
        .sum();
    Ok(CwnResult {
        distance: plan.cost,
        reflected_share,
        plan: plan.flows,
        pivots: plan.pivots,
        cost_ms,
        transport_ms,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cp::{self, PrepareParams};
    use crate::testing::synth::{self, CROWN_GENERA};

    fn prepared(
        genus: usize,
        seed: u64,
        mesh_fn: impl Fn(crate::mesh::Mesh) -> crate::mesh::Mesh,
    ) -> Prepared {
        let m = mesh_fn(synth::crown(&CROWN_GENERA[genus], seed, 2500));
        cp::prepare(&m, &PrepareParams::default()).expect("prepare")
    }

    #[test]
    fn a_surface_is_at_distance_zero_from_itself() {
        let params = CwnParams::default();
        let p = prepared(0, 1, |m| m);
        let l = prepare(&p, &params).unwrap();
        let r = distance(&l, &l, &params).unwrap();
        assert!(r.distance.abs() < 1e-9, "{}", r.distance);
    }

    #[test]
    fn rigid_motions_and_scalings_are_near_zero_and_distance_is_symmetric() {
        let params = CwnParams::default();
        let a = prepare(&prepared(0, 1, |m| m), &params).unwrap();
        let moved = prepare(
            &prepared(0, 1, |m| synth::scale(&synth::rigid_motion(&m, 5), 3.7)),
            &params,
        )
        .unwrap();
        let other = prepare(&prepared(2, 9, |m| m), &params).unwrap();
        let same = distance(&a, &moved, &params).unwrap().distance;
        let diff = distance(&a, &other, &params).unwrap().distance;
        assert!(same < 0.05 * diff, "same {same} vs different {diff}");
        let back = distance(&other, &a, &params).unwrap().distance;
        assert!((diff - back).abs() < 1e-6 * diff, "{diff} vs {back}");
    }

    #[test]
    fn a_different_flattening_of_the_same_surface_is_close() {
        // Re-centre the flattening by a disk automorphism: the hyperbolic
        // density moves with it, so cWn should barely change, far less
        // than the distance to another surface.
        let params = CwnParams::default();
        let p = prepared(1, 3, |m| m);
        let mob = cp::Mobius::sending([0.0, 0.0], [0.25, -0.15], 0.7, false);
        let q = p.reflattened(|z| mob.apply(z));
        let a = prepare(&p, &params).unwrap();
        let b = prepare(&q, &params).unwrap();
        let other = prepare(&prepared(3, 4, |m| m), &params).unwrap();
        let moved = distance(&a, &b, &params).unwrap().distance;
        let diff = distance(&a, &other, &params).unwrap().distance;
        // Not zero: the automorphism turns each neighbourhood by an angle
        // that is no multiple of the quadrature's 15° step, and the density
        // is interpolated in other triangles. Measured: 0.26 × the distance
        // to another synthetic crown at R = 0.6 (these crowns differ
        // little; real teeth are farther apart).
        assert!(
            moved < 0.35 * diff,
            "re-centred {moved} vs different {diff}"
        );
    }

    #[test]
    fn mirror_images_match_through_reflections() {
        let params = CwnParams::default();
        let a = prepare(&prepared(0, 1, |m| m), &params).unwrap();
        let b = prepare(&prepared(0, 1, |m| synth::mirror(&m)), &params).unwrap();
        let with = distance(&a, &b, &params).unwrap();
        let without = distance(
            &a,
            &b,
            &CwnParams {
                reflections: false,
                ..params.clone()
            },
        )
        .unwrap();
        assert!(with.distance <= without.distance);
        assert!(with.reflected_share > 0.5, "{}", with.reflected_share);
    }

    #[test]
    fn bad_parameters_and_mismatched_landscapes_are_errors() {
        let p = prepared(0, 1, |m| m);
        for bad in [
            CwnParams {
                radius: 1.0,
                ..Default::default()
            },
            CwnParams {
                radius: -0.1,
                ..Default::default()
            },
            CwnParams {
                rings: 0,
                ..Default::default()
            },
            CwnParams {
                angles: 2,
                ..Default::default()
            },
        ] {
            assert!(matches!(prepare(&p, &bad), Err(CwnError::Params(_))));
            let key = bad.validate().unwrap_err().key;
            assert!(["radius", "rings", "angles"].contains(&key), "{key}");
        }
        let a = prepare(&p, &CwnParams::default()).unwrap();
        let b = prepare(
            &p,
            &CwnParams {
                radius: 0.3,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(matches!(
            distance(&a, &b, &CwnParams::default()),
            Err(CwnError::Mismatch { .. })
        ));
    }
}
