//! Shape rules on voxel masks, pure functions over plain data: cube
//! erosion, dilation and opening (what survives an opening of radius `r`
//! is at least `2r + 1` samples thick; what it removes are thin parts:
//! tube walls, straws, pins, strands of foam), per-component statistics
//! (size, bounding box, mean grey, whether it spans the field of view),
//! and the local variation that tells textured foam from homogeneous
//! dentine.

use rayon::prelude::*;

/// Whether each sample has, within the cube of half-side `r` along `axis`
/// (outside the grid counting as `false`), all (`all`) or any samples set.
fn window_filter(mask: &[bool], dims: [usize; 3], axis: usize, r: usize, all: bool) -> Vec<bool> {
    let [nx, ny, nz] = dims;
    let plane = nx * ny;
    let need = if all { 2 * r + 1 } else { 1 };
    let mut out = vec![false; mask.len()];
    if axis < 2 {
        out.par_chunks_mut(plane)
            .zip(mask.par_chunks(plane))
            .for_each(|(o, m)| {
                let (n, stride, lines, line_stride) = if axis == 0 {
                    (nx, 1, ny, nx)
                } else {
                    (ny, nx, nx, 1)
                };
                for l in 0..lines {
                    let base = l * line_stride;
                    let mut count = (0..r.min(n)).filter(|&p| m[base + p * stride]).count();
                    for p in 0..n {
                        if p + r < n && m[base + (p + r) * stride] {
                            count += 1;
                        }
                        if p > r && m[base + (p - r - 1) * stride] {
                            count -= 1;
                        }
                        o[base + p * stride] = count >= need;
                    }
                }
            });
    } else {
        // Along z: a running count per column, one plane at a time (plain
        // loops over a plane: cheaper than handing planes to threads).
        let mut count = vec![0u16; plane];
        let add = |count: &mut [u16], z: usize, step: i16| {
            for (c, &m) in count.iter_mut().zip(&mask[z * plane..(z + 1) * plane]) {
                *c = c.wrapping_add_signed(step * i16::from(m));
            }
        };
        for z in 0..r.min(nz) {
            add(&mut count, z, 1);
        }
        for z in 0..nz {
            if z + r < nz {
                add(&mut count, z + r, 1);
            }
            if z > r {
                add(&mut count, z - r - 1, -1);
            }
            for (o, &c) in out[z * plane..(z + 1) * plane].iter_mut().zip(&count) {
                *o = usize::from(c) >= need;
            }
        }
    }
    out
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
