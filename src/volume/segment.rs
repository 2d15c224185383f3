//! Segmentation of the specimen on the working grid: voxels above the
//! threshold, the largest 6-connected component kept, and the background
//! not connected to the grid's border (internal cavities) filled.

use std::collections::VecDeque;

/// What segmentation kept and dropped.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SegmentReport {
    /// Voxels of the kept component before filling.
    pub kept_voxels: usize,
    /// Other components above the threshold, dropped.
    pub dropped_components: usize,
    /// Voxels of the dropped components.
    pub dropped_voxels: usize,
    /// Internal cavities filled.
    pub filled_cavities: usize,
    /// Voxels filled.
    pub filled_voxels: usize,
}

/// 6-connected components of the `true` voxels of `mask` on a grid of
/// `dims`: a label per voxel (`u32::MAX` for `false`) and each label's size.
pub fn connected_components(mask: &[bool], dims: [usize; 3]) -> (Vec<u32>, Vec<usize>) {
    let mut labels = vec![u32::MAX; mask.len()];
    let mut sizes = Vec::new();
    let mut queue = VecDeque::new();
    for start in 0..mask.len() {
        if !mask[start] || labels[start] != u32::MAX {
            continue;
        }
        let label = sizes.len() as u32;
        labels[start] = label;
        queue.push_back(start);
        let mut size = 0;
        while let Some(i) = queue.pop_front() {
            size += 1;
            for j in neighbours6(i, dims) {
                if mask[j] && labels[j] == u32::MAX {
                    labels[j] = label;
                    queue.push_back(j);
                }
            }
        }
        sizes.push(size);
    }
    (labels, sizes)
}

/// The up to six face neighbours of voxel `i`.
fn neighbours6(i: usize, dims: [usize; 3]) -> impl Iterator<Item = usize> {
    let [nx, ny, nz] = dims;
    let x = i % nx;
    let y = (i / nx) % ny;
    let z = i / (nx * ny);
    let plane = nx * ny;
    [
        (x > 0).then(|| i - 1),
        (x + 1 < nx).then(|| i + 1),
        (y > 0).then(|| i - nx),
        (y + 1 < ny).then(|| i + nx),
        (z > 0).then(|| i - plane),
        (z + 1 < nz).then(|| i + plane),
    ]
    .into_iter()
    .flatten()
}

fn on_border(i: usize, dims: [usize; 3]) -> bool {
    let [nx, ny, nz] = dims;
    let x = i % nx;
    let y = (i / nx) % ny;
    let z = i / (nx * ny);
    x == 0 || y == 0 || z == 0 || x + 1 == nx || y + 1 == ny || z + 1 == nz
}

/// The largest component of `mask` with its internal cavities filled, and
/// what was dropped and filled. `None` when `mask` is empty.
pub fn specimen_mask(mask: &[bool], dims: [usize; 3]) -> Option<(Vec<bool>, SegmentReport)> {
    let (labels, sizes) = connected_components(mask, dims);
    let (largest, &kept) = sizes
        .iter()
        .enumerate()
        .max_by_key(|&(i, s)| (*s, usize::MAX - i))?;
    let mut out: Vec<bool> = labels.iter().map(|&l| l == largest as u32).collect();
    // Background reachable from the border is outside; the rest is cavity.
    let background: Vec<bool> = out.iter().map(|&m| !m).collect();
    let (bg_labels, bg_sizes) = connected_components(&background, dims);
    let mut outside = vec![false; bg_sizes.len()];
    for (i, &l) in bg_labels.iter().enumerate() {
        if l != u32::MAX && on_border(i, dims) {
            outside[l as usize] = true;
        }
    }
    let mut report = SegmentReport {
        kept_voxels: kept,
        dropped_components: sizes.len() - 1,
        dropped_voxels: sizes.iter().sum::<usize>() - kept,
        ..Default::default()
    };
    for (l, &o) in outside.iter().enumerate() {
        if !o {
            report.filled_cavities += 1;
            report.filled_voxels += bg_sizes[l];
        }
    }
    for (i, &l) in bg_labels.iter().enumerate() {
        if l != u32::MAX && !outside[l as usize] {
            out[i] = true;
        }
    }
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
