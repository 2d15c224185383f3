//! Thread priorities inside the daemon: identifying the scanner's scans
//! comes first; the console and the calibration take the CPU it leaves (on
//! an idle machine this changes nothing), the console before the
//! calibration.

/// How many nice steps below the daemon the calibration's threads run: as
/// far as Linux goes (nice 19 for a daemon at 0). The calibration is long
/// and nobody waits on it.
pub(crate) const BACKGROUND_NICENESS: i32 = 19;

/// How many nice steps below the daemon the console's threads run. Fewer
/// than the calibration's: a person waits on each page. Measured in one
/// session with `benches/console_load.rs` (200 connections, 48 scans
/// identified meanwhile; identification's rate against its rate without
/// the load, then the p95 latency), a request a second on each connection
/// / requests back to back:
///
/// | steps | a request a second | back to back |
/// |-------|--------------------|--------------|
/// | 10    | 0.93, 6.3–6.7 ms   | 0.73, 63–64 ms |
/// | 15    | 0.93, 23 ms        | 0.80, 69–72 ms |
/// | 19    | 1.00, 52–56 ms     | 0.87, 109–116 ms |
///
/// 15 keeps a person's pages well under 50 ms while scans are identified.
/// A client on the same two cores asking back to back takes CPU for itself
/// at the daemon's priority, which no niceness of the console's takes back;
/// nor did slowing each connection to 10 requests a second while a scan is
/// identified (0.76 back to back at 10 steps).
pub(crate) const CONSOLE_NICENESS: i32 = 15;

/// The nice value [`BACKGROUND_NICENESS`] steps below the calling
/// process, at most 19.
pub(crate) fn background_niceness() -> i32 {
    niceness_below(BACKGROUND_NICENESS)
}

/// The nice value [`CONSOLE_NICENESS`] steps below the calling process, at
/// most 19.
pub(crate) fn console_niceness() -> i32 {
    niceness_below(CONSOLE_NICENESS)
}

/// The nice value `steps` below the calling process's, at most 19.
fn niceness_below(steps: i32) -> i32 {
    let base = rustix::process::getpriority_process(None).unwrap_or(0);
    (base + steps).min(19)
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
