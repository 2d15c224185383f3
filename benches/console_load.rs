//! The web console under load (issue 32's load target): the overview
//! (`GET /`) and `GET /api/v1/scans?genus=…` served by the real `morphoid
//! run` from a database of 100,000 identified scans, to 200 concurrent
//! keep-alive connections on loopback; and the daemon's identification
//! rate while the console is under that load, against its rate without it.
//! The target: p95 under 50 ms, and the rate within 10 % of the unloaded
//! one. Nothing is asserted: the figures are printed (and written as CSV
//! when asked).
//!
//! Everything is made in a temporary folder, never in the repository:
//!
//! - The database: 100 references (`bench-ref-000` …, 20 genera of 10
//!   families, one order; 5 references a genus), then [`SEED_SCANS`] scans
//!   queued, claimed and finished through the project's own `Store` API
//!   (each with its 3 rank results with confidence, 10 distance rows,
//!   timings and cleaning; about 2 % failed; genera drawn with Zipf-like
//!   weights, so that some are common and some rare). Filling 100,000 scans
//!   one transaction (and fsync) at a time would take long, so the rest are
//!   copies of those, made with rusqlite in ONE transaction: new ids, paths
//!   (`export/batch-NNNN/…`) and content hashes (random, 64 hex digits),
//!   their result and distance rows copied with the new ids, and every
//!   scan's queue, start and finish times spread over the two years before
//!   now in id order. The copies are then read back through the `Store`
//!   API (the scans finished, the newest, a genus search deep among the
//!   copies, one copy by id) and checked to be whole scans. No `ANALYZE` is run: the daemon's own
//!   databases never have statistics either.
//! - The daemon: `morphoid run` on that database, with a synthetic library
//!   (`morphoid_synth`, 4 crowns of each of 5 genera, 3000 vertices), a
//!   watch folder, and `[http] listen = "127.0.0.1:0"` (loopback only; the
//!   port is read from its log) with `public_read = true`. The bench waits
//!   until the library's calibration is over before measuring.
//!
//! The measurement, in one run:
//!
//! 1. Identification without load: [`DEFAULT_IDENTIFY`] new synthetic
//!    crowns (3000 vertices, posed at random) moved into the watch folder
//!    at once; the rate is their number over the time from the first one's
//!    start to the last one's finish (the database's own timestamps).
//! 2. Each load of `MORPHOID_BENCH_THINK_MS` in turn:
//!    `MORPHOID_BENCH_CONNECTIONS` connections (tokio tasks on a 2-thread
//!    runtime, each with a reqwest client of its own that keeps its one
//!    connection alive) each send requests, alternately `GET /` and `GET
//!    /api/v1/scans?genus=G` (G in turn over the 20 genera), each latency
//!    taken from sending to the last byte of the body. After a warm-up of
//!    [`WARM_UP`] (not recorded), another batch of crowns is dropped; the
//!    load goes on for `MORPHOID_BENCH_SECONDS` and at least until that
//!    batch is identified (at most [`MAX_LOAD`]).
//! 3. Identification without load again, one more batch: the machine's
//!    drift shows as a difference between 1 and 3, and each loaded rate is
//!    compared with their mean.
//!
//! The first load (think time 0) is closed-loop: each connection sends its
//! next request as soon as the last one is answered, so throughput and
//! latency are tied (Little's law: mean latency = connections /
//! throughput): it measures the console saturated. The second pauses 1 s
//! between a connection's requests (200 requests a second offered by 200
//! connections), a heavier use than a browser's live overview makes (it
//! asks `/api/v1/changes` every 2 s and the page only when that changes).
//!
//! The client runs on the same machine as the daemon and takes its share
//! of the CPU; on a machine of few cores the figures are those of client,
//! console and identification together.
//!
//! ```sh
//! cargo bench --bench console_load
//! MORPHOID_BENCH_SCANS=20000 MORPHOID_BENCH_SECONDS=10 cargo bench --bench console_load
//! ```
//!
//! Environment:
//! - `MORPHOID_BENCH_SCANS`: scans in the database (default 100000);
//! - `MORPHOID_BENCH_CONNECTIONS`: concurrent connections (default 200);
//! - `MORPHOID_BENCH_SECONDS`: the load's least duration after the warm-up
//!   (default 20);
//! - `MORPHOID_BENCH_THINK_MS`: the loads, each a pause (ms) of every
//!   connection between its requests, comma-separated (default `0,1000`);
//! - `MORPHOID_BENCH_IDENTIFY`: crowns in each identification batch
//!   (default 16);
//! - `MORPHOID_BENCH_SEED`: the seed of everything made (default 32);
//! - `MORPHOID_BENCH_CLIENT_NICE`: nice steps the load client's threads
//!   take below the daemon's (default 0), as when the browsers are on
//!   other machines and take none of its CPU;
//! - `MORPHOID_BENCH_CSV`: also write the figures as CSV to this file;
//! - `MORPHOID_BENCH_WORK`: a folder to work in, kept at the end, instead of
//!   a temporary one (its database is made again each run);
//! - `TMPDIR`: where the temporary folder is made (removed at the end).

use anyhow::{bail, ensure, Context, Result};
use morphoid_data::atomic_write::write_atomic;
use morphoid_data::hash::content_hash;
use morphoid_data::mesh_io;
use morphoid_service::identify::{Confidence, DistanceRow, RankResult, ScanOutcome};
use morphoid_service::store::{Labels, ScanQuery, ScanStatus, Store};
use morphoid_synth::mesh::{self as synth, LibrarySpec, RigidMotion, CROWN_GENERA};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rusqlite::{params, Connection};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[allow(dead_code)]
#[path = "../tests/it/support/mod.rs"]
mod support;

use support::daemon::{wait_until, Daemon, Env};

/// Scans in the database unless `MORPHOID_BENCH_SCANS` says otherwise.
const DEFAULT_SCANS: usize = 100_000;
/// Scans made through the `Store` API; the rest are copies of these.
const SEED_SCANS: usize = 400;
/// References in the database.
const REFERENCES: usize = 100;
/// Distance rows of each scan.
const DISTANCES: usize = 10;
/// Connections unless `MORPHOID_BENCH_CONNECTIONS` says otherwise.
const DEFAULT_CONNECTIONS: usize = 200;
/// The load's least duration (s) unless `MORPHOID_BENCH_SECONDS` says
/// otherwise.
const DEFAULT_SECONDS: f64 = 20.0;
/// Crowns in each identification batch unless `MORPHOID_BENCH_IDENTIFY`
/// says otherwise.
const DEFAULT_IDENTIFY: usize = 16;
/// The loads unless `MORPHOID_BENCH_THINK_MS` says otherwise: back to
/// back, and a request a second on each connection.
const DEFAULT_THINK_MS: &str = "0,1000";
/// Seed unless `MORPHOID_BENCH_SEED` says otherwise.
const DEFAULT_SEED: u64 = 32;
/// Load before the latencies are recorded (connections opened, caches
/// warm).
const WARM_UP: Duration = Duration::from_secs(2);
/// The load never lasts longer than this, identified or not.
const MAX_LOAD: Duration = Duration::from_secs(900);
/// How long a batch may take to be identified without load.
const BATCH_TIMEOUT: Duration = Duration::from_secs(900);
/// The span of time the scans' dates are spread over (two years).
const SPAN_MS: i64 = 2 * 365 * 86_400_000;
/// The daemon's synthetic crowns' vertex count (library and scans): a
/// scan takes about half a second, so that a batch's rate is measured
/// over seconds, not a few timer ticks.
const VERTICES: usize = 3000;
/// The daemon's library: this many crowns of each synthetic genus.
const LIBRARY_PER_GENUS: usize = 4;

/// The genera of the bench's references and scans, with their families.
const GENERA: [(&str, &str); 20] = [
    ("Ateles", "Atelidae"),
    ("Alouatta", "Atelidae"),
    ("Lagothrix", "Atelidae"),
    ("Cebus", "Cebidae"),
    ("Saimiri", "Cebidae"),
    ("Callithrix", "Callitrichidae"),
    ("Saguinus", "Callitrichidae"),
    ("Aotus", "Aotidae"),
    ("Pithecia", "Pitheciidae"),
    ("Cacajao", "Pitheciidae"),
    ("Macaca", "Cercopithecidae"),
    ("Papio", "Cercopithecidae"),
    ("Colobus", "Cercopithecidae"),
    ("Cercopithecus", "Cercopithecidae"),
    ("Hylobates", "Hylobatidae"),
    ("Pongo", "Hominidae"),
    ("Gorilla", "Hominidae"),
    ("Pan", "Hominidae"),
    ("Lemur", "Lemuridae"),
    ("Galago", "Galagidae"),
];

/// The two endpoints loaded.
const ENDPOINTS: [&str; 2] = ["GET /", "GET /api/v1/scans?genus="];

/// The bench's knobs.
struct Knobs {
    scans: usize,
    connections: usize,
    seconds: f64,
    think: Vec<Duration>,
    identify: usize,
    seed: u64,
    csv: Option<PathBuf>,
    /// Nice steps the load client's threads take below the bench's.
    client_nice: i32,
}

/// Lower the calling thread's priority by `steps` nice steps (0: leave
/// it). Clients on other machines take none of the daemon's CPU; niced,
/// this one takes only what the daemon leaves.
fn lower_thread_priority(steps: i32) {
    if steps == 0 {
        return;
    }
    // SAFETY: plain syscalls on the calling thread, no memory passed.
    unsafe {
        let tid = libc::gettid() as libc::id_t;
        let now = libc::getpriority(libc::PRIO_PROCESS, tid);
        libc::setpriority(libc::PRIO_PROCESS, tid, (now + steps).min(19));
    }
}

/// `name` from the environment, or `default`.
fn knob<T: std::str::FromStr>(name: &str, default: T) -> Result<T>
where
    T::Err: std::fmt::Display,
{
    match std::env::var(name) {
        Ok(v) if !v.trim().is_empty() => v
            .trim()
            .parse()
            .map_err(|e| anyhow::anyhow!("{name}={v:?}: {e}")),
        _ => Ok(default),
    }
}

/// `MORPHOID_BENCH_THINK_MS`: the pauses of the loads, one load each.
fn think_times() -> Result<Vec<Duration>> {
    let text = std::env::var("MORPHOID_BENCH_THINK_MS").unwrap_or_default();
    let text = if text.trim().is_empty() {
        DEFAULT_THINK_MS
    } else {
        text.as_str()
    };
    text.split(',')
        .map(|ms| {
            ms.trim()
                .parse()
                .map(Duration::from_millis)
                .with_context(|| format!("MORPHOID_BENCH_THINK_MS: {ms:?} is not milliseconds"))
        })
        .collect()
}

impl Knobs {
    fn from_env() -> Result<Knobs> {
        let k = Knobs {
            scans: knob("MORPHOID_BENCH_SCANS", DEFAULT_SCANS)?,
            connections: knob("MORPHOID_BENCH_CONNECTIONS", DEFAULT_CONNECTIONS)?,
            seconds: knob("MORPHOID_BENCH_SECONDS", DEFAULT_SECONDS)?,
            think: think_times()?,
            identify: knob("MORPHOID_BENCH_IDENTIFY", DEFAULT_IDENTIFY)?,
            seed: knob("MORPHOID_BENCH_SEED", DEFAULT_SEED)?,
            csv: std::env::var_os("MORPHOID_BENCH_CSV").map(PathBuf::from),
            client_nice: knob("MORPHOID_BENCH_CLIENT_NICE", 0)?,
        };
        ensure!(
            k.scans >= SEED_SCANS,
            "MORPHOID_BENCH_SCANS: at least {SEED_SCANS}"
        );
        ensure!(k.connections >= 1, "MORPHOID_BENCH_CONNECTIONS: at least 1");
        ensure!(k.identify >= 2, "MORPHOID_BENCH_IDENTIFY: at least 2");
        ensure!(
            k.seconds.is_finite() && k.seconds > 0.0,
            "MORPHOID_BENCH_SECONDS: a positive number"
        );
        Ok(k)
    }
}

fn main() -> Result<()> {
    // `cargo bench` passes `--bench`; the knobs are in the environment.
    let knobs = Knobs::from_env()?;
    let (tmp, root) = work_folder()?;
    println!(
        "machine: {} cores, load average {}",
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    println!(
        "console load: {} scans, {} connections, {} s, {} crowns a batch, seed {}, client {} nice steps below, folder {}",
        knobs.scans,
        knobs.connections,
        knobs.seconds,
        knobs.identify,
        knobs.seed,
        knobs.client_nice,
        root.display()
    );

    let db = root.join("db.sqlite");
    for suffix in ["", "-wal", "-shm"] {
        let file = PathBuf::from(format!("{}{suffix}", db.display()));
        if file.exists() {
            std::fs::remove_file(&file).with_context(|| format!("removing {}", file.display()))?;
        }
    }
    let t = Instant::now();
    seed_database(&db, knobs.seed)?;
    let seeded = t.elapsed();
    let t = Instant::now();
    replicate(&db, knobs.scans)?;
    println!(
        "database: {SEED_SCANS} scans through the Store in {:.1} s, {} in all after copying in {:.1} s ({:.0} MB)",
        seeded.as_secs_f64(),
        knobs.scans,
        t.elapsed().as_secs_f64(),
        std::fs::metadata(&db).map(|m| m.len()).unwrap_or(0) as f64 / 1e6
    );
    check_copies(&db, knobs.scans)?;

    let env = daemon_env(tmp, &root, &db)?;
    let t = Instant::now();
    let daemon = Daemon::start(&env);
    let base = console_address(&daemon)?;
    let client_nice = knobs.client_nice;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .on_thread_start(move || lower_thread_priority(client_nice))
        .enable_all()
        .build()
        .context("tokio runtime")?;
    let calibration = runtime.block_on(wait_calibrated(&base))?;
    println!(
        "daemon ready in {:.1} s ({} references, calibration {calibration}), console at {base}",
        t.elapsed().as_secs_f64(),
        daemon.references()
    );

    let staging = env.root.join("staging");
    std::fs::create_dir_all(&staging).context("staging folder")?;
    let batch = |n: usize| Batch {
        env: &env,
        staging: &staging,
        number: n,
        size: knobs.identify,
        seed: knobs.seed,
    };

    let idle = runtime.block_on(idle_latencies(&base))?;
    print_idle(&idle);
    let before = batch(1).run_without_load()?;
    println!("identification without load: {}", before.describe());
    let mut loads = Vec::new();
    for (k, &think) in knobs.think.iter().enumerate() {
        let load = runtime.block_on(load_while_identifying(
            &base,
            daemon.pid(),
            &knobs,
            think,
            batch(2 + k),
        ))?;
        println!(
            "identification under load:   {}",
            load.identified.describe()
        );
        loads.push(load);
    }
    let after = batch(2 + knobs.think.len()).run_without_load()?;
    println!("identification without load: {}", after.describe());

    let unloaded = (before.per_minute() + after.per_minute()) / 2.0;
    println!(
        "\n{} scans in the database, {} connections; identification without load: {:.1} scans/min (mean of {:.1} and {:.1})",
        knobs.scans,
        knobs.connections,
        unloaded,
        before.per_minute(),
        after.per_minute()
    );
    let mut csv = csv_header();
    for load in &loads {
        let rows = latency_rows(&load.samples, load.lasted);
        print_latencies(&rows, load.think);
        let requests = load.samples.len().max(1) as f64;
        println!(
            "CPU meanwhile: console {:.1} s ({:.0} µs a request), identification and the rest of the daemon {:.1} s, load client {:.1} s ({:.0} µs a request)",
            load.cpu.console,
            load.cpu.console * 1e6 / requests,
            load.cpu.daemon_rest,
            load.cpu.client,
            load.cpu.client * 1e6 / requests
        );
        let ratio = load.identified.per_minute() / unloaded;
        println!(
            "identification under this load: {:.1} scans/min, {:.2} of the rate without ({:+.1} %)",
            load.identified.per_minute(),
            ratio,
            (ratio - 1.0) * 100.0
        );
        csv_latencies(&mut csv, &rows, load.think, &knobs);
        csv_identified(&mut csv, "with load", &load.identified, load.think, &knobs);
    }
    csv_idle(&mut csv, &idle, &knobs);
    csv_identified(&mut csv, "without load", &before, Duration::ZERO, &knobs);
    csv_identified(&mut csv, "without load", &after, Duration::ZERO, &knobs);
    if let Some(path) = &knobs.csv {
        write_atomic(path, csv.as_bytes())
            .with_context(|| format!("writing MORPHOID_BENCH_CSV={}", path.display()))?;
        println!("figures written to {}", path.display());
    }
    drop(daemon);
    Ok(())
}

/// The folder worked in: `MORPHOID_BENCH_WORK`, kept, or a new temporary
/// one, removed when the returned guard is dropped.
fn work_folder() -> Result<(Option<tempfile::TempDir>, PathBuf)> {
    if let Some(dir) = std::env::var_os("MORPHOID_BENCH_WORK") {
        let dir = PathBuf::from(dir);
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("MORPHOID_BENCH_WORK={}", dir.display()))?;
        return Ok((None, dir));
    }
    let tmp = tempfile::Builder::new()
        .prefix("morphoid-console-load-")
        .tempdir()
        .context("temporary folder")?;
    let path = tmp.path().to_path_buf();
    Ok((Some(tmp), path))
}

/// Reference `i`'s name.
fn reference_name(i: usize) -> String {
    format!("bench-ref-{i:03}")
}

/// The genus (index into [`GENERA`]) of reference `i`: 5 a genus.
fn genus_of_reference(i: usize) -> usize {
    i % GENERA.len()
}

/// Genera drawn with weights 1/(k+1) (Zipf-like): the commonest about 20
/// times as frequent as the rarest.
fn draw_genus(rng: &mut ChaCha8Rng) -> usize {
    let total: f64 = (1..=GENERA.len()).map(|k| 1.0 / k as f64).sum();
    let mut u = rng.gen_range(0.0..total);
    for k in 0..GENERA.len() {
        u -= 1.0 / (k + 1) as f64;
        if u <= 0.0 {
            return k;
        }
    }
    GENERA.len() - 1
}

/// An identification of a scan of genus `g`, as the daemon records one:
/// distances to the genus's references and to others, the nearest per
/// rank with its runner-up and margin, confidence, timings and cleaning.
fn outcome(g: usize, rng: &mut ChaCha8Rng) -> ScanOutcome {
    let own: Vec<usize> = (0..REFERENCES)
        .filter(|&i| genus_of_reference(i) == g)
        .collect();
    let mut others: Vec<usize> = (0..REFERENCES)
        .filter(|&i| genus_of_reference(i) != g)
        .collect();
    others.shuffle(rng);
    let mut distances = Vec::with_capacity(DISTANCES);
    // The genus's own references are nearer than the others.
    let near = own.iter().map(|&i| (i, 0.02..0.06));
    let far = others
        .iter()
        .take(DISTANCES - own.len())
        .map(|&i| (i, 0.05..0.15));
    for (i, range) in near.chain(far) {
        let forward = rng.gen_range(range);
        let backward = forward + rng.gen_range(0.0..0.004);
        distances.push(DistanceRow {
            reference: reference_name(i),
            forward,
            backward,
            distance: forward.min(backward),
            reflected: rng.gen_bool(0.5),
        });
    }
    distances.sort_by(|a, b| a.distance.total_cmp(&b.distance));
    let nearest = &distances[0];
    let runner_up = (g + 1 + rng.gen_range(0..GENERA.len() - 1)) % GENERA.len();
    let flagged = rng.gen_bool(0.1);
    let (genus, family) = GENERA[g];
    let ranks = [("order", "Primates"), ("family", family), ("genus", genus)]
        .iter()
        .map(|&(rank, taxon)| RankResult {
            rank: rank.into(),
            taxon: taxon.into(),
            reference: nearest.reference.clone(),
            distance: nearest.distance,
            runner_up: (rank == "genus").then(|| GENERA[runner_up].0.to_string()),
            margin: Some(rng.gen_range(0.001..0.03)),
            confidence: Some(Confidence {
                probability: if flagged {
                    rng.gen_range(0.1..0.5)
                } else {
                    rng.gen_range(0.7..1.0)
                },
                novelty: if flagged {
                    rng.gen_range(1.6..4.0)
                } else {
                    rng.gen_range(0.2..1.4)
                },
                novelty_threshold: Some(1.5),
                no_close_match: Some(flagged),
            }),
        })
        .collect();
    let mut timings_ms = BTreeMap::new();
    for (stage, range) in [
        ("load", 5.0..40.0),
        ("clean", 200.0..900.0),
        ("flatten", 100.0..400.0),
        ("compare", 800.0..4000.0),
    ] {
        timings_ms.insert(stage.to_string(), rng.gen_range(range));
    }
    ScanOutcome {
        ranks,
        distances,
        cleaning: serde_json::json!({
            "vertices_before": rng.gen_range(20_000..400_000),
            "vertices_after": 5000,
            "components_removed": rng.gen_range(0..4),
        }),
        timings_ms,
        landmarks: None,
        calibrating: false,
    }
}

/// A new database with the references and [`SEED_SCANS`] scans, made
/// through the `Store` API as the daemon makes them.
fn seed_database(db: &Path, seed: u64) -> Result<()> {
    let mut store = Store::open(db).with_context(|| format!("creating {}", db.display()))?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for i in 0..REFERENCES {
        let (genus, family) = GENERA[genus_of_reference(i)];
        let mut labels = Labels::new();
        labels.insert("order".into(), Some("Primates".into()));
        labels.insert("family".into(), Some(family.into()));
        labels.insert("genus".into(), Some(genus.into()));
        let name = reference_name(i);
        store
            .register_reference(&name, &content_hash(name.as_bytes()), &labels)
            .with_context(|| format!("registering {name}"))?;
        store.mark_reference_prepared(&name)?;
    }
    for i in 0..SEED_SCANS {
        let path = format!("export/seed/scan-{i:04}.ply");
        let bytes = format!("seed {seed} scan {i}");
        let id = store
            .enqueue(
                &path,
                &content_hash(bytes.as_bytes()),
                rng.gen_range(200_000..20_000_000),
            )
            .with_context(|| format!("queueing {path}"))?
            .scan_id();
        let job = store
            .claim(id)?
            .with_context(|| format!("claiming scan {id}"))?;
        if rng.gen_bool(0.02) {
            store.fail(
                job.scan_id,
                &format!("cannot read {path}: truncated binary PLY"),
            )?;
        } else {
            let g = draw_genus(&mut rng);
            store
                .complete(job.scan_id, &outcome(g, &mut rng))
                .with_context(|| format!("recording scan {id}"))?;
        }
    }
    Ok(())
}

/// Copy the seeded scans (ids 1..=[`SEED_SCANS`]) with their result and
/// distance rows until the database holds `total` scans, then spread the
/// scans' times over [`SPAN_MS`] in id order; one transaction.
fn replicate(db: &Path, total: usize) -> Result<()> {
    let mut conn = Connection::open(db).context("opening the database with rusqlite")?;
    let tx = conn.transaction()?;
    let (max_id, rows): (i64, i64) =
        tx.query_row("SELECT max(id), count(*) FROM scan", [], |r| {
            Ok((r.get(0)?, r.get(1)?))
        })?;
    ensure!(
        max_id == SEED_SCANS as i64 && rows == max_id,
        "the seeded scans are not ids 1..={SEED_SCANS} (max {max_id}, {rows} rows)"
    );
    let seed = SEED_SCANS as i64;
    let total = total as i64;
    let columns = "path, content_hash, size, status, error, attempts, created_at, started_at, \
                   finished_at, timings, cleaning, files_due, calibrating";
    let mut copy_scans = tx.prepare(&format!(
        "INSERT INTO scan (id, {columns})
         SELECT id + ?1, replace(path, 'export/seed/', printf('export/batch-%04d/', ?2)),
                lower(hex(randomblob(32))), size + ?2, status, error, attempts, created_at,
                started_at, finished_at, timings, cleaning, files_due, calibrating
         FROM scan WHERE id <= ?3"
    ))?;
    let mut copy_results = tx.prepare(
        "INSERT INTO result (scan_id, ordinal, rank, taxon, reference_id, distance, runner_up,
                             margin, probability, novelty, novelty_threshold, no_close_match)
         SELECT scan_id + ?1, ordinal, rank, taxon, reference_id, distance, runner_up, margin,
                probability, novelty, novelty_threshold, no_close_match
         FROM result WHERE scan_id <= ?2",
    )?;
    let mut copy_distances = tx.prepare(
        "INSERT INTO distance (scan_id, reference_id, forward, backward, distance, reflected)
         SELECT scan_id + ?1, reference_id, forward, backward, distance, reflected
         FROM distance WHERE scan_id <= ?2",
    )?;
    let mut copy = 1i64;
    while copy * seed < total {
        let offset = copy * seed;
        let last = seed.min(total - offset);
        copy_scans.execute(params![offset, copy, last])?;
        copy_results.execute(params![offset, last])?;
        copy_distances.execute(params![offset, last])?;
        copy += 1;
    }
    drop((copy_scans, copy_results, copy_distances));
    // Queued in id order over the span, ending an hour ago; waited up to a
    // minute, identified in 2 to 10 s (spread by the id: reproducible).
    // One statement: a finished scan's finish time is never null (CHECK).
    let step = SPAN_MS / total;
    let start = morphoid_service::store::now_ms() - SPAN_MS - 3_600_000;
    tx.execute(
        "UPDATE scan SET
             created_at = ?1 + id * ?2,
             started_at = ?1 + id * ?2 + 1000 + (id * 7919) % 60000,
             finished_at = CASE WHEN finished_at IS NULL THEN NULL
                           ELSE ?1 + id * ?2 + 1000 + (id * 7919) % 60000
                                + 2000 + (id * 104729) % 8000 END",
        params![start, step],
    )?;
    tx.commit()?;
    Ok(())
}

/// Read the copies back through the `Store` API: every scan finished, the
/// newest, a genus search deep among the copies, one copy by id.
fn check_copies(db: &Path, total: usize) -> Result<()> {
    let mut store = Store::open(db).context("reopening the database")?;
    store
        .check_integrity()
        .context("integrity check of the filled database")?;
    let finished = store.finished_since(0)?;
    ensure!(
        finished == total as u64,
        "{finished} scans finished instead of {total}"
    );
    let newest = store.search_scans(&ScanQuery {
        limit: 1,
        ..ScanQuery::default()
    })?;
    let newest = newest.scans.first().context("no scans read back")?;
    ensure!(
        newest.id == total as i64,
        "newest scan {} instead of {total}",
        newest.id
    );
    let page = store.search_scans(&ScanQuery {
        taxa: vec![("genus".into(), "ateles".into())],
        before_id: Some(total as i64 / 2),
        limit: 50,
        ..ScanQuery::default()
    })?;
    ensure!(
        page.scans.len() == 50,
        "a genus page of {} scans",
        page.scans.len()
    );
    for scan in &page.scans {
        let genus = scan
            .ranks
            .iter()
            .find(|r| r.rank == "genus")
            .map(|r| r.taxon.as_str());
        ensure!(
            scan.status == ScanStatus::Ok
                && scan.ranks.len() == 3
                && genus == Some("Ateles")
                && scan.nearest.len() == 5
                && scan.path.starts_with("export/batch-")
                && scan.finished_at_ms > scan.started_at_ms
                && scan.started_at_ms > Some(scan.created_at_ms),
            "copied scan {} reads back wrong: {scan:?}",
            scan.id
        );
    }
    let middle = store
        .scan(total as i64 / 2 + 1, 5)?
        .context("the middle scan is missing")?;
    ensure!(
        middle.content_hash.len() == 64 && middle.finished_at_ms.is_some(),
        "scan {} reads back wrong: {middle:?}",
        middle.id
    );
    Ok(())
}

/// The daemon's deployment: a synthetic library, the watch folder, the
/// database and a config serving the console on loopback.
fn daemon_env(tmp: Option<tempfile::TempDir>, root: &Path, db: &Path) -> Result<Env> {
    let library = root.join("library");
    let spec = LibrarySpec {
        per_genus: LIBRARY_PER_GENUS,
        target_vertices: VERTICES,
        seed: 3,
        random_pose: true,
    };
    synth::write_synthetic_library(&library, &spec).context("writing the synthetic library")?;
    let export = root.join("export");
    if export.exists() {
        std::fs::remove_dir_all(&export).context("emptying the watch folder")?;
    }
    std::fs::create_dir_all(&export).context("watch folder")?;
    let config = root.join("morphoid.toml");
    std::fs::write(
        &config,
        format!(
            "[watch]\ndir = {export:?}\nsettle_seconds = 0.5\n\
             [library]\ndir = {library:?}\nranks = [\"order\", \"family\", \"genus\"]\ncache = {:?}\n\
             [database]\npath = {db:?}\n[clean]\ntarget_vertices = {VERTICES}\n\
             [http]\nlisten = \"127.0.0.1:0\"\npublic_read = true\n",
            root.join("cache")
        ),
    )
    .context("writing the config")?;
    // `Env` owns the temporary folder; a kept work folder gets an empty
    // temporary one of its own.
    let tmp = match tmp {
        Some(t) => t,
        None => tempfile::tempdir().context("temporary folder")?,
    };
    Ok(Env {
        tmp,
        root: root.to_path_buf(),
        export,
        db: db.to_path_buf(),
        config,
    })
}

/// `http://127.0.0.1:PORT` of the daemon's console, from its log.
fn console_address(daemon: &Daemon) -> Result<String> {
    let mut found = None;
    wait_until(Duration::from_secs(30), || {
        found = daemon
            .log_text()
            .split("web console listening on ")
            .nth(1)
            .and_then(|rest| rest.split_whitespace().next())
            .map(str::to_string);
        found.is_some()
    });
    found.with_context(|| format!("no console address in the log:\n{}", daemon.log_text()))
}

/// Wait until the daemon's calibration is no longer running; its state.
async fn wait_calibrated(base: &str) -> Result<String> {
    let client = reqwest::Client::new();
    let end = Instant::now() + Duration::from_secs(600);
    loop {
        let status: serde_json::Value = client
            .get(format!("{base}/api/v1/status"))
            .send()
            .await
            .and_then(|r| r.error_for_status())
            .context("GET /api/v1/status")?
            .json()
            .await
            .context("GET /api/v1/status: JSON")?;
        let calibration = status["calibration"].as_str().unwrap_or("?").to_string();
        if status["running"] == true && calibration != "calibrating" {
            return Ok(calibration);
        }
        ensure!(Instant::now() < end, "still calibrating after 10 minutes");
        tokio::time::sleep(Duration::from_millis(500)).await;
    }
}

/// One batch of crowns to identify.
struct Batch<'a> {
    env: &'a Env,
    staging: &'a Path,
    number: usize,
    size: usize,
    seed: u64,
}

/// What a batch took.
struct Identified {
    scans: usize,
    /// From the first start to the last finish.
    span: Duration,
    /// Each scan's identification time, sorted.
    each: Vec<Duration>,
}

impl Identified {
    fn per_minute(&self) -> f64 {
        self.scans as f64 * 60.0 / self.span.as_secs_f64().max(1e-3)
    }

    fn describe(&self) -> String {
        let median = self
            .each
            .get(self.each.len() / 2)
            .copied()
            .unwrap_or_default();
        format!(
            "{} scans in {:.1} s: {:.1} scans/min (median {:.2} s a scan)",
            self.scans,
            self.span.as_secs_f64(),
            self.per_minute(),
            median.as_secs_f64()
        )
    }
}

impl Batch<'_> {
    /// Write the crowns beside the watch folder, then move them in at
    /// once; returns the largest scan id before them.
    fn drop_in(&self) -> Result<i64> {
        let conn = Connection::open(&self.env.db)?;
        let before: i64 =
            conn.query_row("SELECT coalesce(max(id), 0) FROM scan", [], |r| r.get(0))?;
        let mut staged = Vec::new();
        for i in 0..self.size {
            // A seed of its own per batch and crown: no content repeats.
            let seed = self.seed * 1_000_000 + (self.number * 1000 + i) as u64;
            let name = format!("load-{}-{i:02}.ply", self.number);
            let path = self.staging.join(&name);
            let genus = &CROWN_GENERA[i % CROWN_GENERA.len()];
            let crown = RigidMotion::random(seed, 20.0).apply(&synth::crown(genus, seed, VERTICES));
            mesh_io::save(&path, &crown).with_context(|| format!("writing {name}"))?;
            staged.push((path, self.env.export.join(&name)));
        }
        for (from, to) in staged {
            std::fs::rename(&from, &to).with_context(|| format!("moving {}", from.display()))?;
        }
        Ok(before)
    }

    /// Whether every scan after `before` is finished; `Some` when all
    /// [`Batch::size`] are.
    fn finished(&self, before: i64) -> Result<Option<Identified>> {
        let conn = Connection::open(&self.env.db)?;
        let mut stmt = conn.prepare(
            "SELECT status, started_at, finished_at FROM scan WHERE id > ?1 AND parent_id IS NULL",
        )?;
        let rows: Vec<(String, Option<i64>, Option<i64>)> = stmt
            .query_map([before], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))?
            .collect::<Result<_, _>>()?;
        let done: Vec<(i64, i64)> = rows
            .iter()
            .filter_map(|(status, s, f)| match (status.as_str(), s, f) {
                ("ok", Some(s), Some(f)) => Some((*s, *f)),
                _ => None,
            })
            .collect();
        if let Some((status, _, _)) = rows
            .iter()
            .find(|(s, _, _)| s == "error" || s == "duplicate")
        {
            bail!("batch {}: a scan ended {status}", self.number);
        }
        if done.len() < self.size {
            return Ok(None);
        }
        let first = done.iter().map(|d| d.0).min().unwrap_or(0);
        let last = done.iter().map(|d| d.1).max().unwrap_or(0);
        let mut each: Vec<Duration> = done
            .iter()
            .map(|&(s, f)| Duration::from_millis(u64::try_from(f - s).unwrap_or(0)))
            .collect();
        each.sort();
        Ok(Some(Identified {
            scans: done.len(),
            span: Duration::from_millis(u64::try_from(last - first).unwrap_or(0)),
            each,
        }))
    }

    /// Drop the batch in and wait until it is identified.
    fn run_without_load(&self) -> Result<Identified> {
        let before = self.drop_in()?;
        let end = Instant::now() + BATCH_TIMEOUT;
        loop {
            if let Some(done) = self.finished(before)? {
                return Ok(done);
            }
            ensure!(
                Instant::now() < end,
                "batch {} not identified in time",
                self.number
            );
            std::thread::sleep(Duration::from_millis(250));
        }
    }
}

/// Requests sent one after another on one connection, without load, per
/// endpoint.
const IDLE_REQUESTS: usize = 40;

/// Endpoints timed without load: the two loaded, and the two every open
/// console polls (the live overview asks `/api/v1/changes` every 2 s).
const IDLE_ENDPOINTS: [&str; 4] = [
    "GET /",
    "GET /api/v1/scans?genus=",
    "GET /api/v1/changes",
    "GET /api/v1/status",
];

/// Each of [`IDLE_ENDPOINTS`]' latencies, sorted: [`IDLE_REQUESTS`]
/// requests one after another (genera in turn), after one not counted.
async fn idle_latencies(base: &str) -> Result<Vec<Vec<Duration>>> {
    let client = reqwest::Client::builder()
        .timeout(Duration::from_secs(60))
        .build()
        .context("HTTP client")?;
    let mut out = Vec::new();
    for endpoint in IDLE_ENDPOINTS {
        let mut v = Vec::with_capacity(IDLE_REQUESTS);
        for n in 0..=IDLE_REQUESTS {
            let path = endpoint.trim_start_matches("GET ");
            let url = if path.ends_with("genus=") {
                format!("{base}{path}{}", GENERA[n % GENERA.len()].0)
            } else {
                format!("{base}{path}")
            };
            let t = Instant::now();
            let response = client
                .get(&url)
                .send()
                .await
                .and_then(|r| r.error_for_status())
                .with_context(|| format!("GET {url}"))?;
            response
                .bytes()
                .await
                .with_context(|| format!("GET {url}"))?;
            if n > 0 {
                v.push(t.elapsed());
            }
        }
        v.sort();
        out.push(v);
    }
    Ok(out)
}

/// The table of [`idle_latencies`].
fn print_idle(idle: &[Vec<Duration>]) {
    println!("without load, {IDLE_REQUESTS} requests one after another:");
    println!(
        "{:<28} {:>9} {:>9} {:>9}",
        "endpoint", "p50 ms", "p95 ms", "max ms"
    );
    for (endpoint, v) in IDLE_ENDPOINTS.iter().zip(idle) {
        println!(
            "{:<28} {:>9.1} {:>9.1} {:>9.1}",
            endpoint,
            ms(quantile(v, 0.5)),
            ms(quantile(v, 0.95)),
            ms(v.last().copied().unwrap_or_default())
        );
    }
}

/// One CSV line per endpoint timed without load.
fn csv_idle(out: &mut String, idle: &[Vec<Duration>], knobs: &Knobs) {
    for (endpoint, v) in IDLE_ENDPOINTS.iter().zip(idle) {
        out.push_str(&format!(
            "idle latency,{endpoint},{},1,0,{},0,{:.3},{:.3},{:.3},{:.3},,\n",
            knobs.scans,
            v.len(),
            ms(quantile(v, 0.5)),
            ms(quantile(v, 0.95)),
            ms(quantile(v, 0.99)),
            ms(v.last().copied().unwrap_or_default()),
        ));
    }
}

/// One request's outcome: endpoint, latency, whether it succeeded.
type Sample = (usize, Duration, bool);

/// A load and what was measured under it.
struct Load {
    /// Each connection's pause between its requests.
    think: Duration,
    /// The requests recorded.
    samples: Vec<Sample>,
    /// How long they were recorded.
    lasted: Duration,
    /// The batch identified meanwhile.
    identified: Identified,
    /// CPU used while the requests were recorded.
    cpu: CpuUse,
}

/// The load: `knobs.connections` keep-alive connections sending requests
/// (each pausing `think` after each answer) until stopped; after
/// [`WARM_UP`] the batch is dropped in, and the load goes on for
/// `knobs.seconds` and until the batch is identified.
async fn load_while_identifying(
    base: &str,
    daemon: i32,
    knobs: &Knobs,
    think: Duration,
    batch: Batch<'_>,
) -> Result<Load> {
    let stop = Arc::new(AtomicBool::new(false));
    let record = Arc::new(AtomicBool::new(false));
    let mut tasks = Vec::with_capacity(knobs.connections);
    let spread = knobs.connections as f64;
    for c in 0..knobs.connections {
        let client = reqwest::Client::builder()
            .pool_max_idle_per_host(1)
            .tcp_nodelay(true)
            .redirect(reqwest::redirect::Policy::none())
            .timeout(Duration::from_secs(60))
            .build()
            .context("HTTP client")?;
        let (base, stop, record) = (base.to_string(), Arc::clone(&stop), Arc::clone(&record));
        tasks.push(tokio::spawn(async move {
            // Paced connections start spread over one pause, as browsers
            // opened one after another do.
            if !think.is_zero() {
                tokio::time::sleep(think.mul_f64(c as f64 / spread)).await;
            }
            let mut samples = Vec::new();
            let mut n = c;
            while !stop.load(Ordering::Relaxed) {
                let endpoint = n % 2;
                let url = if endpoint == 0 {
                    format!("{base}/")
                } else {
                    format!(
                        "{base}/api/v1/scans?genus={}",
                        GENERA[(n / 2) % GENERA.len()].0
                    )
                };
                let t = Instant::now();
                let ok = match client.get(&url).send().await {
                    Ok(r) => {
                        let good = r.status().is_success();
                        r.bytes().await.is_ok() && good
                    }
                    Err(_) => false,
                };
                if record.load(Ordering::Relaxed) {
                    samples.push((endpoint, t.elapsed(), ok));
                }
                n += 1;
                if !think.is_zero() {
                    tokio::time::sleep(think).await;
                }
            }
            samples
        }));
    }
    tokio::time::sleep(WARM_UP.max(think * 2)).await;
    record.store(true, Ordering::Relaxed);
    let started = Instant::now();
    let cpu_before = CpuUse::now(daemon)?;
    let before = tokio::task::block_in_place(|| batch.drop_in())?;
    let least = Duration::from_secs_f64(knobs.seconds);
    let mut identified = None;
    while identified.is_none() || started.elapsed() < least {
        if identified.is_none() {
            identified = tokio::task::block_in_place(|| batch.finished(before))?;
        }
        if started.elapsed() > MAX_LOAD {
            break;
        }
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
    stop.store(true, Ordering::Relaxed);
    let lasted = started.elapsed();
    let cpu = CpuUse::now(daemon)?.minus(&cpu_before);
    let mut samples = Vec::new();
    for task in tasks {
        samples.extend(task.await.context("a load task failed")?);
    }
    println!(
        "load: {} requests recorded in {:.1} s on {} connections, {} ms between a connection's requests",
        samples.len(),
        lasted.as_secs_f64(),
        knobs.connections,
        think.as_millis()
    );
    let identified = identified.with_context(|| {
        format!(
            "batch {} not identified in {} s of load",
            batch.number,
            MAX_LOAD.as_secs()
        )
    })?;
    Ok(Load {
        think,
        samples,
        lasted,
        identified,
        cpu,
    })
}

/// CPU time (s) used by the console, by the rest of the daemon, and by
/// this process (the load client).
#[derive(Debug, Clone, Copy)]
struct CpuUse {
    console: f64,
    daemon_rest: f64,
    client: f64,
}

/// Clock ticks a second in `/proc` (`USER_HZ`, 100 on Linux).
const TICKS: f64 = 100.0;

/// User and system CPU seconds in a `/proc/…/stat` file: the process's
/// (its ended threads included) or one thread's.
fn stat_cpu(path: &Path) -> Result<f64> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
    // The name in parentheses may hold spaces: the fields follow its end.
    let fields: Vec<&str> = text
        .rsplit_once(')')
        .map(|(_, rest)| rest.split_whitespace().collect())
        .unwrap_or_default();
    let tick = |i: usize| -> Result<f64> {
        fields
            .get(i)
            .and_then(|f| f.parse::<f64>().ok())
            .with_context(|| format!("{}: no CPU time", path.display()))
    };
    // utime and stime: fields 14 and 15, counted from the pid as 1.
    Ok((tick(11)? + tick(12)?) / TICKS)
}

impl CpuUse {
    /// The totals so far. The console's threads are named
    /// `morphoid-http…`; they come and go (the blocking pool's), so the
    /// console's time is the process's less that of the other threads,
    /// which live as long as the daemon.
    fn now(daemon: i32) -> Result<CpuUse> {
        let proc = PathBuf::from(format!("/proc/{daemon}"));
        let total = stat_cpu(&proc.join("stat"))?;
        let mut rest = 0.0;
        for task in std::fs::read_dir(proc.join("task")).context("the daemon's threads")? {
            let task = task?.path();
            let name = std::fs::read_to_string(task.join("comm")).unwrap_or_default();
            if !name.starts_with("morphoid-http") {
                // A thread that ended meanwhile counts as none.
                rest += stat_cpu(&task.join("stat")).unwrap_or(0.0);
            }
        }
        Ok(CpuUse {
            console: total - rest,
            daemon_rest: rest,
            client: stat_cpu(Path::new("/proc/self/stat"))?,
        })
    }

    fn minus(&self, earlier: &CpuUse) -> CpuUse {
        CpuUse {
            console: self.console - earlier.console,
            daemon_rest: self.daemon_rest - earlier.daemon_rest,
            client: self.client - earlier.client,
        }
    }
}

/// The figures of one endpoint.
struct LatencyRow {
    endpoint: &'static str,
    requests: usize,
    errors: usize,
    p50: Duration,
    p95: Duration,
    p99: Duration,
    max: Duration,
    per_second: f64,
}

/// The `q` quantile of sorted `v` (nearest rank).
fn quantile(v: &[Duration], q: f64) -> Duration {
    if v.is_empty() {
        return Duration::ZERO;
    }
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[rank - 1]
}

/// Each endpoint's figures over `samples`, recorded during `lasted`.
fn latency_rows(samples: &[Sample], lasted: Duration) -> Vec<LatencyRow> {
    let seconds = lasted.as_secs_f64();
    (0..ENDPOINTS.len())
        .map(|e| {
            let mut v: Vec<Duration> = samples.iter().filter(|s| s.0 == e).map(|s| s.1).collect();
            let errors = samples.iter().filter(|s| s.0 == e && !s.2).count();
            v.sort();
            LatencyRow {
                endpoint: ENDPOINTS[e],
                requests: v.len(),
                errors,
                p50: quantile(&v, 0.50),
                p95: quantile(&v, 0.95),
                p99: quantile(&v, 0.99),
                max: v.last().copied().unwrap_or_default(),
                per_second: v.len() as f64 / seconds.max(1e-3),
            }
        })
        .collect()
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1000.0
}

/// The table of one load.
fn print_latencies(rows: &[LatencyRow], think: Duration) {
    if think.is_zero() {
        println!("\nload: requests back to back on each connection");
    } else {
        println!(
            "\nload: {} ms between a connection's requests",
            think.as_millis()
        );
    }
    println!(
        "{:<28} {:>9} {:>7} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "endpoint", "requests", "errors", "p50 ms", "p95 ms", "p99 ms", "max ms", "req/s"
    );
    for r in rows {
        println!(
            "{:<28} {:>9} {:>7} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>9.1}",
            r.endpoint,
            r.requests,
            r.errors,
            ms(r.p50),
            ms(r.p95),
            ms(r.p99),
            ms(r.max),
            r.per_second
        );
    }
}

/// The CSV's first line.
fn csv_header() -> String {
    "kind,name,scans_in_db,connections,think_ms,count,errors,p50_ms,p95_ms,p99_ms,max_ms,rate,rate_unit\n"
        .to_string()
}

/// One CSV line per endpoint of a load.
fn csv_latencies(out: &mut String, rows: &[LatencyRow], think: Duration, knobs: &Knobs) {
    for r in rows {
        out.push_str(&format!(
            "latency,{},{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.2},requests/s\n",
            r.endpoint,
            knobs.scans,
            knobs.connections,
            think.as_millis(),
            r.requests,
            r.errors,
            ms(r.p50),
            ms(r.p95),
            ms(r.p99),
            ms(r.max),
            r.per_second
        ));
    }
}

/// The CSV line of an identification batch (its quantiles are of each
/// scan's identification time).
fn csv_identified(out: &mut String, name: &str, b: &Identified, think: Duration, knobs: &Knobs) {
    out.push_str(&format!(
        "identification,{name},{},{},{},{},0,{:.3},{:.3},{:.3},{:.3},{:.3},scans/min\n",
        knobs.scans,
        knobs.connections,
        think.as_millis(),
        b.scans,
        ms(quantile(&b.each, 0.5)),
        ms(quantile(&b.each, 0.95)),
        ms(quantile(&b.each, 0.99)),
        ms(b.each.last().copied().unwrap_or_default()),
        b.per_minute()
    ));
}
