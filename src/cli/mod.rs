//! Subcommands of the `morphoid` binary. Each module parses nothing itself:
//! clap builds the argument structs here; the modules call the library,
//! print, and turn library errors into one-line messages with context.

mod align;
mod assets;
mod check_config;
mod classify;
mod common;
mod demo;
mod distance;
mod evaluate;
mod inspect;
mod library;
mod library_add;
mod matrix;
mod method;
mod propagate;
mod report;
mod results;
mod review;
mod run;
mod synth;
mod user;

use clap::{Parser, Subcommand};
use common::ConfigFile;
use std::path::PathBuf;
use std::process::ExitCode;

/// `morphoid --version`: the crate version and the commit it was built
/// from (`build.rs`).
const VERSION: &str = concat!(
    env!("CARGO_PKG_VERSION"),
    " (commit ",
    env!("MORPHOID_COMMIT"),
    ")"
);

/// Identify anatomical surfaces with the continuous Procrustes distance.
#[derive(Debug, Parser)]
#[command(name = "morphoid", version = VERSION, about)]
struct Cli {
    /// More log output (repeat for more).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    verbose: u8,
    /// Configuration file (TOML; see config/morphoid.toml), read by every
    /// command. Without it, the built-in defaults.
    #[arg(long, global = true, value_name = "FILE")]
    config: Option<PathBuf>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Load and clean a surface, print the cleaning report.
    Inspect(inspect::Args),
    /// The whole loop on synthetic data in a temporary folder (no data or config needed).
    Demo(demo::Args),
    /// Identify scans against the reference library; results go to the database.
    Classify(classify::Args),
    /// Show what has been identified, newest first.
    Results(results::Args),
    /// Write the HTML report of recorded scans (and the overview page) into a folder.
    Report(report::Args),
    /// Prepare and cache the reference library, or list it.
    Library(library::Args),
    /// The cP (or cWn) distance of two surfaces, and the cP correspondence.
    Distance(distance::Args),
    /// The all-pairs cP (or cWn) distance matrix of a folder of surfaces.
    Matrix(matrix::Args),
    /// Leave-one-out nearest-neighbour classification from a distance matrix.
    Evaluate(evaluate::Args),
    /// Watch the export folder and identify every new scan (the daemon).
    Run(run::Args),
    /// Validate a configuration file; name any wrong key or value.
    CheckConfig(check_config::Args),
    /// Write a synthetic crown-like surface (to try morphoid without data).
    Synth(synth::Args),
    /// Carry landmarks of a reference onto another surface through cP maps.
    Propagate(propagate::Args),
    /// Put a whole collection in correspondence: pseudolandmarks, GPA, PCA.
    Align(align::Args),
    /// Confirm, correct or reject a scan's identification (a curator's decision).
    Review(review::Args),
    /// Manage the web console's curators and their API tokens.
    User(user::Args),
    /// Write man pages and shell completions (for packagers).
    #[command(hide = true)]
    Assets(assets::Args),
}

/// Parse the command line, run the subcommand, map errors to an exit code.
pub(crate) fn main() -> ExitCode {
    let cli = Cli::parse();
    // The daemon logs one info line per scan by default.
    let daemon = matches!(cli.command, Command::Run(_));
    init_tracing(cli.verbose + u8::from(daemon));
    let config = ConfigFile(cli.config.as_deref());
    let result = match cli.command {
        Command::Inspect(a) => inspect::run(a, config),
        Command::Synth(a) => synth::run(a, config),
        Command::Distance(a) => distance::run(a, config),
        Command::Library(a) => library::run(a, config),
        Command::Classify(a) => classify::run(a, config),
        Command::Demo(a) => demo::run(a, config),
        Command::Results(a) => results::run(a, config),
        Command::Report(a) => report::run(a, config),
        Command::Matrix(a) => matrix::run(a, config),
        Command::Evaluate(a) => evaluate::run(a, config),
        Command::Propagate(a) => propagate::run(a, config),
        Command::Align(a) => align::run(a, config),
        Command::Run(a) => run::run(a, config),
        Command::CheckConfig(a) => check_config::run(a, config),
        Command::Review(a) => review::run(a, config),
        Command::User(a) => user::run(a, config),
        Command::Assets(a) => assets::run(a),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("morphoid: error: {}", one_line(&e));
            ExitCode::FAILURE
        }
    }
}

/// One line, as users read it in a log: the context chain joined by `: `,
/// by the library's one rule (a cause whose text the line already ends
/// with is not repeated).
fn one_line(e: &anyhow::Error) -> String {
    morphoid_data::present::error_chain(e.as_ref())
}

/// Logs go to stderr so that `--json` output on stdout stays parseable.
fn init_tracing(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        2 => "debug",
        _ => "trace",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_env("MORPHOID_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        // `MORPHOID_LOG_SPANS=1`: each stage's span, when it closes, with
        // its busy and idle time (where a slow scan's time goes).
        .with_span_events(if std::env::var_os("MORPHOID_LOG_SPANS").is_some() {
            tracing_subscriber::fmt::format::FmtSpan::CLOSE
        } else {
            tracing_subscriber::fmt::format::FmtSpan::NONE
        })
        // journald and files get no colour codes.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()));
    // Under systemd the journal stamps each line itself.
    let _ = if std::env::var_os("JOURNAL_STREAM").is_some() {
        builder.without_time().try_init()
    } else {
        builder.try_init()
    };
}

/// Size rayon's global pool once, before any parallel work.
fn configure_threads(threads: Option<usize>) -> anyhow::Result<()> {
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global()
            .map_err(|e| anyhow::anyhow!("cannot start {n} worker threads: {e}"))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn the_command_line_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn an_error_line_names_the_os_error_once() {
        let os = "(os error 2)";
        let shard =
            morphoid_research::eval::ShardFile::read(std::path::Path::new("/nonexistent/s.csv"))
                .unwrap_err();
        let e = anyhow::Error::new(shard).context("merging");
        let line = one_line(&e);
        assert_eq!(line.matches(os).count(), 1, "{line}");
        assert!(line.starts_with("merging: /nonexistent/s.csv"), "{line}");
    }

    #[test]
    fn the_version_names_the_commit() {
        let version = Cli::command().render_version();
        assert!(version.contains(env!("CARGO_PKG_VERSION")), "{version}");
        assert!(version.contains("(commit "), "{version}");
    }

    #[test]
    fn every_command_takes_config_before_or_after_its_name() {
        for args in [
            &[
                "morphoid",
                "matrix",
                "--library",
                "l",
                "--out",
                "o",
                "--config",
                "c",
            ][..],
            &["morphoid", "--config", "c", "distance", "a", "b"],
            &["morphoid", "check-config", "--config", "c"],
            &["morphoid", "synth", "--out", "x.ply", "--config", "c"],
            &["morphoid", "library", "build", "--config", "c"],
        ] {
            let cli = Cli::try_parse_from(args).unwrap();
            assert_eq!(
                cli.config.as_deref(),
                Some(std::path::Path::new("c")),
                "{args:?}"
            );
        }
    }
}
