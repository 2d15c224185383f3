//! The console inside the real `morphoid run`: it starts with the daemon,
//! shows what the daemon does (its state and each scan as it is
//! identified) and stops with it.

use crate::support::daemon::{env, genus, put, scan_bytes, thread_niceness, wait_until, Daemon};
use crate::support::faults::running_as_root;
use std::time::Duration;

#[test]
fn http_the_console_follows_the_running_daemon() {
    let env = env(
        0.5,
        "",
        "[http]\nlisten = \"127.0.0.1:0\"\npublic_read = true\n",
    );
    let mut daemon = Daemon::start(&env);
    let base = daemon.console_url();
    // A fresh connection per request: the server closes a kept-alive
    // connection once it has been idle for the header timeout, and a
    // request sent on it at that moment fails (a POST is not retried).
    let client = reqwest::blocking::Client::builder()
        .pool_max_idle_per_host(0)
        .timeout(Duration::from_secs(20))
        .build()
        .unwrap();
    let get = |path: &str| -> serde_json::Value {
        client
            .get(format!("{base}{path}"))
            .send()
            .and_then(|r| r.error_for_status())
            .and_then(|r| r.json())
            .unwrap_or(serde_json::Value::Null)
    };
    assert!(
        wait_until(Duration::from_secs(30), || get("/api/v1/status")["running"]
            == true),
        "the daemon's state never reached the console"
    );
    // The console's threads run at the daemon's priority while it is
    // light, 15 nice steps below while busy, so that browsing many pages
    // yields the CPU to identification (README, "Identification first").
    // Coming back needs the right to lower a nice value (root here; else
    // they stay down).
    let console_niceness = || -> (i64, Vec<i64>) {
        let threads = thread_niceness(daemon.pid());
        let daemon_nice = threads
            .iter()
            .find(|(name, _)| name == "morphoid")
            .map(|t| t.1)
            .expect("the daemon's main thread");
        let console = threads
            .iter()
            .filter(|(name, _)| name == "morphoid-http")
            .map(|t| t.1)
            .collect();
        (daemon_nice, console)
    };
    let (daemon_nice, console) = console_niceness();
    assert!(!console.is_empty(), "no console thread");
    let down = (daemon_nice + 15).min(19);
    let light = if running_as_root() { daemon_nice } else { down };
    assert!(
        console.iter().all(|&n| n == light),
        "light console threads' nice values {console:?}, the daemon's {daemon_nice}"
    );
    // Busy: four clients asking back to back for the daemon's state (a
    // query each) for at most 10 s, until the console has gone down.
    let stop = std::sync::atomic::AtomicBool::new(false);
    let busy_seen = std::thread::scope(|scope| {
        for _ in 0..4 {
            scope.spawn(|| {
                let t = std::time::Instant::now();
                while !stop.load(std::sync::atomic::Ordering::Relaxed)
                    && t.elapsed() < Duration::from_secs(10)
                {
                    get("/api/v1/status");
                }
            });
        }
        let seen = wait_until(Duration::from_secs(10), || {
            let (_, console) = console_niceness();
            !console.is_empty() && console.iter().all(|&n| n == down)
        });
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        seen
    });
    assert!(
        busy_seen,
        "the busy console stayed at {:?}",
        console_niceness().1
    );
    assert!(
        wait_until(Duration::from_secs(10), || console_niceness()
            .1
            .iter()
            .all(|&n| n == light)),
        "the console, light again, stayed at {:?}",
        console_niceness().1
    );
    let status = get("/api/v1/status");
    assert_eq!(status["references"], daemon.references());
    assert_eq!(status["watching"], env.export.display().to_string());
    assert_eq!(get("/api/v1/references")["count"], daemon.references());

    put(&env, &env.export.join("new.ply"), &scan_bytes(1, 77));
    assert!(
        wait_until(Duration::from_secs(300), || get("/api/v1/scans?status=ok")
            ["scans"]
            .as_array()
            .is_some_and(|s| s.len() == 1)),
        "the scan was not shown identified:\n{}",
        daemon.log_text()
    );
    let scans = get("/api/v1/scans?status=ok");
    let scan = &scans["scans"][0];
    assert_eq!(
        scan["scan"],
        env.export.join("new.ply").display().to_string()
    );
    assert_eq!(scan["ranks"]["genus"]["taxon"], genus(1));
    let id = scan["id"].as_i64().unwrap();
    let by_genus = get(&format!("/api/v1/scans?genus={}", genus(1)));
    assert_eq!(by_genus["scans"][0]["id"], id);
    let page = client.get(format!("{base}/scans/{id}")).send().unwrap();
    assert_eq!(page.status().as_u16(), 200);
    let page = page.text().unwrap();
    assert!(page.contains("new.ply"));
    // The report's pictures and 3D view, drawn again from the scan's file
    // by the daemon's library.
    assert!(
        page.contains("src=\"data:image/png;base64,"),
        "no pictures in the console's report:\n{page}"
    );
    assert!(
        page.contains("<canvas"),
        "no 3D view in the console's report"
    );
    let metrics = client
        .get(format!("{base}/metrics"))
        .send()
        .unwrap()
        .text()
        .unwrap();
    assert!(
        metrics.contains("morphoid_identification_seconds_count 1"),
        "{metrics}"
    );
    assert!(metrics.contains("morphoid_daemon_running 1"), "{metrics}");

    // A curator confirms it and adds it to the library: the daemon reloads
    // and uses it, without a restart.
    let before = daemon.references();
    let mut store = morphoid_service::store::Store::open(&env.db).unwrap();
    let hash = morphoid_service::http::hash_password("a long password").unwrap();
    store.add_curator("ana", &hash).unwrap();
    let token = morphoid_service::http::new_api_token();
    store
        .add_api_token("ana", &morphoid_service::http::token_hash(&token), "test")
        .unwrap();
    drop(store);
    let post = |path: &str, body: serde_json::Value| {
        client
            .post(format!("{base}{path}"))
            .bearer_auth(&token)
            .json(&body)
            .send()
            .unwrap()
            .status()
            .as_u16()
    };
    assert_eq!(
        post(
            &format!("/api/v1/scans/{id}/review"),
            serde_json::json!({"decision": "confirm"})
        ),
        201
    );
    let asked = std::time::Instant::now();
    assert_eq!(
        post(
            &format!("/api/v1/scans/{id}/add-to-library"),
            serde_json::json!({})
        ),
        201
    );
    assert!(
        wait_until(Duration::from_secs(120), || get("/api/v1/references")
            ["count"]
            == before + 1
            && get("/api/v1/status")["references"] == before + 1),
        "the daemon did not take the new reference:\n{}",
        daemon.log_text()
    );
    eprintln!(
        "added reference in use after {:.1} s",
        asked.elapsed().as_secs_f64()
    );
    assert!(daemon
        .log_text()
        .contains(&format!("reloaded: {} references", before + 1)));
    let names: Vec<String> = get("/api/v1/references")["references"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["name"].as_str().unwrap().to_string())
        .collect();
    assert!(names.contains(&"new".to_string()), "{names:?}");

    daemon.signal(libc::SIGTERM);
    let exit = daemon
        .wait_exit(Duration::from_secs(30))
        .expect("the daemon stops");
    assert!(exit.success(), "{exit:?}\n{}", daemon.log_text());
    assert!(daemon.log_text().contains("web console stopped"));
    assert!(
        client.get(format!("{base}/healthz")).send().is_err(),
        "still served after the stop"
    );
}
