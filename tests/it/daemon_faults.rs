//! Storage faults under the running daemon (issue 16): a database on a
//! file system that fills up, I/O errors under the database and under the
//! results folder, the database deleted, the results folder read-only, a
//! truncated cache entry, a database replaced by another file or locked by
//! another process, and a file whose content is another's. Each test
//! asserts that every arriving file ends with exactly one result once the
//! fault clears, and that the fault is logged once, not per retry.
//! The mount tests need root (`support::faults`).

use crate::support::daemon::*;
use crate::support::faults::{fill, have_root, Mount};
use morphoid_service::store::ScanStatus;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// How long a fault lasts in these tests: several retries at the longest
/// backoff would each log if the daemon logged per attempt.
const FAULT: Duration = Duration::from_secs(12);

/// Put the database of `env` at `db` (a mount).
fn move_database(env: &mut Env, db: PathBuf) {
    let config = std::fs::read_to_string(&env.config)
        .unwrap()
        .replace(&format!("{:?}", env.db), &format!("{db:?}"));
    std::fs::write(&env.config, config).unwrap();
    env.db = db;
}

/// A config with result files in `dir`.
fn results_config(dir: &Path) -> String {
    format!("[results]\ndir = {dir:?}\n")
}

/// Drop scan `i` (genus `i`) into the export folder as `s<i>.ply`.
fn drop_scan(env: &Env, i: usize) -> String {
    let name = format!("s{i}.ply");
    put(
        env,
        &env.export.join(&name),
        &scan_bytes(i, 1600 + i as u64),
    );
    name
}

/// Wait until the files `names` are all finished, then assert that each
/// has exactly one row, identified as its genus, and nothing else is
/// recorded.
fn assert_exactly_once(env: &Env, d: &Daemon, names: &[String], within: Duration) {
    let done = |rows: &[morphoid_service::store::ScanRecord]| {
        names.iter().all(|n| {
            rows.iter()
                .any(|r| r.path.ends_with(&format!("/{n}")) && r.status == ScanStatus::Ok)
        })
    };
    assert!(
        wait_until(within, || done(&rows(&env.db))),
        "not all identified: {:#?}\n{}",
        rows(&env.db)
            .iter()
            .map(|r| (&r.path, r.status))
            .collect::<Vec<_>>(),
        d.log_text()
    );
    // Anything still in flight would show as a second row now.
    std::thread::sleep(Duration::from_secs(2));
    let r = rows(&env.db);
    for (i, n) in names.iter().enumerate() {
        let mine: Vec<_> = r
            .iter()
            .filter(|x| x.path.ends_with(&format!("/{n}")))
            .collect();
        assert_eq!(mine.len(), 1, "{n}: {mine:?}");
        assert_eq!(mine[0].status, ScanStatus::Ok, "{n}: {:?}", mine[0]);
        let g: usize = n[1..n.len() - 4].parse().unwrap_or(i);
        assert_eq!(genus_of(mine[0]), Some(genus(g)), "{n}: {:?}", mine[0]);
    }
    assert_eq!(r.len(), names.len(), "{r:?}");
}

/// Lines the daemon logged since `from` lines, for the fault's duration.
fn lines_since(d: &Daemon, from: usize) -> Vec<String> {
    d.log_text()
        .lines()
        .skip(from)
        .map(str::to_string)
        .collect()
}

/// The log lines during a fault: the fault once, nothing per retry.
fn assert_quiet(during: &[String], what: &str) {
    let faults = during.iter().filter(|l| l.contains("unavailable")).count();
    assert_eq!(
        faults, 1,
        "{what}: the fault logged {faults} times:\n{during:#?}"
    );
    assert!(
        during.len() <= 4,
        "{what}: {} lines during the fault:\n{during:#?}",
        during.len()
    );
}

#[test]
#[cfg_attr(
    morphoid_skip_root,
    ignore = "needs root (MORPHOID_SKIP_ROOT=1 and not root)"
)]
fn a_full_disk_under_the_database_loses_and_repeats_nothing() {
    if !have_root("a_full_disk_under_the_database_loses_and_repeats_nothing") {
        return;
    }
    let mut env = env(0.5, "", "");
    let mnt = Mount::tmpfs(&env.root.join("dbfs"), "6m");
    let db = env.root.join("dbfs/db.sqlite");
    move_database(&mut env, db);
    let d = Daemon::start(&env);
    let mut names: Vec<String> = (0..3).map(|i| drop_scan(&env, i)).collect();
    assert!(wait_until(Duration::from_secs(60), || finished(&env.db) >= 1));
    // Full while jobs are queued, running and arriving.
    let filler = fill(&env.root.join("dbfs"), "filler");
    let before = d.log_text().lines().count();
    names.extend((3..6).map(|i| drop_scan(&env, i)));
    std::thread::sleep(FAULT);
    let during = lines_since(&d, before);
    std::fs::remove_file(&filler).unwrap();
    assert_quiet(&during, "disk full");
    assert_exactly_once(&env, &d, &names, Duration::from_secs(120));
    let log = d.log_once("database available again");
    assert!(!log.contains("complete needs running"), "{log}");
    drop(d);
    drop(mnt);
}

/// Issue 30: a database on a 512 kB file system (400 kB before schema 9,
/// where a fresh database now fails its first write). Its log stays small
/// (checkpointed after every scan or two and cut back), so six scans fit;
/// filled up by another file meanwhile, the daemon retries (the log
/// checkpointed and cut to nothing on SQLITE_FULL) and, once the space is
/// free again, records every scan exactly once within a minute.
#[test]
#[cfg_attr(
    morphoid_skip_root,
    ignore = "needs root (MORPHOID_SKIP_ROOT=1 and not root)"
)]
fn a_nearly_full_small_disk_recovers_once_space_is_free() {
    if !have_root("a_nearly_full_small_disk_recovers_once_space_is_free") {
        return;
    }
    let mut env = env(0.5, "", "");
    let mnt = Mount::tmpfs(&env.root.join("dbfs"), "512k");
    let db = env.root.join("dbfs/db.sqlite");
    move_database(&mut env, db.clone());
    let d = Daemon::start(&env);
    let mut names: Vec<String> = (0..3).map(|i| drop_scan(&env, i)).collect();
    assert!(
        wait_until(Duration::from_secs(60), || finished(&env.db) >= 1),
        "{}",
        d.log_text()
    );
    let filler = fill(&env.root.join("dbfs"), "filler");
    names.extend((3..6).map(|i| drop_scan(&env, i)));
    std::thread::sleep(FAULT);
    std::fs::remove_file(&filler).unwrap();
    let freed = std::time::Instant::now();
    assert_exactly_once(&env, &d, &names, Duration::from_secs(60));
    let wal = std::fs::metadata(env.root.join("dbfs/db.sqlite-wal")).map_or(0, |m| m.len());
    println!(
        "6/6 recorded {:.1} s after the space was freed; log {wal} bytes, database {} bytes",
        freed.elapsed().as_secs_f64() - 2.0,
        std::fs::metadata(&db).unwrap().len()
    );
    drop(d);
    drop(mnt);
}

#[test]
#[cfg_attr(
    morphoid_skip_root,
    ignore = "needs root (MORPHOID_SKIP_ROOT=1 and not root)"
)]
fn io_errors_under_the_database_and_the_results_folder_are_survived() {
    if !have_root("io_errors_under_the_database_and_the_results_folder_are_survived") {
        return;
    }
    let mut env = env(0.5, "", "");
    let results = env.root.join("results");
    let config = std::fs::read_to_string(&env.config).unwrap() + &results_config(&results);
    std::fs::write(&env.config, config).unwrap();
    let mut dbfs = Mount::ext4(&env.root.join("dbfs"), &env.root.join("db.img"), 16);
    let mut resfs = Mount::ext4(&results, &env.root.join("results.img"), 16);
    let db = env.root.join("dbfs/db.sqlite");
    move_database(&mut env, db);
    let d = Daemon::start(&env);
    let mut names: Vec<String> = (0..2).map(|i| drop_scan(&env, i)).collect();
    assert!(wait_until(Duration::from_secs(60), || finished(&env.db) >= 1));
    dbfs.fail_io();
    resfs.fail_io();
    let before = d.log_text().lines().count();
    names.extend((2..4).map(|i| drop_scan(&env, i)));
    std::thread::sleep(FAULT);
    let during = lines_since(&d, before);
    dbfs.recover();
    resfs.recover();
    let faults = during.iter().filter(|l| l.contains("unavailable")).count();
    assert!(faults <= 2 && during.len() <= 6, "{during:#?}");
    assert_exactly_once(&env, &d, &names, Duration::from_secs(120));
    // One result file per file, each the recorded result.
    assert!(
        wait_until(Duration::from_secs(30), || names
            .iter()
            .all(|n| results.join(format!("{n}.json")).is_file())),
        "result files missing: {:?}\n{}",
        std::fs::read_dir(&results).map(|r| r.count()),
        d.log_text()
    );
    for n in &names {
        let text = std::fs::read_to_string(results.join(format!("{n}.json"))).unwrap();
        assert!(text.contains(r#""status":"ok""#), "{n}: {text}");
    }
}

#[test]
#[cfg_attr(
    morphoid_skip_root,
    ignore = "needs root (MORPHOID_SKIP_ROOT=1 and not root)"
)]
fn the_database_deleted_under_the_daemon_comes_back_whole() {
    if !have_root("the_database_deleted_under_the_daemon_comes_back_whole") {
        return;
    }
    let env = env(0.5, "", "");
    let d = Daemon::start(&env);
    let mut names: Vec<String> = (0..2).map(|i| drop_scan(&env, i)).collect();
    assert!(wait_until(Duration::from_secs(60), || finished(&env.db) >= 2));
    for suffix in ["", "-wal", "-shm"] {
        let mut p = env.db.clone().into_os_string();
        p.push(suffix);
        let _ = std::fs::remove_file(PathBuf::from(p));
    }
    // Nothing may open the path before the daemon has noticed (a reader
    // would create an empty database there).
    assert!(
        wait_until(Duration::from_secs(20), || d
            .log_text()
            .contains("deleted under the running daemon")),
        "{}",
        d.log_text()
    );
    d.log_once("it is back with everything recorded");
    names.extend((2..4).map(|i| drop_scan(&env, i)));
    assert_exactly_once(&env, &d, &names, Duration::from_secs(120));
}

#[test]
fn a_database_replaced_under_the_daemon_is_used_and_gets_what_it_lacks() {
    let env = env(0.5, "", "");
    let d = Daemon::start(&env);
    let mut names = vec![drop_scan(&env, 0)];
    assert!(wait_until(Duration::from_secs(60), || finished(&env.db) >= 1));
    // An operator's backup, taken now: it has s0 but will lack s1.
    let backup = env.root.join("backup.sqlite");
    morphoid_service::store::Store::open(&env.db)
        .unwrap()
        .copy_to(&backup)
        .unwrap();
    names.push(drop_scan(&env, 1));
    assert!(wait_until(Duration::from_secs(60), || finished(&env.db) >= 2));
    std::fs::rename(&backup, &env.db).unwrap();
    // Nothing may open the path before the daemon has let go of the old
    // file (a reader would take the old write-ahead log for the new file's).
    assert!(
        wait_until(Duration::from_secs(20), || d
            .log_text()
            .contains("was replaced under the running daemon")),
        "{}",
        d.log_text()
    );
    names.extend((2..4).map(|i| drop_scan(&env, i)));
    // s1 is identified again into the new file; s0 is not repeated.
    assert_exactly_once(&env, &d, &names, Duration::from_secs(120));
}

#[test]
fn a_scan_whose_row_is_lost_while_it_is_identified_is_identified_again() {
    // What a disk that loses its last writes, or a backup restored into
    // the file in place, does to the scan in progress: its row is gone
    // when the result comes. The file was taken already, so only a fresh
    // listing can queue it again.
    let env = env(0.5, "", "");
    let d = Daemon::start(&env);
    let mut names = vec![drop_scan(&env, 0)];
    assert!(wait_until(Duration::from_secs(60), || finished(&env.db) >= 1));
    let staged = large_scan(&env, 1, 931, 200_000);
    let large = env.export.join("large.ply");
    std::fs::rename(&staged, &large).unwrap();
    names.push("large.ply".into());
    let running = |db: &Path| {
        rows(db)
            .iter()
            .any(|r| r.path.ends_with("/large.ply") && r.status == ScanStatus::Running)
    };
    assert!(
        wait_until(Duration::from_secs(60), || running(&env.db)),
        "{}",
        d.log_text()
    );
    let other = rusqlite::Connection::open(&env.db).unwrap();
    other.busy_timeout(Duration::from_secs(10)).unwrap();
    let deleted = other
        .execute("DELETE FROM scan WHERE path LIKE '%/large.ply'", [])
        .unwrap();
    drop(other);
    assert_eq!(deleted, 1);
    assert!(
        wait_until(Duration::from_secs(60), || d
            .log_text()
            .contains("large.ply: identification not recorded")),
        "the row was deleted after the identification: {}",
        d.log_text()
    );
    assert_exactly_once(&env, &d, &names, Duration::from_secs(120));
}

#[test]
fn a_database_locked_by_another_process_delays_but_loses_nothing() {
    let env = env(0.5, "", "");
    let d = Daemon::start(&env);
    let mut names = vec![drop_scan(&env, 0)];
    assert!(wait_until(Duration::from_secs(60), || finished(&env.db) >= 1));
    let other = rusqlite::Connection::open(&env.db).unwrap();
    other.execute_batch("BEGIN EXCLUSIVE").unwrap();
    let before = d.log_text().lines().count();
    names.extend((1..4).map(|i| drop_scan(&env, i)));
    std::thread::sleep(FAULT);
    let during = lines_since(&d, before);
    other.execute_batch("COMMIT").unwrap();
    drop(other);
    assert_quiet(&during, "database locked");
    assert_exactly_once(&env, &d, &names, Duration::from_secs(120));
    d.log_once("database available again");
}

#[test]
#[cfg_attr(
    morphoid_skip_root,
    ignore = "needs root (MORPHOID_SKIP_ROOT=1 and not root)"
)]
fn a_read_only_results_folder_gets_every_result_file_once_writable() {
    if !have_root("a_read_only_results_folder_gets_every_result_file_once_writable") {
        return;
    }
    let env = env(0.5, "", "");
    let results = env.root.join("results");
    std::fs::create_dir_all(&results).unwrap();
    let config = std::fs::read_to_string(&env.config).unwrap() + &results_config(&results);
    std::fs::write(&env.config, config).unwrap();
    let d = Daemon::start(&env);
    let ro = Mount::read_only(&results);
    let before = d.log_text().lines().count();
    let names: Vec<String> = (0..3).map(|i| drop_scan(&env, i)).collect();
    assert!(wait_until(Duration::from_secs(90), || finished(&env.db) >= 3));
    std::thread::sleep(Duration::from_secs(6));
    let during: Vec<String> = lines_since(&d, before)
        .into_iter()
        .filter(|l| !l.contains(": order="))
        .collect();
    assert_eq!(std::fs::read_dir(&results).unwrap().count(), 0);
    drop(ro);
    assert_quiet(&during, "read-only results");
    assert!(
        wait_until(Duration::from_secs(30), || names
            .iter()
            .all(|n| results.join(format!("{n}.json")).is_file())),
        "{}",
        d.log_text()
    );
    assert_exactly_once(&env, &d, &names, Duration::from_secs(10));
    // Each scan's JSON, report and thumbnail once, and the overview.
    let files: Vec<String> = std::fs::read_dir(&results)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    for ext in [".json", ".html", ".png"] {
        let n = files
            .iter()
            .filter(|f| f.ends_with(ext) && f.as_str() != "index.html")
            .count();
        assert_eq!(n, names.len(), "{ext}: {files:?}");
    }
    assert!(files.iter().any(|f| f == "index.html"), "{files:?}");
    assert_eq!(files.len(), 3 * names.len() + 1, "{files:?}");
    d.log_once("results folder available again");
}

#[test]
fn a_truncated_cache_entry_is_prepared_again() {
    let env = env(0.5, "", "");
    let d = Daemon::start(&env);
    let n = d.references();
    drop(d);
    let entries: Vec<PathBuf> = walk(&env.root.join("cache"))
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "prep"))
        .collect();
    assert_eq!(entries.len() as i64, n);
    let victim = &entries[0];
    let len = std::fs::metadata(victim).unwrap().len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(victim)
        .unwrap()
        .set_len(len / 2)
        .unwrap();
    let d = Daemon::start(&env);
    assert_eq!(d.references(), n, "{}", d.log_text());
    assert_eq!(std::fs::metadata(victim).unwrap().len(), len);
    let names = vec![drop_scan(&env, 2)];
    assert_exactly_once(&env, &d, &names, Duration::from_secs(90));
}

#[test]
fn a_file_with_known_content_gets_its_own_duplicate_row_and_result_file() {
    let env = env(0.5, "", "");
    let results = env.root.join("results");
    let config = std::fs::read_to_string(&env.config).unwrap() + &results_config(&results);
    std::fs::write(&env.config, config).unwrap();
    let d = Daemon::start(&env);
    let bytes = scan_bytes(4, 77);
    put(&env, &env.export.join("a.ply"), &bytes);
    assert!(wait_until(Duration::from_secs(60), || finished(&env.db) >= 1));
    put(&env, &env.export.join("b.ply"), &bytes);
    let json = results.join("b.ply.json");
    assert!(
        wait_until(Duration::from_secs(30), || json.is_file()),
        "{}",
        d.log_text()
    );
    let r = rows(&env.db);
    assert_eq!(r.len(), 2, "{r:?}");
    assert_eq!(r[1].status, ScanStatus::Duplicate);
    assert_eq!(r[1].duplicate_of.as_ref().map(|o| o.id), Some(r[0].id));
    assert_eq!(genus_of(&r[1]), Some(genus(4)));
    let text = std::fs::read_to_string(&json).unwrap();
    assert!(text.contains(r#""status":"duplicate""#), "{text}");
    assert!(text.contains(r#""ranks""#), "{text}");
    let log = d.log_once("b.ply: same content as scan");
    assert!(
        log.contains("b.ply: same content as scan") && log.contains("a.ply"),
        "{log}"
    );
    // A second listing (restart) adds nothing.
    drop(d);
    let d = Daemon::start(&env);
    std::thread::sleep(Duration::from_secs(3));
    assert_eq!(rows(&env.db).len(), 2, "{}", d.log_text());
    let out = std::process::Command::new(BIN)
        .args(["results", "--config"])
        .arg(&env.config)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("b.ply: duplicate of scan"), "{text}");
}

/// Every file under `dir`.
fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}
