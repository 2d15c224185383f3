//! Helpers shared by the store tests.

use morphoid_service::identify::{DistanceRow, RankResult, ScanOutcome};
use morphoid_service::store::{Labels, Store};
use std::collections::BTreeMap;

/// Ranks used by the tests, broadest first.
pub(crate) const RANKS: [&str; 3] = ["order", "family", "genus"];

/// Name of reference `i`.
pub(crate) fn reference_name(i: usize) -> String {
    format!("ref{i:03}")
}

/// Register `n` references with labels and mark them prepared.
pub(crate) fn register_references(store: &mut Store, n: usize) {
    for i in 0..n {
        let mut labels = Labels::new();
        labels.insert("order".into(), Some("Primates".into()));
        labels.insert("family".into(), Some(format!("F{}", i % 3)));
        labels.insert(
            "genus".into(),
            if i % 5 == 4 {
                None
            } else {
                Some(format!("G{}", i % 7))
            },
        );
        let name = reference_name(i);
        store
            .register_reference(&name, &format!("hash-of-{name}"), &labels)
            .expect("register reference");
        store.mark_reference_prepared(&name).expect("mark prepared");
    }
}

/// A full outcome against `n_refs` references, derived from `seed` so that
/// every scan's numbers differ and can be checked.
pub(crate) fn outcome(seed: u64, n_refs: usize) -> ScanOutcome {
    let distances: Vec<DistanceRow> = (0..n_refs)
        .map(|i| {
            let forward = 0.01 + ((seed as usize * 31 + i * 17) % 97) as f64 / 1000.0;
            let backward = forward + 0.001 * (i % 3) as f64;
            DistanceRow {
                reference: reference_name(i),
                forward,
                backward,
                distance: forward.min(backward),
                reflected: (i + seed as usize).is_multiple_of(2),
            }
        })
        .collect();
    let nearest = distances
        .iter()
        .min_by(|a, b| a.distance.total_cmp(&b.distance))
        .map(|d| (d.reference.clone(), d.distance))
        .unwrap_or_default();
    let ranks = RANKS
        .iter()
        .map(|rank| RankResult {
            rank: rank.to_string(),
            taxon: format!("{rank}-taxon-{seed}"),
            reference: nearest.0.clone(),
            distance: nearest.1,
            runner_up: Some(format!("{rank}-other")),
            margin: Some(0.005),
            confidence: None,
        })
        .collect();
    let mut timings_ms = BTreeMap::new();
    timings_ms.insert("load".to_string(), 12.5);
    timings_ms.insert("compare".to_string(), 900.0 + seed as f64);
    ScanOutcome {
        ranks,
        distances,
        cleaning: serde_json::json!({"vertices_before": 5100 + seed, "vertices_after": 5000}),
        timings_ms,
        landmarks: None,
        calibrating: false,
    }
}
