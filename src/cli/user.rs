//! `morphoid user add|remove|list|token|revoke-tokens`: the curators who
//! may log in to the web console and take decisions (`[http]`).

use super::common::{ConfigArgs, ConfigFile};
use anyhow::{bail, Context, Result};
use morphoid_service::http::{hash_password, new_api_token, token_hash};
use morphoid_service::store::Store;
use std::io::{BufRead, IsTerminal, Write};
use std::process::{Command, ExitCode, Stdio};

/// Arguments of `morphoid user`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
    #[command(subcommand)]
    action: Action,
}

#[derive(Debug, clap::Subcommand)]
enum Action {
    /// Add a curator; the password is read from standard input (one line).
    Add {
        /// Login name (letters, digits, '.', '_', '-', '@').
        name: String,
        #[command(flatten)]
        config: ConfigArgs,
    },
    /// Remove a curator and their API tokens (their decisions stay).
    Remove {
        /// Login name.
        name: String,
        #[command(flatten)]
        config: ConfigArgs,
    },
    /// List the curators.
    List {
        /// One JSON object per curator.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        config: ConfigArgs,
    },
    /// Issue an API token for scripts (`Authorization: Bearer TOKEN`);
    /// printed once, only its hash is stored.
    Token {
        /// The curator the token acts as.
        name: String,
        /// What the token is for (shown nowhere but the database).
        #[arg(long, default_value = "")]
        label: String,
        #[command(flatten)]
        config: ConfigArgs,
    },
    /// Remove every API token of a curator.
    RevokeTokens {
        /// Login name.
        name: String,
        #[command(flatten)]
        config: ConfigArgs,
    },
}

/// Run `morphoid user`.
pub(super) fn run(args: Args, file: ConfigFile) -> Result<ExitCode> {
    let open = |config: &ConfigArgs| -> Result<Store> {
        let config = config.load(file)?;
        let db = &config.database.path;
        Store::open(db).with_context(|| format!("opening {}", db.display()))
    };
    match args.action {
        Action::Add { name, config } => {
            let mut store = open(&config)?;
            let password = read_password(&name)?;
            let hash = hash_password(&password)?;
            store.add_curator(&name, &hash)?;
            eprintln!("user {name} added");
        }
        Action::Remove { name, config } => {
            open(&config)?.remove_curator(&name)?;
            eprintln!("user {name} removed");
        }
        Action::List { json, config } => {
            for c in open(&config)?.curators()? {
                if json {
                    println!("{}", serde_json::to_string(&c)?);
                } else {
                    println!(
                        "{}\tadded {}\t{} API token(s)",
                        c.name,
                        morphoid_service::report::utc_time(c.created_at_ms),
                        c.tokens
                    );
                }
            }
        }
        Action::Token {
            name,
            label,
            config,
        } => {
            let token = new_api_token();
            open(&config)?.add_api_token(&name, &token_hash(&token), &label)?;
            println!("{token}");
            eprintln!("API token of {name} (shown once; send it as `Authorization: Bearer …`)");
        }
        Action::RevokeTokens { name, config } => {
            let n = open(&config)?.revoke_api_tokens(&name)?;
            eprintln!("{n} API token(s) of {name} removed");
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The password: the first line of standard input (typed without echo on a
/// terminal, and asked twice).
fn read_password(name: &str) -> Result<String> {
    let stdin = std::io::stdin();
    if !stdin.is_terminal() {
        let mut line = String::new();
        stdin
            .lock()
            .read_line(&mut line)
            .context("reading the password")?;
        return Ok(line.trim_end_matches(['\r', '\n']).to_string());
    }
    let first = prompt_hidden(&format!("password for {name}: "))?;
    let again = prompt_hidden("again: ")?;
    if first != again {
        bail!("the passwords differ");
    }
    Ok(first)
}

/// One line typed on the terminal with echo off (`stty`), the echo put
/// back afterwards.
fn prompt_hidden(prompt: &str) -> Result<String> {
    let stty = |arg: &str| {
        Command::new("stty")
            .arg(arg)
            .stdin(Stdio::inherit())
            .status()
            .is_ok_and(|s| s.success())
    };
    eprint!("{prompt}");
    let _ = std::io::stderr().flush();
    let hidden = stty("-echo");
    let mut line = String::new();
    let read = std::io::stdin().lock().read_line(&mut line);
    if hidden {
        stty("echo");
    }
    eprintln!();
    read.context("reading the password")?;
    Ok(line.trim_end_matches(['\r', '\n']).to_string())
}
