//! The write-ahead log stays bounded (issue 30): 1,000 scans queued,
//! claimed and completed against 116 references on a connection set up as
//! the daemon's (a checkpoint every 16 pages, and after every scan), never
//! let the log file grow past [`WAL_BOUND`].

use crate::support::store::{outcome, register_references};
use morphoid_data::hash::content_hash;
use morphoid_service::store::Store;

/// The bound the log must keep: far below SQLite's default of a 4 MB log
/// before its first checkpoint.
const WAL_BOUND: u64 = 256 * 1024;

#[test]
fn the_log_stays_bounded_over_a_thousand_scans() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("db.sqlite");
    let wal = dir.path().join("db.sqlite-wal");
    let mut store = Store::open(&db).unwrap();
    store.set_result_files(true);
    store.set_wal_autocheckpoint(16).unwrap();
    register_references(&mut store, 116);
    let size = || std::fs::metadata(&wal).map(|m| m.len()).unwrap_or(0);
    let mut largest = size();
    for i in 0..1000u64 {
        let bytes = format!("scan {i}");
        store
            .enqueue(
                &format!("export/s{i}.ply"),
                &content_hash(bytes.as_bytes()),
                9,
            )
            .unwrap();
        largest = largest.max(size());
        let job = store.claim_next().unwrap().unwrap();
        largest = largest.max(size());
        store.complete(job.scan_id, &outcome(i, 116)).unwrap();
        largest = largest.max(size());
        // As the daemon's worker does after recording each scan.
        store.checkpoint_without_waiting().unwrap();
        store.files_written(job.scan_id).unwrap();
        largest = largest.max(size());
    }
    let db_size = std::fs::metadata(&db).unwrap().len();
    println!("largest log {largest} bytes over 1000 scans; database {db_size} bytes");
    assert!(
        largest <= WAL_BOUND,
        "the log reached {largest} bytes (bound {WAL_BOUND})"
    );
    assert_eq!(store.counts().unwrap().ok, 1000);
    // A checkpoint leaves nothing in the log.
    assert!(store.checkpoint().unwrap());
    assert_eq!(size(), 0);
}

/// The daemon's checkpoints never wait for a reader (the web console reads
/// all the time under load): beside a reader that holds an old snapshot,
/// one returns "not complete" at once, although the connection's busy
/// timeout is a minute; the log is cut once the reader is done.
#[test]
fn a_checkpoint_beside_a_reader_does_not_wait_for_it() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("db.sqlite");
    let wal = dir.path().join("db.sqlite-wal");
    let mut store = Store::open(&db).unwrap();
    store
        .set_busy_timeout(std::time::Duration::from_secs(60))
        .unwrap();
    store
        .enqueue("export/a.ply", &content_hash(b"a"), 1)
        .unwrap();
    let reader = rusqlite::Connection::open(&db).unwrap();
    reader.execute_batch("BEGIN").unwrap();
    let seen: i64 = reader
        .query_row("SELECT count(*) FROM scan", [], |r| r.get(0))
        .unwrap();
    assert_eq!(seen, 1);
    store
        .enqueue("export/b.ply", &content_hash(b"b"), 1)
        .unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    let worker = std::thread::spawn(move || {
        let done = store.checkpoint_without_waiting().unwrap();
        tx.send(done).unwrap();
        store
    });
    // Far less than the busy timeout: a checkpoint that waited for the
    // reader would still be waiting.
    let done = rx
        .recv_timeout(std::time::Duration::from_secs(20))
        .expect("the checkpoint waited for the reader");
    assert!(!done, "the reader's snapshot cannot be checkpointed past");
    let mut store = worker.join().unwrap();
    reader.execute_batch("COMMIT").unwrap();
    assert!(store.checkpoint_without_waiting().unwrap());
    assert_eq!(std::fs::metadata(&wal).unwrap().len(), 0);
    assert_eq!(store.counts().unwrap().pending, 2);
}
