//! `morphoid evaluate`: leave-one-out nearest-neighbour classification.

use anyhow::{bail, Result};
use morphoid::eval::{self, DistanceMatrix, Labels};
use serde::Serialize;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `morphoid evaluate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Distance matrix CSV (as written by `morphoid matrix`).
    #[arg(long)]
    matrix: PathBuf,
    /// labels.csv: column `name`, then one column per rank.
    #[arg(long)]
    labels: PathBuf,
    /// Ranks to evaluate, comma-separated (default: every column but `name`).
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
pub fn run(args: Args) -> Result<ExitCode> {
    let matrix = DistanceMatrix::read_csv(&args.matrix)?;
    let labels = Labels::read(&args.labels, args.ranks.as_deref())?;
    let missing: Vec<&str> = matrix
        .names
        .iter()
        .filter(|n| !labels.names.contains(n))
        .map(String::as_str)
        .collect();
    if !missing.is_empty() {
        bail!(
            "{}: no label row for {} specimen(s) of {}: {}",
            args.labels.display(),
            missing.len(),
            args.matrix.display(),
            missing.join(", ")
        );
    }
    let scores = eval::leave_one_out(&matrix, &labels, &labels.ranks);
    let rows: Vec<RankJson> = scores
        .into_iter()
        .map(|s| RankJson {
            percent: if s.total == 0 {
                0.0
            } else {
                100.0 * s.correct as f64 / s.total as f64
            },
            rank: s.rank,
            correct: s.correct,
            total: s.total,
        })
        .collect();
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "specimens": matrix.names.len(),
                "ranks": rows,
            }))?
        );
    } else {
        println!(
            "leave-one-out nearest neighbour, {} specimens",
            matrix.names.len()
        );
        for r in &rows {
            println!(
                "  {:<16} {:>4}/{:<4} {:6.1} %",
                r.rank, r.correct, r.total, r.percent
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
