//! `morphoid report`: write the HTML report of recorded scans (and the
//! overview of the folder) from the database.

use super::common::{progress_bar, ConfigArgs, ConfigFile};
use anyhow::{bail, Context, Result};
use morphoid_service::classify::{Classifier, ResultFiles, NEAREST};
use morphoid_service::config::Config;
use morphoid_service::store::{ScanRecord, Store};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `morphoid report`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
    /// The scan's id (as `morphoid results` shows it).
    #[arg(conflicts_with = "last", required_unless_present = "last")]
    scan_id: Option<i64>,
    /// The N most recent scans instead of one.
    #[arg(long, value_name = "N")]
    last: Option<usize>,
    /// Folder the reports and `index.html` go into.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    #[command(flatten)]
    config: ConfigArgs,
}

/// Run `morphoid report`.
pub(super) fn run(args: Args, file: ConfigFile) -> Result<ExitCode> {
    let config = args.config.load(file)?;
    let db = &config.database.path;
    let mut store = Store::open(db).with_context(|| format!("opening {}", db.display()))?;
    let records: Vec<ScanRecord> = match (args.scan_id, args.last) {
        (Some(id), _) => match store.scan(id, NEAREST)? {
            Some(r) => vec![r],
            None => bail!("{}: no scan with id {id}", db.display()),
        },
        (None, Some(n)) => store.recent(n)?,
        (None, None) => bail!("give a scan id or --last N"),
    };
    // A scan of several specimens: each specimen's page too.
    let records: Vec<ScanRecord> = records
        .into_iter()
        .flat_map(|r| {
            let specimens = r.specimens.clone();
            std::iter::once(r).chain(specimens)
        })
        .collect();
    let files = ResultFiles::new(args.out.clone(), Some(config.watch.dir.clone()));
    // The library is needed only to draw identified scans.
    let mut classifier: Option<Classifier> = None;
    for record in &records {
        let (scene, note) = if record.nearest.is_empty() {
            (None, None)
        } else {
            if classifier.is_none() {
                classifier = Some(build(&config)?);
            }
            match classifier.as_ref().map(|c| c.scene_of_record(record)) {
                Some(Ok(scene)) => (Some(scene), None),
                Some(Err(e)) => {
                    eprintln!("morphoid: warning: {e}");
                    (None, Some(e.to_string()))
                }
                None => (None, None),
            }
        };
        let path = files
            .write_report(record, scene.as_ref(), note.as_deref())
            .with_context(|| format!("writing the report of scan {}", record.id))?;
        println!("{}", path.display());
    }
    let index = files
        .write_index(&mut store)
        .with_context(|| format!("writing the overview in {}", args.out.display()))?;
    println!("{}", index.display());
    Ok(ExitCode::SUCCESS)
}

/// The classifier of the configured library (from its cache).
fn build(config: &Config) -> Result<Classifier> {
    let lib = config.open_library()?;
    let cache = config.open_cache()?;
    let bar = progress_bar(lib.members().len() as u64, "library");
    let (classifier, _) = Classifier::build(&lib, &cache, &config.settings(), |_| bar.inc(1))?;
    bar.finish_and_clear();
    Ok(classifier)
}
