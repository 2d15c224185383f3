//! The distance-matrix heatmap of the paper's Figure 1: one matrix in the
//! upper right triangle, another in the lower left, specimens ordered so
//! that near ones sit together, each matrix coloured over its own range
//! with a perceptual colour map. Pure functions from matrices to an RGB
//! image; [`RgbImage::to_png`] turns the image into PNG bytes, the caller writes
//! them.

use super::mantel::{align_to, check_distance_matrix, MantelError};
use super::tree::average_linkage_merges;
use morphoid_data::present::{png_bytes, Channels};
use morphoid_data::table::DistanceMatrix;

/// An 8-bit RGB raster, row-major, top row first.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 · width · height` bytes: R, G, B of each pixel.
    pub pixels: Vec<u8>,
}

impl RgbImage {
    /// The colour at column `x`, row `y` (`None` outside the image).
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let k = 3 * (y as usize * self.width as usize + x as usize);
        let p = self.pixels.get(k..k + 3)?;
        Some([p[0], p[1], p[2]])
    }

    /// The image as PNG bytes (8-bit RGB).
    pub fn to_png(&self) -> Result<Vec<u8>, png::EncodingError> {
        png_bytes(self.width, self.height, Channels::Rgb, &self.pixels)
    }
}

/// Why a heatmap could not be drawn or encoded.
#[derive(Debug, thiserror::Error)]
pub enum HeatmapError {
    /// The matrices do not fit together (different specimens, asymmetric…).
    #[error(transparent)]
    Matrix(#[from] MantelError),
    /// The order is not a permutation of the specimens.
    #[error("the order is not a permutation of the {0} specimens")]
    BadOrder(usize),
    /// No specimens.
    #[error("the matrix is empty")]
    Empty,
    /// The image would be too large.
    #[error("{0} × {0} pixels is too large an image")]
    TooLarge(u64),
}

/// Colour where a specimen meets itself: the separating diagonal.
const DIAGONAL_COLOUR: [u8; 3] = [255, 255, 255];

/// Viridis (the perceptually uniform map of matplotlib), sampled at eleven
/// evenly spaced points; [`viridis`] interpolates linearly between them.
const VIRIDIS: [[u8; 3]; 11] = [
    [0x44, 0x01, 0x54],
    [0x48, 0x25, 0x76],
    [0x41, 0x44, 0x87],
    [0x35, 0x60, 0x8d],
    [0x2a, 0x78, 0x8e],
    [0x21, 0x90, 0x8c],
    [0x22, 0xa8, 0x84],
    [0x43, 0xbf, 0x71],
    [0x7a, 0xd1, 0x51],
    [0xbb, 0xdf, 0x27],
    [0xfd, 0xe7, 0x25],
];

/// The viridis colour of `t ∈ [0, 1]` (dark violet at 0, yellow at 1;
/// values outside are clamped, NaN maps to 0).
fn viridis(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let k = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - k as f64;
    let (a, b) = (VIRIDIS[k], VIRIDIS[k + 1]);
    let mix = |u: u8, v: u8| (u as f64 + f * (v as f64 - u as f64)).round() as u8;
    [mix(a[0], b[0]), mix(a[1], b[1]), mix(a[2], b[2])]
}

/// The matrix rescaled to `[0, 1]` over the range of its off-diagonal
/// entries (all zero when they are constant).
fn normalized(m: &DistanceMatrix) -> Vec<Vec<f64>> {
    let n = m.names().len();
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..n {
        for j in (0..n).filter(|&j| j != i) {
            let v = m.get(i, j);
            if v.is_finite() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
    }
    let span = hi - lo;
    (0..n)
        .map(|i| {
            (0..n)
                .map(|j| {
                    let v = m.get(i, j);
                    if span > 0.0 && v.is_finite() {
                        ((v - lo) / span).clamp(0.0, 1.0)
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect()
}

/// The leaf order of the average-linkage (UPGMA) hierarchical clustering
/// of `m` ([`average_linkage_merges`]): near specimens end up next to each
/// other. At each merge the two leaf sequences are joined (the one holding
/// the lower index first) and flipped where that brings the two facing
/// ends closest. The order is deterministic.
pub fn average_linkage_order(m: &DistanceMatrix) -> Vec<usize> {
    let mut leaves: Vec<Vec<usize>> = (0..m.len()).map(|i| vec![i]).collect();
    for merge in average_linkage_merges(m) {
        leaves[merge.keep] = join_leaves(&leaves[merge.keep], &leaves[merge.gone], m);
        leaves[merge.gone].clear();
    }
    // Cluster 0 is never merged away: it is the lowest index.
    leaves.into_iter().next().unwrap_or_default()
}

/// Concatenate two leaf sequences, the one with the lower first index
/// first, reversing either where that makes the facing ends nearest (ties
/// keep the sequences as they are).
fn join_leaves(x: &[usize], y: &[usize], m: &DistanceMatrix) -> Vec<usize> {
    let min_x = x.iter().min().copied().unwrap_or(usize::MAX);
    let min_y = y.iter().min().copied().unwrap_or(usize::MAX);
    let (first, second) = if min_x <= min_y { (x, y) } else { (y, x) };
    let (Some(&f0), Some(&f1), Some(&s0), Some(&s1)) =
        (first.first(), first.last(), second.first(), second.last())
    else {
        return first.iter().chain(second).copied().collect();
    };
    // (reverse first, reverse second, distance between the facing ends)
    let options = [
        (false, false, m.get(f1, s0)),
        (false, true, m.get(f1, s1)),
        (true, false, m.get(f0, s0)),
        (true, true, m.get(f0, s1)),
    ];
    let mut best = options[0];
    for o in &options[1..] {
        if o.2 < best.2 {
            best = *o;
        }
    }
    let mut out: Vec<usize> = Vec::with_capacity(first.len() + second.len());
    if best.0 {
        out.extend(first.iter().rev());
    } else {
        out.extend(first);
    }
    if best.1 {
        out.extend(second.iter().rev());
    } else {
        out.extend(second);
    }
    out
}

/// Regroup `order` by a label: groups follow each other in the order of
/// their first member in `order`, members keep their relative order,
/// specimens without a label (`None`) come last as one group. Returns the
/// new order and the group boundaries (positions `k`, `0 < k < n`, where a
/// new group starts), for [`heatmap`]'s separating lines.
pub fn grouped_order(order: &[usize], group: &[Option<String>]) -> (Vec<usize>, Vec<usize>) {
    let mut keys: Vec<Option<&str>> = Vec::new();
    for &k in order {
        let g = group.get(k).and_then(|g| g.as_deref());
        if g.is_some() && !keys.contains(&g) {
            keys.push(g);
        }
    }
    keys.push(None);
    let mut out = Vec::with_capacity(order.len());
    let mut boundaries = Vec::new();
    for key in keys {
        let members = order
            .iter()
            .filter(|&&k| group.get(k).and_then(|g| g.as_deref()) == key);
        let before = out.len();
        out.extend(members);
        if before > 0 && out.len() > before {
            boundaries.push(before);
        }
    }
    (out, boundaries)
}

/// Pixels per specimen so that the image is about 800 pixels wide (between
/// 1 and 24).
pub fn default_cell_size(specimens: usize) -> u32 {
    (800 / specimens.max(1)).clamp(1, 24) as u32
}

/// Draw the heatmap: specimen `order[k]` at row and column `k`, each cell
/// `cell × cell` pixels; `upper` (rows above the diagonal: right of it) and
/// `lower` (matched to `upper` by name) each coloured with the viridis map over
/// its own range; the diagonal cells white. At each
/// position in `boundaries` (a group starts there) a one-pixel line in the
/// diagonal colour separates the groups.
pub fn heatmap(
    upper: &DistanceMatrix,
    lower: &DistanceMatrix,
    order: &[usize],
    boundaries: &[usize],
    cell: u32,
) -> Result<RgbImage, HeatmapError> {
    check_distance_matrix(upper)?;
    let lower = align_to(upper, lower)?;
    let n = upper.names().len();
    if n == 0 {
        return Err(HeatmapError::Empty);
    }
    let mut seen = vec![false; n];
    for &k in order {
        match seen.get_mut(k) {
            Some(s) if !*s => *s = true,
            _ => return Err(HeatmapError::BadOrder(n)),
        }
    }
    if order.len() != n {
        return Err(HeatmapError::BadOrder(n));
    }
    let cell = cell.max(1);
    let side = n as u64 * cell as u64;
    if side > 16_384 {
        return Err(HeatmapError::TooLarge(side));
    }
    let side = side as u32;
    let (nu, nl) = (normalized(upper), normalized(&lower));
    let c = cell as usize;
    let w = side as usize;
    let mut pixels = vec![0u8; 3 * w * w];
    for (row, &i) in order.iter().enumerate() {
        for (col, &j) in order.iter().enumerate() {
            let colour = match col.cmp(&row) {
                std::cmp::Ordering::Greater => viridis(nu[i][j]),
                std::cmp::Ordering::Less => viridis(nl[i][j]),
                std::cmp::Ordering::Equal => DIAGONAL_COLOUR,
            };
            for y in row * c..(row + 1) * c {
                let start = 3 * (y * w + col * c);
                for px in pixels[start..start + 3 * c].chunks_exact_mut(3) {
                    px.copy_from_slice(&colour);
                }
            }
        }
    }
    for &b in boundaries.iter().filter(|&&b| b > 0 && b < n) {
        let at = b * c;
        for t in 0..w {
            for (x, y) in [(at, t), (t, at)] {
                let k = 3 * (y * w + x);
                pixels[k..k + 3].copy_from_slice(&DIAGONAL_COLOUR);
            }
        }
    }
    Ok(RgbImage {
        width: side,
        height: side,
        pixels,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::seq::SliceRandom;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Three planted groups (sizes 4, 5, 6) in shuffled order: distances
    /// about 1 within a group, about 10 between groups. Returns the matrix
    /// and each specimen's group.
    fn planted(seed: u64) -> (DistanceMatrix, Vec<usize>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut group: Vec<usize> = [0; 4].into_iter().chain([1; 5]).chain([2; 6]).collect();
        group.shuffle(&mut rng);
        let n = group.len();
        let mut values = vec![vec![0.0; n]; n];
        for i in 0..n {
            for j in i + 1..n {
                let base = if group[i] == group[j] { 1.0 } else { 10.0 };
                let v = base + rng.gen_range(0.0..0.5);
                values[i][j] = v;
                values[j][i] = v;
            }
        }
        let names = (0..n).map(|i| format!("x{i:02}")).collect();
        (DistanceMatrix::new(names, values).unwrap(), group)
    }

    #[test]
    fn order_puts_planted_groups_together() {
        for seed in 0..5 {
            let (m, group) = planted(seed);
            let order = average_linkage_order(&m);
            let mut sorted = order.clone();
            sorted.sort();
            assert_eq!(sorted, (0..m.names().len()).collect::<Vec<_>>());
            // Along the order the group changes exactly twice.
            let changes = order
                .windows(2)
                .filter(|w| group[w[0]] != group[w[1]])
                .count();
            assert_eq!(changes, 2, "seed {seed}: {order:?} {group:?}");
            assert_eq!(order, average_linkage_order(&m));
        }
    }

    #[test]
    fn order_follows_a_line() {
        // Points on a line: the order must be monotone along it.
        let xs = [5.0, 1.0, 9.0, 3.0, 7.0, 0.0, 8.0, 2.0, 6.0, 4.0];
        let m = DistanceMatrix::new(
            (0..xs.len()).map(|i| i.to_string()).collect(),
            xs.iter()
                .map(|a| xs.iter().map(|b: &f64| (a - b).abs()).collect())
                .collect(),
        )
        .unwrap();
        let along: Vec<f64> = average_linkage_order(&m).iter().map(|&k| xs[k]).collect();
        let up = along.windows(2).all(|w| w[0] < w[1]);
        let down = along.windows(2).all(|w| w[0] > w[1]);
        assert!(up || down, "{along:?}");
    }

    #[test]
    fn triangles_come_from_their_matrices() {
        let (a, _) = planted(1);
        let n = a.names().len();
        // b: a different matrix over the same names, listed in reverse.
        let (b0, _) = planted(2);
        let rev: Vec<usize> = (0..n).rev().collect();
        let b = DistanceMatrix::new(
            rev.iter().map(|&i| a.names()[i].clone()).collect(),
            rev.iter()
                .map(|&i| rev.iter().map(|&j| b0.values()[i][j]).collect())
                .collect(),
        )
        .unwrap();
        let order = average_linkage_order(&a);
        let cell = 3;
        let img = heatmap(&a, &b, &order, &[], cell).unwrap();
        assert_eq!((img.width, img.height), (n as u32 * 3, n as u32 * 3));
        assert_eq!(img.pixels.len(), 3 * 9 * n * n);
        let (na, nb) = (normalized(&a), normalized(&b0));
        for (row, &i) in order.iter().enumerate() {
            for (col, &j) in order.iter().enumerate() {
                let expected = match col.cmp(&row) {
                    std::cmp::Ordering::Greater => viridis(na[i][j]),
                    // b's row for a's specimen i is b0's row i (same name).
                    std::cmp::Ordering::Less => viridis(nb[i][j]),
                    std::cmp::Ordering::Equal => DIAGONAL_COLOUR,
                };
                for (dx, dy) in [(0, 0), (2, 2), (1, 2)] {
                    let px = img.pixel(col as u32 * cell + dx, row as u32 * cell + dy);
                    assert_eq!(px, Some(expected), "cell {row},{col}");
                }
            }
        }
        // The two matrices differ, so the triangles must differ somewhere.
        assert!((0..n).any(|k| {
            let (r, c) = (k, (k + 1) % n);
            img.pixel(c as u32 * cell, r as u32 * cell)
                != img.pixel(r as u32 * cell, c as u32 * cell)
        }));
    }

    #[test]
    fn groups_and_their_lines() {
        let group: Vec<Option<String>> = ["b", "a", "b", "", "a", "c"]
            .iter()
            .map(|g| (!g.is_empty()).then(|| g.to_string()))
            .collect();
        let order = [5, 0, 1, 2, 3, 4];
        let (grouped, bounds) = grouped_order(&order, &group);
        // c (first seen), then b, then a, then the unlabelled one.
        assert_eq!(grouped, vec![5, 0, 2, 1, 4, 3]);
        assert_eq!(bounds, vec![1, 3, 5]);

        let (m, _) = planted(4);
        let n = m.names().len() as u32;
        let order = average_linkage_order(&m);
        let img = heatmap(&m, &m, &order, &[3], 4).unwrap();
        let plain = heatmap(&m, &m, &order, &[], 4).unwrap();
        for t in 0..4 * n {
            assert_eq!(img.pixel(12, t), Some(DIAGONAL_COLOUR));
            assert_eq!(img.pixel(t, 12), Some(DIAGONAL_COLOUR));
        }
        // Away from the lines nothing changes.
        assert_eq!(img.pixel(13, 30), plain.pixel(13, 30));
        assert_ne!(plain.pixel(12, 30), Some(DIAGONAL_COLOUR));
    }

    #[test]
    fn colour_map_and_normalization() {
        assert_eq!(viridis(0.0), [0x44, 0x01, 0x54]);
        assert_eq!(viridis(1.0), [0xfd, 0xe7, 0x25]);
        assert_eq!(viridis(0.5), [0x21, 0x90, 0x8c]);
        assert_eq!(viridis(f64::NAN), viridis(0.0));
        // Lightness (green channel here) increases monotonically.
        let g: Vec<u8> = (0..=100).map(|k| viridis(k as f64 / 100.0)[1]).collect();
        assert!(g.windows(2).all(|w| w[0] <= w[1]));
        let m = DistanceMatrix::new(
            vec!["a".into(), "b".into(), "c".into()],
            vec![
                vec![0.0, 2.0, 4.0],
                vec![2.0, 0.0, 3.0],
                vec![4.0, 3.0, 0.0],
            ],
        )
        .unwrap();
        let nm = normalized(&m);
        assert_eq!(nm[0][1], 0.0);
        assert_eq!(nm[0][2], 1.0);
        assert_eq!(nm[1][2], 0.5);
    }

    #[test]
    fn png_round_trip_and_errors() {
        let (a, _) = planted(3);
        let img = heatmap(&a, &a, &average_linkage_order(&a), &[], 2).unwrap();
        let bytes = img.to_png().unwrap();
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (img.width, img.height));
        assert_eq!(&buf[..info.buffer_size()], &img.pixels[..]);
        // With one matrix the picture is symmetric.
        assert_eq!(img.pixel(2, 10), img.pixel(10, 2));
        assert!(matches!(
            heatmap(&a, &a, &[0, 1, 2], &[], 2),
            Err(HeatmapError::BadOrder(15))
        ));
        let (mut names, values) = a.clone().into_parts();
        names[0] = "nobody".into();
        let other = DistanceMatrix::new(names, values).unwrap();
        let e = heatmap(&a, &other, &average_linkage_order(&a), &[], 2).unwrap_err();
        assert!(e.to_string().contains("nobody"), "{e}");
    }
}
