//! morphoid's research layer, on top of the core and the data crate:
//! - [`surfaces`]: the distance matrix of prepared surfaces by cP, cWn or cW;
//! - [`eval`]: leave-one-out classification, Mantel tests, MDS, trees,
//!   heatmaps and plots, matrices in shards;
//! - [`collection`]: a whole collection in correspondence (pseudolandmarks,
//!   GPA, PCA).

pub mod collection;
pub mod eval;
pub mod surfaces;
