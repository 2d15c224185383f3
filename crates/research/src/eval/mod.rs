//! Leave-one-out classification and Mantel tests over distance matrices; classical
//! MDS, the average-linkage tree (Newick, dendrogram) and scatter plots.

mod heatmap;
mod labels;
mod loo;
mod mantel;
mod mds;
mod plot;
mod shard;
mod tree;

pub(crate) use heatmap::RgbImage;
pub use heatmap::{average_linkage_order, default_cell_size, grouped_order, heatmap};
pub use labels::{evaluation_labels, folder_groups, EvaluationLabels, Groups, LabelsError};
pub use loo::{leave_one_out, RankScore};
pub use mantel::{mantel_test, Mantel, DEFAULT_PERMUTATIONS, DEFAULT_SEED};
pub use mds::classical_mds;
pub use plot::{scatter_raster, scatter_svg, Scatter};
pub use shard::{
    compute_shard, merge_shards, pair_count, pair_specimens, shard_pairs, PairDistance, Shard,
    ShardFile,
};
pub use tree::{average_linkage_tree, dendrogram_svg, newick};
