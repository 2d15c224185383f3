//! What is wrong with the storage right now, for the log and the STATUS
//! line: each part (the database, the results folder) is either fine or
//! faulty with a message. Entering and leaving a fault are logged once
//! each, however often the failing operation is retried; retries wait
//! with [`Backoff`].

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// The first wait after a failure.
const BACKOFF_FIRST: Duration = Duration::from_millis(250);
/// The longest wait between retries: work resumes at most this long after
/// a fault clears.
pub const BACKOFF_MAX: Duration = Duration::from_secs(8);

/// A part of the storage that can fail on its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Part {
    /// The SQLite database (queue and results).
    Database,
    /// The results folder.
    Results,
}

impl Part {
    fn name(self) -> &'static str {
        match self {
            Part::Database => "database",
            Part::Results => "results folder",
        }
    }
}

#[derive(Debug)]
struct Fault {
    message: String,
    since: Instant,
    /// The latest failure: the fault clears only after [`CLEAR_AFTER`]
    /// without one.
    last: Instant,
}

/// How long a faulty part must work without failing before it counts as
/// available again: a disk that is nearly full lets one write through
/// after a checkpoint frees the log and then fails again; that is one
/// fault, not several.
const CLEAR_AFTER: Duration = Duration::from_secs(3);

/// The faults of the storage, shared by the control loop and the worker.
#[derive(Debug, Clone, Default)]
pub(super) struct Health {
    faults: Arc<Mutex<BTreeMap<Part, Fault>>>,
}

impl Health {
    fn faults(&self) -> MutexGuard<'_, BTreeMap<Part, Fault>> {
        // A panic elsewhere cannot leave the map inconsistent.
        self.faults.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// `part` failed with `message`: logged (ERROR) when it was fine until
    /// now; a further failure while faulty is not logged again.
    pub(super) fn fault(&self, part: Part, message: &str) {
        match self.faults().entry(part) {
            std::collections::btree_map::Entry::Vacant(slot) => {
                tracing::error!(
                    "{} unavailable: {message}; work is kept and retried until it recovers",
                    part.name()
                );
                slot.insert(Fault {
                    message: message.to_string(),
                    since: Instant::now(),
                    last: Instant::now(),
                });
            }
            std::collections::btree_map::Entry::Occupied(mut f) => {
                f.get_mut().last = Instant::now()
            }
        }
    }

    /// `part` worked: logged (INFO) when it was faulty until now (the
    /// database: and has not failed for [`CLEAR_AFTER`]; until then it stays
    /// faulty, and the worker's next look, at most 5 s on, clears it).
    pub(super) fn clear(&self, part: Part) {
        let quiet = match part {
            Part::Database => CLEAR_AFTER,
            // Cleared only by a write that works, which may be the last.
            Part::Results => Duration::ZERO,
        };
        self.clear_after(part, quiet);
    }

    fn clear_after(&self, part: Part, quiet: Duration) {
        let mut faults = self.faults();
        if faults.get(&part).is_some_and(|f| f.last.elapsed() < quiet) {
            return;
        }
        if let Some(f) = faults.remove(&part) {
            tracing::info!(
                "{} available again after {:.0} s",
                part.name(),
                f.since.elapsed().as_secs_f64()
            );
        }
    }

    /// "degraded: database: disk full" for the STATUS line, `None` when all
    /// is well.
    pub(super) fn summary(&self) -> Option<String> {
        let faults = self.faults();
        (!faults.is_empty()).then(|| {
            let parts: Vec<String> = faults
                .iter()
                .map(|(p, f)| format!("{}: {}", p.name(), f.message))
                .collect();
            format!("degraded: {}", parts.join("; "))
        })
    }
}

/// When to try a failing operation again: waits double from
/// [`BACKOFF_FIRST`] up to [`BACKOFF_MAX`], and start over after a success.
#[derive(Debug, Clone, Default)]
pub(super) struct Backoff {
    delay: Option<Duration>,
    next: Option<Instant>,
}

impl Backoff {
    /// Whether the operation may be tried now.
    pub(super) fn ready(&self) -> bool {
        self.next.is_none_or(|t| Instant::now() >= t)
    }

    /// How long until it may be tried (zero when ready).
    pub(super) fn remaining(&self) -> Duration {
        self.next.map_or(Duration::ZERO, |t| {
            t.saturating_duration_since(Instant::now())
        })
    }

    /// Whether the last attempt failed.
    pub(super) fn failing(&self) -> bool {
        self.delay.is_some()
    }

    /// The attempt failed: wait longer before the next.
    pub(super) fn failed(&mut self) {
        let delay = self
            .delay
            .map_or(BACKOFF_FIRST, |d| (d * 2).min(BACKOFF_MAX));
        self.delay = Some(delay);
        self.next = Some(Instant::now() + delay);
    }

    /// The attempt succeeded.
    pub(super) fn succeeded(&mut self) {
        self.delay = None;
        self.next = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn waits_double_up_to_the_limit_and_reset_on_success() {
        let mut b = Backoff::default();
        assert!(b.ready() && !b.failing());
        let mut last = Duration::ZERO;
        for _ in 0..10 {
            b.failed();
            let d = b.delay.unwrap();
            assert!(d >= last && d <= BACKOFF_MAX);
            last = d;
        }
        assert_eq!(last, BACKOFF_MAX);
        assert!(!b.ready() && b.remaining() > Duration::ZERO);
        b.succeeded();
        assert!(b.ready() && !b.failing());
    }

    #[test]
    fn a_fault_is_reported_until_it_clears() {
        let h = Health::default();
        assert_eq!(h.summary(), None);
        h.fault(Part::Database, "disk full");
        h.fault(Part::Database, "still full");
        assert_eq!(h.summary().unwrap(), "degraded: database: disk full");
        // Working right after a failure does not clear it yet.
        h.clear(Part::Database);
        assert!(h.summary().is_some());
        h.clear_after(Part::Database, Duration::ZERO);
        assert_eq!(h.summary(), None);
    }
}
