//! Point location in a triangulation of the unit disk: a uniform grid over
//! `[-1, 1]²` whose cells list the triangles overlapping them, so that a
//! query costs O(1) on a well-shaped mesh; and, for a query near a known
//! triangle, a walk across triangle edges that touches only a few
//! triangles (the grid's lists are too large to stay in cache).

use crate::mesh::triangle_adjacency;
pub(super) use crate::mesh::NO_TRIANGLE;
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
pub(super) struct LocateGrid {
    /// Cells per side.
    pub resolution: u32,
    /// Compressed rows: triangles of cell `k` are
    /// `items[starts[k]..starts[k + 1]]`.
    pub starts: Vec<u32>,
    /// Triangle indices, cell after cell.
    pub items: Vec<u32>,
    /// For each triangle, the triangle across the edge opposite each of its
    /// corners ([`NO_TRIANGLE`] on the boundary); see [`triangle_adjacency`].
    pub adjacency: Vec<[u32; 3]>,
    /// The boundary edges in order of polar angle, to place points that
    /// fall between the boundary polygon and the unit circle.
    pub rim: Vec<RimEdge>,
    /// Points closer to the origin than this are inside the boundary
    /// polygon (its distance to the nearest boundary edge line).
    pub rim_radius: f64,
}

/// A boundary edge of a disk triangulation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub(super) struct RimEdge {
    /// Polar angle, in `[-π, π)`, where the edge's arc starts (going
    /// counter-clockwise).
    pub start: f64,
    /// The triangle the edge belongs to.
    pub face: u32,
    /// The corner of that triangle opposite the edge.
    pub corner: u8,
}

/// How far outside a triangle (in barycentric coordinates) a point may lie
/// and still count as inside it, clamped onto its edge. Rounding puts a
/// point that is exactly on a vertex of a tiny triangle (a feature point
/// mapped onto a feature point, where the disk is most compressed) up to
/// about 1e-16 / (triangle size) outside every triangle around it.
const INSIDE: f64 = 1e-9;

/// Longest walk tried before falling back to the grid: a hint farther than
/// this is no better than none.
const MAX_WALK: usize = 64;

/// The boundary edges of a disk triangulation (edges with no triangle
/// across, from `adjacency`) sorted by the polar angle where each edge's
/// arc starts, and the distance from the origin to the nearest edge line.
/// The rim is only usable when the boundary is inscribed in the unit
/// circle (so the polygon is convex and the slivers outside it are the
/// edges' circular segments); otherwise it is empty with an infinite
/// radius, which turns it off.
fn rim_edges(uv: &[[f64; 2]], faces: &[[u32; 3]], adjacency: &[[u32; 3]]) -> (Vec<RimEdge>, f64) {
    let mut rim = Vec::new();
    let mut radius = f64::INFINITY;
    for (fi, (f, next)) in faces.iter().zip(adjacency).enumerate() {
        for k in 0..3 {
            if next[k] != NO_TRIANGLE {
                continue;
            }
            let (Some(&a), Some(&b)) = (
                uv.get(f[(k + 1) % 3] as usize),
                uv.get(f[(k + 2) % 3] as usize),
            ) else {
                continue;
            };
            if (a[0].hypot(a[1]) - 1.0).abs() > 1e-6 || (b[0].hypot(b[1]) - 1.0).abs() > 1e-6 {
                return (Vec::new(), f64::INFINITY);
            }
            let (alpha, beta) = (a[1].atan2(a[0]), b[1].atan2(b[0]));
            // The arc spanned by the edge is the shorter way round.
            let ccw = (beta - alpha).rem_euclid(std::f64::consts::TAU);
            let start = if ccw <= std::f64::consts::PI {
                alpha
            } else {
                beta
            };
            let len = (b[0] - a[0]).hypot(b[1] - a[1]);
            if len > 0.0 {
                radius = radius.min((a[0] * b[1] - a[1] * b[0]).abs() / len);
            }
            rim.push(RimEdge {
                start,
                face: fi as u32,
                corner: k as u8,
            });
        }
    }
    rim.sort_by(|x, y| x.start.total_cmp(&y.start).then(x.face.cmp(&y.face)));
    if rim.len() < 3 {
        return (Vec::new(), f64::INFINITY);
    }
    (rim, radius)
}

/// Barycentric coordinates of `p` in the triangle `abc` (unclamped); `None`
/// for a degenerate triangle.
#[inline]
pub(super) fn barycentric(p: [f64; 2], a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> Option<[f64; 3]> {
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
    /// has about one cell per triangle. Finer grids were measured no
    /// faster (most queries walk instead) and cost memory: the large
    /// triangles near the boundary fall in many cells each.
    pub(super) fn build(uv: &[[f64; 2]], faces: &[[u32; 3]]) -> Self {
        let resolution = ((faces.len() as f64).sqrt().ceil() as u32).clamp(1, 2048);
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
        let adjacency = triangle_adjacency(faces);
        let (rim, rim_radius) = rim_edges(uv, faces, &adjacency);
        Self {
            resolution,
            starts,
            items,
            adjacency,
            rim,
            rim_radius,
        }
    }

    /// Whether the grid fits a triangulation of `faces` triangles: its
    /// cells, triangle lists and adjacency are consistent and refer to
    /// those triangles only (e.g. after reading a cached copy).
    pub(super) fn fits(&self, faces: usize) -> bool {
        let r = self.resolution as usize;
        let in_range = |f: u32| (f as usize) < faces;
        self.starts.len() == r * r + 1
            && self.starts.last().map(|&s| s as usize) == Some(self.items.len())
            && self.items.iter().all(|&f| in_range(f))
            && self.adjacency.len() == faces
            && self
                .adjacency
                .iter()
                .flatten()
                .all(|&f| f == NO_TRIANGLE || in_range(f))
    }

    /// For a point outside the boundary polygon (in the sliver between an
    /// edge and the unit circle): the nearest point of the edge whose arc
    /// holds it. `None` for a point inside, or one the sorted rim cannot
    /// place (the grid search handles those).
    fn locate_on_rim(&self, uv: &[[f64; 2]], faces: &[[u32; 3]], p: [f64; 2]) -> Option<Location> {
        if p[0] * p[0] + p[1] * p[1] < self.rim_radius * self.rim_radius {
            return None;
        }
        let theta = p[1].atan2(p[0]);
        let i = self.rim.partition_point(|e| e.start <= theta);
        let edge = if i == 0 {
            self.rim.last()?
        } else {
            self.rim.get(i - 1)?
        };
        let f = faces.get(edge.face as usize)?;
        let k = edge.corner as usize % 3;
        let corner = |j: usize| uv.get(f[(k + j) % 3] as usize).copied();
        let (c, a, b) = (corner(0)?, corner(1)?, corner(2)?);
        if barycentric(p, c, a, b)?[0] >= -INSIDE {
            return None;
        }
        let e = [b[0] - a[0], b[1] - a[1]];
        let len2 = e[0] * e[0] + e[1] * e[1];
        let t = if len2 > 0.0 {
            (((p[0] - a[0]) * e[0] + (p[1] - a[1]) * e[1]) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let mut bary = [0.0; 3];
        bary[(k + 1) % 3] = 1.0 - t;
        bary[(k + 2) % 3] = t;
        Some(Location {
            face: edge.face,
            bary,
        })
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
    pub(super) fn locate(
        &self,
        uv: &[[f64; 2]],
        faces: &[[u32; 3]],
        p: [f64; 2],
    ) -> Option<Location> {
        if let Some(l) = self.locate_on_rim(uv, faces, p) {
            return Some(l);
        }
        let n = self.resolution as usize;
        let cx = Self::cell_coord(p[0], self.resolution);
        let cy = Self::cell_coord(p[1], self.resolution);
        let corners = |fi: u32| -> Option<[[f64; 2]; 3]> {
            let f = faces.get(fi as usize)?;
            Some([
                *uv.get(f[0] as usize)?,
                *uv.get(f[1] as usize)?,
                *uv.get(f[2] as usize)?,
            ])
        };
        // A point inside the triangulation is in a triangle of its cell.
        for &fi in self.cell(cx, cy) {
            let Some([a, b, c]) = corners(fi) else {
                continue;
            };
            if let Some(l) = barycentric(p, a, b, c) {
                if l[0].min(l[1]).min(l[2]) >= -INSIDE {
                    return Some(Location {
                        face: fi,
                        bary: clamp_barycentric(l),
                    });
                }
            }
        }
        // Otherwise: the nearest triangle, searched in rings of cells
        // around p until some candidate is found.
        let mut best: Option<(f64, u32, [f64; 3])> = None;
        for ring in 0..n {
            let (x0, x1) = (cx.saturating_sub(ring), (cx + ring).min(n - 1));
            let (y0, y1) = (cy.saturating_sub(ring), (cy + ring).min(n - 1));
            for y in y0..=y1 {
                for x in x0..=x1 {
                    if ring > 0 && x != x0 && x != x1 && y != y0 && y != y1 {
                        continue;
                    }
                    for &fi in self.cell(x, y) {
                        let Some(t) = corners(fi) else {
                            continue;
                        };
                        let (d, l) = closest_on_triangle(p, t);
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

impl LocateGrid {
    /// Locate `p` as [`LocateGrid::locate`] does, starting with a walk
    /// from the triangle `hint` (for a point known to be near it, e.g. the
    /// image of a neighbouring vertex). Each step crosses the edge that `p`
    /// is farthest beyond; a walk that leaves the triangulation or runs
    /// long falls back to the grid, and so does a `hint` of
    /// [`NO_TRIANGLE`] (no hint) at once.
    pub(super) fn locate_near(
        &self,
        uv: &[[f64; 2]],
        faces: &[[u32; 3]],
        p: [f64; 2],
        hint: u32,
    ) -> Option<Location> {
        let mut face = hint;
        for _ in 0..MAX_WALK {
            let (Some(f), Some(next)) =
                (faces.get(face as usize), self.adjacency.get(face as usize))
            else {
                break;
            };
            let (Some(&a), Some(&b), Some(&c)) = (
                uv.get(f[0] as usize),
                uv.get(f[1] as usize),
                uv.get(f[2] as usize),
            ) else {
                break;
            };
            // Twice the signed areas of the triangles p makes with each
            // edge: the barycentric coordinates times twice the area, so
            // the test needs no division until p is found.
            let area = |u: [f64; 2], v: [f64; 2]| {
                (u[0] - p[0]) * (v[1] - p[1]) - (v[0] - p[0]) * (u[1] - p[1])
            };
            let mut w = [area(b, c), area(c, a), area(a, b)];
            let d = w[0] + w[1] + w[2];
            if d.is_nan() || d.abs() <= 1e-300 {
                break;
            }
            if d < 0.0 {
                w = w.map(|x| -x);
            }
            let k = if w[0] <= w[1] && w[0] <= w[2] {
                0
            } else if w[1] <= w[2] {
                1
            } else {
                2
            };
            if w[k] >= -INSIDE * d.abs() {
                let d = d.abs();
                return Some(Location {
                    face,
                    bary: clamp_barycentric(w.map(|x| x / d)),
                });
            }
            if next[k] == NO_TRIANGLE {
                break;
            }
            face = next[k];
        }
        self.locate(uv, faces, p)
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
fn clamp_barycentric(l: [f64; 3]) -> [f64; 3] {
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

    /// The point of the triangulation at a location.
    fn point_at(uv: &[[f64; 2]], faces: &[[u32; 3]], loc: Location) -> [f64; 2] {
        let f = faces[loc.face as usize];
        [0, 1].map(|d| {
            (0..3)
                .map(|i| loc.bary[i] * uv[f[i] as usize][d])
                .sum::<f64>()
        })
    }

    /// The `k`-th of a scattered set of points within `radius` of 0.
    fn probe(k: usize, radius: f64) -> [f64; 2] {
        let t = k as f64 * 0.37;
        let r = radius * ((k * 7919) % 100) as f64 / 100.0;
        [r * t.cos(), r * t.sin()]
    }

    #[test]
    fn locates_interior_points_exactly() {
        let (uv, faces) = disk(8, 24);
        let grid = LocateGrid::build(&uv, &faces);
        for k in 0..200 {
            let p = probe(k, 0.95);
            let loc = grid.locate(&uv, &faces, p).expect("located");
            let q = point_at(&uv, &faces, loc);
            assert!((q[0] - p[0]).abs() < 1e-12 && (q[1] - p[1]).abs() < 1e-12);
            assert!(loc.bary.iter().all(|&b| b >= 0.0));
        }
    }

    #[test]
    fn adjacency_pairs_the_triangles_sharing_each_edge() {
        let (_, faces) = disk(3, 6);
        let adj = triangle_adjacency(&faces);
        let mut boundary = 0;
        for (f, nb) in adj.iter().enumerate() {
            for k in 0..3 {
                let edge = [faces[f][(k + 1) % 3], faces[f][(k + 2) % 3]];
                if nb[k] == NO_TRIANGLE {
                    boundary += 1;
                    continue;
                }
                let g = faces[nb[k] as usize];
                assert!(edge.iter().all(|v| g.contains(v)), "{f} {k}");
                assert!(adj[nb[k] as usize].contains(&(f as u32)));
            }
        }
        // The outer ring of a 6-sector disk has 6 edges.
        assert_eq!(boundary, 6);
    }

    #[test]
    fn a_walk_from_any_hint_finds_the_triangle_the_grid_finds() {
        let (uv, faces) = disk(8, 24);
        let grid = LocateGrid::build(&uv, &faces);
        for k in 0..300 {
            let p = probe(k, 1.02);
            let hint = ((k * 31) % faces.len()) as u32;
            let a = grid.locate(&uv, &faces, p).expect("grid");
            let b = grid.locate_near(&uv, &faces, p, hint).expect("walk");
            let (qa, qb) = (point_at(&uv, &faces, a), point_at(&uv, &faces, b));
            assert!((qa[0] - qb[0]).hypot(qa[1] - qb[1]) < 1e-12, "{p:?}");
        }
    }

    #[test]
    fn points_in_the_rim_slivers_snap_to_their_edge() {
        let (uv, faces) = disk(4, 12);
        let grid = LocateGrid::build(&uv, &faces);
        assert_eq!(grid.rim.len(), 12);
        for k in 0..120 {
            // Just inside the unit circle, mostly outside the polygon.
            let t = -3.0 + k as f64 * 0.05;
            let p = [0.999_999 * t.cos(), 0.999_999 * t.sin()];
            let loc = grid.locate(&uv, &faces, p).expect("located");
            let q = point_at(&uv, &faces, loc);
            // The nearest point of the polygon is at most the sagitta of a
            // 30° chord away.
            let gap = (q[0] - p[0]).hypot(q[1] - p[1]);
            let sagitta = 1.0 - (std::f64::consts::PI / 12.0).cos();
            assert!(gap <= sagitta + 1e-9, "{t}: {gap}");
            // And it is on a boundary edge, or p is inside the polygon.
            let on_rim = (0..3)
                .any(|c| grid.adjacency[loc.face as usize][c] == NO_TRIANGLE && loc.bary[c] == 0.0);
            assert!(on_rim || gap < 1e-12, "{t}: not on the rim");
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
        let q = point_at(&uv, &faces, loc);
        // The snapped point is on the polygon, close to p.
        let gap = (q[0] - p[0]).hypot(q[1] - p[1]);
        assert!(gap < 0.01, "{gap} {f:?} {:?}", loc.bary);
        assert!(f.iter().any(|&v| v as usize > 7 * 24));
    }
}
