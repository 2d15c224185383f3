//! The landmark table (schema version 2) on real database files: an
//! existing version-1 database is upgraded in place without losing a row,
//! and a scan's landmarks are committed together with its result or not
//! at all.

use crate::support::store::{outcome, reference_name, register_references};
use morphoid_service::identify::{LandmarkPoint, ScanLandmarks};
use morphoid_service::store::{
    ScanStatus, Store, StoreError, APPLICATION_ID, MIGRATIONS, SCHEMA_VERSION,
};
use rusqlite::{params, Connection};

fn temp_db() -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("morphoid.sqlite");
    (dir, path)
}

fn count(conn: &Connection, table: &str, scan_id: i64) -> i64 {
    conn.query_row(
        &format!("SELECT count(*) FROM {table} WHERE scan_id = ?1"),
        [scan_id],
        |r| r.get(0),
    )
    .expect("count")
}

/// Ten landmarks carried from `reference`.
fn carried(reference: &str) -> ScanLandmarks {
    ScanLandmarks {
        reference: reference.to_string(),
        points: (0..10)
            .map(|k| LandmarkPoint {
                label: (k % 3 != 0).then(|| format!("L{k}")),
                x: k as f64 * 1.5,
                y: -(k as f64) / 7.0,
                z: 1e3 + k as f64,
            })
            .collect(),
    }
}

/// A version-1 database as the previous morphoid left it: two references,
/// one identified scan with its result and distances, one pending scan.
fn version_1_database(path: &std::path::Path) {
    let conn = Connection::open(path).expect("raw open");
    conn.execute_batch("PRAGMA journal_mode = WAL;")
        .expect("wal");
    conn.execute_batch(MIGRATIONS[0]).expect("schema 1");
    conn.pragma_update(None, "user_version", 1).expect("v1");
    conn.pragma_update(None, "application_id", APPLICATION_ID)
        .expect("app id");
    for (id, name) in [(1, "ref000"), (2, "ref001")] {
        conn.execute(
            "INSERT INTO reference (id, name, content_hash, labels, state, added_at, prepared_at)
             VALUES (?1, ?2, ?3, '{\"genus\": \"G\"}', 'prepared', 1, 2)",
            params![id, name, format!("hash-of-{name}")],
        )
        .expect("reference");
    }
    conn.execute(
        "INSERT INTO scan (id, path, content_hash, size, status, attempts, created_at,
                           started_at, finished_at, timings, cleaning)
         VALUES (1, 'old.ply', 'h-old', 10, 'ok', 1, 1, 2, 3, '{\"compare\": 5.0}', '{}')",
        [],
    )
    .expect("scan");
    conn.execute(
        "INSERT INTO result (scan_id, ordinal, rank, taxon, reference_id, distance)
         VALUES (1, 0, 'genus', 'G', 1, 0.02)",
        [],
    )
    .expect("result");
    for (rid, d) in [(1, 0.02), (2, 0.05)] {
        conn.execute(
            "INSERT INTO distance (scan_id, reference_id, forward, backward, distance, reflected)
             VALUES (1, ?1, ?2, ?2, ?2, 0)",
            params![rid, d],
        )
        .expect("distance");
    }
    conn.execute(
        "INSERT INTO scan (id, path, content_hash, size, status, created_at)
         VALUES (2, 'new.ply', 'h-new', 20, 'pending', 4)",
        [],
    )
    .expect("pending scan");
}

#[test]
fn version_1_database_is_upgraded_without_losing_rows() {
    let (_dir, path) = temp_db();
    version_1_database(&path);

    let mut store = Store::open(&path).expect("open upgrades");
    assert_eq!(store.schema_version().expect("version"), SCHEMA_VERSION);
    store.check_integrity().expect("integrity");
    let old = store.scan(1, 5).expect("read").expect("old scan kept");
    assert_eq!(old.status, ScanStatus::Ok);
    assert_eq!(old.path, "old.ply");
    assert_eq!(old.ranks.len(), 1);
    assert_eq!(old.ranks[0].reference, "ref000");
    assert_eq!(old.nearest.len(), 2);
    assert_eq!(old.timings_ms["compare"], 5.0);
    assert!(old.landmarks.is_none());
    let json = serde_json::to_value(&old).expect("json");
    assert!(json.get("landmarks").is_none(), "{json}");
    assert_eq!(store.references().expect("refs").len(), 2);

    // The pending scan from before the upgrade is identified with landmarks.
    let job = store
        .claim_next()
        .expect("claim")
        .expect("the pending scan");
    assert_eq!(job.path, "new.ply");
    let mut out = outcome(1, 0);
    out.ranks.clear();
    out.landmarks = Some(carried("ref001"));
    store.complete(job.scan_id, &out).expect("complete");
    let new = store.scan(job.scan_id, 5).expect("read").expect("present");
    assert_eq!(new.landmarks, Some(carried("ref001")));
    let json = serde_json::to_value(&new).expect("json");
    assert_eq!(json["landmarks_reference"], "ref001");
    assert_eq!(json["landmarks"][1]["label"], "L1");
    assert!(json["landmarks"][0]["label"].is_null());
    assert_eq!(json["landmarks"][9]["z"], 1009.0);
    drop(store);

    // Reopening an upgraded file changes nothing.
    let store = Store::open(&path).expect("reopen");
    assert_eq!(store.schema_version().expect("version"), SCHEMA_VERSION);
    assert_eq!(
        store.scan(1, 5).expect("read").expect("kept").ranks,
        old.ranks
    );
}

#[test]
fn landmarks_are_committed_with_the_result_or_not_at_all() {
    let (_dir, path) = temp_db();
    let mut store = Store::open(&path).expect("create");
    register_references(&mut store, 4);
    let id = store
        .enqueue("a.ply", "h-a", 10)
        .expect("enqueue")
        .scan_id();
    let job = store.claim(id).expect("claim").expect("pending");
    let mut out = outcome(7, 4);
    let nearest = out.ranks[0].reference.clone();
    out.landmarks = Some(carried(&nearest));

    // A failure in the middle of the landmark rows (after the result and
    // distance rows are in): nothing of the result is recorded.
    let raw = Connection::open(&path).expect("raw open");
    raw.execute_batch(
        "CREATE TRIGGER fail_landmark BEFORE INSERT ON landmark WHEN NEW.idx = 5
         BEGIN SELECT RAISE(ABORT, 'disk on fire'); END;",
    )
    .expect("trigger");
    let err = store.complete(job.scan_id, &out).expect_err("must fail");
    assert!(err.to_string().contains("disk on fire"), "{err}");
    for table in ["result", "distance", "landmark"] {
        assert_eq!(count(&raw, table, id), 0, "{table} rows left behind");
    }
    let rec = store.scan(id, 5).expect("read").expect("present");
    assert_eq!(rec.status, ScanStatus::Running);

    // Landmarks of an unknown reference, or with a non-finite coordinate:
    // refused before anything is written.
    let mut bad = out.clone();
    bad.landmarks = Some(carried("no-such-reference"));
    raw.execute_batch("DROP TRIGGER fail_landmark")
        .expect("drop");
    assert!(matches!(
        store.complete(job.scan_id, &bad),
        Err(StoreError::UnknownReference(_))
    ));
    let mut bad = out.clone();
    if let Some(lm) = bad.landmarks.as_mut() {
        lm.points[3].y = f64::NAN;
    }
    assert!(matches!(
        store.complete(job.scan_id, &bad),
        Err(StoreError::InvalidNumber { .. })
    ));
    for table in ["result", "distance", "landmark"] {
        assert_eq!(count(&raw, table, id), 0, "{table} rows left behind");
    }

    // Now it goes through: everything at once.
    store.complete(job.scan_id, &out).expect("complete");
    assert_eq!(count(&raw, "landmark", id), 10);
    assert_eq!(count(&raw, "result", id), 3);
    assert_eq!(count(&raw, "distance", id), 4);
    let rec = store.scan(id, 5).expect("read").expect("present");
    assert_eq!(rec.status, ScanStatus::Ok);
    assert_eq!(rec.landmarks, out.landmarks);
    assert_eq!(store.recent(1).expect("recent")[0].landmarks, out.landmarks);

    // A retry drops the landmarks with the result; deleting the scan
    // cascades.
    store.retry(id).expect("retry");
    assert_eq!(count(&raw, "landmark", id), 0);
    let job = store.claim(id).expect("claim").expect("pending again");
    store.complete(job.scan_id, &out).expect("complete again");
    assert_eq!(count(&raw, "landmark", id), 10);
    raw.execute_batch("PRAGMA foreign_keys = ON").expect("fk");
    raw.execute("DELETE FROM scan WHERE id = ?1", [id])
        .expect("delete");
    assert_eq!(count(&raw, "landmark", id), 0);
    assert_eq!(reference_name(0), "ref000");
}
