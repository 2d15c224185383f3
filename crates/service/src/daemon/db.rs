//! The daemon's one connection to its database, shared by the control loop
//! and the worker: one connection, so that a database file deleted or
//! replaced under the running daemon is let go by everyone at once (two
//! connections could open a new file beside the old write-ahead log, which
//! SQLite would take for the new file's).
//!
//! Before each use the file at the configured path is checked to be the
//! one open: when it was deleted, everything recorded is put back at the
//! path from the still-open connection; when it was replaced, the new
//! file is used. A storage failure drops the connection, so the next use
//! opens the file again (a disk that was full, a file system remounted
//! after an I/O error).

use super::health::{Health, Part};
use crate::store::{Store, StoreError};
use morphoid_data::present::error_chain;
use std::os::unix::fs::MetadataExt as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

/// How long an operation waits for another process's lock before it fails
/// (and is retried): short, as the control loop shares the connection.
const BUSY_TIMEOUT: Duration = Duration::from_secs(2);

/// Pages the log may hold before a commit folds it back: a scan's
/// transactions touch a few dozen pages, so the log stays near one scan's
/// worth (a database on a small file system needs little more than its
/// own size); the worker also checkpoints after every scan.
const WAL_AUTOCHECKPOINT_PAGES: u32 = 16;

/// The database connection, opened on demand.
#[derive(Debug)]
pub(super) struct Db {
    path: PathBuf,
    store: Option<Store>,
    /// Device and inode of the file the connection has open.
    identity: Option<(u64, u64)>,
    /// Counts the connections opened, so a user can tell a new one (whose
    /// file may be new and lack the references).
    generation: u64,
    result_files: bool,
    health: Health,
    /// The file at the path is another than the one recorded into (a
    /// replacement, or a new file after a deletion that could not be
    /// undone), or it lacks a scan recorded into it; and the control loop
    /// has not yet listed the export folder again for what it lacks.
    new_file: bool,
}

/// The connection as the control loop and the worker share it.
pub(super) type SharedDb = Arc<Mutex<Db>>;

/// Lock the shared connection (a panic elsewhere does not make it unusable).
pub(super) fn lock(db: &SharedDb) -> MutexGuard<'_, Db> {
    db.lock().unwrap_or_else(|p| p.into_inner())
}

/// Device and inode of the file at `path`.
fn identity_of(path: &Path) -> Option<(u64, u64)> {
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

impl Db {
    /// Open the database at `path` (an error here stops the start).
    pub(super) fn open(path: &Path, health: Health) -> Result<Db, StoreError> {
        let mut db = Db {
            path: path.to_path_buf(),
            store: None,
            identity: None,
            generation: 0,
            result_files: false,
            health,
            new_file: false,
        };
        db.store()?;
        Ok(db)
    }

    /// Whether finished scans get their result files marked due.
    pub(super) fn set_result_files(&mut self, on: bool) {
        self.result_files = on;
        if let Some(s) = &mut self.store {
            s.set_result_files(on);
        }
    }

    /// The connection to the file now at the path, opened when needed,
    /// and the number of connections opened so far (a new number: the file
    /// may be new and lack the references).
    pub(super) fn store(&mut self) -> Result<(&mut Store, u64), StoreError> {
        self.follow_file();
        if self.store.is_none() {
            let mut store = Store::open(&self.path)?;
            store.set_busy_timeout(BUSY_TIMEOUT)?;
            store.set_wal_autocheckpoint(WAL_AUTOCHECKPOINT_PAGES)?;
            store.set_result_files(self.result_files);
            self.identity = identity_of(&self.path);
            self.generation += 1;
            self.store = Some(store);
        }
        match &mut self.store {
            Some(s) => Ok((s, self.generation)),
            None => Err(StoreError::Corrupt("no connection".into())),
        }
    }

    /// An operation failed with `e`. When the storage failed: report it
    /// (once while it lasts) and let go of the connection, so the next use
    /// opens the file afresh; returns whether it did.
    pub(super) fn failed(&mut self, e: &StoreError) -> bool {
        let storage = e.is_storage_fault();
        if e.is_disk_full() {
            self.follow_file();
            // The log may be what fills the disk: folded into the
            // database and cut to nothing, its space is free for the
            // retry. On a disk with no room even for that, the retry
            // (on a new connection) tries again.
            match self.store.as_ref().map(Store::checkpoint) {
                Some(Ok(done)) => tracing::debug!("disk full: log checkpointed (complete: {done})"),
                Some(Err(c)) => tracing::debug!("disk full: checkpoint failed: {c}"),
                None => {}
            }
        }
        if storage {
            self.store = None;
            self.health.fault(Part::Database, &error_chain(e));
        }
        storage
    }

    /// Whether the database file became another one since the last call
    /// (then the export folder is to be listed again: the new file may
    /// lack scans that the old one had recorded).
    pub(super) fn take_new_file(&mut self) -> bool {
        self.follow_file();
        std::mem::take(&mut self.new_file)
    }

    /// The database lacks a scan this daemon had recorded in it (a disk
    /// that lost its last writes, a file swapped while the connection was
    /// closed): the export folder is to be listed again as for a new file,
    /// so that what it lacks is queued again.
    pub(super) fn lacks_recorded_scans(&mut self) {
        self.new_file = true;
    }

    /// Fold the write-ahead log into the database and cut it to nothing
    /// (the periodic bound on its size; see [`Store::checkpoint`]).
    /// Nothing when no connection is open; a failure is handled as any
    /// other storage failure.
    pub(super) fn checkpoint(&mut self) {
        // Never on a connection to a file replaced meanwhile: its log's
        // name is the new file's.
        self.follow_file();
        let Some(store) = &mut self.store else {
            return;
        };
        // Never waiting on the console's readers: the control loop must
        // not stall, and the next interval tries again.
        match store.checkpoint_without_waiting() {
            Ok(done) => tracing::trace!("checkpoint (complete: {done})"),
            Err(e) => {
                self.failed(&e);
            }
        }
    }

    /// An operation worked: the database is healthy.
    pub(super) fn worked(&self) {
        self.health.clear(Part::Database);
    }

    /// Compare the file at the path with the open one; on a difference,
    /// put a deleted file back from the connection, or let go of the
    /// connection to a replaced one.
    fn follow_file(&mut self) {
        let Some(store) = &self.store else {
            return;
        };
        let now = identity_of(&self.path);
        if now.is_some() && now == self.identity {
            return;
        }
        if now.is_none() {
            match restore(store, &self.path) {
                Ok(staged) => {
                    // Closing the last connection removes the old log files
                    // by name; only then may the copy take the path.
                    self.store = None;
                    match std::fs::rename(&staged, &self.path) {
                        Ok(()) => tracing::error!(
                            "database {} was deleted under the running daemon; \
                             it is back with everything recorded",
                            self.path.display()
                        ),
                        Err(e) => {
                            self.new_file = true;
                            tracing::error!(
                                "database {} was deleted under the running daemon and \
                                 cannot be put back ({e}); a new one is started",
                                self.path.display()
                            )
                        }
                    }
                }
                Err(e) => {
                    self.store = None;
                    self.new_file = true;
                    tracing::error!(
                        "database {} was deleted under the running daemon and cannot \
                         be put back ({}); a new one is started",
                        self.path.display(),
                        error_chain(&e)
                    );
                }
            }
        } else {
            self.store = None;
            self.new_file = true;
            tracing::warn!(
                "database {} was replaced under the running daemon; using the new file \
                 and queueing the export folder's files it has not recorded",
                self.path.display()
            );
        }
    }
}

/// Copy the open database to a new file beside `path`; returns the copy.
fn restore(store: &Store, path: &Path) -> Result<PathBuf, StoreError> {
    let mut name = std::ffi::OsString::from(".");
    name.push(path.file_name().unwrap_or_default());
    name.push(format!(".restore-{}", std::process::id()));
    let staged = path.with_file_name(name);
    let _ = std::fs::remove_file(&staged);
    store.copy_to(&staged)?;
    Ok(staged)
}
