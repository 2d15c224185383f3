//! Many scans dropped at once: each identified exactly once, memory bounded.
//! `MORPHOID_DAEMON_SCANS` sets the count (default 200).

mod daemon_support;

use daemon_support::*;
use morphoid::store::ScanStatus;
use std::time::{Duration, Instant};

#[test]
fn scans_dropped_at_once_are_all_identified_once_in_bounded_memory() {
    let n: usize = std::env::var("MORPHOID_DAEMON_SCANS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(200);
    let env = env(1.0, "", "");
    // Written elsewhere, then moved in together.
    let staging = env.root.join("staging");
    std::fs::create_dir_all(&staging).unwrap();
    for i in 0..n {
        std::fs::write(
            staging.join(format!("s{i:03}.ply")),
            scan_bytes(i, 2000 + i as u64),
        )
        .unwrap();
    }
    let d = Daemon::start(&env);
    let started = Instant::now();
    for i in 0..n {
        let name = format!("s{i:03}.ply");
        std::fs::rename(staging.join(&name), env.export.join(&name)).unwrap();
    }
    let mut peak_kb = 0;
    let done = wait_until(Duration::from_secs(60 + 10 * n as u64), || {
        peak_kb = peak_kb.max(d.peak_rss_kb().unwrap_or(0));
        finished(&env.db) >= n
    });
    assert!(
        done,
        "{} of {n} finished\n{}",
        finished(&env.db),
        d.log_text()
    );
    let took = started.elapsed().as_secs_f64();
    std::thread::sleep(Duration::from_secs(2));
    peak_kb = peak_kb.max(d.peak_rss_kb().unwrap_or(0));
    let r = rows(&env.db);
    assert_eq!(r.len(), n);
    let mut paths: Vec<&str> = r.iter().map(|s| s.path.as_str()).collect();
    paths.sort();
    paths.dedup();
    assert_eq!(paths.len(), n, "a file was queued twice");
    assert!(
        r.iter()
            .all(|s| s.status == ScanStatus::Ok && s.attempts == 1),
        "{r:?}"
    );
    let correct = r
        .iter()
        .filter(|s| {
            let i: usize = s.path.rsplit('s').next().unwrap()[..3].parse().unwrap();
            genus_of(s) == Some(genus(i))
        })
        .count();
    eprintln!(
        "{n} scans in {took:.1} s ({:.2} s each), {correct} genera right, peak RSS {} MB",
        took / n as f64,
        peak_kb / 1024
    );
    assert!(correct * 10 >= n * 9, "{correct} of {n} right");
    assert!(peak_kb > 0 && peak_kb < 300 * 1024, "peak RSS {peak_kb} kB");
}
