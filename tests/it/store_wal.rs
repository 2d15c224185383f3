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
        store.checkpoint().unwrap();
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
