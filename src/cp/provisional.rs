//! A provisional conformal flattening onto the unit disk, used until the
//! `conformal` module provides one.
//!
//! Method: the boundary correspondence of the conformal map that sends a
//! central vertex `p` to 0 is the harmonic measure seen from `p`, i.e. the
//! flux of the Green's function with pole `p` through the boundary. Place
//! the boundary on the unit circle by that measure, then extend harmonically
//! (cotangent Laplacian): the real and imaginary parts of a conformal map
//! are harmonic, so this is the conformal map up to discretization.

use crate::mesh::{boundary_loops, Mesh};
use std::collections::BinaryHeap;

/// Why a surface could not be flattened.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum ProvisionalError {
    /// No boundary loop: not a disk-type surface.
    #[error("the surface has no boundary; a disk-type surface is needed")]
    NoBoundary,
    /// No interior vertex.
    #[error("the surface has no interior vertex")]
    NoInterior,
    /// The linear solver did not converge.
    #[error("the Laplace solve did not converge")]
    Solve,
}

/// Symmetric sparse matrix in adjacency form: off-diagonal cotangent
/// weights per vertex and the diagonal.
struct CotLaplacian {
    nbr: Vec<Vec<(u32, f64)>>,
    diag: Vec<f64>,
}

fn cotangent(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    // Cotangent of the angle at a.
    let u = crate::mesh::sub(b, a);
    let v = crate::mesh::sub(c, a);
    let cr = crate::mesh::norm(crate::mesh::cross(u, v));
    if cr < 1e-300 {
        0.0
    } else {
        crate::mesh::dot(u, v) / cr
    }
}

fn cot_laplacian(mesh: &Mesh) -> CotLaplacian {
    let n = mesh.vertices.len();
    let mut map: Vec<std::collections::BTreeMap<u32, f64>> = vec![Default::default(); n];
    for f in &mesh.faces {
        for k in 0..3 {
            let (i, j, o) = (f[k], f[(k + 1) % 3], f[(k + 2) % 3]);
            let w = 0.5
                * cotangent(
                    mesh.vertices[o as usize],
                    mesh.vertices[i as usize],
                    mesh.vertices[j as usize],
                );
            // Clamp slightly to keep the operator an M-matrix-like
            // positive definite system on poor triangles.
            let w = w.max(-0.2);
            *map[i as usize].entry(j).or_default() += w;
            *map[j as usize].entry(i).or_default() += w;
        }
    }
    let mut nbr = Vec::with_capacity(n);
    let mut diag = vec![0.0; n];
    for (i, m) in map.into_iter().enumerate() {
        let row: Vec<(u32, f64)> = m.into_iter().collect();
        diag[i] = row.iter().map(|(_, w)| w).sum();
        nbr.push(row);
    }
    CotLaplacian { nbr, diag }
}

/// Solve `L_II x = b` on the free vertices (`fixed[i]` false) by Jacobi
/// preconditioned conjugate gradients.
fn solve_free(l: &CotLaplacian, fixed: &[bool], b: &[f64]) -> Result<Vec<f64>, ProvisionalError> {
    let n = b.len();
    let apply = |x: &[f64], out: &mut [f64]| {
        for i in 0..n {
            if fixed[i] {
                out[i] = 0.0;
                continue;
            }
            let mut s = l.diag[i] * x[i];
            for &(j, w) in &l.nbr[i] {
                if !fixed[j as usize] {
                    s -= w * x[j as usize];
                }
            }
            out[i] = s;
        }
    };
    let inv: Vec<f64> = l
        .diag
        .iter()
        .map(|&d| if d > 0.0 { 1.0 / d } else { 1.0 })
        .collect();
    let mut x = vec![0.0; n];
    let mut r: Vec<f64> = (0..n).map(|i| if fixed[i] { 0.0 } else { b[i] }).collect();
    let bn = r.iter().map(|v| v * v).sum::<f64>().sqrt();
    if bn == 0.0 {
        return Ok(x);
    }
    let mut z: Vec<f64> = (0..n).map(|i| r[i] * inv[i]).collect();
    let mut p = z.clone();
    let mut rz: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
    let mut ap = vec![0.0; n];
    for _ in 0..20 * n.max(50) {
        apply(&p, &mut ap);
        let pap: f64 = p.iter().zip(&ap).map(|(a, b)| a * b).sum();
        if !(pap > 0.0) {
            return Err(ProvisionalError::Solve);
        }
        let alpha = rz / pap;
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        let rn = r.iter().map(|v| v * v).sum::<f64>().sqrt();
        if rn <= 1e-11 * bn {
            return Ok(x);
        }
        for i in 0..n {
            z[i] = r[i] * inv[i];
        }
        let rz_new: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
    }
    Err(ProvisionalError::Solve)
}

/// Geodesic (edge-path) distance from the sources to every vertex.
pub fn graph_distance(mesh: &Mesh, sources: &[u32]) -> Vec<f64> {
    let n = mesh.vertices.len();
    let adj = vertex_adjacency(mesh);
    let mut dist = vec![f64::INFINITY; n];
    let mut heap = BinaryHeap::new();
    for &s in sources {
        if let Some(d) = dist.get_mut(s as usize) {
            *d = 0.0;
            heap.push(HeapItem(0.0, s));
        }
    }
    while let Some(HeapItem(d, v)) = heap.pop() {
        if d > dist[v as usize] {
            continue;
        }
        for &u in &adj[v as usize] {
            let nd = d + crate::mesh::norm(crate::mesh::sub(
                mesh.vertices[v as usize],
                mesh.vertices[u as usize],
            ));
            if nd < dist[u as usize] {
                dist[u as usize] = nd;
                heap.push(HeapItem(nd, u));
            }
        }
    }
    dist
}

/// Sorted neighbour lists of every vertex.
pub fn vertex_adjacency(mesh: &Mesh) -> Vec<Vec<u32>> {
    let mut adj: Vec<Vec<u32>> = vec![Vec::new(); mesh.vertices.len()];
    for f in &mesh.faces {
        for k in 0..3 {
            let (a, b) = (f[k] as usize, f[(k + 1) % 3] as usize);
            if a < adj.len() && b < adj.len() {
                adj[a].push(b as u32);
                adj[b].push(a as u32);
            }
        }
    }
    for a in &mut adj {
        a.sort_unstable();
        a.dedup();
    }
    adj
}

/// Min-heap entry (distance, vertex), ties by vertex index.
#[derive(PartialEq)]
pub(crate) struct HeapItem(pub f64, pub u32);
impl Eq for HeapItem {}
impl PartialOrd for HeapItem {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for HeapItem {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}

/// Flatten a disk-type mesh conformally onto the unit disk. Returns the
/// disk coordinates of every vertex and the central vertex sent near 0.
pub fn flatten_to_disk(mesh: &Mesh) -> Result<(Vec<[f64; 2]>, u32), ProvisionalError> {
    let n = mesh.vertices.len();
    let loops = boundary_loops(mesh);
    let boundary = loops.first().ok_or(ProvisionalError::NoBoundary)?;
    if boundary.len() < 3 {
        return Err(ProvisionalError::NoBoundary);
    }
    let mut fixed = vec![false; n];
    for &b in boundary {
        fixed[b as usize] = true;
    }
    // Centre: the vertex farthest from the boundary (ties: smallest index).
    let dist = graph_distance(mesh, boundary);
    let mut center = None;
    for (i, &d) in dist.iter().enumerate() {
        if !fixed[i] && d.is_finite() && center.is_none_or(|(_, bd)| d > bd) {
            center = Some((i, d));
        }
    }
    let (center, _) = center.ok_or(ProvisionalError::NoInterior)?;
    let lap = cot_laplacian(mesh);
    // Green's function with pole at the centre, zero on the boundary.
    let mut rhs = vec![0.0; n];
    rhs[center] = 1.0;
    let green = solve_free(&lap, &fixed, &rhs)?;
    // Flux through each boundary vertex = harmonic measure.
    let mut flux: Vec<f64> = boundary
        .iter()
        .map(|&b| {
            lap.nbr[b as usize]
                .iter()
                .filter(|(j, _)| !fixed[*j as usize])
                .map(|&(j, w)| w * green[j as usize])
                .sum::<f64>()
        })
        .collect();
    let total: f64 = flux.iter().map(|f| f.max(0.0)).sum();
    if !(total > 0.0) {
        return Err(ProvisionalError::Solve);
    }
    let floor = 1e-3 * total / boundary.len() as f64;
    for f in &mut flux {
        *f = f.max(floor);
    }
    let total: f64 = flux.iter().sum();
    let mut uv = vec![[0.0; 2]; n];
    let mut acc = 0.0;
    for (&b, &f) in boundary.iter().zip(&flux) {
        let t = (acc + 0.5 * f) / total * std::f64::consts::TAU;
        uv[b as usize] = [t.cos(), t.sin()];
        acc += f;
    }
    // Harmonic extension of the boundary values.
    for d in 0..2 {
        let mut rhs = vec![0.0; n];
        for &b in boundary {
            for &(j, w) in &lap.nbr[b as usize] {
                if !fixed[j as usize] {
                    rhs[j as usize] += w * uv[b as usize][d];
                }
            }
        }
        let x = solve_free(&lap, &fixed, &rhs)?;
        for i in 0..n {
            if !fixed[i] {
                uv[i][d] = x[i];
            }
        }
    }
    // Keep every vertex in the closed disk.
    for p in &mut uv {
        let r = p[0].hypot(p[1]);
        if !r.is_finite() {
            return Err(ProvisionalError::Solve);
        }
        if r > 1.0 {
            *p = [p[0] / r, p[1] / r];
        }
    }
    Ok((uv, center as u32))
}
