//! Prepared surfaces and the continuous Procrustes (cP) distance.
//!
//! [`prepare`] turns a clean disk-type mesh into a [`Prepared`] surface
//! (normalized, flattened to the unit disk, with features and samples);
//! [`compare`] searches disk automorphisms between two prepared surfaces
//! and returns the cP distance and the correspondence.
//!
//! The search, per direction `S → S′`: for every feature pair and a grid
//! of rotation angles, in both orientations, the Möbius map sending one
//! feature to the other is scored by the weighted Procrustes residual of
//! the first (farthest-point) samples; the best few are refined by
//! Nelder–Mead over the disk automorphisms near them on all samples; the
//! best is optionally deformed so that features land on features
//! ([`warp`]); the result is made area preserving, as the cP distance
//! requires ([`moser`]: the paper's χ); the final map is evaluated on every
//! vertex weighted by vertex area with the optimal rigid motion (improper
//! for orientation reversing maps). Everything is sequential and deterministic; matrices
//! parallelize over pairs.

pub mod distance;
pub mod features;
pub mod locate;
pub mod mobius;
pub mod moser;
pub mod prepare;
pub mod procrustes;
pub mod samples;
pub mod warp;

pub use distance::{compare, compare_directed, search_directed, Comparison, Directed};
pub use locate::{LocateGrid, Location};
pub use mobius::Mobius;
pub use prepare::{prepare, CpError, CpParams, Prepared};
pub use procrustes::{weighted_procrustes, Handedness, RigidFit};
