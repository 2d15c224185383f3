//! A scalar field sampled on a regular grid: the volume at working
//! resolution, the phantoms the generators build, and the solids the
//! cleaning takes through a grid; the parity test of a closed surface's
//! inside and the Gaussian blur are defined here once.

use super::Mesh;
use rayon::prelude::*;

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

    /// Blur by a separable Gaussian of standard deviation `sigma` samples
    /// (clamped at the edges); nothing for `sigma ≤ 0`.
    pub fn gaussian_blur(&mut self, sigma: f64) {
        if sigma.is_nan() || sigma <= 0.0 {
            return;
        }
        let kernel = gaussian_kernel(sigma);
        if self.values.is_empty() {
            return;
        }
        let [nx, ny, _] = self.dims;
        // Along x a line is contiguous; along y and z a "line" of samples
        // is a whole row (y) or plane (z) at a time, which keeps the reads
        // sequential. Each sample's taps are summed in the same order as
        // by its definition, so the result does not depend on the layout.
        blur_lines(&mut self.values, 1, self.dims[0], &kernel);
        blur_lines(&mut self.values, nx, self.dims[1], &kernel);
        blur_lines(&mut self.values, nx * ny, self.dims[2], &kernel);
    }
}

/// The Gaussian of standard deviation `sigma` sampled at the integers
/// within 3σ (rounded up) of 0, normalized to sum 1.
fn gaussian_kernel(sigma: f64) -> Vec<f64> {
    let r = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f64 = kernel.iter().sum();
    kernel.iter().map(|k| k / sum).collect()
}

/// Convolve `values`, seen as blocks of `n` rows of `inner` samples, with
/// `kernel` (odd length, centred) along the rows of each block; outside a
/// block the edge row is repeated. Sample `(row p, column e)` becomes
/// `Σ_k kernel[k] · row(clamp(p + k − r))[e]`, summed in increasing `k`.
fn blur_lines(values: &mut [f32], inner: usize, n: usize, kernel: &[f64]) {
    let r = kernel.len() / 2;
    if n == 0 || inner == 0 {
        return;
    }
    let src = values.to_vec();
    let block = inner * n;
    if inner == 1 {
        // One line per block: padded into a buffer once, then each output
        // reads its neighbours without clamping.
        values
            .par_chunks_mut(block)
            .zip(src.par_chunks(block))
            .for_each_init(
                || Vec::with_capacity(n + 2 * r),
                |line, (out, inp)| {
                    line.clear();
                    line.extend(std::iter::repeat_n(f64::from(inp[0]), r));
                    line.extend(inp.iter().map(|&v| f64::from(v)));
                    line.extend(std::iter::repeat_n(f64::from(inp[n - 1]), r));
                    for (p, o) in out.iter_mut().enumerate() {
                        let mut acc = 0.0;
                        for (k, w) in kernel.iter().enumerate() {
                            acc += w * line[p + k];
                        }
                        *o = acc as f32;
                    }
                },
            );
        return;
    }
    values.par_chunks_mut(inner).enumerate().for_each_init(
        || vec![0.0f64; inner],
        |acc, (row, out)| {
            let (b, p) = (row / n, row % n);
            acc.iter_mut().for_each(|a| *a = 0.0);
            for (k, w) in kernel.iter().enumerate() {
                let j = (p + k).saturating_sub(r).min(n - 1);
                let from = &src[b * block + j * inner..][..inner];
                for (a, &v) in acc.iter_mut().zip(from) {
                    *a += w * f64::from(v);
                }
            }
            for (o, &a) in out.iter_mut().zip(acc.iter()) {
                *o = a as f32;
            }
        },
    );
}

/// Whether each sample of `grid` lies inside the closed surface `mesh`: the
/// crossings of the line of samples along `axis` through it, in parity
/// (the two other axes in cyclic order name the lines).
pub fn inside_by_parity(mesh: &Mesh, grid: &Grid, axis: usize) -> Vec<bool> {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let (n, nu, nv) = (grid.dims[axis], grid.dims[u], grid.dims[v]);
    // Faces binned by the lines (u, v) their projection may cover.
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); nu * nv];
    let line = |p: f64, a: usize| (p - grid.origin[a]) / grid.spacing[a];
    for (fi, f) in mesh.faces.iter().enumerate() {
        let ps = f.map(|i| mesh.vertices[i as usize]);
        let (ulo, uhi) = span(ps.map(|p| line(p[u], u)), nu);
        let (vlo, vhi) = span(ps.map(|p| line(p[v], v)), nv);
        for iv in vlo..vhi {
            for iu in ulo..uhi {
                bins[iu + nu * iv].push(fi as u32);
            }
        }
    }
    let lines: Vec<Vec<bool>> = (0..nu * nv)
        .into_par_iter()
        .map(|r| {
            let (iu, iv) = (r % nu, r / nu);
            // A tiny irrational offset keeps the line off edges and vertices.
            let pu = grid.origin[u] + iu as f64 * grid.spacing[u] + 1.234_567e-7 * grid.spacing[u];
            let pv = grid.origin[v] + iv as f64 * grid.spacing[v] + 2.345_678e-7 * grid.spacing[v];
            let mut ts: Vec<f64> = bins[r]
                .iter()
                .filter_map(|&fi| {
                    let t = mesh.faces[fi as usize].map(|i| mesh.vertices[i as usize]);
                    line_crossing(t, axis, pu, pv)
                })
                .collect();
            ts.sort_by(f64::total_cmp);
            let mut out = vec![false; n];
            for pair in ts.chunks_exact(2) {
                let lo = ((pair[0] - grid.origin[axis]) / grid.spacing[axis])
                    .ceil()
                    .max(0.0) as usize;
                let hi = ((pair[1] - grid.origin[axis]) / grid.spacing[axis]).floor();
                if hi < 0.0 {
                    continue;
                }
                for x in out.iter_mut().take((hi as usize + 1).min(n)).skip(lo) {
                    *x = true;
                }
            }
            out
        })
        .collect();
    let mut inside = vec![false; grid.values.len()];
    for (r, line) in lines.iter().enumerate() {
        let (iu, iv) = (r % nu, r / nu);
        for (i, &x) in line.iter().enumerate() {
            let mut c = [0usize; 3];
            c[axis] = i;
            c[u] = iu;
            c[v] = iv;
            inside[grid.index(c[0], c[1], c[2])] = x;
        }
    }
    inside
}

/// The samples `lo..hi` whose index lies within the range of `c`.
fn span(c: [f64; 3], n: usize) -> (usize, usize) {
    let lo = c.iter().copied().fold(f64::MAX, f64::min).ceil().max(0.0) as usize;
    let hi =
        (c.iter().copied().fold(f64::MIN, f64::max).floor() + 1.0).clamp(0.0, n as f64) as usize;
    (lo.min(n), hi)
}

/// Where the line along `axis` through (`pu`, `pv`) on the two other axes
/// crosses triangle `t`, if it does.
fn line_crossing(t: [[f64; 3]; 3], axis: usize, pu: f64, pv: f64) -> Option<f64> {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let [a, b, c] = t;
    let d = (b[u] - a[u]) * (c[v] - a[v]) - (c[u] - a[u]) * (b[v] - a[v]);
    if d.abs() < 1e-300 {
        return None;
    }
    let s = ((pu - a[u]) * (c[v] - a[v]) - (c[u] - a[u]) * (pv - a[v])) / d;
    let r = ((b[u] - a[u]) * (pv - a[v]) - (pu - a[u]) * (b[v] - a[v])) / d;
    (s >= 0.0 && r >= 0.0 && s + r <= 1.0)
        .then(|| a[axis] + s * (b[axis] - a[axis]) + r * (c[axis] - a[axis]))
}

/// Whether `p` lies inside the closed surface `mesh`: the parity of the
/// triangles a ray from `p` crosses, by majority over three skew
/// directions (a ray through an edge or a vertex may count a crossing
/// twice or not at all; three rarely all do).
pub(crate) fn point_inside_by_parity(mesh: &Mesh, p: [f64; 3]) -> bool {
    // Skew directions: along no axis, plane diagonal or each other.
    const DIRECTIONS: [[f64; 3]; 3] = [
        [0.8018, 0.5345, 0.2673],
        [-0.3015, 0.9045, -0.3015],
        [0.2357, -0.2357, 0.9428],
    ];
    let votes = DIRECTIONS
        .iter()
        .filter(|d| ray_crossings(mesh, p, **d) % 2 == 1)
        .count();
    votes >= 2
}

/// Triangles of `mesh` the ray `p + t d` (t > 0) crosses (Möller–Trumbore).
fn ray_crossings(mesh: &Mesh, p: [f64; 3], d: [f64; 3]) -> usize {
    use super::{cross, dot, sub};
    mesh.faces
        .iter()
        .filter(|f| {
            let [a, b, c] = f.map(|i| mesh.vertices[i as usize]);
            let (e1, e2) = (sub(b, a), sub(c, a));
            let h = cross(d, e2);
            let det = dot(e1, h);
            if det.abs() < 1e-300 {
                return false;
            }
            let s = sub(p, a);
            let u = dot(s, h) / det;
            if !(0.0..=1.0).contains(&u) {
                return false;
            }
            let q = cross(s, e1);
            let v = dot(d, q) / det;
            if v < 0.0 || u + v > 1.0 {
                return false;
            }
            dot(e2, q) / det > 0.0
        })
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The blur by its definition, one sample at a time.
    fn blurred_by_definition(grid: &Grid, sigma: f64) -> Vec<f32> {
        let kernel = gaussian_kernel(sigma);
        let r = (kernel.len() / 2) as i64;
        let dims = grid.dims;
        let strides = [1, dims[0], dims[0] * dims[1]];
        let mut values = grid.values.clone();
        for axis in 0..3 {
            let n = dims[axis] as i64;
            let src = values.clone();
            for (i, out) in values.iter_mut().enumerate() {
                let pos = ((i / strides[axis]) % dims[axis]) as i64;
                let mut acc = 0.0;
                for (k, w) in kernel.iter().enumerate() {
                    let j = (pos + k as i64 - r).clamp(0, n - 1);
                    acc +=
                        w * f64::from(src[(i as i64 + (j - pos) * strides[axis] as i64) as usize]);
                }
                *out = acc as f32;
            }
        }
        values
    }

    #[test]
    fn blur_is_its_definition_bit_for_bit() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        for (dims, sigma) in [
            ([1, 1, 1], 1.0),
            ([7, 1, 3], 0.7),
            ([1, 9, 2], 1.5),
            ([13, 11, 9], 1.5),
            ([20, 4, 31], 0.4),
        ] {
            let mut grid = Grid::filled(dims, [0.0; 3], [1.0; 3], 0.0);
            for v in &mut grid.values {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                *v = (state % 1000) as f32 / 7.0 - 50.0;
            }
            let expected = blurred_by_definition(&grid, sigma);
            grid.gaussian_blur(sigma);
            let same = grid
                .values
                .iter()
                .zip(&expected)
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "{dims:?}, sigma {sigma}");
        }
    }

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
