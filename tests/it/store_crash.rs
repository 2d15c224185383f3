//! A writer killed with SIGKILL at a random moment, over and over, leaves
//! a database that opens cleanly and holds only whole results; after each
//! restart the interrupted scan is identified exactly once.
//!
//! The writer is this test binary itself, re-run as a child process with
//! `CRASH_CHILD_DB` set, executing the ignored test `crash_child_writer`.

use crate::support::store::{outcome, register_references};
use morphoid_data::hash::content_hash;
use morphoid_service::store::{ScanStatus, Store};
use rand::Rng;
use rusqlite::Connection;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// References per scan: 3 result rows and this many distance rows go into
/// each transaction, so a kill often lands inside one.
const REFS: usize = 400;
const CHILD_ENV: &str = "CRASH_CHILD_DB";
const ROUNDS: usize = 5;

fn scan_index(path: &str) -> u64 {
    path.trim_start_matches('s')
        .trim_end_matches(".ply")
        .parse()
        .unwrap_or(u64::MAX)
}

/// The child: identify scans s0, s1, … for ever (until killed).
#[test]
#[ignore = "child process of killed_writer_leaves_only_whole_results"]
fn crash_child_writer() {
    let Ok(db) = std::env::var(CHILD_ENV) else {
        panic!("{CHILD_ENV} not set: this test only runs as a child process");
    };
    let mut store = Store::open(Path::new(&db)).expect("child open");
    if store.references().expect("refs").is_empty() {
        register_references(&mut store, REFS);
    }
    store.requeue_running().expect("requeue");
    for i in 0..1_000_000u64 {
        store
            .enqueue(
                &format!("s{i}.ply"),
                &content_hash(&i.to_le_bytes()),
                1000 + i,
            )
            .expect("enqueue");
        while let Some(job) = store.claim_next().expect("claim") {
            let seed = scan_index(&job.path);
            if seed % 10 == 9 {
                store
                    .fail(job.scan_id, &format!("bad scan {seed}"))
                    .expect("fail");
            } else {
                store
                    .complete(job.scan_id, &outcome(seed, REFS))
                    .expect("complete");
            }
        }
    }
}

fn check_database(path: &Path) -> (u64, u64) {
    let mut store = Store::open(path).expect("a killed writer's database must open");
    store.check_integrity().expect("integrity");
    let conn = Connection::open(path).expect("raw open");
    let partial: i64 = conn
        .query_row(
            "SELECT count(*) FROM scan WHERE
               (status = 'ok' AND ((SELECT count(*) FROM result r WHERE r.scan_id = scan.id) <> 3
                                OR (SELECT count(*) FROM distance d WHERE d.scan_id = scan.id) <> ?1))
            OR (status <> 'ok' AND (EXISTS (SELECT 1 FROM result r WHERE r.scan_id = scan.id)
                                OR EXISTS (SELECT 1 FROM distance d WHERE d.scan_id = scan.id)))",
            [REFS as i64],
            |r| r.get(0),
        )
        .expect("partial-row query");
    assert_eq!(partial, 0, "a scan holds a partial result");
    let counts = store.counts().expect("counts");
    assert!(counts.running <= 1, "{counts:?}");
    // Every recorded number is the one that was written.
    for rec in store.recent(usize::MAX).expect("recent") {
        let seed = scan_index(&rec.path);
        match rec.status {
            ScanStatus::Ok => {
                let expected = outcome(seed, REFS);
                assert_eq!(rec.ranks, expected.ranks, "{}", rec.path);
                assert_eq!(rec.cleaning, expected.cleaning);
                let best = expected
                    .distances
                    .iter()
                    .map(|d| d.distance)
                    .fold(f64::INFINITY, f64::min);
                assert_eq!(rec.nearest.first().map(|n| n.distance), Some(best));
            }
            ScanStatus::Error => assert_eq!(rec.error, Some(format!("bad scan {seed}"))),
            ScanStatus::Pending | ScanStatus::Running => {}
            ScanStatus::Duplicate => panic!("{}: no duplicates were written", rec.path),
            ScanStatus::Superseded => panic!("{}: no content changed", rec.path),
        }
    }
    (counts.ok, counts.error)
}

#[test]
fn killed_writer_leaves_only_whole_results() {
    let dir = tempfile::tempdir().expect("temp dir");
    let db = dir.path().join("crash.sqlite");
    let exe = std::env::current_exe().expect("test binary path");
    let mut rng = rand::thread_rng();
    let mut finished_before = 0;
    let mut requeued_total = 0;
    for round in 0..ROUNDS {
        let mut child = Command::new(&exe)
            .args([
                // Test names in the one test crate carry their module.
                "store_crash::crash_child_writer",
                "--exact",
                "--ignored",
                "--test-threads=1",
            ])
            .env(CHILD_ENV, &db)
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("spawn child");
        // Wait for the child to commit at least one more scan, then kill it
        // after a random delay.
        let start = Instant::now();
        loop {
            if let Some(status) = child.try_wait().expect("child status") {
                panic!("child exited on its own: {status}");
            }
            let done = if db.exists() {
                Store::open(&db)
                    .and_then(|s| s.counts())
                    .map(|c| c.ok + c.error)
                    .unwrap_or(0)
            } else {
                0
            };
            if done > finished_before {
                break;
            }
            assert!(
                start.elapsed() < Duration::from_secs(120),
                "child made no progress"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        std::thread::sleep(Duration::from_millis(rng.gen_range(0..400)));
        child.kill().expect("SIGKILL child");
        let status = child.wait().expect("reap child");
        assert!(!status.success(), "round {round}: child was not killed");

        let (ok, error) = check_database(&db);
        assert!(ok + error > finished_before, "round {round}: no progress");
        finished_before = ok + error;
        let mut store = Store::open(&db).expect("reopen");
        requeued_total += store.requeue_running().expect("requeue");
    }
    // After the last kill, finish the queue in-process: every enqueued scan
    // ends with exactly one outcome.
    let mut store = Store::open(&db).expect("final open");
    while let Some(job) = store.claim_next().expect("claim") {
        let seed = scan_index(&job.path);
        store
            .complete(job.scan_id, &outcome(seed, REFS))
            .expect("complete");
    }
    let (ok, error) = check_database(&db);
    let records = store.recent(usize::MAX).expect("recent");
    assert_eq!(ok + error, records.len() as u64);
    let conn = Connection::open(&db).expect("raw");
    let distances: i64 = conn
        .query_row("SELECT count(*) FROM distance", [], |r| r.get(0))
        .expect("count");
    assert_eq!(
        distances as u64,
        ok * REFS as u64,
        "a scan was recorded twice"
    );
    eprintln!(
        "{ROUNDS} kills: {ok} ok, {error} error scans, {requeued_total} interrupted jobs requeued"
    );
}
