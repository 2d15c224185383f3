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
//! The store does no numerical work: it takes results as plain data.
//!
//! ```
//! use morphoid::hash::content_hash;
//! use morphoid::store::{DistanceRow, Labels, RankResult, ScanOutcome, Store};
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

pub mod schema;
mod types;

pub use schema::SCHEMA_VERSION;
pub use types::{
    DistanceRow, Enqueued, Job, Labels, LandmarkPoint, Nearest, RankResult, ReferenceRecord,
    ReferenceState, ScanLandmarks, ScanOutcome, ScanRecord, ScanStatus, StatusCounts,
};

use rusqlite::{params, Connection, OptionalExtension, Row, TransactionBehavior};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// How long a writer waits for another connection's lock before failing.
pub const BUSY_TIMEOUT: Duration = Duration::from_secs(10);

/// How many nearest references a [`ScanRecord`] carries by default.
pub const DEFAULT_NEAREST: usize = 5;

/// Errors of the store.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The file could not be opened or configured.
    #[error("cannot open database {path}: {source}")]
    Open {
        /// Database file.
        path: PathBuf,
        /// SQLite's error.
        source: rusqlite::Error,
    },
    /// Any other SQLite error.
    #[error("database error: {0}")]
    Sqlite(#[from] rusqlite::Error),
    /// The file was written by a newer morphoid.
    #[error(
        "database {path}: schema version {found} is newer than this morphoid \
         supports (version {supported}); use a newer morphoid or another database file"
    )]
    SchemaTooNew {
        /// Database file.
        path: PathBuf,
        /// Version in the file.
        found: u32,
        /// Newest version this build knows.
        supported: u32,
    },
    /// The file is an SQLite database of some other application.
    #[error("{path} is not a morphoid database (SQLite application id {application_id:#010x})")]
    NotMorphoid {
        /// Database file.
        path: PathBuf,
        /// The file's `application_id`.
        application_id: i32,
    },
    /// No scan has this id.
    #[error("no scan with id {0}")]
    NoSuchScan(i64),
    /// The scan is not in a state that allows the operation.
    #[error("scan {scan_id} is {status}; {operation} needs {expected}")]
    WrongStatus {
        /// Scan id.
        scan_id: i64,
        /// Its status.
        status: ScanStatus,
        /// What was attempted.
        operation: &'static str,
        /// The status it needs.
        expected: &'static str,
    },
    /// A result names a reference that is not registered as current.
    #[error("unknown reference {0:?} (register it before recording results against it)")]
    UnknownReference(String),
    /// NaN, infinity or a negative distance in an outcome.
    #[error("invalid value {value} for {field}")]
    InvalidNumber {
        /// Which field.
        field: String,
        /// The value.
        value: f64,
    },
    /// A value that does not fit the database (e.g. a size above 2⁶³).
    #[error("value out of range for {0}")]
    OutOfRange(&'static str),
    /// A JSON column could not be written or read.
    #[error("JSON column {column}: {source}")]
    Json {
        /// Column.
        column: &'static str,
        /// serde_json's error.
        source: serde_json::Error,
    },
    /// The database holds something this build cannot interpret.
    #[error("corrupt database: {0}")]
    Corrupt(String),
}

/// An open morphoid database.
///
/// One `Store` is one SQLite connection: use one per thread (they can
/// share the file), or guard one with a mutex.
pub struct Store {
    conn: Connection,
    path: PathBuf,
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
        conn.pragma_update(None, "foreign_keys", true)
            .map_err(open_err)?;
        schema::migrate(&mut conn, path)?;
        Ok(Store {
            conn,
            path: path.to_path_buf(),
        })
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
            .query_row("PRAGMA foreign_key_check", [], |r| r.get(0))
            .optional()?;
        if let Some(table) = orphan {
            return Err(StoreError::Corrupt(format!(
                "dangling foreign key in table {table}"
            )));
        }
        Ok(())
    }

    // ----- references -----

    /// Register reference `name` with the given content and labels, as the
    /// current version of that name. Same name and content: labels updated,
    /// state kept (a removed one becomes pending again). New content: a new
    /// pending row, and the previous version is marked superseded (its
    /// recorded distances stay attached to the content they were measured
    /// on). Returns the row id.
    pub fn register_reference(
        &mut self,
        name: &str,
        content_hash: &str,
        labels: &Labels,
    ) -> Result<i64, StoreError> {
        let labels_json = to_json("reference.labels", labels)?;
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        tx.execute(
            "UPDATE reference SET state = 'superseded'
             WHERE name = ?1 AND content_hash <> ?2 AND state NOT IN ('superseded', 'removed')",
            params![name, content_hash],
        )?;
        let existing: Option<(i64, String)> = tx
            .query_row(
                "SELECT id, state FROM reference WHERE name = ?1 AND content_hash = ?2",
                params![name, content_hash],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .optional()?;
        let id = match existing {
            Some((id, state)) => {
                let revived = if state == "superseded" || state == "removed" {
                    "pending"
                } else {
                    state.as_str()
                };
                tx.execute(
                    "UPDATE reference SET labels = ?2, state = ?3 WHERE id = ?1",
                    params![id, labels_json, revived],
                )?;
                id
            }
            None => {
                tx.execute(
                    "INSERT INTO reference (name, content_hash, labels, state, added_at)
                     VALUES (?1, ?2, ?3, 'pending', ?4)",
                    params![name, content_hash, labels_json, now_ms()],
                )?;
                tx.last_insert_rowid()
            }
        };
        tx.commit()?;
        Ok(id)
    }

    /// Mark the current version of `name` prepared (now).
    pub fn mark_reference_prepared(&mut self, name: &str) -> Result<(), StoreError> {
        let n = self.conn.execute(
            "UPDATE reference SET state = 'prepared', error = NULL, prepared_at = ?2
             WHERE name = ?1 AND state NOT IN ('superseded', 'removed')",
            params![name, now_ms()],
        )?;
        if n == 0 {
            return Err(StoreError::UnknownReference(name.to_string()));
        }
        Ok(())
    }

    /// Mark the current version of `name` failed, with the reason.
    pub fn mark_reference_failed(&mut self, name: &str, message: &str) -> Result<(), StoreError> {
        let n = self.conn.execute(
            "UPDATE reference SET state = 'failed', error = ?2
             WHERE name = ?1 AND state NOT IN ('superseded', 'removed')",
            params![name, message],
        )?;
        if n == 0 {
            return Err(StoreError::UnknownReference(name.to_string()));
        }
        Ok(())
    }

    /// Mark every current reference whose name is not in `keep` removed
    /// (its mesh left the library folder). Returns how many were removed.
    pub fn remove_references_except(&mut self, keep: &[&str]) -> Result<usize, StoreError> {
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        tx.execute_batch("CREATE TEMP TABLE IF NOT EXISTS keep_name (name TEXT PRIMARY KEY)")?;
        tx.execute("DELETE FROM temp.keep_name", [])?;
        {
            let mut insert =
                tx.prepare("INSERT OR IGNORE INTO temp.keep_name (name) VALUES (?1)")?;
            for name in keep {
                insert.execute([name])?;
            }
        }
        let n = tx.execute(
            "UPDATE reference SET state = 'removed'
             WHERE state NOT IN ('superseded', 'removed')
               AND name NOT IN (SELECT name FROM temp.keep_name)",
            [],
        )?;
        tx.execute("DELETE FROM temp.keep_name", [])?;
        tx.commit()?;
        Ok(n)
    }

    /// The current references (not superseded, not removed), by name.
    pub fn references(&self) -> Result<Vec<ReferenceRecord>, StoreError> {
        let mut stmt = self.conn.prepare(
            "SELECT id, name, content_hash, labels, state, error, added_at, prepared_at
             FROM reference WHERE state NOT IN ('superseded', 'removed') ORDER BY name",
        )?;
        let rows = stmt.query_map([], |r| {
            Ok((
                r.get::<_, i64>(0)?,
                r.get::<_, String>(1)?,
                r.get::<_, String>(2)?,
                r.get::<_, String>(3)?,
                r.get::<_, String>(4)?,
                r.get::<_, Option<String>>(5)?,
                r.get::<_, i64>(6)?,
                r.get::<_, Option<i64>>(7)?,
            ))
        })?;
        let mut out = Vec::new();
        for row in rows {
            let (id, name, content_hash, labels, state, error, added_at_ms, prepared_at_ms) = row?;
            let state = ReferenceState::parse(&state)
                .ok_or_else(|| StoreError::Corrupt(format!("reference state {state:?}")))?;
            out.push(ReferenceRecord {
                id,
                name,
                content_hash,
                labels: from_json("reference.labels", &labels)?,
                state,
                error,
                added_at_ms,
                prepared_at_ms,
            });
        }
        Ok(out)
    }

    // ----- jobs -----

    /// Add a pending scan for the file at `path` with this content, unless
    /// the content is already known: then nothing is added and the existing
    /// scan is returned, whatever its status (the same bytes are identified
    /// once; use [`Store::retry`] to identify them again). A changed file
    /// has a new hash and is enqueued.
    pub fn enqueue(
        &mut self,
        path: &str,
        content_hash: &str,
        size: u64,
    ) -> Result<Enqueued, StoreError> {
        let size = i64::try_from(size).map_err(|_| StoreError::OutOfRange("scan.size"))?;
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let existing: Option<(i64, String)> = tx
            .query_row(
                "SELECT id, status FROM scan WHERE content_hash = ?1",
                [content_hash],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .optional()?;
        let out = match existing {
            Some((id, status)) => Enqueued::Existing(id, parse_status(&status)?),
            None => {
                tx.execute(
                    "INSERT INTO scan (path, content_hash, size, status, created_at)
                     VALUES (?1, ?2, ?3, 'pending', ?4)",
                    params![path, content_hash, size, now_ms()],
                )?;
                Enqueued::New(tx.last_insert_rowid())
            }
        };
        tx.commit()?;
        Ok(out)
    }

    /// Take the oldest pending scan: mark it running (atomically, so two
    /// workers never get the same one) and return it. `None` when nothing
    /// is pending.
    pub fn claim_next(&mut self) -> Result<Option<Job>, StoreError> {
        let job = self
            .conn
            .query_row(
                "UPDATE scan SET status = 'running', started_at = ?1, attempts = attempts + 1
                 WHERE id = (SELECT id FROM scan WHERE status = 'pending' ORDER BY id LIMIT 1)
                 RETURNING id, path, content_hash, size, attempts",
                [now_ms()],
                read_job_row,
            )
            .optional()?;
        job.map(finish_job_row).transpose()
    }

    /// Take this particular scan if it is pending (what one-shot `classify`
    /// does with the scan it has just enqueued, leaving the rest of the
    /// queue alone). `None` when it is not pending: running elsewhere, or
    /// already finished (read it with [`Store::scan`]).
    pub fn claim(&mut self, scan_id: i64) -> Result<Option<Job>, StoreError> {
        let job = self
            .conn
            .query_row(
                "UPDATE scan SET status = 'running', started_at = ?1, attempts = attempts + 1
                 WHERE id = ?2 AND status = 'pending'
                 RETURNING id, path, content_hash, size, attempts",
                params![now_ms(), scan_id],
                read_job_row,
            )
            .optional()?;
        job.map(finish_job_row).transpose()
    }

    /// Record the identification of a running scan: status `ok`, timings,
    /// cleaning report, the per-rank results, every distance and the
    /// carried landmarks, all in ONE
    /// transaction. If anything fails (an unknown reference, a bad number,
    /// the process dies) nothing of it is recorded and the scan stays
    /// running.
    pub fn complete(&mut self, scan_id: i64, outcome: &ScanOutcome) -> Result<(), StoreError> {
        validate_outcome(outcome)?;
        let timings = to_json("scan.timings", &outcome.timings_ms)?;
        let cleaning = to_json("scan.cleaning", &outcome.cleaning)?;
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        require_status(&tx, scan_id, ScanStatus::Running, "complete", "running")?;
        {
            let mut reference_id = tx.prepare_cached(
                "SELECT id FROM reference
                 WHERE name = ?1 AND state NOT IN ('superseded', 'removed')",
            )?;
            let mut lookup = |name: &str| -> Result<i64, StoreError> {
                reference_id
                    .query_row([name], |r| r.get(0))
                    .optional()?
                    .ok_or_else(|| StoreError::UnknownReference(name.to_string()))
            };
            let mut insert_result = tx.prepare_cached(
                "INSERT INTO result
                 (scan_id, ordinal, rank, taxon, reference_id, distance, runner_up, margin)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
            )?;
            for (ordinal, r) in outcome.ranks.iter().enumerate() {
                let ref_id = lookup(&r.reference)?;
                insert_result.execute(params![
                    scan_id,
                    ordinal as i64,
                    r.rank,
                    r.taxon,
                    ref_id,
                    r.distance,
                    r.runner_up,
                    r.margin
                ])?;
            }
            let mut insert_distance = tx.prepare_cached(
                "INSERT INTO distance
                 (scan_id, reference_id, forward, backward, distance, reflected)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
            )?;
            for d in &outcome.distances {
                let ref_id = lookup(&d.reference)?;
                insert_distance.execute(params![
                    scan_id,
                    ref_id,
                    d.forward,
                    d.backward,
                    d.distance,
                    d.reflected
                ])?;
            }
            if let Some(lm) = &outcome.landmarks {
                let ref_id = lookup(&lm.reference)?;
                let mut insert_landmark = tx.prepare_cached(
                    "INSERT INTO landmark (scan_id, idx, label, x, y, z, reference_id)
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
                )?;
                for (idx, p) in lm.points.iter().enumerate() {
                    let idx =
                        i64::try_from(idx).map_err(|_| StoreError::OutOfRange("landmark.idx"))?;
                    insert_landmark
                        .execute(params![scan_id, idx, p.label, p.x, p.y, p.z, ref_id])?;
                }
            }
        }
        tx.execute(
            "UPDATE scan SET status = 'ok', error = NULL, finished_at = ?2,
                    timings = ?3, cleaning = ?4
             WHERE id = ?1",
            params![scan_id, now_ms(), timings, cleaning],
        )?;
        tx.commit()?;
        Ok(())
    }

    /// Record that a pending or running scan cannot be identified.
    pub fn fail(&mut self, scan_id: i64, message: &str) -> Result<(), StoreError> {
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let status = scan_status(&tx, scan_id)?;
        if !matches!(status, ScanStatus::Pending | ScanStatus::Running) {
            return Err(StoreError::WrongStatus {
                scan_id,
                status,
                operation: "fail",
                expected: "pending or running",
            });
        }
        tx.execute(
            "UPDATE scan SET status = 'error', error = ?2, finished_at = ?3 WHERE id = ?1",
            params![scan_id, message, now_ms()],
        )?;
        tx.commit()?;
        Ok(())
    }

    /// Give a running scan back to the queue without a result (a clean
    /// shutdown in the middle of a job): it becomes pending, and the claim
    /// does not count as a failed attempt.
    pub fn abandon(&mut self, scan_id: i64) -> Result<(), StoreError> {
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        require_status(&tx, scan_id, ScanStatus::Running, "abandon", "running")?;
        tx.execute(
            "UPDATE scan SET status = 'pending', started_at = NULL,
                    attempts = max(attempts - 1, 0)
             WHERE id = ?1",
            [scan_id],
        )?;
        tx.commit()?;
        Ok(())
    }

    /// At start-up: put every scan left `running` by a worker that died
    /// back to pending. Only one process may work a database's queue, so
    /// call this before claiming. A running scan never has results (they
    /// are committed together with `ok`); the query checks it anyway.
    /// Returns how many were requeued.
    pub fn requeue_running(&mut self) -> Result<usize, StoreError> {
        Ok(self.conn.execute(
            "UPDATE scan SET status = 'pending', started_at = NULL
             WHERE status = 'running'
               AND NOT EXISTS (SELECT 1 FROM result WHERE result.scan_id = scan.id)
               AND NOT EXISTS (SELECT 1 FROM distance WHERE distance.scan_id = scan.id)
               AND NOT EXISTS (SELECT 1 FROM landmark WHERE landmark.scan_id = scan.id)",
            [],
        )?)
    }

    /// Identify a finished scan again (after a library change, or an error
    /// that has been fixed): drop its result, distances and landmarks and make it
    /// pending, in one transaction.
    pub fn retry(&mut self, scan_id: i64) -> Result<(), StoreError> {
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let status = scan_status(&tx, scan_id)?;
        if !matches!(status, ScanStatus::Ok | ScanStatus::Error) {
            return Err(StoreError::WrongStatus {
                scan_id,
                status,
                operation: "retry",
                expected: "ok or error",
            });
        }
        tx.execute("DELETE FROM result WHERE scan_id = ?1", [scan_id])?;
        tx.execute("DELETE FROM distance WHERE scan_id = ?1", [scan_id])?;
        tx.execute("DELETE FROM landmark WHERE scan_id = ?1", [scan_id])?;
        tx.execute(
            "UPDATE scan SET status = 'pending', error = NULL, started_at = NULL,
                    finished_at = NULL, timings = NULL, cleaning = NULL
             WHERE id = ?1",
            [scan_id],
        )?;
        tx.commit()?;
        Ok(())
    }

    // ----- queries -----

    /// The scan with this id, with its result and `nearest_count` nearest
    /// references.
    pub fn scan(
        &self,
        scan_id: i64,
        nearest_count: usize,
    ) -> Result<Option<ScanRecord>, StoreError> {
        self.scan_where(
            "id = ?1",
            rusqlite::types::Value::Integer(scan_id),
            nearest_count,
        )
    }

    /// The scan of this content, if any.
    pub fn scan_by_hash(
        &self,
        content_hash: &str,
        nearest_count: usize,
    ) -> Result<Option<ScanRecord>, StoreError> {
        self.scan_where(
            "content_hash = ?1",
            rusqlite::types::Value::Text(content_hash.to_string()),
            nearest_count,
        )
    }

    /// The `n` most recently enqueued scans, newest first, each with
    /// [`DEFAULT_NEAREST`] nearest references (`morphoid results --last N`).
    /// Read in one transaction: a consistent snapshot.
    pub fn recent(&mut self, n: usize) -> Result<Vec<ScanRecord>, StoreError> {
        let limit = i64::try_from(n).unwrap_or(i64::MAX);
        let tx = self.conn.transaction()?;
        let mut out = Vec::new();
        {
            let mut stmt = tx.prepare(&format!(
                "SELECT {SCAN_COLUMNS} FROM scan ORDER BY id DESC LIMIT ?1"
            ))?;
            let rows = stmt.query_map([limit], read_scan_row)?;
            for row in rows {
                let mut record = finish_scan_row(row?)?;
                load_result(&tx, &mut record, DEFAULT_NEAREST)?;
                out.push(record);
            }
        }
        tx.commit()?;
        Ok(out)
    }

    /// Number of scans in each status.
    pub fn counts(&self) -> Result<StatusCounts, StoreError> {
        let mut stmt = self
            .conn
            .prepare("SELECT status, count(*) FROM scan GROUP BY status")?;
        let rows = stmt.query_map([], |r| Ok((r.get::<_, String>(0)?, r.get::<_, i64>(1)?)))?;
        let mut counts = StatusCounts::default();
        for row in rows {
            let (status, n) = row?;
            let n = u64::try_from(n).unwrap_or(0);
            match parse_status(&status)? {
                ScanStatus::Pending => counts.pending = n,
                ScanStatus::Running => counts.running = n,
                ScanStatus::Ok => counts.ok = n,
                ScanStatus::Error => counts.error = n,
            }
        }
        Ok(counts)
    }

    /// Number of scans finished (ok or error) at or after `since_ms`; with
    /// [`utc_day_start_ms`]`(now_ms())`, the "scans today" of a status line.
    pub fn finished_since(&self, since_ms: i64) -> Result<u64, StoreError> {
        let n: i64 = self.conn.query_row(
            "SELECT count(*) FROM scan WHERE finished_at >= ?1",
            [since_ms],
            |r| r.get(0),
        )?;
        Ok(u64::try_from(n).unwrap_or(0))
    }

    fn scan_where(
        &self,
        condition: &str,
        key: rusqlite::types::Value,
        nearest_count: usize,
    ) -> Result<Option<ScanRecord>, StoreError> {
        let row = self
            .conn
            .query_row(
                &format!("SELECT {SCAN_COLUMNS} FROM scan WHERE {condition}"),
                [key],
                read_scan_row,
            )
            .optional()?;
        let Some(row) = row else {
            return Ok(None);
        };
        let mut record = finish_scan_row(row)?;
        load_result(&self.conn, &mut record, nearest_count)?;
        Ok(Some(record))
    }
}

type JobRow = (i64, String, String, i64, i64);

fn read_job_row(r: &Row<'_>) -> rusqlite::Result<JobRow> {
    Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?))
}

fn finish_job_row(row: JobRow) -> Result<Job, StoreError> {
    let (scan_id, path, content_hash, size, attempts) = row;
    Ok(Job {
        scan_id,
        path,
        content_hash,
        size: u64::try_from(size).map_err(|_| StoreError::OutOfRange("scan.size"))?,
        attempts: u32::try_from(attempts).unwrap_or(u32::MAX),
    })
}

const SCAN_COLUMNS: &str = "id, path, content_hash, size, status, error, attempts, \
     created_at, started_at, finished_at, timings, cleaning";

/// A scan row as read, before its JSON columns are parsed.
type ScanRow = (
    i64,
    String,
    String,
    i64,
    String,
    Option<String>,
    i64,
    i64,
    Option<i64>,
    Option<i64>,
    Option<String>,
    Option<String>,
);

fn read_scan_row(r: &Row<'_>) -> rusqlite::Result<ScanRow> {
    Ok((
        r.get(0)?,
        r.get(1)?,
        r.get(2)?,
        r.get(3)?,
        r.get(4)?,
        r.get(5)?,
        r.get(6)?,
        r.get(7)?,
        r.get(8)?,
        r.get(9)?,
        r.get(10)?,
        r.get(11)?,
    ))
}

fn finish_scan_row(row: ScanRow) -> Result<ScanRecord, StoreError> {
    let (
        id,
        path,
        content_hash,
        size,
        status,
        error,
        attempts,
        created,
        started,
        finished,
        timings,
        cleaning,
    ) = row;
    Ok(ScanRecord {
        id,
        path,
        content_hash,
        size: u64::try_from(size)
            .map_err(|_| StoreError::Corrupt(format!("scan {id} size {size}")))?,
        status: parse_status(&status)?,
        error,
        attempts: u32::try_from(attempts).unwrap_or(u32::MAX),
        created_at_ms: created,
        started_at_ms: started,
        finished_at_ms: finished,
        timings_ms: match timings {
            Some(t) => from_json("scan.timings", &t)?,
            None => BTreeMap::new(),
        },
        cleaning: match cleaning {
            Some(c) => from_json("scan.cleaning", &c)?,
            None => serde_json::Value::Null,
        },
        ranks: Vec::new(),
        nearest: Vec::new(),
        landmarks: None,
    })
}

/// Fill `record.ranks` and its `nearest_count` nearest references.
fn load_result(
    conn: &Connection,
    record: &mut ScanRecord,
    nearest_count: usize,
) -> Result<(), StoreError> {
    let mut ranks = conn.prepare_cached(
        "SELECT result.rank, result.taxon, reference.name, result.distance,
                result.runner_up, result.margin
         FROM result JOIN reference ON reference.id = result.reference_id
         WHERE result.scan_id = ?1 ORDER BY result.ordinal",
    )?;
    let rows = ranks.query_map([record.id], |r| {
        Ok(RankResult {
            rank: r.get(0)?,
            taxon: r.get(1)?,
            reference: r.get(2)?,
            distance: r.get(3)?,
            runner_up: r.get(4)?,
            margin: r.get(5)?,
        })
    })?;
    record.ranks = rows.collect::<Result<_, _>>()?;
    let mut nearest = conn.prepare_cached(
        "SELECT reference.name, distance.distance
         FROM distance JOIN reference ON reference.id = distance.reference_id
         WHERE distance.scan_id = ?1 ORDER BY distance.distance, reference.name LIMIT ?2",
    )?;
    let limit = i64::try_from(nearest_count).unwrap_or(i64::MAX);
    let rows = nearest.query_map(params![record.id, limit], |r| {
        Ok(Nearest {
            reference: r.get(0)?,
            distance: r.get(1)?,
        })
    })?;
    record.nearest = rows.collect::<Result<_, _>>()?;
    let mut landmarks = conn.prepare_cached(
        "SELECT reference.name, landmark.label, landmark.x, landmark.y, landmark.z
         FROM landmark JOIN reference ON reference.id = landmark.reference_id
         WHERE landmark.scan_id = ?1 ORDER BY landmark.idx",
    )?;
    let rows = landmarks.query_map([record.id], |r| {
        Ok((
            r.get::<_, String>(0)?,
            LandmarkPoint {
                label: r.get(1)?,
                x: r.get(2)?,
                y: r.get(3)?,
                z: r.get(4)?,
            },
        ))
    })?;
    let mut carried: Option<ScanLandmarks> = None;
    for row in rows {
        let (reference, point) = row?;
        carried
            .get_or_insert_with(|| ScanLandmarks {
                reference,
                points: Vec::new(),
            })
            .points
            .push(point);
    }
    record.landmarks = carried;
    Ok(())
}

fn parse_status(s: &str) -> Result<ScanStatus, StoreError> {
    ScanStatus::parse(s).ok_or_else(|| StoreError::Corrupt(format!("scan status {s:?}")))
}

fn scan_status(conn: &Connection, scan_id: i64) -> Result<ScanStatus, StoreError> {
    let status: Option<String> = conn
        .query_row("SELECT status FROM scan WHERE id = ?1", [scan_id], |r| {
            r.get(0)
        })
        .optional()?;
    match status {
        Some(s) => parse_status(&s),
        None => Err(StoreError::NoSuchScan(scan_id)),
    }
}

fn require_status(
    conn: &Connection,
    scan_id: i64,
    wanted: ScanStatus,
    operation: &'static str,
    expected: &'static str,
) -> Result<(), StoreError> {
    let status = scan_status(conn, scan_id)?;
    if status != wanted {
        return Err(StoreError::WrongStatus {
            scan_id,
            status,
            operation,
            expected,
        });
    }
    Ok(())
}

/// Reject NaN, infinities and negative distances before anything is written.
fn validate_outcome(outcome: &ScanOutcome) -> Result<(), StoreError> {
    let check = |field: String, value: f64, nonnegative: bool| {
        if value.is_finite() && (!nonnegative || value >= 0.0) {
            Ok(())
        } else {
            Err(StoreError::InvalidNumber { field, value })
        }
    };
    for r in &outcome.ranks {
        check(format!("{} distance", r.rank), r.distance, true)?;
        if let Some(m) = r.margin {
            check(format!("{} margin", r.rank), m, true)?;
        }
    }
    for d in &outcome.distances {
        check(
            format!("forward distance to {}", d.reference),
            d.forward,
            true,
        )?;
        check(
            format!("backward distance to {}", d.reference),
            d.backward,
            true,
        )?;
        check(format!("distance to {}", d.reference), d.distance, true)?;
    }
    for (stage, &ms) in &outcome.timings_ms {
        check(format!("timing {stage}"), ms, true)?;
    }
    if let Some(lm) = &outcome.landmarks {
        for (i, p) in lm.points.iter().enumerate() {
            for (axis, v) in [("x", p.x), ("y", p.y), ("z", p.z)] {
                check(format!("landmark {i} {axis}"), v, false)?;
            }
        }
    }
    Ok(())
}

fn to_json<T: serde::Serialize>(column: &'static str, value: &T) -> Result<String, StoreError> {
    serde_json::to_string(value).map_err(|source| StoreError::Json { column, source })
}

fn from_json<T: serde::de::DeserializeOwned>(
    column: &'static str,
    text: &str,
) -> Result<T, StoreError> {
    serde_json::from_str(text).map_err(|source| StoreError::Json { column, source })
}
