//! Synthetic surfaces and volumes that morphoid's tests, benchmarks and
//! demo are made of. Nothing in the product depends on this crate.
//! - [`mesh`]: crown-like surfaces of a few synthetic genera, whole teeth,
//!   damaged and scanner-like variants, a labelled library;
//! - [`volume`]: voxelized teeth as slice stacks and volume files, mounted
//!   or several in foam.

pub mod mesh;
pub mod volume;
