//! `morphoid matrix`: the all-pairs cP distance matrix of a folder, whole
//! or in shards for cluster job arrays (`--shard K/N`, then `matrix merge`);
//! with `--method cwn` the cWn matrix and with `--method cw` the cW
//! matrix (whole only); with `--method
//! landmarks`, the discrete Procrustes distance matrix of the folder's
//! landmark files (the paper's ODLP).

use super::common::{progress_bar, ConfigFile};
use super::method::{CwArgs, CwnArgs, Method};
use anyhow::{bail, Context, Result};
use morphoid_data::landmarks;
use morphoid_data::library::{self, Member, Preparation};
use morphoid_data::pipeline::Settings;
use morphoid_research::eval::{self, Shard, ShardFile};
use morphoid_research::surfaces::SurfaceDistance;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `morphoid matrix`.
#[derive(Debug, clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub(super) struct Args {
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
    /// Cache of prepared surfaces (default: the `[library] cache` of the
    /// configuration, else the default cache folder): the cache folder or
    /// the library's own folder in it, as `library build` and this command
    /// print it. Surfaces whose file and
    /// settings are unchanged are taken from it, the others are prepared
    /// and stored in it. Saves every shard of a job array, and every later
    /// run, from preparing the whole library again.
    #[arg(long, value_name = "DIR")]
    cache: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Which distance: cp (continuous Procrustes), cwn (conformal
    /// Wasserstein neighbourhood dissimilarity; no --shard), cw (conformal
    /// Wasserstein; no --shard) or landmarks
    /// (the discrete Procrustes distance of
    /// `landmarks/<name>.{csv,fcsv,mrk.json,pp}`, every specimen with the
    /// same number of landmarks).
    #[arg(long, value_enum, default_value_t = Method::Cp)]
    method: Method,
    #[command(flatten)]
    cwn: CwnArgs,
    #[command(flatten)]
    cw: CwArgs,
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
pub(super) fn run(args: Args, config: ConfigFile) -> Result<ExitCode> {
    if let Some(MatrixCommand::Merge(m)) = args.command {
        return merge(m);
    }
    let (Some(library), Some(out)) = (args.library, args.out) else {
        bail!("`morphoid matrix` needs --library and --out (or the `merge` subcommand)");
    };
    let config = config.load()?;
    let settings = config.settings();
    super::configure_threads(args.threads)?;
    let members = library::members(&library)?;
    let distance = match args.method {
        Method::Cp => SurfaceDistance::Cp,
        Method::Cwn => SurfaceDistance::Cwn(args.cwn.params()),
        Method::Cw => SurfaceDistance::Cw(args.cw.params()),
        Method::Landmarks => {
            if args.shard.is_some() || args.cache.is_some() {
                bail!("--shard and --cache apply to the surface distances only");
            }
            return run_landmarks(&library, &members, &out, args.allow_reflection);
        }
    };
    // Fail on bad options before hours of preparation.
    distance.validate()?;
    if args.shard.is_some() && distance != SurfaceDistance::Cp {
        bail!(
            "--shard computes cP shards only; run --method {} without --shard",
            distance.name()
        );
    }
    let cache = config.cache_for(&library, args.cache.as_deref())?;
    let preparation = Preparation::new(Some(&cache), &settings);
    let code = match args.shard {
        Some(shard) => run_shard(&members, &out, shard, &preparation, &settings)?,
        None => run_whole(&members, &out, &preparation, &settings, &distance)?,
    };
    if let Some(dir) = preparation.cache_dir() {
        eprintln!(
            "cache {}: {} of {} prepared surfaces found, {} stored",
            dir.display(),
            preparation.reused(),
            preparation.reused() + preparation.prepared(),
            preparation.stored()
        );
        if args.cache.is_some() && preparation.reused() == 0 && preparation.prepared() > 0 {
            eprintln!(
                "note: nothing was found in the cache: give --cache the folder `morphoid library build` \
                 printed, and the same --config (preparation settings key the entries)"
            );
        }
    }
    Ok(code)
}

/// The whole matrix in one run.
fn run_whole(
    members: &[Member],
    out: &Path,
    preparation: &Preparation,
    settings: &Settings,
    distance: &SurfaceDistance,
) -> Result<ExitCode> {
    let started = Instant::now();
    let bar = progress_bar(members.len() as u64, "preparing");
    let prepared = preparation.prepare_all(members, |_| bar.inc(1))?;
    bar.finish_and_clear();
    let prepare_s = started.elapsed().as_secs_f64();

    let n = prepared.len();
    let pairs = eval::pair_count(n);
    let bar = progress_bar(pairs as u64, "comparing");
    let matrix = distance.matrix(&prepared, settings, |_| bar.inc(1))?;
    bar.finish_and_clear();
    matrix
        .write_csv(out)
        .with_context(|| format!("writing {}", out.display()))?;
    eprintln!(
        "{} specimens ({} from the cache), {} pairs, {}: prepared in {:.1} s, compared in {:.1} s; wrote {}",
        n,
        preparation.reused(),
        pairs,
        distance.name(),
        prepare_s,
        started.elapsed().as_secs_f64() - prepare_s,
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// Compute one shard: prepare only the specimens its pairs involve.
fn run_shard(
    members: &[Member],
    out: &Path,
    which: Shard,
    preparation: &Preparation,
    settings: &Settings,
) -> Result<ExitCode> {
    let names: Vec<String> = members.iter().map(|m| m.name().to_string()).collect();
    let started = Instant::now();
    let own_pairs = eval::shard_pairs(names.len(), which);
    let (pairs, needed) = (own_pairs.len(), eval::pair_specimens(&own_pairs).len());
    let bar = progress_bar(pairs as u64, "comparing");
    let file = eval::compute_shard(
        &names,
        which,
        |k| {
            let member = members.get(k).context("a shard pair outside the library")?;
            anyhow::Ok(preparation.prepare_hashed(member)?)
        },
        &settings.cp.compare,
        |_| bar.inc(1),
    )?;
    bar.finish_and_clear();
    file.write(out)?;
    eprintln!(
        "shard {which}: {pairs} of {} pairs, {needed} of {} specimens prepared ({} from the cache), {:.1} s; wrote {}",
        eval::pair_count(names.len()),
        names.len(),
        preparation.reused(),
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
    let matrix = eval::merge_shards(&shards)?;
    matrix
        .write_csv(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    eprintln!(
        "merged {} shards: {} specimens; wrote {}",
        shards.len(),
        matrix.names().len(),
        args.out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// The landmark Procrustes matrix over the specimens of the folder (the
/// surface files' names, so that it lines up with the cP matrix).
fn run_landmarks(
    library: &Path,
    members: &[Member],
    out: &Path,
    allow_reflection: bool,
) -> Result<ExitCode> {
    let names: Vec<String> = members.iter().map(|m| m.name().to_string()).collect();
    let (matrix, count) = landmarks::procrustes_matrix(library, &names, allow_reflection)?;
    matrix
        .write_csv(out)
        .with_context(|| format!("writing {}", out.display()))?;
    let n = names.len();
    eprintln!(
        "{n} specimens, {count} landmarks each, {} pairs: wrote {}",
        eval::pair_count(n),
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}
