//! Screening: which references of a large library a scan is compared with
//! by the cP distance. The references are ranked by the distance between
//! screening signatures ([`shape_signature`](morphoid_core::cp::shape_signature)),
//! cheap and computed once per reference; the best few and those within a
//! margin of them are kept. Pure: signatures in, indices out.

use morphoid_core::cp::{signature_distance, ScreenParams, Signature};

/// The indices (ascending) of the references a scan with signature `scan`
/// is compared with: every reference when `params` do not screen a
/// library of this size; else the [`ScreenParams::screen_keep`] nearest by
/// signature distance (ties to the lower index), every other within
/// [`ScreenParams::screen_margin`] of the last of those, and the indices
/// of `always` (those a calibration reads whatever the screen says).
pub fn screened_references(
    scan: &Signature,
    references: &[impl std::borrow::Borrow<Signature>],
    params: &ScreenParams,
    always: &[usize],
) -> Vec<usize> {
    let n = references.len();
    if !params.screens(n) || n <= params.screen_keep {
        return (0..n).collect();
    }
    let mut by_likeness: Vec<(f64, usize)> = references
        .iter()
        .enumerate()
        .map(|(i, r)| (signature_distance(scan, r.borrow()), i))
        .collect();
    by_likeness.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let last_kept = by_likeness[params.screen_keep - 1].0;
    let bound = last_kept * (1.0 + params.screen_margin);
    let mut keep: Vec<usize> = by_likeness
        .iter()
        .enumerate()
        .take_while(|&(k, &(d, _))| k < params.screen_keep || d <= bound)
        .map(|(_, &(_, i))| i)
        .chain(always.iter().copied().filter(|&i| i < n))
        .collect();
    keep.sort_unstable();
    keep.dedup();
    keep
}

#[cfg(test)]
mod tests {
    use super::*;
    use morphoid_core::cp::Screening;

    /// Signatures along one line: reference i lies at `xs[i]`. Built
    /// through serde, since a signature's fields are the core's business.
    fn signatures(xs: &[f32]) -> Vec<Signature> {
        xs.iter()
            .map(|&x| {
                serde_json::from_value(serde_json::json!({
                    "radial": [0.0], "spread": [x, 0.0, 0.0]
                }))
                .unwrap()
            })
            .collect()
    }

    fn params(screening: Screening, keep: usize, margin: f64) -> ScreenParams {
        ScreenParams {
            screening,
            screen_keep: keep,
            screen_margin: margin,
            screen_from: 4,
        }
    }

    #[test]
    fn the_nearest_by_signature_and_those_within_the_margin_are_kept() {
        let refs = signatures(&[5.0, 1.0, 1.05, 9.0, 1.1, 3.0, 0.5]);
        let scan = &signatures(&[1.0])[0];
        // Nearest two: 1 (0) and 2 (0.05); 4 (0.1) is within 150 % of 0.05.
        let kept = screened_references(scan, &refs, &params(Screening::On, 2, 1.5), &[]);
        assert_eq!(kept, vec![1, 2, 4]);
        let kept = screened_references(scan, &refs, &params(Screening::On, 2, 0.0), &[3]);
        assert_eq!(kept, vec![1, 2, 3], "the always-compared join in order");
    }

    #[test]
    fn small_libraries_and_screening_off_compare_every_reference() {
        let refs = signatures(&[5.0, 1.0, 1.05, 9.0, 1.1]);
        let scan = &signatures(&[1.0])[0];
        let all: Vec<usize> = (0..5).collect();
        let off = params(Screening::Off, 1, 0.0);
        assert_eq!(screened_references(scan, &refs, &off, &[]), all);
        let auto = params(Screening::Auto, 1, 0.0);
        assert_eq!(screened_references(scan, &refs, &auto, &[]), vec![1]);
        let auto_small = ScreenParams {
            screen_from: 5,
            ..auto
        };
        assert_eq!(screened_references(scan, &refs, &auto_small, &[]), all);
    }
}
