//! Touching specimens: one object of a mask separated where a thin neck
//! joins two bulky parts (teeth touching at a contact point, or through a
//! bridge of bright mounting material).
//!
//! The object is eroded by growing cubes; at the first radius where the
//! erosion falls into two or more comparable cores, the object is cut
//! there: each of its samples goes to the core it reaches first inside the
//! object (a geodesic Voronoi partition). A neck is thin when the cores
//! appear at a radius of at most [`NECK_RADIUS`]; a wider junction that
//! separates at up to [`FUSED_RADIUS`] is only reported (two specimens
//! fused, identified as one).

use super::segment::connected_components;
use super::shape::erode_cube;
use std::collections::VecDeque;

/// The widest neck cut, as the half-side of the eroding cube (working
/// samples): a neck at most `2 * NECK_RADIUS + 1` samples across. A tooth's
/// own narrowings (cervical constriction, root trunk) are several times
/// wider at any working resolution that resolves the tooth.
pub(crate) const NECK_RADIUS: usize = 3;

/// Up to this radius a split into comparable parts is looked for but not
/// made: the object may be two specimens fused over a wide junction.
pub(crate) const FUSED_RADIUS: usize = 6;

/// A core counts when it holds at least this share of the largest core:
/// cusp tips and root apices that an erosion cuts off are far smaller.
const CORE_SHARE: f64 = 0.25;

/// A fused pair is reported only when the smaller part holds at least
/// this share of the larger.
const FUSED_SHARE: f64 = 0.4;

/// Fewest samples of a core at any radius.
const MIN_CORE: usize = 64;

/// How an object came apart.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Separation {
    /// Cut at a thin neck into these parts (a partition of the object, in
    /// the order of their cores' first samples).
    Cut {
        /// The parts.
        parts: Vec<Vec<bool>>,
        /// The eroding radius at which they separated.
        radius: usize,
    },
    /// No thin neck, but a wider junction separates two comparable parts
    /// at this radius: possibly two specimens fused.
    Fused {
        /// The eroding radius at which they separated.
        radius: usize,
    },
    /// One object.
    Whole,
}

/// Separate the object `mask` (one connected object on a grid of `dims`)
/// at its thin necks (see the module documentation).
pub(crate) fn separate_at_necks(mask: &[bool], dims: [usize; 3]) -> Separation {
    // Within the object's box (outside it the grid is empty anyway): a
    // specimen is a small part of a batch's grid.
    let mut lo = [usize::MAX; 3];
    let mut hi = [0usize; 3];
    for (i, _) in mask.iter().enumerate().filter(|(_, &b)| b) {
        let c = [
            i % dims[0],
            (i / dims[0]) % dims[1],
            i / (dims[0] * dims[1]),
        ];
        for a in 0..3 {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a]);
        }
    }
    if lo[0] == usize::MAX {
        return Separation::Whole;
    }
    let bd = [0, 1, 2].map(|a| hi[a] - lo[a] + 1);
    let full =
        |c: [usize; 3]| (lo[0] + c[0]) + dims[0] * ((lo[1] + c[1]) + dims[1] * (lo[2] + c[2]));
    let cropped: Vec<bool> = (0..bd[0] * bd[1] * bd[2])
        .map(|i| mask[full([i % bd[0], (i / bd[0]) % bd[1], i / (bd[0] * bd[1])])])
        .collect();
    match separate_in_box(&cropped, bd) {
        Separation::Cut { parts, radius } => Separation::Cut {
            parts: parts
                .iter()
                .map(|p| {
                    let mut out = vec![false; mask.len()];
                    for (i, _) in p.iter().enumerate().filter(|(_, &b)| b) {
                        out[full([i % bd[0], (i / bd[0]) % bd[1], i / (bd[0] * bd[1])])] = true;
                    }
                    out
                })
                .collect(),
            radius,
        },
        other => other,
    }
}

/// [`separate_at_necks`] on a grid of `dims` cropped to the object.
fn separate_in_box(mask: &[bool], dims: [usize; 3]) -> Separation {
    let mut eroded = mask.to_vec();
    for radius in 1..=FUSED_RADIUS {
        // Erosion by the cube of half-side r, one sample at a time (cubes
        // add up: r then 1 is r + 1).
        eroded = erode_cube(&eroded, dims, 1);
        let (labels, sizes) = connected_components(&eroded, dims);
        let largest = sizes.iter().copied().max().unwrap_or(0);
        if largest < MIN_CORE {
            return Separation::Whole;
        }
        let keep = |n: usize| n >= MIN_CORE && n as f64 >= CORE_SHARE * largest as f64;
        let cores: Vec<u32> = (0..sizes.len() as u32)
            .filter(|&l| keep(sizes[l as usize]))
            .collect();
        if cores.len() < 2 {
            continue;
        }
        if radius <= NECK_RADIUS {
            return Separation::Cut {
                parts: geodesic_partition(mask, dims, &labels, &cores),
                radius,
            };
        }
        let mut big: Vec<usize> = cores.iter().map(|&l| sizes[l as usize]).collect();
        big.sort_unstable_by(|a, b| b.cmp(a));
        if big[1] as f64 >= FUSED_SHARE * big[0] as f64 {
            return Separation::Fused { radius };
        }
    }
    Separation::Whole
}

/// Each sample of `mask` given to the core (of `labels`, among `cores`)
/// that reaches it first through `mask` (6-connected, breadth first);
/// samples no core reaches go to none.
fn geodesic_partition(
    mask: &[bool],
    dims: [usize; 3],
    labels: &[u32],
    cores: &[u32],
) -> Vec<Vec<bool>> {
    let [nx, ny, nz] = dims;
    let plane = nx * ny;
    let mut owner = vec![u32::MAX; mask.len()];
    let mut queue = VecDeque::new();
    for (i, &l) in labels.iter().enumerate() {
        if let Some(k) = cores.iter().position(|&c| c == l) {
            owner[i] = k as u32;
            queue.push_back(i);
        }
    }
    while let Some(i) = queue.pop_front() {
        let (x, y, z) = (i % nx, (i / nx) % ny, i / plane);
        let mut next = |j: usize| {
            if mask[j] && owner[j] == u32::MAX {
                owner[j] = owner[i];
                queue.push_back(j);
            }
        };
        if x > 0 {
            next(i - 1);
        }
        if x + 1 < nx {
            next(i + 1);
        }
        if y > 0 {
            next(i - nx);
        }
        if y + 1 < ny {
            next(i + nx);
        }
        if z > 0 {
            next(i - plane);
        }
        if z + 1 < nz {
            next(i + plane);
        }
    }
    (0..cores.len() as u32)
        .map(|k| owner.iter().map(|&o| o == k).collect())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two balls of radius `r` on a grid of `n`³, their centres `gap`
    /// apart along x, joined by a square bar `neck` samples wide.
    fn dumbbell(n: usize, r: f64, gap: f64, neck: usize) -> (Vec<bool>, [usize; 3]) {
        let dims = [n, n, n];
        let c = n as f64 / 2.0;
        let (a, b) = (c - gap / 2.0, c + gap / 2.0);
        let mut mask = vec![false; n * n * n];
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let (fx, fy, fz) = (x as f64, y as f64, z as f64);
                    let d =
                        |cx: f64| ((fx - cx).powi(2) + (fy - c).powi(2) + (fz - c).powi(2)).sqrt();
                    let bar = fx >= a
                        && fx <= b
                        && (fy - c).abs() * 2.0 < neck as f64
                        && (fz - c).abs() * 2.0 < neck as f64;
                    mask[x + n * (y + n * z)] = d(a) < r || d(b) < r || bar;
                }
            }
        }
        (mask, dims)
    }

    #[test]
    fn two_balls_touching_through_a_thin_bar_are_cut_apart() {
        let (mask, dims) = dumbbell(48, 9.0, 22.0, 3);
        let Separation::Cut { parts, radius } = separate_at_necks(&mask, dims) else {
            panic!("not cut");
        };
        assert_eq!(parts.len(), 2);
        assert!(radius <= NECK_RADIUS);
        let total = mask.iter().filter(|&&b| b).count();
        let sizes: Vec<usize> = parts
            .iter()
            .map(|p| p.iter().filter(|&&b| b).count())
            .collect();
        // A partition: every sample once, and the halves alike.
        assert_eq!(sizes.iter().sum::<usize>(), total);
        assert!(sizes[0].abs_diff(sizes[1]) * 10 < total, "{sizes:?}");
    }

    #[test]
    fn a_wide_junction_is_reported_not_cut_and_one_ball_stays_whole() {
        let (mask, dims) = dumbbell(64, 14.0, 30.0, 10);
        assert!(
            matches!(separate_at_necks(&mask, dims), Separation::Fused { radius } if radius > NECK_RADIUS),
            "{:?}",
            separate_at_necks(&mask, dims)
        );
        let (ball, dims) = dumbbell(48, 12.0, 0.0, 0);
        assert_eq!(separate_at_necks(&ball, dims), Separation::Whole);
    }
}
