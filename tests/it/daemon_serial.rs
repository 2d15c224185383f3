//! A pseudo-terminal pair stands in for the scanner's serial line.

use crate::support::daemon::*;
use morphoid_service::daemon::BACKOFF_MAX;
use morphoid_service::store::ScanStatus;
use std::fs::File;
use std::io::Write;
use std::os::fd::FromRawFd;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Open a pty pair; returns the master end and the slave's device path
/// (the slave fd is closed: the daemon opens the device itself).
fn pty() -> (File, PathBuf) {
    let (mut master, mut slave) = (0, 0);
    // SAFETY: openpty writes two fds; the optional arguments are null.
    let rc = unsafe {
        libc::openpty(
            &mut master,
            &mut slave,
            std::ptr::null_mut(),
            std::ptr::null(),
            std::ptr::null(),
        )
    };
    assert_eq!(rc, 0, "openpty: {}", std::io::Error::last_os_error());
    // Not inherited by the daemon, or closing our end would not hang up.
    // SAFETY: fcntl on our own open fds.
    unsafe {
        libc::fcntl(master, libc::F_SETFD, libc::FD_CLOEXEC);
        libc::fcntl(slave, libc::F_SETFD, libc::FD_CLOEXEC);
    }
    let name = std::fs::read_link(format!("/proc/self/fd/{slave}")).unwrap();
    // SAFETY: both fds are ours and open.
    unsafe {
        drop(File::from_raw_fd(slave));
        (File::from_raw_fd(master), name)
    }
}

fn point(link: &Path, target: &Path) {
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(target, link).unwrap();
}

fn count(log: &str, what: &str) -> usize {
    log.matches(what).count()
}

#[test]
fn trigger_lines_rescan_the_folder_and_an_unplugged_port_is_survived() {
    // Settle time of an hour: only a trigger takes files.
    let link_dir = tempfile::tempdir().unwrap();
    let link = link_dir.path().join("ttyTEST");
    let (mut master, device) = pty();
    point(&link, &device);
    let serial = format!(
        "[serial]\nport = {:?}\nbaud = 9600\ntrigger = \"^SCAN (COMPLETE|DONE)\"\n",
        link
    );
    let env = env(3600.0, "", &serial);
    let d = Daemon::start(&env);
    assert!(wait_until(Duration::from_secs(120), || count(
        &d.log_text(),
        "open at 9600 baud"
    ) == 1));

    std::fs::write(env.export.join("a.ply"), scan_bytes(0, 911)).unwrap();
    master.write_all(b"HELLO\r\nSCAN STARTED\n").unwrap();
    std::thread::sleep(Duration::from_secs(3));
    assert!(rows(&env.db).is_empty(), "taken without a trigger");
    master.write_all(b"SCAN DONE\r\n").unwrap();
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) == 1),
        "{}",
        d.log_text()
    );

    // A trigger line naming a file outside the export folder: not taken.
    let outside = tempfile::tempdir().unwrap();
    let foreign = outside.path().join("o.ply");
    std::fs::write(&foreign, scan_bytes(4, 919)).unwrap();
    master
        .write_all(format!("SCAN DONE {}\n", foreign.display()).as_bytes())
        .unwrap();
    assert!(wait_until(Duration::from_secs(120), || count(
        &d.log_text(),
        "serial trigger:"
    ) == 2));
    std::thread::sleep(Duration::from_secs(2));
    assert_eq!(
        rows(&env.db).len(),
        1,
        "a file outside the folder was taken"
    );

    // A trigger line naming a file.
    std::fs::write(env.export.join("b.ply"), scan_bytes(1, 912)).unwrap();
    master.write_all(b"SCAN COMPLETE b.ply\n").unwrap();
    assert!(wait_until(Duration::from_secs(120), || finished(&env.db) == 2));

    // Unplugged: the far end closes; later a new device appears.
    drop(master);
    assert!(
        wait_until(Duration::from_secs(120), || d.log_text().contains("lost")),
        "{}",
        d.log_text()
    );
    std::thread::sleep(Duration::from_secs(1));
    let (mut master, device) = pty();
    point(&link, &device);
    assert!(
        wait_until(Duration::from_secs(120), || count(
            &d.log_text(),
            "open at 9600 baud"
        ) == 2),
        "{}",
        d.log_text()
    );
    std::fs::write(env.export.join("c.ply"), scan_bytes(2, 913)).unwrap();
    master.write_all(b"SCAN DONE\n").unwrap();
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) == 3),
        "{}",
        d.log_text()
    );
    let r = rows(&env.db);
    assert_eq!(r.len(), 3);
    for (row, (name, g)) in r.iter().zip([("a.ply", 0), ("b.ply", 1), ("c.ply", 2)]) {
        assert!(row.path.ends_with(name), "{}", row.path);
        assert_eq!(row.status, ScanStatus::Ok);
        assert_eq!(genus_of(row), Some(genus(g)));
    }
}

#[test]
fn an_absent_port_is_retried_and_does_not_stop_the_daemon() {
    let link_dir = tempfile::tempdir().unwrap();
    let link = link_dir.path().join("ttyNONE");
    let serial = format!(
        "[serial]\nport = {:?}\nbaud = 9600\ntrigger = \"^GO$\"\n",
        link
    );
    let env = env(0.2, "", &serial);
    let d = Daemon::start(&env);
    assert!(wait_until(Duration::from_secs(120), || count(
        &d.log_text(),
        "unavailable"
    ) >= 2));
    // The folder is still watched (the file put there whole: with a 0.2 s
    // settle time, one caught empty would be a scan of its own).
    put(&env, &env.export.join("a.ply"), &scan_bytes(3, 914));
    assert!(wait_until(Duration::from_secs(120), || finished(&env.db) == 1));
    // The port appears: opened at the next retry, at most BACKOFF_MAX
    // after the last, with as much again as margin.
    let (mut master, device) = pty();
    point(&link, &device);
    assert!(
        wait_until(2 * BACKOFF_MAX, || d
            .log_text()
            .contains("open at 9600 baud")),
        "{}",
        d.log_text()
    );
    master.write_all(b"GO\n").unwrap();
    assert!(wait_until(Duration::from_secs(120), || d
        .log_text()
        .contains("serial trigger: \"GO\"")));
}
