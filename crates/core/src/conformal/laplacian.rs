//! The cotangent Laplacian.

use crate::mesh::{cross, dot, edge_key, norm, sub, Mesh};
use faer::sparse::{SparseColMat, SymbolicSparseColMat};

/// Symmetric edge weights `((i, j), w)` with `i < j`, sorted by edge.
pub(super) type EdgeWeights = Vec<((u32, u32), f64)>;

/// Cotangent of the angle at `o` in the triangle `o a b`, or `None` when the
/// triangle is degenerate (zero area relative to its edge lengths).
#[inline]
pub(crate) fn cot_at(o: [f64; 3], a: [f64; 3], b: [f64; 3]) -> Option<f64> {
    let u = sub(a, o);
    let v = sub(b, o);
    let s = norm(cross(u, v));
    let scale = dot(u, u).max(dot(v, v));
    if s.is_nan() || s <= 1e-14 * scale {
        return None;
    }
    Some(dot(u, v) / s)
}

/// Cotangent weights `w_ij = ½ (cot α_ij + cot β_ij)` of every edge, as
/// `((i, j), w)` with `i < j`, sorted by edge. Faces with an out-of-range
/// index or zero area contribute nothing.
///
/// A weight is negative when the angles opposite the edge sum to more than π
/// (the edge is not locally Delaunay).
pub fn cotangent_edge_weights(mesh: &Mesh) -> EdgeWeights {
    let n = mesh.vertices.len();
    let mut w = Vec::with_capacity(3 * mesh.faces.len());
    for f in &mesh.faces {
        if f.iter().any(|&v| v as usize >= n) {
            continue;
        }
        let p = f.map(|v| mesh.vertices[v as usize]);
        for k in 0..3 {
            let (i, j) = (f[(k + 1) % 3], f[(k + 2) % 3]);
            let c = cot_at(p[k], p[(k + 1) % 3], p[(k + 2) % 3]).unwrap_or(0.0);
            w.push((edge_key(i, j), 0.5 * c));
        }
    }
    sum_by_edge(w)
}

/// Sort `((i, j), w)` entries by edge and add up the weights of equal edges
/// (a stable sort, so the summation order, and the result, are
/// deterministic).
pub(crate) fn sum_by_edge(mut entries: EdgeWeights) -> EdgeWeights {
    entries.sort_by_key(|&(e, _)| e);
    let mut out: EdgeWeights = Vec::with_capacity(entries.len() / 2 + 1);
    for (e, w) in entries {
        match out.last_mut() {
            Some(last) if last.0 == e => last.1 += w,
            _ => out.push((e, w)),
        }
    }
    out
}

/// The weighted graph Laplacian of symmetric edge weights: `L_ij = w_ij`,
/// `L_ii = −Σ_j w_ij` (n × n, compressed sparse columns). Edges with an
/// index `≥ n` or a self-loop are ignored.
#[cfg(test)]
pub(crate) fn graph_laplacian(n: usize, weights: &[((u32, u32), f64)]) -> SparseColMat<usize, f64> {
    let mut cols: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
    let mut diag = vec![0.0; n];
    for &((i, j), w) in weights {
        let (i, j) = (i as usize, j as usize);
        if i >= n || j >= n || i == j {
            continue;
        }
        cols[j].push((i, w));
        cols[i].push((j, w));
        diag[i] -= w;
        diag[j] -= w;
    }
    for (j, c) in cols.iter_mut().enumerate() {
        c.push((j, diag[j]));
    }
    csc_from_columns(n, cols)
}

/// The stiffness matrix `−L + shift·I` of symmetric edge weights (`L` as in
/// [`graph_laplacian`]): positive definite for `shift > 0` and non-negative
/// weights, or for the cotangent weights of any planar triangulation
/// without flipped triangles.
pub(crate) fn shifted_stiffness(
    n: usize,
    weights: &[((u32, u32), f64)],
    shift: f64,
) -> SparseColMat<usize, f64> {
    let mut cols: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
    let mut diag = vec![shift; n];
    for &((i, j), w) in weights {
        let (i, j) = (i as usize, j as usize);
        if i >= n || j >= n || i == j {
            continue;
        }
        cols[j].push((i, -w));
        cols[i].push((j, -w));
        diag[i] += w;
        diag[j] += w;
    }
    for (j, c) in cols.iter_mut().enumerate() {
        c.push((j, diag[j]));
    }
    csc_from_columns(n, cols)
}

/// Assemble an `n × n` sparse matrix from per-column `(row, value)` lists
/// (duplicates summed, rows sorted). Rows must be `< n`.
pub(crate) fn csc_from_columns(
    n: usize,
    mut cols: Vec<Vec<(usize, f64)>>,
) -> SparseColMat<usize, f64> {
    let mut col_ptr = Vec::with_capacity(n + 1);
    let mut row_idx = Vec::new();
    let mut values = Vec::new();
    col_ptr.push(0usize);
    for c in cols.iter_mut() {
        c.sort_by_key(|&(r, _)| r);
        let mut last: Option<usize> = None;
        for &(r, v) in c.iter() {
            if last == Some(r) {
                if let Some(x) = values.last_mut() {
                    *x += v;
                }
            } else {
                row_idx.push(r);
                values.push(v);
                last = Some(r);
            }
        }
        col_ptr.push(row_idx.len());
    }
    let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
    SparseColMat::new(symbolic, values)
}

/// The cotangent Laplacian `L` (n × n, symmetric, negative semi-definite on
/// Delaunay meshes): `L_ij = w_ij` for each edge, `L_ii = −Σ_j w_ij`, with the
/// weights of [`cotangent_edge_weights`]. `(L x)_i` is the integral of the
/// Laplace–Beltrami operator of the piecewise-linear `x` over the dual cell
/// of vertex `i` (libigl's sign convention).
#[cfg(test)]
pub(crate) fn cotmatrix(mesh: &Mesh) -> SparseColMat<usize, f64> {
    graph_laplacian(mesh.vertices.len(), &cotangent_edge_weights(mesh))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cotmatrix_of_a_right_triangle_pair() {
        // Unit square split along 0-2: the diagonal has weight 0 (two right
        // angles opposite), the sides ½ cot 45° = ½.
        let m = Mesh::new(
            vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let l = cotmatrix(&m).to_dense();
        assert!((l[(0, 1)] - 0.5).abs() < 1e-12);
        assert!(l[(0, 2)].abs() < 1e-12);
        assert!((l[(0, 0)] + 1.0).abs() < 1e-12);
        // Linear functions are in the kernel away from the boundary and rows
        // sum to zero everywhere.
        for i in 0..4 {
            let s: f64 = (0..4).map(|j| l[(i, j)]).sum();
            assert!(s.abs() < 1e-12);
            for j in 0..4 {
                assert_eq!(l[(i, j)], l[(j, i)]);
            }
        }
    }
}
