//! The worker: a dedicated thread that owns the classifier (the library is
//! loaded once and replaced only on reload), claims pending jobs one at a
//! time through the daemon's database connection and identifies them. The
//! numerical work (itself parallel on rayon's pool) thus never runs on the
//! async control loop, which stays free for signals, the watchdog and the
//! folder.
//!
//! Storage faults never lose work: a job is identified only after its
//! claim committed; its finding is held in memory until the transaction
//! that records it (and moves the row from `running` to `ok` or `error`)
//! commits, retried with [`Backoff`] meanwhile. Result files are written
//! from the database's list of due ones, so a results folder that cannot
//! be written gets them once it can.

use super::db::{self, SharedDb};
use super::health::{Backoff, Health, Part};
use crate::classify::{self, Classifier, Finding, ResultFiles, NEAREST};
use crate::report::Scene;
use crate::store::{now_ms, Job, ScanStatus, Store, StoreError};
use morphoid_data::present::error_chain;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// A scan claimed this many times without finishing has crashed the
/// daemon each time (or hung it until the watchdog fired): it is failed
/// instead of being tried for ever.
pub(crate) const MAX_ATTEMPTS: u32 = 3;

/// How often the worker looks for work nobody told it about (jobs queued
/// by another process, `morphoid retry`).
const IDLE_WAKE: Duration = Duration::from_secs(5);

/// Result files written per pass, so jobs are not held up behind a backlog.
const FILES_PER_PASS: usize = 16;

/// Scenes of identified scans kept for their reports until the result
/// files are written (a report whose scene is gone draws it again from the
/// file).
const SCENES_KEPT: usize = 8;

/// What the worker works with; replaced as a whole on reload.
pub(super) struct Setup {
    /// The prepared library.
    pub classifier: Classifier,
    /// Where result files go, if anywhere.
    pub files: Option<ResultFiles>,
    /// Where unusable files are moved, if anywhere.
    pub quarantine: Option<PathBuf>,
}

/// Messages to the worker thread.
enum ToWorker {
    /// New jobs may be pending.
    Wake,
    /// Use this setup from the next job on.
    Reload(Box<Setup>),
}

/// What the worker shares with the control loop: the scan it is
/// identifying (0: none) and since when (Unix ms), and the stop flag it
/// checks between jobs.
#[derive(Debug, Clone, Default)]
pub(super) struct Progress {
    current: Arc<AtomicI64>,
    started_ms: Arc<AtomicI64>,
    stop: Arc<AtomicBool>,
}

impl Progress {
    /// The scan being identified, if any.
    pub(super) fn current(&self) -> Option<i64> {
        let id = self.current.load(Ordering::SeqCst);
        (id > 0).then_some(id)
    }

    /// How long the current job has been running.
    pub(super) fn running_for(&self) -> Option<Duration> {
        self.current()?;
        let started = self.started_ms.load(Ordering::SeqCst);
        (started > 0).then(|| Duration::from_millis((now_ms() - started).max(0) as u64))
    }
}

/// The handle the control loop keeps on the worker thread.
pub(super) struct Worker {
    tx: Option<Sender<ToWorker>>,
    thread: JoinHandle<()>,
    progress: Progress,
}

impl Worker {
    /// Start the worker on the daemon's database connection.
    pub(super) fn spawn(db: SharedDb, setup: Setup, health: Health) -> std::io::Result<Self> {
        let (tx, rx) = mpsc::channel();
        let progress = Progress::default();
        let shared = progress.clone();
        let thread = std::thread::Builder::new()
            .name("morphoid-worker".into())
            .spawn(move || {
                let mut w = WorkerState {
                    db,
                    setup,
                    health,
                    progress: shared,
                    held: None,
                    backoff: Backoff::default(),
                    files_backoff: Backoff::default(),
                    registered: 0,
                    scenes: BTreeMap::new(),
                };
                w.run(rx)
            })?;
        Ok(Worker {
            tx: Some(tx),
            thread,
            progress,
        })
    }

    /// Tell the worker that jobs may be pending.
    pub(super) fn wake(&self) {
        if let Some(tx) = &self.tx {
            let _ = tx.send(ToWorker::Wake);
        }
    }

    /// Hand the worker a new setup (SIGHUP); the job in progress finishes
    /// with the old one.
    pub(super) fn reload(&self, setup: Setup) {
        if let Some(tx) = &self.tx {
            let _ = tx.send(ToWorker::Reload(Box::new(setup)));
        }
    }

    /// What the worker is doing.
    pub(super) fn progress(&self) -> &Progress {
        &self.progress
    }

    /// Ask the worker to stop after the current job (no new job is taken).
    pub(super) fn request_stop(&mut self) {
        self.progress.stop.store(true, Ordering::SeqCst);
        // Dropping the sender wakes a worker waiting for work.
        self.tx = None;
    }

    /// Whether the worker thread has ended.
    pub(super) fn is_finished(&self) -> bool {
        self.thread.is_finished()
    }
}

/// A job identified but not recorded yet.
struct Held {
    job: Job,
    finding: Finding,
    secs: f64,
    /// The pictures of a scan of several specimens, one per specimen, kept
    /// under the specimens' rows once they are recorded.
    specimen_scenes: Vec<Option<Scene>>,
}

/// What one step of the worker came to.
enum Step {
    /// Something was done; look for more.
    Worked,
    /// Nothing to do.
    Idle,
    /// The database failed; wait before trying again.
    Fault,
}

/// The worker thread's state.
struct WorkerState {
    db: SharedDb,
    setup: Setup,
    health: Health,
    progress: Progress,
    /// The finding waiting for the database.
    held: Option<Held>,
    /// Retries of database operations.
    backoff: Backoff,
    /// Retries of result files.
    files_backoff: Backoff,
    /// The connection generation the references were registered on.
    registered: u64,
    /// What the reports of recently identified scans draw, by scan id.
    scenes: BTreeMap<i64, Scene>,
}

impl WorkerState {
    fn run(&mut self, rx: Receiver<ToWorker>) {
        let stop = self.progress.stop.clone();
        loop {
            let wait = if self.backoff.failing() {
                self.backoff.remaining()
            } else if self.files_backoff.failing() {
                self.files_backoff.remaining().min(IDLE_WAKE)
            } else {
                IDLE_WAKE
            };
            match rx.recv_timeout(wait) {
                Ok(ToWorker::Reload(setup)) => self.setup = *setup,
                Ok(ToWorker::Wake) | Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => {
                    // Stopping: a finding not recorded yet gets a last try.
                    if self.held.is_some() {
                        let _ = self.step();
                    }
                    return;
                }
            }
            while !stop.load(Ordering::SeqCst) {
                while let Ok(msg) = rx.try_recv() {
                    if let ToWorker::Reload(setup) = msg {
                        self.setup = *setup;
                    }
                }
                if !self.backoff.ready() {
                    break;
                }
                match self.step() {
                    Step::Worked => self.backoff.succeeded(),
                    Step::Idle => {
                        self.backoff.succeeded();
                        break;
                    }
                    Step::Fault => {
                        self.backoff.failed();
                        break;
                    }
                }
            }
            if stop.load(Ordering::SeqCst) {
                if self.held.is_some() {
                    let _ = self.step();
                }
                return;
            }
        }
    }

    /// Record the held finding, else write due result files, else claim
    /// and identify the next job (outside the lock: the control loop
    /// queues files meanwhile).
    fn step(&mut self) -> Step {
        let db = Arc::clone(&self.db);
        let mut guard = db::lock(&db);
        let next = match guard.store() {
            Ok((store, generation)) => self.step_on(store, generation),
            Err(e) => Err(e),
        };
        let job = match next {
            Ok(Next::Claimed(job)) => job,
            Ok(Next::Worked) => {
                guard.worked();
                return Step::Worked;
            }
            Ok(Next::Idle) => {
                guard.worked();
                return Step::Idle;
            }
            Ok(Next::Lacking) => {
                guard.worked();
                guard.lacks_recorded_scans();
                return Step::Worked;
            }
            Err(e) => {
                if !guard.failed(&e) {
                    // Not the storage: the same request would fail again;
                    // reported once, retried with the same backoff.
                    self.health.fault(Part::Database, &error_chain(&e));
                }
                return Step::Fault;
            }
        };
        // Marked current before the lock is released: a stop takes the
        // lock before it reads the marker, so a committed claim is always
        // seen (and abandoned) by it.
        self.progress.started_ms.store(now_ms(), Ordering::SeqCst);
        self.progress.current.store(job.scan_id, Ordering::SeqCst);
        guard.worked();
        drop(guard);
        let started = Instant::now();
        let (finding, mut scenes) =
            classify::identify_job(&self.setup.classifier, &job, self.setup.files.is_some());
        let specimen_scenes = if matches!(finding, Finding::Specimens(_)) {
            scenes
        } else {
            if let Some(scene) = scenes.pop().flatten() {
                self.keep_scene(job.scan_id, scene);
            }
            Vec::new()
        };
        let secs = started.elapsed().as_secs_f64();
        self.progress.current.store(0, Ordering::SeqCst);
        self.held = Some(Held {
            job,
            finding,
            secs,
            specimen_scenes,
        });
        Step::Worked
    }

    fn step_on(&mut self, store: &mut Store, generation: u64) -> Result<Next, StoreError> {
        if generation != self.registered {
            // A new connection may be to a new file: results need the
            // references registered.
            self.setup.classifier.register_references(store)?;
            // This thread identifies one scan at a time, and between
            // steps none but the held one: any other left running (a claim
            // reported failed that reached the file all the same) is
            // pending again, or it would never be identified.
            let held = self.held.as_ref().map(|h| h.job.scan_id);
            let requeued = store.requeue_running_but(held)?;
            if requeued > 0 {
                tracing::info!(
                    "{requeued} scan(s) left running when the database failed are pending again"
                );
            }
            self.registered = generation;
        }
        if let Some(held) = self.held.take() {
            match classify::record_finding(store, held.job.scan_id, &held.finding) {
                Ok(status) => {
                    // The log folded back and cut to nothing after every
                    // scan: a database on a small file system needs little
                    // more than its own size. Without waiting for readers
                    // (the console's): a wait would hold up the next scan
                    // for up to the busy timeout, and the periodic
                    // checkpoint takes what is left.
                    if let Err(e) = store.checkpoint_without_waiting() {
                        tracing::debug!("checkpoint after scan {}: {e}", held.job.scan_id);
                    }
                    self.keep_specimen_scenes(store, &held);
                    self.recorded(store, &held, status)
                }
                Err(e @ (StoreError::WrongStatus { .. } | StoreError::NoSuchScan(_))) => {
                    // Recorded already, or the database file was replaced:
                    // never a second result; a file the database does not
                    // know is queued again by the next listing.
                    tracing::warn!("{}: identification not recorded: {e}", held.job.path);
                    // Its file may be queued under another id in a
                    // replaced database, and claimed there by a claim
                    // reported failed: this thread now holds nothing, so
                    // any row left running is pending again.
                    let requeued = store.requeue_running_but(None)?;
                    if requeued > 0 {
                        tracing::info!("{requeued} scan(s) left running are pending again");
                    }
                    if matches!(e, StoreError::NoSuchScan(_)) {
                        // Its file was taken already: only a fresh listing
                        // queues it again.
                        return Ok(Next::Lacking);
                    }
                }
                Err(e) => {
                    self.held = Some(held);
                    return Err(e);
                }
            }
            return Ok(Next::Worked);
        }
        if self.files_backoff.ready() && self.write_due_files(store)? {
            return Ok(Next::Worked);
        }
        // A stop asked for while this thread waited for the lock: no new
        // claim (the stop would not see it).
        if self.progress.stop.load(Ordering::SeqCst) {
            return Ok(Next::Idle);
        }
        let Some(job) = store.claim_next()? else {
            return Ok(Next::Idle);
        };
        if job.attempts > MAX_ATTEMPTS {
            let message = format!(
                "{}: given up after {} attempts that did not finish (the daemon died on it)",
                job.path,
                job.attempts - 1
            );
            tracing::error!("{message}");
            self.held = Some(Held {
                job,
                finding: Finding::Failed(message),
                secs: 0.0,
                specimen_scenes: Vec::new(),
            });
            return Ok(Next::Worked);
        }
        Ok(Next::Claimed(job))
    }

    /// Keep `scene` for the report of scan `id` (the oldest go first).
    fn keep_scene(&mut self, id: i64, scene: Scene) {
        self.scenes.insert(id, scene);
        while self.scenes.len() > SCENES_KEPT {
            self.scenes.pop_first();
        }
    }

    /// Keep the pictures of a recorded scan of several specimens under
    /// their rows.
    fn keep_specimen_scenes(&mut self, store: &Store, held: &Held) {
        if held.specimen_scenes.is_empty() {
            return;
        }
        let Ok(Some(record)) = store.scan(held.job.scan_id, 0) else {
            return;
        };
        for (child, scene) in record.specimens.iter().zip(&held.specimen_scenes) {
            if let Some(scene) = scene {
                self.keep_scene(child.id, scene.clone());
            }
        }
    }

    /// The log line of a recorded job, and the quarantine of a failed one.
    fn recorded(&self, store: &Store, held: &Held, status: ScanStatus) {
        let (job, secs) = (&held.job, held.secs);
        match (&held.finding, status) {
            (_, ScanStatus::Ok) => log_result(store, job.scan_id, &job.path, secs),
            (Finding::Superseded(content), _) => {
                let newer = store
                    .scan(job.scan_id, 0)
                    .ok()
                    .flatten()
                    .and_then(|r| r.superseded_by);
                tracing::info!(
                    "{}: changed since it was queued as scan {}; not identified, the content \
                     read ({} bytes) is scan {}",
                    job.path,
                    job.scan_id,
                    content.size,
                    newer.map_or_else(|| "?".to_string(), |id| id.to_string())
                );
            }
            (Finding::Failed(message), _) => {
                tracing::warn!("{}: error after {secs:.1} s: {message}", job.path);
                if let Some(q) = &self.setup.quarantine {
                    move_to_quarantine(Path::new(&job.path), q);
                }
            }
            _ => {}
        }
    }

    /// Write the due result files (a few per pass); `true` when some were
    /// written. A scan whose files cannot be written gets the error in its
    /// row (cleared when a later attempt writes them); the folder's fault
    /// is reported once and tried again later; jobs go on meanwhile.
    fn write_due_files(&mut self, store: &mut Store) -> Result<bool, StoreError> {
        let Some(files) = &self.setup.files else {
            return Ok(false);
        };
        let due = store.files_due(FILES_PER_PASS)?;
        let mut wrote = false;
        let mut failed = false;
        for id in due {
            let Some(mut record) = store.scan(id, NEAREST)? else {
                continue;
            };
            if failed && record.files_error.is_some() {
                // Failed before and the folder still fails: not again now.
                continue;
            }
            // The page written now is the attempt that succeeds: an
            // earlier failure does not belong on it.
            record.files_error = None;
            // The JSON first: it is cheap, and when the folder cannot be
            // written no scene is drawn again for nothing.
            let written = files.write(&record).and_then(|_| {
                // The scene kept from identification, else drawn again
                // from the file (after a restart); why not, on the page.
                let (scene, note) = match self.scenes.remove(&id) {
                    Some(scene) => (Some(scene), None),
                    None if !record.nearest.is_empty() => {
                        match self.setup.classifier.scene_of_record(&record) {
                            Ok(scene) => (Some(scene), None),
                            Err(e) => (None, Some(e.to_string())),
                        }
                    }
                    None => (None, None),
                };
                let out = files.write_report(&record, scene.as_ref(), note.as_deref());
                if let (Err(_), Some(scene)) = (&out, scene) {
                    // Kept for the next attempt.
                    self.scenes.insert(id, scene);
                }
                out
            });
            match written {
                Ok(_) => {
                    store.files_written(id)?;
                    wrote = true;
                }
                Err(e) => {
                    // Logged once per fault by the health, kept per scan
                    // in its row.
                    let message = error_chain(&e);
                    tracing::debug!(scan = %record.path, "result files not written: {message}");
                    store.files_failed(id, &message)?;
                    self.health.fault(Part::Results, &message);
                    failed = true;
                }
            }
        }
        if failed {
            self.files_backoff.failed();
        } else if wrote {
            self.health.clear(Part::Results);
            self.files_backoff.succeeded();
        }
        if wrote {
            if let Err(e) = files.write_index(store) {
                self.health.fault(Part::Results, &error_chain(&e));
            }
        }
        Ok(wrote)
    }
}

/// What [`WorkerState::step_on`] came to.
enum Next {
    Worked,
    Idle,
    /// A job whose claim has committed, to identify now.
    Claimed(Job),
    /// The held job's row is gone: the database lacks what was recorded.
    Lacking,
}

/// One info line per identified scan: file, nearest taxon per rank with
/// its reference and distance, time taken.
fn log_result(store: &Store, id: i64, path: &str, secs: f64) {
    let ranks_of = |r: &crate::store::ScanRecord| {
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
    };
    let record = store.scan(id, NEAREST).ok().flatten();
    match record {
        Some(r) if !r.specimens.is_empty() => {
            let each = r
                .specimens
                .iter()
                .map(|c| match &c.error {
                    Some(e) => format!("#{}: error: {e}", c.specimen.unwrap_or(0)),
                    None => format!("#{}: {}", c.specimen.unwrap_or(0), ranks_of(c)),
                })
                .collect::<Vec<_>>()
                .join("; ");
            tracing::info!(
                "{path}: {} specimens: {each}; {secs:.1} s",
                r.specimens.len()
            );
        }
        r => {
            let ranks = r.as_ref().map(ranks_of).unwrap_or_default();
            tracing::info!("{path}: {ranks}; {secs:.1} s");
        }
    }
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
