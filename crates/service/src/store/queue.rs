//! Scans as jobs: `pending` → `running` → `ok` | `error`. A scan is
//! queued once per content, claimed atomically, and finished with its
//! whole result in one transaction, so a scan with a result is never
//! run again and a crash leaves nothing half recorded.

use super::{now_ms, parse_status, to_json, Enqueued, Job, ScanStatus, Store, StoreError};
use crate::identify::{ScanOutcome, SpecimenOutcome, SpecimensOutcome};
use rusqlite::{params, Connection, OptionalExtension, Row, TransactionBehavior};

/// The columns a claim returns, in [`job_from_row`]'s terms.
const JOB_COLUMNS: &str = "id, path, content_hash, size, attempts";

impl Store {
    /// Add a pending scan for the file at `path` with this content. Content
    /// already known is not identified again: the same file (the content's
    /// scan at this path, or a duplicate row of it) returns the existing
    /// row, whatever its status; the same content at another path gets its
    /// own row with status `duplicate`, pointing at the earlier scan (use
    /// [`Store::retry`] to identify the content again). A changed file has
    /// a new hash and is enqueued.
    pub fn enqueue(
        &mut self,
        path: &str,
        content_hash: &str,
        size: u64,
    ) -> Result<Enqueued, StoreError> {
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let out = enqueue_in(&tx, path, content_hash, size, self.result_files)?;
        tx.commit()?;
        Ok(out)
    }

    /// Take the oldest pending scan: mark it running (atomically, so two
    /// workers never get the same one) and return it once the claim has
    /// committed: a job is never worked on under a claim that did not
    /// reach the database. `None` when nothing is pending.
    pub fn claim_next(&mut self) -> Result<Option<Job>, StoreError> {
        self.claim_where(
            "(SELECT id FROM scan WHERE status = 'pending' ORDER BY id LIMIT 1)",
            None,
        )
    }

    /// Take this particular scan if it is pending (what one-shot `classify`
    /// does with the scan it has just enqueued, leaving the rest of the
    /// queue alone), once the claim has committed. `None` when it is not
    /// pending: running elsewhere, or already finished (read it with
    /// [`Store::scan`]).
    pub fn claim(&mut self, scan_id: i64) -> Result<Option<Job>, StoreError> {
        self.claim_where("?2 AND status = 'pending'", Some(scan_id))
    }

    /// Mark the scan `id = <target>` running in its own transaction and
    /// return it after the commit. The row is read to the end inside the
    /// transaction: an `UPDATE … RETURNING` whose implicit commit fails
    /// (a full disk, an I/O error) would otherwise hand out a job whose
    /// claim never happened.
    fn claim_where(
        &mut self,
        target: &str,
        scan_id: Option<i64>,
    ) -> Result<Option<Job>, StoreError> {
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let job = {
            let mut stmt = tx.prepare(&format!(
                "UPDATE scan SET status = 'running', started_at = ?1, attempts = attempts + 1
                 WHERE id = {target}
                 RETURNING {JOB_COLUMNS}"
            ))?;
            let mut rows = match scan_id {
                Some(id) => stmt.query(params![now_ms(), id])?,
                None => stmt.query(params![now_ms()])?,
            };
            let job = rows.next()?.map(job_from_row).transpose()?;
            while rows.next()?.is_some() {}
            job
        };
        tx.commit()?;
        Ok(job)
    }

    /// Record the identification of a running scan: status `ok`, timings,
    /// cleaning report, the per-rank results, every distance and the
    /// carried landmarks, all in ONE transaction. If anything fails (an
    /// unknown reference, a bad number, the process dies) nothing of it is
    /// recorded and the scan stays running.
    pub fn complete(&mut self, scan_id: i64, outcome: &ScanOutcome) -> Result<(), StoreError> {
        validate_outcome(outcome)?;
        let timings = to_json("scan.timings", &outcome.timings_ms)?;
        let cleaning = to_json("scan.cleaning", &outcome.cleaning)?;
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        require_status(&tx, scan_id, ScanStatus::Running, "complete", "running")?;
        insert_outcome(&tx, scan_id, outcome)?;
        tx.execute(
            "UPDATE scan SET status = 'ok', error = NULL, finished_at = ?2,
                    timings = ?3, cleaning = ?4, files_due = ?5, calibrating = ?6
             WHERE id = ?1",
            params![
                scan_id,
                now_ms(),
                timings,
                cleaning,
                self.result_files,
                outcome.calibrating
            ],
        )?;
        tx.commit()?;
        Ok(())
    }

    /// Record the identification of a running scan of several specimens,
    /// all in ONE transaction: a row `<scan>#n` for each specimen (its
    /// number, position, and its result like [`Store::complete`]'s, or
    /// its error), and the scan's own row `ok` (with the number of
    /// specimens and the segmentation) when at least one specimen was
    /// identified, else `error`.
    pub fn complete_specimens(
        &mut self,
        scan_id: i64,
        outcome: &SpecimensOutcome,
    ) -> Result<(), StoreError> {
        validate_specimens(outcome)?;
        let count = outcome.specimens.len();
        let timings = to_json("scan.timings", &outcome.timings_ms)?;
        let segmentation = to_json("scan.cleaning", &outcome.segmentation)?;
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        require_status(&tx, scan_id, ScanStatus::Running, "complete", "running")?;
        let parent = ParentScan::read(&tx, scan_id)?;
        let now = now_ms();
        let mut errors = Vec::new();
        for (i, s) in outcome.specimens.iter().enumerate() {
            let n = i + 1;
            if let Some(e) = insert_specimen(&tx, &parent, n, s, now, self.result_files)? {
                errors.push(format!("#{n}: {e}"));
            }
        }
        let error = (errors.len() == count).then(|| {
            format!(
                "none of its {count} specimens could be identified: {}",
                errors.join("; ")
            )
        });
        tx.execute(
            "UPDATE scan SET status = ?2, error = ?3, finished_at = ?4, timings = ?5,
                    cleaning = ?6, files_due = ?7, specimens = ?8
             WHERE id = ?1",
            params![
                scan_id,
                if error.is_some() { "error" } else { "ok" },
                error,
                now,
                timings,
                segmentation,
                self.result_files,
                count as i64
            ],
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
            "UPDATE scan SET status = 'error', error = ?2, finished_at = ?3, files_due = ?4
             WHERE id = ?1",
            params![scan_id, message, now_ms(), self.result_files],
        )?;
        tx.commit()?;
        Ok(())
    }

    /// Record that when the running scan `scan_id` was read, its file held
    /// other content (`content_hash`, `size` bytes) than the one queued:
    /// the queued content is not identified. In one transaction the content
    /// read is queued at the scan's path (as [`Store::enqueue`] would: a
    /// new pending row, the row it already has, or a `duplicate`), and the
    /// scan ends `superseded`, pointing at that row. Returns what the
    /// queueing did.
    pub fn supersede(
        &mut self,
        scan_id: i64,
        content_hash: &str,
        size: u64,
    ) -> Result<Enqueued, StoreError> {
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        require_status(&tx, scan_id, ScanStatus::Running, "supersede", "running")?;
        let (path, queued): (String, String) = tx.query_row(
            "SELECT path, content_hash FROM scan WHERE id = ?1",
            [scan_id],
            |r| Ok((r.get("path")?, r.get("content_hash")?)),
        )?;
        if queued == content_hash {
            return Err(StoreError::WrongStatus {
                scan_id,
                status: ScanStatus::Running,
                operation: "supersede with its own content",
                expected: "other content",
            });
        }
        let newer = enqueue_in(&tx, &path, content_hash, size, self.result_files)?;
        tx.execute(
            "UPDATE scan SET status = 'superseded', superseded_by = ?2, finished_at = ?3
             WHERE id = ?1",
            params![scan_id, newer.scan_id(), now_ms()],
        )?;
        tx.commit()?;
        Ok(newer)
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
        self.requeue_running_but(None)
    }

    /// [`Store::requeue_running`], but for the scan `held` (the one the
    /// worker holds a finding for): after a storage fault, a claim whose
    /// commit was reported failed may still have reached the file, and
    /// would stay running for good.
    pub fn requeue_running_but(&mut self, held: Option<i64>) -> Result<usize, StoreError> {
        Ok(self.conn.execute(
            "UPDATE scan SET status = 'pending', started_at = NULL
             WHERE status = 'running' AND id IS NOT ?1
               AND NOT EXISTS (SELECT 1 FROM result WHERE result.scan_id = scan.id)
               AND NOT EXISTS (SELECT 1 FROM distance WHERE distance.scan_id = scan.id)
               AND NOT EXISTS (SELECT 1 FROM landmark WHERE landmark.scan_id = scan.id)",
            [held],
        )?)
    }

    /// Identify a finished scan again (after a library change, or an error
    /// that has been fixed): drop its result, distances and landmarks and
    /// make it pending, in one transaction.
    pub fn retry(&mut self, scan_id: i64) -> Result<(), StoreError> {
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        // A specimen is identified again with its scan.
        let parent: Option<i64> = tx
            .query_row("SELECT parent_id FROM scan WHERE id = ?1", [scan_id], |r| {
                r.get(0)
            })
            .optional()?
            .flatten();
        let scan_id = parent.unwrap_or(scan_id);
        let status = scan_status(&tx, scan_id)?;
        if !matches!(status, ScanStatus::Ok | ScanStatus::Error) {
            return Err(StoreError::WrongStatus {
                scan_id,
                status,
                operation: "retry",
                expected: "ok or error",
            });
        }
        // A scan of several specimens is identified again as a whole: its
        // specimens' rows and their results go too.
        for table in ["result", "distance", "landmark"] {
            tx.execute(
                &format!(
                    "DELETE FROM {table} WHERE scan_id = ?1
                        OR scan_id IN (SELECT id FROM scan WHERE parent_id = ?1)"
                ),
                [scan_id],
            )?;
        }
        tx.execute("DELETE FROM scan WHERE parent_id = ?1", [scan_id])?;
        tx.execute(
            "UPDATE scan SET status = 'pending', error = NULL, started_at = NULL,
                    finished_at = NULL, timings = NULL, cleaning = NULL, calibrating = 0,
                    specimens = NULL
             WHERE id = ?1",
            [scan_id],
        )?;
        tx.commit()?;
        Ok(())
    }
}

impl Store {
    /// Up to `limit` scans whose result files are due and can be written
    /// now: finished scans, and duplicates whose earlier scan has finished
    /// (a duplicate's result is the earlier scan's). Those not tried yet
    /// come first, then those whose last attempt failed, each oldest
    /// first: a backlog of failures never keeps a new scan from being
    /// tried (and from getting its own error when the folder still fails).
    pub fn files_due(&self, limit: usize) -> Result<Vec<i64>, StoreError> {
        let limit = i64::try_from(limit).unwrap_or(i64::MAX);
        let mut stmt = self.conn.prepare_cached(
            "SELECT s.id AS id FROM scan s LEFT JOIN scan o ON o.id = s.duplicate_of
             WHERE s.files_due = 1
               AND (s.status IN ('ok', 'error') OR o.status IN ('ok', 'error'))
             ORDER BY s.files_error IS NOT NULL, s.id LIMIT ?1",
        )?;
        let ids = stmt.query_map([limit], |r| r.get("id"))?;
        Ok(ids.collect::<Result<_, _>>()?)
    }

    /// Record that the result files of scan `scan_id` are written (an
    /// earlier failure to write them is cleared).
    pub fn files_written(&mut self, scan_id: i64) -> Result<(), StoreError> {
        self.conn.execute(
            "UPDATE scan SET files_due = 0, files_error = NULL WHERE id = ?1",
            [scan_id],
        )?;
        Ok(())
    }

    /// Forget an earlier failure to write the result files of scan
    /// `scan_id` (they were written, elsewhere or by hand); whether they
    /// are due is not changed.
    pub fn clear_files_error(&mut self, scan_id: i64) -> Result<(), StoreError> {
        self.conn.execute(
            "UPDATE scan SET files_error = NULL WHERE id = ?1 AND files_error IS NOT NULL",
            [scan_id],
        )?;
        Ok(())
    }

    /// Record why the result files of scan `scan_id` could not be written
    /// (`message`, naming the file and the cause); they stay due when they
    /// were, and the identification is untouched.
    pub fn files_failed(&mut self, scan_id: i64, message: &str) -> Result<(), StoreError> {
        self.conn.execute(
            "UPDATE scan SET files_error = ?2 WHERE id = ?1 AND files_error IS NOT ?2",
            params![scan_id, message],
        )?;
        Ok(())
    }
}

/// [`Store::enqueue`] inside the transaction `tx`.
fn enqueue_in(
    tx: &Connection,
    path: &str,
    content_hash: &str,
    size: u64,
    result_files: bool,
) -> Result<Enqueued, StoreError> {
    let size = i64::try_from(size).map_err(|_| StoreError::OutOfRange("scan.size"))?;
    // A superseded row never stands for its content: that content was
    // not identified there.
    let known: Option<(i64, String, String)> = tx
        .query_row(
            "SELECT id, status, path FROM scan
             WHERE content_hash = ?1 AND status NOT IN ('duplicate', 'superseded')
               AND parent_id IS NULL",
            [content_hash],
            |r| Ok((r.get("id")?, r.get("status")?, r.get("path")?)),
        )
        .optional()?;
    let out = match known {
        Some((id, status, known_path)) if known_path == path => {
            Enqueued::Existing(id, parse_status(&status)?)
        }
        Some((of, _, _)) => {
            let again: Option<i64> = tx
                .query_row(
                    "SELECT id FROM scan
                         WHERE content_hash = ?1 AND path = ?2 AND status = 'duplicate'",
                    params![content_hash, path],
                    |r| r.get("id"),
                )
                .optional()?;
            match again {
                Some(id) => Enqueued::Existing(id, ScanStatus::Duplicate),
                None => {
                    let now = now_ms();
                    tx.execute(
                        "INSERT INTO scan (path, content_hash, size, status, created_at,
                                               finished_at, duplicate_of, files_due)
                             VALUES (?1, ?2, ?3, 'duplicate', ?4, ?4, ?5, ?6)",
                        params![path, content_hash, size, now, of, result_files],
                    )?;
                    Enqueued::Duplicate {
                        id: tx.last_insert_rowid(),
                        of,
                    }
                }
            }
        }
        None => {
            tx.execute(
                "INSERT INTO scan (path, content_hash, size, status, created_at)
                     VALUES (?1, ?2, ?3, 'pending', ?4)",
                params![path, content_hash, size, now_ms()],
            )?;
            Enqueued::New(tx.last_insert_rowid())
        }
    };
    Ok(out)
}

/// An error unless every specimen's result of `outcome` holds only
/// numbers the store takes, and it has at least two specimens.
fn validate_specimens(outcome: &SpecimensOutcome) -> Result<(), StoreError> {
    for s in &outcome.specimens {
        if let Ok(o) = &s.result {
            validate_outcome(o)?;
        }
    }
    if outcome.specimens.len() < 2 {
        return Err(StoreError::OutOfRange("scan.specimens"));
    }
    Ok(())
}

/// What the rows of a scan's specimens take from the scan's own row.
struct ParentScan {
    id: i64,
    path: String,
    content_hash: String,
    size: i64,
    started_at: Option<i64>,
}

impl ParentScan {
    /// The row of scan `scan_id`.
    fn read(conn: &Connection, scan_id: i64) -> Result<Self, StoreError> {
        Ok(conn.query_row(
            "SELECT path, content_hash, size, started_at FROM scan WHERE id = ?1",
            [scan_id],
            |r| {
                Ok(ParentScan {
                    id: scan_id,
                    path: r.get("path")?,
                    content_hash: r.get("content_hash")?,
                    size: r.get("size")?,
                    started_at: r.get("started_at")?,
                })
            },
        )?)
    }
}

/// Insert the row `<path>#n` of specimen `n` (1-based) of `parent`,
/// finished `now`, with its result when it has one; returns its error
/// message when it has none.
fn insert_specimen(
    conn: &Connection,
    parent: &ParentScan,
    n: usize,
    s: &SpecimenOutcome,
    now: i64,
    result_files: bool,
) -> Result<Option<String>, StoreError> {
    let position = to_json("scan.position", &s.position)?;
    let name = format!("{}#{n}", parent.path);
    let (status, error, timings, cleaning, calibrating) = match &s.result {
        Ok(o) => (
            "ok",
            None,
            Some(to_json("scan.timings", &o.timings_ms)?),
            Some(to_json("scan.cleaning", &o.cleaning)?),
            o.calibrating,
        ),
        Err(e) => ("error", Some(e.to_string()), None, None, false),
    };
    conn.execute(
        "INSERT INTO scan (path, content_hash, size, status, error, attempts, created_at,
                           started_at, finished_at, timings, cleaning, files_due,
                           calibrating, parent_id, specimen, position)
         VALUES (?1, ?2, ?3, ?4, ?5, 1, ?6, ?7, ?6, ?8, ?9, ?10, ?11, ?12, ?13, ?14)",
        params![
            name,
            parent.content_hash,
            parent.size,
            status,
            error,
            now,
            parent.started_at,
            timings,
            cleaning,
            result_files,
            calibrating,
            parent.id,
            n as i64,
            position
        ],
    )?;
    if let Ok(o) = &s.result {
        insert_outcome(conn, conn.last_insert_rowid(), o)?;
    }
    Ok(error)
}

/// A claimed scan row ([`JOB_COLUMNS`]) as a job.
fn job_from_row(r: &Row<'_>) -> Result<Job, StoreError> {
    let size: i64 = r.get("size")?;
    let attempts: i64 = r.get("attempts")?;
    Ok(Job {
        scan_id: r.get("id")?,
        path: r.get("path")?,
        content_hash: r.get("content_hash")?,
        size: u64::try_from(size).map_err(|_| StoreError::OutOfRange("scan.size"))?,
        attempts: u32::try_from(attempts).unwrap_or(u32::MAX),
    })
}

/// Insert the per-rank results, the distances and the carried landmarks
/// of `outcome` for `scan_id`, each naming its reference by the row id of
/// the reference's current version.
fn insert_outcome(
    conn: &Connection,
    scan_id: i64,
    outcome: &ScanOutcome,
) -> Result<(), StoreError> {
    let mut reference_id = conn.prepare_cached(
        "SELECT id FROM reference
         WHERE name = ?1 AND state NOT IN ('superseded', 'removed')",
    )?;
    let mut lookup = |name: &str| -> Result<i64, StoreError> {
        reference_id
            .query_row([name], |r| r.get("id"))
            .optional()?
            .ok_or_else(|| StoreError::UnknownReference(name.to_string()))
    };
    let mut insert_result = conn.prepare_cached(
        "INSERT INTO result
         (scan_id, ordinal, rank, taxon, reference_id, distance, runner_up, margin,
          probability, novelty, novelty_threshold, no_close_match)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)",
    )?;
    for (ordinal, r) in outcome.ranks.iter().enumerate() {
        let ordinal =
            i64::try_from(ordinal).map_err(|_| StoreError::OutOfRange("result.ordinal"))?;
        insert_result.execute(params![
            scan_id,
            ordinal,
            r.rank,
            r.taxon,
            lookup(&r.reference)?,
            r.distance,
            r.runner_up,
            r.margin,
            r.confidence.as_ref().map(|c| c.probability),
            r.confidence.as_ref().map(|c| c.novelty),
            r.confidence.as_ref().and_then(|c| c.novelty_threshold),
            r.confidence.as_ref().and_then(|c| c.no_close_match)
        ])?;
    }
    let mut insert_distance = conn.prepare_cached(
        "INSERT INTO distance
         (scan_id, reference_id, forward, backward, distance, reflected)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
    )?;
    for d in &outcome.distances {
        insert_distance.execute(params![
            scan_id,
            lookup(&d.reference)?,
            d.forward,
            d.backward,
            d.distance,
            d.reflected
        ])?;
    }
    if let Some(lm) = &outcome.landmarks {
        let ref_id = lookup(&lm.reference)?;
        let mut insert_landmark = conn.prepare_cached(
            "INSERT INTO landmark (scan_id, idx, label, x, y, z, reference_id)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
        )?;
        for (idx, p) in lm.points.iter().enumerate() {
            let idx = i64::try_from(idx).map_err(|_| StoreError::OutOfRange("landmark.idx"))?;
            insert_landmark.execute(params![scan_id, idx, p.label, p.x, p.y, p.z, ref_id])?;
        }
    }
    Ok(())
}

/// The status of scan `scan_id`.
fn scan_status(conn: &Connection, scan_id: i64) -> Result<ScanStatus, StoreError> {
    let status: Option<String> = conn
        .query_row("SELECT status FROM scan WHERE id = ?1", [scan_id], |r| {
            r.get("status")
        })
        .optional()?;
    match status {
        Some(s) => parse_status(&s),
        None => Err(StoreError::NoSuchScan(scan_id)),
    }
}

/// An error unless scan `scan_id` is `wanted`.
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

/// Reject NaN, infinities and negative distances before anything is
/// written: a check, not arithmetic.
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
        if let Some(c) = &r.confidence {
            check(format!("{} novelty", r.rank), c.novelty, false)?;
            if let Some(t) = c.novelty_threshold {
                check(format!("{} novelty threshold", r.rank), t, false)?;
            }
            if !(0.0..=1.0).contains(&c.probability) {
                return Err(StoreError::InvalidNumber {
                    field: format!("{} probability", r.rank),
                    value: c.probability,
                });
            }
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
