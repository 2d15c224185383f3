//! Distance matrices, labels and leave-one-out classification.

pub(crate) mod csv_text;
pub mod heatmap;
pub mod labels;
pub mod loo;
pub mod mantel;
pub mod matrix;
pub mod shard;

pub use labels::{Labels, LabelsError};
pub use loo::{leave_one_out, RankScore};
pub use mantel::{mantel_r, mantel_test, Mantel, MantelError};
pub use matrix::{distance_matrix, pairwise_matrix, DistanceMatrix, MatrixError};
