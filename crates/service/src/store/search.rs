//! Finding scans: filters and paging for the web console and the API, a
//! cheap fingerprint of the scan table (the console's live overview polls
//! it), and the identification times behind the metrics.

use super::results::{load_result, scan_from_row, SCAN_COLUMNS};
use super::{ScanRecord, ScanStatus, Store, StoreError, DEFAULT_NEAREST};
use rusqlite::types::Value;

/// Upper bounds (seconds) of the identification-time histogram's buckets.
pub(crate) const IDENTIFICATION_BUCKETS_S: [f64; 11] = [
    0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 60.0, 120.0, 300.0, 600.0,
];

/// Which scans to list. Every filter given must hold; a scan's taxa are its
/// own result's, its original's for a duplicate, and its specimens' for a
/// scan of several. Scans' own rows are listed (specimens inside them),
/// newest first.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ScanQuery {
    /// The row's own status.
    pub status: Option<ScanStatus>,
    /// `(rank, taxon)` pairs that the answer must name (taxon compared
    /// without regard to ASCII case).
    pub taxa: Vec<(String, String)>,
    /// `Some(true)`: flagged "no close match" at some rank; `Some(false)`:
    /// identified and flagged at no rank.
    pub no_close_match: Option<bool>,
    /// Queued at or after (Unix milliseconds).
    pub since_ms: Option<i64>,
    /// Queued before (Unix milliseconds).
    pub until_ms: Option<i64>,
    /// A piece of the file's path (without regard to ASCII case).
    pub name: Option<String>,
    /// `Some(true)`: decided on by a curator; `Some(false)`: not yet.
    pub reviewed: Option<bool>,
    /// Only scans with a smaller id (the cursor of the page before).
    pub before_id: Option<i64>,
    /// Scans skipped after the filters.
    pub offset: u64,
    /// Scans on the page.
    pub limit: usize,
}

/// A page of scans and the cursor of the next one.
#[derive(Debug, Clone)]
pub struct ScanPage {
    /// The scans, newest first, each with [`DEFAULT_NEAREST`] nearest
    /// references and its specimens.
    pub scans: Vec<ScanRecord>,
    /// `before_id` of the next page (`None`: this is the last).
    pub next_cursor: Option<i64>,
}

/// Identification times of the identified scans, as a cumulative
/// histogram over [`IDENTIFICATION_BUCKETS_S`].
#[derive(Debug, Clone, PartialEq)]
pub struct IdentificationTimes {
    /// Scans at or under each bucket's bound.
    pub buckets: Vec<u64>,
    /// All of them.
    pub count: u64,
    /// Their total, in seconds.
    pub sum_s: f64,
}

/// Where a scan's answer is recorded: its original's row for a duplicate.
const ANSWER_ROW: &str = "coalesce(scan.duplicate_of, scan.id)";

impl Store {
    /// The scans `query` selects. Read in one transaction: a consistent
    /// snapshot.
    pub fn search_scans(&mut self, query: &ScanQuery) -> Result<ScanPage, StoreError> {
        let mut conditions = vec!["scan.parent_id IS NULL".to_string()];
        let mut values: Vec<Value> = Vec::new();
        let bind = |values: &mut Vec<Value>, v: Value| {
            values.push(v);
            format!("?{}", values.len())
        };
        if let Some(status) = query.status {
            let p = bind(&mut values, Value::Text(status.as_str().into()));
            conditions.push(format!("scan.status = {p}"));
        }
        for (rank, taxon) in &query.taxa {
            let r = bind(&mut values, Value::Text(rank.clone()));
            let t = bind(&mut values, Value::Text(taxon.clone()));
            conditions.push(format!(
                "EXISTS (SELECT 1 FROM result JOIN scan AS owner ON owner.id = result.scan_id
                         WHERE result.rank = {r} AND result.taxon = {t} COLLATE NOCASE
                           AND (owner.id = {ANSWER_ROW} OR owner.parent_id = {ANSWER_ROW}))"
            ));
        }
        let flagged = |flag: &str| {
            format!(
                "EXISTS (SELECT 1 FROM result JOIN scan AS owner ON owner.id = result.scan_id
                         WHERE {flag}
                           AND (owner.id = {ANSWER_ROW} OR owner.parent_id = {ANSWER_ROW}))"
            )
        };
        match query.no_close_match {
            Some(true) => conditions.push(flagged("result.no_close_match = 1")),
            Some(false) => conditions.push(format!(
                "{} AND NOT {}",
                flagged("1"),
                flagged("result.no_close_match = 1")
            )),
            None => {}
        }
        if let Some(t) = query.since_ms {
            let p = bind(&mut values, Value::Integer(t));
            conditions.push(format!("scan.created_at >= {p}"));
        }
        if let Some(t) = query.until_ms {
            let p = bind(&mut values, Value::Integer(t));
            conditions.push(format!("scan.created_at < {p}"));
        }
        if let Some(name) = &query.name {
            let p = bind(&mut values, Value::Text(name.to_ascii_lowercase()));
            conditions.push(format!("instr(lower(scan.path), {p}) > 0"));
        }
        match query.reviewed {
            Some(true) => conditions
                .push("EXISTS (SELECT 1 FROM review WHERE review.scan_id = scan.id)".into()),
            Some(false) => conditions
                .push("NOT EXISTS (SELECT 1 FROM review WHERE review.scan_id = scan.id)".into()),
            None => {}
        }
        if let Some(before) = query.before_id {
            let p = bind(&mut values, Value::Integer(before));
            conditions.push(format!("scan.id < {p}"));
        }
        // One more than asked: whether a next page exists.
        let limit = bind(
            &mut values,
            Value::Integer(i64::try_from(query.limit.saturating_add(1)).unwrap_or(i64::MAX)),
        );
        let offset = bind(
            &mut values,
            Value::Integer(i64::try_from(query.offset).unwrap_or(i64::MAX)),
        );
        let sql = format!(
            "SELECT {SCAN_COLUMNS} FROM scan WHERE {} ORDER BY scan.id DESC LIMIT {limit} OFFSET {offset}",
            conditions.join(" AND ")
        );
        let tx = self.conn.transaction()?;
        let mut scans = Vec::new();
        {
            let mut stmt = tx.prepare(&sql)?;
            let mut rows = stmt.query(rusqlite::params_from_iter(values))?;
            while let Some(row) = rows.next()? {
                scans.push(scan_from_row(row)?);
            }
        }
        let next_cursor = if scans.len() > query.limit {
            scans.truncate(query.limit);
            scans.last().map(|s| s.id)
        } else {
            None
        };
        for record in &mut scans {
            load_result(&tx, record, DEFAULT_NEAREST)?;
        }
        tx.commit()?;
        Ok(ScanPage { scans, next_cursor })
    }

    /// A short text that changes whenever a scan is queued, claimed,
    /// finished or requeued, or a decision is recorded: the live overview
    /// reloads its rows when it does.
    pub fn changes_fingerprint(&self) -> Result<String, StoreError> {
        let (max_id, rows, finished, started, pending, running): (i64, i64, i64, i64, i64, i64) =
            self.conn.query_row(
                "SELECT coalesce(max(id), 0), count(*), coalesce(max(finished_at), 0),
                        coalesce(max(started_at), 0),
                        coalesce(sum(status = 'pending'), 0), coalesce(sum(status = 'running'), 0)
                 FROM scan",
                [],
                |r| {
                    Ok((
                        r.get(0)?,
                        r.get(1)?,
                        r.get(2)?,
                        r.get(3)?,
                        r.get(4)?,
                        r.get(5)?,
                    ))
                },
            )?;
        let review: i64 =
            self.conn
                .query_row("SELECT coalesce(max(id), 0) FROM review", [], |r| r.get(0))?;
        Ok(format!(
            "{max_id}-{rows}-{finished}-{started}-{pending}-{running}-{review}"
        ))
    }

    /// How long the identified scans took, from their claim to their
    /// result (scans' own rows).
    pub fn identification_times(&self) -> Result<IdentificationTimes, StoreError> {
        let bucket_sums: Vec<String> = IDENTIFICATION_BUCKETS_S
            .iter()
            .map(|b| format!("coalesce(sum(d <= {}), 0)", (b * 1000.0).round() as i64))
            .collect();
        let sql = format!(
            "SELECT count(*), coalesce(sum(d), 0), {} FROM
               (SELECT finished_at - started_at AS d FROM scan
                WHERE status = 'ok' AND parent_id IS NULL AND started_at IS NOT NULL
                  AND finished_at >= started_at)",
            bucket_sums.join(", ")
        );
        Ok(self.conn.query_row(&sql, [], |r| {
            let count: i64 = r.get(0)?;
            let sum_ms: i64 = r.get(1)?;
            let mut buckets = Vec::with_capacity(IDENTIFICATION_BUCKETS_S.len());
            for i in 0..IDENTIFICATION_BUCKETS_S.len() {
                buckets.push(u64::try_from(r.get::<_, i64>(i + 2)?).unwrap_or(0));
            }
            Ok(IdentificationTimes {
                buckets,
                count: u64::try_from(count).unwrap_or(0),
                sum_s: sum_ms as f64 / 1000.0,
            })
        })?)
    }

    /// Whether the scan `scan_id` is recorded (any status).
    pub fn scan_exists(&self, scan_id: i64) -> Result<bool, StoreError> {
        Ok(self.conn.query_row(
            "SELECT EXISTS (SELECT 1 FROM scan WHERE id = ?1)",
            [scan_id],
            |r| r.get(0),
        )?)
    }
}
