//! Curators' decisions on scans: the append-only audit trail of
//! migration 8. A decision is recorded in one immediate transaction that
//! reads the scan and the scan's latest decision and appends the next one,
//! so decisions taken at once by two curators are both kept, in the order
//! SQLite serialised them, each pointing at the one before it.

use super::results::{load_result, scan_from_row, SCAN_COLUMNS};
use super::{from_json, now_ms, to_json, ScanStatus, Store, StoreError};
use rusqlite::{params, Connection, OptionalExtension, Row, TransactionBehavior};
use serde::Serialize;
use std::collections::BTreeMap;

/// Longest comment kept with a decision, in characters.
pub(super) const MAX_COMMENT_CHARS: usize = 2000;

/// Longest rank or taxon name in a correction, in characters.
pub(super) const MAX_TAXON_CHARS: usize = 200;

/// What a curator decided about a scan's identification.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Decision {
    /// The identification is right, at every rank.
    Confirm,
    /// The right taxon per rank (the ranks given; others unchanged).
    Correct(BTreeMap<String, String>),
    /// The scan is unusable (not a tooth, broken, wrong specimen).
    Reject,
}

impl Decision {
    /// The name stored and shown: `confirm`, `correct` or `reject`.
    pub fn as_str(&self) -> &'static str {
        match self {
            Decision::Confirm => "confirm",
            Decision::Correct(_) => "correct",
            Decision::Reject => "reject",
        }
    }
}

/// A decision to record.
#[derive(Debug, Clone)]
pub struct NewReview<'a> {
    /// The scan decided on.
    pub scan_id: i64,
    /// Who decided (a curator's name, or the command line's user).
    pub curator: &'a str,
    /// What.
    pub decision: Decision,
    /// Why, in the curator's words.
    pub comment: Option<&'a str>,
    /// The id of the decision the curator saw as the scan's latest
    /// (`Some(None)`: none): when another was recorded meanwhile, nothing
    /// is recorded and [`ReviewError::Conflict`] says which. `None`: no check.
    pub expected_latest: Option<Option<i64>>,
    /// The ranks a correction may name (empty: any).
    pub ranks: &'a [String],
}

/// A recorded decision.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReviewRecord {
    /// The decision's id (increasing over the whole table).
    pub id: i64,
    /// The scan decided on.
    pub scan_id: i64,
    /// Its place among the scan's decisions (1, 2, …).
    pub seq: i64,
    /// The scan's decision before it (`None` for the first).
    pub previous_id: Option<i64>,
    /// Who decided.
    pub curator: String,
    /// When (Unix milliseconds).
    pub decided_at_ms: i64,
    /// `confirm`, `correct` or `reject`.
    pub decision: String,
    /// The taxon per rank confirmed or given (empty for a rejection).
    pub taxa: BTreeMap<String, String>,
    /// What the identification said when the decision was taken.
    pub identified: BTreeMap<String, String>,
    /// Why, in the curator's words.
    pub comment: Option<String>,
    /// The content decided on (the scan's hash then).
    pub content_hash: String,
    /// The scan's file then.
    pub path: String,
}

/// Why a decision was not recorded.
#[derive(Debug, thiserror::Error)]
pub enum ReviewError {
    /// No scan has this id.
    #[error("no scan with id {0}")]
    NoSuchScan(i64),
    /// The scan cannot be decided on (not finished, superseded, or a scan
    /// of several specimens, whose specimens are decided on one by one).
    #[error("scan {scan_id} cannot be reviewed: {why}")]
    NotReviewable {
        /// The scan.
        scan_id: i64,
        /// Why.
        why: String,
    },
    /// A confirmation of a scan without an identification.
    #[error("scan {0} has no identification to confirm (correct or reject it instead)")]
    NothingToConfirm(i64),
    /// A correction without taxa, with an unknown rank, or with names out
    /// of bounds; or a comment too long.
    #[error("{0}")]
    Invalid(String),
    /// Another decision was recorded since the one the curator saw.
    #[error(
        "scan {scan_id} was reviewed meanwhile: its latest decision is {} (expected {})",
        latest.map_or("none".to_string(), |l| format!("#{l}")),
        expected.map_or("none".to_string(), |l| format!("#{l}"))
    )]
    Conflict {
        /// The scan.
        scan_id: i64,
        /// The latest decision the curator expected.
        expected: Option<i64>,
        /// The latest decision recorded.
        latest: Option<i64>,
    },
    /// The database failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

impl From<rusqlite::Error> for ReviewError {
    fn from(e: rusqlite::Error) -> Self {
        ReviewError::Store(e.into())
    }
}

/// The `review` columns [`review_from_row`] reads.
const REVIEW_COLUMNS: &str = "id, scan_id, seq, previous_id, curator, decided_at, decision, \
     taxa, identified, comment, content_hash, path";

impl Store {
    /// Append a curator's decision on a scan to the audit trail and return
    /// it as recorded. Checked in the same transaction: the scan exists
    /// and is finished, a confirmation has an identification to confirm,
    /// a correction names known ranks, and (when asked) no other decision
    /// came first.
    pub fn record_review(&mut self, review: &NewReview<'_>) -> Result<ReviewRecord, ReviewError> {
        let taxa_given = checked_decision(review)?;
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let mut scan = {
            let mut stmt =
                tx.prepare_cached(&format!("SELECT {SCAN_COLUMNS} FROM scan WHERE id = ?1"))?;
            let mut rows = stmt.query([review.scan_id])?;
            match rows.next()? {
                Some(row) => scan_from_row(row)?,
                None => return Err(ReviewError::NoSuchScan(review.scan_id)),
            }
        };
        load_result(&tx, &mut scan, 0)?;
        let not_reviewable = |why: String| ReviewError::NotReviewable {
            scan_id: review.scan_id,
            why,
        };
        match scan.status {
            ScanStatus::Pending | ScanStatus::Running => {
                return Err(not_reviewable(format!(
                    "it is {}; wait for its identification",
                    scan.status
                )))
            }
            ScanStatus::Superseded => {
                return Err(not_reviewable(format!(
                    "it is superseded by scan {}",
                    scan.superseded_by.unwrap_or_default()
                )))
            }
            ScanStatus::Ok | ScanStatus::Error | ScanStatus::Duplicate => {}
        }
        if let Some(n) = scan.specimen_count {
            let ids: Vec<String> = scan.specimens.iter().map(|s| s.id.to_string()).collect();
            return Err(not_reviewable(format!(
                "it holds {n} specimens; review each of them (scans {})",
                ids.join(", ")
            )));
        }
        let identified: BTreeMap<String, String> = scan
            .ranks
            .iter()
            .map(|r| (r.rank.clone(), r.taxon.clone()))
            .collect();
        let taxa = match &review.decision {
            Decision::Confirm if identified.is_empty() => {
                return Err(ReviewError::NothingToConfirm(review.scan_id))
            }
            Decision::Confirm => identified.clone(),
            Decision::Correct(_) | Decision::Reject => taxa_given,
        };
        let latest: Option<(i64, i64)> = tx
            .query_row(
                "SELECT id, seq FROM review WHERE scan_id = ?1 ORDER BY seq DESC LIMIT 1",
                [review.scan_id],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .optional()?;
        let latest_id = latest.map(|(id, _)| id);
        if let Some(expected) = review.expected_latest {
            if expected != latest_id {
                return Err(ReviewError::Conflict {
                    scan_id: review.scan_id,
                    expected,
                    latest: latest_id,
                });
            }
        }
        let seq = latest.map_or(1, |(_, seq)| seq + 1);
        tx.execute(
            "INSERT INTO review (scan_id, seq, previous_id, content_hash, path, curator,
                                 decided_at, decision, taxa, identified, comment)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
            params![
                review.scan_id,
                seq,
                latest_id,
                scan.content_hash,
                scan.path,
                review.curator,
                now_ms(),
                review.decision.as_str(),
                to_json("review.taxa", &taxa)?,
                to_json("review.identified", &identified)?,
                review.comment,
            ],
        )?;
        let id = tx.last_insert_rowid();
        let record = review_where(&tx, "id = ?1", id)?
            .into_iter()
            .next()
            .ok_or_else(|| StoreError::Corrupt(format!("review {id} vanished")))?;
        tx.commit()?;
        Ok(record)
    }

    /// Every decision on a scan, first to last.
    pub fn reviews_of(&self, scan_id: i64) -> Result<Vec<ReviewRecord>, StoreError> {
        review_where(&self.conn, "scan_id = ?1 ORDER BY seq", scan_id)
    }

    /// The latest decision on a scan, if any.
    pub fn latest_review(&self, scan_id: i64) -> Result<Option<ReviewRecord>, StoreError> {
        Ok(review_where(
            &self.conn,
            "scan_id = ?1 ORDER BY seq DESC LIMIT 1",
            scan_id,
        )?
        .into_iter()
        .next())
    }

    /// How many decisions of each kind were recorded.
    pub fn review_counts(&self) -> Result<BTreeMap<String, u64>, StoreError> {
        let mut stmt = self
            .conn
            .prepare("SELECT decision, count(*) AS n FROM review GROUP BY decision")?;
        let rows = stmt.query_map([], |r| {
            Ok((
                r.get::<_, String>("decision")?,
                u64::try_from(r.get::<_, i64>("n")?).unwrap_or(0),
            ))
        })?;
        Ok(rows.collect::<Result<_, _>>()?)
    }
}

/// The decision's taxa (a correction's, checked; empty otherwise), and
/// the comment checked.
fn checked_decision(review: &NewReview<'_>) -> Result<BTreeMap<String, String>, ReviewError> {
    if review.curator.trim().is_empty() {
        return Err(ReviewError::Invalid("a decision needs a curator".into()));
    }
    if review
        .comment
        .is_some_and(|c| c.chars().count() > MAX_COMMENT_CHARS)
    {
        return Err(ReviewError::Invalid(format!(
            "the comment is longer than {MAX_COMMENT_CHARS} characters"
        )));
    }
    let Decision::Correct(taxa) = &review.decision else {
        return Ok(BTreeMap::new());
    };
    if taxa.is_empty() {
        return Err(ReviewError::Invalid(
            "a correction names a taxon for at least one rank".into(),
        ));
    }
    for (rank, taxon) in taxa {
        let plain = |s: &str| {
            !s.trim().is_empty()
                && s.chars().count() <= MAX_TAXON_CHARS
                && !s.chars().any(char::is_control)
        };
        if !plain(rank) || !plain(taxon) {
            return Err(ReviewError::Invalid(format!(
                "{rank:?} = {taxon:?}: ranks and taxa are 1 to {MAX_TAXON_CHARS} characters \
                 without control characters"
            )));
        }
        if !review.ranks.is_empty() && !review.ranks.iter().any(|r| r == rank) {
            return Err(ReviewError::Invalid(format!(
                "unknown rank {rank:?} (the library's ranks: {})",
                review.ranks.join(", ")
            )));
        }
    }
    Ok(taxa.clone())
}

/// The decisions that `condition` (on `?1` = `key`) selects, in its order.
fn review_where(
    conn: &Connection,
    condition: &str,
    key: i64,
) -> Result<Vec<ReviewRecord>, StoreError> {
    let mut stmt = conn.prepare_cached(&format!(
        "SELECT {REVIEW_COLUMNS} FROM review WHERE {condition}"
    ))?;
    let mut rows = stmt.query([key])?;
    let mut out = Vec::new();
    while let Some(row) = rows.next()? {
        out.push(review_from_row(row)?);
    }
    Ok(out)
}

/// A `review` row ([`REVIEW_COLUMNS`]) as a record.
fn review_from_row(r: &Row<'_>) -> Result<ReviewRecord, StoreError> {
    let taxa: String = r.get("taxa")?;
    let identified: String = r.get("identified")?;
    Ok(ReviewRecord {
        id: r.get("id")?,
        scan_id: r.get("scan_id")?,
        seq: r.get("seq")?,
        previous_id: r.get("previous_id")?,
        curator: r.get("curator")?,
        decided_at_ms: r.get("decided_at")?,
        decision: r.get("decision")?,
        taxa: from_json("review.taxa", &taxa)?,
        identified: from_json("review.identified", &identified)?,
        comment: r.get("comment")?,
        content_hash: r.get("content_hash")?,
        path: r.get("path")?,
    })
}
