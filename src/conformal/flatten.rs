//! Conformal map of a disk-type surface onto the unit disk.

use super::cholesky::SpdFactor;
use super::intrinsic::intrinsic_delaunay_weights;
use super::laplacian::{cotangent_edge_weights, csc_from_columns, EdgeWeights};
use super::quality::flipped_triangles;
use super::validate::check_disk_topology;
use super::FlattenError;
use crate::mesh::{norm, sub, Mesh};
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// A surface flattened onto the closed unit disk.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DiskMap {
    /// Disk coordinates of every vertex: boundary vertices on the unit
    /// circle, interior vertices strictly inside.
    pub uv: Vec<[f64; 2]>,
    /// The vertex mapped to the origin.
    pub center: u32,
}

/// Conformal map of a clean, disk-type, consistently oriented mesh onto the
/// unit disk, with its [`central_vertex`] at 0.
///
/// Counter-clockwise faces stay counter-clockwise in the disk (the map
/// preserves orientation), so a reflected copy of a surface gives a
/// reflected map. The rotation is fixed by putting the boundary vertex with
/// the smallest index at angle 0 of the harmonic-measure parametrization.
///
/// Method: the discrete Green's function `u` of the cotangent Laplacian with
/// unit source at the centre and `u = 0` on the boundary gives, through its
/// flux across the boundary, the harmonic measure of the boundary seen from
/// the centre; cumulated along the boundary loop it is the angle of each
/// boundary vertex under the conformal map sending the centre to 0. The
/// interior is then the harmonic (cotangent) extension of those boundary
/// positions, solved with the same Cholesky factor. The cotangent weights
/// are those of the intrinsic Delaunay triangulation, which are
/// non-negative, so that Tutte's theorem (the boundary polygon is convex)
/// rules out fold-overs; should a face of the input still come out flipped,
/// the extrinsic cotangent weights with negative ones raised to a small
/// positive floor are used instead. A final Möbius transformation puts the
/// centre exactly at 0.
///
/// Errors: the mesh is not a clean disk (see [`FlattenError`]), has
/// degenerate faces, the solve fails, or the result has flipped triangles.
pub fn flatten_to_disk(mesh: &Mesh) -> Result<DiskMap, FlattenError> {
    match flatten_to_disk_with(mesh, LaplacianWeights::IntrinsicDelaunay) {
        Err(FlattenError::Flipped { .. }) => {
            flatten_to_disk_with(mesh, LaplacianWeights::ClampedCotangent)
        }
        other => other,
    }
}

/// Which cotangent weights the harmonic problems of [`flatten_to_disk_with`]
/// use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LaplacianWeights {
    /// Cotangent weights of the intrinsic Delaunay triangulation (edge flips
    /// on the edge lengths; non-negative by construction): the accurate
    /// choice.
    IntrinsicDelaunay,
    /// Cotangent weights of the mesh itself with negative ones raised to a
    /// small positive floor: always an embedding, slightly less conformal
    /// near obtuse triangles.
    ClampedCotangent,
}

/// [`flatten_to_disk`] with a given choice of Laplacian and no fallback.
pub fn flatten_to_disk_with(
    mesh: &Mesh,
    weights: LaplacianWeights,
) -> Result<DiskMap, FlattenError> {
    let boundary = check_disk_topology(mesh)?;
    check_faces_nondegenerate(mesh)?;
    let center = central_vertex(mesh, &boundary).ok_or_else(|| FlattenError::Degenerate {
        reason: "no interior vertex to use as the centre".into(),
    })?;
    let w = match weights {
        LaplacianWeights::IntrinsicDelaunay => {
            positive_weights(intrinsic_delaunay_weights(mesh).0, INTRINSIC_FLOOR)
        }
        LaplacianWeights::ClampedCotangent => {
            positive_weights(cotangent_edge_weights(mesh), CLAMPED_FLOOR)
        }
    };
    let mut uv = harmonic_disk_map(&mesh.vertices, &boundary, center, &w)?;
    center_by_mobius(&mut uv, center as usize, &boundary);
    if uv.iter().any(|z| !(z[0].is_finite() && z[1].is_finite())) {
        return Err(FlattenError::Solve {
            reason: "non-finite disk coordinates".into(),
        });
    }
    let count = flipped_triangles(&mesh.faces, &uv);
    if count > 0 {
        return Err(FlattenError::Flipped { count });
    }
    Ok(DiskMap { uv, center })
}

/// Floor of the intrinsic Delaunay weights relative to their mean: only
/// (nearly) co-circular edges, whose weight is zero up to rounding, reach it.
const INTRINSIC_FLOOR: f64 = 1e-6;

/// Floor of the clamped extrinsic cotangent weights relative to their mean.
const CLAMPED_FLOOR: f64 = 1e-3;

/// Fail on faces whose area is zero relative to their edge lengths.
fn check_faces_nondegenerate(mesh: &Mesh) -> Result<(), FlattenError> {
    for (fi, f) in mesh.faces.iter().enumerate() {
        let p = f.map(|v| mesh.vertices[v as usize]);
        let e = [sub(p[1], p[0]), sub(p[2], p[1]), sub(p[0], p[2])];
        let longest = e.iter().map(|&x| norm(x)).fold(0.0, f64::max);
        let twice_area = norm(crate::mesh::cross(e[0], e[1]));
        if twice_area.is_nan() || twice_area <= 1e-12 * longest * longest {
            return Err(FlattenError::Degenerate {
                reason: format!("face {fi} has (almost) zero area"),
            });
        }
    }
    Ok(())
}

/// Raise non-positive edge weights to a small fraction of the mean absolute
/// weight: with all weights positive the harmonic extension onto a convex
/// boundary is an embedding (Tutte, Floater).
fn positive_weights(mut weights: EdgeWeights, relative_floor: f64) -> EdgeWeights {
    let mean = weights.iter().map(|&(_, w)| w.abs()).sum::<f64>() / weights.len().max(1) as f64;
    let floor = relative_floor * mean;
    for (_, w) in weights.iter_mut() {
        if w.is_nan() || *w < floor {
            *w = floor;
        }
    }
    weights
}

/// The most central interior vertex: farthest from the boundary in
/// graph-geodesic distance (Dijkstra along edges with Euclidean lengths).
/// Distances within a relative 1e-9 of the maximum count as ties, broken
/// by the smallest index, so the choice does not change under rigid motions
/// and scaling. `None` when every vertex is on the boundary.
pub fn central_vertex(mesh: &Mesh, boundary: &[u32]) -> Option<u32> {
    let n = mesh.vertices.len();
    let adj = vertex_adjacency(mesh);
    let mut dist = vec![f64::INFINITY; n];
    let mut heap = BinaryHeap::new();
    for &b in boundary {
        if let Some(d) = dist.get_mut(b as usize) {
            *d = 0.0;
            heap.push(HeapItem(0.0, b));
        }
    }
    while let Some(HeapItem(d, v)) = heap.pop() {
        let v = v as usize;
        if d > dist[v] {
            continue;
        }
        for &u in &adj[v] {
            let nd = d + norm(sub(mesh.vertices[v], mesh.vertices[u as usize]));
            if nd < dist[u as usize] {
                dist[u as usize] = nd;
                heap.push(HeapItem(nd, u));
            }
        }
    }
    let max = dist
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .fold(0.0, f64::max);
    if max <= 0.0 {
        return None;
    }
    dist.iter()
        .position(|&d| d.is_finite() && d >= max * (1.0 - 1e-9))
        .map(|v| v as u32)
}

/// Min-heap entry (distance, vertex) for Dijkstra.
struct HeapItem(f64, u32);

impl PartialEq for HeapItem {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for HeapItem {}
impl PartialOrd for HeapItem {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for HeapItem {
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .0
            .total_cmp(&self.0)
            .then_with(|| other.1.cmp(&self.1))
    }
}

/// Sorted, deduplicated neighbour lists (indices assumed valid).
fn vertex_adjacency(mesh: &Mesh) -> Vec<Vec<u32>> {
    let n = mesh.vertices.len();
    let mut adj: Vec<Vec<u32>> = vec![Vec::new(); n];
    for f in &mesh.faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            if (a as usize) < n && (b as usize) < n {
                adj[a as usize].push(b);
                adj[b as usize].push(a);
            }
        }
    }
    for l in adj.iter_mut() {
        l.sort_unstable();
        l.dedup();
    }
    adj
}

/// Disk coordinates from symmetric positive edge weights: boundary angles
/// from the harmonic measure seen from `center`, interior by harmonic
/// extension. Both solves share one factorization of the interior block.
fn harmonic_disk_map(
    positions: &[[f64; 3]],
    boundary: &[u32],
    center: u32,
    weights: &[((u32, u32), f64)],
) -> Result<Vec<[f64; 2]>, FlattenError> {
    let n = positions.len();
    // Interior numbering.
    let mut interior_index: Vec<Option<usize>> = vec![Some(0); n];
    for &b in boundary {
        interior_index[b as usize] = None;
    }
    let mut m = 0;
    for slot in interior_index.iter_mut() {
        if slot.is_some() {
            *slot = Some(m);
            m += 1;
        }
    }
    let pc = interior_index[center as usize].ok_or_else(|| FlattenError::Degenerate {
        reason: "the centre vertex is on the boundary".into(),
    })?;

    // K_II = −L_II (positive definite for positive weights and a connected
    // mesh with a boundary).
    let mut cols: Vec<Vec<(usize, f64)>> = vec![Vec::new(); m];
    let mut diag = vec![0.0; m];
    for &((i, j), w) in weights {
        let (ii, jj) = (interior_index[i as usize], interior_index[j as usize]);
        if let Some(a) = ii {
            diag[a] += w;
        }
        if let Some(b) = jj {
            diag[b] += w;
        }
        if let (Some(a), Some(b)) = (ii, jj) {
            // Lower triangle only: that is the side the factorization reads.
            let (r, c) = if a > b { (a, b) } else { (b, a) };
            cols[c].push((r, -w));
        }
    }
    for (j, c) in cols.iter_mut().enumerate() {
        c.push((j, diag[j]));
    }
    let factor = SpdFactor::new(&csc_from_columns(m, cols))?;

    // Green's function with unit source at the centre.
    let mut green = vec![vec![0.0; m]];
    green[0][pc] = 1.0;
    factor.solve_columns(&mut green)?;
    let u = &green[0];

    // Flux through each boundary vertex = its harmonic measure.
    let mut flux = vec![0.0; n];
    for &((i, j), w) in weights {
        match (interior_index[i as usize], interior_index[j as usize]) {
            (None, Some(b)) => flux[i as usize] += w * u[b],
            (Some(a), None) => flux[j as usize] += w * u[a],
            _ => {}
        }
    }
    let flux_total: f64 = boundary.iter().map(|&b| flux[b as usize].max(0.0)).sum();
    if !(flux_total.is_finite() && flux_total > 0.0) {
        return Err(FlattenError::Solve {
            reason: format!("harmonic measure of the boundary is {flux_total}"),
        });
    }
    // A boundary vertex with no interior neighbour (the tip of an "ear"
    // triangle whose three vertices are all on the boundary) has zero flux;
    // two such neighbours would land on the same point of the circle. Give
    // every boundary vertex at least a fraction of its share by boundary
    // length, which keeps the boundary polygon strictly convex.
    let dual_length = boundary_dual_lengths(positions, boundary);
    let length_total: f64 = dual_length.iter().sum();
    let omega: Vec<f64> = boundary
        .iter()
        .zip(&dual_length)
        .map(|(&b, &l)| {
            let share = if length_total > 0.0 {
                l / length_total
            } else {
                1.0 / boundary.len() as f64
            };
            flux[b as usize].max(MIN_MEASURE_SHARE * share * flux_total)
        })
        .collect();
    let total: f64 = omega.iter().sum();
    let mut uv = vec![[0.0; 2]; n];
    let mut acc = 0.0;
    for (&b, &w) in boundary.iter().zip(&omega) {
        let theta = std::f64::consts::TAU * (acc + 0.5 * w) / total;
        acc += w;
        uv[b as usize] = [theta.cos(), theta.sin()];
    }

    // Harmonic extension of the boundary positions.
    let mut rhs = vec![vec![0.0; m], vec![0.0; m]];
    for &((i, j), w) in weights {
        let (a, b) = (i as usize, j as usize);
        match (interior_index[a], interior_index[b]) {
            (Some(ia), None) => {
                rhs[0][ia] += w * uv[b][0];
                rhs[1][ia] += w * uv[b][1];
            }
            (None, Some(ib)) => {
                rhs[0][ib] += w * uv[a][0];
                rhs[1][ib] += w * uv[a][1];
            }
            _ => {}
        }
    }
    factor.solve_columns(&mut rhs)?;
    for (v, slot) in interior_index.iter().enumerate() {
        if let Some(k) = *slot {
            uv[v] = [rhs[0][k], rhs[1][k]];
        }
    }
    Ok(uv)
}

/// Smallest share of the harmonic measure a boundary vertex gets, as a
/// fraction of its share by boundary length.
const MIN_MEASURE_SHARE: f64 = 0.1;

/// Half the length of the two boundary edges at each boundary vertex.
fn boundary_dual_lengths(positions: &[[f64; 3]], boundary: &[u32]) -> Vec<f64> {
    let k = boundary.len();
    let edge = |i: usize| {
        norm(sub(
            positions[boundary[i] as usize],
            positions[boundary[(i + 1) % k] as usize],
        ))
    };
    (0..k)
        .map(|i| 0.5 * (edge((i + k - 1) % k) + edge(i)))
        .collect()
}

/// Apply the disk automorphism `z ↦ (z − a)/(1 − ā z)`, `a = uv[center]`,
/// which sends the centre to 0, and put the boundary back exactly on the
/// unit circle.
fn center_by_mobius(uv: &mut [[f64; 2]], center: usize, boundary: &[u32]) {
    let Some(&a) = uv.get(center) else { return };
    let r2 = a[0] * a[0] + a[1] * a[1];
    if r2.is_nan() || r2 >= 1.0 {
        return;
    }
    for z in uv.iter_mut() {
        // numerator z − a, denominator 1 − ā z
        let num = [z[0] - a[0], z[1] - a[1]];
        let den = [
            1.0 - (a[0] * z[0] + a[1] * z[1]),
            -(a[0] * z[1] - a[1] * z[0]),
        ];
        let d2 = den[0] * den[0] + den[1] * den[1];
        *z = [
            (num[0] * den[0] + num[1] * den[1]) / d2,
            (num[1] * den[0] - num[0] * den[1]) / d2,
        ];
    }
    uv[center] = [0.0, 0.0];
    for &b in boundary {
        let z = &mut uv[b as usize];
        let r = z[0].hypot(z[1]);
        if r > 0.0 {
            *z = [z[0] / r, z[1] / r];
        }
    }
}
