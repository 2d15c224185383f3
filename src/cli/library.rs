//! `morphoid library build|list`: prepare and cache the references.

use super::common::{progress_bar, ConfigArgs, ConfigFile};
use anyhow::{bail, Context, Result};
use indicatif::ProgressBar;
use morphoid_data::library;
use morphoid_data::shard::Shard;
use morphoid_service::app::{self, Progress};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Mutex;
use std::time::Instant;

/// Arguments of `morphoid library`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
    #[command(subcommand)]
    action: Action,
}

#[derive(Debug, clap::Subcommand)]
enum Action {
    /// Prepare every reference (clean, flatten, features, samples) into the
    /// cache; unchanged references are reused, removed ones dropped.
    Build(BuildArgs),
    /// One task of a cluster job array: part K of N of the calibration's
    /// comparisons, into a shard file (`library calibrate merge` joins them).
    Calibrate(CalibrateArgs),
    /// Show the references, their labels and whether they are prepared.
    List(ConfigArgs),
    /// Add a confirmed or corrected scan to the library: its original file
    /// and the taxa of its latest decision (then reload the daemon).
    Add(super::library_add::Args),
}

/// Arguments of `morphoid library build`.
#[derive(Debug, clap::Args)]
struct BuildArgs {
    #[command(flatten)]
    config: ConfigArgs,
    /// Prepare only part K of N (1-based) of the sorted references, for a
    /// cluster job array sharing the cache (no calibration; run
    /// `library build` without --shard, or `library calibrate`, afterwards).
    #[arg(long, value_name = "K/N")]
    shard: Option<Shard>,
}

/// Arguments of `morphoid library calibrate`.
#[derive(Debug, clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
struct CalibrateArgs {
    #[command(flatten)]
    config: ConfigArgs,
    /// Compute part K of N (1-based) of the calibration's pair list.
    #[arg(long, value_name = "K/N", required = true)]
    shard: Option<Shard>,
    /// The shard file to write.
    #[arg(long, value_name = "FILE", required = true)]
    out: Option<PathBuf>,
    #[command(subcommand)]
    command: Option<CalibrateCommand>,
}

/// Subcommands of `morphoid library calibrate`.
#[derive(Debug, clap::Subcommand)]
enum CalibrateCommand {
    /// Join the shard files of `library calibrate --shard K/N` (all N, any
    /// order) into the library's calibration, stored in its cache.
    Merge(MergeArgs),
}

/// Arguments of `morphoid library calibrate merge`.
#[derive(Debug, clap::Args)]
struct MergeArgs {
    #[command(flatten)]
    config: ConfigArgs,
    /// The shard files.
    #[arg(required = true)]
    shards: Vec<PathBuf>,
}

/// Run `morphoid library`.
pub(super) fn run(args: Args, config: ConfigFile) -> Result<ExitCode> {
    match args.action {
        Action::Build(b) => match b.shard {
            Some(shard) => build_shard(&b.config, shard, config),
            None => build(&b.config, config),
        },
        Action::Calibrate(c) => calibrate(c, config),
        Action::List(c) => list(&c, config),
        Action::Add(a) => super::library_add::run(a, config),
    }
}

/// Progress bars for the preparation and the calibration, one at a time.
#[derive(Default)]
struct Bars(Mutex<Option<(ProgressBar, bool)>>);

impl Bars {
    fn show(&self, p: Progress) {
        let (done, total, calibrating) = match p {
            Progress::Preparing { done, total } => (done, total, false),
            Progress::Calibrating { done, total } => (done, total, true),
        };
        let Ok(mut bar) = self.0.lock() else { return };
        if bar.as_ref().is_none_or(|(_, c)| *c != calibrating) {
            if let Some((old, _)) = bar.take() {
                old.finish_and_clear();
            }
            let what = if calibrating {
                "calibrating"
            } else {
                "preparing"
            };
            *bar = Some((progress_bar(total as u64, what), calibrating));
        }
        if let Some((b, _)) = bar.as_ref() {
            b.set_position(done as u64);
        }
    }

    fn finish(self) {
        if let Ok(Some((bar, _))) = self.0.into_inner() {
            bar.finish_and_clear();
        }
    }
}

fn build(args: &ConfigArgs, file: ConfigFile) -> Result<ExitCode> {
    let config = args.load(file)?;
    let started = Instant::now();
    let bars = Bars::default();
    let built = app::build_library(&config, |p| bars.show(p))?;
    bars.finish();
    report_build(&built, started)
}

fn build_shard(args: &ConfigArgs, shard: Shard, file: ConfigFile) -> Result<ExitCode> {
    let config = args.load(file)?;
    let started = Instant::now();
    let bars = Bars::default();
    let built = app::build_library_shard(&config, shard, |p| bars.show(p))?;
    bars.finish();
    let out = &built.outcome;
    for f in out.failures() {
        eprintln!("morphoid: error: reference {}: {}", f.name(), f.error());
    }
    println!(
        "{}: shard {shard}: {} references ({} prepared, {} from the cache, {} failed) in {:.1} s; cache {}",
        built.library.dir().display(),
        out.prepared() + out.reused() + out.failures().len(),
        out.prepared(),
        out.reused(),
        out.failures().len(),
        started.elapsed().as_secs_f64(),
        built.cache.dir().display()
    );
    Ok(if out.failures().is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn calibrate(args: CalibrateArgs, file: ConfigFile) -> Result<ExitCode> {
    let started = Instant::now();
    let bars = Bars::default();
    if let Some(CalibrateCommand::Merge(m)) = args.command {
        let config = m.config.load(file)?;
        let built = app::merge_calibration(&config, &m.shards, |p| bars.show(p))?;
        bars.finish();
        return report_build(&built, started);
    }
    let (Some(shard), Some(out)) = (args.shard, args.out) else {
        bail!("`morphoid library calibrate` needs --shard and --out (or the `merge` subcommand)");
    };
    let config = args.config.load(file)?;
    let part = app::calibration_shard(&config, shard, |p| bars.show(p))?;
    bars.finish();
    part.write(&out)
        .with_context(|| format!("writing the calibration shard {}", out.display()))?;
    println!(
        "calibration shard {shard}: {} pairs in {:.1} s; written to {}",
        part.pairs(),
        started.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// Print what a library build did (failures on standard error) and its
/// calibration; failure when a reference or landmark file failed.
fn report_build(built: &app::LibraryBuild, started: Instant) -> Result<ExitCode> {
    let out = &built.outcome;
    for f in out.failures() {
        eprintln!("morphoid: error: reference {}: {}", f.name(), f.error());
    }
    // A reference whose landmark file cannot be used still identifies
    // scans, without landmarks; the file needs fixing all the same.
    for (name, why) in out.landmarks().problems() {
        eprintln!("morphoid: error: landmarks of reference {name}: {why}");
    }
    println!(
        "{}: {} references ({} prepared, {} from the cache, {} failed; {} stale cache entries removed) in {:.1} s; cache {}",
        built.library.dir().display(),
        out.references().len(),
        out.prepared(),
        out.reused(),
        out.failures().len(),
        out.removed(),
        started.elapsed().as_secs_f64(),
        built.cache.dir().display()
    );
    for r in built.calibration.iter().flat_map(|c| c.ranks()) {
        let threshold = match r.threshold {
            Some(t) => format!("no close match above novelty {t:.3}"),
            None => "no threshold (too few shared taxa)".to_string(),
        };
        println!(
            "calibration {}: {}/{} right in leave-one-out; {threshold}",
            r.rank, r.right, r.held
        );
    }
    if let Some(count) = out.landmarks().count() {
        println!(
            "{} references with landmarks ({count} each), {} landmark files not usable",
            out.landmarks().by_name().len(),
            out.landmarks().problems().len()
        );
    }
    Ok(
        if out.failures().is_empty() && out.landmarks().problems().is_empty() {
            ExitCode::SUCCESS
        } else {
            ExitCode::FAILURE
        },
    )
}

fn list(args: &ConfigArgs, file: ConfigFile) -> Result<ExitCode> {
    let config = args.load(file)?;
    let lib = config.open_library()?;
    let cache = config.open_cache()?;
    let cached = library::cached_members(&lib, &cache, &config.settings());
    let mut header = format!("{:<16}", "name");
    for r in lib.labels().ranks() {
        header.push_str(&format!(" {r:<18}"));
    }
    println!("{header} state");
    for (m, cached) in lib.members().iter().zip(&cached) {
        let state = match cached {
            Some(true) => "prepared",
            Some(false) => "not prepared",
            None => "unreadable",
        };
        let mut row = format!("{:<16}", m.name());
        for r in lib.labels().ranks() {
            row.push_str(&format!(
                " {:<18}",
                lib.labels().get(m.name(), r).unwrap_or("NA")
            ));
        }
        println!("{row} {state}");
    }
    println!(
        "{} references, {} prepared (cache {})",
        lib.members().len(),
        cached.iter().filter(|c| **c == Some(true)).count(),
        cache.dir().display()
    );
    Ok(ExitCode::SUCCESS)
}
