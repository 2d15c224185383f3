//! Point location in a triangulation of the unit disk: a uniform grid over
//! `[-1, 1]²` whose cells list the triangles overlapping them, so that a
//! query costs O(1) on a well-shaped mesh.

use serde::{Deserialize, Serialize};

/// A point located in a triangulation: the triangle and the barycentric
/// coordinates (non-negative, summing to 1) of the point in it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Location {
    /// Index of the triangle.
    pub face: u32,
    /// Barycentric coordinates with respect to the triangle's vertices.
    pub bary: [f64; 3],
}

/// Bucketing of the triangles of a planar triangulation of the disk.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LocateGrid {
    /// Cells per side.
    pub resolution: u32,
    /// Compressed rows: triangles of cell `k` are
    /// `items[starts[k]..starts[k + 1]]`.
    pub starts: Vec<u32>,
    /// Triangle indices, cell after cell.
    pub items: Vec<u32>,
}

/// Barycentric coordinates of `p` in the triangle `abc` (unclamped); `None`
/// for a degenerate triangle.
#[inline]
pub fn barycentric(p: [f64; 2], a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> Option<[f64; 3]> {
    let d = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
    if d.abs() < 1e-300 {
        return None;
    }
    let l1 = ((p[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (p[1] - a[1])) / d;
    let l2 = ((b[0] - a[0]) * (p[1] - a[1]) - (p[0] - a[0]) * (b[1] - a[1])) / d;
    Some([1.0 - l1 - l2, l1, l2])
}

impl LocateGrid {
    /// Bucket the triangles `faces` of the planar positions `uv`; the grid
    /// has about four cells per triangle (short lists where triangles are small).
    pub fn build(uv: &[[f64; 2]], faces: &[[u32; 3]]) -> Self {
        let resolution = ((2.0 * (faces.len() as f64).sqrt()).ceil() as u32).clamp(1, 2048);
        let n = resolution as usize;
        let cell_range = |lo: f64, hi: f64| -> (usize, usize) {
            (
                Self::cell_coord(lo, resolution),
                Self::cell_coord(hi, resolution),
            )
        };
        let mut counts = vec![0u32; n * n + 1];
        let bbox = |f: &[u32; 3]| -> Option<([f64; 2], [f64; 2])> {
            let p = [
                uv.get(f[0] as usize)?,
                uv.get(f[1] as usize)?,
                uv.get(f[2] as usize)?,
            ];
            let lo = [
                p[0][0].min(p[1][0]).min(p[2][0]),
                p[0][1].min(p[1][1]).min(p[2][1]),
            ];
            let hi = [
                p[0][0].max(p[1][0]).max(p[2][0]),
                p[0][1].max(p[1][1]).max(p[2][1]),
            ];
            Some((lo, hi))
        };
        for f in faces {
            if let Some((lo, hi)) = bbox(f) {
                let (x0, x1) = cell_range(lo[0], hi[0]);
                let (y0, y1) = cell_range(lo[1], hi[1]);
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        counts[y * n + x + 1] += 1;
                    }
                }
            }
        }
        for k in 1..counts.len() {
            counts[k] += counts[k - 1];
        }
        let starts = counts;
        let mut fill = starts.clone();
        let mut items = vec![0u32; starts[n * n] as usize];
        for (fi, f) in faces.iter().enumerate() {
            if let Some((lo, hi)) = bbox(f) {
                let (x0, x1) = cell_range(lo[0], hi[0]);
                let (y0, y1) = cell_range(lo[1], hi[1]);
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        let k = y * n + x;
                        items[fill[k] as usize] = fi as u32;
                        fill[k] += 1;
                    }
                }
            }
        }
        Self {
            resolution,
            starts,
            items,
        }
    }

    #[inline]
    fn cell_coord(t: f64, resolution: u32) -> usize {
        let r = resolution as f64;
        let k = ((t + 1.0) * 0.5 * r).floor();
        if k.is_nan() {
            0
        } else {
            k.clamp(0.0, r - 1.0) as usize
        }
    }

    #[inline]
    fn cell(&self, x: usize, y: usize) -> &[u32] {
        let k = y * self.resolution as usize + x;
        match (self.starts.get(k), self.starts.get(k + 1)) {
            (Some(&s), Some(&e)) => self.items.get(s as usize..e as usize).unwrap_or(&[]),
            _ => &[],
        }
    }

    /// Locate `p`: the triangle containing it, or, for a point outside the
    /// triangulation (e.g. between the polygonal boundary and the unit
    /// circle), the nearby triangle it is least outside of, with clamped
    /// barycentric coordinates. `None` only for an empty triangulation.
    pub fn locate(&self, uv: &[[f64; 2]], faces: &[[u32; 3]], p: [f64; 2]) -> Option<Location> {
        let n = self.resolution as usize;
        let cx = Self::cell_coord(p[0], self.resolution);
        let cy = Self::cell_coord(p[1], self.resolution);
        let mut best: Option<(f64, u32, [f64; 3])> = None;
        // Search rings of cells around p until some candidate is found.
        for ring in 0..n {
            let (x0, x1) = (cx.saturating_sub(ring), (cx + ring).min(n - 1));
            let (y0, y1) = (cy.saturating_sub(ring), (cy + ring).min(n - 1));
            for y in y0..=y1 {
                for x in x0..=x1 {
                    if ring > 0 && x != x0 && x != x1 && y != y0 && y != y1 {
                        continue;
                    }
                    for &fi in self.cell(x, y) {
                        let Some(f) = faces.get(fi as usize) else {
                            continue;
                        };
                        let (Some(&a), Some(&b), Some(&c)) = (
                            uv.get(f[0] as usize),
                            uv.get(f[1] as usize),
                            uv.get(f[2] as usize),
                        ) else {
                            continue;
                        };
                        let Some(l) = barycentric(p, a, b, c) else {
                            continue;
                        };
                        let m = l[0].min(l[1]).min(l[2]);
                        if m >= -1e-12 {
                            return Some(Location {
                                face: fi,
                                bary: clamp_barycentric(l),
                            });
                        }
                        let (d, l) = closest_on_triangle(p, [a, b, c]);
                        // Ties broken by the smaller triangle index.
                        if best.is_none_or(|(bd, bf, _)| d < bd || (d == bd && fi < bf)) {
                            best = Some((d, fi, l));
                        }
                    }
                }
            }
            if best.is_some() && ring >= 1 {
                break;
            }
        }
        best.map(|(_, face, bary)| Location { face, bary })
    }
}

/// Squared distance from `p` to the triangle `t` and the barycentric
/// coordinates of the closest point (searched on the edges: call it for
/// points outside the triangle).
fn closest_on_triangle(p: [f64; 2], t: [[f64; 2]; 3]) -> (f64, [f64; 3]) {
    let mut best = (f64::INFINITY, [1.0, 0.0, 0.0]);
    for k in 0..3 {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        let e = [b[0] - a[0], b[1] - a[1]];
        let len2 = e[0] * e[0] + e[1] * e[1];
        let s = if len2 > 0.0 {
            (((p[0] - a[0]) * e[0] + (p[1] - a[1]) * e[1]) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = [a[0] + s * e[0], a[1] + s * e[1]];
        let d = (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2);
        if d < best.0 {
            let mut l = [0.0; 3];
            l[k] = 1.0 - s;
            l[(k + 1) % 3] = s;
            best = (d, l);
        }
    }
    best
}

/// Clamp barycentric coordinates to be non-negative and renormalize.
#[inline]
pub fn clamp_barycentric(l: [f64; 3]) -> [f64; 3] {
    let c = [l[0].max(0.0), l[1].max(0.0), l[2].max(0.0)];
    let s = c[0] + c[1] + c[2];
    if s > 0.0 {
        [c[0] / s, c[1] / s, c[2] / s]
    } else {
        [1.0 / 3.0; 3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fan triangulation of a regular polygon inscribed in the circle,
    /// with concentric rings.
    fn disk(rings: usize, sectors: usize) -> (Vec<[f64; 2]>, Vec<[u32; 3]>) {
        let mut uv = vec![[0.0, 0.0]];
        for r in 1..=rings {
            for s in 0..sectors {
                let t = s as f64 / sectors as f64 * std::f64::consts::TAU;
                let rad = r as f64 / rings as f64;
                uv.push([rad * t.cos(), rad * t.sin()]);
            }
        }
        let idx = |r: usize, s: usize| -> u32 {
            if r == 0 {
                0
            } else {
                (1 + (r - 1) * sectors + s % sectors) as u32
            }
        };
        let mut faces = Vec::new();
        for s in 0..sectors {
            faces.push([idx(0, 0), idx(1, s), idx(1, s + 1)]);
        }
        for r in 1..rings {
            for s in 0..sectors {
                faces.push([idx(r, s), idx(r + 1, s), idx(r + 1, s + 1)]);
                faces.push([idx(r, s), idx(r + 1, s + 1), idx(r, s + 1)]);
            }
        }
        (uv, faces)
    }

    #[test]
    fn locates_interior_points_exactly() {
        let (uv, faces) = disk(8, 24);
        let grid = LocateGrid::build(&uv, &faces);
        for k in 0..200 {
            let t = k as f64 * 0.37;
            let r = 0.95 * ((k * 7919) % 100) as f64 / 100.0;
            let p = [r * t.cos(), r * t.sin()];
            let loc = grid.locate(&uv, &faces, p).expect("located");
            let f = faces[loc.face as usize];
            let q = [0, 1].map(|d| {
                (0..3)
                    .map(|i| loc.bary[i] * uv[f[i] as usize][d])
                    .sum::<f64>()
            });
            assert!((q[0] - p[0]).abs() < 1e-12 && (q[1] - p[1]).abs() < 1e-12);
            assert!(loc.bary.iter().all(|&b| b >= 0.0));
        }
    }

    #[test]
    fn snaps_points_just_outside_to_a_boundary_triangle() {
        let (uv, faces) = disk(8, 24);
        let grid = LocateGrid::build(&uv, &faces);
        // Midway between two boundary vertices, on the unit circle.
        let t = 0.5 / 24.0 * std::f64::consts::TAU;
        let p = [t.cos(), t.sin()];
        let loc = grid.locate(&uv, &faces, p).expect("located");
        let f = faces[loc.face as usize];
        let q = [0, 1].map(|d| {
            (0..3)
                .map(|i| loc.bary[i] * uv[f[i] as usize][d])
                .sum::<f64>()
        });
        // The snapped point is on the polygon, close to p.
        let gap = (q[0] - p[0]).hypot(q[1] - p[1]);
        assert!(gap < 0.01, "{gap} {f:?} {:?}", loc.bary);
        assert!(f.iter().any(|&v| v as usize > 7 * 24));
    }
}
