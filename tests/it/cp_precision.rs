//! What storing the prepared forms in `f32` would cost in precision,
//! measured on the 116 real teeth: every floating-point value of every
//! prepared form is rounded to `f32` (through the form's serialized
//! fields, as a compact cache entry would hold it), the whole matrix is
//! computed again from the rounded forms, and its distances and
//! leave-one-out answers are compared with the exact ones. Also reports
//! how much of a cache entry's bytes the `f64` values are.

use morphoid_core::cp::{compare, Prepared};
use morphoid_service::identify::{identify, DistanceRow};
use rayon::prelude::*;
use serde_json::Value;

/// Every float of `value` rounded to `f32`; returns how many.
fn round_floats_to_f32(value: &mut Value) -> usize {
    match value {
        Value::Number(n) if n.is_f64() => {
            let x = n.as_f64().unwrap_or(0.0);
            if let Some(r) = serde_json::Number::from_f64(x as f32 as f64) {
                *n = r;
            }
            1
        }
        Value::Array(items) => items.iter_mut().map(round_floats_to_f32).sum(),
        Value::Object(map) => map.values_mut().map(round_floats_to_f32).sum(),
        _ => 0,
    }
}

#[test]
#[ignore = "full 116-tooth matrix from f32-rounded forms (minutes); run by name"]
fn f32_forms_of_the_real_teeth() {
    let Some(real) = crate::support::library::real_library() else {
        return;
    };
    let refs = real.classifier.references();
    let labels = real.library.labels();
    let n = refs.len();
    let params = real.settings.cp.compare.clone();
    let exact: Vec<std::sync::Arc<Prepared>> = refs
        .iter()
        .map(|r| r.prepared().expect("in the cache"))
        .collect();
    let (mut floats, mut bytes) = (0usize, 0usize);
    let rounded: Vec<Prepared> = exact
        .iter()
        .map(|p| {
            bytes += postcard::to_allocvec(&**p).expect("encodes").len();
            let mut value = serde_json::to_value(&**p).expect("to JSON");
            floats += round_floats_to_f32(&mut value);
            let r: Prepared = serde_json::from_value(value).expect("back from JSON");
            r.validate().expect("a consistent form");
            r
        })
        .collect();
    eprintln!(
        "prepared forms: {bytes} bytes encoded, {floats} f64 values ({:.0} % of the bytes; \
         in f32 the entries would be {:.0} % of their size)",
        100.0 * (8 * floats) as f64 / bytes as f64,
        100.0 * (bytes - 4 * floats) as f64 / bytes as f64
    );
    let pairs: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .collect();
    let d32: Vec<f64> = pairs
        .par_iter()
        .map(|&(i, j)| compare(&rounded[i], &rounded[j], &params).distance)
        .collect();
    let d64 = |i: usize, j: usize| real.table.distance(i, j).expect("a complete table");
    let mut relative: Vec<f64> = pairs
        .iter()
        .zip(&d32)
        .map(|(&(i, j), &d)| (d - d64(i, j)).abs() / d64(i, j).max(1e-12))
        .collect();
    let changed = relative.iter().filter(|&&r| r > 0.0).count();
    relative.sort_by(f64::total_cmp);
    eprintln!(
        "{} pairs: {changed} distances differ; relative difference median {:.2e}, 99th percentile {:.2e}, max {:.2e}",
        pairs.len(),
        relative[relative.len() / 2],
        relative[relative.len() * 99 / 100],
        relative[relative.len() - 1]
    );
    let mut matrix = vec![vec![0.0; n]; n];
    for (&(i, j), &d) in pairs.iter().zip(&d32) {
        matrix[i][j] = d;
        matrix[j][i] = d;
    }
    let mut tally = crate::support::library::AnswerTally::new(labels);
    let mut same_nearest = 0usize;
    for i in 0..n {
        let others: Vec<usize> = (0..n).filter(|&j| j != i).collect();
        let rows = |d: &dyn Fn(usize) -> f64| -> Vec<DistanceRow> {
            others
                .iter()
                .map(|&j| DistanceRow {
                    reference: refs[j].name().to_string(),
                    forward: d(j),
                    backward: d(j),
                    distance: d(j),
                    reflected: false,
                })
                .collect()
        };
        let nearest = |d: &dyn Fn(usize) -> f64| {
            others
                .iter()
                .copied()
                .min_by(|&a, &b| d(a).total_cmp(&d(b)))
        };
        let f64_of = |j: usize| d64(i, j);
        let f32_of = |j: usize| matrix[i][j];
        same_nearest += usize::from(nearest(&f64_of) == nearest(&f32_of));
        let a64 = identify(&rows(&f64_of), labels, 5);
        let a32 = identify(&rows(&f32_of), labels, 5);
        tally.add(labels, refs[i].name(), &a64, &a32);
    }
    eprintln!("nearest reference the same: {same_nearest}/{n}");
    let mut all_same = true;
    for (rank, same, right64, right32) in tally.per_rank() {
        eprintln!("{rank}: same answer {same}/{n}; right with f64 {right64}, with f32 {right32}");
        all_same &= same == n;
    }
    // What docs/design.md says of f32 forms: every answer the same, no
    // distance off by 1 %.
    assert_eq!(same_nearest, n);
    assert!(all_same, "answers changed");
    assert!(relative[relative.len() - 1] < 0.01);
}
