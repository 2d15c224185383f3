//! The screen measured on the 116 real teeth (leave-one-out): how often
//! the exhaustive nearest reference (smallest cP distance) of each
//! held-out tooth is among the references the screen keeps from the other
//! 115, and whether the answers at each rank stay those of the exhaustive
//! search.

use morphoid_core::cp::{
    shape_signature, signature_distance, signature_terms, ScreenParams, Screening,
};
use morphoid_service::identify::{identify, screened_references, DistanceRow};

/// Recall of the exhaustive nearest reference in the best K by signature,
/// for several K; then the product's screen (`[cp] screening = "on"`, the
/// default keep and margin): recall, references kept, and the
/// leave-one-out answers per rank against the exhaustive ones. Set
/// `MORPHOID_CALIBRATION_CACHE` to keep the prepared teeth and their
/// distances between runs.
#[test]
#[ignore = "full 116-tooth measurement (minutes without a warm cache); run by name"]
fn screen_recall_on_the_116_teeth() {
    let Some(real) = crate::support::library::real_library() else {
        return;
    };
    let refs = real.classifier.references();
    let labels = real.library.labels();
    let n = refs.len();
    assert_eq!(n, 116);
    // The signature each reference carries is the one of its prepared form.
    let signatures: Vec<_> = refs.iter().map(|r| r.signature().clone()).collect();
    for r in refs.iter().take(3) {
        assert_eq!(
            &shape_signature(&r.prepared().expect("in the cache")),
            r.signature()
        );
    }
    let d = |i: usize, j: usize| real.table.distance(i, j).expect("a complete table");
    let nearest_of = |i: usize, among: &[usize]| -> usize {
        *among
            .iter()
            .min_by(|&&a, &&b| d(i, a).total_cmp(&d(i, b)))
            .expect("other teeth")
    };
    for term in 0..2 {
        let mut v: Vec<f64> = (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .map(|(i, j)| signature_terms(&signatures[i], &signatures[j])[term])
            .collect();
        v.sort_by(f64::total_cmp);
        eprintln!("median of signature term {term}: {:.6}", v[v.len() / 2]);
    }
    let ks = [8usize, 16, 24, 32, 48];
    let mut found = vec![0usize; ks.len()];
    let mut worst = 0usize;
    let params = ScreenParams {
        screening: Screening::On,
        ..ScreenParams::default()
    };
    let (mut kept_found, mut kept_total) = (0usize, 0usize);
    let mut tally = crate::support::library::AnswerTally::new(labels);
    for i in 0..n {
        let others: Vec<usize> = (0..n).filter(|&j| j != i).collect();
        let nearest = nearest_of(i, &others);
        let mut by_signature = others.clone();
        by_signature.sort_by(|&a, &b| {
            signature_distance(&signatures[i], &signatures[a])
                .total_cmp(&signature_distance(&signatures[i], &signatures[b]))
        });
        let rank = by_signature
            .iter()
            .position(|&j| j == nearest)
            .expect("kept");
        worst = worst.max(rank + 1);
        for (f, &k) in found.iter_mut().zip(&ks) {
            *f += usize::from(rank < k);
        }
        // The product's screen over the other 115.
        let other_signatures: Vec<_> = others.iter().map(|&j| signatures[j].clone()).collect();
        let kept: Vec<usize> = screened_references(&signatures[i], &other_signatures, &params, &[])
            .into_iter()
            .map(|k| others[k])
            .collect();
        kept_total += kept.len();
        kept_found += usize::from(kept.contains(&nearest));
        let rows = |among: &[usize]| -> Vec<DistanceRow> {
            among
                .iter()
                .map(|&j| DistanceRow {
                    reference: refs[j].name().to_string(),
                    forward: d(i, j),
                    backward: d(i, j),
                    distance: d(i, j),
                    reflected: false,
                })
                .collect()
        };
        let exhaustive = identify(&rows(&others), labels, 5);
        let screened = identify(&rows(&kept), labels, 5);
        tally.add(labels, refs[i].name(), &exhaustive, &screened);
    }
    eprintln!("| best K by signature | exhaustive nearest among them |");
    eprintln!("|---|---|");
    for (k, f) in ks.iter().zip(&found) {
        eprintln!("| {k} | {f}/{n} |");
    }
    eprintln!("worst rank of the exhaustive nearest: {worst} of {}", n - 1);
    eprintln!(
        "the screen (keep {}, margin {}): exhaustive nearest kept {kept_found}/{n}, {:.1} references compared on average",
        params.screen_keep,
        params.screen_margin,
        kept_total as f64 / n as f64
    );
    let mut all_alike = true;
    for (rank, same, exhaustive, screened) in tally.per_rank() {
        eprintln!(
            "{rank}: same answer {same}/{n}; right exhaustive {exhaustive}, screened {screened}"
        );
        all_alike &= exhaustive == screened;
    }
    assert!(
        kept_found as f64 >= 0.995 * n as f64,
        "recall {kept_found}/{n}"
    );
    assert!(all_alike, "the screen changed how many answers are right");
}
