//! Where a whole tooth's neck is, from its outline alone: the crown's
//! outline is widest at its height of contour and curves in below it; the
//! margin is where that convex bulge ends and the neck's concave bend
//! begins. No crease is needed, so a smooth junction (an isosurface
//! export, a worn or smoothed tooth) has a margin too; on a sharp enamel
//! edge the bulge ends at the edge.
//!
//! Measured round an axis in polar sectors: each sector's outline is the
//! largest distance from the axis of the surface at each height, smoothed
//! along the axis; the margin's height in a sector is the first height
//! below the height of contour where the outline bends outward.

use super::geometry::Cylinder;

/// Polar sectors round the axis.
const SECTORS: usize = 48;

/// Height bins along the tooth's length.
const BINS: usize = 120;

/// Gaussian smoothing of each sector's outline along the axis, in bins
/// (2.5 % of the tooth's length: the voxel staircase and the crown's small
/// grooves are below it, the neck's bend above it).
const OUTLINE_SIGMA: f64 = 3.0;

/// The height of contour is searched above this share of the length (the
/// crown's end of the tooth): spreading roots can be wider than the crown
/// lower down.
const CONTOUR_FROM: f64 = 0.4;

/// The lowest a margin is looked for, as a share of the length from the
/// root end: the smoothing bends every outline outward at its very ends.
const LOWEST_MARGIN: f64 = 0.15;

/// The smallest outward bend (second difference of the outline per bin²,
/// as a share of the widest outline) that counts as the neck's.
const MIN_BEND: f64 = 2e-4;

/// The smallest share of the sectors with a neck for the tooth to have
/// one.
const MIN_SECTORS_WITH_NECK: f64 = 0.5;

/// The margin's height in each polar sector, as a fraction of the tooth's
/// length along the axis (0 at the root end, 1 at the crown's top).
#[derive(Debug, Clone)]
pub(super) struct NeckHeights {
    heights: Vec<f64>,
    /// How much wider the outline is at the height of contour than at the
    /// margin (median over the sectors with a neck).
    pub bulge: f64,
}

impl NeckHeights {
    /// The margin's height at the polar angle `theta` (interpolated
    /// between sector centres).
    pub(super) fn at(&self, theta: f64) -> f64 {
        let n = self.heights.len();
        let x = (theta + std::f64::consts::PI) / (2.0 * std::f64::consts::PI) * n as f64 - 0.5;
        let i = x.floor();
        let t = x - i;
        let a = (i as isize).rem_euclid(n as isize) as usize;
        let b = (a + 1) % n;
        self.heights[a] * (1.0 - t) + self.heights[b] * t
    }
}

/// Each sector's outline: the largest distance from the axis of `points`
/// in each height bin (`NaN` where a bin holds none), with the heights'
/// range.
fn sector_outlines(points: &[[f64; 3]], cyl: &Cylinder) -> (Vec<Vec<f64>>, f64, f64) {
    let heights: Vec<f64> = points.iter().map(|&p| cyl.height(p)).collect();
    let zmin = heights.iter().copied().fold(f64::MAX, f64::min);
    let zmax = heights.iter().copied().fold(f64::MIN, f64::max);
    let length = (zmax - zmin).max(f64::MIN_POSITIVE);
    let mut outline = vec![vec![f64::NAN; BINS]; SECTORS];
    for (p, z) in points.iter().zip(&heights) {
        let (theta, r) = cyl.polar(*p);
        let s = (((theta + std::f64::consts::PI) / (2.0 * std::f64::consts::PI)) * SECTORS as f64)
            as usize;
        let b = (((z - zmin) / length) * BINS as f64) as usize;
        let cell = &mut outline[s.min(SECTORS - 1)][b.min(BINS - 1)];
        if !(r <= *cell) {
            *cell = r;
        }
    }
    (outline, zmin, zmax)
}

/// `values` with its `NaN`s filled by linear interpolation (the ends by
/// the nearest value), smoothed by a Gaussian of `sigma` samples; `None`
/// when all are `NaN`.
fn filled_and_smoothed(values: &[f64], sigma: f64) -> Option<Vec<f64>> {
    let known: Vec<usize> = (0..values.len())
        .filter(|&i| values[i].is_finite())
        .collect();
    let (&first, &last) = (known.first()?, known.last()?);
    let mut filled = values.to_vec();
    for i in 0..values.len() {
        if i <= first {
            filled[i] = values[first];
        } else if i >= last {
            filled[i] = values[last];
        } else if !values[i].is_finite() {
            let k = known.partition_point(|&j| j < i);
            let (a, b) = (known[k - 1], known[k]);
            let t = (i - a) as f64 / (b - a) as f64;
            filled[i] = values[a] * (1.0 - t) + values[b] * t;
        }
    }
    let radius = (3.0 * sigma).ceil() as isize;
    let weights: Vec<f64> = (-radius..=radius)
        .map(|k| (-((k * k) as f64) / (2.0 * sigma * sigma)).exp())
        .collect();
    let n = filled.len() as isize;
    Some(
        (0..n)
            .map(|i| {
                let (mut s, mut w) = (0.0, 0.0);
                for (k, &wk) in (-radius..=radius).zip(&weights) {
                    let j = (i + k).clamp(0, n - 1);
                    s += wk * filled[j as usize];
                    w += wk;
                }
                s / w
            })
            .collect(),
    )
}

/// The margin's height (fraction of the length) on one smoothed sector
/// outline, and how much wider the outline is at the height of contour
/// than there: below the height of contour (the widest point above
/// [`CONTOUR_FROM`]), the neck is the first outward bend of at least
/// `min_bend`, and the margin the top of that bend, where the crown's
/// convex outline turns into it (the zero of the bend above it).
/// `None` when the outline never bends outward there (a sphere, an
/// ellipsoid, a cylinder).
fn margin_on_outline(outline: &[f64], min_bend: f64) -> Option<(f64, f64)> {
    let n = outline.len();
    let from = (CONTOUR_FROM * n as f64) as usize;
    let contour = (from..n - 1).max_by(|&a, &b| outline[a].total_cmp(&outline[b]))?;
    let bend = |b: usize| outline[b + 1] - 2.0 * outline[b] + outline[b - 1];
    let lowest = ((LOWEST_MARGIN * n as f64) as usize).max(2);
    let top = contour.min(n - 2);
    // The first outward bend below the height of contour, then up from
    // it to where the bend turns negative.
    let mut b = (lowest + 1..=top).rev().find(|&b| bend(b) > min_bend)?;
    while b < top && bend(b + 1) > 0.0 {
        b += 1;
    }
    let (inside, above) = (bend(b), if b < top { bend(b + 1) } else { 0.0 });
    let t = if inside - above > 0.0 {
        inside / (inside - above)
    } else {
        0.0
    };
    let bulge = outline[contour] / outline[b].max(f64::MIN_POSITIVE);
    Some(((b as f64 + 0.5 + t) / n as f64, bulge))
}

/// The margin's height in each polar sector round `cyl` (the crown at the
/// axis' positive end), from the outline of `points` (the surface's
/// vertices). `None` when fewer than [`MIN_SECTORS_WITH_NECK`] of the
/// sectors show a neck.
pub(super) fn neck_heights(points: &[[f64; 3]], cyl: &Cylinder) -> Option<NeckHeights> {
    let (outlines, _, _) = sector_outlines(points, cyl);
    let widest = outlines
        .iter()
        .flatten()
        .copied()
        .filter(|r| r.is_finite())
        .fold(0.0, f64::max);
    if !(widest > 0.0) {
        return None;
    }
    let found: Vec<Option<(f64, f64)>> = outlines
        .iter()
        .map(|o| {
            let smooth = filled_and_smoothed(o, OUTLINE_SIGMA)?;
            margin_on_outline(&smooth, MIN_BEND * widest)
        })
        .collect();
    let mut bulges: Vec<f64> = found.iter().flatten().map(|f| f.1).collect();
    let found: Vec<Option<f64>> = found.iter().map(|f| f.map(|f| f.0)).collect();
    let count = bulges.len();
    tracing::debug!(sectors = count, axis = ?cyl.axis(), "neck sectors");
    if (count as f64) < MIN_SECTORS_WITH_NECK * SECTORS as f64 {
        return None;
    }
    // A sector's height is the median of it and its neighbours (one
    // sector's groove or cusp ridge does not move the margin), sectors
    // without a neck taking their neighbours'.
    let heights: Vec<f64> =
        (0..SECTORS)
            .map(|s| {
                let mut near: Vec<f64> = (-2isize..=2)
                    .filter_map(|d| found[(s as isize + d).rem_euclid(SECTORS as isize) as usize])
                    .collect();
                let mut k = 3isize;
                while near.is_empty() {
                    near.extend([-k, k].iter().filter_map(|d| {
                        found[(s as isize + d).rem_euclid(SECTORS as isize) as usize]
                    }));
                    k += 1;
                }
                near.sort_by(f64::total_cmp);
                near[near.len() / 2]
            })
            .collect();
    bulges.sort_by(f64::total_cmp);
    Some(NeckHeights {
        heights,
        bulge: bulges[bulges.len() / 2],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A profile: a bulge (the crown) above a neck that bends outward at
    /// bin 60, then a straight taper.
    fn crown_and_root(n: usize) -> Vec<f64> {
        (0..n)
            .map(|b| {
                let t = b as f64 / n as f64;
                if t >= 0.5 {
                    // Crown: a half-ellipse bulge from 0.5 to 1.
                    let u = (t - 0.75) / 0.25;
                    0.6 + 0.4 * (1.0 - u * u).max(0.0).sqrt()
                } else {
                    // Neck and root: narrower, tapering to the apex.
                    0.6 * (t / 0.5).sqrt()
                }
            })
            .collect()
    }

    #[test]
    fn the_margin_is_where_the_bulge_ends() {
        let o = filled_and_smoothed(&crown_and_root(BINS), OUTLINE_SIGMA).unwrap();
        let (m, bulge) = margin_on_outline(&o, MIN_BEND).unwrap();
        assert!((m - 0.5).abs() < 0.04, "{m}");
        assert!(bulge > 1.3, "{bulge}");
    }

    #[test]
    fn a_convex_outline_has_no_neck() {
        // A sphere's outline: a half circle.
        let o: Vec<f64> = (0..BINS)
            .map(|b| {
                let u = 2.0 * (b as f64 + 0.5) / BINS as f64 - 1.0;
                (1.0 - u * u).sqrt()
            })
            .collect();
        let o = filled_and_smoothed(&o, OUTLINE_SIGMA).unwrap();
        assert_eq!(margin_on_outline(&o, MIN_BEND), None);
        // A cylinder's: constant.
        assert_eq!(margin_on_outline(&vec![1.0; BINS], MIN_BEND), None);
    }

    #[test]
    fn gaps_are_filled() {
        let v = [f64::NAN, 1.0, f64::NAN, 3.0, f64::NAN];
        let f = filled_and_smoothed(&v, 0.1).unwrap();
        assert!(
            (f[0] - 1.0).abs() < 1e-9 && (f[2] - 2.0).abs() < 1e-9 && (f[4] - 3.0).abs() < 1e-9
        );
        assert!(filled_and_smoothed(&[f64::NAN; 3], 1.0).is_none());
    }
}
