//! What the background calibrations of one daemon share. A curator adding
//! references one after another reloads the library each time, and each
//! reload starts a calibration of the new library; the one before is then
//! of no use. It stops at its next pair (it is superseded), and every
//! distance it computed stays in the share for the next, which computes
//! only what no calibration has yet. Without this, calibrations pile up,
//! each computing the same pairs, and identification waits behind them.

use morphoid_data::library::CachedReference;
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// Pair distances kept at most (then forgotten at once): about 200 bytes
/// each.
const MEMO_LIMIT: usize = 1_000_000;

/// A pair of references by name and content, the smaller first.
type PairKey = (String, String);

/// The calibrations of one daemon (cheap to clone: shared).
#[derive(Debug, Clone, Default)]
pub(crate) struct CalibrationShare {
    memo: Arc<Mutex<HashMap<PairKey, f64>>>,
    latest: Arc<AtomicU64>,
}

impl CalibrationShare {
    /// The turn of a calibration that starts now: every earlier turn is
    /// superseded.
    pub(crate) fn next_turn(&self) -> CalibrationTurn {
        let turn = self.latest.fetch_add(1, Ordering::SeqCst) + 1;
        CalibrationTurn {
            share: self.clone(),
            turn,
        }
    }
}

/// One calibration's place in a [`CalibrationShare`].
#[derive(Debug, Clone)]
pub struct CalibrationTurn {
    share: CalibrationShare,
    turn: u64,
}

impl CalibrationTurn {
    /// Whether a later calibration has started.
    pub(crate) fn superseded(&self) -> bool {
        self.share.latest.load(Ordering::SeqCst) != self.turn
    }

    /// The distance of `a` and `b` if a calibration of this share has
    /// computed it (for the same contents).
    pub(crate) fn get(&self, a: &CachedReference, b: &CachedReference) -> Option<f64> {
        let memo = self.share.memo.lock().unwrap_or_else(|p| p.into_inner());
        memo.get(&pair_key(a, b)).copied()
    }

    /// Keep the distance of `a` and `b` for later calibrations.
    pub(crate) fn put(&self, a: &CachedReference, b: &CachedReference, distance: f64) {
        let mut memo = self.share.memo.lock().unwrap_or_else(|p| p.into_inner());
        if memo.len() >= MEMO_LIMIT {
            memo.clear();
        }
        memo.insert(pair_key(a, b), distance);
    }
}

fn pair_key(a: &CachedReference, b: &CachedReference) -> PairKey {
    let one = |r: &CachedReference| format!("{}\0{}", r.name(), r.content_hash());
    let (x, y) = (one(a), one(b));
    if x <= y {
        (x, y)
    } else {
        (y, x)
    }
}
