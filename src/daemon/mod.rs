//! The daemon behind `morphoid run`: watches the export folder, queues each
//! complete file as a job in the store, identifies jobs one at a time on a
//! worker thread with the library loaded once, and reacts to the serial
//! trigger, SIGTERM/SIGINT (stop), SIGHUP (reload) and the systemd watchdog.
//!
//! Threads: the control loop (this module's [`run`]) polls the folder every
//! [`POLL_INTERVAL`] (a listing + `stat` per file; the settle rule needs
//! periodic checks anyway, and polling sees renames, moves from other
//! filesystems and network folders alike), a worker thread owns the
//! classifier and does the numerical work, and an optional serial thread
//! forwards trigger lines.

pub mod glob;
pub mod sd_notify;
pub mod serial;
pub mod settle;
mod signals;

use crate::classify::{self, Classifier, NEAREST};
use crate::config::Config;
use crate::library::BuildOutcome;
use crate::mesh::io::Format;
use crate::store::{
    content_hash_file, now_ms, utc_day_start_ms, Enqueued, ScanStatus, Store, StoreError,
};
use regex::Regex;
use sd_notify::Notifier;
use settle::{Settler, Stamp};
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How often the export folder is listed while a file is settling.
pub const POLL_INTERVAL: Duration = Duration::from_millis(250);
/// How often it is listed when nothing is settling (a large folder costs
/// one `stat` per file per listing).
pub const IDLE_POLL_INTERVAL: Duration = Duration::from_secs(1);
/// A scan claimed this many times without finishing has crashed the
/// daemon each time (or hung it until the watchdog fired): it is failed
/// instead of being tried for ever.
pub const MAX_ATTEMPTS: u32 = 3;
/// A job running longer than this is taken as hung: watchdog pings stop,
/// so systemd restarts the daemon (and [`MAX_ATTEMPTS`] ends the loop).
pub const JOB_HANG_LIMIT: Duration = Duration::from_secs(30 * 60);
/// How long a stop waits for the current job before abandoning it, unless
/// `$MORPHOID_STOP_GRACE` (seconds, at most 60) says otherwise. systemd's
/// `TimeoutStopSec=` must be longer.
pub const STOP_GRACE: Duration = Duration::from_secs(7);

/// The stop grace period: `$MORPHOID_STOP_GRACE` or [`STOP_GRACE`].
pub fn stop_grace() -> Duration {
    std::env::var("MORPHOID_STOP_GRACE")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s >= 0.0)
        .map(|s| Duration::from_secs_f64(s.min(60.0)))
        .unwrap_or(STOP_GRACE)
}

/// Why the daemon could not start (or reload).
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    /// The configuration or the library could not be loaded.
    #[error("{0}")]
    Load(String),
    /// The database failed.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// The export folder cannot be listed.
    #[error("{path}: cannot watch the export folder: {source}")]
    Watch {
        /// The folder.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// `serial.trigger` is not a valid regex.
    #[error("serial.trigger: {0}")]
    Trigger(#[from] regex::Error),
    /// Signal handlers could not be installed.
    #[error("cannot install signal handlers: {0}")]
    Signals(std::io::Error),
}

/// What the daemon needs from its caller: the configuration (re-read on
/// SIGHUP) and the prepared library for a configuration.
pub trait Loader {
    /// The current configuration, with any command-line overrides.
    fn config(&self) -> Result<Config, String>;
    /// The classifier of the configured library (cached references).
    fn library(&self, config: &Config) -> Result<(Classifier, BuildOutcome), String>;
}

/// Messages to the worker thread.
enum ToWorker {
    /// New jobs may be pending.
    Wake,
    /// Use this classifier and quarantine folder from the next job on.
    Reload(Box<Classifier>, Option<PathBuf>),
}

/// Every non-ignored surface file (a format morphoid reads, by extension)
/// under `dir`, recursively if asked, with its stamp; `skip` (the
/// quarantine folder) is not entered. Other files (the scanner's logs,
/// reports, images) are left alone rather than recorded as errors.
pub fn list_candidates(
    dir: &Path,
    recursive: bool,
    ignore: &[String],
    skip: Option<&Path>,
) -> std::io::Result<Vec<(PathBuf, Stamp)>> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    let mut top = true;
    while let Some(d) = stack.pop() {
        let entries = match std::fs::read_dir(&d) {
            Ok(e) => e,
            // Only the export folder itself must be readable; a subfolder
            // may vanish between listing and reading.
            Err(e) if top => return Err(e),
            Err(_) => continue,
        };
        top = false;
        for entry in entries.flatten() {
            let name = entry.file_name();
            let name = name.to_string_lossy();
            if glob::is_ignored(ignore, &name) {
                continue;
            }
            let path = entry.path();
            let Ok(meta) = std::fs::metadata(&path) else {
                continue;
            };
            if meta.is_dir() {
                if recursive && skip.is_none_or(|s| !same_dir(s, &path)) {
                    stack.push(path);
                }
            } else if meta.is_file() && Format::from_path(&path).is_some() {
                let stamp = Stamp {
                    size: meta.len(),
                    mtime: meta.modified().ok(),
                };
                out.push((path, stamp));
            }
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

fn same_dir(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

/// Run the daemon until SIGTERM/SIGINT. Returns an error only when it
/// cannot start; afterwards every problem is logged and survived.
pub fn run(loader: &dyn Loader) -> Result<(), DaemonError> {
    signals::install().map_err(DaemonError::Signals)?;
    let notifier = Notifier::from_env();
    let mut config = loader.config().map_err(DaemonError::Load)?;
    let trigger = compile_trigger(&config)?;
    let db = config.database.path.clone();
    let mut store = Store::open(&db)?;
    let requeued = store.requeue_running()?;
    if requeued > 0 {
        tracing::info!("{requeued} scan(s) left running by an earlier run are pending again");
    }
    let (classifier, outcome) = loader.library(&config).map_err(DaemonError::Load)?;
    classifier.register(&mut store, &outcome)?;
    for (name, why) in &outcome.failures {
        tracing::warn!("reference {name} left out: {why}");
    }
    let mut n_refs = classifier.references.len();
    tracing::info!(
        "library {} loaded: {n_refs} references; watching {}",
        config.library.dir.display(),
        config.watch.dir.display()
    );

    let stop = Arc::new(AtomicBool::new(false));
    let current = Arc::new(AtomicI64::new(0));
    let job_started_ms = Arc::new(AtomicI64::new(0));
    let (to_worker, worker_rx) = mpsc::channel::<ToWorker>();
    let worker = {
        let stop = stop.clone();
        let current = current.clone();
        let job_started_ms = job_started_ms.clone();
        let store = Store::open(&db)?;
        let quarantine = config.watch.quarantine.clone();
        std::thread::Builder::new()
            .name("morphoid-worker".into())
            .spawn(move || {
                let progress = Progress {
                    current,
                    started_ms: job_started_ms,
                };
                worker_loop(store, classifier, quarantine, worker_rx, stop, progress)
            })
            .map_err(|e| DaemonError::Load(format!("cannot start the worker thread: {e}")))?
    };

    let (serial_tx, serial_rx) = mpsc::channel::<String>();
    let mut serial_stop = start_serial(&config, trigger.as_ref(), &serial_tx);

    notifier.send("READY=1");
    let watchdog = Notifier::watchdog_interval();
    let mut last_ping = Instant::now();
    let mut last_status = String::new();
    let mut last_status_at = Instant::now() - Duration::from_secs(60);
    let mut settler = Settler::new();
    let mut watch_error_logged = false;
    let mut hang_logged = false;
    let _ = to_worker.send(ToWorker::Wake);

    loop {
        if signals::stop_requested() {
            break;
        }
        if signals::take_reload() {
            tracing::info!("reloading the configuration and the library");
            notifier.send("RELOADING=1");
            match reload(loader, &mut store) {
                Ok((c, classifier, t)) => {
                    n_refs = classifier.references.len();
                    let _ = to_worker.send(ToWorker::Reload(
                        Box::new(classifier),
                        c.watch.quarantine.clone(),
                    ));
                    if c.serial != config.serial {
                        if let Some(s) = serial_stop.take() {
                            s.store(true, Ordering::SeqCst);
                        }
                        serial_stop = start_serial(&c, t.as_ref(), &serial_tx);
                    }
                    if c.database.path != config.database.path {
                        tracing::warn!("database.path changes only at restart");
                    }
                    config = c;
                    settler = Settler::new();
                    tracing::info!("reloaded: {n_refs} references");
                }
                Err(e) => tracing::error!("reload failed, keeping the previous setup: {e}"),
            }
            notifier.send("READY=1");
        }

        // Serial triggers: a named file first, then everything now.
        let mut forced = false;
        while let Ok(line) = serial_rx.try_recv() {
            forced = true;
            if let Some(file) = named_file(&line, &config.watch.dir) {
                if let Ok(meta) = std::fs::metadata(&file) {
                    let stamp = Stamp {
                        size: meta.len(),
                        mtime: meta.modified().ok(),
                    };
                    if settler.force(&file, stamp, Instant::now()) {
                        take_file(&mut store, &mut settler, &file, &to_worker);
                    }
                }
            }
        }

        let skip = config.watch.quarantine.as_deref();
        match list_candidates(
            &config.watch.dir,
            config.watch.recursive,
            &config.watch.ignore,
            skip,
        ) {
            Ok(files) => {
                watch_error_logged = false;
                let now = Instant::now();
                let settle = Duration::from_secs_f64(config.watch.settle_seconds);
                let listed: HashSet<PathBuf> = files.iter().map(|(p, _)| p.clone()).collect();
                settler.retain_listed(&listed);
                for (path, stamp) in files {
                    let ready = if forced {
                        settler.force(&path, stamp, now)
                    } else {
                        settler.observe(&path, stamp, now, settle)
                    };
                    if ready {
                        take_file(&mut store, &mut settler, &path, &to_worker);
                    }
                }
            }
            Err(e) => {
                if !watch_error_logged {
                    tracing::error!(
                        "{}: cannot list the export folder: {e}; retrying",
                        config.watch.dir.display()
                    );
                    watch_error_logged = true;
                }
            }
        }

        if let Some(interval) = watchdog {
            let started = job_started_ms.load(Ordering::SeqCst);
            let hung = current.load(Ordering::SeqCst) > 0
                && started > 0
                && now_ms() - started > JOB_HANG_LIMIT.as_millis() as i64;
            if hung && !hang_logged {
                tracing::error!(
                    "the current job looks hung; letting the watchdog restart the daemon"
                );
                hang_logged = true;
            }
            if !hung && last_ping.elapsed() >= interval {
                notifier.send("WATCHDOG=1");
                last_ping = Instant::now();
            }
        }
        if last_status_at.elapsed() >= Duration::from_secs(2) {
            let status = status_line(&store, n_refs, current.load(Ordering::SeqCst));
            if status != last_status {
                notifier.send(&format!("STATUS={status}"));
                last_status = status;
            }
            last_status_at = Instant::now();
        }
        // Sleep in short steps so signals and triggers are handled fast.
        let next = if settler.waiting() {
            POLL_INTERVAL
        } else {
            IDLE_POLL_INTERVAL
        };
        let until = Instant::now() + next;
        while Instant::now() < until && !signals::stop_requested() {
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    tracing::info!("stopping");
    notifier.send("STOPPING=1");
    stop.store(true, Ordering::SeqCst);
    if let Some(s) = serial_stop.take() {
        s.store(true, Ordering::SeqCst);
    }
    drop(to_worker);
    let deadline = Instant::now() + stop_grace();
    while !worker.is_finished() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(50));
    }
    if !worker.is_finished() {
        let id = current.load(Ordering::SeqCst);
        if id > 0 {
            match store.abandon(id) {
                Ok(()) => tracing::info!("scan {id} abandoned; it is pending for the next start"),
                Err(e) => tracing::warn!("scan {id} could not be abandoned: {e}"),
            }
        }
    }
    Ok(())
}

fn compile_trigger(config: &Config) -> Result<Option<Regex>, DaemonError> {
    Ok(match &config.serial {
        Some(s) => Some(Regex::new(&s.trigger)?),
        None => None,
    })
}

/// Re-read the configuration and load its library (SIGHUP).
fn reload(
    loader: &dyn Loader,
    store: &mut Store,
) -> Result<(Config, Classifier, Option<Regex>), String> {
    let config = loader.config()?;
    let trigger = compile_trigger(&config).map_err(|e| e.to_string())?;
    let (classifier, outcome) = loader.library(&config)?;
    classifier
        .register(store, &outcome)
        .map_err(|e| e.to_string())?;
    Ok((config, classifier, trigger))
}

fn start_serial(
    config: &Config,
    trigger: Option<&Regex>,
    tx: &Sender<String>,
) -> Option<Arc<AtomicBool>> {
    let (s, re) = (config.serial.as_ref()?, trigger?);
    let stop = Arc::new(AtomicBool::new(false));
    let (port, baud, re, tx, flag) = (s.port.clone(), s.baud, re.clone(), tx.clone(), stop.clone());
    let spawned = std::thread::Builder::new()
        .name("morphoid-serial".into())
        .spawn(move || serial::run(port, baud, re, tx, flag));
    match spawned {
        Ok(_) => Some(stop),
        Err(e) => {
            tracing::error!("cannot start the serial thread: {e}");
            None
        }
    }
}

/// A word of a trigger line that names an existing file, as given or
/// relative to the export folder.
pub fn named_file(line: &str, watch_dir: &Path) -> Option<PathBuf> {
    line.split_whitespace().find_map(|word| {
        let p = Path::new(word);
        [p.to_path_buf(), watch_dir.join(p)]
            .into_iter()
            .find(|c| c.is_file())
    })
}

/// Hash a settled file and queue it; known content is not queued again.
fn take_file(store: &mut Store, settler: &mut Settler, path: &Path, to_worker: &Sender<ToWorker>) {
    let (hash, size) = match content_hash_file(path) {
        Ok(h) => h,
        Err(e) => {
            tracing::warn!("{}: cannot read: {e}", path.display());
            settler.release(path);
            return;
        }
    };
    match store.enqueue(&path.display().to_string(), &hash, size) {
        Ok(Enqueued::New(id)) => {
            tracing::debug!("{}: queued as scan {id}", path.display());
            let _ = to_worker.send(ToWorker::Wake);
        }
        Ok(Enqueued::Existing(id, status)) => tracing::debug!(
            "{}: content already known as scan {id} ({})",
            path.display(),
            status.as_str()
        ),
        Err(e) => {
            tracing::error!("{}: cannot queue: {e}", path.display());
            settler.release(path);
        }
    }
}

/// "idle, 116 references, 42 scans today" (or "identifying …").
fn status_line(store: &Store, n_refs: usize, current: i64) -> String {
    let today = store
        .finished_since(utc_day_start_ms(now_ms()))
        .unwrap_or(0);
    let pending = store.counts().map(|c| c.pending).unwrap_or(0);
    let state = if current > 0 {
        format!("identifying scan {current}")
    } else {
        "idle".to_string()
    };
    let queue = if pending > 0 {
        format!(", {pending} pending")
    } else {
        String::new()
    };
    format!("{state}, {n_refs} references, {today} scans today{queue}")
}

/// What the worker shares with the control loop: the scan it is
/// identifying (0: none) and since when (Unix ms).
struct Progress {
    current: Arc<AtomicI64>,
    started_ms: Arc<AtomicI64>,
}

/// The worker: claim pending jobs one at a time and identify them.
fn worker_loop(
    mut store: Store,
    mut classifier: Classifier,
    mut quarantine: Option<PathBuf>,
    rx: Receiver<ToWorker>,
    stop: Arc<AtomicBool>,
    progress: Progress,
) {
    loop {
        // Drain messages; a periodic wake-up also catches jobs queued by
        // another process (`classify` leaves none behind, but be safe).
        match rx.recv_timeout(Duration::from_secs(5)) {
            Ok(ToWorker::Reload(c, q)) => {
                classifier = *c;
                quarantine = q;
            }
            Ok(ToWorker::Wake) | Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => return,
        }
        while !stop.load(Ordering::SeqCst) {
            if let Ok(ToWorker::Reload(c, q)) = rx.try_recv() {
                classifier = *c;
                quarantine = q;
            }
            let job = match store.claim_next() {
                Ok(Some(job)) => job,
                Ok(None) => break,
                Err(e) => {
                    tracing::error!("cannot claim a job: {e}");
                    std::thread::sleep(Duration::from_secs(1));
                    break;
                }
            };
            if job.attempts > MAX_ATTEMPTS {
                let message = format!(
                    "{}: given up after {} attempts that did not finish (the daemon died on it)",
                    job.path,
                    job.attempts - 1
                );
                tracing::error!("{message}");
                if let Err(e) = store.fail(job.scan_id, &message) {
                    tracing::error!("{}: cannot record the failure: {e}", job.path);
                }
                continue;
            }
            progress.started_ms.store(now_ms(), Ordering::SeqCst);
            progress.current.store(job.scan_id, Ordering::SeqCst);
            let started = Instant::now();
            let status = classify::run_job(&mut store, &classifier, &job);
            let secs = started.elapsed().as_secs_f64();
            progress.current.store(0, Ordering::SeqCst);
            match status {
                Ok(ScanStatus::Ok) => log_result(&store, job.scan_id, &job.path, secs),
                Ok(_) => {
                    let message = store
                        .scan(job.scan_id, 0)
                        .ok()
                        .flatten()
                        .and_then(|r| r.error)
                        .unwrap_or_default();
                    tracing::warn!("{}: error after {secs:.1} s: {message}", job.path);
                    if let Some(q) = &quarantine {
                        move_to_quarantine(Path::new(&job.path), q);
                    }
                }
                Err(e) => tracing::error!("{}: cannot record the result: {e}", job.path),
            }
        }
        if stop.load(Ordering::SeqCst) {
            return;
        }
    }
}

/// One info line per identified scan: file, nearest taxon per rank with
/// its distance, time taken.
fn log_result(store: &Store, id: i64, path: &str, secs: f64) {
    let record = store.scan(id, NEAREST).ok().flatten();
    let ranks = record
        .map(|r| {
            r.ranks
                .iter()
                .map(|k| {
                    format!(
                        "{}={} ({} at {:.4})",
                        k.rank, k.taxon, k.reference, k.distance
                    )
                })
                .collect::<Vec<_>>()
                .join(", ")
        })
        .unwrap_or_default();
    tracing::info!("{path}: {ranks}; {secs:.1} s");
}

/// Move an unusable file into the quarantine folder (keeping its name,
/// numbered if taken). Failures are logged: the error row is what counts.
fn move_to_quarantine(file: &Path, folder: &Path) {
    let Some(name) = file.file_name() else {
        return;
    };
    if let Err(e) = std::fs::create_dir_all(folder) {
        tracing::warn!("{}: cannot create quarantine: {e}", folder.display());
        return;
    }
    let mut target = folder.join(name);
    let mut n = 1;
    while target.exists() {
        target = folder.join(format!("{}.{n}", name.to_string_lossy()));
        n += 1;
    }
    let moved = std::fs::rename(file, &target)
        .or_else(|_| std::fs::copy(file, &target).and_then(|_| std::fs::remove_file(file)));
    match moved {
        Ok(()) => tracing::info!("{} moved to {}", file.display(), target.display()),
        Err(e) => tracing::warn!("{}: cannot quarantine: {e}", file.display()),
    }
}
