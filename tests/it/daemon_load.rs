//! Many scans dropped at once: each identified exactly once, memory bounded.
//! `MORPHOID_DAEMON_SCANS` sets the count (default 100).

use crate::support::daemon::*;
use morphoid_service::store::ScanStatus;
use std::time::{Duration, Instant};

#[test]
fn scans_dropped_at_once_are_all_identified_once_in_bounded_memory() {
    let n: usize = std::env::var("MORPHOID_DAEMON_SCANS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(100);
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

/// The 116-tooth library, when the data is present: real scans (copies of
/// library teeth, each identified as itself), peak memory under 300 MB.
/// `MORPHOID_DAEMON_REAL_SCANS` sets how many (default 5, at most 116).
#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn the_real_library_identifies_its_own_teeth_in_bounded_memory() {
    let Some(data) = crate::support::data::teeth_dir() else {
        return;
    };
    let n: usize = std::env::var("MORPHOID_DAEMON_REAL_SCANS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5)
        .min(116);
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().to_path_buf();
    let root = root.as_path();
    let export = root.join("export");
    let staging = root.join("staging");
    std::fs::create_dir_all(&export).unwrap();
    std::fs::create_dir_all(&staging).unwrap();
    let mut meshes: Vec<_> = std::fs::read_dir(data.join("meshes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ply"))
        .collect();
    meshes.sort();
    // Spread over the library rather than the first few genera.
    let step = (meshes.len() / n.max(1)).max(1);
    let picked: Vec<_> = meshes.iter().step_by(step).take(n).collect();
    for m in &picked {
        std::fs::copy(m, staging.join(m.file_name().unwrap())).unwrap();
    }
    let db = root.join("db.sqlite");
    let config = root.join("m.toml");
    // Without the calibration: it compares all 6,670 pairs of references
    // once per library (minutes), and this test is about identification's
    // memory; the calibration has its own tests (library_confidence).
    std::fs::write(
        &config,
        format!(
            "[watch]\ndir = {export:?}\nsettle_seconds = 1\n[library]\ndir = {data:?}\ncache = {:?}\n\
             calibrate = false\n\
             [database]\npath = {db:?}\n",
            root.join("cache")
        ),
    )
    .unwrap();
    let env = Env {
        tmp,
        root: root.to_path_buf(),
        export: export.clone(),
        db: db.clone(),
        config,
    };
    let loaded = Instant::now();
    let d = Daemon::start(&env);
    eprintln!(
        "library of {} loaded in {:.1} s",
        d.references(),
        loaded.elapsed().as_secs_f64()
    );
    let started = Instant::now();
    for m in &picked {
        let name = m.file_name().unwrap();
        std::fs::rename(staging.join(name), export.join(name)).unwrap();
    }
    let mut peak_kb = 0;
    let done = wait_until(Duration::from_secs(120 + 60 * n as u64), || {
        peak_kb = peak_kb.max(d.peak_rss_kb().unwrap_or(0));
        finished(&db) >= picked.len()
    });
    assert!(done, "{}", d.log_text());
    let took = started.elapsed().as_secs_f64();
    peak_kb = peak_kb.max(d.peak_rss_kb().unwrap_or(0));
    let r = rows(&db);
    assert_eq!(r.len(), picked.len());
    for s in &r {
        assert_eq!(s.status, ScanStatus::Ok, "{s:?}");
        let stem = std::path::Path::new(&s.path)
            .file_stem()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        assert_eq!(
            s.nearest.first().map(|x| x.reference.as_str()),
            Some(stem.as_str())
        );
    }
    eprintln!(
        "{} real scans in {took:.1} s ({:.1} s each), peak RSS {} MB",
        r.len(),
        took / r.len() as f64,
        peak_kb / 1024
    );
    assert!(peak_kb > 0 && peak_kb < 300 * 1024, "peak RSS {peak_kb} kB");
}
