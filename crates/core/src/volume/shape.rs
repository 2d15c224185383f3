//! Shape rules on voxel masks, pure functions over plain data: cube
//! erosion, dilation and opening (what survives an opening of radius `r`
//! is at least `2r + 1` samples thick; what it removes are thin parts:
//! tube walls, straws, pins, strands of foam), per-component statistics
//! (size, bounding box, mean grey, whether it spans the field of view),
//! and the local variation that tells textured foam from homogeneous
//! dentine.

use rayon::prelude::*;

/// Whether each sample has, within the window of half-width `r` along
/// `axis` (outside the grid counting as `false`), all (`all`) or any
/// samples set. Along y and z the window slides over whole rows (planes)
/// at once, a count per column, and nothing branches on the samples: on
/// noisy masks a branch per sample is mispredicted half the time (the
/// segmentation of a 356×300×300 batch stack took 1.32 s with such
/// branches, 1.21 s without).
fn window_filter(mask: &[bool], dims: [usize; 3], axis: usize, r: usize, all: bool) -> Vec<bool> {
    let [nx, ny, _] = dims;
    let plane = nx * ny;
    let need = if all { 2 * r + 1 } else { 1 };
    let mut out = vec![false; mask.len()];
    match axis {
        0 => out
            .par_chunks_mut(plane)
            .zip(mask.par_chunks(plane))
            .for_each(|(o, m)| {
                for (o, m) in o.chunks_mut(nx).zip(m.chunks(nx)) {
                    window_along_line(m, o, r, need);
                }
            }),
        1 => out
            .par_chunks_mut(plane)
            .zip(mask.par_chunks(plane))
            .for_each(|(o, m)| window_across_rows(m, o, nx, r, need)),
        // Along z: one pass over the planes (cheaper than handing planes to
        // threads).
        _ => window_across_rows(mask, &mut out, plane, r, need),
    }
    out
}

/// [`window_filter`] along one line `m` of samples, into `o`.
fn window_along_line(m: &[bool], o: &mut [bool], r: usize, need: usize) {
    let n = m.len();
    let mut count: usize = m.iter().take(r).map(|&b| usize::from(b)).sum();
    for p in 0..n {
        if let Some(&b) = m.get(p + r) {
            count += usize::from(b);
        }
        if p > r {
            count -= usize::from(m[p - r - 1]);
        }
        o[p] = count >= need;
    }
}

/// [`window_filter`] across the rows of `m` (each `width` samples long,
/// one after another), into `o`: a running count for each column.
fn window_across_rows(m: &[bool], o: &mut [bool], width: usize, r: usize, need: usize) {
    let rows = m.len() / width.max(1);
    let row = |k: usize| &m[k * width..(k + 1) * width];
    let mut count = vec![0u16; width];
    for k in 0..r.min(rows) {
        for (c, &b) in count.iter_mut().zip(row(k)) {
            *c += u16::from(b);
        }
    }
    for k in 0..rows {
        if k + r < rows {
            for (c, &b) in count.iter_mut().zip(row(k + r)) {
                *c += u16::from(b);
            }
        }
        if k > r {
            for (c, &b) in count.iter_mut().zip(row(k - r - 1)) {
                *c -= u16::from(b);
            }
        }
        for (o, &c) in o[k * width..(k + 1) * width].iter_mut().zip(&count) {
            *o = usize::from(c) >= need;
        }
    }
}

/// Erosion of `mask` by the cube of half-side `r` (outside the grid is
/// empty): the samples whose whole cube is set.
pub(crate) fn erode_cube(mask: &[bool], dims: [usize; 3], r: usize) -> Vec<bool> {
    let x = window_filter(mask, dims, 0, r, true);
    let y = window_filter(&x, dims, 1, r, true);
    window_filter(&y, dims, 2, r, true)
}

/// Dilation of `mask` by the cube of half-side `r`.
pub(crate) fn dilate_cube(mask: &[bool], dims: [usize; 3], r: usize) -> Vec<bool> {
    let x = window_filter(mask, dims, 0, r, false);
    let y = window_filter(&x, dims, 1, r, false);
    window_filter(&y, dims, 2, r, false)
}

/// Opening of `mask` by the cube of half-side `r`: the union of the cubes
/// that fit inside it. Parts thinner than `2r + 1` samples are removed.
pub(crate) fn open_cube(mask: &[bool], dims: [usize; 3], r: usize) -> Vec<bool> {
    dilate_cube(&erode_cube(mask, dims, r), dims, r)
}

/// Size, extent and grey level of one object.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ObjectStats {
    /// Samples.
    pub voxels: usize,
    /// First sample along x, y, z.
    pub min: [usize; 3],
    /// Last sample along x, y, z.
    pub max: [usize; 3],
    /// Mean grey value.
    pub mean: f64,
}

impl ObjectStats {
    /// The first axis (0 = x, 1 = y, 2 = z) along which the object reaches
    /// both ends of a grid of `dims`: it spans the field of view, as a tube,
    /// foam filling it, or the background do and a specimen does not.
    pub(crate) fn spanned_axis(&self, dims: [usize; 3]) -> Option<usize> {
        (0..3).find(|&a| dims[a] > 1 && self.min[a] == 0 && self.max[a] + 1 == dims[a])
    }
}

/// The statistics of each of `count` labelled objects (`labels` as
/// [`super::connected_components`] gives them, `u32::MAX` = none).
pub(crate) fn object_stats(
    labels: &[u32],
    count: usize,
    values: &[f32],
    dims: [usize; 3],
) -> Vec<ObjectStats> {
    let mut out = vec![
        ObjectStats {
            voxels: 0,
            min: [usize::MAX; 3],
            max: [0; 3],
            mean: 0.0,
        };
        count
    ];
    let mut sums = vec![0.0f64; count];
    let mut i = 0;
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let l = labels[i];
                if l != u32::MAX {
                    let o = &mut out[l as usize];
                    o.voxels += 1;
                    for (a, p) in [x, y, z].into_iter().enumerate() {
                        o.min[a] = o.min[a].min(p);
                        o.max[a] = o.max[a].max(p);
                    }
                    sums[l as usize] += f64::from(values[i]);
                }
                i += 1;
            }
        }
    }
    for (o, s) in out.iter_mut().zip(sums) {
        o.mean = s / o.voxels.max(1) as f64;
    }
    out
}

/// The local variation of the grey values within `mask`: the median
/// absolute difference between samples set in `mask` and their set
/// neighbour along x, with the mean of the set samples. Scanner noise on a
/// homogeneous material gives a small variation; foam's texture a large
/// one. `None` for fewer than 16 neighbour pairs.
pub(crate) fn local_variation(
    values: &[f32],
    mask: &[bool],
    dims: [usize; 3],
) -> Option<(f64, f64)> {
    let mut diffs = Vec::new();
    let (mut n, mut s) = (0usize, 0.0f64);
    for (i, &m) in mask.iter().enumerate() {
        if !m {
            continue;
        }
        n += 1;
        s += f64::from(values[i]);
        if (i + 1) % dims[0] != 0 && mask[i + 1] {
            diffs.push((values[i + 1] - values[i]).abs());
        }
    }
    if diffs.len() < 16 {
        return None;
    }
    let mid = diffs.len() / 2;
    let (_, median, _) = diffs.select_nth_unstable_by(mid, f32::total_cmp);
    Some((f64::from(*median), s / n as f64))
}

/// The value below which a fraction `q` of `values` lies (nearest rank);
/// `None` when empty.
pub(super) fn quantile(mut values: Vec<f32>, q: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let k = ((values.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    let (_, v, _) = values.select_nth_unstable_by(k, f32::total_cmp);
    Some(f64::from(*v))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize, f: impl Fn(usize, usize, usize) -> bool) -> Vec<bool> {
        let mut m = vec![false; n * n * n];
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    m[x + n * (y + n * z)] = f(x, y, z);
                }
            }
        }
        m
    }

    /// The window, counted directly for every sample, on a noisy mask of
    /// unequal sides, along each axis, for erosion and dilation.
    #[test]
    fn the_sliding_window_counts_what_a_direct_count_does() {
        let dims = [13, 7, 9];
        let mut state = 12345u64;
        let mask: Vec<bool> = (0..dims[0] * dims[1] * dims[2])
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                !(state >> 33).is_multiple_of(3)
            })
            .collect();
        let at = |p: [usize; 3]| mask[p[0] + dims[0] * (p[1] + dims[1] * p[2])];
        for axis in 0..3 {
            for r in [0, 1, 2, 4, 20] {
                for all in [true, false] {
                    let fast = window_filter(&mask, dims, axis, r, all);
                    for (i, &got) in fast.iter().enumerate() {
                        let p = [
                            i % dims[0],
                            (i / dims[0]) % dims[1],
                            i / (dims[0] * dims[1]),
                        ];
                        let lo = p[axis].saturating_sub(r);
                        let hi = (p[axis] + r).min(dims[axis] - 1);
                        let set = (lo..=hi)
                            .filter(|&k| {
                                let mut q = p;
                                q[axis] = k;
                                at(q)
                            })
                            .count();
                        let want = if all { set == 2 * r + 1 } else { set > 0 };
                        assert_eq!(got, want, "axis {axis}, r {r}, all {all}, at {p:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn an_opening_removes_a_thin_wall_and_a_rod_and_keeps_a_block() {
        let n = 30;
        let dims = [n; 3];
        // A block 8 thick, a wall 3 thick across the whole grid, a rod 2 wide.
        let block = |x: usize, y: usize, z: usize| {
            (5..13).contains(&x) && (5..13).contains(&y) && (5..13).contains(&z)
        };
        let wall = |x: usize, _: usize, _: usize| (20..23).contains(&x);
        let rod = |x: usize, y: usize, _: usize| (14..16).contains(&x) && (8..10).contains(&y);
        let m = grid(n, |x, y, z| block(x, y, z) || wall(x, y, z) || rod(x, y, z));
        let opened = open_cube(&m, dims, 2);
        let want = grid(n, block);
        assert_eq!(opened, want);
        // Erosion and dilation by 1 of the block.
        let e = erode_cube(&want, dims, 1);
        assert_eq!(e.iter().filter(|&&b| b).count(), 6 * 6 * 6);
        let d = dilate_cube(&want, dims, 1);
        assert_eq!(d.iter().filter(|&&b| b).count(), 10 * 10 * 10);
        // The wall spans the field of view along y and z, the block does not.
        let walls = grid(n, wall);
        let (labels, sizes) = super::super::segment::connected_components(&walls, dims);
        let values = vec![1.0f32; n * n * n];
        let st = object_stats(&labels, sizes.len(), &values, dims);
        assert_eq!(st.len(), 1);
        assert_eq!(st[0].voxels, 3 * n * n);
        assert_eq!(st[0].spanned_axis(dims), Some(1));
        assert_eq!((st[0].min, st[0].max), ([20, 0, 0], [22, n - 1, n - 1]));
    }

    #[test]
    fn local_variation_tells_texture_from_noise() {
        let n = 24;
        let dims = [n; 3];
        let mask = vec![true; n * n * n];
        // Alternating along x (texture) against a constant.
        let banded: Vec<f32> = (0..n * n * n)
            .map(|i| if i % 2 == 0 { 0.1 } else { 0.3 })
            .collect();
        let (v, m) = local_variation(&banded, &mask, dims).unwrap();
        assert!((v - 0.2).abs() < 1e-6, "{v}");
        assert!((m - 0.2).abs() < 1e-3);
        let flat = vec![0.5f32; n * n * n];
        assert_eq!(local_variation(&flat, &mask, dims), Some((0.0, 0.5)));
        assert_eq!(quantile(vec![3.0, 1.0, 2.0], 0.5), Some(2.0));
        assert_eq!(quantile(Vec::new(), 0.5), None);
    }
}
