//! The export folder as a source of settled files: a `notify` watcher for
//! prompt reaction, a full listing at start, on a serial trigger and every
//! [`RESCAN_INTERVAL`] as a safety net (events can be lost: inotify queue
//! overflow, network filesystems, a folder moved in whole), and the settle
//! rule applied on a short tick, because a file that has stopped changing
//! sends no further event.
//!
//! When the watcher cannot be created (inotify limits, a folder that does
//! not exist yet, `MORPHOID_WATCH=poll`), the folder is polled instead: a
//! listing every [`POLL_INTERVAL`] while a file is settling, every
//! [`IDLE_POLL_INTERVAL`] otherwise. Watching is retried at each safety
//! rescan unless polling was asked for.

use super::intake::{stamp_of, Filter};
use super::settle::Settler;
use notify::event::{AccessKind, AccessMode};
use notify::{EventKind, RecommendedWatcher, RecursiveMode, Watcher};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use tokio::sync::mpsc::{self, UnboundedReceiver, UnboundedSender};

/// How often settling files are looked at again (and, when polling, how
/// often the folder is listed while something settles).
pub(super) const POLL_INTERVAL: Duration = Duration::from_millis(250);
/// How often a polled folder is listed when nothing is settling (a large
/// folder costs one `stat` per file per listing).
const IDLE_POLL_INTERVAL: Duration = Duration::from_secs(1);
/// How often the whole folder is listed even when the watcher works.
pub(super) const RESCAN_INTERVAL: Duration = Duration::from_secs(30);

/// The environment variable that forces polling (`MORPHOID_WATCH=poll`),
/// for folders where change events are unreliable (some network mounts).
const WATCH_MODE_VAR: &str = "MORPHOID_WATCH";

/// What a batch of watcher events asks for.
#[derive(Debug, Default)]
pub(super) struct Outcome {
    /// Files that have settled: to be hashed and queued.
    pub ready: Vec<PathBuf>,
    /// Whether a full listing is needed (events were lost, or a folder
    /// appeared whose files were never reported one by one).
    pub rescan: bool,
}

/// How changes are noticed.
enum Mode {
    /// A live watcher; its events arrive on `rx`.
    Events { _watcher: RecommendedWatcher },
    /// Periodic listings; `forced` when asked for (not retried).
    Polling { forced: bool },
}

/// The watched export folder with its settle bookkeeping.
pub(super) struct FolderWatch {
    filter: Filter,
    settle: Duration,
    settler: Settler,
    mode: Mode,
    tx: UnboundedSender<notify::Result<notify::Event>>,
    rx: UnboundedReceiver<notify::Result<notify::Event>>,
    last_poll: Option<Instant>,
    list_error_logged: bool,
}

impl FolderWatch {
    /// Start watching the folder of `watch` (falls back to polling, with a
    /// log line, when a watcher cannot be set up).
    pub(super) fn start(watch: &crate::config::Watch) -> Self {
        let (tx, rx) = mpsc::unbounded_channel();
        let forced = std::env::var(WATCH_MODE_VAR).is_ok_and(|v| v.trim() == "poll");
        let mut w = FolderWatch {
            filter: Filter::from_config(watch),
            settle: Duration::from_secs_f64(watch.settle_seconds.max(0.0)),
            settler: Settler::new(),
            mode: Mode::Polling { forced },
            tx,
            rx,
            last_poll: None,
            list_error_logged: false,
        };
        if forced {
            tracing::info!(
                "{}: polling the folder ({WATCH_MODE_VAR}=poll)",
                w.filter.dir.display()
            );
        } else {
            w.try_watch();
        }
        w
    }

    /// Try to set up the watcher; on failure stay in polling mode.
    fn try_watch(&mut self) {
        let tx = self.tx.clone();
        let made = notify::recommended_watcher(move |res| {
            // The receiver lives as long as the daemon; a send error only
            // happens while shutting down.
            let _ = tx.send(res);
        })
        .and_then(|mut w| {
            // Recursive even when subfolders' files are not scans: the
            // slices of a stack in a subfolder must be seen arriving.
            w.watch(&self.filter.dir, RecursiveMode::Recursive)
                .map(|()| w)
        });
        match made {
            Ok(w) => {
                tracing::info!("{}: watching for changes", self.filter.dir.display());
                self.mode = Mode::Events { _watcher: w };
            }
            Err(e) => {
                tracing::warn!(
                    "{}: cannot watch for changes ({e}); polling the folder instead",
                    self.filter.dir.display()
                );
                self.mode = Mode::Polling { forced: false };
            }
        }
    }

    /// Whether the folder is being polled rather than watched.
    fn is_polling(&self) -> bool {
        matches!(self.mode, Mode::Polling { .. })
    }

    /// The next watcher event (pending for ever when polling).
    pub(super) async fn event(&mut self) -> Option<notify::Result<notify::Event>> {
        self.rx.recv().await
    }

    /// Take every event already waiting, after `first`, and apply them.
    pub(super) fn handle(&mut self, first: notify::Result<notify::Event>) -> Outcome {
        let mut out = Outcome::default();
        let now = Instant::now();
        let mut next = Some(first);
        while let Some(res) = next {
            match res {
                Ok(event) => self.apply(&event, now, &mut out),
                Err(e) => {
                    tracing::warn!("watcher error: {e}; listing the folder");
                    out.rescan = true;
                }
            }
            next = self.rx.try_recv().ok();
        }
        out
    }

    fn apply(&mut self, event: &notify::Event, now: Instant, out: &mut Outcome) {
        if event.need_rescan() {
            out.rescan = true;
            return;
        }
        // Our own reads (hashing, loading) show up as opens and reads:
        // they change nothing. A close after writing is worth a look.
        if let EventKind::Access(kind) = event.kind {
            if kind != AccessKind::Close(AccessMode::Write) {
                return;
            }
        }
        // The export folder itself removed or renamed: its watch is gone
        // with it. Poll (which also retries watching at each safety
        // rescan) until a folder of that name can be watched again.
        if event.paths.iter().any(|p| p == &self.filter.dir) && !self.filter.dir.is_dir() {
            tracing::warn!(
                "{}: the export folder is gone; polling until it can be watched again",
                self.filter.dir.display()
            );
            self.mode = Mode::Polling { forced: false };
            out.rescan = true;
            return;
        }
        for path in &event.paths {
            match std::fs::metadata(path) {
                // A folder created or moved in: inotify reports its files
                // only from the moment its own watch exists.
                Ok(meta) if meta.is_dir() => out.rescan = true,
                // A slice counts for its folder, the scan it belongs to.
                Ok(meta) if meta.is_file() => {
                    if let Some(scan) = self.filter.scan_of(path) {
                        if let Some(stamp) = stamp_of(&scan) {
                            if self.settler.observe(&scan, stamp, now, self.settle)
                                && !out.ready.contains(&scan)
                            {
                                out.ready.push(scan);
                            }
                        }
                    }
                }
                // Gone (deleted or renamed away): a file reappearing under
                // that name is new.
                Err(_) => self.settler.forget(path),
                Ok(_) => {}
            }
        }
    }

    /// The settle tick: files still settling are looked at again; when
    /// polling, the whole folder is listed (at most every
    /// [`POLL_INTERVAL`] while something settles, [`IDLE_POLL_INTERVAL`]
    /// otherwise). Returns the files that are now complete.
    pub(super) fn tick(&mut self) -> Vec<PathBuf> {
        let now = Instant::now();
        if self.is_polling() {
            let every = if self.settler.waiting() {
                POLL_INTERVAL
            } else {
                IDLE_POLL_INTERVAL
            };
            if self
                .last_poll
                .is_some_and(|t| now.duration_since(t) < every)
            {
                return Vec::new();
            }
            return self.rescan(false);
        }
        let mut ready = Vec::new();
        for path in self.settler.waiting_paths() {
            match stamp_of(&path) {
                Some(stamp) => {
                    if self.settler.observe(&path, stamp, now, self.settle) {
                        ready.push(path);
                    }
                }
                None => self.settler.forget(&path),
            }
        }
        ready
    }

    /// The safety-net rescan: in watching mode a full listing; in polling
    /// mode (not forced) first another try at watching.
    pub(super) fn safety_rescan(&mut self) -> Vec<PathBuf> {
        if matches!(self.mode, Mode::Polling { forced: false }) {
            self.try_watch();
        }
        self.rescan(false)
    }

    /// List the whole folder and observe every candidate; `force` takes
    /// each file now whatever its age (a serial trigger says the scanner
    /// has finished writing). Returns the files that are complete.
    pub(super) fn rescan(&mut self, force: bool) -> Vec<PathBuf> {
        let now = Instant::now();
        self.last_poll = Some(now);
        let files = match self.filter.list() {
            Ok(files) => {
                if self.list_error_logged {
                    tracing::info!("{}: listed again", self.filter.dir.display());
                }
                self.list_error_logged = false;
                files
            }
            Err(e) => {
                if !self.list_error_logged {
                    tracing::error!(
                        "{}: cannot list the export folder: {e}; retrying",
                        self.filter.dir.display()
                    );
                    self.list_error_logged = true;
                }
                return Vec::new();
            }
        };
        let listed: std::collections::HashSet<PathBuf> =
            files.iter().map(|(p, _)| p.clone()).collect();
        self.settler.retain_listed(&listed);
        let mut ready = Vec::new();
        for (path, stamp) in files {
            let taken = if force {
                self.settler.force(&path, stamp, now)
            } else {
                self.settler.observe(&path, stamp, now, self.settle)
            };
            if taken {
                ready.push(path);
            }
        }
        ready
    }

    /// Take `path` now if it is a candidate that was not yet taken with
    /// its current content (a trigger line named it).
    pub(super) fn force_file(&mut self, path: &Path) -> bool {
        if !self.filter.is_candidate(path) {
            return false;
        }
        match stamp_of(path) {
            Some(stamp) => self.settler.force(path, stamp, Instant::now()),
            None => false,
        }
    }

    /// Let `path` be taken again at its next settled observation (it could
    /// not be read or queued this time).
    pub(super) fn release(&mut self, path: &Path) {
        self.settler.release(path);
    }

    /// Take `path` again only after another settle time (it is not
    /// complete yet by its format).
    pub(super) fn defer(&mut self, path: &Path) {
        self.settler.defer(path, Instant::now());
    }

    /// The export folder.
    pub(super) fn dir(&self) -> &Path {
        &self.filter.dir
    }
}
