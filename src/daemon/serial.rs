//! The serial trigger: a thread that keeps the configured port open, reads
//! lines and passes those matching the trigger regex to the control loop.
//! A missing or unplugged port is logged and retried with exponential
//! backoff (capped), never fatal. Raw termios through `libc`, so no udev.

use regex::Regex;
use std::fs::File;
use std::io::Read;
use std::os::fd::AsRawFd;
use std::os::unix::fs::OpenOptionsExt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::Arc;
use std::time::Duration;

/// First retry delay after the port fails.
const BACKOFF_START: Duration = Duration::from_millis(500);
/// Longest retry delay.
pub const BACKOFF_MAX: Duration = Duration::from_secs(30);

/// The next retry delay: doubled, capped at [`BACKOFF_MAX`].
pub fn next_backoff(current: Duration) -> Duration {
    (current * 2).min(BACKOFF_MAX)
}

/// The termios speed constant of a baud rate, `None` if unsupported.
pub fn speed_constant(baud: u32) -> Option<libc::speed_t> {
    Some(match baud {
        1200 => libc::B1200,
        2400 => libc::B2400,
        4800 => libc::B4800,
        9600 => libc::B9600,
        19200 => libc::B19200,
        38400 => libc::B38400,
        57600 => libc::B57600,
        115200 => libc::B115200,
        230400 => libc::B230400,
        460800 => libc::B460800,
        921600 => libc::B921600,
        _ => return None,
    })
}

/// Open `port` read-only as a raw 8N1 line at `baud`.
fn open_port(port: &str, baud: u32) -> std::io::Result<File> {
    let file = std::fs::OpenOptions::new()
        .read(true)
        // Non-blocking open: without CLOCAL (set below) opening a real
        // port can wait for carrier detect for ever.
        .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
        .open(port)?;
    let fd = file.as_raw_fd();
    let speed = speed_constant(baud).ok_or_else(|| {
        std::io::Error::new(std::io::ErrorKind::InvalidInput, "unsupported baud rate")
    })?;
    // SAFETY: fd is open for the lifetime of `file`; termios is plain data.
    unsafe {
        let mut t: libc::termios = std::mem::zeroed();
        if libc::tcgetattr(fd, &mut t) != 0 {
            return Err(std::io::Error::last_os_error());
        }
        libc::cfmakeraw(&mut t);
        t.c_cflag |= libc::CLOCAL | libc::CREAD;
        libc::cfsetispeed(&mut t, speed);
        libc::cfsetospeed(&mut t, speed);
        t.c_cc[libc::VMIN] = 1;
        t.c_cc[libc::VTIME] = 0;
        if libc::tcsetattr(fd, libc::TCSANOW, &t) != 0 {
            return Err(std::io::Error::last_os_error());
        }
        // Reads happen after poll() says there is input: blocking is fine.
        let flags = libc::fcntl(fd, libc::F_GETFL);
        if flags < 0 || libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK) != 0 {
            return Err(std::io::Error::last_os_error());
        }
    }
    Ok(file)
}

/// Wait up to `timeout` for input; true when readable (or hung up, which
/// the next read reports).
fn wait_readable(file: &File, timeout: Duration) -> std::io::Result<bool> {
    let mut pfd = libc::pollfd {
        fd: file.as_raw_fd(),
        events: libc::POLLIN,
        revents: 0,
    };
    let ms = timeout.as_millis().min(i32::MAX as u128) as libc::c_int;
    // SAFETY: one valid pollfd.
    let rc = unsafe { libc::poll(&mut pfd, 1, ms) };
    if rc < 0 {
        let e = std::io::Error::last_os_error();
        return if e.kind() == std::io::ErrorKind::Interrupted {
            Ok(false)
        } else {
            Err(e)
        };
    }
    Ok(rc > 0)
}

/// Read lines from the port until it fails or `stop` is set; each line
/// matching `trigger` is sent. Returns why it ended.
fn read_lines(
    file: &mut File,
    trigger: &Regex,
    tx: &Sender<String>,
    stop: &AtomicBool,
) -> std::io::Result<()> {
    let mut pending: Vec<u8> = Vec::new();
    let mut buf = [0u8; 512];
    while !stop.load(Ordering::SeqCst) {
        if !wait_readable(file, Duration::from_millis(200))? {
            continue;
        }
        let n = file.read(&mut buf)?;
        if n == 0 {
            return Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "the line was closed",
            ));
        }
        pending.extend_from_slice(&buf[..n]);
        while let Some(end) = pending.iter().position(|&b| b == b'\n' || b == b'\r') {
            let line: Vec<u8> = pending.drain(..=end).collect();
            let text = String::from_utf8_lossy(&line).trim().to_string();
            if text.is_empty() {
                continue;
            }
            if trigger.is_match(&text) {
                tracing::info!("serial trigger: {text:?}");
                if tx.send(text).is_err() {
                    return Ok(());
                }
            } else {
                tracing::debug!("serial line ignored: {text:?}");
            }
        }
        // A device that never sends a newline must not grow memory.
        if pending.len() > 64 * 1024 {
            pending.clear();
        }
    }
    Ok(())
}

/// Keep `port` open and forward trigger lines until `stop` is set.
pub fn run(port: String, baud: u32, trigger: Regex, tx: Sender<String>, stop: Arc<AtomicBool>) {
    let mut backoff = BACKOFF_START;
    while !stop.load(Ordering::SeqCst) {
        match open_port(&port, baud) {
            Ok(mut file) => {
                tracing::info!("serial port {port} open at {baud} baud");
                backoff = BACKOFF_START;
                match read_lines(&mut file, &trigger, &tx, &stop) {
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
        let until = std::time::Instant::now() + backoff;
        while std::time::Instant::now() < until && !stop.load(Ordering::SeqCst) {
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
        assert_eq!(speed_constant(9600), Some(libc::B9600));
        assert_eq!(speed_constant(9601), None);
    }
}
