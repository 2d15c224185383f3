//! What `morphoid run` leaves in its results folder: a report and a
//! thumbnail per scan and the overview, written whole; a results folder
//! that cannot be written (an error in the log and in the scan's row, the
//! identification recorded, the files written once it can be); and the
//! library's calibration fitted in the background while scans are
//! identified.

use crate::support::daemon::*;
use morphoid_service::store::{ScanRecord, ScanStatus};
use morphoid_synth::mesh::LibrarySpec;
use std::collections::BTreeSet;
use std::os::unix::net::UnixDatagram;
use std::path::Path;
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Append `[results] dir` to the config, and `calibrate = false` to its
/// `[library]` unless `calibrate`.
fn with_results(env: &Env, results: &Path, calibrate: bool) {
    let mut text = std::fs::read_to_string(&env.config).unwrap();
    if !calibrate {
        text = text.replace("[library]\n", "[library]\ncalibrate = false\n");
    }
    text.push_str(&format!("[results]\ndir = {results:?}\n"));
    std::fs::write(&env.config, text).unwrap();
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Every file under `dir`, relative, sorted.
fn files_under(dir: &Path) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(p.strip_prefix(dir).unwrap().to_string_lossy().into_owned());
            }
        }
    }
    out
}

/// The row of the scan at `path`.
fn row_of(db: &Path, path: &Path) -> Option<ScanRecord> {
    rows(db).into_iter().find(|r| Path::new(&r.path) == path)
}

/// `morphoid results` (plain, or `--json` parsed per line).
fn results_plain(env: &Env) -> String {
    let o = Command::new(BIN)
        .args(["results", "--config"])
        .arg(&env.config)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

fn results_json(env: &Env) -> Vec<serde_json::Value> {
    let o = Command::new(BIN)
        .args(["results", "--json", "--config"])
        .arg(&env.config)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Put `bytes` at `path` and wait until the daemon has queued it, so that
/// scans get their ids in the order they are put.
fn put_queued(env: &Env, path: &Path, bytes: &[u8]) {
    let before = rows(&env.db).len();
    put(env, path, bytes);
    assert!(
        wait_until(Duration::from_secs(60), || rows(&env.db).len() > before),
        "{} was not queued",
        path.display()
    );
}

#[test]
fn the_daemon_writes_a_report_per_scan_and_the_overview_newest_first() {
    // broken.ply is short of the elements its header declares: it waits
    // a second for the rest, then is recorded as an error.
    let env = env(0.3, "incomplete_seconds = 1", "");
    let out = env.root.join("results");
    with_results(&env, &out, false);
    let _d = Daemon::start(&env);
    let first = env.export.join("tooth 1.ply");
    let bad = env.export.join("broken.ply");
    let second = env.export.join("tooth 4.ply");
    put_queued(&env, &first, &scan_bytes(1, 71));
    put_queued(
        &env,
        &bad,
        b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n",
    );
    put_queued(&env, &second, &scan_bytes(4, 72));
    // Exactly the files of three scans and the overview: no temporary
    // file left by an atomic write.
    let expected: BTreeSet<String> = [
        "tooth 1.ply.json",
        "tooth 1.ply.html",
        "tooth 1.ply.png",
        "tooth 4.ply.json",
        "tooth 4.ply.html",
        "tooth 4.ply.png",
        "broken.ply.json",
        "broken.ply.html",
        "index.html",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    // Done when every file is there and the overview shows both
    // thumbnails: it is written after the files of the scans it shows.
    let done = || {
        finished(&env.db) == 3
            && out.is_dir()
            && files_under(&out).is_superset(&expected)
            && read_index(&out)
                .is_some_and(|i| i.contains("tooth%201.ply.png") && i.contains("tooth%204.ply.png"))
    };
    assert!(
        wait_until(Duration::from_secs(240), done),
        "{}",
        _d.log_text()
    );
    assert_eq!(files_under(&out), expected);

    for (scan, g) in [(&first, 1), (&second, 4)] {
        let html = read(&out.join(format!("{}.html", file(scan))));
        assert!(html.contains(&format!("<b>{}</b>", genus(g))), "{html}");
        assert_eq!(html.matches("data:image/png;base64,").count(), 6);
        assert!(html.contains("<canvas id=\"viewer\""));
        // Without a calibration the page says so.
        assert!(html.contains("not calibrated"));
        assert!(!html.contains("files-error"));
        let png = image::open(out.join(format!("{}.png", file(scan))))
            .unwrap()
            .to_rgba8();
        assert!(png.pixels().filter(|p| p[3] != 0).count() > 500);
    }
    let html = read(&out.join("broken.ply.html"));
    let error = rows(&env.db)
        .into_iter()
        .find(|r| r.status == ScanStatus::Error)
        .and_then(|r| r.error)
        .unwrap();
    assert!(error.contains("broken.ply"), "{error}");
    assert!(html.contains("id=\"error\""), "{html}");
    assert!(
        html.contains(&morphoid_data::present::escape(&error)),
        "{html}"
    );

    // The overview lists the three newest first, the failed one with its
    // error, each linking to its report.
    let index = read(&out.join("index.html"));
    let at: Vec<usize> = [
        "tooth%204.ply.html",
        "broken.ply.html",
        "tooth%201.ply.html",
    ]
    .iter()
    .map(|l| index.find(&format!("href=\"{l}\"")).unwrap())
    .collect();
    assert!(at.windows(2).all(|w| w[0] < w[1]), "{at:?}");
    assert!(index.contains(&morphoid_data::present::escape(&error)));
    assert!(index.contains("class=\"bad\""));
    assert!(index.contains("tooth%201.ply.png") && index.contains("tooth%204.ply.png"));
    assert!(!index.contains("result files not written"));
}

/// The overview, when it exists.
fn read_index(out: &Path) -> Option<String> {
    std::fs::read_to_string(out.join("index.html")).ok()
}

/// The file name of `p`.
fn file(p: &Path) -> String {
    p.file_name().unwrap().to_string_lossy().into_owned()
}

#[test]
fn an_unwritable_results_folder_is_in_the_log_and_the_row_until_written() {
    let env = env(0.3, "", "");
    // A folder below a regular file cannot be created, even by root.
    let blocker = env.root.join("not-a-folder");
    std::fs::write(&blocker, b"x").unwrap();
    let out = blocker.join("results");
    with_results(&env, &out, false);
    let d = Daemon::start(&env);
    let scan = env.export.join("tooth.ply");
    put(&env, &scan, &scan_bytes(2, 81));
    let failed = || row_of(&env.db, &scan).is_some_and(|r| r.files_error.is_some());
    assert!(
        wait_until(Duration::from_secs(120), failed),
        "{}",
        d.log_text()
    );
    // The identification is recorded all the same.
    let row = row_of(&env.db, &scan).unwrap();
    assert_eq!(row.status, ScanStatus::Ok);
    assert_eq!(genus_of(&row), Some(genus(2)));
    let message = row.files_error.clone().unwrap();
    assert!(message.contains("not-a-folder"), "{message}");
    // In the log, as an error naming the folder (written after the row).
    let logged = || {
        d.log_text()
            .lines()
            .any(|l| l.contains("ERROR") && l.contains("not-a-folder"))
    };
    assert!(
        wait_until(Duration::from_secs(30), logged),
        "{}",
        d.log_text()
    );
    // In `morphoid results`, plain and JSON.
    let plain = results_plain(&env);
    assert!(
        plain.contains("result files not written") && plain.contains("not-a-folder"),
        "{plain}"
    );
    let json = results_json(&env);
    assert_eq!(json[0]["status"], "ok");
    assert_eq!(json[0]["files_error"], message.as_str());
    // The report of that scan, written from the database elsewhere,
    // shows it; so does the overview's row.
    let elsewhere = env.root.join("elsewhere");
    let o = Command::new(BIN)
        .args(["report", &row.id.to_string(), "--config"])
        .arg(&env.config)
        .arg("--out")
        .arg(&elsewhere)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page = read(&elsewhere.join("tooth.ply.html"));
    assert!(page.contains("id=\"files-error\""), "{page}");
    assert!(page.contains("not-a-folder"));
    let index = read(&elsewhere.join("index.html"));
    assert!(index.contains("result files not written"), "{index}");

    // The folder can be made: the next attempt writes the files and the
    // error is gone from the row, the JSON and the pages.
    std::fs::remove_file(&blocker).unwrap();
    std::fs::create_dir(&blocker).unwrap();
    let written = || {
        row_of(&env.db, &scan).is_some_and(|r| r.files_error.is_none())
            && out.join("index.html").is_file()
    };
    assert!(
        wait_until(Duration::from_secs(120), written),
        "{}",
        d.log_text()
    );
    assert!(results_json(&env)[0].get("files_error").is_none());
    assert!(!results_plain(&env).contains("result files not written"));
    let page = read(&out.join("tooth.ply.html"));
    assert!(!page.contains("files-error"), "{page}");
    assert!(!read(&out.join("index.html")).contains("result files not written"));
    let json: serde_json::Value = serde_json::from_str(&read(&out.join("tooth.ply.json"))).unwrap();
    assert!(json.get("files_error").is_none(), "{json}");
}

/// A deployment whose library (5 per genus, 25 crowns at 800 vertices)
/// takes many times longer to calibrate (every pair of references, on
/// half the cores) than a scan takes to identify (each reference once).
fn calibrating_env() -> Env {
    let spec = LibrarySpec {
        per_genus: 5,
        target_vertices: 800,
        seed: 11,
        random_pose: true,
    };
    let env = env_with(&spec, 0.3, "", "");
    let mut config = std::fs::read_to_string(&env.config).unwrap();
    config += &format!("[results]\ndir = {:?}\n", env.root.join("results"));
    std::fs::write(&env.config, config).unwrap();
    env
}

/// The STATUS lines a service manager gets, collected on a thread.
fn status_lines(socket: UnixDatagram) -> Arc<Mutex<Vec<String>>> {
    let got = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&got);
    socket
        .set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    std::thread::spawn(move || {
        let mut buf = [0u8; 2048];
        loop {
            if let Ok(n) = socket.recv(&mut buf) {
                let mut lines = sink.lock().unwrap();
                for l in String::from_utf8_lossy(&buf[..n]).lines() {
                    if let Some(s) = l.strip_prefix("STATUS=") {
                        lines.push(s.to_string());
                    }
                }
            }
            if Arc::strong_count(&sink) == 1 {
                return;
            }
        }
    });
    got
}

#[test]
fn scans_are_identified_while_the_calibration_runs_and_get_confidence_after() {
    let env = calibrating_env();
    let socket_path = env.root.join("notify.sock");
    let status = status_lines(UnixDatagram::bind(&socket_path).unwrap());
    // There before the start: queued as soon as the library is loaded.
    let early = env.export.join("early.ply");
    put(&env, &early, &scan_bytes(3, 301));
    let d = Daemon::start_with(&env, &[("NOTIFY_SOCKET", socket_path.to_str().unwrap())]);
    let recorded = |p: &Path| row_of(&env.db, p).is_some_and(|r| r.status == ScanStatus::Ok);
    // The calibration's threads run 19 nice steps below the daemon's, so
    // that a scan arriving meanwhile is identified first.
    let calibration_niceness = || {
        let threads = thread_niceness(d.pid());
        let daemon_nice = threads.iter().find(|(n, _)| n == "morphoid")?.1;
        let niceness: Vec<i64> = threads
            .iter()
            .filter(|(n, _)| n.starts_with("morphoid-calib"))
            .map(|t| t.1)
            .collect();
        (!niceness.is_empty()).then_some((daemon_nice, niceness))
    };
    // (A thread just started may not have lowered itself yet.)
    let mut seen = None;
    let lowered = wait_until(Duration::from_secs(60), || {
        seen = calibration_niceness();
        seen.as_ref().is_some_and(|(daemon_nice, niceness)| {
            niceness.iter().all(|&n| n == (daemon_nice + 19).min(19))
        })
    });
    assert!(
        lowered,
        "calibration threads' nice values (daemon's, theirs): {seen:?}\n{}",
        d.log_text()
    );
    assert!(
        wait_until(Duration::from_secs(240), || recorded(&early)),
        "{}",
        d.log_text()
    );
    // The row is committed before its log line is written.
    assert!(
        wait_until(Duration::from_secs(30), || d
            .log_text()
            .contains("early.ply: order=")),
        "result not logged: {}",
        d.log_text()
    );
    let row = row_of(&env.db, &early).unwrap();
    let log = d.log_text();
    let started = log.find("calibration started").expect("start logged");
    let identified = log.find("early.ply: order=").expect("result logged");
    assert!(started < identified, "{log}");
    assert_eq!(genus_of(&row), Some(genus(3)));
    // Whether the calibration was still running when the scan was
    // identified is recorded with it.
    assert!(
        row.calibrating,
        "the calibration finished before the first scan: the library is too small for this test\n{row:?}\n{log}"
    );
    assert!(row.ranks.iter().all(|r| r.confidence.is_none()), "{row:?}");
    let json = results_json(&env);
    assert_eq!(json[0]["calibrating"], true);
    assert!(json[0]["ranks"]["genus"]["probability"].is_null());
    assert!(results_plain(&env).contains("confidence: calibrating"));
    let report = env.root.join("results").join("early.ply.html");
    assert!(
        wait_until(Duration::from_secs(60), || report.is_file()),
        "{}",
        d.log_text()
    );
    assert!(read(&report).contains("confidence: calibrating"));
    // The service manager is told while it runs.
    assert!(
        wait_until(Duration::from_secs(10), || status
            .lock()
            .unwrap()
            .iter()
            .any(|s| s.contains("calibrating the confidence"))),
        "{:?}",
        status.lock().unwrap()
    );

    // Once ready, new scans carry their confidence.
    assert!(
        wait_until(Duration::from_secs(600), || d
            .log_text()
            .contains("calibration done")),
        "{}",
        d.log_text()
    );
    let late = env.export.join("late.ply");
    put(&env, &late, &scan_bytes(0, 302));
    assert!(
        wait_until(Duration::from_secs(120), || recorded(&late)),
        "{}",
        d.log_text()
    );
    let row = row_of(&env.db, &late).unwrap();
    assert!(!row.calibrating);
    let genus_rank = row.ranks.iter().find(|r| r.rank == "genus").unwrap();
    let p = genus_rank
        .confidence
        .as_ref()
        .expect("confidence")
        .probability;
    assert!((0.0..=1.0).contains(&p));
    let json = results_json(&env);
    assert!(json[0].get("calibrating").is_none());
    assert_eq!(json[0]["ranks"]["genus"]["probability"].as_f64(), Some(p));
    // The earlier scan keeps what it was identified with.
    assert!(row_of(&env.db, &early).unwrap().calibrating);
    let index = env.root.join("results").join("index.html");
    assert!(
        wait_until(Duration::from_secs(60), || read_index(
            &env.root.join("results")
        )
        .is_some_and(|i| i.contains("late.ply"))),
        "{}",
        d.log_text()
    );
    let index = read(&index);
    assert!(index.contains("confidence: calibrating"));
    assert!(index.contains(&format!("{:.0} %", p * 100.0)));
    // One line at the start and one at the end, with its duration; the
    // status line no longer mentions it.
    let log = d.log_text();
    assert_eq!(log.matches("calibration started").count(), 1, "{log}");
    let done: Vec<&str> = log
        .lines()
        .filter(|l| l.contains("calibration done"))
        .collect();
    assert_eq!(done.len(), 1, "{log}");
    assert!(
        done[0].contains(" s (held out: ") && done[0].contains("genus "),
        "{}",
        done[0]
    );
    assert!(
        wait_until(Duration::from_secs(10), || status
            .lock()
            .unwrap()
            .last()
            .is_some_and(|s| !s.contains("calibrating"))),
        "{:?}",
        status.lock().unwrap()
    );
}
