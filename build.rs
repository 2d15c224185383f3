//! Records the commit the binary is built from, for `morphoid --version`,
//! and tells the integration tests what the developer opted out of.
//!
//! From a git checkout: `git rev-parse HEAD`. From a `git archive` tarball: the `COMMIT` file,
//! which `export-subst` (`.gitattributes`) fills in. A packager may set
//! `MORPHOID_COMMIT` instead. Otherwise `unknown`: a build never fails for
//! want of git.

use std::path::Path;
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    if !out.status.success() {
        return None;
    }
    let text = String::from_utf8(out.stdout).ok()?;
    Some(text.trim().to_string())
}

/// The commit of the checkout, and the files whose change means a new one.
fn from_git() -> Option<(String, Vec<String>)> {
    let commit = git(&["rev-parse", "--short=12", "HEAD"])?;
    // Not the index (a dirty flag): every `git add` would rebuild the crate.
    let mut watch = Vec::new();
    // In a worktree `.git` is a file; ask git where HEAD and its ref live.
    for path in ["HEAD", "packed-refs"] {
        if let Some(p) = git(&["rev-parse", "--git-path", path]) {
            watch.push(p);
        }
    }
    if let Some(reference) = git(&["symbolic-ref", "-q", "HEAD"]) {
        if let Some(p) = git(&["rev-parse", "--git-path", &reference]) {
            watch.push(p);
        }
    }
    Some((commit, watch))
}

/// The commit `git archive` wrote into `COMMIT` (still `$Format:…$` in a
/// checkout).
fn from_archive() -> Option<String> {
    let text = std::fs::read_to_string("COMMIT").ok()?;
    let commit = text.trim();
    (!commit.is_empty() && !commit.contains('$')).then(|| commit.chars().take(12).collect())
}

/// Whether the real teeth are where the tests look for them
/// (`tests/it/support/data.rs`).
fn teeth_present() -> bool {
    let dir = std::env::var_os("MORPHOID_TEETH")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| Path::new("../shared/data/pnas-teeth").to_path_buf());
    dir.join("labels.csv").is_file() && dir.join("meshes").is_dir()
}

/// Whether the build runs as root (the tests run as the same user).
fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

/// The tests that need the real teeth or root fail when they are missing,
/// unless the developer opts out (`MORPHOID_SKIP_DATA=1`,
/// `MORPHOID_SKIP_ROOT=1`): then they are compiled as ignored, so that the
/// test summary counts them and says why.
fn test_opt_outs() {
    println!("cargo::rustc-check-cfg=cfg(morphoid_skip_data)");
    println!("cargo::rustc-check-cfg=cfg(morphoid_skip_root)");
    for var in ["MORPHOID_SKIP_DATA", "MORPHOID_SKIP_ROOT", "MORPHOID_TEETH"] {
        println!("cargo:rerun-if-env-changed={var}");
    }
    let set = |var: &str| std::env::var(var).is_ok_and(|v| v == "1");
    if set("MORPHOID_SKIP_DATA") && !teeth_present() {
        println!("cargo::rustc-cfg=morphoid_skip_data");
    }
    if set("MORPHOID_SKIP_ROOT") && !is_root() {
        println!("cargo::rustc-cfg=morphoid_skip_root");
    }
}

fn main() {
    test_opt_outs();
    println!("cargo:rerun-if-env-changed=MORPHOID_COMMIT");
    println!("cargo:rerun-if-changed=COMMIT");
    let commit = match std::env::var("MORPHOID_COMMIT") {
        Ok(c) if !c.trim().is_empty() => c.trim().to_string(),
        _ => match from_git() {
            Some((commit, watch)) => {
                for p in watch.iter().filter(|p| Path::new(p).exists()) {
                    println!("cargo:rerun-if-changed={p}");
                }
                commit
            }
            None => from_archive().unwrap_or_else(|| "unknown".into()),
        },
    };
    println!("cargo:rustc-env=MORPHOID_COMMIT={commit}");
}
