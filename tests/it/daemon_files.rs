//! `morphoid run` and the export folder: slow writers, temporary names,
//! bad inputs, restarts.

use crate::support::daemon::*;
use morphoid_service::store::ScanStatus;
use std::io::Write;
use std::time::Duration;

#[test]
fn a_file_written_slowly_and_a_renamed_part_file_are_each_processed_once() {
    // Settle time well above the 2 s pause between chunks: a pause as long
    // as the settle time is indistinguishable from the end, and a writer
    // woken late on a busy machine makes a pause longer than asked. The
    // 4 s margin absorbs that; the whole write (10 s) still lasts longer
    // than the settle time, so a wait counted from the file's creation
    // rather than from its last change would be caught.
    let env = env(6.0, "", "");
    let d = Daemon::start(&env);

    // Written in 6 chunks over 10 s: never taken early.
    let bytes = scan_bytes(1, 901);
    let target = env.export.join("slow.ply");
    let mut f = std::fs::File::create(&target).unwrap();
    let chunk = bytes.len().div_ceil(6);
    for (i, part) in bytes.chunks(chunk).enumerate() {
        f.write_all(part).unwrap();
        f.flush().unwrap();
        if i + 1 < bytes.len().div_ceil(chunk) {
            std::thread::sleep(Duration::from_secs(2));
            assert!(rows(&env.db).is_empty(), "taken before its last chunk");
        }
    }
    drop(f);

    // Written under a temporary name, renamed at the end (after more than
    // the settle time: a `.part` file taken would show here).
    let part = env.export.join("x.part");
    std::fs::write(&part, scan_bytes(3, 902)).unwrap();
    std::thread::sleep(Duration::from_secs(7));
    std::fs::rename(&part, env.export.join("x.ply")).unwrap();

    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 2),
        "not processed: {:?}\n{}",
        rows(&env.db),
        d.log_text()
    );
    std::thread::sleep(Duration::from_secs(3));
    let r = rows(&env.db);
    assert_eq!(r.len(), 2, "{r:?}");
    assert!(r[0].path.ends_with("slow.ply"), "{}", r[0].path);
    assert!(r[1].path.ends_with("x.ply"), "{}", r[1].path);
    for (row, g) in r.iter().zip([1, 3]) {
        assert_eq!(row.status, ScanStatus::Ok, "{row:?}");
        assert_eq!(
            row.size as usize,
            if g == 1 {
                bytes.len()
            } else {
                row.size as usize
            }
        );
        assert_eq!(genus_of(row), Some(genus(g)), "{row:?}");
    }
    let log = d.log_once("slow.ply: order=");
    assert!(
        !log.contains("\u{1b}["),
        "colour codes in a non-terminal log"
    );
}

#[test]
fn the_eight_bad_inputs_become_error_rows_and_the_next_scan_is_identified() {
    let env = env(0.5, "quarantine = \"QUARANTINE\"", "");
    let quarantine = env.root.join("quarantine");
    let config = std::fs::read_to_string(&env.config)
        .unwrap()
        .replace("QUARANTINE", &quarantine.display().to_string());
    std::fs::write(&env.config, config).unwrap();
    let d = Daemon::start(&env);

    // Written beside the export folder and moved in, each file whole: one
    // caught empty between its creation and its write would be taken as a
    // scan of its own.
    let staging = env.root.join("bad");
    let bad = morphoid_synth::mesh::write_bad_inputs(&staging).unwrap();
    assert_eq!(bad.len(), 8);
    for (path, _) in &bad {
        std::fs::rename(path, env.export.join(path.file_name().unwrap())).unwrap();
    }
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 8),
        "{:?}\n{}",
        rows(&env.db),
        d.log_text()
    );
    put(&env, &env.export.join("good.ply"), &scan_bytes(2, 903));
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 9),
        "{:?}\n{}",
        rows(&env.db),
        d.log_text()
    );
    let r = rows(&env.db);
    assert_eq!(r.len(), 9, "{r:?}");
    let errors: Vec<_> = r.iter().filter(|s| s.status == ScanStatus::Error).collect();
    assert_eq!(errors.len(), 8, "{r:?}");
    for e in &errors {
        let message = e.error.as_deref().unwrap_or("");
        let name = std::path::Path::new(&e.path).file_name().unwrap();
        // The message names the file and says something.
        assert!(
            message.contains(&*name.to_string_lossy()) && message.len() > name.len() + 5,
            "unclear message for {}: {message:?}",
            e.path
        );
        // Moved to the quarantine folder.
        assert!(!std::path::Path::new(&e.path).exists(), "{} left", e.path);
        assert!(quarantine.join(name).exists(), "{name:?} not quarantined");
    }
    let good = r.iter().find(|s| s.path.ends_with("good.ply")).unwrap();
    assert_eq!(good.status, ScanStatus::Ok, "{good:?}");
    assert_eq!(genus_of(good), Some(genus(2)));
    // Quarantined files are not picked up again from the quarantine folder.
    std::thread::sleep(Duration::from_secs(2));
    assert_eq!(rows(&env.db).len(), 9);
}

#[test]
fn files_that_arrived_while_down_are_processed_once_and_changed_content_again() {
    let env = env(0.5, "", "");
    let a = env.export.join("sub").join("a.ply");
    std::fs::create_dir_all(a.parent().unwrap()).unwrap();
    std::fs::write(&a, scan_bytes(0, 904)).unwrap();
    {
        let _d = Daemon::start(&env);
        assert!(wait_until(Duration::from_secs(120), || finished(&env.db) >= 1));
    }
    // Down: a new file arrives, the old one is still there.
    std::fs::write(env.export.join("b.ply"), scan_bytes(4, 905)).unwrap();
    let d = Daemon::start(&env);
    assert!(wait_until(Duration::from_secs(120), || finished(&env.db) >= 2));
    // A changed file is new content (replaced whole: never seen empty).
    put(&env, &a, &scan_bytes(5, 906));
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 3),
        "{}",
        d.log_text()
    );
    std::thread::sleep(Duration::from_secs(2));
    let r = rows(&env.db);
    assert_eq!(r.len(), 3, "{r:?}");
    assert!(r.iter().all(|s| s.status == ScanStatus::Ok), "{r:?}");
    assert_eq!(genus_of(&r[2]), Some(genus(5)));
}

#[test]
fn run_needs_no_config_file_with_watch_library_and_db_given() {
    let env = env(2.0, "", "");
    let db = env.root.join("flags.sqlite");
    let log = env.root.join("flags.log");
    // A relative export folder: the watcher's events name absolute paths.
    let mut child = std::process::Command::new(BIN)
        .current_dir(&env.root)
        .arg("run")
        .arg("--watch")
        .arg("export")
        .arg("--library")
        .arg(env.root.join("library"))
        .arg("--db")
        .arg(&db)
        .env("XDG_CACHE_HOME", env.root.join("xdg"))
        .env_remove("CACHE_DIRECTORY")
        .env_remove("NOTIFY_SOCKET")
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .unwrap();
    let text = || std::fs::read_to_string(&log).unwrap_or_default();
    assert!(
        wait_until(Duration::from_secs(120), || text()
            .contains("references; watching")),
        "{}",
        text()
    );
    // Queued well before the 30 s safety rescan: the watcher saw it. Only
    // the queueing is held to that bound; identifying it may take longer
    // on a busy machine.
    put(&env, &env.export.join("f.ply"), &scan_bytes(4, 916));
    let seen = wait_until(Duration::from_secs(20), || !rows(&db).is_empty());
    let ok = seen && wait_until(Duration::from_secs(120), || finished(&db) >= 1);
    let _ = child.kill();
    let _ = child.wait();
    let text = std::fs::read_to_string(&log).unwrap_or_default();
    assert!(seen, "not queued within 20 s: {text}");
    assert!(ok, "{text}");
    let r = rows(&db);
    assert_eq!(r[0].status, ScanStatus::Ok, "{text}");
    assert_eq!(genus_of(&r[0]), Some(genus(4)));
    assert!(env.root.join("xdg/morphoid").is_dir());
}

#[test]
fn files_of_other_kinds_are_left_alone() {
    let env = env(0.3, "", "");
    let d = Daemon::start(&env);
    std::fs::write(env.export.join("scanner.log"), "scan 17 done\n").unwrap();
    std::fs::write(env.export.join("notes.txt"), "x").unwrap();
    put(&env, &env.export.join("UPPER.PLY"), &scan_bytes(1, 917));
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 1),
        "{}",
        d.log_text()
    );
    std::thread::sleep(Duration::from_secs(2));
    let r = rows(&env.db);
    assert_eq!(r.len(), 1, "{r:?}");
    assert!(r[0].path.ends_with("UPPER.PLY"));
    assert_eq!(r[0].status, ScanStatus::Ok);
}

#[test]
fn the_polling_fallback_takes_settled_files_once() {
    let env = env(1.0, "", "");
    let d = Daemon::start_with(&env, &[("MORPHOID_WATCH", "poll")]);
    // Logged just after the library line that `start` waits for.
    assert!(
        wait_until(Duration::from_secs(120), || d
            .log_text()
            .contains("polling the folder")),
        "{}",
        d.log_text()
    );
    assert!(!d.log_text().contains("watching for changes"));

    // A temporary name renamed at the end, and a file in a subfolder.
    let part = env.export.join("p.part");
    std::fs::write(&part, scan_bytes(1, 931)).unwrap();
    std::fs::create_dir_all(env.export.join("day2")).unwrap();
    put(&env, &env.export.join("day2/q.ply"), &scan_bytes(2, 932));
    std::thread::sleep(Duration::from_secs(2));
    std::fs::rename(&part, env.export.join("p.ply")).unwrap();
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 2),
        "{:?}\n{}",
        rows(&env.db),
        d.log_text()
    );
    std::thread::sleep(Duration::from_secs(3));
    let r = rows(&env.db);
    assert_eq!(r.len(), 2, "{r:?}");
    let mut names: Vec<&str> = r
        .iter()
        .map(|s| s.path.rsplit('/').next().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["p.ply", "q.ply"]);
    assert!(r.iter().all(|s| s.status == ScanStatus::Ok), "{r:?}");
}

#[test]
fn a_folder_moved_in_whole_is_picked_up_by_the_watcher() {
    let env = env(0.5, "", "");
    let d = Daemon::start(&env);
    // Logged just after the library line that `start` waits for.
    assert!(
        wait_until(Duration::from_secs(120), || d
            .log_text()
            .contains("watching for changes")),
        "{}",
        d.log_text()
    );
    // Files inside a folder that is renamed into the export folder raise
    // one event for the folder only.
    let staged = env.root.join("batch");
    std::fs::create_dir_all(staged.join("inner")).unwrap();
    std::fs::write(staged.join("m1.ply"), scan_bytes(0, 933)).unwrap();
    std::fs::write(staged.join("inner/m2.ply"), scan_bytes(3, 934)).unwrap();
    std::fs::rename(&staged, env.export.join("batch")).unwrap();
    // Both queued before the 30 s safety rescan: the watcher's event for
    // the folder found them. Identifying them may take longer.
    assert!(
        wait_until(Duration::from_secs(25), || rows(&env.db).len() >= 2),
        "{:?}\n{}",
        rows(&env.db),
        d.log_text()
    );
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 2),
        "{:?}\n{}",
        rows(&env.db),
        d.log_text()
    );
    assert_eq!(rows(&env.db).len(), 2);
}

#[test]
fn an_export_folder_missing_at_start_is_polled_until_it_appears() {
    let env = env(0.5, "", "");
    std::fs::remove_dir(&env.export).unwrap();
    let d = Daemon::start(&env);
    // No watcher can be set on a missing folder: logged, then polling.
    assert!(
        wait_until(Duration::from_secs(120), || d
            .log_text()
            .contains("polling the folder instead")),
        "{}",
        d.log_text()
    );
    std::fs::create_dir_all(&env.export).unwrap();
    put(&env, &env.export.join("late.ply"), &scan_bytes(5, 935));
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 1),
        "{}",
        d.log_text()
    );
    let r = rows(&env.db);
    assert_eq!(r.len(), 1);
    assert_eq!(r[0].status, ScanStatus::Ok);
    assert_eq!(genus_of(&r[0]), Some(genus(5)));
}

#[test]
fn an_export_folder_removed_and_created_again_is_still_watched() {
    let env = env(0.5, "", "");
    let d = Daemon::start(&env);
    std::fs::remove_dir(&env.export).unwrap();
    // Seen gone by the watcher, or, when the folder went before the watch
    // was set, by the first listing: either way the daemon polls.
    assert!(
        wait_until(Duration::from_secs(120), || {
            let log = d.log_text();
            log.contains("the export folder is gone")
                || log.contains("cannot list the export folder")
        }),
        "{}",
        d.log_text()
    );
    std::fs::create_dir_all(&env.export).unwrap();
    put(&env, &env.export.join("back.ply"), &scan_bytes(0, 936));
    // Queued well before the 30 s safety rescan; identifying it may take
    // longer on a busy machine.
    assert!(
        wait_until(Duration::from_secs(20), || !rows(&env.db).is_empty()),
        "{}",
        d.log_text()
    );
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 1),
        "{}",
        d.log_text()
    );
    assert_eq!(rows(&env.db)[0].status, ScanStatus::Ok);
}
