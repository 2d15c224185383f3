//! Distance matrices, labels and leave-one-out classification; classical
//! MDS, the average-linkage tree (Newick, dendrogram) and scatter plots.

pub(crate) mod csv_text;
mod heatmap;
mod labels;
mod loo;
mod mantel;
mod matrix;
mod mds;
mod plot;
mod shard;
mod tree;

pub use csv_text::TableError;
pub use heatmap::{
    average_linkage_order, default_cell_size, grouped_order, heatmap, HeatmapError, RgbImage,
};
pub use labels::Labels;
pub use loo::{leave_one_out, RankScore};
pub use mantel::{mantel_test, Mantel, MantelError, DEFAULT_PERMUTATIONS, DEFAULT_SEED};
pub use matrix::{distance_matrix, pairwise_matrix, DistanceMatrix, MatrixShapeError};
pub use mds::{classical_mds, Mds};
pub use plot::{scatter_raster, scatter_svg, Scatter};
pub use shard::{
    compute_shard, merge_shards, pair_count, pair_specimens, shard_pairs, PairDistance, Shard,
    ShardError, ShardFile,
};
pub use tree::{average_linkage_tree, dendrogram_svg, newick, Dendrogram};
