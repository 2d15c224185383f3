//! The SQLite store on real database files: schema, migrations, the job
//! queue's transitions, atomic results, concurrent readers, JSON form.

use crate::support::store::{outcome, reference_name, register_references, RANKS};
use morphoid_data::hash::content_hash;
use morphoid_service::identify::DistanceRow;
use morphoid_service::store::{
    migrate, now_ms, utc_day_start_ms, Enqueued, Labels, ReferenceState, ScanStatus, Store,
    StoreError, SCHEMA_VERSION,
};
use rusqlite::Connection;

fn temp_db() -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("morphoid.sqlite");
    (dir, path)
}

fn count(conn: &Connection, sql: &str, id: i64) -> i64 {
    conn.query_row(sql, [id], |r| r.get(0))
        .expect("count query")
}

fn schema_sql(conn: &Connection) -> Vec<String> {
    let mut stmt = conn
        .prepare("SELECT coalesce(sql, name) FROM sqlite_schema ORDER BY name")
        .expect("prepare");
    let rows = stmt.query_map([], |r| r.get(0)).expect("query");
    rows.collect::<Result<_, _>>().expect("rows")
}

#[test]
fn creates_schema_with_pragmas_and_reopens_with_data() {
    let (_dir, path) = temp_db();
    let id = {
        let mut store = Store::open(&path).expect("create");
        assert_eq!(store.schema_version().expect("version"), SCHEMA_VERSION);
        register_references(&mut store, 4);
        store
            .enqueue("a.ply", "h-a", 10)
            .expect("enqueue")
            .scan_id()
    };
    let store = Store::open(&path).expect("reopen");
    assert_eq!(store.schema_version().expect("version"), SCHEMA_VERSION);
    store.check_integrity().expect("integrity");
    let rec = store.scan(id, 5).expect("read").expect("scan present");
    assert_eq!((rec.path.as_str(), rec.size), ("a.ply", 10));
    assert_eq!(store.references().expect("refs").len(), 4);

    let conn = Connection::open(&path).expect("raw open");
    let mode: String = conn
        .query_row("PRAGMA journal_mode", [], |r| r.get(0))
        .expect("mode");
    assert_eq!(mode, "wal");
    // A table rebuilt by a migration is stored with its name quoted.
    let tables = schema_sql(&conn).join("\n").replace("\"scan\"", "scan");
    for table in [
        "CREATE TABLE reference",
        "CREATE TABLE scan",
        "CREATE TABLE result",
        "CREATE TABLE distance",
    ] {
        assert!(tables.contains(table), "missing {table}");
    }
    assert!(tables.contains("REFERENCES scan (id) ON DELETE CASCADE"));
}

#[test]
fn migrations_run_twice_change_nothing() {
    let (_dir, path) = temp_db();
    drop(Store::open(&path).expect("create"));
    let mut conn = Connection::open(&path).expect("raw open");
    let before = schema_sql(&conn);
    assert_eq!(migrate(&mut conn, &path).expect("again"), SCHEMA_VERSION);
    assert_eq!(
        migrate(&mut conn, &path).expect("and again"),
        SCHEMA_VERSION
    );
    assert_eq!(schema_sql(&conn), before);
    drop(conn);
    drop(Store::open(&path).expect("reopen"));
    let conn = Connection::open(&path).expect("raw open");
    assert_eq!(schema_sql(&conn), before);
}

#[test]
fn database_from_a_newer_version_is_refused() {
    let (_dir, path) = temp_db();
    drop(Store::open(&path).expect("create"));
    {
        let conn = Connection::open(&path).expect("raw open");
        conn.pragma_update(None, "user_version", SCHEMA_VERSION + 1)
            .expect("bump");
    }
    let err = Store::open(&path).expect_err("future schema must be refused");
    match &err {
        StoreError::SchemaTooNew {
            found, supported, ..
        } => {
            assert_eq!((*found, *supported), (SCHEMA_VERSION + 1, SCHEMA_VERSION));
        }
        other => panic!("unexpected error {other:?}"),
    }
    assert!(
        err.to_string().contains("morphoid.sqlite: schema version"),
        "{err}"
    );
    // And it was not touched.
    let conn = Connection::open(&path).expect("raw open");
    let v: u32 = conn
        .query_row("PRAGMA user_version", [], |r| r.get(0))
        .expect("version");
    assert_eq!(v, SCHEMA_VERSION + 1);
}

#[test]
fn other_applications_database_is_refused() {
    let (_dir, path) = temp_db();
    {
        let conn = Connection::open(&path).expect("raw open");
        conn.execute_batch("CREATE TABLE invoices (id INTEGER PRIMARY KEY)")
            .expect("create");
    }
    let err = Store::open(&path).expect_err("foreign database must be refused");
    assert!(matches!(err, StoreError::NotMorphoid { .. }), "{err:?}");
    assert!(
        err.to_string().contains("is not a morphoid database"),
        "{err}"
    );
    let conn = Connection::open(&path).expect("raw open");
    assert_eq!(schema_sql(&conn).len(), 1, "the foreign file was altered");
}

#[test]
fn enqueue_is_idempotent_by_content_hash() {
    let (_dir, path) = temp_db();
    let mut store = Store::open(&path).expect("open");
    register_references(&mut store, 3);
    let first = store.enqueue("x.ply", "h1", 100).expect("enqueue");
    let Enqueued::New(id) = first else {
        panic!("expected new, got {first:?}")
    };
    assert_eq!(
        store.enqueue("x.ply", "h1", 100).expect("again"),
        Enqueued::Existing(id, ScanStatus::Pending)
    );
    // Same bytes under another name: a row of its own, a duplicate of the
    // scan, added once.
    let copy = store.enqueue("copy/x.ply", "h1", 100).expect("copy");
    let Enqueued::Duplicate { id: copy_id, of } = copy else {
        panic!("expected a duplicate, got {copy:?}")
    };
    assert_eq!(of, id);
    assert_eq!(
        store.enqueue("copy/x.ply", "h1", 100).expect("copy again"),
        Enqueued::Existing(copy_id, ScanStatus::Duplicate)
    );
    let job = store.claim_next().expect("claim").expect("job");
    assert_eq!(
        store.enqueue("x.ply", "h1", 100).expect("while running"),
        Enqueued::Existing(id, ScanStatus::Running)
    );
    store
        .complete(job.scan_id, &outcome(1, 3))
        .expect("complete");
    assert_eq!(
        store.enqueue("x.ply", "h1", 100).expect("after ok"),
        Enqueued::Existing(id, ScanStatus::Ok)
    );
    // The file changed: a new scan.
    let changed = store.enqueue("x.ply", "h2", 120).expect("changed");
    assert!(
        matches!(changed, Enqueued::New(new_id) if new_id != id),
        "{changed:?}"
    );
    assert_eq!(store.counts().expect("counts").pending, 1);
    assert!(store
        .claim_next()
        .expect("claim")
        .is_some_and(|j| j.content_hash == "h2"));
    assert!(
        store.claim_next().expect("claim").is_none(),
        "only one pending scan existed"
    );
}

#[test]
fn claim_complete_fail_transitions() {
    let (_dir, path) = temp_db();
    let mut store = Store::open(&path).expect("open");
    register_references(&mut store, 8);
    assert!(store.claim_next().expect("claim on empty").is_none());
    let a = store.enqueue("a.ply", "ha", 1).expect("a").scan_id();
    let b = store.enqueue("b.ply", "hb", 2).expect("b").scan_id();
    let c = store.enqueue("c.ply", "hc", 3).expect("c").scan_id();

    // Only a running scan can be completed.
    let err = store
        .complete(a, &outcome(1, 8))
        .expect_err("pending cannot complete");
    assert!(
        matches!(
            err,
            StoreError::WrongStatus {
                status: ScanStatus::Pending,
                ..
            }
        ),
        "{err:?}"
    );
    assert!(matches!(
        store.complete(999, &outcome(1, 8)),
        Err(StoreError::NoSuchScan(999))
    ));

    // The start of the UTC day before anything finishes, so that the
    // "finished today" count below is not cut short by a test that runs
    // across midnight.
    let today = utc_day_start_ms(now_ms());

    // Oldest first.
    let job = store.claim_next().expect("claim").expect("job a");
    assert_eq!(
        (job.scan_id, job.path.as_str(), job.size, job.attempts),
        (a, "a.ply", 1, 1)
    );
    let out_a = outcome(1, 8);
    store.complete(a, &out_a).expect("complete a");
    let rec = store.scan(a, 3).expect("read").expect("a");
    assert_eq!(rec.status, ScanStatus::Ok);
    assert!(rec.finished_at_ms.is_some() && rec.started_at_ms.is_some());
    assert_eq!(rec.ranks, out_a.ranks);
    assert_eq!(
        rec.ranks
            .iter()
            .map(|r| r.rank.as_str())
            .collect::<Vec<_>>(),
        RANKS
    );
    assert_eq!(rec.timings_ms, out_a.timings_ms);
    assert_eq!(rec.cleaning, out_a.cleaning);
    let mut expected: Vec<_> = out_a
        .distances
        .iter()
        .map(|d| (d.distance, d.reference.clone()))
        .collect();
    expected.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    let got: Vec<_> = rec
        .nearest
        .iter()
        .map(|n| (n.distance, n.reference.clone()))
        .collect();
    assert_eq!(got, expected[..3].to_vec());

    // A completed scan is never completed again, nor failed.
    let err = store
        .complete(a, &outcome(2, 8))
        .expect_err("double complete");
    assert!(
        matches!(
            err,
            StoreError::WrongStatus {
                status: ScanStatus::Ok,
                ..
            }
        ),
        "{err:?}"
    );
    assert!(matches!(
        store.fail(a, "late"),
        Err(StoreError::WrongStatus { .. })
    ));
    assert_eq!(
        store.scan(a, 3).expect("read").expect("a").ranks,
        out_a.ranks
    );

    // b fails while running, c fails while still pending.
    assert_eq!(
        store.claim_next().expect("claim").map(|j| j.scan_id),
        Some(b)
    );
    store
        .fail(b, "not a disk-type surface: 2 boundary loops")
        .expect("fail b");
    store.fail(c, "unreadable").expect("fail c");
    let rec_b = store.scan(b, 3).expect("read").expect("b");
    assert_eq!(rec_b.status, ScanStatus::Error);
    assert_eq!(
        rec_b.error.as_deref(),
        Some("not a disk-type surface: 2 boundary loops")
    );
    assert!(rec_b.ranks.is_empty() && rec_b.nearest.is_empty());
    assert!(store.claim_next().expect("claim").is_none());
    let counts = store.counts().expect("counts");
    assert_eq!(
        (counts.pending, counts.running, counts.ok, counts.error),
        (0, 0, 1, 2)
    );
    assert_eq!(store.finished_since(today).expect("today"), 3);
    assert_eq!(store.finished_since(now_ms() + 60_000).expect("future"), 0);

    // Retry drops the result and makes it pending again.
    store.retry(a).expect("retry");
    let conn = Connection::open(&path).expect("raw");
    assert_eq!(
        count(&conn, "SELECT count(*) FROM distance WHERE scan_id = ?1", a),
        0
    );
    assert_eq!(
        count(&conn, "SELECT count(*) FROM result WHERE scan_id = ?1", a),
        0
    );
    let again = store.claim_next().expect("claim").expect("a again");
    assert_eq!((again.scan_id, again.attempts), (a, 2));
}

#[test]
fn requeue_after_crash_runs_each_scan_once() {
    let (_dir, path) = temp_db();
    let (done, interrupted) = {
        let mut store = Store::open(&path).expect("open");
        register_references(&mut store, 5);
        let done = store.enqueue("done.ply", "hd", 1).expect("d").scan_id();
        let interrupted = store.enqueue("cut.ply", "hc", 1).expect("c").scan_id();
        store.enqueue("later.ply", "hl", 1).expect("l");
        let job = store.claim_next().expect("claim").expect("done");
        store
            .complete(job.scan_id, &outcome(7, 5))
            .expect("complete");
        let job = store.claim_next().expect("claim").expect("cut");
        assert_eq!(job.scan_id, interrupted);
        (done, interrupted)
        // The store is dropped with `cut.ply` running: the worker died.
    };
    let mut store = Store::open(&path).expect("restart");
    assert_eq!(store.requeue_running().expect("requeue"), 1);
    assert_eq!(store.requeue_running().expect("requeue twice"), 0);
    let rec = store.scan(done, 5).expect("read").expect("done");
    assert_eq!((rec.status, rec.ranks.len()), (ScanStatus::Ok, 3));
    let mut claimed = Vec::new();
    while let Some(job) = store.claim_next().expect("claim") {
        store
            .complete(job.scan_id, &outcome(job.scan_id as u64, 5))
            .expect("complete");
        claimed.push((job.scan_id, job.attempts));
    }
    assert_eq!(claimed.len(), 2, "{claimed:?}");
    assert!(claimed.contains(&(interrupted, 2)), "{claimed:?}");
    assert!(
        !claimed.iter().any(|(id, _)| *id == done),
        "a finished scan was re-run"
    );
    let conn = Connection::open(&path).expect("raw");
    for id in [done, interrupted] {
        assert_eq!(
            count(&conn, "SELECT count(*) FROM result WHERE scan_id = ?1", id),
            3
        );
        assert_eq!(
            count(
                &conn,
                "SELECT count(*) FROM distance WHERE scan_id = ?1",
                id
            ),
            5
        );
    }
}

/// After a storage fault the worker requeues every running scan but the
/// one it holds a finding for: that one is recorded, the others run again.
#[test]
fn requeue_keeps_the_held_scan_running() {
    let (_dir, path) = temp_db();
    let mut store = Store::open(&path).expect("open");
    register_references(&mut store, 5);
    store.enqueue("held.ply", "hh", 1).expect("h");
    store.enqueue("lost.ply", "hl", 1).expect("l");
    let held = store.claim_next().expect("claim").expect("held");
    let lost = store.claim_next().expect("claim").expect("lost");
    assert_eq!(
        store
            .requeue_running_but(Some(held.scan_id))
            .expect("requeue"),
        1
    );
    let status = |store: &Store, id| store.scan(id, 5).expect("read").expect("row").status;
    assert_eq!(status(&store, held.scan_id), ScanStatus::Running);
    assert_eq!(status(&store, lost.scan_id), ScanStatus::Pending);
    store
        .complete(held.scan_id, &outcome(7, 5))
        .expect("the held finding is recorded");
    let again = store.claim_next().expect("claim").expect("lost again");
    assert_eq!(again.scan_id, lost.scan_id);
}

#[test]
fn complete_is_all_or_nothing() {
    let (_dir, path) = temp_db();
    let mut store = Store::open(&path).expect("open");
    register_references(&mut store, 20);
    let id = store.enqueue("s.ply", "hs", 1).expect("enqueue").scan_id();
    store.claim_next().expect("claim").expect("job");
    let conn = Connection::open(&path).expect("raw");
    let rows = |conn: &Connection| {
        (
            count(conn, "SELECT count(*) FROM result WHERE scan_id = ?1", id),
            count(conn, "SELECT count(*) FROM distance WHERE scan_id = ?1", id),
        )
    };

    // 1. The last distance names a reference that does not exist: the
    //    results and the first 20 distances were already inserted.
    let mut bad = outcome(3, 20);
    bad.distances.push(DistanceRow {
        reference: "nobody".into(),
        forward: 0.1,
        backward: 0.1,
        distance: 0.1,
        reflected: false,
    });
    let err = store.complete(id, &bad).expect_err("unknown reference");
    assert!(
        matches!(&err, StoreError::UnknownReference(n) if n == "nobody"),
        "{err:?}"
    );
    assert_eq!(rows(&conn), (0, 0));
    assert_eq!(
        store.scan(id, 5).expect("read").expect("s").status,
        ScanStatus::Running
    );

    // 2. The database itself fails at the 11th distance row.
    conn.execute_batch(
        "CREATE TRIGGER fail_midway BEFORE INSERT ON distance
         WHEN (SELECT count(*) FROM distance WHERE scan_id = NEW.scan_id) >= 10
         BEGIN SELECT RAISE(ABORT, 'injected failure'); END;",
    )
    .expect("trigger");
    let err = store
        .complete(id, &outcome(3, 20))
        .expect_err("injected failure");
    assert!(err.to_string().contains("injected failure"), "{err}");
    assert_eq!(rows(&conn), (0, 0));
    let rec = store.scan(id, 5).expect("read").expect("s");
    assert_eq!(
        (rec.status, rec.finished_at_ms, rec.cleaning.is_null()),
        (ScanStatus::Running, None, true)
    );

    // 3. A NaN is refused before anything is written.
    conn.execute_batch("DROP TRIGGER fail_midway")
        .expect("drop trigger");
    let mut nan = outcome(3, 20);
    if let Some(d) = nan.distances.get_mut(5) {
        d.backward = f64::NAN;
    }
    assert!(matches!(
        store.complete(id, &nan),
        Err(StoreError::InvalidNumber { .. })
    ));
    assert_eq!(rows(&conn), (0, 0));

    // Then the good outcome goes in whole.
    store.complete(id, &outcome(3, 20)).expect("complete");
    assert_eq!(rows(&conn), (3, 20));
    store.check_integrity().expect("integrity");
}

#[test]
fn readers_see_whole_results_while_a_writer_commits() {
    const REFS: usize = 60;
    const SCANS: usize = 120;
    let (_dir, path) = temp_db();
    {
        let mut store = Store::open(&path).expect("open");
        register_references(&mut store, REFS);
    }
    let writer_path = path.clone();
    // The writer starts only after the reader's first snapshot, so at least
    // one read overlaps the writes however the threads are scheduled.
    let start = std::sync::Arc::new(std::sync::Barrier::new(2));
    let writer_start = start.clone();
    let writer = std::thread::spawn(move || {
        writer_start.wait();
        let mut store = Store::open(&writer_path).expect("writer open");
        for i in 0..SCANS {
            let id = store
                .enqueue(&format!("s{i}.ply"), &content_hash(&i.to_le_bytes()), 1)
                .expect("enqueue")
                .scan_id();
            let job = store.claim_next().expect("claim").expect("job");
            assert_eq!(job.scan_id, id);
            store
                .complete(id, &outcome(i as u64, REFS))
                .expect("complete");
        }
    });
    let mut reader = Store::open(&path).expect("reader open");
    let mut raw = Connection::open(&path).expect("raw reader");
    raw.busy_timeout(std::time::Duration::from_secs(10))
        .expect("timeout");
    let mut reads = 0;
    let mut last_ok = 0;
    loop {
        let finished = writer.is_finished();
        // A consistent snapshot: every ok scan has all its rows, no other
        // scan has any.
        let tx = raw.transaction().expect("read transaction");
        let bad: i64 = tx
            .query_row(
                "SELECT count(*) FROM scan WHERE
                   (status = 'ok' AND ((SELECT count(*) FROM result r WHERE r.scan_id = scan.id) <> 3
                                    OR (SELECT count(*) FROM distance d WHERE d.scan_id = scan.id) <> ?1))
                OR (status <> 'ok' AND (EXISTS (SELECT 1 FROM result r WHERE r.scan_id = scan.id)
                                    OR EXISTS (SELECT 1 FROM distance d WHERE d.scan_id = scan.id)))",
                [REFS as i64],
                |r| r.get(0),
            )
            .expect("check");
        tx.commit().expect("end read");
        assert_eq!(bad, 0, "a reader saw a partial result");
        let recent = reader.recent(10).expect("recent");
        for rec in &recent {
            if rec.status == ScanStatus::Ok {
                assert_eq!(rec.ranks.len(), 3);
                assert_eq!(rec.nearest.len(), 5);
            }
        }
        let ok = reader.counts().expect("counts").ok;
        assert!(ok >= last_ok, "ok count went backwards");
        last_ok = ok;
        reads += 1;
        if reads == 1 {
            start.wait();
        }
        if finished {
            break;
        }
    }
    writer.join().expect("writer thread");
    assert!(reads >= 2);
    assert_eq!(reader.counts().expect("counts").ok, SCANS as u64);
}

#[test]
fn recent_is_newest_first_and_serializes_in_the_design_form() {
    let (_dir, path) = temp_db();
    let mut store = Store::open(&path).expect("open");
    register_references(&mut store, 6);
    let ids: Vec<i64> = (0..5)
        .map(|i| {
            store
                .enqueue(&format!("scan{i}.ply"), &format!("h{i}"), 10)
                .expect("enqueue")
                .scan_id()
        })
        .collect();
    let j0 = store.claim_next().expect("claim").expect("job");
    store
        .complete(j0.scan_id, &outcome(0, 6))
        .expect("complete");
    let j1 = store.claim_next().expect("claim").expect("job");
    store
        .fail(j1.scan_id, "PLY: face 7 has index 9000 >= 5100 vertices")
        .expect("fail");

    let recent = store.recent(3).expect("recent");
    assert_eq!(
        recent.iter().map(|r| r.id).collect::<Vec<_>>(),
        vec![ids[4], ids[3], ids[2]]
    );
    let all = store.recent(100).expect("recent all");
    assert_eq!(all.len(), 5);
    assert_eq!(all.last().map(|r| r.path.as_str()), Some("scan0.ply"));

    let ok = serde_json::to_value(&all[4]).expect("json");
    assert_eq!(ok["scan"], "scan0.ply");
    assert_eq!(ok["status"], "ok");
    let genus = &ok["ranks"]["genus"];
    assert_eq!(genus["taxon"], "genus-taxon-0");
    assert_eq!(genus["runner_up"], "genus-other");
    assert!(
        genus["distance"].is_f64() && genus["margin"].is_f64() && genus["reference"].is_string()
    );
    // Ranks in their order, broadest first.
    let text = serde_json::to_string(&all[4]).expect("json text");
    let (o, f, g) = (
        text.find("\"order\""),
        text.find("\"family\""),
        text.find("\"genus\""),
    );
    assert!(o < f && f < g, "{text}");
    let nearest = ok["nearest"].as_array().expect("nearest array");
    assert_eq!(nearest.len(), 5);
    assert!(nearest
        .windows(2)
        .all(|w| w[0]["distance"].as_f64() <= w[1]["distance"].as_f64()));
    assert_eq!(ok["cleaning"]["vertices_after"], 5000);
    assert_eq!(ok["timings_ms"]["load"], 12.5);

    let err = serde_json::to_value(&all[3]).expect("json");
    assert_eq!(err["status"], "error");
    assert_eq!(err["error"], "PLY: face 7 has index 9000 >= 5100 vertices");
    assert!(err.get("ranks").is_none());
    let pending = serde_json::to_value(&all[0]).expect("json");
    assert_eq!(
        (pending["status"].as_str(), pending["scan"].as_str()),
        (Some("pending"), Some("scan4.ply"))
    );

    let by_hash = store.scan_by_hash("h0", 2).expect("by hash").expect("h0");
    assert_eq!((by_hash.id, by_hash.nearest.len()), (ids[0], 2));
    assert!(store.scan_by_hash("nope", 2).expect("by hash").is_none());
}

#[test]
fn references_are_versioned_by_content() {
    let (_dir, path) = temp_db();
    let mut store = Store::open(&path).expect("open");
    register_references(&mut store, 3);
    let names: Vec<String> = store
        .references()
        .expect("refs")
        .into_iter()
        .map(|r| r.name)
        .collect();
    assert_eq!(
        names,
        vec![reference_name(0), reference_name(1), reference_name(2)]
    );

    // Record a result against ref001's current content.
    let id = store.enqueue("s.ply", "hs", 1).expect("enqueue").scan_id();
    store.claim_next().expect("claim");
    store.complete(id, &outcome(1, 3)).expect("complete");

    // ref001's mesh changes: a new pending version, the old one superseded
    // and still holding the distances measured on it.
    let mut labels = Labels::new();
    labels.insert("genus".into(), Some("Galago".into()));
    let new_id = store
        .register_reference(&reference_name(1), "new-content", &labels)
        .expect("re-register");
    let refs = store.references().expect("refs");
    let r1 = refs
        .iter()
        .find(|r| r.name == reference_name(1))
        .expect("ref001");
    assert_eq!(
        (r1.id, r1.state, r1.content_hash.as_str()),
        (new_id, ReferenceState::Pending, "new-content")
    );
    assert_eq!(r1.labels.get("genus"), Some(&Some("Galago".to_string())));
    let rec = store.scan(id, 10).expect("read").expect("s");
    assert_eq!(
        rec.nearest.len(),
        3,
        "distances to the old content were lost"
    );

    // Registering the same content again keeps its state.
    store
        .mark_reference_prepared(&reference_name(1))
        .expect("prepared");
    store
        .register_reference(&reference_name(1), "new-content", &labels)
        .expect("same again");
    let refs = store.references().expect("refs");
    assert!(refs
        .iter()
        .any(|r| r.name == reference_name(1) && r.state == ReferenceState::Prepared));

    // ref002 leaves the library.
    let keep = [reference_name(0), reference_name(1)];
    let keep: Vec<&str> = keep.iter().map(String::as_str).collect();
    assert_eq!(store.remove_references_except(&keep).expect("remove"), 1);
    assert_eq!(store.references().expect("refs").len(), 2);
    store
        .mark_reference_failed(&reference_name(0), "closed surface")
        .expect("failed");
    assert!(matches!(
        store.mark_reference_prepared(&reference_name(2)),
        Err(StoreError::UnknownReference(_))
    ));

    // Results can no longer be recorded against a removed reference.
    let id2 = store.enqueue("t.ply", "ht", 1).expect("enqueue").scan_id();
    store.claim_next().expect("claim");
    assert!(matches!(
        store.complete(id2, &outcome(2, 3)),
        Err(StoreError::UnknownReference(_))
    ));
    store.check_integrity().expect("integrity");
}

#[test]
fn claim_by_id_takes_only_that_pending_scan() {
    let (_dir, path) = temp_db();
    let mut store = Store::open(&path).expect("open");
    register_references(&mut store, 2);
    let queued = store.enqueue("queued.ply", "hq", 1).expect("q").scan_id();
    let mine = store.enqueue("mine.ply", "hm", 1).expect("m").scan_id();
    let job = store.claim(mine).expect("claim").expect("pending");
    assert_eq!((job.scan_id, job.path.as_str()), (mine, "mine.ply"));
    assert!(store.claim(mine).expect("claim running").is_none());
    store.complete(mine, &outcome(4, 2)).expect("complete");
    assert!(store.claim(mine).expect("claim ok").is_none());
    assert!(store.claim(12345).expect("claim missing").is_none());
    // A clean shutdown gives a job back without counting an attempt.
    let job = store.claim(queued).expect("claim").expect("pending");
    assert_eq!(job.attempts, 1);
    store.abandon(queued).expect("abandon");
    assert!(matches!(
        store.abandon(queued),
        Err(StoreError::WrongStatus {
            status: ScanStatus::Pending,
            ..
        })
    ));
    let job = store.claim_next().expect("claim").expect("queued again");
    assert_eq!((job.scan_id, job.attempts), (queued, 1));
    store.abandon(queued).expect("abandon");
    assert_eq!(
        store.scan(queued, 1).expect("read").expect("q").status,
        ScanStatus::Pending
    );
}

#[test]
fn concurrent_workers_never_claim_the_same_scan() {
    const SCANS: usize = 60;
    let (_dir, path) = temp_db();
    {
        let mut store = Store::open(&path).expect("open");
        register_references(&mut store, 4);
        for i in 0..SCANS {
            store
                .enqueue(&format!("s{i}.ply"), &format!("h{i}"), 1)
                .expect("enqueue");
        }
    }
    let workers: Vec<_> = (0..3)
        .map(|_| {
            let path = path.clone();
            std::thread::spawn(move || {
                let mut store = Store::open(&path).expect("worker open");
                let mut mine = Vec::new();
                while let Some(job) = store.claim_next().expect("claim") {
                    store
                        .complete(job.scan_id, &outcome(job.scan_id as u64, 4))
                        .expect("complete");
                    mine.push(job.scan_id);
                }
                mine
            })
        })
        .collect();
    let mut all: Vec<i64> = workers
        .into_iter()
        .flat_map(|w| w.join().expect("worker"))
        .collect();
    all.sort_unstable();
    let n = all.len();
    all.dedup();
    assert_eq!(
        (n, all.len()),
        (SCANS, SCANS),
        "a scan was claimed twice or not at all"
    );
    let store = Store::open(&path).expect("open");
    assert_eq!(store.counts().expect("counts").ok, SCANS as u64);
}

#[test]
fn a_file_that_is_not_a_database_is_a_clear_error() {
    let (_dir, path) = temp_db();
    std::fs::write(&path, b"ply\nformat ascii 1.0\nend_header\n").expect("write");
    let err = Store::open(&path).expect_err("not a database");
    let text = err.to_string();
    assert!(text.contains("morphoid.sqlite"), "{text}");
    assert!(text.contains("not a database"), "{text}");
}

#[test]
fn a_failure_to_write_result_files_is_kept_in_the_row_until_they_are_written() {
    let (_dir, path) = temp_db();
    let mut store = Store::open(&path).expect("create");
    store.set_result_files(true);
    register_references(&mut store, 3);
    let mut ids = Vec::new();
    for (k, name) in ["a.ply", "b.ply", "c.ply"].iter().enumerate() {
        let id = store
            .enqueue(name, &format!("h-{name}"), 10)
            .expect("enqueue")
            .scan_id();
        let job = store.claim(id).expect("claim").expect("pending");
        let mut out = outcome(k as u64, 3);
        out.calibrating = k == 1;
        store.complete(job.scan_id, &out).expect("complete");
        ids.push(id);
    }
    assert_eq!(store.files_due(10).expect("due"), ids);
    let message = "/results/a.ply.json: cannot write: Read-only file system";
    store.files_failed(ids[0], message).expect("failed");
    // A scan whose files failed goes behind the ones not tried yet.
    assert_eq!(
        store.files_due(10).expect("due"),
        vec![ids[1], ids[2], ids[0]]
    );
    let rec = store.scan(ids[0], 5).expect("read").expect("row");
    assert_eq!(rec.status, ScanStatus::Ok);
    assert_eq!(rec.ranks.len(), RANKS.len());
    assert_eq!(rec.files_error.as_deref(), Some(message));
    let json = serde_json::to_value(&rec).expect("json");
    assert_eq!(json["files_error"], message);
    assert!(json.get("calibrating").is_none(), "{json}");
    // The flag of a scan identified while the calibration ran.
    let rec = store.scan(ids[1], 5).expect("read").expect("row");
    assert!(rec.calibrating);
    assert_eq!(
        serde_json::to_value(&rec).expect("json")["calibrating"],
        true
    );
    // Written at the next attempt: the error is gone with the due mark.
    store.files_written(ids[0]).expect("written");
    let rec = store.scan(ids[0], 5).expect("read").expect("row");
    assert_eq!(rec.files_error, None);
    assert!(serde_json::to_value(&rec)
        .expect("json")
        .get("files_error")
        .is_none());
    assert_eq!(store.files_due(10).expect("due"), vec![ids[1], ids[2]]);
    // A retried scan is identified afresh: no stale calibration flag.
    store.retry(ids[1]).expect("retry");
    let job = store.claim(ids[1]).expect("claim").expect("pending");
    store
        .complete(job.scan_id, &outcome(9, 3))
        .expect("complete");
    assert!(
        !store
            .scan(ids[1], 5)
            .expect("read")
            .expect("row")
            .calibrating
    );
}

#[test]
fn a_version_4_database_opens_and_gains_the_new_columns() {
    let (_dir, path) = temp_db();
    {
        let conn = Connection::open(&path).expect("raw open");
        for sql in &morphoid_service::store::MIGRATIONS[..4] {
            conn.execute_batch(sql).expect("schema");
        }
        conn.pragma_update(None, "user_version", 4).expect("v4");
        conn.pragma_update(
            None,
            "application_id",
            morphoid_service::store::APPLICATION_ID,
        )
        .expect("app id");
        conn.execute(
            "INSERT INTO scan (id, path, content_hash, size, status, error, attempts,
                               created_at, started_at, finished_at, files_due)
             VALUES (1, 'old.ply', 'h-old', 10, 'error', 'broken', 1, 1, 2, 3, 1)",
            [],
        )
        .expect("scan");
    }
    let mut store = Store::open(&path).expect("open upgrades");
    assert_eq!(store.schema_version().expect("version"), SCHEMA_VERSION);
    store.check_integrity().expect("integrity");
    let old = store.scan(1, 5).expect("read").expect("kept");
    assert_eq!((old.files_error, old.calibrating), (None, false));
    assert_eq!(old.error.as_deref(), Some("broken"));
    store.files_failed(1, "cannot write").expect("failed");
    assert_eq!(
        store.recent(1).expect("recent")[0].files_error.as_deref(),
        Some("cannot write")
    );
}

/// Issue 30: a job whose file held other content when read ends
/// `superseded`, pointing at the row of the content read (queued then, or
/// the row it already had); the superseded content may be queued again.
#[test]
fn a_superseded_scan_points_at_the_content_read() {
    use morphoid_service::store::{Enqueued, ScanStatus, Store};
    let dir = tempfile::tempdir().unwrap();
    let mut store = Store::open(&dir.path().join("db.sqlite")).unwrap();
    let Enqueued::New(a) = store.enqueue("e/x.ply", "h1", 10).unwrap() else {
        panic!("not new")
    };
    let job = store.claim_next().unwrap().unwrap();
    assert_eq!(job.scan_id, a);
    // Its own content is no reason to supersede it.
    assert!(store.supersede(a, "h1", 10).is_err());
    let Enqueued::New(b) = store.supersede(a, "h2", 20).unwrap() else {
        panic!("the content read is queued")
    };
    let old = store.scan(a, 0).unwrap().unwrap();
    assert_eq!(
        (old.status, old.superseded_by, old.content_hash.as_str()),
        (ScanStatus::Superseded, Some(b), "h1")
    );
    assert!(old.finished_at_ms.is_some());
    let json = serde_json::to_value(&old).unwrap();
    assert_eq!(json["superseded_by"], b);
    let new = store.scan(b, 0).unwrap().unwrap();
    assert_eq!(
        (
            new.status,
            new.path.as_str(),
            new.content_hash.as_str(),
            new.size
        ),
        (ScanStatus::Pending, "e/x.ply", "h2", 20)
    );
    // The content read was queued already: pointed at, not queued again.
    let Enqueued::New(c) = store.enqueue("e/x.ply", "h3", 30).unwrap() else {
        panic!("not new")
    };
    let job = store.claim_next().unwrap().unwrap();
    assert_eq!(job.scan_id, b);
    assert_eq!(
        store.supersede(b, "h3", 30).unwrap(),
        Enqueued::Existing(c, ScanStatus::Pending)
    );
    // A superseded content is not identified: arriving again, it is queued.
    assert!(matches!(
        store.enqueue("e/x.ply", "h1", 10).unwrap(),
        Enqueued::New(_)
    ));
    assert!(store.scan_by_hash("h1", 0).unwrap().unwrap().status == ScanStatus::Pending);
    let counts = store.counts().unwrap();
    assert_eq!((counts.superseded, counts.pending), (2, 2));
    store.check_integrity().unwrap();
}
