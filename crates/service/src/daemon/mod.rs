//! The daemon behind `morphoid run`: watches the export folder, queues each
//! complete surface file as a job in the store, identifies jobs one at a
//! time on a worker thread with the library loaded once, and reacts to the
//! serial trigger, SIGTERM/SIGINT (stop), SIGHUP (reload) and the systemd
//! watchdog.
//!
//! The control loop runs on a current-thread tokio runtime: one `select!`
//! over the signals, the folder watcher's events, serial trigger lines and
//! a few timers (settle checks, the safety rescan, watchdog and status),
//! each kind of event handled by its own method of the running `Daemon`. Everything
//! slow is elsewhere: hashing a settled file runs on the blocking pool,
//! identification on the worker thread (`worker`), the serial port on its
//! own thread (`serial`). Only SIGHUP's reload builds the library on the
//! loop (prepared references come from the cache), as nothing else can
//! usefully happen meanwhile.
//!
//! Modules: `watch` (notify watcher, rescans, polling fallback), `settle`
//! (when a file is complete), `intake` (which files become jobs), `glob`
//! (`watch.ignore`), `worker`, `serial`.

mod db;
mod glob;
mod health;
mod intake;
mod serial;
mod settle;
mod watch;
mod worker;

pub use health::BACKOFF_MAX as STORAGE_RETRY_MAX;
pub use serial::BACKOFF_MAX;

use crate::classify::{
    CalibrationProbe, CalibrationState, Classifier, Fitted, PendingCalibration, ResultFiles,
};
use crate::config::Config;
use crate::identify::CalibrationShare;
use crate::store::{now_ms, utc_day_start_ms, Enqueued, Store, StoreError};
use db::{Db, SharedDb};
use health::{Backoff, Health};
use morphoid_data::library::BuildOutcome;
use morphoid_data::present::error_chain;
use regex::Regex;
use sd_notify::NotifyState;
use serial::SerialTrigger;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::signal::unix::{signal, Signal, SignalKind};
use tokio::sync::mpsc::{self, UnboundedReceiver, UnboundedSender};
use tokio::time::{interval, interval_at, sleep, Instant, Interval, MissedTickBehavior};
use watch::FolderWatch;
use worker::{Setup, Worker};

/// A job running longer than this is taken as hung: watchdog pings stop,
/// so systemd restarts the daemon (and [`MAX_ATTEMPTS`] ends the loop).
const JOB_HANG_LIMIT: Duration = Duration::from_secs(30 * 60);
/// How long a stop waits for the current job before abandoning it, unless
/// `$MORPHOID_STOP_GRACE` (seconds, at most 60) says otherwise. systemd's
/// `TimeoutStopSec=` must be longer.
const STOP_GRACE: Duration = Duration::from_secs(7);
/// How often the STATUS line is recomputed (sent only when it changes).
const STATUS_INTERVAL: Duration = Duration::from_secs(2);
/// How often the database's write-ahead log is checkpointed and cut to
/// nothing, beside SQLite's own checkpoints after commits.
const CHECKPOINT_INTERVAL: Duration = Duration::from_secs(30);

/// The stop grace period: `$MORPHOID_STOP_GRACE` or [`STOP_GRACE`].
fn stop_grace() -> Duration {
    std::env::var("MORPHOID_STOP_GRACE")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s >= 0.0)
        .map(|s| Duration::from_secs_f64(s.min(60.0)))
        .unwrap_or(STOP_GRACE)
}

/// Any error a [`Loader`] reports, with its chain of causes.
type BoxError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Why a [`Loader`] could not load the configuration or the library.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The configuration could not be read.
    #[error("cannot load the configuration")]
    Config(#[source] BoxError),
    /// The reference library could not be opened or prepared.
    #[error("cannot load the library {}", dir.display())]
    Library {
        /// The configured library folder.
        dir: PathBuf,
        /// Why.
        #[source]
        source: BoxError,
    },
}

/// Why the daemon could not start (or reload).
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    /// The configuration or the library could not be loaded.
    #[error(transparent)]
    Load(#[from] LoadError),
    /// The database failed.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// `serial.trigger` is not a valid regex.
    #[error("serial.trigger: {0}")]
    Trigger(#[from] regex::Error),
    /// Signal handlers could not be installed.
    #[error("cannot install signal handlers: {0}")]
    Signals(#[source] std::io::Error),
    /// The web console could not start (`[http]`).
    #[error(transparent)]
    Http(#[from] crate::http::HttpError),
    /// The async runtime or a thread could not be started.
    #[error("cannot start the {what}: {source}")]
    Start {
        /// What could not be started.
        what: &'static str,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// A loaded library: the classifier, the report of its build, and its
/// calibration when that is still to be fitted (the daemon fits it on a
/// thread of its own, so identification starts at once).
pub struct LoadedLibrary {
    /// The classifier of the configured library.
    pub classifier: Classifier,
    /// What the build reports (failures, landmark problems).
    pub outcome: BuildOutcome,
    /// The calibration to fit in the background (`None`: none, or fitted).
    pub calibration: Option<PendingCalibration>,
}

/// What the daemon needs from its caller: the configuration (re-read on
/// SIGHUP) and the prepared library for a configuration.
pub trait Loader {
    /// The current configuration, with any command-line overrides.
    fn config(&self) -> Result<Config, LoadError>;
    /// The classifier of the configured library (cached references), the
    /// report of its build and its pending calibration
    /// ([`Classifier::build_deferred`]).
    fn library(&self, config: &Config) -> Result<LoadedLibrary, LoadError>;
}

/// Send a state change to the service manager, if there is one (the
/// crate does nothing without `$NOTIFY_SOCKET`). Failures are not fatal:
/// the daemon works without systemd.
fn notify(state: &[NotifyState]) {
    if let Err(e) = sd_notify::notify(state) {
        tracing::debug!("cannot notify the service manager: {e}");
    }
}

/// Run the daemon until SIGTERM/SIGINT. Returns an error only when it
/// cannot start; afterwards every problem is logged and survived.
pub fn run(loader: &dyn Loader) -> Result<(), DaemonError> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .thread_name("morphoid-control")
        .build()
        .map_err(|source| DaemonError::Start {
            what: "async runtime",
            source,
        })?;
    let result = runtime.block_on(control_loop(loader));
    // No blocking task should be left (hashes are awaited), but never let
    // one delay the exit.
    runtime.shutdown_timeout(Duration::from_secs(1));
    result
}

/// The signals the daemon acts on.
struct Signals {
    term: Signal,
    int: Signal,
    hup: Signal,
}

impl Signals {
    fn install() -> Result<Self, DaemonError> {
        let on = |kind| signal(kind).map_err(DaemonError::Signals);
        Ok(Signals {
            term: on(SignalKind::terminate())?,
            int: on(SignalKind::interrupt())?,
            hup: on(SignalKind::hangup())?,
        })
    }
}

/// The periodic wake-ups of the control loop.
struct Timers {
    /// Watchdog pings and the status line.
    house: Interval,
    /// Settle checks of files seen changing.
    settle: Interval,
    /// The full listing of the folder, in case events were lost.
    rescan: Interval,
}

impl Timers {
    fn start(watchdog: Option<Duration>) -> Self {
        let house_period = watchdog.map_or(Duration::from_millis(500), |w| {
            w.clamp(Duration::from_millis(10), Duration::from_millis(500))
        });
        let mut timers = Timers {
            house: interval(house_period),
            settle: interval(watch::POLL_INTERVAL),
            rescan: interval_at(
                Instant::now() + watch::RESCAN_INTERVAL,
                watch::RESCAN_INTERVAL,
            ),
        };
        for t in [&mut timers.house, &mut timers.settle, &mut timers.rescan] {
            t.set_missed_tick_behavior(MissedTickBehavior::Delay);
        }
        timers
    }
}

async fn control_loop(loader: &dyn Loader) -> Result<(), DaemonError> {
    // Installed first, so a signal during the library load is not lost.
    let mut signals = Signals::install()?;
    let mut daemon = Daemon::start(loader).await?;
    notify(&[NotifyState::Ready]);
    let mut timers = Timers::start(daemon.watchdog);
    // The web console asks for a reload when it added a reference.
    let console_reload = daemon.live.reload_signal();
    loop {
        tokio::select! {
            // Signals first: a stop must not wait behind a busy folder.
            biased;
            _ = signals.term.recv() => break,
            _ = signals.int.recv() => break,
            _ = signals.hup.recv() => daemon.on_reload().await,
            _ = console_reload.notified() => daemon.on_reload().await,
            Some(line) = daemon.serial_rx.recv() => daemon.on_trigger(line).await,
            Some(event) = daemon.folder.event() => daemon.on_folder_event(event).await,
            _ = timers.settle.tick() => {
                let ready = daemon.folder.tick();
                daemon.queue(ready).await;
            }
            _ = timers.rescan.tick() => {
                let ready = daemon.folder.safety_rescan();
                daemon.queue(ready).await;
            }
            _ = timers.house.tick() => {
                daemon.on_housekeeping();
                daemon.retry_intake().await;
                daemon.after_database_change().await;
            }
        }
    }
    daemon.stop().await;
    Ok(())
}

/// The running daemon: what the control loop's handlers share.
struct Daemon<'a> {
    loader: &'a dyn Loader,
    config: Config,
    /// The database connection, shared with the worker.
    db: SharedDb,
    /// What is wrong with the storage, if anything.
    health: Health,
    /// Settled files that could not be queued (the database failed):
    /// queued as soon as it works again, never dropped.
    unqueued: Vec<PathBuf>,
    /// Settled files whose format says they are not complete yet, since
    /// when (they wait up to `watch.incomplete_seconds`).
    incomplete: std::collections::HashMap<PathBuf, Instant>,
    intake_backoff: Backoff,
    worker: Worker,
    folder: FolderWatch,
    serial: Option<SerialTrigger>,
    serial_tx: UnboundedSender<String>,
    serial_rx: UnboundedReceiver<String>,
    references: usize,
    /// Where the current library's calibration stands (status line).
    calibration: CalibrationProbe,
    /// What the library's successive calibrations share (a reload stops
    /// the one before and goes on from its distances).
    calibrations: CalibrationShare,
    /// Half of systemd's watchdog period, when it has one.
    watchdog: Option<Duration>,
    last_ping: Instant,
    hang_logged: bool,
    last_status: String,
    last_status_at: Option<Instant>,
    last_checkpoint: Instant,
    /// What the web console shows of the daemon.
    live: crate::http::LiveStatus,
    /// The web console, when `[http] listen` is set.
    http: Option<crate::http::Server>,
}

impl<'a> Daemon<'a> {
    /// Load the configuration and the library, recover the queue, start
    /// the worker, the serial trigger and the folder watch, and queue the
    /// files that arrived while the daemon was down.
    async fn start(loader: &'a dyn Loader) -> Result<Daemon<'a>, DaemonError> {
        let config = loader.config()?;
        let trigger = compile_trigger(&config)?;
        let health = Health::default();
        let mut db = Db::open(&config.database.path, health.clone())?;
        // Before the library: the console answers while it is prepared.
        let live = crate::http::LiveStatus::new();
        let http = crate::http::Server::start_configured(
            &config.http,
            crate::http::Sources::of(&config, live.clone()),
        )?;
        let calibrations = CalibrationShare::default();
        let (classifier, files) = {
            let (store, _) = db.store()?;
            let requeued = store.requeue_running()?;
            if requeued > 0 {
                tracing::info!(
                    "{requeued} scan(s) left running by an earlier run are pending again"
                );
            }
            load_library(loader, &config, store, &calibrations)?
        };
        db.set_result_files(files.is_some());
        live.set_classifier(&classifier);
        let references = classifier.references().len();
        let calibration = classifier.calibration_probe();
        tracing::info!(
            "library {} loaded: {references} references; watching {}",
            config.library.dir.display(),
            config.watch.dir.display()
        );
        let db = Arc::new(Mutex::new(db));
        let setup = Setup {
            classifier,
            files,
            quarantine: config.watch.quarantine.clone(),
        };
        let worker = Worker::spawn(Arc::clone(&db), setup, health.clone()).map_err(|source| {
            DaemonError::Start {
                what: "worker thread",
                source,
            }
        })?;
        let (serial_tx, serial_rx) = mpsc::unbounded_channel::<String>();
        let serial = start_serial(&config, trigger.as_ref(), &serial_tx);
        let folder = FolderWatch::start(&config.watch);
        let mut daemon = Daemon {
            loader,
            config,
            db,
            health,
            unqueued: Vec::new(),
            incomplete: std::collections::HashMap::new(),
            intake_backoff: Backoff::default(),
            worker,
            folder,
            serial,
            serial_tx,
            serial_rx,
            references,
            calibration,
            calibrations,
            watchdog: sd_notify::watchdog_enabled().map(|d| d / 2),
            last_ping: Instant::now(),
            hang_logged: false,
            last_status: String::new(),
            last_status_at: None,
            last_checkpoint: Instant::now(),
            live,
            http,
        };
        // Files that arrived while the daemon was down.
        let ready = daemon.folder.rescan(false);
        daemon.queue(ready).await;
        daemon.worker.wake();
        Ok(daemon)
    }

    /// Hash and queue settled files (hashing on the blocking pool: a large
    /// file takes a while to read); wakes the worker when something is new.
    async fn queue(&mut self, ready: Vec<PathBuf>) {
        let mut new = false;
        let mut failed = false;
        for path in ready {
            let Some(hashed) = self.hashed(&path).await else {
                continue;
            };
            let queued = match hashed {
                Err(e) => (Err(e), false),
                Ok((hash, size, error)) => {
                    self.enqueue_hashed(&path, &hash, size, error.as_deref())
                }
            };
            match queued {
                (Ok(Enqueued::New(_) | Enqueued::Duplicate { .. }), _) => new = true,
                (Ok(Enqueued::Existing(..)), _) => {}
                (Err(_), true) => {
                    // Kept, not dropped: queued when the database works
                    // again (the fault is logged once, by the health).
                    if !self.unqueued.contains(&path) {
                        self.unqueued.push(path);
                    }
                    failed = true;
                }
                (Err(e @ intake::IntakeError::Read { .. }), false) => {
                    // Gone or unreadable: the next listing sees it again.
                    tracing::warn!("{e}");
                    self.folder.release(&path);
                }
                (Err(e), false) => tracing::error!("{e}"),
            }
        }
        if failed {
            self.intake_backoff.failed();
        }
        if new {
            self.worker.wake();
        }
    }

    /// The settled file `path`'s content hash and size, and the error to
    /// record for it (a file that stayed incomplete too long), or why it
    /// cannot be read; `None` when it is not to be queued now (deferred
    /// while incomplete, or released after the hashing task failed).
    async fn hashed(&mut self, path: &Path) -> Option<Result<Hashed, intake::IntakeError>> {
        let p = path.to_path_buf();
        let taken = match tokio::task::spawn_blocking(move || intake::take(&p)).await {
            Ok(h) => h,
            Err(e) => {
                tracing::error!("{}: hashing failed: {e}", path.display());
                self.folder.release(path);
                return None;
            }
        };
        match taken {
            Err(e) => Some(Err(e)),
            Ok(intake::Taken::Ready(hash, size)) => {
                if self.incomplete.remove(path).is_some() {
                    tracing::info!("{}: complete now", path.display());
                }
                Some(Ok((hash, size, None)))
            }
            Ok(intake::Taken::Incomplete(problem)) => self.hashed_incomplete(path, &problem).await,
        }
    }

    /// [`Daemon::hashed`] for a file whose format says it is incomplete
    /// (`problem`): deferred (`None`) until it has waited
    /// `watch.incomplete_seconds`, then hashed as it is, with the error
    /// to record.
    async fn hashed_incomplete(
        &mut self,
        path: &Path,
        problem: &str,
    ) -> Option<Result<Hashed, intake::IntakeError>> {
        let since = *self
            .incomplete
            .entry(path.to_path_buf())
            .or_insert_with(|| {
                tracing::info!(
                    "{}: not complete yet ({problem}); waiting for the rest",
                    path.display()
                );
                Instant::now()
            });
        let limit = Duration::from_secs_f64(self.config.watch.incomplete_seconds);
        if since.elapsed() < limit {
            self.folder.defer(path);
            return None;
        }
        self.incomplete.remove(path);
        let message = format!(
            "{}: incomplete after waiting {:.0} s: {problem}",
            path.display(),
            limit.as_secs_f64()
        );
        let p = path.to_path_buf();
        match tokio::task::spawn_blocking(move || intake::hash(&p)).await {
            Ok(Ok((hash, size))) => Some(Ok((hash, size, Some(message)))),
            Ok(Err(e)) => Some(Err(e)),
            Err(_) => {
                self.folder.release(path);
                None
            }
        }
    }

    /// Queue the hashed file `path` in the store (failed at once with
    /// `error` when it has one and is new), and tell the storage's health
    /// how the database did. Returns what the store did, and whether a
    /// failure is the storage's (the file is to be queued again later).
    fn enqueue_hashed(
        &self,
        path: &Path,
        hash: &str,
        size: u64,
        error: Option<&str>,
    ) -> (Result<Enqueued, intake::IntakeError>, bool) {
        let mut db = db::lock(&self.db);
        let out = match db.store() {
            Ok((store, _)) => enqueue_failing(store, path, hash, size, error),
            Err(source) => Err(intake::IntakeError::Queue {
                path: path.to_path_buf(),
                source,
            }),
        };
        let storage = match &out {
            Err(intake::IntakeError::Queue { source, .. }) => db.failed(source),
            Ok(_) => {
                db.worked();
                false
            }
            Err(_) => false,
        };
        (out, storage)
    }

    /// Queue again the files the database refused, when their wait is up.
    async fn retry_intake(&mut self) {
        if self.unqueued.is_empty() || !self.intake_backoff.ready() {
            return;
        }
        let paths = std::mem::take(&mut self.unqueued);
        let n = paths.len();
        self.queue(paths).await;
        if self.unqueued.is_empty() {
            self.intake_backoff.succeeded();
            tracing::info!("{n} file(s) held while the database failed are queued");
        }
    }

    /// SIGHUP: re-read the configuration, load its library and hand it to
    /// the worker; restart what the new configuration changes. On failure
    /// the previous setup stays.
    async fn on_reload(&mut self) {
        tracing::info!("reloading the configuration and the library");
        notify(&[NotifyState::Reloading]);
        let db = Arc::clone(&self.db);
        let reloaded = with_watchdog_pings(self.watchdog, || {
            let mut db = db::lock(&db);
            let out = match db.store() {
                Ok((store, _)) => reload(self.loader, store, &self.calibrations),
                Err(e) => Err(e.into()),
            };
            if let Ok((_, _, files, _)) = &out {
                db.set_result_files(files.is_some());
            }
            out
        });
        match reloaded {
            Ok((config, classifier, files, trigger)) => {
                self.live.set_classifier(&classifier);
                self.references = classifier.references().len();
                self.calibration = classifier.calibration_probe();
                self.worker.reload(Setup {
                    classifier,
                    files,
                    quarantine: config.watch.quarantine.clone(),
                });
                if config.serial != self.config.serial {
                    // Dropping the old trigger stops its thread.
                    drop(self.serial.take());
                    self.serial = start_serial(&config, trigger.as_ref(), &self.serial_tx);
                }
                if config.database.path != self.config.database.path {
                    tracing::warn!("database.path changes only at restart");
                }
                if config.http != self.config.http {
                    tracing::warn!("[http] changes only at restart");
                }
                if config.watch != self.config.watch {
                    self.folder = FolderWatch::start(&config.watch);
                }
                self.config = config;
                tracing::info!("reloaded: {} references", self.references);
                let ready = self.folder.rescan(false);
                self.queue(ready).await;
            }
            Err(e) => tracing::error!(
                "reload failed, keeping the previous setup: {}",
                error_chain(&e)
            ),
        }
        notify(&[NotifyState::Ready]);
        self.last_status_at = None;
    }

    /// The database file became another one: every file of the export
    /// folder is looked at again, as at start, so that the scans the new
    /// file lacks are identified into it (those it has are not repeated).
    async fn after_database_change(&mut self) {
        let changed = match self.db.try_lock() {
            Ok(mut db) => db.take_new_file(),
            // The worker is using the connection: look at the next tick.
            Err(_) => false,
        };
        if changed {
            self.folder = FolderWatch::start(&self.config.watch);
            let ready = self.folder.rescan(false);
            self.queue(ready).await;
        }
    }

    /// A serial trigger line: the scanner has finished writing. A file the
    /// line names is taken first, then everything settled in the folder.
    async fn on_trigger(&mut self, line: String) {
        let mut lines = vec![line];
        while let Ok(more) = self.serial_rx.try_recv() {
            lines.push(more);
        }
        let mut ready = Vec::new();
        for line in &lines {
            if let Some(file) = intake::named_file(line, self.folder.dir()) {
                if self.folder.force_file(&file) {
                    ready.push(file);
                }
            }
        }
        self.queue(ready).await;
        let ready = self.folder.rescan(true);
        self.queue(ready).await;
    }

    /// A batch of watcher events.
    async fn on_folder_event(&mut self, event: notify::Result<notify::Event>) {
        let out = self.folder.handle(event);
        let mut ready = out.ready;
        if out.rescan {
            ready.extend(self.folder.rescan(false));
        }
        self.queue(ready).await;
    }

    /// The watchdog ping (withheld while a job looks hung) and the STATUS
    /// line (sent when it changes).
    fn on_housekeeping(&mut self) {
        if let Some(every) = self.watchdog {
            let hung = self
                .worker
                .progress()
                .running_for()
                .is_some_and(|d| d > JOB_HANG_LIMIT);
            if hung && !self.hang_logged {
                tracing::error!(
                    "the current job looks hung; letting the watchdog restart the daemon"
                );
                self.hang_logged = true;
            }
            if !hung && self.last_ping.elapsed() >= every {
                notify(&[NotifyState::Watchdog]);
                self.last_ping = Instant::now();
            }
        }
        if self.last_checkpoint.elapsed() >= CHECKPOINT_INTERVAL {
            // Not while the worker uses the connection: next tick then.
            if let Ok(mut db) = self.db.try_lock() {
                db.checkpoint();
                self.last_checkpoint = Instant::now();
            }
        }
        if self
            .last_status_at
            .is_none_or(|t| t.elapsed() >= STATUS_INTERVAL)
        {
            let mut status = match self.db.try_lock() {
                Ok(mut db) => match db.store() {
                    Ok((store, _)) => {
                        status_line(store, self.references, self.worker.progress().current())
                    }
                    Err(_) => self.last_status.clone(),
                },
                // The worker is using the connection: keep the last line.
                Err(_) => self.last_status.clone(),
            };
            if let Some(p) = status.find("; ") {
                status.truncate(p);
            }
            if let Some(calibration) = calibration_status(self.calibration.state()) {
                status = format!("{status}; {calibration}");
            }
            if let Some(degraded) = self.health.summary() {
                status = format!("{status}; {degraded}");
            }
            if status != self.last_status {
                notify(&[NotifyState::Status(&status)]);
                self.last_status = status;
            }
            self.publish_status();
            self.last_status_at = Some(Instant::now());
        }
    }

    /// What the web console shows of the daemon: the status line's parts.
    fn publish_status(&self) {
        let config = &self.config;
        self.live.update(|s| {
            s.running = true;
            s.current_scan = self.worker.progress().current();
            s.references = self.references;
            s.calibration = crate::http::calibration_name(self.calibration.state()).into();
            s.degraded = self.health.summary();
            s.serial = config.serial.as_ref().map(|c| crate::http::SerialStatus {
                port: c.port.clone(),
                baud: c.baud,
                trigger: c.trigger.clone(),
            });
            s.status_line = self.last_status.clone();
            s.watching = config.watch.dir.display().to_string();
            s.library = config.library.dir.display().to_string();
            s.updated_at_ms = now_ms();
        });
    }

    /// Stop: the worker finishes its job within the grace period, or the
    /// job goes back to the queue.
    async fn stop(mut self) {
        tracing::info!("stopping");
        notify(&[NotifyState::Stopping]);
        self.live.update(|s| s.running = false);
        // Joins the console's thread: its requests have a short grace.
        drop(self.http.take());
        self.worker.request_stop();
        drop(self.serial.take());
        let deadline = Instant::now() + stop_grace();
        while !self.worker.is_finished() && Instant::now() < deadline {
            sleep(Duration::from_millis(50)).await;
        }
        if !self.worker.is_finished() {
            // The lock first, then the marker: the worker marks a claim
            // current before it lets go of the lock.
            let mut db = db::lock(&self.db);
            if let Some(id) = self.worker.progress().current() {
                let abandoned = db.store().and_then(|(store, _)| store.abandon(id));
                match abandoned {
                    Ok(()) => {
                        tracing::info!("scan {id} abandoned; it is pending for the next start")
                    }
                    Err(e) => tracing::warn!("scan {id} could not be abandoned: {e}"),
                }
            }
        }
    }
}

/// A settled file's content hash and size, and the error to record for
/// it (a file that stayed incomplete too long).
type Hashed = (String, u64, Option<String>);

/// Queue the hashed file `path` in `store`; when it is new and has an
/// `error` to record, log it and fail the scan at once (reported as an
/// existing scan in error: nothing for the worker).
fn enqueue_failing(
    store: &mut Store,
    path: &Path,
    hash: &str,
    size: u64,
    error: Option<&str>,
) -> Result<Enqueued, intake::IntakeError> {
    let q = intake::enqueue(store, path, hash, size)?;
    match (&q, error) {
        (Enqueued::New(id), Some(message)) => {
            tracing::error!("{message}");
            store
                .fail(*id, message)
                .map_err(|source| intake::IntakeError::Queue {
                    path: path.to_path_buf(),
                    source,
                })?;
            Ok(Enqueued::Existing(*id, crate::store::ScanStatus::Error))
        }
        _ => Ok(q),
    }
}

/// The classifier of `config`'s library with its references recorded in
/// the store, and the result files it configures; its calibration, if
/// still to be fitted, is started in the background. The build report is
/// logged and dropped here: the daemon keeps only the classifier.
fn load_library(
    loader: &dyn Loader,
    config: &Config,
    store: &mut Store,
    calibrations: &CalibrationShare,
) -> Result<(Classifier, Option<ResultFiles>), DaemonError> {
    let LoadedLibrary {
        classifier,
        outcome,
        calibration,
    } = loader.library(config)?;
    classifier.register(store, &outcome)?;
    if let Some(pending) = calibration {
        calibrate_in_background(pending, calibrations);
    }
    let results = config
        .results
        .dir
        .clone()
        .map(|dir| ResultFiles::new(dir, Some(config.watch.dir.clone())));
    Ok((classifier, results))
}

/// Threads of the calibration's own rayon pool: half the machine, so that
/// identification (on the global pool) keeps most of it meanwhile.
fn calibration_threads() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get() / 2)
        .unwrap_or(1)
        .max(1)
}

/// Fit `pending` on a thread of its own (with its own, smaller rayon pool),
/// logging its start and its end with the time it took. A failure is one
/// error line: the daemon goes on without confidence.
fn calibrate_in_background(pending: PendingCalibration, share: &CalibrationShare) {
    let n = pending.references();
    let pending = pending.in_turn(share.next_turn());
    let spawned = std::thread::Builder::new()
        .name("morphoid-calibration".into())
        .spawn(move || {
            // Below identification: a scan that arrives meanwhile is
            // identified in seconds, the calibration waits.
            let niceness = crate::priority::background_niceness();
            crate::priority::set_thread_niceness(niceness, "calibration");
            let threads = calibration_threads();
            tracing::info!(
                "calibration started: {n} references compared with each other \
                 ({threads} thread(s)); scans are identified meanwhile, without confidence"
            );
            let started = std::time::Instant::now();
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .thread_name(|i| format!("morphoid-calibration-{i}"))
                .start_handler(move |_| {
                    crate::priority::set_thread_niceness(niceness, "calibration")
                })
                .build();
            let fitted = match pool {
                Ok(pool) => pool.install(|| pending.run()),
                // Its own pool only keeps it from crowding identification.
                Err(e) => {
                    tracing::warn!("calibration on the shared thread pool: {e}");
                    pending.run()
                }
            };
            let secs = started.elapsed().as_secs_f64();
            match fitted {
                Ok(Fitted::Ranks(summary)) => tracing::info!(
                    "calibration done in {secs:.1} s ({summary}): scans identified from now on \
                     carry their confidence"
                ),
                Ok(Fitted::Superseded) => tracing::info!(
                    "calibration of {n} references stopped after {secs:.1} s: a newer library's \
                     calibration goes on from its distances"
                ),
                Err(e) => tracing::error!(
                    "{} after {secs:.1} s; going on without confidence",
                    error_chain(&e)
                ),
            }
        });
    if let Err(e) = spawned {
        // The pending calibration was dropped with the closure: failed.
        tracing::error!("cannot start the calibration thread: {e}; going on without confidence");
    }
}

/// What the status line says of the calibration (`None`: nothing).
fn calibration_status(state: CalibrationState) -> Option<&'static str> {
    match state {
        CalibrationState::Calibrating => Some("calibrating the confidence"),
        CalibrationState::Failed => Some("no confidence (the calibration failed)"),
        CalibrationState::Off | CalibrationState::Ready => None,
    }
}

/// What a reload gives: the configuration, its classifier, result files
/// and serial trigger.
type Reloaded = (Config, Classifier, Option<ResultFiles>, Option<Regex>);

/// Re-read the configuration and load its library (SIGHUP).
fn reload(
    loader: &dyn Loader,
    store: &mut Store,
    calibrations: &CalibrationShare,
) -> Result<Reloaded, DaemonError> {
    let config = loader.config()?;
    let trigger = compile_trigger(&config)?;
    let (classifier, files) = load_library(loader, &config, store, calibrations)?;
    Ok((config, classifier, files, trigger))
}

/// Run `work`, pinging the watchdog from a helper thread meanwhile: a
/// reload blocks the control loop, and preparing references that are not
/// in the cache yet (new ones, or changed parameters) can take longer
/// than `WatchdogSec=`; a reload is slow, not hung.
fn with_watchdog_pings<T>(watchdog: Option<Duration>, work: impl FnOnce() -> T) -> T {
    let Some(every) = watchdog else {
        return work();
    };
    let done = std::sync::atomic::AtomicBool::new(false);
    std::thread::scope(|scope| {
        let pinger = std::thread::Builder::new()
            .name("morphoid-reload-ping".into())
            .spawn_scoped(scope, || {
                let mut last = std::time::Instant::now();
                while !done.load(std::sync::atomic::Ordering::SeqCst) {
                    std::thread::sleep(Duration::from_millis(50));
                    if last.elapsed() >= every {
                        notify(&[NotifyState::Watchdog]);
                        last = std::time::Instant::now();
                    }
                }
            });
        if let Err(e) = pinger {
            tracing::warn!("cannot start the watchdog thread for the reload: {e}");
        }
        let result = work();
        done.store(true, std::sync::atomic::Ordering::SeqCst);
        result
    })
}

fn start_serial(
    config: &Config,
    trigger: Option<&Regex>,
    tx: &UnboundedSender<String>,
) -> Option<SerialTrigger> {
    let (s, re) = (config.serial.as_ref()?, trigger?);
    match SerialTrigger::start(s.port.clone(), s.baud, re.clone(), tx.clone()) {
        Ok(t) => Some(t),
        Err(e) => {
            tracing::error!("cannot start the serial thread: {e}");
            None
        }
    }
}

fn compile_trigger(config: &Config) -> Result<Option<Regex>, DaemonError> {
    Ok(match &config.serial {
        Some(s) => Some(Regex::new(&s.trigger)?),
        None => None,
    })
}

/// "idle, 116 references, 42 scans today" (or "identifying …").
fn status_line(store: &Store, n_refs: usize, current: Option<i64>) -> String {
    let today = store
        .finished_since(utc_day_start_ms(now_ms()))
        .unwrap_or(0);
    let pending = store.counts().map(|c| c.pending).unwrap_or(0);
    let state = match current {
        Some(id) => format!("identifying scan {id}"),
        None => "idle".to_string(),
    };
    let queue = if pending > 0 {
        format!(", {pending} pending")
    } else {
        String::new()
    };
    format!("{state}, {n_refs} references, {today} scans today{queue}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_logged_error_shows_its_causes() {
        let inner = std::io::Error::other("permission denied");
        let e = LoadError::Library {
            dir: PathBuf::from("/lib"),
            source: Box::new(inner),
        };
        assert_eq!(
            error_chain(&e),
            "cannot load the library /lib: permission denied"
        );
    }
}
