//! `morphoid classify`: one-shot identification of scans, recorded in the
//! database exactly as the daemon records them.

use super::common::{progress_bar, ConfigArgs, ConfigFile};
use anyhow::{Context, Result};
use morphoid_service::classify::{self, Classifier, ResultFiles};
use morphoid_service::identify::Confidence;
use morphoid_service::store::{ScanRecord, ScanStatus, Store};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `morphoid classify`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
    /// Surface files to identify.
    #[arg(required = true)]
    scans: Vec<PathBuf>,
    #[command(flatten)]
    config: ConfigArgs,
    /// Print one JSON object per scan on stdout.
    #[arg(long)]
    json: bool,
    /// Write `<name>.json` (the JSON line) for each scan into DIR and, when
    /// the nearest reference has landmarks, `<name>.fcsv` (the landmarks
    /// carried onto the scan); `<name>` is the scan's path relative to the
    /// export folder (`[watch] dir`) or as given, extension included.
    /// Default: `[results] dir` of the configuration, if any.
    #[arg(long, value_name = "DIR")]
    out_dir: Option<PathBuf>,
}

/// Run `morphoid classify`.
pub(super) fn run(args: Args, file: ConfigFile) -> Result<ExitCode> {
    let config = args.config.load(file)?;
    let lib = config.open_library()?;
    let cache = config.open_cache()?;
    let bar = progress_bar(lib.members().len() as u64, "library");
    let (classifier, built) = Classifier::build_with(&lib, &cache, &config, |_| bar.inc(1))?;
    bar.finish_and_clear();
    let db = &config.database.path;
    let mut store = Store::open(db)?;
    classifier
        .register(&mut store, &built)
        .with_context(|| format!("recording the references in {}", db.display()))?;

    let results = args
        .out_dir
        .clone()
        .or_else(|| config.results.dir.clone())
        .map(|dir| ResultFiles::for_scans(dir, &config.watch.dir, &args.scans));
    // Scans identified now get their report (and the overview) from the
    // job; the JSON of known ones is written below.
    let classifier = classifier.with_result_files(results.clone());
    let mut all_ok = true;
    for scan in &args.scans {
        let record = classify::identify_file(&mut store, &classifier, scan);
        let record = match record {
            Ok(r) => r,
            Err(e) => {
                all_ok = false;
                let message = morphoid_data::present::error_chain(&e);
                if args.json {
                    println!(
                        "{}",
                        serde_json::json!({"scan": scan.display().to_string(), "status": "error", "error": message})
                    );
                }
                eprintln!("morphoid: error: {message}");
                continue;
            }
        };
        if record.status != ScanStatus::Ok {
            all_ok = false;
            if let Some(e) = &record.error {
                eprintln!("morphoid: error: {e}");
            }
        }
        if args.json {
            println!("{}", serde_json::to_string(&record)?);
        } else {
            println!("{}", summary(&record));
        }
        if let Some(files) = &results {
            let written = write_known(&mut store, &classifier, files, &record);
            if let Err(e) = &written {
                all_ok = false;
                eprintln!("morphoid: error: {}: result files: {e}", scan.display());
            }
            classify::record_files_attempt(&mut store, record.id, &written).with_context(|| {
                format!("recording in {} how the result files went", db.display())
            })?;
        }
    }
    Ok(if all_ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// The result files of a scan: the JSON always, and the report (drawn
/// again from the file) and overview when the report is missing (a scan
/// identified before, or into another folder).
fn write_known(
    store: &mut Store,
    classifier: &Classifier,
    files: &ResultFiles,
    record: &ScanRecord,
) -> Result<(), classify::ResultsError> {
    // Written now, so no earlier failure belongs on the page.
    let record = &ScanRecord {
        files_error: None,
        ..record.clone()
    };
    for c in &record.specimens {
        write_known(store, classifier, files, c)?;
    }
    files.write(record)?;
    if files.report_paths(record).0.exists() {
        return Ok(());
    }
    let (scene, note) = match classifier.scene_of_record(record) {
        Ok(scene) => (Some(scene), None),
        Err(_) if record.nearest.is_empty() => (None, None),
        Err(e) => (None, Some(e.to_string())),
    };
    files.write_report(record, scene.as_ref(), note.as_deref())?;
    files.write_index(store)?;
    Ok(())
}

/// One line per scan for people: the taxon at each rank with its
/// probability and the "NO CLOSE MATCH" flag when the library is
/// calibrated, "confidence: calibrating" when it was identified before the
/// calibration was ready (and how many landmarks were carried onto the
/// scan); then why its result files could not be written, if they could
/// not.
pub(super) fn summary(r: &ScanRecord) -> String {
    let line = status_summary(r);
    let mut out = match &r.files_error {
        Some(e) => format!("{line}; result files not written: {e}"),
        None => line,
    };
    // A scan of several specimens: one line each, below it.
    for c in &r.specimens {
        out.push_str("\n  ");
        out.push_str(&summary(c));
    }
    out
}

/// The "no close match" flag with its reason: the scan's novelty score
/// over the threshold the library's own members set.
fn no_close_match(c: &Confidence) -> String {
    match (c.no_close_match, c.novelty_threshold) {
        (Some(true), Some(t)) => format!(
            "; NO CLOSE MATCH: novelty {:.2} over {t:.2}, farther from the library than its own members are",
            c.novelty
        ),
        (Some(true), None) => "; NO CLOSE MATCH".to_string(),
        _ => String::new(),
    }
}

/// [`summary`] without the result files.
fn status_summary(r: &ScanRecord) -> String {
    if let (Some(n), ScanStatus::Ok) = (r.specimen_count, r.status) {
        return format!(
            "{}: {n} specimens (numbered along the scan's longest axis)",
            r.path
        );
    }
    match r.status {
        ScanStatus::Ok => {
            let ranks: Vec<String> = r
                .ranks
                .iter()
                .map(|k| {
                    let runner = match (&k.runner_up, k.margin) {
                        (Some(t), Some(m)) => format!("; next {t} +{m:.4}"),
                        _ => String::new(),
                    };
                    let confidence = match &k.confidence {
                        Some(c) => format!("; p {:.2}{}", c.probability, no_close_match(c)),
                        None => String::new(),
                    };
                    format!(
                        "{} {} ({} at {:.4}{runner}{confidence})",
                        k.rank, k.taxon, k.reference, k.distance
                    )
                })
                .collect();
            let landmarks = match &r.landmarks {
                Some(lm) => format!("; {} landmarks from {}", lm.points.len(), lm.reference),
                None => String::new(),
            };
            let calibrating = if r.calibrating {
                "; confidence: calibrating"
            } else {
                ""
            };
            let warnings: String = r.cleaning["warnings"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|w| w.as_str())
                .map(|w| format!("; warning: {w}"))
                .collect();
            format!(
                "{}: {}{calibrating}{landmarks}{warnings}",
                r.path,
                ranks.join(", ")
            )
        }
        ScanStatus::Error => format!(
            "{}: error: {}",
            r.path,
            r.error.as_deref().unwrap_or("unknown")
        ),
        ScanStatus::Duplicate => {
            let (id, path) = r
                .duplicate_of
                .as_ref()
                .map(|o| (o.id, o.path.as_str()))
                .unwrap_or_default();
            format!("{}: duplicate of scan {id} ({path})", r.path)
        }
        ScanStatus::Superseded => format!(
            "{}: changed while it was read; superseded by scan {}",
            r.path,
            r.superseded_by.unwrap_or_default()
        ),
        s => format!("{}: {}", r.path, s.as_str()),
    }
}
