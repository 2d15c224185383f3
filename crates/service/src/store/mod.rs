//! The SQLite record of references, scans (the job queue), results and
//! distances.
//!
//! One database file, opened in WAL mode so that readers (`morphoid
//! results`, a status line) never wait for the writer. Scans are jobs:
//! [`Store::enqueue`] adds a pending row (once per content hash),
//! [`Store::claim_next`] marks the oldest pending one running,
//! [`Store::complete`] records the whole result in one transaction and
//! [`Store::fail`] records an error. After a crash, [`Store::requeue_running`]
//! puts the interrupted job back; since a result is only ever committed
//! together with the `ok` status, a scan with a result is never re-run.
//!
//! Durability: `synchronous=FULL`. In WAL mode `NORMAL` keeps the database
//! consistent but may lose the last commits on power loss; an identification
//! that was reported must never vanish, and one fsync per scan costs nothing
//! next to the seconds an identification takes.
//!
//! The store does no numerical work: it records the plain data of an
//! identification ([`crate::identify::ScanOutcome`]) and reads it back.
//! Its parts: `references` (the library's specimens), `queue` (scans as
//! jobs, and the transaction that records a result), `results` (reading
//! scans back), `schema` (the tables and their migrations).
//!
//! ```
//! use morphoid_data::hash::content_hash;
//! use morphoid_service::identify::{DistanceRow, RankResult, ScanOutcome};
//! use morphoid_service::store::{Labels, Store};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! # let dir = tempfile::tempdir()?;
//! let mut store = Store::open(&dir.path().join("morphoid.sqlite"))?;
//! let mut labels = Labels::new();
//! labels.insert("genus".into(), Some("Galago".into()));
//! store.register_reference("x21", &content_hash(b"x21 mesh"), &labels)?;
//! store.mark_reference_prepared("x21")?;
//!
//! store.requeue_running()?; // at start-up
//! let bytes = b"scan bytes";
//! store.enqueue("export/a.ply", &content_hash(bytes), bytes.len() as u64)?;
//! while let Some(job) = store.claim_next()? {
//!     let outcome = ScanOutcome {
//!         ranks: vec![RankResult {
//!             rank: "genus".into(),
//!             taxon: "Galago".into(),
//!             reference: "x21".into(),
//!             distance: 0.031,
//!             runner_up: None,
//!             margin: None,
//!             confidence: None,
//!         }],
//!         distances: vec![DistanceRow {
//!             reference: "x21".into(),
//!             forward: 0.031,
//!             backward: 0.034,
//!             distance: 0.031,
//!             reflected: false,
//!         }],
//!         ..ScanOutcome::default()
//!     };
//!     store.complete(job.scan_id, &outcome)?;
//! }
//! let last = store.recent(1)?;
//! let json = serde_json::to_string(&last)?;
//! assert!(json.contains(r#""taxon":"Galago""#));
//! # Ok(())
//! # }
//! ```

mod error;
mod queue;
mod references;
mod results;
mod reviews;
mod schema;
mod search;
mod types;
mod users;

pub use error::StoreError;
pub use reviews::{Decision, NewReview, ReviewError, ReviewRecord};
pub use schema::{migrate, APPLICATION_ID, MIGRATIONS, SCHEMA_VERSION};
pub(crate) use search::IDENTIFICATION_BUCKETS_S;
pub use search::{IdentificationTimes, ScanPage, ScanQuery};
pub use types::{Enqueued, Labels, ReferenceState, ScanRecord, ScanStatus};
pub(crate) use types::{Job, Original, ReferenceRecord, StatusCounts};
pub use users::{CuratorRecord, UserError};

use rusqlite::{Connection, OptionalExtension};
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// How long a writer waits for another connection's lock before failing.
const BUSY_TIMEOUT: Duration = Duration::from_secs(10);

/// Bytes the write-ahead log file is cut back to when it is reset after a
/// checkpoint (SQLite otherwise keeps the file at its largest size).
pub(crate) const JOURNAL_SIZE_LIMIT: u64 = 64 * 1024;

/// How many nearest references a [`ScanRecord`] carries by default.
pub(crate) const DEFAULT_NEAREST: usize = 5;

/// An open morphoid database.
///
/// One `Store` is one SQLite connection: use one per thread (they can
/// share the file), or guard one with a mutex.
pub struct Store {
    conn: Connection,
    path: PathBuf,
    /// Whether finishing a scan marks its result files as due
    /// ([`Store::set_result_files`]).
    result_files: bool,
    /// How long a write waits for another connection's lock.
    busy_timeout: Duration,
}

impl std::fmt::Debug for Store {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Store").field("path", &self.path).finish()
    }
}

/// Current time in Unix milliseconds (0 if the clock is before 1970).
pub fn now_ms() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
        .unwrap_or(0)
}

/// Start of the UTC day containing `t_ms` (for "scans today").
pub fn utc_day_start_ms(t_ms: i64) -> i64 {
    const DAY_MS: i64 = 86_400_000;
    t_ms - t_ms.rem_euclid(DAY_MS)
}

impl Store {
    /// Open (or create) the database at `path`, configure the connection
    /// (WAL, foreign keys, busy timeout, `synchronous=FULL`) and migrate the
    /// schema to [`SCHEMA_VERSION`]. A database from a newer morphoid or of
    /// another application is refused.
    pub fn open(path: &Path) -> Result<Store, StoreError> {
        let open_err = |source| StoreError::Open {
            path: path.to_path_buf(),
            source,
        };
        let mut conn = Connection::open(path).map_err(open_err)?;
        conn.busy_timeout(BUSY_TIMEOUT).map_err(open_err)?;
        let mode: String = conn
            .query_row("PRAGMA journal_mode = WAL", [], |r| r.get(0))
            .map_err(open_err)?;
        if !mode.eq_ignore_ascii_case("wal") {
            return Err(StoreError::Corrupt(format!(
                "journal mode {mode} instead of wal"
            )));
        }
        conn.pragma_update(None, "synchronous", "FULL")
            .map_err(open_err)?;
        // A bounded log: on a small file system an unbounded one fills the
        // disk long before the data does.
        conn.pragma_update(None, "journal_size_limit", JOURNAL_SIZE_LIMIT as i64)
            .map_err(open_err)?;
        conn.pragma_update(None, "foreign_keys", true)
            .map_err(open_err)?;
        schema::migrate(&mut conn, path)?;
        Ok(Store {
            conn,
            path: path.to_path_buf(),
            result_files: false,
            busy_timeout: BUSY_TIMEOUT,
        })
    }

    /// Whether this connection marks the result files of every scan it
    /// finishes (`complete`, `fail`, a duplicate's `enqueue`) as due, in
    /// the same transaction; [`Store::files_due`] lists them until
    /// [`Store::files_written`]. A daemon with a results folder sets it, so
    /// a result file that cannot be written now is written later.
    pub fn set_result_files(&mut self, on: bool) {
        self.result_files = on;
    }

    /// How long a write waits for another connection's lock before it
    /// fails as busy (default 10 s). The daemon waits less, so that its
    /// control loop is never held up long; the job is retried instead.
    pub fn set_busy_timeout(&mut self, timeout: Duration) -> Result<(), StoreError> {
        self.conn.busy_timeout(timeout)?;
        self.busy_timeout = timeout;
        Ok(())
    }

    /// SQLite's `data_version` on this connection: it changes whenever
    /// another connection (of this process or another) commits to the
    /// file, and never for this connection's own commits. What the
    /// console's answer cache is keyed on.
    pub fn data_version(&self) -> Result<i64, StoreError> {
        Ok(self
            .conn
            .query_row("PRAGMA data_version", [], |row| row.get(0))?)
    }

    /// Write a consistent copy of the whole database to the new file
    /// `target` (`VACUUM INTO`): how the daemon puts back a database file
    /// deleted under its open connection.
    pub fn copy_to(&self, target: &Path) -> Result<(), StoreError> {
        let target = target
            .to_str()
            .ok_or_else(|| StoreError::Corrupt(format!("{} is not UTF-8", target.display())))?;
        self.conn.execute("VACUUM INTO ?1", [target])?;
        Ok(())
    }

    /// Fold the whole write-ahead log into the database and cut the log
    /// file to zero bytes (`wal_checkpoint(TRUNCATE)`): what frees the
    /// log's space when the disk is full, and keeps it small in normal
    /// running. Returns whether it completed (`false`: another connection
    /// was reading or writing, so part of the log stays until next time).
    pub fn checkpoint(&self) -> Result<bool, StoreError> {
        self.checkpoint_as("TRUNCATE")
    }

    /// [`Store::checkpoint`] without waiting for other connections: while
    /// one is reading (the web console, always, under load) this folds
    /// what it can and leaves the rest for a later checkpoint, where a
    /// checkpoint that waits would hold the caller for up to its busy
    /// timeout. Returns whether it completed.
    pub fn checkpoint_without_waiting(&mut self) -> Result<bool, StoreError> {
        self.conn.busy_timeout(Duration::ZERO)?;
        let done = self.checkpoint_as("TRUNCATE");
        self.conn.busy_timeout(self.busy_timeout)?;
        done
    }

    /// Let a commit fold the write-ahead log back into the database once it
    /// holds `pages` pages (SQLite's default: 1000, 4 MB). The daemon sets
    /// a small value, so that its log never holds much more than one
    /// scan's pages.
    pub fn set_wal_autocheckpoint(&mut self, pages: u32) -> Result<(), StoreError> {
        self.conn.pragma_update(None, "wal_autocheckpoint", pages)?;
        Ok(())
    }

    fn checkpoint_as(&self, mode: &str) -> Result<bool, StoreError> {
        let (busy, log, done): (i64, i64, i64) =
            self.conn
                .query_row(&format!("PRAGMA wal_checkpoint({mode})"), [], |r| {
                    Ok((r.get(0)?, r.get(1)?, r.get(2)?))
                })?;
        Ok(busy == 0 && log == done)
    }

    /// The database file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The schema version of the file.
    pub fn schema_version(&self) -> Result<u32, StoreError> {
        let v: i64 = self
            .conn
            .query_row("PRAGMA user_version", [], |r| r.get(0))?;
        u32::try_from(v).map_err(|_| StoreError::Corrupt(format!("schema version {v}")))
    }

    /// Run SQLite's integrity and foreign-key checks; an error names the
    /// first problem found.
    pub fn check_integrity(&self) -> Result<(), StoreError> {
        let verdict: String = self
            .conn
            .query_row("PRAGMA integrity_check", [], |r| r.get(0))?;
        if verdict != "ok" {
            return Err(StoreError::Corrupt(verdict));
        }
        let orphan: Option<String> = self
            .conn
            .query_row("PRAGMA foreign_key_check", [], |r| r.get("table"))
            .optional()?;
        if let Some(table) = orphan {
            return Err(StoreError::Corrupt(format!(
                "dangling foreign key in table {table}"
            )));
        }
        Ok(())
    }
}

/// The status named `s` in the database.
fn parse_status(s: &str) -> Result<ScanStatus, StoreError> {
    ScanStatus::parse(s).ok_or_else(|| StoreError::Corrupt(format!("scan status {s:?}")))
}

/// `value` as the text of a JSON column.
fn to_json<T: serde::Serialize>(column: &'static str, value: &T) -> Result<String, StoreError> {
    serde_json::to_string(value).map_err(|source| StoreError::Json { column, source })
}

/// The text of a JSON column as a value.
fn from_json<T: serde::de::DeserializeOwned>(
    column: &'static str,
    text: &str,
) -> Result<T, StoreError> {
    serde_json::from_str(text).map_err(|source| StoreError::Json { column, source })
}
