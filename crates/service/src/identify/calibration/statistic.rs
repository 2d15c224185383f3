//! The numbers behind calibrated confidence: the two terms of the novelty
//! score of one scan at one rank and the weight that combines them, the
//! logistic map from that score to the probability that the nearest taxon
//! is right, and the quantile that sets the "no close match" threshold.
//! Pure functions over plain numbers.

use serde::{Deserialize, Serialize};

/// `ln(nearest / median)`: the distance to the nearest reference relative
/// to the scan's median distance to the library, so that the scale of the
/// scan's own distances (a worn or noisy scan is far from everything)
/// drops out. `None` when either is not positive and finite.
pub(super) fn relative_distance(nearest: f64, median: f64) -> Option<f64> {
    let ok = |x: f64| x.is_finite() && x > 0.0;
    (ok(nearest) && ok(median)).then(|| (nearest / median).ln())
}

/// The scan's mean rank among the members of one taxon: for each member
/// `t`, the number of other members nearer to `t` than the scan is
/// (`scan[t]`; `among[t][u]` between members `t` and `u`), averaged over
/// the members. A member of the taxon ranks among its mates; a scan from
/// outside ranks behind them. `None` without members or when the shapes
/// differ.
pub(super) fn mean_within_taxon_rank(scan: &[f64], among: &[Vec<f64>]) -> Option<f64> {
    if scan.is_empty() || among.len() != scan.len() || among.iter().any(|r| r.len() != scan.len()) {
        return None;
    }
    let nearer: usize = among
        .iter()
        .zip(scan)
        .enumerate()
        .map(|(t, (row, &s))| {
            row.iter()
                .enumerate()
                .filter(|&(u, &v)| u != t && v < s)
                .count()
        })
        .sum();
    Some(nearer as f64 / scan.len() as f64)
}

/// `ln(1 + rank)` of a [`mean_within_taxon_rank`]: the second term of the
/// novelty score, on the same logarithmic footing as the first.
pub(super) fn rank_term(rank: f64) -> f64 {
    rank.max(0.0).ln_1p()
}

/// How far a scan is from the library at one rank:
/// `relative_distance(nearest, median) + weight · rank_term(rank)`, where
/// `nearest` is the distance to the nearest reference known at the rank,
/// `median` the scan's median distance to the library and `rank` its
/// [`mean_within_taxon_rank`] among the members of that reference's
/// taxon. A scan of a taxon the library holds sits well inside the bulk
/// of its distances and among its taxon's members; a scan of a taxon it
/// does not hold does neither. `None` when a distance is not positive and
/// finite.
pub(crate) fn novelty_score(nearest: f64, median: f64, rank: f64, weight: f64) -> Option<f64> {
    Some(relative_distance(nearest, median)? + weight * rank_term(rank))
}

/// Ridge penalty on the slopes of [`logistic_regression`]: keeps the fit
/// finite when the outcomes are separable.
const RIDGE: f64 = 1e-2;

/// Logistic regression of `targets` (in [0, 1]) on `features` (one row of
/// equal length per case) by maximum likelihood with a small ridge on the
/// slopes (Newton's method): the intercept followed by one slope per
/// feature. `None` when there is no case, the lengths differ, or the fit
/// is not finite.
fn logistic_regression(features: &[Vec<f64>], targets: &[f64]) -> Option<Vec<f64>> {
    let k = features.first()?.len() + 1;
    if features.len() != targets.len() || features.iter().any(|x| x.len() + 1 != k) {
        return None;
    }
    let mut w = vec![0.0f64; k];
    for _ in 0..100 {
        // Gradient and Hessian of the penalized negative log-likelihood,
        // as one augmented system [H | g].
        let mut m = vec![vec![0.0f64; k + 1]; k];
        for (x, &y) in features.iter().zip(targets) {
            let z: Vec<f64> = std::iter::once(1.0).chain(x.iter().copied()).collect();
            let p = logistic(w.iter().zip(&z).map(|(a, b)| a * b).sum());
            let q = p * (1.0 - p);
            for (row, &za) in m.iter_mut().zip(&z) {
                row[k] += (p - y) * za;
                for (h, &zb) in row.iter_mut().zip(&z) {
                    *h += q * za * zb;
                }
            }
        }
        for (a, row) in m.iter_mut().enumerate().skip(1) {
            row[k] += RIDGE * w[a];
            row[a] += RIDGE;
        }
        let step = solve(m)?;
        for (wa, da) in w.iter_mut().zip(&step) {
            *wa -= da;
        }
        if step.iter().all(|d| d.abs() < 1e-10) {
            break;
        }
    }
    w.iter().all(|x| x.is_finite()).then_some(w)
}

/// `1 / (1 + exp(-z))`.
fn logistic(z: f64) -> f64 {
    1.0 / (1.0 + (-z).exp())
}

/// The solution of the augmented system `[A | b]` (Gaussian elimination
/// with partial pivoting); `None` when `A` is singular.
fn solve(mut m: Vec<Vec<f64>>) -> Option<Vec<f64>> {
    let k = m.len();
    for c in 0..k {
        let pivot = (c..k).max_by(|&a, &b| m[a][c].abs().total_cmp(&m[b][c].abs()))?;
        m.swap(c, pivot);
        let p = m[c][c];
        if !(p.is_finite() && p.abs() > 1e-300) {
            return None;
        }
        let pivot_row = m[c].clone();
        for (r, row) in m.iter_mut().enumerate() {
            if r != c {
                let f = row[c] / p;
                for (x, &v) in row.iter_mut().zip(&pivot_row).skip(c) {
                    *x -= f * v;
                }
            }
        }
    }
    Some((0..k).map(|a| m[a][k] / m[a][a]).collect())
}

/// Largest weight of the rank term that [`fit_rank_weight`] tries.
const MAX_RANK_WEIGHT: f64 = 2.0;

/// Step of [`fit_rank_weight`]'s search.
const RANK_WEIGHT_STEP: f64 = 0.025;

/// The weight of the rank term in [`novelty_score`] learnt from the
/// library: held-out references scored with their taxon still in the
/// library (`present`) and with it removed (`absent`), each as its two
/// terms `[relative_distance, rank_term]`; the weight (searched from 0 to
/// [`MAX_RANK_WEIGHT`]) whose scores flag the largest share of `absent`
/// when at most a share `rate` of `present` is flagged
/// ([`share_caught_at`]), ties going to the larger ROC AUC and then to the
/// smaller weight. Fitted for the point where the flag works (a fixed
/// share of false flags) rather than for the likelihood of the whole
/// curve: on the 116 PNAS teeth the likelihood's weight caught fewer
/// absent genera at 5 % false flags. `None` when either set is empty or
/// no weight separates at all (AUC ≤ ½).
pub(super) fn fit_rank_weight(present: &[[f64; 2]], absent: &[[f64; 2]], rate: f64) -> Option<f64> {
    if present.is_empty() || absent.is_empty() {
        return None;
    }
    let steps = (MAX_RANK_WEIGHT / RANK_WEIGHT_STEP).round() as usize;
    let mut best: Option<(f64, f64, f64)> = None;
    for k in 0..=steps {
        let w = k as f64 * RANK_WEIGHT_STEP;
        let score = |x: &[f64; 2]| x[0] + w * x[1];
        let p: Vec<f64> = present.iter().map(score).collect();
        let a: Vec<f64> = absent.iter().map(score).collect();
        let caught = share_caught_at(&a, &p, rate)?;
        let auc = roc_auc(&a, &p)?;
        if best.is_none_or(|(c, u, _)| caught > c || (caught == c && auc > u)) {
            best = Some((caught, auc, w));
        }
    }
    best.filter(|&(_, auc, _)| auc > 0.5).map(|(_, _, w)| w)
}

/// The split-conformal quantile of `values` at miscoverage `alpha`: the
/// ⌈(n + 1)(1 − alpha)⌉-th smallest of the n values (the largest when
/// that exceeds n). A new value drawn like them lies above it with
/// probability at most `alpha` — unlike the plain (1 − alpha)-quantile,
/// which a new value exceeds more often than `alpha` when n is small.
/// `None` when there is no finite value.
pub(super) fn conformal_quantile(values: &[f64], alpha: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let k = (((n + 1) as f64 * (1.0 - alpha.clamp(0.0, 1.0))).ceil() as usize).clamp(1, n);
    Some(v[k - 1])
}

/// `P(right) = 1 / (1 + exp(-(intercept + slope · score)))`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Logistic {
    /// Log-odds at score 0.
    pub intercept: f64,
    /// Change of the log-odds per unit of score.
    pub slope: f64,
}

impl Logistic {
    /// The probability at `score`.
    pub fn probability(&self, score: f64) -> f64 {
        logistic(self.intercept + self.slope * score)
    }
}

/// The logistic regression of `outcomes` (right or wrong) on `scores`
/// ([`logistic_regression`] with one feature). The outcomes enter as
/// Platt's targets, (right + 1)/(right + 2) and 1/(wrong + 2) instead of 1
/// and 0, so that a library where every held-out reference was right
/// gives a probability below 1 that grows with its size. `None` when there
/// is no pair or the lengths differ.
pub(crate) fn fit_logistic(scores: &[f64], outcomes: &[bool]) -> Option<Logistic> {
    if scores.len() != outcomes.len() {
        return None;
    }
    let right = outcomes.iter().filter(|&&y| y).count() as f64;
    let wrong = outcomes.len() as f64 - right;
    let target_right = (right + 1.0) / (right + 2.0);
    let target_wrong = 1.0 / (wrong + 2.0);
    let features: Vec<Vec<f64>> = scores.iter().map(|&s| vec![s]).collect();
    let targets: Vec<f64> = outcomes
        .iter()
        .map(|&y| if y { target_right } else { target_wrong })
        .collect();
    let w = logistic_regression(&features, &targets)?;
    Some(Logistic {
        intercept: w[0],
        slope: w[1],
    })
}

/// Expected calibration error of `probabilities` against `outcomes` over
/// `bins` equal-width bins of the probability: the mean, weighted by bin
/// size, of |mean probability − share right|. `None` when empty.
pub fn expected_calibration_error(
    probabilities: &[f64],
    outcomes: &[bool],
    bins: usize,
) -> Option<f64> {
    reliability(probabilities, outcomes, bins).map(|rows| {
        let n: usize = rows.iter().map(|r| r.count).sum();
        rows.iter()
            .map(|r| r.count as f64 * (r.mean_probability - r.share_right).abs())
            .sum::<f64>()
            / n as f64
    })
}

/// One bin of a reliability table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ReliabilityBin {
    /// Lower edge of the bin (probability).
    pub from: f64,
    /// Upper edge.
    pub to: f64,
    /// How many predictions fell in it.
    pub count: usize,
    /// Their mean probability.
    pub mean_probability: f64,
    /// The share of them that were right.
    pub share_right: f64,
}

/// The reliability table of `probabilities` against `outcomes`: the
/// non-empty ones of `bins` equal-width bins (the last includes 1).
/// `None` when empty or the lengths differ.
pub fn reliability(
    probabilities: &[f64],
    outcomes: &[bool],
    bins: usize,
) -> Option<Vec<ReliabilityBin>> {
    if probabilities.is_empty() || probabilities.len() != outcomes.len() || bins == 0 {
        return None;
    }
    let mut sum = vec![(0usize, 0.0f64, 0usize); bins];
    for (&p, &y) in probabilities.iter().zip(outcomes) {
        let k = ((p.clamp(0.0, 1.0) * bins as f64) as usize).min(bins - 1);
        sum[k].0 += 1;
        sum[k].1 += p;
        sum[k].2 += usize::from(y);
    }
    Some(
        sum.iter()
            .enumerate()
            .filter(|(_, s)| s.0 > 0)
            .map(|(k, &(count, p, right))| ReliabilityBin {
                from: k as f64 / bins as f64,
                to: (k + 1) as f64 / bins as f64,
                count,
                mean_probability: p / count as f64,
                share_right: right as f64 / count as f64,
            })
            .collect(),
    )
}

/// Area under the ROC curve of `positive` against `negative` scores (the
/// probability that a positive scores above a negative, ties counting
/// half); `None` when either is empty.
pub fn roc_auc(positive: &[f64], negative: &[f64]) -> Option<f64> {
    if positive.is_empty() || negative.is_empty() {
        return None;
    }
    let mut wins = 0.0;
    for &p in positive {
        for &n in negative {
            wins += match p.total_cmp(&n) {
                std::cmp::Ordering::Greater => 1.0,
                std::cmp::Ordering::Equal => 0.5,
                std::cmp::Ordering::Less => 0.0,
            };
        }
    }
    Some(wins / (positive.len() * negative.len()) as f64)
}

/// The largest share of `positive` scores above a threshold that puts at
/// most a share `rate` of `negative` scores above it (the ROC curve read
/// at a false-positive rate); `None` when either is empty.
pub fn share_caught_at(positive: &[f64], negative: &[f64], rate: f64) -> Option<f64> {
    if positive.is_empty() || negative.is_empty() {
        return None;
    }
    let above = |v: &[f64], t: f64| v.iter().filter(|&&x| x > t).count() as f64 / v.len() as f64;
    positive
        .iter()
        .chain(negative)
        .copied()
        .filter(|&t| above(negative, t) <= rate)
        .map(|t| above(positive, t))
        .fold(None, |best: Option<f64>, s| {
            Some(best.map_or(s, |b| b.max(s)))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conformal_quantile_takes_the_rank_of_the_level() {
        let v: Vec<f64> = (1..=20).map(f64::from).collect();
        // (20 + 1) · 0.95 = 19.95: the 20th of 20; 19 values: the 19th.
        assert_eq!(conformal_quantile(&v, 0.05), Some(20.0));
        assert_eq!(conformal_quantile(&v[..19], 0.05), Some(19.0));
        assert_eq!(conformal_quantile(&v, 0.5), Some(11.0));
        assert_eq!(conformal_quantile(&v, 1.0), Some(1.0));
        assert_eq!(conformal_quantile(&[], 0.5), None);
    }

    #[test]
    fn novelty_grows_with_the_relative_distance_and_the_rank() {
        let s = |d, m, r| novelty_score(d, m, r, 0.25).unwrap();
        assert!((s(0.05, 0.1, 0.0) - 0.5f64.ln()).abs() < 1e-12);
        assert!(s(0.08, 0.1, 0.0) > s(0.05, 0.1, 0.0));
        assert!(s(0.05, 0.1, 2.5) > s(0.05, 0.1, 0.0));
        assert!((s(0.05, 0.1, 3.0) - s(0.05, 0.1, 0.0) - 0.25 * 4f64.ln()).abs() < 1e-12);
        // Scaling every distance of a scan leaves the score alone.
        assert!((s(0.5, 1.0, 3.0) - s(0.05, 0.1, 3.0)).abs() < 1e-12);
        assert_eq!(novelty_score(0.0, 0.1, 0.0, 0.1), None);
        assert_eq!(novelty_score(0.1, f64::NAN, 0.0, 0.1), None);
        assert_eq!(relative_distance(0.1, 0.1), Some(0.0));
        assert_eq!(rank_term(-1.0), 0.0);
    }

    #[test]
    fn the_rank_among_a_taxon_counts_mates_nearer_than_the_scan() {
        // Three members on a line at 0, 1 and 3.
        let among = vec![
            vec![0.0, 1.0, 3.0],
            vec![1.0, 0.0, 2.0],
            vec![3.0, 2.0, 0.0],
        ];
        // A scan at 1.2 is 1.2, 0.2 and 1.8 away: member 0 has one mate
        // nearer (1 at 1.0 < 1.2), member 1 none, member 2 none (2.0 ≥ 1.8).
        assert_eq!(
            mean_within_taxon_rank(&[1.2, 0.2, 1.8], &among),
            Some(1.0 / 3.0)
        );
        // A scan at 10 is behind every mate of every member.
        assert_eq!(mean_within_taxon_rank(&[10.0, 9.0, 7.0], &among), Some(2.0));
        // A lone member has no mates to rank behind.
        assert_eq!(mean_within_taxon_rank(&[5.0], &[vec![0.0]]), Some(0.0));
        assert_eq!(mean_within_taxon_rank(&[], &[]), None);
        assert_eq!(mean_within_taxon_rank(&[1.0, 2.0], &among), None);
    }

    /// When only the rank term tells absent from present, the weight is
    /// the one that separates them; when it points the wrong way, it is 0.
    #[test]
    fn the_rank_weight_follows_what_separates_absent_from_present() {
        let present: Vec<[f64; 2]> = (0..40)
            .map(|i| [-1.0 + 0.02 * i as f64, 0.1 * (i % 3) as f64])
            .collect();
        // Absent: the same distances, one step further behind in rank.
        let absent: Vec<[f64; 2]> = present.iter().map(|x| [x[0] + 0.1, x[1] + 1.0]).collect();
        let w = fit_rank_weight(&present, &absent, 0.05).unwrap();
        // Scores `d + w·r` separate fully from w ≈ 0.85 on; at 5 % false
        // flags all absent are caught a little before.
        assert!((0.5..=0.9).contains(&w), "{w}");
        let score = |x: &[f64; 2]| x[0] + w * x[1];
        let (p, a): (Vec<f64>, Vec<f64>) = (
            present.iter().map(score).collect(),
            absent.iter().map(score).collect(),
        );
        assert_eq!(share_caught_at(&a, &p, 0.05), Some(1.0));
        let backwards: Vec<[f64; 2]> = present.iter().map(|x| [x[0] + 0.3, x[1] - 0.5]).collect();
        assert_eq!(fit_rank_weight(&present, &backwards, 0.05), Some(0.0));
        assert_eq!(fit_rank_weight(&present, &[], 0.05), None);
        // The distance term pointing the wrong way gives no weight at all.
        let nearer: Vec<[f64; 2]> = present.iter().map(|x| [x[0] - 0.5, x[1]]).collect();
        assert_eq!(fit_rank_weight(&present, &nearer, 0.05), None);
    }

    /// Outcomes drawn from a known logistic law are fitted back to it.
    #[test]
    fn logistic_fit_recovers_a_known_law() {
        let truth = Logistic {
            intercept: -1.0,
            slope: -4.0,
        };
        let mut scores = Vec::new();
        let mut outcomes = Vec::new();
        // A deterministic stand-in for sampling: at each score, the share
        // of right outcomes among 200 follows the law.
        for k in 0..41 {
            let s = -2.0 + k as f64 * 0.075;
            let right = (truth.probability(s) * 200.0).round() as usize;
            for i in 0..200 {
                scores.push(s);
                outcomes.push(i < right);
            }
        }
        let fit = fit_logistic(&scores, &outcomes).unwrap();
        assert!((fit.intercept - truth.intercept).abs() < 0.05, "{fit:?}");
        assert!((fit.slope - truth.slope).abs() < 0.1, "{fit:?}");
        // And the probabilities of the fit are calibrated on those data.
        let p: Vec<f64> = scores.iter().map(|&s| fit.probability(s)).collect();
        assert!(expected_calibration_error(&p, &outcomes, 10).unwrap() < 0.01);
    }

    #[test]
    fn logistic_fit_stays_below_one_when_all_are_right() {
        let fit = fit_logistic(&[-1.0, -0.5, 0.0], &[true, true, true]).unwrap();
        // Platt's target for three right of three: 4/5.
        assert!((fit.probability(-0.5) - 0.8).abs() < 1e-6, "{fit:?}");
        let many = fit_logistic(&[-0.5; 98], &[true; 98]).unwrap();
        assert!((many.probability(-0.5) - 0.99).abs() < 1e-6, "{many:?}");
        assert_eq!(fit_logistic(&[], &[]), None);
        assert_eq!(fit_logistic(&[1.0], &[]), None);
    }

    #[test]
    fn reliability_bins_and_calibration_error() {
        let p = [0.05, 0.95, 0.95, 0.55, 0.45];
        let y = [false, true, false, true, false];
        let t = reliability(&p, &y, 10).unwrap();
        assert_eq!(t.len(), 4);
        let top = t.last().unwrap();
        assert_eq!((top.count, top.share_right), (2, 0.5));
        assert!((top.mean_probability - 0.95).abs() < 1e-12);
        // |0.05-0|·1 + |0.45-0|·1 + |0.55-1|·1 + |0.95-0.5|·2, over 5.
        let e = expected_calibration_error(&p, &y, 10).unwrap();
        assert!((e - (0.05 + 0.45 + 0.45 + 0.9) / 5.0).abs() < 1e-12, "{e}");
    }

    #[test]
    fn auc_and_share_caught() {
        assert_eq!(roc_auc(&[3.0, 4.0], &[1.0, 2.0]), Some(1.0));
        assert_eq!(roc_auc(&[1.0], &[1.0]), Some(0.5));
        assert_eq!(roc_auc(&[1.0, 4.0], &[2.0, 3.0]), Some(0.5));
        let neg: Vec<f64> = (0..20).map(f64::from).collect();
        // One negative (19) may lie above the threshold at 5 %.
        let pos = [18.5, 18.7, 30.0, 40.0];
        assert_eq!(share_caught_at(&pos, &neg, 0.05), Some(1.0));
        assert_eq!(share_caught_at(&pos, &neg, 0.0), Some(0.5));
        assert_eq!(roc_auc(&[], &neg), None);
    }
}
