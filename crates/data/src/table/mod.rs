//! The CSV tables morphoid reads and writes: a library's `labels.csv`
//! ([`Labels`]) and square distance matrices ([`DistanceMatrix`]), with
//! errors that name the file, line and column.

pub mod csv_text;
mod labels;
mod matrix;

pub use csv_text::TableError;
pub use labels::Labels;
pub use matrix::{distance_matrix, pairwise_matrix, DistanceMatrix};
