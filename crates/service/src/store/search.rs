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

/// The condition that `cond` (on `result`) holds for a result row of the
/// scan's answer: of the answer's row itself or of one of its specimens'
/// rows. Lookups by key (the answer's result rows, then its specimens'
/// rows), not a search of `scan` for the owner of each result: the
/// overview tries this on every scan, newest first, until its page is
/// full. A scan's own row has specimens' rows only when its `specimens`
/// is set (they are written and removed together), so the specimens are
/// looked for only then, or for a duplicate (whose original may have
/// them).
fn answer_has(cond: &str) -> String {
    format!(
        "(EXISTS (SELECT 1 FROM result WHERE result.scan_id = {ANSWER_ROW} AND {cond})
          OR ((scan.specimens IS NOT NULL OR scan.duplicate_of IS NOT NULL)
              AND EXISTS (SELECT 1 FROM scan AS part JOIN result ON result.scan_id = part.id
                          WHERE part.parent_id = {ANSWER_ROW} AND {cond})))"
    )
}

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
            conditions.push(answer_has(&format!(
                "result.rank = {r} AND result.taxon = {t} COLLATE NOCASE"
            )));
        }
        match query.no_close_match {
            Some(true) => conditions.push(answer_has("result.no_close_match = 1")),
            Some(false) => conditions.push(format!(
                "{} AND NOT {}",
                answer_has("1"),
                answer_has("result.no_close_match = 1")
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
        // One statement (one snapshot) of separate aggregates, each read
        // from an index (the largest and smallest key, the number of
        // entries, a status's range), never from the table's rows.
        let (max_id, rows, finished, started, pending, running): (i64, i64, i64, i64, i64, i64) =
            self.conn.query_row(
                "SELECT (SELECT coalesce(max(id), 0) FROM scan),
                        (SELECT count(*) FROM scan),
                        (SELECT coalesce(max(finished_at), 0) FROM scan),
                        (SELECT coalesce(max(started_at), 0) FROM scan),
                        (SELECT count(*) FROM scan WHERE status = 'pending'),
                        (SELECT count(*) FROM scan WHERE status = 'running')",
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identify::{
        Confidence, DistanceRow, RankResult, ScanOutcome, SpecimenOutcome, SpecimensOutcome,
    };
    use crate::store::Labels;
    use morphoid_core::clean::CleanError;
    use morphoid_data::pipeline::{PipelineError, Position};

    /// An identification as `genus` of `family`, flagged "no close match"
    /// or not.
    fn answer(genus: &str, family: &str, flagged: bool) -> ScanOutcome {
        let ranks = [("order", "Primates"), ("family", family), ("genus", genus)]
            .iter()
            .map(|&(rank, taxon)| RankResult {
                rank: rank.into(),
                taxon: taxon.into(),
                reference: "r1".into(),
                distance: 0.03,
                runner_up: None,
                margin: None,
                confidence: Some(Confidence {
                    probability: 0.8,
                    novelty: if flagged { 3.0 } else { 0.5 },
                    novelty_threshold: Some(1.5),
                    no_close_match: Some(flagged),
                }),
            })
            .collect();
        ScanOutcome {
            ranks,
            distances: vec![DistanceRow {
                reference: "r1".into(),
                forward: 0.03,
                backward: 0.031,
                distance: 0.03,
                reflected: false,
            }],
            ..ScanOutcome::default()
        }
    }

    fn identified(store: &mut Store, path: &str, hash: &str, out: &ScanOutcome) -> i64 {
        let id = store.enqueue(path, hash, 10).unwrap().scan_id();
        store.claim(id).unwrap().unwrap();
        store.complete(id, out).unwrap();
        id
    }

    /// The taxon and "no close match" filters find a duplicate by its
    /// original's answer and a scan of several specimens by its specimens'.
    #[test]
    fn duplicates_and_specimens_are_found_by_their_answers() {
        let dir = tempfile::tempdir().unwrap();
        let mut store = Store::open(&dir.path().join("db.sqlite")).unwrap();
        store
            .register_reference("r1", "hash-r1", &Labels::new())
            .unwrap();
        store.mark_reference_prepared("r1").unwrap();
        let ateles = identified(
            &mut store,
            "a.ply",
            "h-a",
            &answer("Ateles", "Atelidae", false),
        );
        let ateles_copy = store.enqueue("copy/a.ply", "h-a", 10).unwrap().scan_id();
        let pair = store.enqueue("pair.nrrd", "h-pair", 10).unwrap().scan_id();
        store.claim(pair).unwrap().unwrap();
        let position = Position {
            voxels: None,
            bounds: [[0.0; 3], [1.0; 3]],
        };
        let specimens = SpecimensOutcome {
            specimens: vec![
                SpecimenOutcome {
                    position: position.clone(),
                    result: Ok(answer("Cebus", "Cebidae", true)),
                },
                SpecimenOutcome {
                    position,
                    result: Err(std::sync::Arc::new(PipelineError::Clean {
                        path: "pair.nrrd".into(),
                        source: CleanError::TooFewFaces(3),
                    })),
                },
            ],
            segmentation: serde_json::json!({}),
            timings_ms: Default::default(),
        };
        store.complete_specimens(pair, &specimens).unwrap();
        // A specimen's failure is recorded as its error's message.
        let recorded = store.scan(pair, 1).unwrap().unwrap();
        let errors: Vec<Option<&str>> = recorded
            .specimens
            .iter()
            .map(|s| s.error.as_deref())
            .collect();
        assert_eq!(
            errors,
            [None, Some("pair.nrrd: too few faces (3) to form a surface")]
        );
        let pair_copy = store
            .enqueue("copy/pair.nrrd", "h-pair", 10)
            .unwrap()
            .scan_id();
        let alouatta = identified(
            &mut store,
            "b.ply",
            "h-b",
            &answer("Alouatta", "Atelidae", false),
        );
        let failed = store.enqueue("c.ply", "h-c", 10).unwrap().scan_id();
        store.claim(failed).unwrap().unwrap();
        store.fail(failed, "unreadable").unwrap();

        let mut by = |taxa: &[(&str, &str)], no_close_match: Option<bool>| -> Vec<i64> {
            let query = ScanQuery {
                taxa: taxa
                    .iter()
                    .map(|(r, t)| (r.to_string(), t.to_string()))
                    .collect(),
                no_close_match,
                limit: 50,
                ..ScanQuery::default()
            };
            let page = store.search_scans(&query).unwrap();
            page.scans.iter().map(|s| s.id).collect()
        };
        assert_eq!(by(&[("genus", "Ateles")], None), [ateles_copy, ateles]);
        assert_eq!(by(&[("genus", "cebus")], None), [pair_copy, pair]);
        assert_eq!(
            by(&[("family", "Atelidae")], None),
            [alouatta, ateles_copy, ateles]
        );
        assert_eq!(
            by(&[("family", "ATELIDAE"), ("genus", "Alouatta")], None),
            [alouatta]
        );
        assert_eq!(by(&[("genus", "Pan")], None), Vec::<i64>::new());
        assert_eq!(by(&[("order", "Atelidae")], None), Vec::<i64>::new());
        assert_eq!(by(&[], Some(true)), [pair_copy, pair]);
        assert_eq!(by(&[], Some(false)), [alouatta, ateles_copy, ateles]);
        assert_eq!(by(&[("genus", "Cebus")], Some(false)), Vec::<i64>::new());
        assert_eq!(
            by(&[], None),
            [failed, alouatta, pair_copy, pair, ateles_copy, ateles]
        );
    }
}
