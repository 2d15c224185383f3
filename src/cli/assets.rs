//! `morphoid assets` (hidden): man pages and shell completions generated
//! from the command-line definitions, for the Debian package
//! (`packaging/build-deb`) and other packagers. Not a user command.

use anyhow::{Context, Result};
use clap::CommandFactory;
use clap_complete::Shell;
use flate2::{Compression, GzBuilder};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `morphoid assets`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
    /// Folder to write `man/*.1.gz` and `completions/{morphoid.bash,
    /// _morphoid,morphoid.fish}` into (created when missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
}

/// Run `morphoid assets`.
pub(super) fn run(args: Args) -> Result<ExitCode> {
    let man = args.out.join("man");
    let completions = args.out.join("completions");
    for dir in [&man, &completions] {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let mut cmd = super::Cli::command();
    // Completions and man pages must not offer `help` as a command name
    // twice, nor this hidden command.
    cmd = cmd.disable_help_subcommand(true);
    cmd.build();
    let pages = write_man_pages(&cmd, &man)?;
    for shell in [Shell::Bash, Shell::Zsh, Shell::Fish] {
        clap_complete::generate_to(shell, &mut cmd, "morphoid", &completions).with_context(
            || {
                format!(
                    "writing the {shell} completion into {}",
                    completions.display()
                )
            },
        )?;
    }
    println!(
        "{} man pages in {}, completions for bash, zsh and fish in {}",
        pages,
        man.display(),
        completions.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// One page per command and nested subcommand (`morphoid-matrix-merge.1`),
/// gzipped without a timestamp (as Debian wants man pages), hidden ones
/// left out; returns how many.
fn write_man_pages(cmd: &clap::Command, dir: &Path) -> Result<usize> {
    let mut count = 0;
    for sub in cmd.get_subcommands().filter(|s| !s.is_hide_set()) {
        count += write_man_pages(sub, dir)?;
    }
    let page = clap_mangen::Man::new(cmd.clone());
    let path = dir.join(format!("{}.gz", page.get_filename()));
    let mut roff = Vec::new();
    page.render(&mut roff)
        .with_context(|| format!("rendering {}", path.display()))?;
    let file =
        std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?;
    let mut gz = GzBuilder::new().mtime(0).write(file, Compression::best());
    gz.write_all(&roff)
        .and_then(|()| gz.finish().map(drop))
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(count + 1)
}
