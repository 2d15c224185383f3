//! Prepared surfaces and the continuous Procrustes (cP) distance.
//!
//! [`prepare`] turns a clean disk-type mesh into a [`Prepared`] surface
//! (normalized, flattened to the unit disk, with features and samples);
//! [`compare`] searches disk automorphisms between two prepared surfaces
//! and returns the cP distance and the correspondence.

pub mod distance;
pub mod features;
pub mod graph;
pub mod locate;
pub mod mobius;
pub mod prepare;
pub mod procrustes;
pub mod samples;
pub mod warp;

pub use distance::{compare, compare_directed, Comparison, Directed};
pub use locate::{LocateGrid, Location};
pub use mobius::Mobius;
pub use prepare::{prepare, CpError, CpParams, Prepared};
pub use procrustes::{weighted_procrustes, Handedness, RigidFit};
