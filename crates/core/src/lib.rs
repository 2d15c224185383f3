//! morphoid's numerical core: pure functions over plain data, no files,
//! no database, no async.
//!
//! Modules, each using only the ones listed before it:
//! - [`stats`]: order statistics over plain numbers;
//! - [`mesh`]: the triangle-mesh type, its combinatorics, grids and the
//!   isosurface;
//! - [`clean`]: a raw scan to a clean disk-type surface (crown extraction);
//! - [`conformal`]: normalization and conformal flattening to the unit disk;
//! - [`cp`]: prepared surfaces and the continuous Procrustes distance;
//! - [`cwn`]: the conformal Wasserstein neighbourhood dissimilarity distance;
//! - [`cw`]: the conformal Wasserstein distance (transport over Möbius maps);
//! - [`volume`]: a volume on a grid to the closed surfaces of its specimens.

pub mod clean;
pub mod conformal;
pub mod cp;
pub mod cw;
pub mod cwn;
pub mod mesh;
pub mod stats;
pub mod volume;

mod union_find;

#[cfg(test)]
mod testing;
