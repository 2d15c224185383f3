//! Closest point on a triangle mesh, accelerated with a uniform grid of
//! triangle buckets.

use crate::mesh::{dot, norm, points_bounding_box, sub, Mesh};
use rustc_hash::FxHashMap as HashMap;

/// The closest point of `p` on the triangle `abc` (Ericson, Real-Time
/// Collision Detection, 5.1.5: Voronoi regions of the vertices and edges).
fn closest_point_on_triangle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return lerp(a, ab, v);
    }
    let cp = sub(p, c);
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return lerp(a, ac, w);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return lerp(b, sub(c, b), w);
    }
    let denom = va + vb + vc;
    if denom.abs() <= f64::MIN_POSITIVE {
        // Degenerate triangle that fell through every region test.
        return a;
    }
    let v = vb / denom;
    let w = vc / denom;
    [
        a[0] + ab[0] * v + ac[0] * w,
        a[1] + ab[1] * v + ac[1] * w,
        a[2] + ab[2] * v + ac[2] * w,
    ]
}

#[inline]
fn lerp(a: [f64; 3], d: [f64; 3], t: f64) -> [f64; 3] {
    [a[0] + d[0] * t, a[1] + d[1] * t, a[2] + d[2] * t]
}

/// A closest-point query result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosestPoint {
    /// The closest point on the surface.
    pub point: [f64; 3],
    /// Its Euclidean distance to the query point.
    pub distance: f64,
    /// Index of the face that contains it.
    pub face: u32,
}

/// Uniform grid over the bounding box of a triangle mesh; each cell lists the
/// triangles whose bounding boxes overlap it. Queries search cells in shells
/// of growing Chebyshev radius until no closer triangle can exist.
#[derive(Debug, Clone)]
pub struct TriangleGrid {
    vertices: Vec<[f64; 3]>,
    faces: Vec<[u32; 3]>,
    origin: [f64; 3],
    cell: f64,
    dims: [i64; 3],
    cells: HashMap<[i64; 3], Vec<u32>>,
}

impl TriangleGrid {
    /// Build the grid; the cell size is about the mean edge length times 2.
    /// Returns `None` for a mesh without faces.
    pub fn new(mesh: &Mesh) -> Option<Self> {
        if mesh.faces.is_empty() {
            return None;
        }
        let nv = mesh.vertices.len();
        if mesh.faces.iter().flatten().any(|&v| v as usize >= nv) {
            return None;
        }
        let mut edge_sum = 0.0;
        for f in &mesh.faces {
            for k in 0..3 {
                let p = mesh.vertices[f[k] as usize];
                edge_sum += norm(sub(p, mesh.vertices[f[(k + 1) % 3] as usize]));
            }
        }
        // The box of the vertices faces use (unreferenced ones are no
        // candidates); there is one, the faces are not empty.
        let (lo, hi) = points_bounding_box(
            mesh.faces
                .iter()
                .flatten()
                .map(|&v| mesh.vertices[v as usize]),
        )?;
        let diag = norm(sub(hi, lo));
        let mean_edge = edge_sum / (3 * mesh.faces.len()) as f64;
        // Cap the number of cells at about 64 per face.
        let min_cell = diag / (64.0 * mesh.faces.len() as f64).cbrt().max(1.0);
        let cell = (2.0 * mean_edge).max(min_cell).max(diag * 1e-9).max(1e-300);
        let dims = [0, 1, 2].map(|d| (((hi[d] - lo[d]) / cell).floor() as i64 + 1).max(1));
        let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::default();
        for (fi, f) in mesh.faces.iter().enumerate() {
            let ps = f.map(|v| mesh.vertices[v as usize]);
            let mut flo = [0i64; 3];
            let mut fhi = [0i64; 3];
            for d in 0..3 {
                let mn = ps[0][d].min(ps[1][d]).min(ps[2][d]);
                let mx = ps[0][d].max(ps[1][d]).max(ps[2][d]);
                flo[d] = (((mn - lo[d]) / cell).floor() as i64).clamp(0, dims[d] - 1);
                fhi[d] = (((mx - lo[d]) / cell).floor() as i64).clamp(0, dims[d] - 1);
            }
            for i in flo[0]..=fhi[0] {
                for j in flo[1]..=fhi[1] {
                    for k in flo[2]..=fhi[2] {
                        cells.entry([i, j, k]).or_default().push(fi as u32);
                    }
                }
            }
        }
        Some(Self {
            vertices: mesh.vertices.clone(),
            faces: mesh.faces.clone(),
            origin: lo,
            cell,
            dims,
            cells,
        })
    }

    /// The closest point of the surface to `p` (of equally close faces,
    /// the one of lowest index).
    pub fn closest_point(&self, p: [f64; 3]) -> ClosestPoint {
        self.closest_point_within(p, f64::INFINITY)
            .unwrap_or(ClosestPoint {
                point: p,
                distance: f64::INFINITY,
                face: 0,
            })
    }

    /// The closest point of the surface to `p` if it lies nearer than
    /// `limit` (as [`Self::closest_point`] finds it); the search stops at
    /// that distance.
    pub fn closest_point_within(&self, p: [f64; 3], limit: f64) -> Option<ClosestPoint> {
        let c = [0, 1, 2].map(|d| ((p[d] - self.origin[d]) / self.cell).floor() as i64);
        // A query outside the grid starts from the nearest cell in it.
        let cc = [0, 1, 2].map(|d| c[d].clamp(0, self.dims[d] - 1));
        let max_r = (0..3).map(|d| self.dims[d]).max().unwrap_or(1) + 1;
        let mut best = ClosestPoint {
            point: p,
            distance: f64::INFINITY,
            face: 0,
        };
        for r in 0..=max_r {
            self.for_each_shell_cell(cc, r, |cell| {
                // A cell farther than the best face so far holds no closer
                // face (the slack covers rounding in the cell's bounds); the
                // test is cheaper than the lookup, and deep inside a solid
                // most cells of the outer shells are skipped by it.
                if self.cell_distance(p, cell) > best.distance.min(limit) * (1.0 + 1e-9) {
                    return;
                }
                let Some(list) = self.cells.get(&cell) else {
                    return;
                };
                for &fi in list {
                    let f = self.faces[fi as usize];
                    let q = closest_point_on_triangle(
                        p,
                        self.vertices[f[0] as usize],
                        self.vertices[f[1] as usize],
                        self.vertices[f[2] as usize],
                    );
                    let d = norm(sub(q, p));
                    if d < best.distance || (d == best.distance && fi < best.face) {
                        best = ClosestPoint {
                            point: q,
                            distance: d,
                            face: fi,
                        };
                    }
                }
            });
            // Everything outside the shells searched so far is at least this
            // far from p (distance from p to the searched box's faces).
            let mut reach = f64::INFINITY;
            for d in 0..3 {
                let lo = self.origin[d] + (cc[d] - r) as f64 * self.cell;
                let hi = self.origin[d] + (cc[d] + r + 1) as f64 * self.cell;
                reach = reach.min((p[d] - lo).max(0.0)).min((hi - p[d]).max(0.0));
            }
            if best.distance.min(limit) <= reach {
                break;
            }
        }
        (best.distance < limit).then_some(best)
    }

    /// Call `visit` on each cell of the grid at Chebyshev distance exactly
    /// `r` from the cell `cc` (cells outside the grid hold no faces and are
    /// left out).
    fn for_each_shell_cell(&self, cc: [i64; 3], r: i64, mut visit: impl FnMut([i64; 3])) {
        let range = |d: usize| (cc[d] - r).max(0)..=(cc[d] + r).min(self.dims[d] - 1);
        for i in range(0) {
            for j in range(1) {
                if (i - cc[0]).abs() == r || (j - cc[1]).abs() == r {
                    for k in range(2) {
                        visit([i, j, k]);
                    }
                } else {
                    // Inside the shell's i–j square (so r > 0): only its
                    // two k faces.
                    for k in [cc[2] - r, cc[2] + r] {
                        if (0..self.dims[2]).contains(&k) {
                            visit([i, j, k]);
                        }
                    }
                }
            }
        }
    }

    /// Distance from `p` to the box of `cell`.
    fn cell_distance(&self, p: [f64; 3], cell: [i64; 3]) -> f64 {
        let mut s = 0.0;
        for d in 0..3 {
            let lo = self.origin[d] + cell[d] as f64 * self.cell;
            let hi = lo + self.cell;
            let g = (lo - p[d]).max(p[d] - hi).max(0.0);
            s += g * g;
        }
        s.sqrt()
    }

    /// Distance from `p` to the surface.
    pub fn distance(&self, p: [f64; 3]) -> f64 {
        self.closest_point(p).distance
    }
}

/// Distance from each point to the surface of `mesh` (empty when the mesh has
/// no faces).
pub fn point_to_surface_distances(points: &[[f64; 3]], mesh: &Mesh) -> Vec<f64> {
    match TriangleGrid::new(mesh) {
        Some(g) => points.iter().map(|&p| g.distance(p)).collect(),
        None => Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(p: [f64; 3], m: &Mesh) -> f64 {
        m.faces
            .iter()
            .map(|f| {
                let q = closest_point_on_triangle(
                    p,
                    m.vertices[f[0] as usize],
                    m.vertices[f[1] as usize],
                    m.vertices[f[2] as usize],
                );
                norm(sub(q, p))
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn triangle_regions() {
        let (a, b, c) = ([0., 0., 0.], [1., 0., 0.], [0., 1., 0.]);
        let q = closest_point_on_triangle([0.2, 0.2, 5.], a, b, c);
        assert!(norm(sub(q, [0.2, 0.2, 0.])) < 1e-12);
        assert_eq!(closest_point_on_triangle([-1., -1., 0.], a, b, c), a);
        assert_eq!(
            closest_point_on_triangle([0.5, -2., 1.], a, b, c),
            [0.5, 0., 0.]
        );
        let q = closest_point_on_triangle([1., 1., 0.], a, b, c);
        assert!(norm(sub(q, [0.5, 0.5, 0.])) < 1e-12);
    }

    #[test]
    fn grid_matches_brute_force() {
        // A wavy height field, queried at points near and far.
        let n = 20;
        let mut v = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let (x, y) = (i as f64 / 10.0, j as f64 / 10.0);
                v.push([x, y, (3.0 * x).sin() * (2.0 * y).cos() * 0.3]);
            }
        }
        let mut f = Vec::new();
        for i in 0..n - 1 {
            for j in 0..n - 1 {
                let a = (i * n + j) as u32;
                f.push([a, a + n as u32, a + 1]);
                f.push([a + 1, a + n as u32, a + n as u32 + 1]);
            }
        }
        let m = Mesh::new(v, f);
        let g = TriangleGrid::new(&m).expect("grid");
        for s in 0..200 {
            let t = s as f64;
            let p = [
                (t * 0.37).sin() * 2.5 + 1.0,
                (t * 0.73).cos() * 2.5 + 1.0,
                (t * 0.11).sin() * 1.5,
            ];
            let d = g.distance(p);
            assert!((d - brute(p, &m)).abs() < 1e-12, "{p:?}");
        }
    }

    /// The face found is the nearest of lowest index, as a search of every
    /// face finds it, for points inside a closed surface (where the
    /// search skips far cells) and outside it.
    #[test]
    fn grid_finds_the_face_a_search_of_all_faces_finds() {
        let m = crate::testing::synth::closed_sphere(2000);
        let g = TriangleGrid::new(&m).expect("grid");
        for s in 0..400 {
            let t = s as f64;
            let r = 0.05 + 1.4 * ((t * 0.61).sin() * 0.5 + 0.5);
            let dir = [(t * 0.37).sin(), (t * 0.73).cos(), (t * 0.11).sin() - 0.3];
            let n = norm(dir);
            let p = dir.map(|x| x / n * r);
            let found = g.closest_point(p);
            let (mut bd, mut bf) = (f64::INFINITY, 0u32);
            for (fi, f) in m.faces.iter().enumerate() {
                let q = closest_point_on_triangle(
                    p,
                    m.vertices[f[0] as usize],
                    m.vertices[f[1] as usize],
                    m.vertices[f[2] as usize],
                );
                let d = norm(sub(q, p));
                if d < bd {
                    (bd, bf) = (d, fi as u32);
                }
            }
            assert_eq!((found.distance, found.face), (bd, bf), "{p:?}");
            // Searched only as far as a limit: the same face when nearer.
            let within = g.closest_point_within(p, 0.1);
            let expected = (bd < 0.1).then_some((bd, bf));
            assert_eq!(within.map(|c| (c.distance, c.face)), expected, "{p:?}");
        }
    }
}
