//! `morphoid matrix`: the all-pairs cP distance matrix of a folder.

use super::common::progress_bar;
use anyhow::{bail, Context, Result};
use morphoid::eval;
use morphoid::library;
use morphoid::pipeline::{self, Settings};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `morphoid matrix`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Folder of surfaces (OBJ, PLY, STL, OFF); names are the file stems.
    /// When it holds no surface but has a `meshes/` folder, that is used.
    #[arg(long)]
    library: PathBuf,
    /// Output CSV: header `name,<name1>,…`, one row per specimen.
    #[arg(long)]
    out: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

/// Run `morphoid matrix`.
pub fn run(args: Args) -> Result<ExitCode> {
    super::configure_threads(args.threads)?;
    let settings = Settings::default();
    let files = surface_files(&args.library)?;
    let started = Instant::now();

    let bar = progress_bar(files.len() as u64, "preparing");
    let prepared = files
        .par_iter()
        .map(|f| {
            let p = pipeline::prepare_file(f, &settings);
            bar.inc(1);
            p.map(|s| s.prepared)
        })
        .collect::<Result<Vec<_>, _>>()?;
    bar.finish_and_clear();
    let prepare_s = started.elapsed().as_secs_f64();

    let n = prepared.len();
    let bar = progress_bar((n * n.saturating_sub(1) / 2) as u64, "comparing");
    let matrix = eval::distance_matrix(&prepared, &settings.cp, |_| bar.inc(1));
    bar.finish_and_clear();
    matrix
        .write_csv(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    eprintln!(
        "{} specimens, {} pairs: prepared in {:.1} s, compared in {:.1} s; wrote {}",
        n,
        n * n.saturating_sub(1) / 2,
        prepare_s,
        started.elapsed().as_secs_f64() - prepare_s,
        args.out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// The surface files of a library folder, sorted by name.
fn surface_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let files = library::surface_files(dir)?;
    if files.is_empty() {
        bail!(
            "{}: no surface files (.obj, .ply, .stl, .off)",
            dir.display()
        );
    }
    Ok(files)
}
