//! `morphoid matrix`: the all-pairs cP distance matrix of a folder, whole
//! or in shards for cluster job arrays (`--shard K/N`, then `matrix merge`);
//! with `--method cwn` the cWn matrix (whole only); with `--method
//! landmarks`, the discrete Procrustes distance matrix of the folder's
//! landmark files (the paper's ODLP).

use super::common::progress_bar;
use super::method::{CwnArgs, Method};
use anyhow::{bail, Context, Result};
use morphoid::cp::Prepared;
use morphoid::cwn;
use morphoid::eval;
use morphoid::eval::shard::{self, Shard, ShardFile};
use morphoid::hash::content_hash;
use morphoid::landmarks;
use morphoid::library::{self, Cache};
use morphoid::pipeline::{self, Settings};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Arguments of `morphoid matrix`.
#[derive(Debug, clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct Args {
    /// Folder of surfaces (OBJ, PLY, STL, OFF); names are the file stems.
    /// When it holds no surface but has a `meshes/` folder, that is used.
    #[arg(long, required = true)]
    library: Option<PathBuf>,
    /// Output CSV: header `name,<name1>,…`, one row per specimen. With
    /// `--shard`, the shard file (pairs with both directed distances).
    #[arg(long, required = true)]
    out: Option<PathBuf>,
    /// Compute only part K of N (1-based) of the sorted pair list, for a
    /// cluster job array; combine the parts with `morphoid matrix merge`.
    #[arg(long, value_name = "K/N")]
    shard: Option<Shard>,
    /// Reuse the prepared surfaces of this cache folder (as `library build`
    /// writes it) where the file and the settings are unchanged; the others
    /// are prepared here and not written back. Saves every shard of a job
    /// array from preparing the whole library again.
    #[arg(long, value_name = "DIR")]
    cache: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Which distance: cp (continuous Procrustes), cwn (conformal
    /// Wasserstein neighbourhood dissimilarity; no --shard) or landmarks
    /// (the discrete Procrustes distance of
    /// `landmarks/<name>.{csv,fcsv,mrk.json,pp}`, every specimen with the
    /// same number of landmarks).
    #[arg(long, value_enum, default_value_t = Method::Cp)]
    method: Method,
    #[command(flatten)]
    cwn: CwnArgs,
    /// With `--method landmarks`: allow reflections in the optimal
    /// superimposition (default: rotations only).
    #[arg(long)]
    allow_reflection: bool,
    #[command(subcommand)]
    command: Option<MatrixCommand>,
}

/// Subcommands of `morphoid matrix`.
#[derive(Debug, clap::Subcommand)]
enum MatrixCommand {
    /// Merge the shard files of `matrix --shard K/N` into the full matrix
    /// CSV (checks that all N shards of one library are there, each once).
    Merge(MergeArgs),
}

/// Arguments of `morphoid matrix merge`.
#[derive(Debug, clap::Args)]
struct MergeArgs {
    /// The shard files (any order).
    #[arg(required = true)]
    shards: Vec<PathBuf>,
    /// Output matrix CSV.
    #[arg(long)]
    out: PathBuf,
}

/// Run `morphoid matrix`.
pub fn run(args: Args) -> Result<ExitCode> {
    if let Some(MatrixCommand::Merge(m)) = args.command {
        return merge(m);
    }
    let (Some(library), Some(out)) = (args.library, args.out) else {
        bail!("`morphoid matrix` needs --library and --out (or the `merge` subcommand)");
    };
    super::configure_threads(args.threads)?;
    match args.method {
        Method::Cp | Method::Cwn => {}
        Method::Landmarks => {
            if args.shard.is_some() || args.cache.is_some() {
                bail!("--shard and --cache apply to --method cp only");
            }
            return run_landmarks(&library, &out, args.allow_reflection);
        }
    }
    let cache = match &args.cache {
        Some(dir) if !dir.is_dir() => bail!("{}: no such cache folder", dir.display()),
        Some(dir) => Some(Cache::open(dir)?),
        None => None,
    };
    match args.shard {
        Some(_) if args.method != Method::Cp => bail!(
            "--shard computes cP shards only; run --method {} without --shard",
            args.method.name()
        ),
        Some(shard) => run_shard(&library, &out, shard, cache.as_ref()),
        None => run_whole(&library, &out, cache.as_ref(), args.method, &args.cwn),
    }
}

/// The prepared form of the surface in `path`: from the cache when it
/// holds an entry for this content and these settings, else prepared now.
/// `hits` counts the surfaces taken from the cache.
fn prepare(
    path: &Path,
    settings: &Settings,
    cache: Option<&Cache>,
    hits: &AtomicUsize,
) -> Result<Prepared> {
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    if let Some(cache) = cache {
        let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
        let key = Cache::key(&content_hash(&bytes), settings);
        if let Some(hit) = cache.get(&name, &key) {
            let mut prepared = hit.prepared;
            prepared.set_name(name);
            hits.fetch_add(1, Ordering::Relaxed);
            return Ok(prepared);
        }
    }
    Ok(pipeline::prepare_file(path, settings)?.prepared)
}

/// The whole matrix in one run.
fn run_whole(
    library: &Path,
    out: &Path,
    cache: Option<&Cache>,
    method: Method,
    cwn_args: &CwnArgs,
) -> Result<ExitCode> {
    let settings = Settings::default();
    let cwn_params = cwn_args.params();
    if method == Method::Cwn {
        // Fail on bad options before hours of preparation.
        cwn_params.validate()?;
    }
    let files = surface_files(library)?;
    let started = Instant::now();
    let hits = AtomicUsize::new(0);

    let bar = progress_bar(files.len() as u64, "preparing");
    let prepared = files
        .par_iter()
        .map(|f| {
            let p = prepare(f, &settings, cache, &hits);
            bar.inc(1);
            p
        })
        .collect::<Result<Vec<_>, _>>()?;
    bar.finish_and_clear();
    let prepare_s = started.elapsed().as_secs_f64();

    let n = prepared.len();
    let bar = progress_bar((n * n.saturating_sub(1) / 2) as u64, "comparing");
    let matrix = match method {
        Method::Cp => eval::distance_matrix(&prepared, &settings.cp.compare, |_| bar.inc(1)),
        Method::Cwn => {
            let landscapes = prepared
                .par_iter()
                .map(|p| cwn::prepare(p, &cwn_params).with_context(|| p.name().to_string()))
                .collect::<Result<Vec<_>>>()?;
            cwn::distance_matrix(&landscapes, &cwn_params, |_| bar.inc(1))?
        }
        // Dispatched to `run_landmarks` before any surface is prepared.
        Method::Landmarks => bail!("--method landmarks does not compare surfaces"),
    };
    bar.finish_and_clear();
    matrix
        .write_csv(out)
        .with_context(|| format!("writing {}", out.display()))?;
    eprintln!(
        "{} specimens ({} from the cache), {} pairs, {}: prepared in {:.1} s, compared in {:.1} s; wrote {}",
        n,
        hits.load(Ordering::Relaxed),
        n * n.saturating_sub(1) / 2,
        method.name(),
        prepare_s,
        started.elapsed().as_secs_f64() - prepare_s,
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// The specimen names of surface files: their stems.
fn file_stems(files: &[PathBuf]) -> Vec<String> {
    files
        .iter()
        .map(|f| {
            f.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        })
        .collect()
}

/// Compute one shard: prepare only the specimens its pairs involve.
fn run_shard(library: &Path, out: &Path, which: Shard, cache: Option<&Cache>) -> Result<ExitCode> {
    let settings = Settings::default();
    let files = surface_files(library)?;
    let names = file_stems(&files);
    let started = Instant::now();
    let hits = AtomicUsize::new(0);
    let own_pairs = shard::shard_pairs(names.len(), which);
    let (pairs, needed) = (own_pairs.len(), shard::pair_specimens(&own_pairs).len());
    let bar = progress_bar(pairs as u64, "comparing");
    let file = shard::compute_shard(
        &names,
        which,
        |k| {
            let path = files.get(k).map(PathBuf::as_path).unwrap_or(library);
            prepare(path, &settings, cache, &hits)
        },
        &settings.cp.compare,
        |_| bar.inc(1),
    )?;
    bar.finish_and_clear();
    file.write(out)?;
    eprintln!(
        "shard {which}: {pairs} of {} pairs, {needed} of {} specimens prepared ({} from the cache), {:.1} s; wrote {}",
        shard::pair_count(names.len()),
        names.len(),
        hits.load(Ordering::Relaxed),
        started.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// `morphoid matrix merge`.
fn merge(args: MergeArgs) -> Result<ExitCode> {
    let shards = args
        .shards
        .iter()
        .map(|p| ShardFile::read(p).map(|s| (p.clone(), s)))
        .collect::<Result<Vec<_>, _>>()?;
    let matrix = shard::merge_shards(&shards)?;
    matrix
        .write_csv(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    eprintln!(
        "merged {} shards: {} specimens; wrote {}",
        shards.len(),
        matrix.names.len(),
        args.out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// The landmark Procrustes matrix over the specimens of the folder (the
/// surface files' names, so that it lines up with the cP matrix).
fn run_landmarks(library: &Path, out: &Path, allow_reflection: bool) -> Result<ExitCode> {
    let names = file_stems(&surface_files(library)?);
    let loaded = landmarks::load_library(library, &names);
    if let Some((name, why)) = loaded.problems.first() {
        bail!("landmarks of `{name}`: {why}");
    }
    let missing: Vec<&str> = names
        .iter()
        .filter(|n| !loaded.by_name.contains_key(*n))
        .map(String::as_str)
        .collect();
    if !missing.is_empty() {
        bail!(
            "{}: no landmark file (landmarks/<name>.csv, .fcsv, .mrk.json or .pp) for {}",
            library.display(),
            missing.join(", ")
        );
    }
    let sets: Vec<&[[f64; 3]]> = names
        .iter()
        .filter_map(|n| loaded.by_name.get(n).map(|l| l.points.as_slice()))
        .collect();
    let n = sets.len();
    let mut values = vec![vec![0.0; n]; n];
    for i in 0..n {
        for j in i + 1..n {
            let d = landmarks::procrustes_distance(sets[i], sets[j], allow_reflection)
                .with_context(|| format!("landmarks of `{}` and `{}`", names[i], names[j]))?;
            values[i][j] = d;
            values[j][i] = d;
        }
    }
    let matrix = eval::DistanceMatrix { names, values };
    matrix
        .write_csv(out)
        .with_context(|| format!("writing {}", out.display()))?;
    eprintln!(
        "{n} specimens, {} landmarks each, {} pairs: wrote {}",
        loaded.count.unwrap_or(0),
        n * n.saturating_sub(1) / 2,
        out.display()
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
