//! The worker: a dedicated thread that owns the classifier (the library is
//! loaded once and replaced only on reload) and its own database
//! connection, claims pending jobs one at a time and runs them through
//! `classify::run_job`. The numerical work (itself parallel on rayon's
//! pool) thus never runs on the async control loop, which stays free for
//! signals, the watchdog and the folder.

use crate::classify::{self, Classifier, NEAREST};
use crate::store::{now_ms, ScanStatus, Store};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// A scan claimed this many times without finishing has crashed the
/// daemon each time (or hung it until the watchdog fired): it is failed
/// instead of being tried for ever.
pub const MAX_ATTEMPTS: u32 = 3;

/// Messages to the worker thread.
enum ToWorker {
    /// New jobs may be pending.
    Wake,
    /// Use this classifier and quarantine folder from the next job on.
    Reload(Box<Classifier>, Option<PathBuf>),
}

/// What the worker shares with the control loop: the scan it is
/// identifying (0: none) and since when (Unix ms), and the stop flag it
/// checks between jobs.
#[derive(Debug, Clone, Default)]
pub struct Progress {
    current: Arc<AtomicI64>,
    started_ms: Arc<AtomicI64>,
    stop: Arc<AtomicBool>,
}

impl Progress {
    /// The scan being identified, if any.
    pub fn current(&self) -> Option<i64> {
        let id = self.current.load(Ordering::SeqCst);
        (id > 0).then_some(id)
    }

    /// How long the current job has been running.
    pub fn running_for(&self) -> Option<Duration> {
        self.current()?;
        let started = self.started_ms.load(Ordering::SeqCst);
        (started > 0).then(|| Duration::from_millis((now_ms() - started).max(0) as u64))
    }
}

/// The handle the control loop keeps on the worker thread.
pub struct Worker {
    tx: Option<Sender<ToWorker>>,
    thread: JoinHandle<()>,
    progress: Progress,
}

impl Worker {
    /// Start the worker on its own connection to the database.
    pub fn spawn(
        store: Store,
        classifier: Classifier,
        quarantine: Option<PathBuf>,
    ) -> std::io::Result<Self> {
        let (tx, rx) = mpsc::channel();
        let progress = Progress::default();
        let shared = progress.clone();
        let thread = std::thread::Builder::new()
            .name("morphoid-worker".into())
            .spawn(move || worker_loop(store, classifier, quarantine, rx, shared))?;
        Ok(Worker {
            tx: Some(tx),
            thread,
            progress,
        })
    }

    /// Tell the worker that jobs may be pending.
    pub fn wake(&self) {
        if let Some(tx) = &self.tx {
            let _ = tx.send(ToWorker::Wake);
        }
    }

    /// Hand the worker a new classifier and quarantine folder (SIGHUP);
    /// the job in progress finishes with the old one.
    pub fn reload(&self, classifier: Classifier, quarantine: Option<PathBuf>) {
        if let Some(tx) = &self.tx {
            let _ = tx.send(ToWorker::Reload(Box::new(classifier), quarantine));
        }
    }

    /// What the worker is doing.
    pub fn progress(&self) -> &Progress {
        &self.progress
    }

    /// Ask the worker to stop after the current job (no new job is taken).
    pub fn request_stop(&mut self) {
        self.progress.stop.store(true, Ordering::SeqCst);
        // Dropping the sender wakes a worker waiting for work.
        self.tx = None;
    }

    /// Whether the worker thread has ended.
    pub fn is_finished(&self) -> bool {
        self.thread.is_finished()
    }
}

/// The worker: claim pending jobs one at a time and identify them.
fn worker_loop(
    mut store: Store,
    mut classifier: Classifier,
    mut quarantine: Option<PathBuf>,
    rx: Receiver<ToWorker>,
    progress: Progress,
) {
    let stop = progress.stop.clone();
    loop {
        // A periodic wake-up also catches jobs queued by another process
        // (`morphoid retry`, for instance).
        match rx.recv_timeout(Duration::from_secs(5)) {
            Ok(ToWorker::Reload(c, q)) => {
                classifier = *c;
                quarantine = q;
            }
            Ok(ToWorker::Wake) | Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => return,
        }
        while !stop.load(Ordering::SeqCst) {
            while let Ok(msg) = rx.try_recv() {
                if let ToWorker::Reload(c, q) = msg {
                    classifier = *c;
                    quarantine = q;
                }
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
/// its reference and distance, time taken.
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
    // A rename fails across filesystems: copy and remove then.
    let moved = std::fs::rename(file, &target)
        .or_else(|_| std::fs::copy(file, &target).and_then(|_| std::fs::remove_file(file)));
    match moved {
        Ok(()) => tracing::info!("{} moved to {}", file.display(), target.display()),
        Err(e) => tracing::warn!("{}: cannot quarantine: {e}", file.display()),
    }
}
