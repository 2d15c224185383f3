//! Thread priorities inside the daemon: identifying the scanner's scans
//! comes first; the console and the calibration take the CPU it leaves (on
//! an idle machine this changes nothing).

/// How many nice steps below the daemon the background threads run (the
/// console's, the calibration's): as far as Linux goes (nice 19 for a
/// daemon at 0). Measured with `benches/console_load.rs`, 200 connections
/// back to back: identification kept 0.75 of its rate at 10 steps, 0.84 at
/// 15 and 0.87 at 19 (0.92–0.95 with the load client niced as well, as
/// when the browsers are on other machines). The console's price is its
/// latency while a scan is identified: p95 36–40 ms at a request a second
/// on each connection, against 6 ms at 10 steps.
pub(crate) const BACKGROUND_NICENESS: i32 = 19;

/// The nice value [`BACKGROUND_NICENESS`] steps below the calling
/// process, at most 19.
pub(crate) fn background_niceness() -> i32 {
    let base = rustix::process::getpriority_process(None).unwrap_or(0);
    (base + BACKGROUND_NICENESS).min(19)
}

/// Give the calling thread the nice value `niceness` (absolute, so that a
/// thread started by a background thread does not go lower still). A
/// refusal leaves it at the daemon's priority, which is only slower for
/// identification under load; `what` names the thread in the debug line.
pub(crate) fn set_thread_niceness(niceness: i32, what: &str) {
    let thread = rustix::thread::gettid();
    if let Err(e) = rustix::process::setpriority_process(Some(thread), niceness) {
        tracing::debug!("{what} thread stays at the daemon's priority: {e}");
    }
}
