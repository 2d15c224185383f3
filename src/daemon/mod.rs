//! The daemon behind `morphoid run`: watches the export folder, queues each
//! complete surface file as a job in the store, identifies jobs one at a
//! time on a worker thread with the library loaded once, and reacts to the
//! serial trigger, SIGTERM/SIGINT (stop), SIGHUP (reload) and the systemd
//! watchdog.
//!
//! The control loop runs on a current-thread tokio runtime: one `select!`
//! over the signals, the folder watcher's events, serial trigger lines and
//! a few timers (settle checks, the safety rescan, watchdog and status).
//! Everything slow is elsewhere: hashing a settled file runs on the
//! blocking pool, identification on the worker thread ([`worker`]), the
//! serial port on its own thread ([`serial`]). Only SIGHUP's reload builds
//! the library on the loop (prepared references come from the cache), as
//! nothing else can usefully happen meanwhile.
//!
//! Modules: [`watch`] (notify watcher, rescans, polling fallback),
//! [`settle`] (when a file is complete), [`intake`] (which files become
//! jobs), [`glob`] (`watch.ignore`), [`worker`], [`serial`].

pub mod glob;
pub mod intake;
pub mod serial;
pub mod settle;
pub mod watch;
pub mod worker;

use crate::classify::Classifier;
use crate::config::Config;
use crate::library::BuildOutcome;
use crate::store::{now_ms, utc_day_start_ms, Store, StoreError};
use regex::Regex;
use sd_notify::NotifyState;
use serial::SerialTrigger;
use std::path::PathBuf;
use std::time::Duration;
use tokio::signal::unix::{signal, SignalKind};
use tokio::sync::mpsc::{self, UnboundedSender};
use tokio::time::{interval, interval_at, sleep, Instant, MissedTickBehavior};
use watch::FolderWatch;
use worker::Worker;

pub use worker::MAX_ATTEMPTS;

/// A job running longer than this is taken as hung: watchdog pings stop,
/// so systemd restarts the daemon (and [`MAX_ATTEMPTS`] ends the loop).
pub const JOB_HANG_LIMIT: Duration = Duration::from_secs(30 * 60);
/// How long a stop waits for the current job before abandoning it, unless
/// `$MORPHOID_STOP_GRACE` (seconds, at most 60) says otherwise. systemd's
/// `TimeoutStopSec=` must be longer.
pub const STOP_GRACE: Duration = Duration::from_secs(7);
/// How often the STATUS line is recomputed (sent only when it changes).
const STATUS_INTERVAL: Duration = Duration::from_secs(2);

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
    /// `serial.trigger` is not a valid regex.
    #[error("serial.trigger: {0}")]
    Trigger(#[from] regex::Error),
    /// Signal handlers could not be installed.
    #[error("cannot install signal handlers: {0}")]
    Signals(std::io::Error),
    /// The async runtime or a thread could not be started.
    #[error("cannot start the {what}: {source}")]
    Start {
        /// What could not be started.
        what: &'static str,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// What the daemon needs from its caller: the configuration (re-read on
/// SIGHUP) and the prepared library for a configuration.
pub trait Loader {
    /// The current configuration, with any command-line overrides.
    fn config(&self) -> Result<Config, String>;
    /// The classifier of the configured library (cached references).
    fn library(&self, config: &Config) -> Result<(Classifier, BuildOutcome), String>;
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

/// Hash and queue settled files (hashing on the blocking pool: a large
/// file takes a while to read); wakes the worker when something is new.
async fn take(store: &mut Store, folder: &mut FolderWatch, ready: Vec<PathBuf>, worker: &Worker) {
    let mut new = false;
    for path in ready {
        let p = path.clone();
        let hashed = match tokio::task::spawn_blocking(move || intake::hash(&p)).await {
            Ok(h) => h,
            Err(e) => {
                tracing::error!("{}: hashing failed: {e}", path.display());
                folder.release(&path);
                continue;
            }
        };
        let queued = hashed.and_then(|(hash, size)| intake::enqueue(store, &path, &hash, size));
        match queued {
            Ok(Some(_)) => new = true,
            Ok(None) => {}
            Err(e) => {
                tracing::warn!("{e}");
                folder.release(&path);
            }
        }
    }
    if new {
        worker.wake();
    }
}

/// [`reload`], with watchdog pings from a helper thread meanwhile: the
/// reload blocks the control loop, and preparing references that are not
/// in the cache yet (new ones, or changed parameters) can take longer
/// than `WatchdogSec=`; a reload is slow, not hung.
fn reload_pinging(
    loader: &dyn Loader,
    store: &mut Store,
    watchdog: Option<Duration>,
) -> Result<(Config, Classifier, Option<Regex>), String> {
    let Some(every) = watchdog else {
        return reload(loader, store);
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
        let result = reload(loader, store);
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

async fn control_loop(loader: &dyn Loader) -> Result<(), DaemonError> {
    // Installed first, so a signal during the library load is not lost.
    let mut sigterm = signal(SignalKind::terminate()).map_err(DaemonError::Signals)?;
    let mut sigint = signal(SignalKind::interrupt()).map_err(DaemonError::Signals)?;
    let mut sighup = signal(SignalKind::hangup()).map_err(DaemonError::Signals)?;

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
    let mut n_refs = classifier.references.len();
    tracing::info!(
        "library {} loaded: {n_refs} references; watching {}",
        config.library.dir.display(),
        config.watch.dir.display()
    );
    let worker_store = Store::open(&db)?;
    let mut worker = Worker::spawn(worker_store, classifier, config.watch.quarantine.clone())
        .map_err(|source| DaemonError::Start {
            what: "worker thread",
            source,
        })?;

    let (serial_tx, mut serial_rx) = mpsc::unbounded_channel::<String>();
    let mut serial = start_serial(&config, trigger.as_ref(), &serial_tx);

    let mut folder = FolderWatch::start(&config.watch);
    // Files that arrived while the daemon was down.
    let ready = folder.rescan(false);
    take(&mut store, &mut folder, ready, &worker).await;
    worker.wake();

    notify(&[NotifyState::Ready]);
    let watchdog = sd_notify::watchdog_enabled().map(|d| d / 2);
    let house_period = watchdog.map_or(Duration::from_millis(500), |w| {
        w.clamp(Duration::from_millis(10), Duration::from_millis(500))
    });
    let mut house = interval(house_period);
    let mut settle_tick = interval(watch::POLL_INTERVAL);
    let start = Instant::now();
    let mut rescan_tick = interval_at(start + watch::RESCAN_INTERVAL, watch::RESCAN_INTERVAL);
    for t in [&mut house, &mut settle_tick, &mut rescan_tick] {
        t.set_missed_tick_behavior(MissedTickBehavior::Delay);
    }
    let mut last_ping = start;
    let mut last_status = String::new();
    let mut last_status_at: Option<Instant> = None;
    let mut hang_logged = false;

    loop {
        tokio::select! {
            // Signals first: a stop must not wait behind a busy folder.
            biased;
            _ = sigterm.recv() => break,
            _ = sigint.recv() => break,
            _ = sighup.recv() => {
                tracing::info!("reloading the configuration and the library");
                notify(&[NotifyState::Reloading]);
                match reload_pinging(loader, &mut store, watchdog) {
                    Ok((c, classifier, t)) => {
                        n_refs = classifier.references.len();
                        worker.reload(classifier, c.watch.quarantine.clone());
                        if c.serial != config.serial {
                            // Dropping the old trigger stops its thread.
                            drop(serial.take());
                            serial = start_serial(&c, t.as_ref(), &serial_tx);
                        }
                        if c.database.path != config.database.path {
                            tracing::warn!("database.path changes only at restart");
                        }
                        if c.watch != config.watch {
                            folder = FolderWatch::start(&c.watch);
                        }
                        config = c;
                        tracing::info!("reloaded: {n_refs} references");
                        let ready = folder.rescan(false);
                        take(&mut store, &mut folder, ready, &worker).await;
                    }
                    Err(e) => tracing::error!("reload failed, keeping the previous setup: {e}"),
                }
                notify(&[NotifyState::Ready]);
                last_status_at = None;
            }
            Some(line) = serial_rx.recv() => {
                // A trigger says the scanner has finished writing: a file
                // the line names first, then everything in the folder.
                let mut lines = vec![line];
                while let Ok(more) = serial_rx.try_recv() {
                    lines.push(more);
                }
                let mut ready = Vec::new();
                for line in &lines {
                    if let Some(file) = intake::named_file(line, folder.dir()) {
                        if folder.force_file(&file) {
                            ready.push(file);
                        }
                    }
                }
                take(&mut store, &mut folder, ready, &worker).await;
                let ready = folder.rescan(true);
                take(&mut store, &mut folder, ready, &worker).await;
            }
            Some(event) = folder.event() => {
                let out = folder.handle(event);
                let mut ready = out.ready;
                if out.rescan {
                    ready.extend(folder.rescan(false));
                }
                take(&mut store, &mut folder, ready, &worker).await;
            }
            _ = settle_tick.tick() => {
                let ready = folder.tick();
                take(&mut store, &mut folder, ready, &worker).await;
            }
            _ = rescan_tick.tick() => {
                let ready = folder.safety_rescan();
                take(&mut store, &mut folder, ready, &worker).await;
            }
            _ = house.tick() => {
                if let Some(every) = watchdog {
                    let hung = worker
                        .progress()
                        .running_for()
                        .is_some_and(|d| d > JOB_HANG_LIMIT);
                    if hung && !hang_logged {
                        tracing::error!(
                            "the current job looks hung; letting the watchdog restart the daemon"
                        );
                        hang_logged = true;
                    }
                    if !hung && last_ping.elapsed() >= every {
                        notify(&[NotifyState::Watchdog]);
                        last_ping = Instant::now();
                    }
                }
                if last_status_at.is_none_or(|t| t.elapsed() >= STATUS_INTERVAL) {
                    let status = status_line(&store, n_refs, worker.progress().current());
                    if status != last_status {
                        notify(&[NotifyState::Status(&status)]);
                        last_status = status;
                    }
                    last_status_at = Some(Instant::now());
                }
            }
        }
    }

    tracing::info!("stopping");
    notify(&[NotifyState::Stopping]);
    worker.request_stop();
    drop(serial);
    let deadline = Instant::now() + stop_grace();
    while !worker.is_finished() && Instant::now() < deadline {
        sleep(Duration::from_millis(50)).await;
    }
    if !worker.is_finished() {
        if let Some(id) = worker.progress().current() {
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
