//! A scalar field sampled on a regular grid: the volume at working
//! resolution, and the phantoms the generators build.

/// Values on a regular grid, `x` fastest, then `y`, then `z`.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Samples along x, y, z.
    pub dims: [usize; 3],
    /// Position of sample (0, 0, 0), physical units.
    pub origin: [f64; 3],
    /// Distance between samples along each axis, physical units.
    pub spacing: [f64; 3],
    /// `dims[0] * dims[1] * dims[2]` values.
    pub values: Vec<f32>,
}

impl Grid {
    /// A grid of `dims` filled with `value`.
    pub fn filled(dims: [usize; 3], origin: [f64; 3], spacing: [f64; 3], value: f32) -> Grid {
        Grid {
            dims,
            origin,
            spacing,
            values: vec![value; dims[0] * dims[1] * dims[2]],
        }
    }

    /// The index of sample (x, y, z) in `values`.
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    /// The physical position of sample (x, y, z).
    pub fn position(&self, x: usize, y: usize, z: usize) -> [f64; 3] {
        [
            self.origin[0] + x as f64 * self.spacing[0],
            self.origin[1] + y as f64 * self.spacing[1],
            self.origin[2] + z as f64 * self.spacing[2],
        ]
    }

    /// Trilinear interpolation at physical position `p`, clamped to the grid.
    pub fn trilinear(&self, p: [f64; 3]) -> f32 {
        let mut base = [0usize; 3];
        let mut frac = [0f64; 3];
        for a in 0..3 {
            let n = self.dims[a];
            let u = ((p[a] - self.origin[a]) / self.spacing[a]).clamp(0.0, (n - 1) as f64);
            let i = (u.floor() as usize).min(n.saturating_sub(2));
            base[a] = i;
            frac[a] = if n > 1 { u - i as f64 } else { 0.0 };
        }
        let step = |a: usize| usize::from(self.dims[a] > 1);
        let mut acc = 0.0f64;
        for corner in 0..8usize {
            let mut w = 1.0;
            let mut c = [0usize; 3];
            for a in 0..3 {
                let bit = (corner >> a) & 1;
                c[a] = base[a] + bit * step(a);
                w *= if bit == 1 { frac[a] } else { 1.0 - frac[a] };
            }
            if w > 0.0 {
                acc += w * f64::from(self.values[self.index(c[0], c[1], c[2])]);
            }
        }
        acc as f32
    }

    /// The grid's largest extent along an axis (physical units).
    pub fn extent(&self) -> f64 {
        (0..3)
            .map(|a| (self.dims[a].saturating_sub(1)) as f64 * self.spacing[a])
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trilinear_reproduces_a_linear_field() {
        let mut g = Grid::filled([4, 5, 6], [1.0, 2.0, 3.0], [0.5, 1.0, 2.0], 0.0);
        for z in 0..6 {
            for y in 0..5 {
                for x in 0..4 {
                    let p = g.position(x, y, z);
                    let i = g.index(x, y, z);
                    g.values[i] = (p[0] + 2.0 * p[1] - p[2]) as f32;
                }
            }
        }
        let p = [1.7, 4.2, 8.1];
        assert!((g.trilinear(p) - (1.7 + 8.4 - 8.1) as f32).abs() < 1e-4);
    }
}
