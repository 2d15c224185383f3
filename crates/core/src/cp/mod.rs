//! Prepared surfaces and the continuous Procrustes (cP) distance.
//!
//! [`prepare`] turns a clean disk-type mesh into a [`Prepared`] surface
//! (normalized, flattened to the unit disk, with features and samples);
//! [`compare`] searches disk automorphisms between two prepared surfaces
//! and returns the cP distance and the correspondence. [`CpParams`] (the
//! `[cp]` section) holds [`PrepareParams`], which shape a prepared surface,
//! and [`CompareParams`], which only the comparison reads.
//!
//! The search, per direction `S → S′` (`search`): for every feature pair
//! and a grid of rotation angles, in both orientations, the Möbius map
//! sending one feature to the other is scored by the weighted Procrustes
//! residual of the first (farthest-point) samples (`evaluate`); the best
//! few are refined by Nelder–Mead (`optimize`) over the disk automorphisms
//! near them on all samples; the best is optionally deformed so that
//! features land on features (`warp`); the result is made area preserving,
//! as the cP distance requires (`moser`: the paper's χ); the final map is
//! evaluated on every vertex weighted by vertex area with the optimal rigid
//! motion (improper for orientation reversing maps). The final descent
//! (`descent`) then lowers the distance of the better direction
//! (`compare`). Everything is sequential and deterministic; matrices
//! parallelize over pairs.

mod compare;
mod comparison;
mod descent;
mod error;
mod evaluate;
mod features;
mod locate;
mod mobius;
mod moser;
mod optimize;
mod params;
mod prepare;
mod prepared;
mod procrustes;
mod recut;
mod samples;
mod search;
mod signature;
mod warp;

pub use compare::{compare, compare_directed};
pub use comparison::{Comparison, Correspondence, Directed};
pub use error::CpError;
pub use mobius::Mobius;
pub(crate) use optimize::nelder_mead;
pub(crate) use params::Requirement;
pub(crate) use params::{check, check_count};
pub use params::{
    CompareParams, CpParams, ParamError, PrepareParams, RecutParams, ScreenParams, Screening,
};
pub use prepare::prepare;
pub use prepared::Prepared;
pub use procrustes::{Handedness, Moments};
pub use recut::{cut_along_rim, cut_along_rims, Alignment, RimProfile};
pub(crate) use search::{candidate_maps, directed_for_mobius};
pub use signature::{shape_signature, signature_distance, signature_terms, Signature};

/// A prepared synthetic crown of 1,500 vertices (genus index, seed): the
/// unit tests' fixture.
#[cfg(test)]
fn test_crown(genus: usize, seed: u64) -> Prepared {
    let m = crate::testing::synth::crown(&crate::testing::synth::CROWN_GENERA[genus], seed, 1500);
    prepare(&m, &PrepareParams::default()).expect("a synthetic crown prepares")
}
