//! A morphoid process measured as a whole by GNU time (`/usr/bin/time`,
//! Debian package `time`), for the benches that time commands: a child
//! forked from `time` carries none of the bench's own peak memory into
//! its `ru_maxrss`, as one forked from the bench would across `exec`.

use anyhow::{bail, ensure, Context, Result};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

/// GNU time, which measures each morphoid process.
pub(crate) const GNU_TIME: &str = "/usr/bin/time";

/// What GNU time measured of one process.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Cost {
    /// Wall seconds.
    pub wall: f64,
    /// CPU seconds, user and system.
    pub cpu: f64,
    /// Peak resident memory, MB (2^20 bytes).
    pub peak_rss_mb: f64,
}

/// Run `bin ARGS` under GNU time, its figures written to `figures` (apart
/// from the program's own output); what it cost and its standard output.
/// An error, with the program's standard error, when it fails.
pub(crate) fn run_measured<A: AsRef<OsStr>>(
    bin: &Path,
    args: &[A],
    figures: &Path,
) -> Result<(Cost, String)> {
    let out = Command::new(GNU_TIME)
        .arg("-o")
        .arg(figures)
        .args(["-f", "%e %U %S %M"])
        .arg(bin)
        .args(args)
        .output()
        .with_context(|| {
            format!(
                "running {GNU_TIME} {} (Debian package `time`)",
                bin.display()
            )
        })?;
    let shown = args
        .iter()
        .map(|a| a.as_ref().to_string_lossy())
        .collect::<Vec<_>>()
        .join(" ");
    ensure!(
        out.status.success(),
        "{} {shown} failed ({}):\n{}",
        bin.display(),
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(figures)
        .with_context(|| format!("reading GNU time's figures in {}", figures.display()))?;
    let numbers: Vec<f64> = text
        .lines()
        .last()
        .unwrap_or("")
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .with_context(|| format!("GNU time's figures for {shown}: {text:?}"))?;
    let &[wall, user, system, peak_kb] = numbers.as_slice() else {
        bail!("GNU time's figures for {shown}: {text:?}, not four numbers");
    };
    let cost = Cost {
        wall,
        cpu: user + system,
        peak_rss_mb: peak_kb / 1024.0,
    };
    Ok((cost, String::from_utf8_lossy(&out.stdout).into_owned()))
}

/// The `morphoid` binary of this build (`target/release/morphoid`), beside
/// the running bench's own folder (`target/release/deps`).
pub(crate) fn morphoid_binary() -> PathBuf {
    let mut p = std::env::current_exe().expect("the bench's own path");
    p.pop(); // the bench's own file name
    p.pop(); // deps
    p.push("morphoid");
    assert!(
        p.is_file(),
        "{} not found: run `cargo build --release` first",
        p.display()
    );
    p
}

/// A configuration file `morphoid-TAG.toml` in `dir` for the library
/// `lib` with its cache `cache` and a database `scans-TAG.db` of its own,
/// made anew (the same content twice in one database is a duplicate, not
/// identified again); its path.
pub(crate) fn library_config(dir: &Path, tag: &str, lib: &Path, cache: &Path) -> String {
    let db = dir.join(format!("scans-{tag}.db"));
    // A folder kept from an earlier run holds its database: the same scan
    // again would be a duplicate there, not identified.
    for suffix in ["", "-wal", "-shm"] {
        let _ = std::fs::remove_file(dir.join(format!("scans-{tag}.db{suffix}")));
    }
    let path = dir.join(format!("morphoid-{tag}.toml"));
    std::fs::write(
        &path,
        format!("[database]\npath = {db:?}\n[library]\ndir = {lib:?}\ncache = {cache:?}\n"),
    )
    .unwrap_or_else(|e| panic!("writing {}: {e}", path.display()));
    path.to_string_lossy().into_owned()
}

/// Wall times of repeated runs as the benches print them: `median M s,
/// LO-HI s over N runs`.
pub(crate) fn wall_summary(walls: &[f64]) -> String {
    let mut w = walls.to_vec();
    w.sort_by(f64::total_cmp);
    match (w.first(), w.last()) {
        (Some(lo), Some(hi)) => format!(
            "median {:.2} s, {lo:.2}-{hi:.2} s over {} runs",
            w[w.len() / 2],
            w.len()
        ),
        _ => "no runs".into(),
    }
}
