//! Thread priorities inside the daemon: identifying the scanner's scans
//! comes first. The calibration takes the CPU identification leaves; so
//! does the console while it is busy, but while it is light (a person or
//! a few browsers) it runs at the daemon's priority, so that a page never
//! waits on identification's scheduler slices ([`ConsolePriority`]). On an
//! idle machine none of this changes anything.

/// How many nice steps below the daemon the calibration's threads run: as
/// far as Linux goes (nice 19 for a daemon at 0). The calibration is long
/// and nobody waits on it.
pub(crate) const BACKGROUND_NICENESS: i32 = 19;

/// How many nice steps below the daemon the console's threads run while
/// the console is busy ([`ConsolePriority`]). Fewer than the
/// calibration's: a person waits on each page. Measured in one session
/// with `benches/console_load.rs` (200 connections, 48 scans identified
/// meanwhile; identification's rate against its rate without the load,
/// then the p95 latency), a request a second on each connection / requests
/// back to back, the console always at these steps:
///
/// | steps | a request a second | back to back |
/// |-------|--------------------|--------------|
/// | 10    | 0.93, 6.3–6.7 ms   | 0.73, 63–64 ms |
/// | 15    | 0.93, 23 ms        | 0.80, 69–72 ms |
/// | 19    | 1.00, 52–56 ms     | 0.87, 109–116 ms |
///
/// 15 keeps identification's rate when the console is busy. A client on
/// the same two cores asking back to back takes CPU for itself at the
/// daemon's priority, which no niceness of the console's takes back; nor
/// did slowing each connection to 10 requests a second while a scan is
/// identified (0.76 back to back at 10 steps).
pub(crate) const CONSOLE_NICENESS: i32 = 15;

/// The share of one core the console's threads may run, averaged over
/// [`CONSOLE_WINDOW`], before they go [`CONSOLE_NICENESS`] steps down. 200
/// connections asking once a second run about 0.09 of a core (0.43 ms a
/// request, `benches/console_load.rs`); asking back to back, far more.
/// While light, a page waits on no scheduler slice of identification's (p95
/// 23–52 ms at 15 steps at a request a second, the table above), and what
/// it takes from identification is small.
const CONSOLE_HEAVY_SHARE: f64 = 0.2;

/// The share of one core the busy console's threads must fall below, run
/// and waiting to run together, to come back up. Waiting counts: 15 steps
/// down under identification they run a few percent of a core however
/// many requests wait, and by their run time alone they would flap.
const CONSOLE_LIGHT_SHARE: f64 = 0.10;

/// How often the console's threads' times are read.
const CONSOLE_TICK: std::time::Duration = std::time::Duration::from_millis(250);

/// How many ticks the console's shares are averaged over (1 s).
const CONSOLE_WINDOW: usize = 4;

/// The nice value [`BACKGROUND_NICENESS`] steps below the calling
/// process, at most 19.
pub(crate) fn background_niceness() -> i32 {
    niceness_below(BACKGROUND_NICENESS)
}

/// The nice value `steps` below the calling process's, at most 19.
fn niceness_below(steps: i32) -> i32 {
    steps_below(
        rustix::process::getpriority_process(None).unwrap_or(0),
        steps,
    )
}

/// The nice value `steps` below `base`, at most 19.
fn steps_below(base: i32, steps: i32) -> i32 {
    (base + steps).min(19)
}

/// Give the calling thread the nice value `niceness` (absolute, so that a
/// thread started by a background thread does not go lower still). A
/// refusal leaves it at the daemon's priority, which is only slower for
/// identification under load; `what` names the thread in the debug line.
pub(crate) fn set_thread_niceness(niceness: i32, what: &str) {
    set_niceness_of(rustix::thread::gettid(), niceness, what);
}

/// Give thread `tid` of this process the nice value `niceness`; a refusal
/// is logged (debug) and leaves it where it was.
fn set_niceness_of(tid: rustix::process::Pid, niceness: i32, what: &str) {
    if let Err(e) = rustix::process::setpriority_process(Some(tid), niceness) {
        tracing::debug!("{what} thread keeps its priority: {e}");
    }
}

/// Whether the console is busy, from `busy` (whether it was), `ran` and
/// `waited`, the shares of one core its threads ran and waited to run over
/// the last window: busy once `ran` passes [`CONSOLE_HEAVY_SHARE`], light
/// again once `ran + waited` is below [`CONSOLE_LIGHT_SHARE`].
fn console_is_busy(busy: bool, ran: f64, waited: f64) -> bool {
    if busy {
        ran + waited >= CONSOLE_LIGHT_SHARE
    } else {
        ran > CONSOLE_HEAVY_SHARE
    }
}

/// How long thread `tid` of this process has run and waited on a run queue
/// to run, in nanoseconds (the first two fields of its `schedstat`);
/// `None` when they cannot be read (the thread is gone, or the kernel
/// keeps no such count).
fn thread_times_ns(tid: rustix::process::Pid) -> Option<[u64; 2]> {
    let path = format!("/proc/self/task/{}/schedstat", tid.as_raw_nonzero());
    let text = std::fs::read_to_string(path).ok()?;
    let mut fields = text.split_whitespace().map(str::parse::<u64>);
    Some([fields.next()?.ok()?, fields.next()?.ok()?])
}

/// Whether a thread of this process may be given back a lower nice value
/// than it was given (root, `CAP_SYS_NICE`, or an `RLIMIT_NICE` that
/// allows the daemon's own; systemd's `LimitNICE=`). Tried on a thread of
/// its own, which ends; `base` is the daemon's nice value.
fn niceness_can_return(base: i32) -> bool {
    if base >= 19 {
        return false;
    }
    std::thread::Builder::new()
        .name("morphoid-nice-probe".into())
        .spawn(move || {
            let me = Some(rustix::thread::gettid());
            rustix::process::setpriority_process(me, base + 1).is_ok()
                && rustix::process::setpriority_process(me, base).is_ok()
        })
        .ok()
        .and_then(|probe| probe.join().ok())
        .unwrap_or(false)
}

/// A console thread's id and its times ([`thread_times_ns`]) last read.
type ConsoleThread = (rustix::process::Pid, [u64; 2]);

/// The console's threads: at the daemon's priority while the console is
/// light (a page then waits on no slice of identification's), and
/// [`CONSOLE_NICENESS`] steps below while busy ([`console_is_busy`]:
/// identification keeps its rate). A thread of its own reads their times
/// every [`CONSOLE_TICK`] and ends when the last handle is dropped. Where a
/// thread may not be given back the daemon's priority, or its times cannot
/// be read, they stay below it always.
#[derive(Clone)]
pub(crate) struct ConsolePriority {
    inner: std::sync::Arc<ConsoleThreads>,
}

/// What [`ConsolePriority`] shares with its thread.
struct ConsoleThreads {
    threads: std::sync::Mutex<Vec<ConsoleThread>>,
    busy: std::sync::atomic::AtomicBool,
    /// The daemon's nice value and the busy console's.
    base: i32,
    low: i32,
}

impl ConsoleThreads {
    fn niceness(&self) -> i32 {
        if self.busy.load(std::sync::atomic::Ordering::Relaxed) {
            self.low
        } else {
            self.base
        }
    }

    fn threads(&self) -> std::sync::MutexGuard<'_, Vec<ConsoleThread>> {
        // A poisoned list is still a list of thread ids.
        self.threads.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl ConsolePriority {
    /// The console's priorities, adaptive where this process may give a
    /// thread back its priority and read its times.
    pub(crate) fn start() -> Self {
        let base = rustix::process::getpriority_process(None).unwrap_or(0);
        let adaptive =
            niceness_can_return(base) && thread_times_ns(rustix::thread::gettid()).is_some();
        let inner = std::sync::Arc::new(ConsoleThreads {
            threads: std::sync::Mutex::new(Vec::new()),
            busy: std::sync::atomic::AtomicBool::new(!adaptive),
            base,
            low: steps_below(base, CONSOLE_NICENESS),
        });
        if adaptive {
            let weak = std::sync::Arc::downgrade(&inner);
            let spawned = std::thread::Builder::new()
                .name("morphoid-http-priority".into())
                .spawn(move || govern(&weak));
            if spawned.is_err() {
                // Without its thread the console stays below identification.
                inner.busy.store(true, std::sync::atomic::Ordering::Relaxed);
            }
        } else {
            tracing::debug!("the console's threads stay {CONSOLE_NICENESS} nice steps down");
        }
        ConsolePriority { inner }
    }

    /// Count the calling thread among the console's and give it the
    /// console's priority now.
    pub(crate) fn enter(&self) {
        let tid = rustix::thread::gettid();
        self.inner.threads().push((tid, [0, 0]));
        set_thread_niceness(self.inner.niceness(), "console");
    }

    /// The calling thread is no longer the console's.
    pub(crate) fn leave(&self) {
        let tid = rustix::thread::gettid();
        self.inner.threads().retain(|&(t, _)| t != tid);
    }
}

/// The loop of [`ConsolePriority`]'s thread: the shares of a core the
/// console's threads ran and waited over the last [`CONSOLE_WINDOW`]
/// ticks, and its threads moved when it turns busy or light.
fn govern(weak: &std::sync::Weak<ConsoleThreads>) {
    // Each tick's seconds run, waited and elapsed.
    let mut ticks = std::collections::VecDeque::with_capacity(CONSOLE_WINDOW);
    let mut last = std::time::Instant::now();
    loop {
        std::thread::sleep(CONSOLE_TICK);
        let Some(inner) = weak.upgrade() else {
            return;
        };
        let mut tick = [0.0; 3];
        let mut threads = inner.threads();
        for (tid, seen) in threads.iter_mut() {
            // A thread started since the last tick ran and waited from 0.
            if let Some(now) = thread_times_ns(*tid) {
                for ((t, n), s) in tick.iter_mut().zip(now).zip(*seen) {
                    *t += n.saturating_sub(s) as f64 * 1e-9;
                }
                *seen = now;
            }
        }
        tick[2] = last.elapsed().as_secs_f64();
        last = std::time::Instant::now();
        if ticks.len() == CONSOLE_WINDOW {
            ticks.pop_front();
        }
        ticks.push_back(tick);
        let sum = ticks
            .iter()
            .fold([0.0; 3], |s, t| [s[0] + t[0], s[1] + t[1], s[2] + t[2]]);
        let (ran, waited) = (sum[0] / sum[2].max(1e-9), sum[1] / sum[2].max(1e-9));
        let busy = inner.busy.load(std::sync::atomic::Ordering::Relaxed);
        let now_busy = console_is_busy(busy, ran, waited);
        if now_busy != busy {
            inner
                .busy
                .store(now_busy, std::sync::atomic::Ordering::Relaxed);
            let niceness = inner.niceness();
            for (tid, _) in threads.iter() {
                set_niceness_of(*tid, niceness, "console");
            }
            tracing::debug!(
                ran,
                waited,
                niceness,
                "the console is {}",
                if now_busy { "busy" } else { "light" }
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_console_turns_busy_by_its_run_time_and_light_by_its_run_and_wait_time() {
        // Light: run time alone, however long the threads waited.
        assert!(!console_is_busy(false, 0.09, 0.5));
        assert!(!console_is_busy(false, CONSOLE_HEAVY_SHARE, 0.0));
        assert!(console_is_busy(false, 0.21, 0.0));
        // Busy: run and waiting time together.
        assert!(console_is_busy(true, 0.12, 0.0));
        assert!(console_is_busy(true, 0.03, 0.4));
        assert!(!console_is_busy(true, 0.05, 0.02));
    }

    /// Spins the calling thread for `d`.
    fn spin(d: std::time::Duration) {
        let t = std::time::Instant::now();
        let mut x = 0u64;
        while t.elapsed() < d {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
    }

    #[test]
    fn a_busy_console_thread_goes_down_and_comes_back_when_light() {
        let console = ConsolePriority::start();
        if console
            .inner
            .busy
            .load(std::sync::atomic::Ordering::Relaxed)
        {
            // Not adaptive here (no right to return): nothing moves.
            return;
        }
        let (base, low) = (console.inner.base, console.inner.low);
        let worker = console.clone();
        let seen = std::thread::spawn(move || {
            let me = Some(rustix::thread::gettid());
            let niceness = || rustix::process::getpriority_process(me).unwrap_or(i32::MIN);
            worker.enter();
            let light = niceness();
            spin(std::time::Duration::from_millis(1500));
            let busy = niceness();
            std::thread::sleep(std::time::Duration::from_millis(2500));
            let again = niceness();
            worker.leave();
            (light, busy, again)
        })
        .join()
        .unwrap();
        assert_eq!(seen, (base, low, base));
    }

    #[test]
    fn a_threads_cpu_time_grows_as_it_runs() {
        let tid = rustix::thread::gettid();
        let Some([before, _]) = thread_times_ns(tid) else {
            // A kernel without scheduler statistics: the console stays down.
            return;
        };
        spin(std::time::Duration::from_millis(30));
        let after = thread_times_ns(tid).map_or(0, |t| t[0]);
        assert!(after >= before + 10_000_000, "{before} → {after}");
    }
}
