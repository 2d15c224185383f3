//! `morphoid review SCAN_ID --confirm | --taxon RANK=NAME… | --reject`: a
//! curator's decision from the command line, into the same audit trail as
//! the web console's.

use super::common::{ConfigArgs, ConfigFile};
use anyhow::{bail, Context, Result};
use morphoid_service::store::{Decision, NewReview, Store};
use std::collections::BTreeMap;
use std::process::ExitCode;

/// Arguments of `morphoid review`.
#[derive(Debug, clap::Args)]
#[command(group = clap::ArgGroup::new("decision").required(true).args(["confirm", "taxon", "reject"]))]
pub(super) struct Args {
    /// The scan's id (as `morphoid results` shows it).
    scan_id: i64,
    /// The identification is right.
    #[arg(long)]
    confirm: bool,
    /// The right taxon at a rank (repeat for several ranks).
    #[arg(long, value_name = "RANK=NAME")]
    taxon: Vec<String>,
    /// The scan is unusable.
    #[arg(long)]
    reject: bool,
    /// Why, in a few words.
    #[arg(long)]
    comment: Option<String>,
    /// Who decides (default: `unix:` and the login name).
    #[arg(long = "as", value_name = "NAME")]
    curator: Option<String>,
    /// Print the decision as recorded, as JSON.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    config: ConfigArgs,
}

/// Run `morphoid review`.
pub(super) fn run(args: Args, file: ConfigFile) -> Result<ExitCode> {
    let config = args.config.load(file)?;
    let decision = if args.confirm {
        Decision::Confirm
    } else if args.reject {
        Decision::Reject
    } else {
        let mut taxa = BTreeMap::new();
        for t in &args.taxon {
            let Some((rank, name)) = t.split_once('=') else {
                bail!("--taxon {t:?}: write RANK=NAME, e.g. genus=Ateles");
            };
            taxa.insert(rank.trim().to_string(), name.trim().to_string());
        }
        Decision::Correct(taxa)
    };
    let curator = args.curator.clone().unwrap_or_else(login_name);
    let db = &config.database.path;
    let mut store = Store::open(db).with_context(|| format!("opening {}", db.display()))?;
    let record = store.record_review(&NewReview {
        scan_id: args.scan_id,
        curator: &curator,
        decision,
        comment: args.comment.as_deref(),
        expected_latest: None,
        ranks: &config.library.ranks,
    })?;
    if args.json {
        println!("{}", serde_json::to_string(&record)?);
    } else {
        let taxa: Vec<String> = record
            .taxa
            .iter()
            .map(|(r, t)| format!("{r}: {t}"))
            .collect();
        println!(
            "scan {}: {} by {} recorded (decision #{}, the scan's {}){}",
            record.scan_id,
            record.decision,
            record.curator,
            record.id,
            record.seq,
            if taxa.is_empty() {
                String::new()
            } else {
                format!("; {}", taxa.join(", "))
            }
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// `unix:` and the name of the user running the command.
fn login_name() -> String {
    let name = ["USER", "LOGNAME"]
        .iter()
        .find_map(|v| std::env::var(v).ok().filter(|n| !n.is_empty()))
        .unwrap_or_else(|| "unknown".into());
    format!("unix:{name}")
}
