//! The serial trigger: a thread that keeps the configured port open
//! (`serialport`, built without libudev), reads lines and passes those
//! matching the trigger regex to the control loop. A missing or unplugged
//! port is logged and retried with exponential backoff (capped), never
//! fatal. A plain thread rather than async I/O: the crate's reads block
//! (with a timeout), and one thread for one port costs nothing.

use regex::Regex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc::UnboundedSender;

/// First retry delay after the port fails.
const BACKOFF_START: Duration = Duration::from_millis(500);
/// Longest retry delay.
pub const BACKOFF_MAX: Duration = Duration::from_secs(30);
/// How long one read waits for input before the stop flag is checked.
const READ_TIMEOUT: Duration = Duration::from_millis(200);
/// The next retry delay: doubled, capped at [`BACKOFF_MAX`].
fn next_backoff(current: Duration) -> Duration {
    (current * 2).min(BACKOFF_MAX)
}

/// A running serial trigger thread; stopped when dropped.
#[derive(Debug)]
pub(super) struct SerialTrigger {
    stop: Arc<AtomicBool>,
}

impl SerialTrigger {
    /// Start reading `port` at `baud`; lines matching `trigger` are sent
    /// on `tx`.
    pub(super) fn start(
        port: String,
        baud: u32,
        trigger: Regex,
        tx: UnboundedSender<String>,
    ) -> std::io::Result<Self> {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        std::thread::Builder::new()
            .name("morphoid-serial".into())
            .spawn(move || run(&port, baud, &trigger, &tx, &flag))?;
        Ok(SerialTrigger { stop })
    }
}

impl Drop for SerialTrigger {
    fn drop(&mut self) {
        // The thread notices within one read timeout and closes the port.
        self.stop.store(true, Ordering::SeqCst);
    }
}

/// Why reading the port ended.
#[derive(Debug, thiserror::Error)]
enum LineError {
    #[error("the line was closed")]
    Closed,
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

/// Splits received bytes into trimmed, non-empty lines (CR, LF or CRLF).
#[derive(Debug, Default)]
struct LineSplitter {
    pending: Vec<u8>,
}

impl LineSplitter {
    /// Add bytes; returns the lines they complete.
    pub(crate) fn push(&mut self, bytes: &[u8]) -> Vec<String> {
        self.pending.extend_from_slice(bytes);
        let mut lines = Vec::new();
        while let Some(end) = self.pending.iter().position(|&b| b == b'\n' || b == b'\r') {
            let line: Vec<u8> = self.pending.drain(..=end).collect();
            let text = String::from_utf8_lossy(&line).trim().to_string();
            if !text.is_empty() {
                lines.push(text);
            }
        }
        // A device that never sends a newline must not grow memory.
        if self.pending.len() > 64 * 1024 {
            self.pending.clear();
        }
        lines
    }
}

/// Read lines from the port until it fails or `stop` is set; each line
/// matching `trigger` is sent.
fn read_lines(
    port: &mut dyn serialport::SerialPort,
    trigger: &Regex,
    tx: &UnboundedSender<String>,
    stop: &AtomicBool,
) -> Result<(), LineError> {
    let mut splitter = LineSplitter::default();
    let mut buf = [0u8; 512];
    while !stop.load(Ordering::SeqCst) {
        let n = match port.read(&mut buf) {
            Ok(0) => return Err(LineError::Closed),
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e.into()),
        };
        for text in splitter.push(&buf[..n]) {
            if trigger.is_match(&text) {
                tracing::info!("serial trigger: {text:?}");
                if tx.send(text).is_err() {
                    // The control loop is gone: the daemon is stopping.
                    return Ok(());
                }
            } else {
                tracing::debug!("serial line ignored: {text:?}");
            }
        }
    }
    Ok(())
}

/// Keep `port` open and forward trigger lines until `stop` is set.
fn run(port: &str, baud: u32, trigger: &Regex, tx: &UnboundedSender<String>, stop: &AtomicBool) {
    let mut backoff = BACKOFF_START;
    while !stop.load(Ordering::SeqCst) {
        match serialport::new(port, baud).timeout(READ_TIMEOUT).open() {
            Ok(mut p) => {
                tracing::info!("serial port {port} open at {baud} baud");
                backoff = BACKOFF_START;
                match read_lines(p.as_mut(), trigger, tx, stop) {
                    Ok(()) => return,
                    Err(e) => tracing::warn!("serial port {port} lost: {e}; reopening"),
                }
            }
            Err(e) => tracing::warn!(
                "serial port {port} unavailable: {e}; retrying in {:.1} s",
                backoff.as_secs_f64()
            ),
        }
        // Sleep in small steps so a stop request is honoured quickly.
        let until = Instant::now() + backoff;
        while Instant::now() < until && !stop.load(Ordering::SeqCst) {
            std::thread::sleep(Duration::from_millis(100));
        }
        backoff = next_backoff(backoff);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backoff_doubles_up_to_the_cap() {
        let mut d = BACKOFF_START;
        for _ in 0..20 {
            let n = next_backoff(d);
            assert!(n >= d && n <= BACKOFF_MAX);
            d = n;
        }
        assert_eq!(d, BACKOFF_MAX);
        let mut s = LineSplitter::default();
        assert_eq!(s.push(b"HEL"), Vec::<String>::new());
        assert_eq!(s.push(b"LO\r\n\nSCAN DONE\nx"), vec!["HELLO", "SCAN DONE"]);
    }
}
