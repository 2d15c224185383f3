//! Streaming reduction of a slice stack to the working resolution: each
//! slice is added into the block it falls in as it is read, so only the
//! reduced volume and one slice are ever in memory.

use crate::mesh::Grid;

/// The integer block size that brings the largest of `dims` to at most
/// `working` samples.
pub fn reduction_factor(dims: [usize; 3], working: usize) -> usize {
    let largest = dims.iter().copied().max().unwrap_or(1);
    largest.div_ceil(working.max(1)).max(1)
}

/// Block averaging of slices pushed one at a time, in order.
#[derive(Debug)]
pub struct BlockAverage {
    factor: usize,
    in_dims: [usize; 3],
    grid: Grid,
    plane: Vec<f64>,
    next_slice: usize,
}

impl BlockAverage {
    /// Averages `factor`³ blocks of a stack of `dims` (x, y, slices) whose
    /// voxels are `voxel_size` apart; the reduced samples sit at the block
    /// centres.
    pub fn new(dims: [usize; 3], voxel_size: [f64; 3], factor: usize) -> BlockAverage {
        let out = dims.map(|d| d.div_ceil(factor));
        let f = factor as f64;
        let origin = voxel_size.map(|s| s * (f - 1.0) / 2.0);
        let spacing = voxel_size.map(|s| s * f);
        BlockAverage {
            factor,
            in_dims: dims,
            grid: Grid::filled(out, origin, spacing, 0.0),
            plane: vec![0.0; out[0] * out[1]],
            next_slice: 0,
        }
    }

    /// Add the next slice (`in_dims[0] * in_dims[1]` values, x fastest).
    pub fn push(&mut self, slice: &[f32]) {
        let [w, h, _] = self.in_dims;
        let (f, ow) = (self.factor, self.grid.dims[0]);
        // Each row's values are added block by block, in x order (the
        // sums of a division per value, without the division).
        for (y, row) in slice.chunks_exact(w.max(1)).take(h).enumerate() {
            let orow = (y / f) * ow;
            let Some(out) = self.plane.get_mut(orow..orow + ow) else {
                break;
            };
            for (cell, block) in out.iter_mut().zip(row.chunks(f)) {
                for &v in block {
                    *cell += f64::from(v);
                }
            }
        }
        self.next_slice += 1;
        if self.next_slice.is_multiple_of(self.factor) || self.next_slice == self.in_dims[2] {
            self.flush();
        }
    }

    fn flush(&mut self) {
        let [w, h, n] = self.in_dims;
        let f = self.factor;
        let [ow, oh, _] = self.grid.dims;
        let z = (self.next_slice - 1) / f;
        let depth = (self.next_slice - z * f).min(n - z * f);
        for oy in 0..oh {
            let ny = (h - oy * f).min(f);
            for ox in 0..ow {
                let nx = (w - ox * f).min(f);
                let count = (nx * ny * depth) as f64;
                let i = self.grid.index(ox, oy, z);
                self.grid.values[i] = (self.plane[ox + oy * ow] / count) as f32;
            }
        }
        self.plane.iter_mut().for_each(|v| *v = 0.0);
    }

    /// The reduced grid, once every slice was pushed.
    pub fn finish(self) -> Grid {
        self.grid
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_average_including_partial_ones() {
        let dims = [5, 3, 3];
        assert_eq!(reduction_factor(dims, 2), 3);
        let mut r = BlockAverage::new(dims, [1.0, 1.0, 2.0], 2);
        for z in 0..3 {
            let s: Vec<f32> = (0..15).map(|i| (i % 5) as f32 + 10.0 * z as f32).collect();
            r.push(&s);
        }
        let g = r.finish();
        assert_eq!(g.dims, [3, 2, 2]);
        // Block x 0..2, y 0..2, z 0..2: x mean 0.5, z mean 5.
        assert!((g.values[0] - 5.5).abs() < 1e-6);
        // Last x block holds x = 4 only; last z block z = 2 only.
        let i = g.index(2, 1, 1);
        assert!((g.values[i] - 24.0).abs() < 1e-6);
        assert_eq!(g.spacing, [2.0, 2.0, 4.0]);
        assert_eq!(g.origin, [0.5, 0.5, 1.0]);
    }
}
