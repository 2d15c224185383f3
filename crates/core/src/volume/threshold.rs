//! Automatic thresholds: Otsu's method on a histogram, applied twice to
//! tell two materials (air, tooth) from three (air, dentine, enamel), and
//! its multi-level form ([`multi_otsu`]) that proposes the candidate levels
//! between air, mounting material, dentine and enamel.

/// A histogram of values over `[lo, hi]` in equal bins.
#[derive(Debug, Clone)]
pub(crate) struct Histogram {
    lo: f64,
    width: f64,
    counts: Vec<u64>,
}

impl Histogram {
    /// The histogram of `values` in `bins` bins between their extremes.
    pub(crate) fn of(values: &[f32], bins: usize) -> Histogram {
        let (lo, hi) = values.iter().fold((f64::MAX, f64::MIN), |(a, b), &v| {
            (a.min(f64::from(v)), b.max(f64::from(v)))
        });
        let (lo, hi) = if lo <= hi { (lo, hi) } else { (0.0, 0.0) };
        let width = ((hi - lo) / bins as f64).max(f64::MIN_POSITIVE);
        let mut counts = vec![0u64; bins.max(1)];
        for &v in values {
            let b = ((f64::from(v) - lo) / width) as usize;
            counts[b.min(bins - 1)] += 1;
        }
        Histogram { lo, width, counts }
    }

    /// The value at the upper edge of bin `b`.
    pub(crate) fn edge(&self, b: usize) -> f64 {
        self.lo + (b + 1) as f64 * self.width
    }

    /// The number of bins.
    #[cfg(test)]
    fn bins(&self) -> usize {
        self.counts.len()
    }

    /// The mean value of the samples in bins `range` (the bin centres
    /// weighted by their counts); `None` when they hold no sample.
    pub(crate) fn mean(&self, range: std::ops::Range<usize>) -> Option<f64> {
        let (mut n, mut s) = (0.0, 0.0);
        for (i, &c) in self.counts.get(range.clone())?.iter().enumerate() {
            n += c as f64;
            s += c as f64 * (self.lo + (range.start + i) as f64 * self.width + 0.5 * self.width);
        }
        (n > 0.0).then(|| s / n)
    }

    /// Whether all values were equal (no threshold separates anything).
    pub(crate) fn is_flat(&self) -> bool {
        self.counts.iter().filter(|&&c| c > 0).count() < 2
    }
}

/// Otsu's threshold within bins `range` of `hist`: the last bin of the
/// lower class and the effectiveness σ²_between / σ²_total (1 for two
/// separate spikes, 2/π for one normal distribution). `None` when the
/// range holds fewer than two distinct bins.
pub(crate) fn otsu(hist: &Histogram, range: std::ops::Range<usize>) -> Option<(usize, f64)> {
    let counts = hist.counts.get(range.clone())?;
    let total: f64 = counts.iter().map(|&c| c as f64).sum();
    if total <= 0.0 || counts.iter().filter(|&&c| c > 0).count() < 2 {
        return None;
    }
    let sum: f64 = counts
        .iter()
        .enumerate()
        .map(|(i, &c)| i as f64 * c as f64)
        .sum();
    let mean = sum / total;
    let var: f64 = counts
        .iter()
        .enumerate()
        .map(|(i, &c)| c as f64 * (i as f64 - mean).powi(2))
        .sum::<f64>()
        / total;
    let (mut w0, mut s0) = (0.0, 0.0);
    let mut best = (0usize, -1.0f64);
    for (i, &c) in counts.iter().enumerate().take(counts.len() - 1) {
        w0 += c as f64;
        s0 += i as f64 * c as f64;
        let w1 = total - w0;
        if w0 <= 0.0 || w1 <= 0.0 {
            continue;
        }
        let m0 = s0 / w0;
        let m1 = (sum - s0) / w1;
        let between = w0 * w1 * (m0 - m1).powi(2) / (total * total);
        if between > best.1 {
            best = (i, between);
        }
    }
    (best.1 >= 0.0).then(|| (range.start + best.0, best.1 / var.max(f64::MIN_POSITIVE)))
}

/// Otsu's method for `classes` classes: the `classes - 1` bins that end
/// each class but the last, in increasing order, maximising the variance
/// between the classes (dynamic programming over the bins, exact). Fewer
/// distinct bins than classes give repeated thresholds.
pub(crate) fn multi_otsu(hist: &Histogram, classes: usize) -> Vec<usize> {
    let l = hist.counts.len();
    let k = classes.clamp(2, l.max(2));
    // Prefix sums: P[j], S[j] over bins 0..j.
    let mut p = vec![0.0f64; l + 1];
    let mut s = vec![0.0f64; l + 1];
    for (i, &c) in hist.counts.iter().enumerate() {
        p[i + 1] = p[i] + c as f64;
        s[i + 1] = s[i] + i as f64 * c as f64;
    }
    // Σ over classes of (sum²/count) is the between-class variance up to
    // constants; a class of bins a..b contributes that of its samples.
    let gain = |a: usize, b: usize| {
        let n = p[b] - p[a];
        if n > 0.0 {
            (s[b] - s[a]).powi(2) / n
        } else {
            0.0
        }
    };
    // best[c][j]: the best split of bins 0..j into c + 1 classes; from[c][j]
    // where its last class starts.
    let mut best = vec![vec![f64::MIN; l + 1]; k];
    let mut from = vec![vec![0usize; l + 1]; k];
    for (j, b) in best[0].iter_mut().enumerate().skip(1) {
        *b = gain(0, j);
    }
    for c in 1..k {
        for j in (c + 1)..=l {
            for i in c..j {
                let v = best[c - 1][i] + gain(i, j);
                if v > best[c][j] {
                    best[c][j] = v;
                    from[c][j] = i;
                }
            }
        }
    }
    let mut cuts = Vec::with_capacity(k - 1);
    let mut j = l;
    for c in (1..k).rev() {
        let i = from[c][j].max(1);
        cuts.push(i - 1);
        j = i;
    }
    cuts.reverse();
    cuts
}

/// The thresholds of a scan: the specimen is above `foreground`; enamel,
/// where the scan shows it, above `enamel`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Thresholds {
    /// Between background and specimen.
    pub foreground: f64,
    /// Between dentine and the brighter enamel, when there are three materials.
    pub enamel: Option<f64>,
}

/// Effectiveness above which a part of the histogram counts as two
/// materials rather than one blurred, noisy one (2/π ≈ 0.64 for a
/// normal distribution).
const TWO_MATERIALS: f64 = 0.8;

/// The threshold between background and specimen: Otsu's threshold, or,
/// when the part below it is itself clearly two materials (enamel so
/// bright that Otsu split it from dentine and air), Otsu's threshold
/// there. `None` when all values are equal.
pub(crate) fn foreground_threshold(values: &[f32]) -> Option<f64> {
    const BINS: usize = 256;
    let hist = Histogram::of(values, BINS);
    if hist.is_flat() {
        return None;
    }
    let (t, _) = otsu(&hist, 0..BINS)?;
    Some(
        match otsu(&hist, 0..t + 1).filter(|&(_, e)| e > TWO_MATERIALS) {
            Some((l, _)) => hist.edge(l),
            None => hist.edge(t),
        },
    )
}

/// The threshold between dentine and enamel among the `interior` values of
/// the specimen (away from its surface, so that the blur between air and
/// tooth does not count as a material), when they are clearly two
/// materials.
pub(crate) fn enamel_threshold(interior: &[f32]) -> Option<f64> {
    const BINS: usize = 256;
    let hist = Histogram::of(interior, BINS);
    otsu(&hist, 0..BINS)
        .filter(|&(_, e)| e > TWO_MATERIALS)
        .map(|(t, _)| hist.edge(t))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn noisy(levels: &[(f32, usize)], sigma: f32) -> Vec<f32> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut v = Vec::new();
        for &(level, n) in levels {
            for _ in 0..n {
                let g: f32 = (0..12).map(|_| rng.gen::<f32>()).sum::<f32>() - 6.0;
                v.push(level + sigma * g);
            }
        }
        v
    }

    #[test]
    fn two_and_three_materials_are_told_apart() {
        let two = foreground_threshold(&noisy(&[(0.1, 8000), (0.5, 2000)], 0.03)).unwrap();
        assert!(two > 0.15 && two < 0.4, "{two}");
        let three = foreground_threshold(&noisy(&[(0.1, 8000), (0.5, 2000), (0.85, 600)], 0.03));
        let three = three.unwrap();
        assert!(three > 0.15 && three < 0.4, "{three}");
        assert_eq!(foreground_threshold(&[1.0; 50]), None);
        assert_eq!(enamel_threshold(&noisy(&[(0.5, 2000)], 0.03)), None);
        let e = enamel_threshold(&noisy(&[(0.5, 2000), (0.85, 600)], 0.03)).unwrap();
        assert!(e > 0.55 && e < 0.75, "{e}");
    }

    #[test]
    fn multi_otsu_separates_four_materials() {
        // Air, foam, dentine, enamel, in unequal amounts.
        let v = noisy(
            &[(0.05, 20000), (0.2, 15000), (0.5, 4000), (0.8, 1500)],
            0.02,
        );
        let hist = Histogram::of(&v, 256);
        let cuts: Vec<f64> = multi_otsu(&hist, 4).iter().map(|&b| hist.edge(b)).collect();
        assert_eq!(cuts.len(), 3);
        for (t, (lo, hi)) in cuts.iter().zip([(0.08, 0.17), (0.25, 0.45), (0.55, 0.75)]) {
            assert!(*t > lo && *t < hi, "{cuts:?}");
        }
        // Two classes: the same threshold as the two-class search.
        let (t2, _) = otsu(&hist, 0..256).unwrap();
        assert_eq!(multi_otsu(&hist, 2), vec![t2]);
        let m = hist.mean(0..hist.bins()).unwrap();
        let exact = v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64;
        assert!((m - exact).abs() < 0.01, "{m} vs {exact}");
    }
}
