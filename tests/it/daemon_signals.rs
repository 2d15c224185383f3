//! `morphoid run` killed or stopped in the middle of a job.

use crate::support::daemon::*;
use morphoid_service::store::ScanStatus;
use std::path::Path;
use std::time::{Duration, Instant};

/// Rows of `result` and `distance` for a scan.
fn result_rows(db: &Path, scan_id: i64) -> (i64, i64, i64) {
    let c = rusqlite::Connection::open(db).unwrap();
    let n = |sql: &str| -> i64 { c.query_row(sql, [scan_id], |r| r.get(0)).unwrap() };
    (
        n("SELECT count(*) FROM result WHERE scan_id = ?1"),
        n("SELECT count(DISTINCT ordinal) FROM result WHERE scan_id = ?1"),
        n("SELECT count(*) FROM distance WHERE scan_id = ?1"),
    )
}

fn wait_running(db: &Path) -> i64 {
    let mut id = 0;
    assert!(
        wait_until(Duration::from_secs(120), || {
            match rows(db).iter().find(|r| r.status == ScanStatus::Running) {
                Some(r) => {
                    id = r.id;
                    true
                }
                None => false,
            }
        }),
        "no job started: {:?}",
        rows(db)
    );
    id
}

#[test]
fn kill_9_in_the_middle_of_a_job_then_restart_gives_exactly_one_result() {
    let env = env(0.2, "", "");
    // A large scan (400k vertices): its job lasts seconds, so it is still
    // running when the kill lands however late the test thread gets to
    // send it (a small scan's job can end between the read that saw it
    // running and the kill).
    let staged = large_scan(&env, 1, 907, 400_000);
    let d = Daemon::start(&env);
    std::fs::rename(&staged, env.export.join("k.ply")).unwrap();
    let refs = d.references();
    assert!(refs >= 6, "{refs} references");
    let id = wait_running(&env.db);
    d.signal(libc::SIGKILL);
    drop(d);
    assert_eq!(rows(&env.db)[0].status, ScanStatus::Running);

    let d = Daemon::start(&env);
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 1),
        "{}",
        d.log_text()
    );
    let r = rows(&env.db);
    assert_eq!(r.len(), 1, "{r:?}");
    assert_eq!(r[0].id, id);
    assert_eq!(r[0].status, ScanStatus::Ok, "{r:?}");
    assert_eq!(genus_of(&r[0]), Some(genus(1)));
    assert_eq!(result_rows(&env.db, id), (3, 3, refs));
}

#[test]
fn sigterm_mid_job_exits_within_10_s_and_the_job_is_pending_or_done() {
    let env = env(0.2, "", "");
    // A larger scan (100k vertices): its job lasts long enough to be seen
    // running by a test thread that is not scheduled promptly, yet ends
    // well within the stop grace period.
    let staged = large_scan(&env, 2, 908, 100_000);
    let mut d = Daemon::start(&env);
    std::fs::rename(&staged, env.export.join("t.ply")).unwrap();
    let refs = d.references();
    let id = wait_running(&env.db);
    let sent = Instant::now();
    d.signal(libc::SIGTERM);
    let status = d.wait_exit(Duration::from_secs(10));
    let took = sent.elapsed();
    assert!(status.is_some(), "still running 10 s after SIGTERM");
    assert!(status.unwrap().success(), "{}", d.log_text());
    eprintln!("exited {:.2} s after SIGTERM", took.as_secs_f64());
    let r = rows(&env.db);
    assert_eq!(r.len(), 1);
    assert_eq!(r[0].id, id);
    match r[0].status {
        ScanStatus::Pending => assert_eq!(result_rows(&env.db, id), (0, 0, 0)),
        ScanStatus::Ok => assert_eq!(result_rows(&env.db, id), (3, 3, refs)),
        s => panic!("scan left {s:?}"),
    }
    // The next start finishes it.
    let _d = Daemon::start(&env);
    assert!(wait_until(Duration::from_secs(120), || finished(&env.db) >= 1));
    assert_eq!(result_rows(&env.db, id), (3, 3, refs));
}

#[test]
fn sighup_reloads_the_configuration() {
    let env = env(0.2, "", "");
    let d = Daemon::start(&env);
    let other = env.root.join("other");
    std::fs::create_dir_all(&other).unwrap();
    let text = std::fs::read_to_string(&env.config).unwrap().replace(
        &format!("dir = {:?}", env.export),
        &format!("dir = {other:?}"),
    );
    std::fs::write(&env.config, text).unwrap();
    d.signal(libc::SIGHUP);
    assert!(
        wait_until(Duration::from_secs(300), || d
            .log_text()
            .contains(&format!("reloaded: {} references", d.references()))),
        "{}",
        d.log_text()
    );
    std::fs::write(other.join("h.ply"), scan_bytes(0, 909)).unwrap();
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 1),
        "{}",
        d.log_text()
    );
    assert!(rows(&env.db)[0].path.ends_with("other/h.ply"));
}

#[test]
fn a_scan_that_killed_the_daemon_three_times_is_failed_not_retried_for_ever() {
    let env = env(0.2, "", "");
    std::fs::write(env.export.join("p.ply"), scan_bytes(3, 910)).unwrap();
    {
        let _d = Daemon::start(&env);
        assert!(wait_until(Duration::from_secs(120), || finished(&env.db) >= 1));
    }
    // As a daemon dying on it three times would leave it.
    let c = rusqlite::Connection::open(&env.db).unwrap();
    c.execute_batch(
        "DELETE FROM result; DELETE FROM distance;
         UPDATE scan SET status = 'running', attempts = 3, finished_at = NULL;",
    )
    .unwrap();
    drop(c);
    let d = Daemon::start(&env);
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 1),
        "{}",
        d.log_text()
    );
    let r = rows(&env.db);
    assert_eq!(r[0].status, ScanStatus::Error, "{r:?}");
    let message = r[0].error.as_deref().unwrap_or("");
    assert!(
        message.contains("p.ply") && message.contains("3 attempts"),
        "{message}"
    );
}

#[test]
fn sigterm_without_grace_abandons_the_job_which_the_next_start_identifies() {
    let env = env(0.2, "", "");
    // A large surface (400k vertices): its job lasts long enough to be cut.
    let big = morphoid_synth::mesh::crown(&morphoid_synth::mesh::CROWN_GENERA[4], 915, 400_000);
    let staging = env.root.join("big.ply");
    morphoid_data::mesh_io::save(&staging, &big).unwrap();
    let mut d = Daemon::start_with(&env, &[("MORPHOID_STOP_GRACE", "0")]);
    let refs = d.references();
    std::fs::rename(&staging, env.export.join("big.ply")).unwrap();
    let id = wait_running(&env.db);
    let sent = Instant::now();
    d.signal(libc::SIGTERM);
    // How soon it exits is not what this test checks (the test above
    // does, with the default grace): a generous bound.
    let status = d.wait_exit(Duration::from_secs(60));
    assert!(status.is_some_and(|s| s.success()), "{}", d.log_text());
    eprintln!(
        "exited {:.2} s after SIGTERM, job abandoned",
        sent.elapsed().as_secs_f64()
    );
    let r = rows(&env.db);
    assert_eq!(r[0].status, ScanStatus::Pending, "{r:?}\n{}", d.log_text());
    assert_eq!(r[0].attempts, 0);
    assert!(d.log_text().contains("abandoned"), "{}", d.log_text());
    let d = Daemon::start(&env);
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 1),
        "{}",
        d.log_text()
    );
    assert_eq!(rows(&env.db)[0].status, ScanStatus::Ok);
    assert_eq!(result_rows(&env.db, id), (3, 3, refs));
}
