//! The `morphoid` command-line tool: argument parsing and dispatch only;
//! each subcommand lives in its own module under `cli/`.

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    cli::main()
}
