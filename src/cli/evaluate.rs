//! `morphoid evaluate`: leave-one-out nearest-neighbour classification,
//! the Mantel test against a second matrix, the Figure 1 heatmap.

use super::common::ConfigFile;
use anyhow::{bail, Context, Result};
use morphoid::eval::{self, DistanceMatrix, Labels, Mantel, DEFAULT_PERMUTATIONS, DEFAULT_SEED};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `morphoid evaluate`. At least one of `--labels`,
/// `--compare`, `--heatmap` says what to do.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("task").required(true).multiple(true).args(["labels", "compare", "heatmap"])))]
pub struct Args {
    /// Distance matrix CSV (as written by `morphoid matrix`).
    #[arg(long)]
    matrix: PathBuf,
    /// labels.csv (column `name`, then one column per rank): leave-one-out
    /// nearest-neighbour classification per rank. Optional when only the
    /// Mantel test or the heatmap is wanted.
    #[arg(long)]
    labels: Option<PathBuf>,
    /// A second distance matrix over the same specimens (matched by name):
    /// Mantel test of --matrix against it; in the heatmap it fills the
    /// lower triangle.
    #[arg(long, value_name = "G.csv")]
    compare: Option<PathBuf>,
    /// Random permutations of the Mantel test.
    #[arg(long, default_value_t = DEFAULT_PERMUTATIONS)]
    permutations: usize,
    /// Seed of the Mantel permutations.
    #[arg(long, default_value_t = DEFAULT_SEED)]
    seed: u64,
    /// Write the heatmap PNG (paper's Figure 1): --matrix in the upper
    /// triangle, --compare (or --matrix again) in the lower, specimens in
    /// average-linkage order of --matrix.
    #[arg(long, value_name = "OUT.png")]
    heatmap: Option<PathBuf>,
    /// In the heatmap, keep the specimens of each taxon at this rank
    /// together (from --labels) and separate the groups by white lines.
    #[arg(long, value_name = "RANK", requires_all = ["labels", "heatmap"])]
    group_rank: Option<String>,
    /// Ranks to evaluate, comma-separated (default: the `[library] ranks`
    /// of --config when one is given, else every column but `name`).
    #[arg(long, value_delimiter = ',')]
    ranks: Option<Vec<String>>,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Serialize)]
struct RankJson {
    rank: String,
    correct: usize,
    total: usize,
    percent: f64,
}

/// Run `morphoid evaluate`.
pub fn run(args: Args, file: ConfigFile) -> Result<ExitCode> {
    let config = file.load()?;
    let ranks = match (&args.ranks, file.0) {
        (Some(r), _) => Some(r.clone()),
        (None, Some(_)) => config.ranks().map(<[String]>::to_vec),
        (None, None) => None,
    };
    let matrix = DistanceMatrix::read_csv(&args.matrix)?;
    let rows = match &args.labels {
        Some(path) => Some(leave_one_out(&matrix, path, &args, ranks.as_deref())?),
        None => None,
    };
    let compare = match &args.compare {
        Some(path) => Some(DistanceMatrix::read_csv(path)?),
        None => None,
    };
    let mantel: Option<Mantel> = match &compare {
        Some(other) => Some(
            eval::mantel_test(&matrix, other, args.permutations, args.seed).with_context(|| {
                format!(
                    "Mantel test of {} against {}",
                    args.matrix.display(),
                    args.compare.as_deref().unwrap_or(&args.matrix).display()
                )
            })?,
        ),
        None => None,
    };
    if let Some(out) = &args.heatmap {
        let lower = compare.as_ref().unwrap_or(&matrix);
        let mut order = eval::average_linkage_order(&matrix);
        let mut boundaries = Vec::new();
        if let (Some(rank), Some(path)) = (&args.group_rank, &args.labels) {
            let labels = Labels::read(path, None)?;
            let Some(group) = labels.column(&matrix.names, rank) else {
                bail!(
                    "{}: no rank column `{rank}` (ranks: {})",
                    path.display(),
                    labels.ranks().join(", ")
                );
            };
            (order, boundaries) = eval::grouped_order(&order, &group);
        }
        let image = eval::heatmap(
            &matrix,
            lower,
            &order,
            &boundaries,
            eval::default_cell_size(matrix.names.len()),
        )?;
        let bytes = eval::encode_png(&image)?;
        std::fs::write(out, bytes).with_context(|| format!("writing {}", out.display()))?;
        eprintln!(
            "wrote {} ({} × {} pixels)",
            out.display(),
            image.width,
            image.height
        );
    }
    if args.json {
        let mut obj = serde_json::json!({ "specimens": matrix.names.len() });
        if let Some(rows) = &rows {
            obj["ranks"] = serde_json::to_value(rows)?;
        }
        if let Some(m) = &mantel {
            obj["mantel"] = serde_json::to_value(m)?;
            obj["mantel"]["seed"] = args.seed.into();
        }
        if let Some(h) = &args.heatmap {
            obj["heatmap"] = serde_json::Value::String(h.display().to_string());
        }
        println!("{}", serde_json::to_string_pretty(&obj)?);
    } else {
        if let Some(rows) = &rows {
            println!(
                "leave-one-out nearest neighbour, {} specimens",
                matrix.names.len()
            );
            for r in rows {
                println!(
                    "  {:<16} {:>4}/{:<4} {:6.1} %",
                    r.rank, r.correct, r.total, r.percent
                );
            }
        }
        if let Some(m) = &mantel {
            println!(
                "Mantel test, {} specimens: r = {:.4}, p = {:.4} ({} permutations, seed {})",
                matrix.names.len(),
                m.r,
                m.p,
                m.permutations,
                args.seed
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Leave-one-out classification of `matrix` with the labels in `path`.
fn leave_one_out(
    matrix: &DistanceMatrix,
    path: &Path,
    args: &Args,
    ranks: Option<&[String]>,
) -> Result<Vec<RankJson>> {
    let labels = Labels::read(path, ranks)?;
    let missing = labels.unlabelled(&matrix.names);
    if !missing.is_empty() {
        bail!(
            "{}: no label row for {} specimen(s) of {}: {}",
            path.display(),
            missing.len(),
            args.matrix.display(),
            missing.join(", ")
        );
    }
    let scores = eval::leave_one_out(matrix, &labels, labels.ranks());
    Ok(scores
        .into_iter()
        .map(|s| RankJson {
            percent: s.percent(),
            rank: s.rank,
            correct: s.correct,
            total: s.total,
        })
        .collect())
}
