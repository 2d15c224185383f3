//! Segmentation on the working grid: 6-connected components, the largest
//! kept (`specimen_mask` in the tests, for a plain mask), and the background not
//! connected to the grid's border (internal cavities) filled. Which object
//! of a volume is the specimen is `specimen`'s to say.

use super::specimen::SegmentObject;
use crate::union_find::UnionFind;

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
/// Labels are numbered in the order of each component's first voxel.
///
/// Two passes over runs of voxels along x: each run gets a provisional
/// label, joined to the labels beside it in the row and the plane before;
/// then each voxel takes its set's final label. It walks the grid in
/// memory order (a flood fill's stack jumps between planes).
pub(crate) fn connected_components(mask: &[bool], dims: [usize; 3]) -> (Vec<u32>, Vec<usize>) {
    let [nx, ny, _] = dims;
    let plane = nx * ny;
    let mut labels = vec![u32::MAX; mask.len()];
    if nx == 0 || ny == 0 {
        return (labels, Vec::new());
    }
    let mut sets = UnionFind::new(0);
    for row in (0..mask.len()).step_by(nx) {
        let after_row = (row / nx) % ny > 0;
        let after_plane = row >= plane;
        let end = (row + nx).min(mask.len());
        let mut i = row;
        while i < end {
            if !mask[i] {
                i += 1;
                continue;
            }
            let run = sets.add();
            // The labels joined last, in the row and the plane before: a
            // run mostly lies along one run of each.
            let (mut joined_row, mut joined_plane) = (u32::MAX, u32::MAX);
            while i < end && mask[i] {
                labels[i] = run;
                if after_row {
                    let l = labels[i - nx];
                    if l != u32::MAX && l != joined_row {
                        sets.union(run, l);
                        joined_row = l;
                    }
                }
                if after_plane {
                    let l = labels[i - plane];
                    if l != u32::MAX && l != joined_plane {
                        sets.union(run, l);
                        joined_plane = l;
                    }
                }
                i += 1;
            }
        }
    }
    // A set's root is its smallest run, the first in the grid's order:
    // numbering sets by their roots numbers components by their first
    // voxel.
    let (final_label, components) = sets.numbered_sets();
    let mut sizes = vec![0usize; components];
    for l in labels.iter_mut().filter(|l| **l != u32::MAX) {
        *l = final_label[*l as usize];
        sizes[*l as usize] += 1;
    }
    (labels, sizes)
}

/// For each of `count` labels, whether a voxel of the grid's border has
/// it: only the six faces of the grid are visited.
fn labels_on_border(labels: &[u32], dims: [usize; 3], count: usize) -> Vec<bool> {
    let [nx, ny, nz] = dims;
    let mut on = vec![false; count];
    let mut mark = |i: usize| {
        if let Some(&l) = labels.get(i) {
            if let Some(o) = on.get_mut(l as usize) {
                *o = true;
            }
        }
    };
    for z in 0..nz {
        for y in 0..ny {
            let row = nx * (y + ny * z);
            if z == 0 || z + 1 == nz || y == 0 || y + 1 == ny {
                (row..row + nx).for_each(&mut mark);
            } else if nx > 0 {
                mark(row);
                mark(row + nx - 1);
            }
        }
    }
    on
}

/// `mask` with the background not connected to the grid's border (internal
/// cavities: pulp, canals, cracks) filled; how many cavities and voxels.
pub(crate) fn fill_cavities(mut mask: Vec<bool>, dims: [usize; 3]) -> (Vec<bool>, usize, usize) {
    let background: Vec<bool> = mask.iter().map(|&m| !m).collect();
    let (bg_labels, bg_sizes) = connected_components(&background, dims);
    let outside = labels_on_border(&bg_labels, dims, bg_sizes.len());
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

    /// Components by flood fill from each unlabelled voxel in the grid's
    /// order: the labels the two-pass labelling must give.
    fn flood_filled(mask: &[bool], [nx, ny, nz]: [usize; 3]) -> (Vec<u32>, Vec<usize>) {
        let mut labels = vec![u32::MAX; mask.len()];
        let mut sizes = Vec::new();
        for start in 0..mask.len() {
            if !mask[start] || labels[start] != u32::MAX {
                continue;
            }
            let label = sizes.len() as u32;
            labels[start] = label;
            let mut queue = std::collections::VecDeque::from([start]);
            let mut size = 0;
            while let Some(i) = queue.pop_front() {
                size += 1;
                let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
                let mut near = Vec::new();
                if x > 0 {
                    near.push(i - 1)
                }
                if x + 1 < nx {
                    near.push(i + 1)
                }
                if y > 0 {
                    near.push(i - nx)
                }
                if y + 1 < ny {
                    near.push(i + nx)
                }
                if z > 0 {
                    near.push(i - nx * ny)
                }
                if z + 1 < nz {
                    near.push(i + nx * ny)
                }
                for j in near {
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

    #[test]
    fn run_labelling_gives_the_flood_fills_components_in_the_same_order() {
        // Random masks from sparse to dense (many small components, and
        // shapes that join only through the row or the plane before), on
        // flat, thin and cubic grids.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for dims in [
            [1, 1, 1],
            [7, 1, 1],
            [1, 9, 4],
            [13, 11, 1],
            [16, 12, 9],
            [5, 40, 33],
        ] {
            for density in [10u64, 35, 50, 65, 90] {
                let n = dims[0] * dims[1] * dims[2];
                let mask: Vec<bool> = (0..n).map(|_| next() % 100 < density).collect();
                assert_eq!(
                    connected_components(&mask, dims),
                    flood_filled(&mask, dims),
                    "{dims:?} at {density} %"
                );
            }
        }
        // A U whose arms meet only at the bottom: two runs of a row join
        // after both were given labels.
        let dims = [5, 4, 1];
        let rows = ["X...X", "X...X", "X...X", "XXXXX"];
        let mask: Vec<bool> = rows
            .iter()
            .flat_map(|r| r.chars().map(|c| c == 'X'))
            .collect();
        let (labels, sizes) = connected_components(&mask, dims);
        assert_eq!(sizes, vec![11]);
        assert!(labels.iter().zip(&mask).all(|(&l, &m)| (l == 0) == m));
    }

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
