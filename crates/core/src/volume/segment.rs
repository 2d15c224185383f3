//! Segmentation on the working grid: 6-connected components, the largest
//! kept (`specimen_mask` in the tests, for a plain mask), and the background not
//! connected to the grid's border (internal cavities) filled. Which object
//! of a volume is the specimen is `specimen`'s to say.

use super::specimen::SegmentObject;

/// What segmentation kept and dropped.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SegmentReport {
    /// Voxels of the kept specimens before filling.
    pub kept_voxels: usize,
    /// Other objects above the specimen's threshold, dropped.
    pub dropped_components: usize,
    /// Voxels of the dropped components.
    pub dropped_voxels: usize,
    /// Internal cavities filled.
    pub filled_cavities: usize,
    /// Voxels filled.
    pub filled_voxels: usize,
    /// The candidate levels examined, highest first (grey values of the
    /// file).
    #[serde(default)]
    pub levels: Vec<f64>,
    /// The objects found: the specimen first, then those dropped, each
    /// with its grey level, size, bounding box and the reason.
    #[serde(default)]
    pub objects: Vec<SegmentObject>,
    /// Dropped objects not listed (under 64 samples, or beyond the 24
    /// largest).
    #[serde(default)]
    pub small_objects: usize,
    /// Their samples.
    #[serde(default)]
    pub small_voxels: usize,
    /// What a user should know about the split into specimens (an object
    /// cut at a neck, or possibly two fused).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// 6-connected components of the `true` voxels of `mask` on a grid of
/// `dims`: a label per voxel (`u32::MAX` for `false`) and each label's size.
pub(crate) fn connected_components(mask: &[bool], dims: [usize; 3]) -> (Vec<u32>, Vec<usize>) {
    let [nx, ny, nz] = dims;
    let plane = nx * ny;
    let mut labels = vec![u32::MAX; mask.len()];
    let mut sizes = Vec::new();
    // Depth-first with an explicit stack: the same components as a
    // breadth-first search, with less bookkeeping per voxel.
    let mut stack = Vec::new();
    for start in 0..mask.len() {
        if !mask[start] || labels[start] != u32::MAX {
            continue;
        }
        let label = sizes.len() as u32;
        labels[start] = label;
        stack.push(start);
        let mut size = 0;
        while let Some(i) = stack.pop() {
            size += 1;
            let x = i % nx;
            let yz = i / nx;
            let (y, z) = (yz % ny, yz / ny);
            let mut visit = |j: usize| {
                if mask[j] && labels[j] == u32::MAX {
                    labels[j] = label;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < nx {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - nx);
            }
            if y + 1 < ny {
                visit(i + nx);
            }
            if z > 0 {
                visit(i - plane);
            }
            if z + 1 < nz {
                visit(i + plane);
            }
        }
        sizes.push(size);
    }
    (labels, sizes)
}

fn on_border(i: usize, dims: [usize; 3]) -> bool {
    let [nx, ny, nz] = dims;
    let x = i % nx;
    let y = (i / nx) % ny;
    let z = i / (nx * ny);
    x == 0 || y == 0 || z == 0 || x + 1 == nx || y + 1 == ny || z + 1 == nz
}

/// `mask` with the background not connected to the grid's border (internal
/// cavities: pulp, canals, cracks) filled; how many cavities and voxels.
pub(crate) fn fill_cavities(mut mask: Vec<bool>, dims: [usize; 3]) -> (Vec<bool>, usize, usize) {
    let background: Vec<bool> = mask.iter().map(|&m| !m).collect();
    let (bg_labels, bg_sizes) = connected_components(&background, dims);
    let mut outside = vec![false; bg_sizes.len()];
    for (i, &l) in bg_labels.iter().enumerate() {
        if l != u32::MAX && on_border(i, dims) {
            outside[l as usize] = true;
        }
    }
    let (mut cavities, mut voxels) = (0, 0);
    for (l, &o) in outside.iter().enumerate() {
        if !o {
            cavities += 1;
            voxels += bg_sizes[l];
        }
    }
    for (i, &l) in bg_labels.iter().enumerate() {
        if l != u32::MAX && !outside[l as usize] {
            mask[i] = true;
        }
    }
    (mask, cavities, voxels)
}

/// The largest component of `mask` with its internal cavities filled, and
/// what was dropped and filled. `None` when `mask` is empty.
#[cfg(test)]
fn specimen_mask(mask: &[bool], dims: [usize; 3]) -> Option<(Vec<bool>, SegmentReport)> {
    let (labels, sizes) = connected_components(mask, dims);
    let (largest, &kept) = sizes
        .iter()
        .enumerate()
        .max_by_key(|&(i, s)| (*s, usize::MAX - i))?;
    let out: Vec<bool> = labels.iter().map(|&l| l == largest as u32).collect();
    let (out, filled_cavities, filled_voxels) = fill_cavities(out, dims);
    let report = SegmentReport {
        kept_voxels: kept,
        dropped_components: sizes.len() - 1,
        dropped_voxels: sizes.iter().sum::<usize>() - kept,
        filled_cavities,
        filled_voxels,
        ..Default::default()
    };
    Some((out, report))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn largest_component_kept_and_cavity_filled() {
        let dims = [9, 9, 9];
        let idx = |x: usize, y: usize, z: usize| x + 9 * (y + 9 * z);
        let mut mask = vec![false; 729];
        // A hollow 5³ cube (cavity of one voxel) and a single far voxel.
        for z in 1..6 {
            for y in 1..6 {
                for x in 1..6 {
                    mask[idx(x, y, z)] = !(x == 3 && y == 3 && z == 3);
                }
            }
        }
        mask[idx(8, 8, 8)] = true;
        let (out, r) = specimen_mask(&mask, dims).unwrap();
        assert_eq!(r.kept_voxels, 124);
        assert_eq!(r.dropped_components, 1);
        assert_eq!(r.filled_cavities, 1);
        assert_eq!(r.filled_voxels, 1);
        assert!(out[idx(3, 3, 3)]);
        assert!(!out[idx(8, 8, 8)]);
        assert_eq!(out.iter().filter(|&&m| m).count(), 125);
        assert!(specimen_mask(&[false; 8], [2, 2, 2]).is_none());
    }
}
