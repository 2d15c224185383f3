//! The systemd notification protocol as a service manager sees it.

use crate::support::daemon::*;
use std::os::unix::net::UnixDatagram;
use std::time::{Duration, Instant};

#[test]
fn ready_status_watchdog_and_stopping_reach_the_service_manager() {
    let env = env(0.2, "", "");
    let socket_path = env.root.join("notify.sock");
    let socket = UnixDatagram::bind(&socket_path).unwrap();
    socket
        .set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let mut d = Daemon::start_with(
        &env,
        &[
            ("NOTIFY_SOCKET", socket_path.to_str().unwrap()),
            ("WATCHDOG_USEC", "1000000"),
        ],
    );
    let mut got: Vec<String> = Vec::new();
    let mut receive = |until: &dyn Fn(&[String]) -> bool, secs: u64| -> bool {
        let end = Instant::now() + Duration::from_secs(secs);
        let mut buf = [0u8; 1024];
        while Instant::now() < end {
            if let Ok(n) = socket.recv(&mut buf) {
                // One state per line; a trailing newline is allowed.
                for line in String::from_utf8_lossy(&buf[..n]).lines() {
                    got.push(line.to_string());
                }
            }
            if until(&got) {
                return true;
            }
        }
        false
    };
    let refs = d.references();
    let idle = format!("STATUS=idle, {refs} references, 0 scans today");
    assert!(
        receive(
            &|g| {
                g.iter().any(|m| m == "READY=1")
                    && g.contains(&idle)
                    && g.iter().filter(|m| *m == "WATCHDOG=1").count() >= 3
            },
            120
        ),
        "{got:?}"
    );
    let utc_day = || morphoid_service::store::utc_day_start_ms(morphoid_service::store::now_ms());
    let day_of_put = utc_day();
    // Where the lines that come after the scan begin.
    let mark = std::cell::Cell::new(0);
    receive(
        &|g| {
            mark.set(g.len());
            true
        },
        1,
    );
    // Put there whole: with a 0.2 s settle time, a file caught empty would
    // be a scan of its own, and the count could go past 1 unseen.
    put(&env, &env.export.join("n.ply"), &scan_bytes(0, 921));
    let done = format!("STATUS=idle, {refs} references, 1 scans today");
    // A scan that finishes just before midnight UTC is not one of the next
    // day's: then the idle line after it counts 0, with the scan recorded.
    let done_yesterday = |g: &[String]| {
        utc_day() != day_of_put
            && g.get(mark.get()..).is_some_and(|new| new.contains(&idle))
            && finished(&env.db) == 1
    };
    assert!(
        receive(&|g| g.contains(&done) || done_yesterday(g), 120),
        "{got:?}\n{}",
        d.log_text()
    );
    // A reload says so, and is ready again after it.
    d.signal(libc::SIGHUP);
    assert!(
        receive(
            &|g| {
                g.iter().any(|m| m == "RELOADING=1")
                    && g.iter().filter(|m| *m == "READY=1").count() >= 2
            },
            300
        ),
        "{got:?}\n{}",
        d.log_text()
    );
    d.signal(libc::SIGTERM);
    assert!(d.wait_exit(Duration::from_secs(60)).is_some());
    // Sent before the exit: already waiting on the socket.
    assert!(
        receive(&|g| g.iter().any(|m| m == "STOPPING=1"), 60),
        "{got:?}"
    );
}
