//! `morphoid evaluate`: leave-one-out nearest-neighbour classification,
//! the Mantel test against a second matrix, the Figure 1 heatmap.

use super::common::{write_output, ConfigFile};
use anyhow::{Context, Result};
use morphoid_data::table::{DistanceMatrix, Labels};
use morphoid_research::eval::{self, Mantel, DEFAULT_PERMUTATIONS, DEFAULT_SEED};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `morphoid evaluate`. At least one of `--labels`,
/// `--compare`, `--heatmap` says what to do.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("task").required(true).multiple(true).args(["labels", "compare", "heatmap", "mds", "tree"])))]
pub(super) struct Args {
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
    /// The MDS plot is coloured and the dendrogram's leaves labelled by it.
    #[arg(long, value_name = "RANK", requires = "labels")]
    group_rank: Option<String>,
    /// Classical MDS of --matrix: the coordinates as CSV here, the
    /// plot of the first two axes next to it (same name, .svg and .png),
    /// coloured by --group-rank when given.
    #[arg(long, value_name = "OUT.csv")]
    mds: Option<PathBuf>,
    /// The average-linkage tree of --matrix in Newick here, its
    /// dendrogram next to it (same name, .svg).
    #[arg(long, value_name = "OUT.nwk")]
    tree: Option<PathBuf>,
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
pub(super) fn run(args: Args, file: ConfigFile) -> Result<ExitCode> {
    let config = file.load()?;
    let ranks = match (&args.ranks, file.0) {
        (Some(r), _) => Some(r.clone()),
        (None, Some(_)) => config.ranks().map(<[String]>::to_vec),
        (None, None) => None,
    };
    let matrix = DistanceMatrix::read_csv(&args.matrix)?;
    let labels = match &args.labels {
        Some(path) => Some(
            eval::evaluation_labels(
                path,
                matrix.names(),
                ranks.as_deref(),
                args.group_rank.as_deref(),
            )
            .with_context(|| format!("labels for {}", args.matrix.display()))?,
        ),
        None => None,
    };
    let rows = labels.as_ref().map(|l| leave_one_out(&matrix, &l.labels));
    let groups = labels.and_then(|l| l.groups);
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
        write_heatmap(&matrix, lower, groups.as_ref(), out)?;
    }
    if let Some(out) = &args.mds {
        write_mds(&matrix, out, groups.as_ref())?;
    }
    if let Some(out) = &args.tree {
        let tree = eval::average_linkage_tree(&matrix).context("the matrix is empty")?;
        write_output(out, eval::newick(&tree, matrix.names()))?;
        let svg = out.with_extension("svg");
        let g = groups.as_ref().map(|(_, g)| g.as_slice());
        write_output(&svg, eval::dendrogram_svg(&tree, matrix.names(), g))?;
        eprintln!("wrote {} and {}", out.display(), svg.display());
    }
    print_results(&args, &matrix, rows.as_deref(), mantel.as_ref())?;
    Ok(ExitCode::SUCCESS)
}

/// The heatmap of `matrix` (upper triangle) and `lower` (lower triangle)
/// as PNG at `out`, in average-linkage order, kept together by `groups`.
fn write_heatmap(
    matrix: &DistanceMatrix,
    lower: &DistanceMatrix,
    groups: Option<&eval::Groups>,
    out: &Path,
) -> Result<()> {
    let mut order = eval::average_linkage_order(matrix);
    let mut boundaries = Vec::new();
    if let Some((_, group)) = groups {
        (order, boundaries) = eval::grouped_order(&order, group);
    }
    let image = eval::heatmap(
        matrix,
        lower,
        &order,
        &boundaries,
        eval::default_cell_size(matrix.names().len()),
    )?;
    write_output(out, image.to_png()?)?;
    eprintln!(
        "wrote {} ({} × {} pixels)",
        out.display(),
        image.width,
        image.height
    );
    Ok(())
}

/// Print the leave-one-out rows and the Mantel test, as JSON with
/// `--json`.
fn print_results(
    args: &Args,
    matrix: &DistanceMatrix,
    rows: Option<&[RankJson]>,
    mantel: Option<&Mantel>,
) -> Result<()> {
    if args.json {
        let mut obj = serde_json::json!({ "specimens": matrix.names().len() });
        if let Some(rows) = rows {
            obj["ranks"] = serde_json::to_value(rows)?;
        }
        if let Some(m) = mantel {
            obj["mantel"] = serde_json::to_value(m)?;
            obj["mantel"]["seed"] = args.seed.into();
        }
        if let Some(h) = &args.heatmap {
            obj["heatmap"] = serde_json::Value::String(h.display().to_string());
        }
        println!("{}", serde_json::to_string_pretty(&obj)?);
    } else {
        if let Some(rows) = rows {
            println!(
                "leave-one-out nearest neighbour, {} specimens",
                matrix.names().len()
            );
            for r in rows {
                println!(
                    "  {:<16} {:>4}/{:<4} {:6.1} %",
                    r.rank, r.correct, r.total, r.percent
                );
            }
        }
        if let Some(m) = mantel {
            println!(
                "Mantel test, {} specimens: r = {:.4}, p = {:.4} ({} permutations, seed {})",
                matrix.names().len(),
                m.r,
                m.p,
                m.permutations,
                args.seed
            );
        }
    }
    Ok(())
}

/// Leave-one-out classification of `matrix` at every rank of `labels`.
fn leave_one_out(matrix: &DistanceMatrix, labels: &Labels) -> Vec<RankJson> {
    eval::leave_one_out(matrix, labels, labels.ranks())
        .into_iter()
        .map(|s| RankJson {
            percent: s.percent(),
            rank: s.rank,
            correct: s.correct,
            total: s.total,
        })
        .collect()
}

/// Classical MDS of `matrix`: coordinates CSV at `out`, the plot of the
/// first two axes as SVG and PNG next to it.
fn write_mds(
    matrix: &DistanceMatrix,
    out: &Path,
    groups: Option<&(String, Vec<Option<String>>)>,
) -> Result<()> {
    let mds = eval::classical_mds(matrix, 10);
    let dims = mds.eigenvalues.len();
    let mut csv = csv::WriterBuilder::new().from_writer(Vec::new());
    let mut header = vec!["name".to_string()];
    header.extend((1..=dims).map(|k| format!("MDS{k}")));
    csv.write_record(&header)?;
    for (n, c) in matrix.names().iter().zip(&mds.coordinates) {
        let mut row = vec![n.clone()];
        row.extend(c.iter().map(|v| format!("{v:?}")));
        csv.write_record(&row)?;
    }
    let bytes = csv.into_inner().map_err(|e| anyhow::anyhow!("{e}"))?;
    write_output(out, bytes)?;
    let total: f64 = mds.eigenvalues.iter().sum();
    let axis = |k: usize| match mds.eigenvalues.get(k) {
        Some(l) if total > 0.0 => format!("MDS{} ({:.1} %)", k + 1, 100.0 * l / total),
        _ => format!("MDS{}", k + 1),
    };
    let coord = |c: &Vec<f64>, k: usize| c.get(k).copied().unwrap_or(0.0);
    let plot = eval::Scatter {
        title: match groups {
            Some((rank, _)) => format!(
                "Classical MDS of {} specimens, by {rank}",
                matrix.names().len()
            ),
            None => format!("Classical MDS of {} specimens", matrix.names().len()),
        },
        x_label: axis(0),
        y_label: axis(1),
        points: mds
            .coordinates
            .iter()
            .map(|c| [coord(c, 0), coord(c, 1)])
            .collect(),
        names: matrix.names().to_vec(),
        groups: groups.map_or_else(|| vec![None; matrix.names().len()], |(_, g)| g.clone()),
    };
    let svg = out.with_extension("svg");
    write_output(&svg, eval::scatter_svg(&plot))?;
    let png = out.with_extension("png");
    let bytes = eval::scatter_raster(&plot, 900, 640).to_png()?;
    write_output(&png, bytes)?;
    eprintln!(
        "wrote {}, {} and {}",
        out.display(),
        svg.display(),
        png.display()
    );
    Ok(())
}
