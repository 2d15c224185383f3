//! Intrinsic Delaunay triangulation (Bobenko–Springborn): edge flips on the
//! metric given by the edge lengths, until every interior edge is locally
//! Delaunay. The cotangent weights of the result are non-negative, and its
//! Laplacian discretizes the same piecewise-flat surface as the input.

use super::laplacian::{sum_by_edge, EdgeWeights};
use super::FlattenError;
use crate::mesh::{edge_face_map, edge_key, norm, sub, Mesh};

/// A triangulation of the input's vertices by intrinsic triangles: face
/// corners plus the length of each half-edge `3f + k` (from corner `k` to
/// corner `k + 1`).
struct IntrinsicMesh {
    faces: Vec<[u32; 3]>,
    twin: Vec<Option<usize>>,
    length: Vec<f64>,
    /// Number of edges at each vertex.
    degree: Vec<u32>,
    /// Fewest edges each vertex may keep: 3 inside, 2 on the boundary.
    min_degree: Vec<u32>,
}

/// Sum of the cotangents of the two angles opposite half-edge `h` and its
/// twin (twice the cotangent weight); `None` for a boundary edge.
fn cot_sum(m: &IntrinsicMesh, h: usize) -> Option<f64> {
    let t = m.twin[h]?;
    Some(opposite_cot(m, h) + opposite_cot(m, t))
}

/// Cotangent of the angle of `h`'s face opposite `h`.
fn opposite_cot(m: &IntrinsicMesh, h: usize) -> f64 {
    let f = h / 3;
    let k = h % 3;
    let a = m.length[h];
    let b = m.length[3 * f + (k + 1) % 3];
    let c = m.length[3 * f + (k + 2) % 3];
    cot_from_lengths(a, b, c)
}

/// Cotangent of the angle opposite side `a` in a triangle with sides `a, b,
/// c`; 0 when the triangle is degenerate.
pub(crate) fn cot_from_lengths(a: f64, b: f64, c: f64) -> f64 {
    let area = triangle_area_from_lengths(a, b, c);
    if area.is_nan() || area <= 0.0 {
        return 0.0;
    }
    (b * b + c * c - a * a) / (4.0 * area)
}

/// Heron's formula in its numerically stable form (sides sorted).
fn triangle_area_from_lengths(a: f64, b: f64, c: f64) -> f64 {
    let mut s = [a, b, c];
    s.sort_by(|x, y| y.total_cmp(x));
    let [a, b, c] = s;
    let p = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c));
    if p.is_nan() || p <= 0.0 {
        0.0
    } else {
        0.25 * p.sqrt()
    }
}

impl IntrinsicMesh {
    /// From a mesh whose faces have valid indices.
    fn new(mesh: &Mesh) -> Self {
        let nf = mesh.faces.len();
        let nv = mesh.vertices.len();
        let mut length = vec![0.0; 3 * nf];
        for (f, face) in mesh.faces.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (face[k], face[(k + 1) % 3]);
                length[3 * f + k] = norm(sub(mesh.vertices[a as usize], mesh.vertices[b as usize]));
            }
        }
        // Twins: the two half-edges of an interior edge. Count each edge
        // once in the degrees; boundary vertices may keep two edges.
        let mut twin = vec![None; 3 * nf];
        let mut degree = vec![0u32; nv];
        let mut min_degree = vec![3u32; nv];
        let edges = edge_face_map(mesh);
        for e in 0..edges.len() {
            let (a, b) = edges.edge(e);
            let (a, b) = (a as usize, b as usize);
            degree[a] += 1;
            degree[b] += 1;
            let start = |h: u32| mesh.faces[h as usize / 3][h as usize % 3];
            match *edges.half_edges_of(e) {
                [h0, h1] if start(h0) != start(h1) => {
                    twin[h0 as usize] = Some(h1 as usize);
                    twin[h1 as usize] = Some(h0 as usize);
                }
                _ => {
                    min_degree[a] = 2;
                    min_degree[b] = 2;
                }
            }
        }
        Self {
            faces: mesh.faces.clone(),
            twin,
            length,
            degree,
            min_degree,
        }
    }

    /// Flip the interior edge `h` (with twin `t`). Faces `(a, b, c)` and
    /// `(b, a, d)` become `(d, b, c)` and `(c, a, d)`. Returns false (and
    /// does nothing) when the flip is impossible or would leave `a` or `b`
    /// with fewer than three edges (two on the boundary): such a vertex
    /// would end up inside a
    /// self-folded triangle, where the harmonic map squeezes it onto a
    /// neighbour and the input's faces around it degenerate.
    fn flip(&mut self, h: usize, t: usize) -> bool {
        let (f0, k0) = (h / 3, h % 3);
        let (f1, k1) = (t / 3, t % 3);
        if f0 == f1 {
            return false;
        }
        let [a, b, c] = [0, 1, 2].map(|i| self.faces[f0][(k0 + i) % 3]);
        let d = self.faces[f1][(k1 + 2) % 3];
        if c == d
            || self.degree[a as usize] <= self.min_degree[a as usize]
            || self.degree[b as usize] <= self.min_degree[b as usize]
        {
            return false;
        }
        let h1 = 3 * f0 + (k0 + 1) % 3; // b → c
        let h2 = 3 * f0 + (k0 + 2) % 3; // c → a
        let t1 = 3 * f1 + (k1 + 1) % 3; // a → d
        let t2 = 3 * f1 + (k1 + 2) % 3; // d → b
        let (l_ab, l_bc, l_ca) = (self.length[h], self.length[h1], self.length[h2]);
        let (l_ad, l_db) = (self.length[t1], self.length[t2]);
        // Unfold the two triangles into the plane: a at 0, b on the x axis,
        // c above, d below; the new edge is |c − d|.
        let cx = (l_ab * l_ab + l_ca * l_ca - l_bc * l_bc) / (2.0 * l_ab);
        let cy = (l_ca * l_ca - cx * cx).max(0.0).sqrt();
        let dx = (l_ab * l_ab + l_ad * l_ad - l_db * l_db) / (2.0 * l_ab);
        let dy = -(l_ad * l_ad - dx * dx).max(0.0).sqrt();
        let l_cd = (cx - dx).hypot(cy - dy);
        if !(l_cd.is_finite() && l_cd > 0.0) {
            return false;
        }
        let outer = [
            (self.twin[t2], l_db),
            (self.twin[h1], l_bc),
            (self.twin[h2], l_ca),
            (self.twin[t1], l_ad),
        ];
        self.faces[f0] = [d, b, c];
        self.faces[f1] = [c, a, d];
        // New half-edges: f0: d→b, b→c, c→d; f1: c→a, a→d, d→c.
        let slots = [3 * f0, 3 * f0 + 1, 3 * f1, 3 * f1 + 1];
        for (&slot, &(tw, len)) in slots.iter().zip(&outer) {
            self.twin[slot] = tw;
            self.length[slot] = len;
            if let Some(o) = tw {
                self.twin[o] = Some(slot);
            }
        }
        self.twin[3 * f0 + 2] = Some(3 * f1 + 2);
        self.twin[3 * f1 + 2] = Some(3 * f0 + 2);
        self.length[3 * f0 + 2] = l_cd;
        self.length[3 * f1 + 2] = l_cd;
        self.degree[a as usize] -= 1;
        self.degree[b as usize] -= 1;
        self.degree[c as usize] += 1;
        self.degree[d as usize] += 1;
        true
    }

    /// Flip non-Delaunay edges until none is left (or a generous flip budget
    /// is spent, which only happens through rounding). Returns the number of
    /// flips.
    fn make_delaunay(&mut self) -> usize {
        let nh = self.length.len();
        let mut queued = vec![true; nh];
        let mut stack: Vec<usize> = (0..nh).rev().collect();
        let budget = 50 * nh + 100;
        let mut flips = 0;
        while let Some(h) = stack.pop() {
            queued[h] = false;
            let Some(t) = self.twin[h] else { continue };
            let Some(s) = cot_sum(self, h) else { continue };
            if s >= -1e-12 {
                continue;
            }
            if flips >= budget || !self.flip(h, t) {
                continue;
            }
            flips += 1;
            let (f0, f1) = (h / 3, t / 3);
            for e in [3 * f0, 3 * f0 + 1, 3 * f1, 3 * f1 + 1] {
                if !queued[e] {
                    queued[e] = true;
                    stack.push(e);
                }
            }
        }
        flips
    }

    /// Cotangent weights `½ Σ cot` per vertex pair (parallel edges summed,
    /// loops dropped), sorted by pair.
    fn edge_weights(&self) -> EdgeWeights {
        let mut w = Vec::with_capacity(self.length.len());
        for (f, face) in self.faces.iter().enumerate() {
            for k in 0..3 {
                let (i, j) = (face[k], face[(k + 1) % 3]);
                if i == j {
                    continue;
                }
                w.push((edge_key(i, j), 0.5 * opposite_cot(self, 3 * f + k)));
            }
        }
        sum_by_edge(w)
    }
}

/// Cotangent edge weights of the intrinsic Delaunay triangulation of `mesh`
/// (non-negative up to rounding), as `((i, j), w)` with `i < j`, sorted,
/// and the number of edge flips it took. Flips that would leave a vertex
/// with fewer than three edges are skipped, so a few weights may stay
/// negative next to such vertices.
///
/// The mesh should be manifold and consistently oriented (as
/// [`check_disk_topology`](super::check_disk_topology) ensures); faces with
/// out-of-range indices are an error.
pub(crate) fn intrinsic_delaunay_weights(
    mesh: &Mesh,
) -> Result<(EdgeWeights, usize), FlattenError> {
    let n = mesh.vertices.len();
    if let Some(face) = mesh
        .faces
        .iter()
        .position(|f| f.iter().any(|&v| v as usize >= n))
    {
        return Err(FlattenError::InvalidFace {
            face,
            reason: format!("vertex index out of range (mesh has {n} vertices)"),
        });
    }
    let mut m = IntrinsicMesh::new(mesh);
    let flips = m.make_delaunay();
    Ok((m.edge_weights(), flips))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conformal::cotangent_edge_weights;

    #[test]
    fn flat_quad_flips_to_the_delaunay_diagonal() {
        // A flat rhombus split along its long diagonal: the two angles
        // opposite it are obtuse, so it must flip to the short one.
        let m = Mesh::new(
            vec![[0., 0., 0.], [4., 0., 0.], [2., 1., 0.], [2., -1., 0.]],
            vec![[0, 1, 2], [1, 0, 3]],
        );
        let raw = cotangent_edge_weights(&m);
        assert!(raw.iter().any(|&(_, w)| w < 0.0));
        let (w, flips) = intrinsic_delaunay_weights(&m).unwrap();
        assert_eq!(flips, 1);
        assert!(w.iter().all(|&(_, x)| x >= 0.0));
        assert!(w.iter().any(|&(e, _)| e == (2, 3)));
        assert!(!w.iter().any(|&(e, _)| e == (0, 1)));
        // In the plane the intrinsic and extrinsic Delaunay weights agree:
        // the short diagonal's weight is ½ (cot α + cot β) with the angles at
        // 0 and 1, whose cotangent is 2·2/... computed directly:
        let flipped = Mesh::new(m.vertices.clone(), vec![[3, 1, 2], [2, 0, 3]]);
        let direct = cotangent_edge_weights(&flipped);
        for (a, b) in w.iter().zip(&direct) {
            assert_eq!(a.0, b.0);
            assert!((a.1 - b.1).abs() < 1e-12);
        }
    }
}
