//! When a file in the export folder counts as complete: its size and
//! modification time have stayed the same for the settle time. Pure
//! bookkeeping over observations; the caller supplies the clock.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime};

/// What a directory listing says about one file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Stamp {
    /// Size in bytes.
    pub size: u64,
    /// Modification time.
    pub mtime: Option<SystemTime>,
}

#[derive(Debug, Clone)]
struct Entry {
    stamp: Stamp,
    stable_since: Instant,
    taken: bool,
}

/// Tracks every file seen in the last listing.
#[derive(Debug, Clone, Default)]
pub(super) struct Settler {
    entries: HashMap<PathBuf, Entry>,
}

impl Settler {
    /// An empty tracker.
    pub(super) fn new() -> Self {
        Self::default()
    }

    /// Record that `path` has `stamp` at `now`. Returns true exactly once
    /// per content: when the stamp has been unchanged for `settle`. A
    /// changed stamp starts the wait again (and the file can be taken
    /// again, as changed content).
    pub(super) fn observe(
        &mut self,
        path: &Path,
        stamp: Stamp,
        now: Instant,
        settle: Duration,
    ) -> bool {
        let entry = self
            .entries
            .entry(path.to_path_buf())
            .or_insert_with(|| Entry {
                stamp,
                stable_since: now,
                taken: false,
            });
        if entry.stamp != stamp {
            *entry = Entry {
                stamp,
                stable_since: now,
                taken: false,
            };
        }
        if !entry.taken && now.saturating_duration_since(entry.stable_since) >= settle {
            entry.taken = true;
            return true;
        }
        false
    }

    /// Take `path` now whatever its age (a trigger says the scanner is
    /// done). Returns false when it was already taken with this stamp.
    pub(super) fn force(&mut self, path: &Path, stamp: Stamp, now: Instant) -> bool {
        self.observe(path, stamp, now, Duration::ZERO)
    }

    /// Forget files that are no longer listed (deleted or renamed: a
    /// renamed file is a new name, observed afresh).
    pub(super) fn retain_listed(&mut self, listed: &std::collections::HashSet<PathBuf>) {
        self.entries.retain(|p, _| listed.contains(p));
    }

    /// Whether some listed file is still waiting to settle (the folder is
    /// then listed often; otherwise less often).
    pub(super) fn waiting(&self) -> bool {
        self.entries.values().any(|e| !e.taken)
    }

    /// The files still waiting to settle: they are looked at again on a
    /// short tick, because a file that stops changing sends no more events.
    pub(super) fn waiting_paths(&self) -> Vec<PathBuf> {
        let mut v: Vec<PathBuf> = self
            .entries
            .iter()
            .filter(|(_, e)| !e.taken)
            .map(|(p, _)| p.clone())
            .collect();
        v.sort();
        v
    }

    /// Forget `path` (deleted or renamed away): if a file appears under
    /// that name again it is observed afresh.
    pub(super) fn forget(&mut self, path: &Path) {
        self.entries.remove(path);
    }

    /// Look at `path` again as if it had just changed: taken once it has
    /// stayed the same for another settle time (its format says it is not
    /// complete yet, so it is checked again, not read on every tick).
    pub(super) fn defer(&mut self, path: &Path, now: Instant) {
        if let Some(e) = self.entries.get_mut(path) {
            e.taken = false;
            e.stable_since = now;
        }
    }

    /// Allow `path` to be taken again at its next settled observation
    /// (after a transient failure to read it).
    pub(super) fn release(&mut self, path: &Path) {
        if let Some(e) = self.entries.get_mut(path) {
            e.taken = false;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stamp(size: u64) -> Stamp {
        Stamp { size, mtime: None }
    }

    #[test]
    fn a_growing_file_is_taken_once_after_it_stops_changing() {
        let mut s = Settler::new();
        let t0 = Instant::now();
        let settle = Duration::from_secs(2);
        let p = Path::new("a.ply");
        let at = |secs: u64| t0 + Duration::from_secs(secs);
        assert!(!s.waiting());
        assert!(!s.observe(p, stamp(10), at(0), settle));
        assert!(s.waiting());
        assert!(!s.observe(p, stamp(20), at(1), settle));
        assert!(!s.observe(p, stamp(30), at(2), settle));
        assert!(!s.observe(p, stamp(30), at(3), settle));
        assert!(s.observe(p, stamp(30), at(4), settle));
        assert!(!s.waiting());
        assert!(!s.observe(p, stamp(30), at(9), settle));
        // Changed again: a new content, taken again once settled.
        assert!(!s.observe(p, stamp(40), at(10), settle));
        assert!(s.observe(p, stamp(40), at(12), settle));
        assert!(!s.force(p, stamp(40), at(13)));
        assert!(s.force(Path::new("b.ply"), stamp(1), at(13)));
        assert!(!s.observe(Path::new("c.ply"), stamp(1), at(13), settle));
        assert_eq!(s.waiting_paths(), vec![PathBuf::from("c.ply")]);
        s.forget(Path::new("c.ply"));
        assert!(!s.waiting());
    }
}
