//! Soak benchmark of the daemon under storage faults (issue 16): scans
//! arrive in the export folder at random intervals while faults are
//! injected at random — the database's file system full for a while (a
//! tmpfs that is filled, needs root), the database locked by another
//! process for a while, `kill -9` of the daemon and a restart. Reports
//! scans lost, scans recorded twice, the longest time from a fault
//! clearing to every file that arrived before it being finished, the
//! daemon's peak resident memory, and log lines per minute during faults
//! (other than the one result line per scan recorded; a fault shorter
//! than a minute counts its lines as that minute's). The daemon's logs
//! are kept in `target/soak-logs`.
//!
//! Uses the 116 PNAS teeth as the library when `../shared/data/pnas-teeth`
//! is beside the project (a synthetic library otherwise); scans are small
//! synthetic crowns. Not part of CI:
//!
//! `MORPHOID_SOAK_SCANS=2000 cargo bench --bench soak`
//!
//! Knobs (environment): `MORPHOID_SOAK_LIBRARY` (`synthetic` for a
//! synthetic library even where the teeth are beside the project: quicker
//! scans, the same faults), `MORPHOID_SOAK_PER_GENUS` (references per
//! genus of the synthetic library, 20), `MORPHOID_SOAK_SCANS` (2000), `MORPHOID_SOAK_INTERVAL`
//! (mean seconds between arrivals, 1.0), `MORPHOID_SOAK_VERTICES` (scan
//! size, 400), `MORPHOID_SOAK_TARGET` (`[clean] target_vertices`, 5000),
//! `MORPHOID_SOAK_SEED` (1), `MORPHOID_SOAK_TMPFS` (size of the file system
//! that holds the database and the results folder, `8g`: a scan's result
//! files take about 2.5 MB).

use morphoid_data::mesh_io;
use morphoid_synth::mesh::{self as synth, LibrarySpec, RigidMotion, CROWN_GENERA};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rusqlite::Connection;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[allow(dead_code)]
#[path = "../tests/it/support/mod.rs"]
mod support;

use support::daemon::{Daemon, Env};
use support::faults::{fill, Mount};

fn knob<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// A fault in progress.
enum Fault {
    Full { filler: PathBuf },
    Locked { conn: Connection },
}

/// What is measured per fault.
struct Episode {
    kind: &'static str,
    started: Instant,
    cleared: Option<Instant>,
    log_lines: usize,
    /// Files that arrived before the fault cleared, and when all of them
    /// were finished.
    waiting_for: usize,
    drained: Option<Duration>,
    /// Files finished when the fault cleared, and how long until the next
    /// one finished (work resumed).
    finished_at_clear: usize,
    resumed: Option<Duration>,
}

fn main() {
    // `cargo bench` passes `--bench`; nothing else is taken.
    let n: usize = knob("MORPHOID_SOAK_SCANS", 2000);
    let interval: f64 = knob("MORPHOID_SOAK_INTERVAL", 1.0);
    let vertices: usize = knob("MORPHOID_SOAK_VERTICES", 400);
    let target: usize = knob("MORPHOID_SOAK_TARGET", 5000);
    let seed: u64 = knob("MORPHOID_SOAK_SEED", 1);
    let root_user = is_root();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);

    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().to_path_buf();
    let synthetic = std::env::var("MORPHOID_SOAK_LIBRARY").is_ok_and(|v| v == "synthetic");
    let per_genus: usize = knob("MORPHOID_SOAK_PER_GENUS", 20);
    let teeth = if synthetic {
        None
    } else {
        support::data::teeth_dir_if_present()
    };
    let library = match teeth {
        Some(d) => d,
        None => {
            let dir = root.join("library");
            let spec = LibrarySpec {
                per_genus,
                target_vertices: target,
                seed: 3,
                random_pose: true,
            };
            synth::write_synthetic_library(&dir, &spec).unwrap();
            dir
        }
    };
    let export = root.join("export");
    std::fs::create_dir_all(&export).unwrap();
    let dbdir = root.join("dbfs");
    // The database and the results folder share one file system, as
    // on a lab server's data disk: when it fills, the result files (about
    // 2.5 MB a scan, mostly the report) fail at once, and the database once
    // its write-ahead log needs to grow.
    let _mount =
        root_user.then(|| Mount::tmpfs(&dbdir, &knob("MORPHOID_SOAK_TMPFS", "8g".to_string())));
    std::fs::create_dir_all(&dbdir).unwrap();
    let db = dbdir.join("db.sqlite");
    let results = dbdir.join("results");
    let cache = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/target/soak-cache"));
    let config = root.join("morphoid.toml");
    std::fs::write(
        &config,
        format!(
            "[watch]\ndir = {export:?}\nsettle_seconds = 0.3\n\
             [library]\ndir = {library:?}\nranks = [\"order\", \"family\", \"genus\"]\ncache = {cache:?}\n\
             [database]\npath = {db:?}\n[results]\ndir = {results:?}\n\
             [clean]\ntarget_vertices = {target}\n"
        ),
    )
    .unwrap();
    let env = Env {
        tmp,
        root: root.clone(),
        export: export.clone(),
        db: db.clone(),
        config,
    };

    println!("soak: {n} scans of {vertices} vertices, mean interval {interval} s, library {}, target_vertices {target}, disk-full faults: {}",
        library.display(), if root_user { "yes (tmpfs)" } else { "no (needs root)" });
    let t0 = Instant::now();
    let mut daemon = Daemon::start(&env);
    println!(
        "daemon ready after {:.0} s ({} references)",
        t0.elapsed().as_secs_f64(),
        daemon.references()
    );
    let mut peak_rss_kb = 0u64;
    let mut kills = 0usize;
    let mut placed: Vec<String> = Vec::new();
    let mut episodes: Vec<Episode> = Vec::new();
    let mut fault: Option<(Fault, Instant)> = None;
    let staging = root.join("staging");
    std::fs::create_dir_all(&staging).unwrap();
    let started = Instant::now();

    let mut i = 0;
    let mut next_arrival = Instant::now();
    while i < n || fault.is_some() {
        // Arrivals.
        if i < n && Instant::now() >= next_arrival {
            let name = format!("s{i:05}.ply");
            let genus = &CROWN_GENERA[i % CROWN_GENERA.len()];
            let crown = synth::crown(genus, 10_000 + i as u64, vertices);
            let posed = RigidMotion::random(i as u64, 20.0).apply(&crown);
            let staged = staging.join(&name);
            mesh_io::save(&staged, &posed).unwrap();
            std::fs::rename(&staged, export.join(&name)).unwrap();
            placed.push(name);
            i += 1;
            next_arrival =
                Instant::now() + Duration::from_secs_f64(rng.gen_range(0.0..2.0 * interval));
        }
        // Faults: start one now and then, end it after its time.
        match &fault {
            // One fault at a time, each after the last one drained.
            None if i < n
                && episodes.last().is_none_or(|e| e.drained.is_some())
                && rng.gen_bool(0.003) =>
            {
                let kinds: &[&str] = if root_user {
                    &["full", "locked", "kill"]
                } else {
                    &["locked", "kill"]
                };
                let kind = kinds[rng.gen_range(0..kinds.len())];
                let lasts = Duration::from_secs_f64(rng.gen_range(5.0..25.0));
                let lines = fault_lines(&daemon.log_text(), &export);
                let mut ep = Episode {
                    kind,
                    started: Instant::now(),
                    cleared: None,
                    log_lines: lines,
                    waiting_for: 0,
                    drained: None,
                    finished_at_clear: 0,
                    resumed: None,
                };
                match kind {
                    "full" => {
                        let filler = fill(&dbdir, "filler");
                        fault = Some((Fault::Full { filler }, Instant::now() + lasts));
                    }
                    "locked" => {
                        let conn = Connection::open(&db).unwrap();
                        conn.busy_timeout(Duration::from_secs(30)).unwrap();
                        conn.execute_batch("BEGIN EXCLUSIVE").unwrap();
                        fault = Some((Fault::Locked { conn }, Instant::now() + lasts));
                    }
                    _ => {
                        peak_rss_kb = peak_rss_kb.max(daemon.peak_rss_kb().unwrap_or(0));
                        let _ = daemon.child.kill();
                        let _ = daemon.child.wait();
                        kills += 1;
                        std::thread::sleep(Duration::from_secs_f64(rng.gen_range(0.5..3.0)));
                        daemon = Daemon::start(&env);
                        ep.log_lines = fault_lines(&daemon.log_text(), &export);
                        ep.cleared = Some(Instant::now());
                        ep.waiting_for = placed.len();
                        ep.finished_at_clear = count_true(&finished_count(&db, &placed));
                    }
                }
                episodes.push(ep);
            }
            Some((_, until)) if Instant::now() >= *until => {
                let (f, _) = fault.take().unwrap();
                let ep = episodes.last_mut().unwrap();
                ep.log_lines = fault_lines(&daemon.log_text(), &export) - ep.log_lines;
                match f {
                    Fault::Full { filler } => std::fs::remove_file(filler).unwrap(),
                    Fault::Locked { conn } => conn.execute_batch("COMMIT").unwrap(),
                }
                ep.cleared = Some(Instant::now());
                ep.waiting_for = placed.len();
                ep.finished_at_clear = count_true(&finished_count(&db, &placed));
            }
            _ => {}
        }
        // Resumed and drained, for the faults that cleared.
        if episodes
            .iter()
            .any(|e| e.cleared.is_some() && (e.drained.is_none() || e.resumed.is_none()))
        {
            note_progress(&mut episodes, &finished_count(&db, &placed));
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    // Let the queue drain.
    let end = Instant::now() + Duration::from_secs(1800);
    while Instant::now() < end && !finished_count(&db, &placed).iter().all(|&d| d) {
        std::thread::sleep(Duration::from_millis(500));
        note_progress(&mut episodes, &finished_count(&db, &placed));
    }
    std::thread::sleep(Duration::from_secs(3));
    peak_rss_kb = peak_rss_kb.max(daemon.peak_rss_kb().unwrap_or(0));
    let wall = started.elapsed();

    // The record.
    let conn = Connection::open(&db).unwrap();
    let mut rows: BTreeMap<String, Vec<String>> = BTreeMap::new();
    {
        let mut stmt = conn.prepare("SELECT path, status FROM scan").unwrap();
        let it = stmt
            .query_map([], |r| Ok((r.get::<_, String>(0)?, r.get::<_, String>(1)?)))
            .unwrap();
        for row in it {
            let (path, status) = row.unwrap();
            let name = Path::new(&path)
                .file_name()
                .unwrap()
                .to_string_lossy()
                .into_owned();
            rows.entry(name).or_default().push(status);
        }
    }
    let lost = placed
        .iter()
        .filter(|p| {
            !rows.get(*p).is_some_and(|s| {
                s.iter()
                    .any(|s| s == "ok" || s == "error" || s == "duplicate")
            })
        })
        .count();
    let duplicated = rows.values().filter(|s| s.len() > 1).count();
    let errors = rows.values().flatten().filter(|s| *s == "error").count();
    println!(
        "\nscans placed: {}, recorded: {}, errors: {errors}",
        placed.len(),
        rows.len()
    );
    println!("lost: {lost}");
    println!("duplicated: {duplicated}");
    println!(
        "faults: {} (kill -9: {kills}), wall time {:.0} s",
        episodes.len(),
        wall.as_secs_f64()
    );
    let mut worst = Duration::ZERO;
    let mut worst_resume = Duration::ZERO;
    let mut worst_rate: f64 = 0.0;
    for e in &episodes {
        let lasted = e.cleared.map(|c| c - e.started).unwrap_or_default();
        let drained = e
            .drained
            .map_or("never".to_string(), |d| format!("{:.1} s", d.as_secs_f64()));
        worst = worst.max(e.drained.unwrap_or(Duration::MAX));
        if let Some(r) = e.resumed {
            worst_resume = worst_resume.max(r);
        }
        let resumed = e
            .resumed
            .map_or("-".to_string(), |d| format!("{:.1} s", d.as_secs_f64()));
        let rate = if e.kind == "kill" {
            None
        } else {
            // A fault shorter than a minute: its lines are that minute's.
            Some(e.log_lines as f64 / (lasted.as_secs_f64() / 60.0).max(1.0))
        };
        if let Some(r) = rate {
            worst_rate = worst_rate.max(r);
        }
        println!(
            "  {:>6} at {:>6.0} s for {:>4.1} s: next scan finished {resumed} and all earlier ones {drained} after it cleared; log lines during it: {}",
            e.kind,
            (e.started - started).as_secs_f64(),
            lasted.as_secs_f64(),
            if e.kind == "kill" { "-".to_string() } else { format!("{} ({:.1}/min)", e.log_lines, rate.unwrap_or(0.0)) }
        );
    }
    println!(
        "longest fault-clear → drained: {:.1} s",
        worst.as_secs_f64()
    );
    println!("peak RSS: {:.0} MB", peak_rss_kb as f64 / 1024.0);
    println!("log lines per minute during faults (worst; scans' own result lines not counted): {worst_rate:.1}");
    // The daemon's logs, for reading after the temporary folder is gone.
    let keep = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/target/soak-logs"));
    let _ = std::fs::remove_dir_all(&keep);
    if std::fs::create_dir_all(&keep).is_ok() {
        for entry in std::fs::read_dir(&root).into_iter().flatten().flatten() {
            let name = entry.file_name();
            if name.to_string_lossy().ends_with(".log") {
                let _ = std::fs::copy(entry.path(), keep.join(&name));
            }
        }
        println!("daemon logs kept in {}", keep.display());
    }
}

/// Lines of the daemon's log that are not a scan's own result line (one
/// INFO line per scan recorded, `<path>: order=…`, which a fault does
/// not cause): the fault's and the recovery's state changes.
fn fault_lines(log: &str, export: &Path) -> usize {
    let prefix = export.to_string_lossy().into_owned();
    log.lines()
        .filter(|l| {
            !(l.contains(" INFO ") && l.contains(prefix.as_str()) && l.contains(": order="))
        })
        .count()
}

/// For each fault that cleared: when the next file finished after it
/// (work resumed) and when every file that arrived before it cleared had
/// finished (drained). `done` holds, per placed file, whether it finished.
fn note_progress(episodes: &mut [Episode], done: &[bool]) {
    let n_done = count_true(done);
    for e in episodes.iter_mut().filter(|e| e.cleared.is_some()) {
        if e.resumed.is_none() && n_done > e.finished_at_clear {
            e.resumed = e.cleared.map(|c| c.elapsed());
        }
        if e.drained.is_none() && done.iter().take(e.waiting_for).all(|&d| d) {
            e.drained = e.cleared.map(|c| c.elapsed());
        }
    }
}

fn count_true(v: &[bool]) -> usize {
    v.iter().filter(|&&b| b).count()
}

/// For each placed file, whether it has a finished row.
fn finished_count(db: &Path, placed: &[String]) -> Vec<bool> {
    let Ok(conn) = Connection::open_with_flags(db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
    else {
        return vec![false; placed.len()];
    };
    let mut done = std::collections::HashSet::new();
    if let Ok(mut stmt) =
        conn.prepare("SELECT path FROM scan WHERE status IN ('ok', 'error', 'duplicate')")
    {
        if let Ok(it) = stmt.query_map([], |r| r.get::<_, String>(0)) {
            for p in it.flatten() {
                if let Some(n) = Path::new(&p).file_name() {
                    done.insert(n.to_string_lossy().into_owned());
                }
            }
        }
    }
    placed.iter().map(|p| done.contains(p)).collect()
}

/// Whether the bench runs as root (mounts a tmpfs for the full-disk fault).
fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("Uid:"))
                .and_then(|l| l.split_whitespace().nth(2).map(|u| u == "0"))
        })
        .unwrap_or(false)
}
