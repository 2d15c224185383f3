//! One specimen of a batch scan at its own resolution.
//!
//! The working grid brings the whole field of view to about
//! `working_voxels` across; a batch of three teeth then has each tooth at a
//! third of that, too coarse for its crown. While the slices stream past,
//! a finer detail grid is kept too (within [`DETAIL_VOXELS`]); each
//! specimen found on the working grid is cut out of it, brought to about
//! `working_voxels` across itself, and thresholded again at the level the
//! segmentation found, within the specimen's own region (so a neighbour or
//! the mount never enters).

use super::segment::{connected_components, fill_cavities};
use super::shape::{dilate_cube, open_cube};
use crate::mesh::{Grid, Mesh};

/// Most samples of the detail grid (128 MB of `f32`): a 300³ scan is kept
/// whole, a larger one block-averaged to fit.
pub(crate) const DETAIL_VOXELS: usize = 32 << 20;

/// The block size of the detail grid of a volume of `dims`: the smallest
/// that keeps it within [`DETAIL_VOXELS`].
pub fn detail_factor(dims: [usize; 3]) -> usize {
    (1..)
        .find(|&f| dims.iter().map(|d| d.div_ceil(f)).product::<usize>() <= DETAIL_VOXELS)
        .unwrap_or(1)
}

/// The closed surface of the specimen `mask` (on `coarse`, the working
/// grid) made from `detail` (the same volume, finer): the specimen's box,
/// one coarse sample wider, averaged to about `working` samples across,
/// lightly blurred against noise, thresholded at `level` within the
/// specimen's own region (the coarse mask grown by one sample), its largest
/// part with cavities filled. `None` when nothing is left (the caller keeps
/// the working grid's surface).
pub(super) fn refined_surface(
    detail: &Grid,
    coarse: &Grid,
    mask: &[bool],
    level: f64,
    working: usize,
) -> Option<Mesh> {
    let region = dilate_cube(mask, coarse.dims, 1);
    // The specimen's physical box, from its coarse samples.
    let mut lo = [f64::MAX; 3];
    let mut hi = [f64::MIN; 3];
    for (i, _) in region.iter().enumerate().filter(|(_, &b)| b) {
        let c = coords(coarse.dims, i);
        for a in 0..3 {
            let p = coarse.origin[a] + c[a] as f64 * coarse.spacing[a];
            lo[a] = lo[a].min(p - coarse.spacing[a]);
            hi[a] = hi[a].max(p + coarse.spacing[a]);
        }
    }
    if lo[0] > hi[0] {
        return None;
    }
    let index = |a: usize, p: f64| ((p - detail.origin[a]) / detail.spacing[a]).round();
    let first: [usize; 3] =
        [0, 1, 2].map(|a| index(a, lo[a]).clamp(0.0, (detail.dims[a] - 1) as f64) as usize);
    let last: [usize; 3] =
        [0, 1, 2].map(|a| index(a, hi[a]).clamp(0.0, (detail.dims[a] - 1) as f64) as usize);
    let extent = (0..3).map(|a| last[a] - first[a] + 1).max().unwrap_or(1);
    let f = extent.div_ceil(working.max(1)).max(1);
    let dims = [0, 1, 2].map(|a| (last[a] - first[a] + 1).div_ceil(f));
    // Block averages of the crop.
    let mut values = vec![0.0f32; dims[0] * dims[1] * dims[2]];
    let mut counts = vec![0u32; values.len()];
    for z in first[2]..=last[2] {
        for y in first[1]..=last[1] {
            for x in first[0]..=last[0] {
                let o = [(x - first[0]) / f, (y - first[1]) / f, (z - first[2]) / f];
                let k = o[0] + dims[0] * (o[1] + dims[1] * o[2]);
                values[k] += detail.values[detail.index(x, y, z)];
                counts[k] += 1;
            }
        }
    }
    for (v, &n) in values.iter_mut().zip(&counts) {
        *v /= n.max(1) as f32;
    }
    let spacing = detail.spacing.map(|s| s * f as f64);
    let origin = [0, 1, 2].map(|a| {
        detail.origin[a]
            + first[a] as f64 * detail.spacing[a]
            + detail.spacing[a] * (f as f64 - 1.0) / 2.0
    });
    let mut crop = Grid {
        dims,
        origin,
        spacing,
        values,
    };
    crop.gaussian_blur(0.7);
    // Which samples of the crop lie in the specimen's coarse region.
    let coarse_index = |p: [f64; 3]| -> Option<usize> {
        let c = [0, 1, 2].map(|a| ((p[a] - coarse.origin[a]) / coarse.spacing[a]).round());
        (0..3)
            .all(|a| c[a] >= 0.0 && c[a] < coarse.dims[a] as f64)
            .then(|| coarse.index(c[0] as usize, c[1] as usize, c[2] as usize))
    };
    let inside: Vec<bool> = (0..crop.values.len())
        .map(|i| {
            let c = coords(dims, i);
            let p = [0, 1, 2].map(|a| origin[a] + c[a] as f64 * spacing[a]);
            f64::from(crop.values[i]) > level && coarse_index(p).is_some_and(|k| region[k])
        })
        .collect();
    // Bright crumbs of foam touching the specimen, thin at this
    // resolution, go (the working grid's opening did the same).
    let inside = open_cube(&inside, dims, 1);
    let (labels, sizes) = connected_components(&inside, dims);
    let (largest, _) = sizes.iter().enumerate().max_by_key(|(_, &n)| n)?;
    let specimen: Vec<bool> = labels.iter().map(|&l| l == largest as u32).collect();
    let (specimen, _, _) = fill_cavities(specimen, dims);
    let mesh = super::masked_isosurface(&crop, &specimen, level as f32);
    (!mesh.faces.is_empty()).then_some(mesh)
}

fn coords(dims: [usize; 3], i: usize) -> [usize; 3] {
    [
        i % dims[0],
        (i / dims[0]) % dims[1],
        i / (dims[0] * dims[1]),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ball_found_coarsely_is_made_again_finely() {
        let n = 64;
        let mut detail = Grid::filled([n, n, n], [0.0; 3], [1.0; 3], 0.0);
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let d = ((x as f64 - 20.0).powi(2)
                        + (y as f64 - 30.0).powi(2)
                        + (z as f64 - 32.0).powi(2))
                    .sqrt();
                    let i = detail.index(x, y, z);
                    detail.values[i] = if d < 10.0 { 1.0 } else { 0.0 };
                }
            }
        }
        // The working grid: blocks of 4.
        let f = 4;
        let mut coarse = Grid::filled([n / f; 3], [1.5; 3], [f as f64; 3], 0.0);
        let mut mask = vec![false; coarse.values.len()];
        for z in 0..n / f {
            for y in 0..n / f {
                for x in 0..n / f {
                    let i = coarse.index(x, y, z);
                    let v = detail.values[detail.index(x * f + 1, y * f + 1, z * f + 1)];
                    coarse.values[i] = v;
                    mask[i] = v > 0.5;
                }
            }
        }
        let mesh = refined_surface(&detail, &coarse, &mask, 0.5, 200).unwrap();
        // The fine surface lies on the sphere of radius 10, within a sample.
        for p in &mesh.vertices {
            let d = ((p[0] - 20.0).powi(2) + (p[1] - 30.0).powi(2) + (p[2] - 32.0).powi(2)).sqrt();
            assert!((d - 10.0).abs() < 1.0, "{d}");
        }
        assert!(detail_factor([300, 300, 300]) == 1 && detail_factor([1000, 1000, 1000]) == 4);
    }
}
