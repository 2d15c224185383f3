//! The cervical margin as a closed height line around the tooth axis: the
//! path through an (angle sector × height bin) image of crease strength
//! that collects the most crease once around the axis, with a bounded
//! climb between neighbouring sectors (dynamic programming over the
//! sectors, closed by returning to the starting height).

use std::f64::consts::{PI, TAU};

/// A crease sample: an edge's angle about the axis, its height and its
/// weight (turn × length × how much it runs around the axis).
#[derive(Debug, Clone, Copy)]
pub(super) struct CreaseSample {
    pub angle: f64,
    pub height: f64,
    pub weight: f64,
}

/// The band searched and its discretisation.
#[derive(Debug, Clone, Copy)]
pub(super) struct Band {
    /// Lowest height searched.
    pub low: f64,
    /// Highest height searched.
    pub high: f64,
    /// Number of angle sectors.
    pub sectors: usize,
    /// Number of height bins.
    pub bins: usize,
    /// Largest climb between neighbouring sectors, in bins.
    pub max_step: usize,
}

/// A closed height line: one height per sector (at the sector's centre
/// angle), linear in between.
#[derive(Debug, Clone)]
pub(super) struct MarginLine {
    heights: Vec<f64>,
    /// Crease strength collected along the line.
    pub score: f64,
}

impl MarginLine {
    /// The line's height at `angle` (radians, any range).
    pub fn height_at(&self, angle: f64) -> f64 {
        let s = self.heights.len();
        let x = (angle + PI).rem_euclid(TAU) / TAU * s as f64 - 0.5;
        let i = x.floor();
        let t = x - i;
        let a = (i as i64).rem_euclid(s as i64) as usize;
        let b = (a + 1) % s;
        self.heights[a] * (1.0 - t) + self.heights[b] * t
    }
}

fn sector_of(angle: f64, sectors: usize) -> usize {
    let x = (angle + PI).rem_euclid(TAU) / TAU * sectors as f64;
    (x as usize).min(sectors - 1)
}

/// The crease image, blurred by one bin in height (a crease that falls on
/// a bin border counts in both).
fn crease_image(samples: &[CreaseSample], band: &Band) -> Vec<Vec<f64>> {
    let (s, b) = (band.sectors, band.bins);
    let bin = (band.high - band.low) / b as f64;
    let mut image = vec![vec![0.0; b]; s];
    for c in samples {
        if !(c.height >= band.low && c.height < band.high && c.weight > 0.0) {
            continue;
        }
        let k = (((c.height - band.low) / bin) as usize).min(b - 1);
        image[sector_of(c.angle, s)][k] += c.weight;
    }
    for row in &mut image {
        let raw = row.clone();
        for k in 0..b {
            let below = if k > 0 { raw[k - 1] } else { 0.0 };
            let above = if k + 1 < b { raw[k + 1] } else { 0.0 };
            row[k] = 0.5 * raw[k] + 0.25 * (below + above);
        }
    }
    image
}

/// Best closed path from height bin `start` in sector `first`: returns the
/// total and, with `trace`, the bin of every sector (in sector order).
fn closed_path(
    image: &[Vec<f64>],
    first: usize,
    start: usize,
    max_step: usize,
    penalty: f64,
    trace: bool,
) -> (f64, Vec<usize>) {
    let (s, b) = (image.len(), image[0].len());
    let mut value = vec![f64::NEG_INFINITY; b];
    value[start] = image[first][start];
    let mut back: Vec<Vec<u32>> = Vec::new();
    let mut next = vec![f64::NEG_INFINITY; b];
    for step in 1..s {
        let row = &image[(first + step) % s];
        let mut from = vec![0u32; if trace { b } else { 0 }];
        for k in 0..b {
            let lo = k.saturating_sub(max_step);
            let hi = (k + max_step).min(b - 1);
            let mut best = f64::NEG_INFINITY;
            let mut arg = k;
            for (j, &v) in value.iter().enumerate().take(hi + 1).skip(lo) {
                let c = v - penalty * k.abs_diff(j) as f64;
                if c > best {
                    best = c;
                    arg = j;
                }
            }
            next[k] = best + row[k];
            if trace {
                from[k] = arg as u32;
            }
        }
        std::mem::swap(&mut value, &mut next);
        if trace {
            back.push(from);
        }
    }
    // Close the loop: back to the starting bin.
    let lo = start.saturating_sub(max_step);
    let hi = (start + max_step).min(b - 1);
    let (mut total, mut end) = (f64::NEG_INFINITY, start);
    for (j, &v) in value.iter().enumerate().take(hi + 1).skip(lo) {
        let c = v - penalty * start.abs_diff(j) as f64;
        if c > total {
            total = c;
            end = j;
        }
    }
    if !trace {
        return (total, Vec::new());
    }
    let mut bins = vec![0usize; s];
    let mut k = end;
    for step in (1..s).rev() {
        bins[(first + step) % s] = k;
        k = back[step - 1][k] as usize;
    }
    bins[first] = k;
    (total, bins)
}

/// The closed line of strongest crease around the axis in `band`, or
/// `None` when the band holds no crease at all.
pub(super) fn trace_margin(samples: &[CreaseSample], band: &Band) -> Option<MarginLine> {
    if band.sectors < 3 || band.bins < 3 || !(band.high > band.low) {
        return None;
    }
    let image = crease_image(samples, band);
    let peaks: Vec<f64> = image
        .iter()
        .map(|r| r.iter().copied().fold(0.0, f64::max))
        .collect();
    // Start in the sector with the sharpest peak, from its strongest bins.
    let first = (0..peaks.len()).max_by(|&a, &b| peaks[a].total_cmp(&peaks[b]))?;
    if !(peaks[first] > 0.0) {
        return None;
    }
    let mut sorted = peaks.clone();
    sorted.sort_by(f64::total_cmp);
    // A full climb costs 0.2 of a typical sector's peak: smooth lines are
    // preferred, steep ones stay possible.
    let penalty = 0.2 * sorted[sorted.len() / 2] / band.max_step.max(1) as f64;
    let mut starts: Vec<usize> = (0..band.bins).collect();
    starts.sort_by(|&a, &b| image[first][b].total_cmp(&image[first][a]));
    starts.truncate(8);
    let best = starts
        .iter()
        .map(|&k| {
            (
                closed_path(&image, first, k, band.max_step, penalty, false).0,
                k,
            )
        })
        .max_by(|a, b| a.0.total_cmp(&b.0))?;
    let (score, bins) = closed_path(&image, first, best.1, band.max_step, penalty, true);
    let bin = (band.high - band.low) / band.bins as f64;
    Some(MarginLine {
        heights: bins
            .iter()
            .map(|&k| band.low + (k as f64 + 0.5) * bin)
            .collect(),
        score,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tilted_crease_ring_is_followed() {
        // A crease line at height 0.5 + 0.2 sin(angle), plus scattered
        // weaker ridges.
        let mut samples = Vec::new();
        for i in 0..720 {
            let a = -PI + TAU * i as f64 / 720.0;
            samples.push(CreaseSample {
                angle: a,
                height: 0.5 + 0.2 * a.sin(),
                weight: 1.0,
            });
            samples.push(CreaseSample {
                angle: a,
                height: 0.05 + 0.9 * ((i * 37) % 100) as f64 / 100.0,
                weight: 0.3,
            });
        }
        let band = Band {
            low: 0.0,
            high: 1.0,
            sectors: 64,
            bins: 100,
            max_step: 4,
        };
        let line = trace_margin(&samples, &band).unwrap();
        for i in 0..64 {
            let a = -PI + TAU * (i as f64 + 0.5) / 64.0;
            let h = line.height_at(a);
            assert!((h - (0.5 + 0.2 * a.sin())).abs() < 0.03, "{a}: {h}");
        }
    }
}
