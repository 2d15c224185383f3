//! The `morphoid` command-line tool: argument parsing and dispatch only;
//! each subcommand lives in its own module under `cli/`.

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    // Like any Unix filter: when the reader of our output goes away
    // (`morphoid library list | head`), end quietly instead of panicking
    // on a failed print.
    // SAFETY: called before any other thread exists; SIG_DFL is always valid.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    cli::main()
}
