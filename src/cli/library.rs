//! `morphoid library build|list`: prepare and cache the references.

use super::common::{open_cache, open_library, progress_bar, ConfigArgs};
use anyhow::Result;
use morphoid::hash::content_hash;
use morphoid::library::{self, Cache};
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `morphoid library`.
#[derive(Debug, clap::Args)]
pub struct Args {
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
}

/// Run `morphoid library`.
pub fn run(args: Args) -> Result<ExitCode> {
    match args.action {
        Action::Build(c) => build(&c),
        Action::List(c) => list(&c),
    }
}

fn build(args: &ConfigArgs) -> Result<ExitCode> {
    let config = args.load()?;
    let lib = open_library(&config)?;
    let cache = open_cache(&config)?;
    let started = Instant::now();
    let bar = progress_bar(lib.members.len() as u64, "preparing");
    let out = library::build(&lib, &cache, &config.settings(), |_| bar.inc(1))?;
    bar.finish_and_clear();
    for (name, why) in &out.failures {
        eprintln!("morphoid: error: reference {name}: {why}");
    }
    // A reference whose landmark file cannot be used still identifies
    // scans, without landmarks; the file needs fixing all the same.
    for (name, why) in &out.landmarks.problems {
        eprintln!("morphoid: error: landmarks of reference {name}: {why}");
    }
    println!(
        "{}: {} references ({} prepared, {} from the cache, {} failed; {} stale cache entries removed) in {:.1} s; cache {}",
        lib.dir.display(),
        out.references.len(),
        out.prepared,
        out.reused,
        out.failures.len(),
        out.removed,
        started.elapsed().as_secs_f64(),
        cache.dir().display()
    );
    if let Some(count) = out.landmarks.count {
        println!(
            "{} references with landmarks ({count} each), {} landmark files not usable",
            out.landmarks.by_name.len(),
            out.landmarks.problems.len()
        );
    }
    Ok(
        if out.failures.is_empty() && out.landmarks.problems.is_empty() {
            ExitCode::SUCCESS
        } else {
            ExitCode::FAILURE
        },
    )
}

fn list(args: &ConfigArgs) -> Result<ExitCode> {
    let config = args.load()?;
    let lib = open_library(&config)?;
    let cache = open_cache(&config)?;
    let settings = config.settings();
    let mut header = format!("{:<16}", "name");
    for r in &lib.labels.ranks {
        header.push_str(&format!(" {r:<18}"));
    }
    println!("{header} state");
    let mut prepared = 0;
    for m in &lib.members {
        let state = match std::fs::read(&m.path) {
            Ok(bytes) => {
                let key = Cache::key(&content_hash(&bytes), &settings);
                if cache.get(&m.name, &key).is_some() {
                    prepared += 1;
                    "prepared"
                } else {
                    "not prepared"
                }
            }
            Err(_) => "unreadable",
        };
        let mut row = format!("{:<16}", m.name);
        for r in &lib.labels.ranks {
            row.push_str(&format!(
                " {:<18}",
                lib.labels.get(&m.name, r).unwrap_or("NA")
            ));
        }
        println!("{row} {state}");
    }
    println!(
        "{} references, {} prepared (cache {})",
        lib.members.len(),
        prepared,
        cache.dir().display()
    );
    Ok(ExitCode::SUCCESS)
}
