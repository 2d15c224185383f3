//! `morphoid library build|list`: prepare and cache the references.

use super::common::{progress_bar, ConfigArgs, ConfigFile};
use anyhow::Result;
use indicatif::ProgressBar;
use morphoid_data::library;
use morphoid_service::app::{self, Progress};
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
    Build(ConfigArgs),
    /// Show the references, their labels and whether they are prepared.
    List(ConfigArgs),
    /// Add a confirmed or corrected scan to the library: its original file
    /// and the taxa of its latest decision (then reload the daemon).
    Add(super::library_add::Args),
}

/// Run `morphoid library`.
pub(super) fn run(args: Args, config: ConfigFile) -> Result<ExitCode> {
    match args.action {
        Action::Build(c) => build(&c, config),
        Action::List(c) => list(&c, config),
        Action::Add(a) => super::library_add::run(a, config),
    }
}

fn build(args: &ConfigArgs, file: ConfigFile) -> Result<ExitCode> {
    let config = args.load(file)?;
    let started = Instant::now();
    let bars: Mutex<Option<(ProgressBar, bool)>> = Mutex::new(None);
    let built = app::build_library(&config, |p| {
        let (done, total, calibrating) = match p {
            Progress::Preparing { done, total } => (done, total, false),
            Progress::Calibrating { done, total } => (done, total, true),
        };
        let Ok(mut bar) = bars.lock() else { return };
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
    })?;
    if let Ok(Some((bar, _))) = bars.into_inner() {
        bar.finish_and_clear();
    }
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
