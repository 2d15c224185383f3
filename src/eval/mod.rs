//! Distance matrices, labels and leave-one-out classification.

pub(crate) mod csv_text;
mod heatmap;
mod labels;
mod loo;
mod mantel;
mod matrix;
mod shard;

pub use csv_text::TableError;
pub use heatmap::{
    average_linkage_order, default_cell_size, encode_png, grouped_order, heatmap, HeatmapError,
    RgbImage,
};
pub use labels::Labels;
pub use loo::{leave_one_out, RankScore};
pub use mantel::{mantel_test, Mantel, MantelError, DEFAULT_PERMUTATIONS, DEFAULT_SEED};
pub use matrix::{distance_matrix, pairwise_matrix, DistanceMatrix};
pub use shard::{
    compute_shard, merge_shards, pair_count, pair_specimens, shard_pairs, PairDistance, Shard,
    ShardError, ShardFile,
};
