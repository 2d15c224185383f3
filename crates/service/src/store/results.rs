//! Reading scans back with their results: one scan, the most recent
//! ones, and the counts behind a status line.

use super::{
    from_json, parse_status, Original, ScanRecord, ScanStatus, StatusCounts, Store, StoreError,
    DEFAULT_NEAREST,
};
use crate::identify::{Confidence, LandmarkPoint, Nearest, RankResult, ScanLandmarks};
use rusqlite::types::Value;
use rusqlite::{params, Connection, Row};
use std::collections::BTreeMap;

/// The `scan` columns [`scan_from_row`] reads.
pub(super) const SCAN_COLUMNS: &str = "id, path, content_hash, size, status, error, attempts, \
     created_at, started_at, finished_at, timings, cleaning, duplicate_of, files_error, \
     calibrating, superseded_by, parent_id, specimen, position, specimens";

impl Store {
    /// The scan with this id, with its result and `nearest_count` nearest
    /// references.
    pub fn scan(
        &self,
        scan_id: i64,
        nearest_count: usize,
    ) -> Result<Option<ScanRecord>, StoreError> {
        scan_where(
            &self.conn,
            "id = ?1",
            Value::Integer(scan_id),
            nearest_count,
        )
    }

    /// The scan of this content, if any.
    pub fn scan_by_hash(
        &self,
        content_hash: &str,
        nearest_count: usize,
    ) -> Result<Option<ScanRecord>, StoreError> {
        // The content's own row, not a duplicate or superseded one.
        scan_where(
            &self.conn,
            "content_hash = ?1 AND status NOT IN ('duplicate', 'superseded') AND parent_id IS NULL",
            Value::Text(content_hash.to_string()),
            nearest_count,
        )
    }

    /// The `n` most recently enqueued scans, newest first, each with
    /// [`DEFAULT_NEAREST`] nearest references (`morphoid results --last N`);
    /// a scan of several specimens carries them in
    /// [`ScanRecord::specimens`] (they are not counted among the `n`).
    /// Read in one transaction: a consistent snapshot.
    pub fn recent(&mut self, n: usize) -> Result<Vec<ScanRecord>, StoreError> {
        let limit = i64::try_from(n).unwrap_or(i64::MAX);
        let tx = self.conn.transaction()?;
        let mut out = Vec::new();
        {
            let mut stmt = tx.prepare(&format!(
                "SELECT {SCAN_COLUMNS} FROM scan WHERE parent_id IS NULL ORDER BY id DESC LIMIT ?1"
            ))?;
            let mut rows = stmt.query([limit])?;
            while let Some(row) = rows.next()? {
                let mut record = scan_from_row(row)?;
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
            .prepare("SELECT status, count(*) AS n FROM scan GROUP BY status")?;
        let mut rows = stmt.query([])?;
        let mut counts = StatusCounts::default();
        while let Some(row) = rows.next()? {
            let status: String = row.get("status")?;
            let n = u64::try_from(row.get::<_, i64>("n")?).unwrap_or(0);
            match parse_status(&status)? {
                ScanStatus::Pending => counts.pending = n,
                ScanStatus::Running => counts.running = n,
                ScanStatus::Ok => counts.ok = n,
                ScanStatus::Error => counts.error = n,
                ScanStatus::Duplicate => counts.duplicate = n,
                ScanStatus::Superseded => counts.superseded = n,
            }
        }
        Ok(counts)
    }

    /// Number of scans finished (ok or error) at or after `since_ms`; with
    /// [`utc_day_start_ms`](super::utc_day_start_ms)`(now_ms())`, the
    /// "scans today" of a status line.
    pub fn finished_since(&self, since_ms: i64) -> Result<u64, StoreError> {
        let n: i64 = self.conn.query_row(
            "SELECT count(*) FROM scan WHERE finished_at >= ?1 AND status <> 'superseded'",
            [since_ms],
            |r| r.get(0),
        )?;
        Ok(u64::try_from(n).unwrap_or(0))
    }
}

/// The scan that `condition` (on `?1` = `key`) selects, with its result.
fn scan_where(
    conn: &Connection,
    condition: &str,
    key: Value,
    nearest_count: usize,
) -> Result<Option<ScanRecord>, StoreError> {
    let mut stmt = conn.prepare_cached(&format!(
        "SELECT {SCAN_COLUMNS} FROM scan WHERE {condition}"
    ))?;
    let mut rows = stmt.query([key])?;
    let Some(row) = rows.next()? else {
        return Ok(None);
    };
    let mut record = scan_from_row(row)?;
    load_result(conn, &mut record, nearest_count)?;
    Ok(Some(record))
}

/// A `scan` row ([`SCAN_COLUMNS`]) as a record, without its result.
pub(super) fn scan_from_row(r: &Row<'_>) -> Result<ScanRecord, StoreError> {
    let id: i64 = r.get("id")?;
    let size: i64 = r.get("size")?;
    let status: String = r.get("status")?;
    let attempts: i64 = r.get("attempts")?;
    let timings: Option<String> = r.get("timings")?;
    let cleaning: Option<String> = r.get("cleaning")?;
    Ok(ScanRecord {
        id,
        path: r.get("path")?,
        content_hash: r.get("content_hash")?,
        size: u64::try_from(size)
            .map_err(|_| StoreError::Corrupt(format!("scan {id} size {size}")))?,
        status: parse_status(&status)?,
        error: r.get("error")?,
        attempts: u32::try_from(attempts).unwrap_or(u32::MAX),
        created_at_ms: r.get("created_at")?,
        started_at_ms: r.get("started_at")?,
        finished_at_ms: r.get("finished_at")?,
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
        duplicate_of: r.get::<_, Option<i64>>("duplicate_of")?.map(|id| Original {
            id,
            path: String::new(),
            status: ScanStatus::Pending,
        }),
        files_error: r.get("files_error")?,
        calibrating: r.get("calibrating")?,
        superseded_by: r.get("superseded_by")?,
        parent: r.get("parent_id")?,
        specimen: r
            .get::<_, Option<i64>>("specimen")?
            .and_then(|n| u32::try_from(n).ok()),
        position: match r.get::<_, Option<String>>("position")? {
            Some(p) => Some(from_json("scan.position", &p)?),
            None => None,
        },
        specimen_count: r
            .get::<_, Option<i64>>("specimens")?
            .and_then(|n| u32::try_from(n).ok()),
        specimens: Vec::new(),
    })
}

/// The specimens' rows of the scan `parent`, in their order, each with its
/// result.
fn specimens_of(
    conn: &Connection,
    parent: i64,
    nearest_count: usize,
) -> Result<Vec<ScanRecord>, StoreError> {
    let mut stmt = conn.prepare_cached(&format!(
        "SELECT {SCAN_COLUMNS} FROM scan WHERE parent_id = ?1 ORDER BY specimen"
    ))?;
    let mut rows = stmt.query([parent])?;
    let mut out = Vec::new();
    while let Some(row) = rows.next()? {
        let mut record = scan_from_row(row)?;
        load_result(conn, &mut record, nearest_count)?;
        out.push(record);
    }
    Ok(out)
}

/// Fill `record`'s ranks, its `nearest_count` nearest references and its
/// carried landmarks; a duplicate's are those of the earlier scan it points
/// at, whose path, status and error it gets too.
pub(super) fn load_result(
    conn: &Connection,
    record: &mut ScanRecord,
    nearest_count: usize,
) -> Result<(), StoreError> {
    let mut of = record.id;
    if let Some(original) = &mut record.duplicate_of {
        let (path, status, error, calibrating): (String, String, Option<String>, bool) = conn
            .prepare_cached("SELECT path, status, error, calibrating FROM scan WHERE id = ?1")?
            .query_row([original.id], |r| {
                Ok((
                    r.get("path")?,
                    r.get("status")?,
                    r.get("error")?,
                    r.get("calibrating")?,
                ))
            })?;
        original.path = path;
        original.status = parse_status(&status)?;
        record.error = error;
        record.calibrating = calibrating;
        of = original.id;
    }
    record.ranks = ranks_of(conn, of)?;
    record.nearest = nearest_of(conn, of, nearest_count)?;
    record.landmarks = landmarks_of(conn, of)?;
    // A duplicate of a scan of several specimens carries them too.
    let count: Option<i64> = if of == record.id {
        record.specimen_count.map(i64::from)
    } else {
        conn.prepare_cached("SELECT specimens FROM scan WHERE id = ?1")?
            .query_row([of], |r| r.get(0))?
    };
    if count.is_some() {
        record.specimens = specimens_of(conn, of, nearest_count)?;
    }
    Ok(())
}

/// The per-rank results of a scan, broadest rank first.
fn ranks_of(conn: &Connection, scan_id: i64) -> Result<Vec<RankResult>, StoreError> {
    let mut stmt = conn.prepare_cached(
        "SELECT result.rank AS rank, result.taxon AS taxon, reference.name AS reference,
                result.distance AS distance, result.runner_up AS runner_up,
                result.margin AS margin, result.probability AS probability,
                result.novelty AS novelty, result.novelty_threshold AS novelty_threshold,
                result.no_close_match AS no_close_match
         FROM result JOIN reference ON reference.id = result.reference_id
         WHERE result.scan_id = ?1 ORDER BY result.ordinal",
    )?;
    let rows = stmt.query_map([scan_id], |r| {
        Ok(RankResult {
            rank: r.get("rank")?,
            taxon: r.get("taxon")?,
            reference: r.get("reference")?,
            distance: r.get("distance")?,
            runner_up: r.get("runner_up")?,
            margin: r.get("margin")?,
            confidence: confidence_from_row(r)?,
        })
    })?;
    Ok(rows.collect::<Result<_, _>>()?)
}

/// The `count` nearest references of a scan, nearest first (ties by name).
fn nearest_of(conn: &Connection, scan_id: i64, count: usize) -> Result<Vec<Nearest>, StoreError> {
    // The limit is written into the statement, not bound: SQLite plans with
    // a bound LIMIT's value and so prepares the statement again at every
    // new binding (half of this function's time went to the parser). One
    // cached statement per count; the count is a number.
    let limit = i64::try_from(count).unwrap_or(i64::MAX);
    let mut stmt = conn.prepare_cached(&format!(
        "SELECT reference.name AS reference, distance.distance AS distance
         FROM distance JOIN reference ON reference.id = distance.reference_id
         WHERE distance.scan_id = ?1 ORDER BY distance.distance, reference.name LIMIT {limit}"
    ))?;
    let rows = stmt.query_map(params![scan_id], |r| {
        Ok(Nearest {
            reference: r.get("reference")?,
            distance: r.get("distance")?,
        })
    })?;
    Ok(rows.collect::<Result<_, _>>()?)
}

/// The landmarks carried onto a scan, in the reference file's order.
fn landmarks_of(conn: &Connection, scan_id: i64) -> Result<Option<ScanLandmarks>, StoreError> {
    let mut stmt = conn.prepare_cached(
        "SELECT reference.name AS reference, landmark.label AS label,
                landmark.x AS x, landmark.y AS y, landmark.z AS z
         FROM landmark JOIN reference ON reference.id = landmark.reference_id
         WHERE landmark.scan_id = ?1 ORDER BY landmark.idx",
    )?;
    let mut rows = stmt.query([scan_id])?;
    let mut carried: Option<ScanLandmarks> = None;
    while let Some(r) = rows.next()? {
        let point = LandmarkPoint {
            label: r.get("label")?,
            x: r.get("x")?,
            y: r.get("y")?,
            z: r.get("z")?,
        };
        match &mut carried {
            Some(lm) => lm.points.push(point),
            None => {
                carried = Some(ScanLandmarks {
                    reference: r.get("reference")?,
                    points: vec![point],
                })
            }
        }
    }
    Ok(carried)
}

/// The confidence columns of a `result` row (all null when the library
/// was not calibrated, or the result predates migration 4).
fn confidence_from_row(r: &Row<'_>) -> rusqlite::Result<Option<Confidence>> {
    let probability: Option<f64> = r.get("probability")?;
    let novelty: Option<f64> = r.get("novelty")?;
    Ok(match (probability, novelty) {
        (Some(probability), Some(novelty)) => Some(Confidence {
            probability,
            novelty,
            novelty_threshold: r.get("novelty_threshold")?,
            no_close_match: r.get("no_close_match")?,
        }),
        _ => None,
    })
}
