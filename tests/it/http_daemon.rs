//! The console inside the real `morphoid run`: it starts with the daemon,
//! shows what the daemon does (its state and each scan as it is
//! identified) and stops with it.

use crate::support::daemon::{env, genus, put, scan_bytes, wait_until, Daemon};
use std::time::Duration;

#[test]
fn http_the_console_follows_the_running_daemon() {
    let env = env(
        0.5,
        "",
        "[http]\nlisten = \"127.0.0.1:0\"\npublic_read = true\n",
    );
    let mut daemon = Daemon::start(&env);
    let log = daemon.log_text();
    let base = log
        .split("web console listening on ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .unwrap_or_else(|| panic!("no listening line:\n{log}"))
        .to_string();
    let client = reqwest::blocking::Client::builder()
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
    assert!(page.text().unwrap().contains("new.ply"));
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
