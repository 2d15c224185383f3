//! Leave-one-out classification and Mantel tests over distance matrices; classical
//! MDS, the average-linkage tree (Newick, dendrogram) and scatter plots.

mod heatmap;
mod loo;
mod mantel;
mod mds;
mod plot;
mod shard;
mod tree;

pub use heatmap::{
    average_linkage_order, default_cell_size, grouped_order, heatmap, HeatmapError, RgbImage,
};
pub use loo::{leave_one_out, RankScore};
pub use mantel::{mantel_test, Mantel, MantelError, DEFAULT_PERMUTATIONS, DEFAULT_SEED};
pub use mds::{classical_mds, Mds};
pub use plot::{scatter_raster, scatter_svg, Scatter};
pub use shard::{
    compute_shard, merge_shards, pair_count, pair_specimens, shard_pairs, PairDistance, Shard,
    ShardError, ShardFile,
};
pub use tree::{average_linkage_tree, dendrogram_svg, newick, Dendrogram};
