//! Conformal map of a disk-type surface onto the unit disk.

use super::cholesky::SpdFactor;
use super::intrinsic::intrinsic_delaunay_weights;
use super::laplacian::{cotangent_edge_weights, csc_from_columns, EdgeWeights};
use super::quality::{flipped_triangles, signed_area_2d};
use super::validate::check_disk_topology;
use super::FlattenError;
use crate::mesh::{graph_distance, norm, sub, Mesh};

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
/// boundary vertex under the conformal map sending the centre to 0 (every
/// boundary vertex gets at least a tenth of its share by boundary length, so
/// the tips of "ear" faces, which carry no flux, stay distinct). The
/// interior is then the harmonic (cotangent) extension of those boundary
/// positions, solved with the same Cholesky factor.
///
/// The cotangent weights are those of the intrinsic Delaunay triangulation
/// (non-negative; any left negative are raised to a tiny positive floor),
/// so by Tutte's theorem the map embeds that triangulation in the convex
/// boundary polygon. The input's own faces are then checked: faces that
/// come out flipped or squeezed (rare: slivers next to vertices with three
/// edges) are repaired locally with mean-value weights; if that fails, the
/// whole map is recomputed with the input's cotangent weights, negative ones
/// raised to a small positive floor (an embedding of the input itself).
/// A final Möbius transformation puts the centre exactly at 0.
///
/// Errors: the mesh is not a clean disk (see [`FlattenError`]), has
/// degenerate faces, the solve fails, or the result has flipped triangles.
pub fn flatten_to_disk(mesh: &Mesh) -> Result<DiskMap, FlattenError> {
    let (boundary, center) = prepare(mesh)?;
    let idt = positive_weights(intrinsic_delaunay_weights(mesh)?.0, INTRINSIC_FLOOR);
    let mut uv = harmonic_disk_map(&mesh.vertices, &boundary, center, &idt)?;
    let mut fixed = vec![false; mesh.vertices.len()];
    for &b in &boundary {
        fixed[b as usize] = true;
    }
    if !bad_faces(mesh, &uv, &fixed).is_empty() && !repair_faces(mesh, &mut uv, &fixed) {
        let clamped = positive_weights(cotangent_edge_weights(mesh), CLAMPED_FLOOR);
        uv = harmonic_disk_map(&mesh.vertices, &boundary, center, &clamped)?;
    }
    finish(mesh, uv, center, &boundary)
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

/// [`flatten_to_disk`] with one given Laplacian throughout and no repair
/// (for comparisons): fails with [`FlattenError::Flipped`] when the map
/// folds.
pub fn flatten_to_disk_with(
    mesh: &Mesh,
    weights: LaplacianWeights,
) -> Result<DiskMap, FlattenError> {
    let (boundary, center) = prepare(mesh)?;
    let w = match weights {
        LaplacianWeights::IntrinsicDelaunay => {
            positive_weights(intrinsic_delaunay_weights(mesh)?.0, INTRINSIC_FLOOR)
        }
        LaplacianWeights::ClampedCotangent => {
            positive_weights(cotangent_edge_weights(mesh), CLAMPED_FLOOR)
        }
    };
    let uv = harmonic_disk_map(&mesh.vertices, &boundary, center, &w)?;
    finish(mesh, uv, center, &boundary)
}

/// Validate the mesh and choose the centre: the boundary loop and the
/// central vertex.
fn prepare(mesh: &Mesh) -> Result<(Vec<u32>, u32), FlattenError> {
    let boundary = check_disk_topology(mesh)?;
    check_faces_nondegenerate(mesh)?;
    let center = central_vertex(mesh, &boundary).ok_or_else(|| FlattenError::Degenerate {
        reason: "no interior vertex to use as the centre".into(),
    })?;
    Ok((boundary, center))
}

/// Send the centre to 0 and check the result: finite, no flipped face.
fn finish(
    mesh: &Mesh,
    mut uv: Vec<[f64; 2]>,
    center: u32,
    boundary: &[u32],
) -> Result<DiskMap, FlattenError> {
    center_by_mobius(&mut uv, center as usize, boundary);
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

/// Faces with an interior vertex whose image is flipped or squeezed: disk
/// area below [`SQUEEZED_AREA`] times what a uniform area scaling would
/// give. (A face with all three vertices on the boundary is inscribed in the
/// circle and may legitimately be thin.)
fn bad_faces(mesh: &Mesh, uv: &[[f64; 2]], fixed: &[bool]) -> Vec<usize> {
    let areas = crate::mesh::face_areas(mesh);
    let total: f64 = areas.iter().sum();
    let scale = std::f64::consts::PI / total;
    mesh.faces
        .iter()
        .zip(&areas)
        .enumerate()
        .filter(|(_, (f, &a))| {
            if f.iter().all(|&v| fixed[v as usize]) {
                return false;
            }
            let s = signed_area_2d(uv[f[0] as usize], uv[f[1] as usize], uv[f[2] as usize]);
            s.is_nan() || s <= SQUEEZED_AREA * a * scale
        })
        .map(|(i, _)| i)
        .collect()
}

/// Relative disk area below which a face counts as squeezed.
const SQUEEZED_AREA: f64 = 1e-4;

/// Repair flipped or squeezed faces locally: in a growing neighbourhood of
/// the [`bad_faces`] (1, 2, 4, 8 rings), re-place the interior vertices as
/// the mean-value (Floater) convex combination of their neighbours, keeping
/// the rest of `uv` fixed, until no bad face is left. Mean-value weights are
/// positive for any triangle shape and close to the cotangent weights on
/// well-shaped meshes, so the patch stays nearly conformal. Returns whether
/// the result has no flipped face (the largest patch tried is kept when
/// squeezed faces remain); `uv` is only changed then.
fn repair_faces(mesh: &Mesh, uv: &mut [[f64; 2]], fixed: &[bool]) -> bool {
    let n = mesh.vertices.len();
    let adj = mean_value_weights(mesh);
    let seeds: Vec<u32> = bad_faces(mesh, uv, fixed)
        .into_iter()
        .flat_map(|f| mesh.faces[f])
        .collect();
    let mut unflipped: Option<Vec<[f64; 2]>> = None;
    for rings in [1, 2, 4, 8] {
        // Region: interior vertices within `rings` edges of a flipped face.
        let mut in_region = vec![false; n];
        let mut frontier: Vec<u32> = Vec::new();
        for &v in &seeds {
            if !in_region[v as usize] {
                in_region[v as usize] = true;
                frontier.push(v);
            }
        }
        for _ in 0..rings {
            let mut next = Vec::new();
            for &v in &frontier {
                for &(u, _) in &adj[v as usize] {
                    if !in_region[u as usize] {
                        in_region[u as usize] = true;
                        next.push(u);
                    }
                }
            }
            frontier = next;
        }
        let region: Vec<usize> = (0..n).filter(|&v| in_region[v] && !fixed[v]).collect();
        if region.is_empty() {
            break;
        }
        // Gauss–Seidel on the (non-symmetric, row-stochastic) mean-value
        // system; it converges because the weights are positive and the
        // region touches fixed vertices.
        let mut trial = uv.to_vec();
        for _ in 0..20_000 {
            let mut change: f64 = 0.0;
            for &v in &region {
                let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
                for &(u, w) in &adj[v] {
                    sx += w * trial[u as usize][0];
                    sy += w * trial[u as usize][1];
                    sw += w;
                }
                if sw > 0.0 {
                    let z = [sx / sw, sy / sw];
                    change = change.max((z[0] - trial[v][0]).abs() + (z[1] - trial[v][1]).abs());
                    trial[v] = z;
                }
            }
            if change.is_nan() || change < 1e-15 {
                break;
            }
        }
        if flipped_triangles(&mesh.faces, &trial) == 0 {
            if bad_faces(mesh, &trial, fixed).is_empty() {
                uv.copy_from_slice(&trial);
                return true;
            }
            unflipped = Some(trial);
        }
    }
    match unflipped {
        Some(best) => {
            uv.copy_from_slice(&best);
            true
        }
        None => flipped_triangles(&mesh.faces, uv) == 0,
    }
}

/// Mean-value weights (Floater 2003) of each vertex's neighbours:
/// `w_ij = (tan(δ/2) + tan(γ/2)) / |x_j − x_i|`, with δ, γ the angles at
/// `i` of the faces on either side of edge `ij`. Positive for any
/// non-degenerate triangle; not symmetric.
fn mean_value_weights(mesh: &Mesh) -> Vec<Vec<(u32, f64)>> {
    let n = mesh.vertices.len();
    let mut adj: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
    for f in &mesh.faces {
        for k in 0..3 {
            let (i, j, l) = (f[k], f[(k + 1) % 3], f[(k + 2) % 3]);
            let xi = mesh.vertices[i as usize];
            let e1 = sub(mesh.vertices[j as usize], xi);
            let e2 = sub(mesh.vertices[l as usize], xi);
            let (l1, l2) = (norm(e1), norm(e2));
            // tan(θ/2) = |e1 × e2| / (|e1||e2| + e1·e2)
            let den = l1 * l2 + crate::mesh::dot(e1, e2);
            let t = norm(crate::mesh::cross(e1, e2)) / den;
            if !(t.is_finite() && l1 > 0.0 && l2 > 0.0) {
                continue;
            }
            adj[i as usize].push((j, t / l1));
            adj[i as usize].push((l, t / l2));
        }
    }
    for list in adj.iter_mut() {
        list.sort_by_key(|&(u, _)| u);
        list.dedup_by(|b, a| {
            if a.0 == b.0 {
                a.1 += b.1;
                true
            } else {
                false
            }
        });
    }
    adj
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
    let dist = graph_distance(mesh, boundary);
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
    let (interior_index, m) = interior_numbering(n, boundary);
    let pc = interior_index[center as usize].ok_or_else(|| FlattenError::Degenerate {
        reason: "the centre vertex is on the boundary".into(),
    })?;
    let factor = SpdFactor::new(&csc_from_columns(
        m,
        interior_stiffness_columns(&interior_index, m, weights),
    ))?;

    // Green's function with unit source at the centre.
    let mut green = vec![vec![0.0; m]];
    green[0][pc] = 1.0;
    factor.solve_columns(&mut green)?;
    let u = &green[0];

    let flux = boundary_flux(&interior_index, weights, u, n);
    let flux_total: f64 = boundary.iter().map(|&b| flux[b as usize].max(0.0)).sum();
    if !(flux_total.is_finite() && flux_total > 0.0) {
        return Err(FlattenError::Solve {
            reason: format!("harmonic measure of the boundary is {flux_total}"),
        });
    }
    let omega = boundary_measures(positions, boundary, &flux, flux_total);
    let mut uv = boundary_on_circle(boundary, &omega, n);
    harmonic_extension(&factor, &interior_index, m, weights, &mut uv)?;
    Ok(uv)
}

/// Each vertex's number among the interior vertices (`None` on the
/// boundary), in vertex order, and how many interior vertices there are.
fn interior_numbering(n: usize, boundary: &[u32]) -> (Vec<Option<usize>>, usize) {
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
    (interior_index, m)
}

/// The columns of K_II = −L_II, the interior block of the negated weighted
/// Laplacian (positive definite for positive weights and a connected mesh
/// with a boundary): lower triangle only, diagonal last in each column.
fn interior_stiffness_columns(
    interior_index: &[Option<usize>],
    m: usize,
    weights: &[((u32, u32), f64)],
) -> Vec<Vec<(usize, f64)>> {
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
    cols
}

/// Flux of the Green's function `u` (by interior number) through each
/// boundary vertex = its harmonic measure; zero at interior vertices.
fn boundary_flux(
    interior_index: &[Option<usize>],
    weights: &[((u32, u32), f64)],
    u: &[f64],
    n: usize,
) -> Vec<f64> {
    let mut flux = vec![0.0; n];
    for &((i, j), w) in weights {
        match (interior_index[i as usize], interior_index[j as usize]) {
            (None, Some(b)) => flux[i as usize] += w * u[b],
            (Some(a), None) => flux[j as usize] += w * u[a],
            _ => {}
        }
    }
    flux
}

/// Each boundary vertex's share of the circle (unnormalized): its
/// harmonic measure, raised to at least [`MIN_MEASURE_SHARE`] of its share
/// by boundary length.
fn boundary_measures(
    positions: &[[f64; 3]],
    boundary: &[u32],
    flux: &[f64],
    flux_total: f64,
) -> Vec<f64> {
    // A boundary vertex with no interior neighbour (the tip of an "ear"
    // triangle whose three vertices are all on the boundary) has zero flux;
    // two such neighbours would land on the same point of the circle. Give
    // every boundary vertex at least a fraction of its share by boundary
    // length, which keeps the boundary polygon strictly convex.
    let dual_length = boundary_dual_lengths(positions, boundary);
    let length_total: f64 = dual_length.iter().sum();
    boundary
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
        .collect()
}

/// Disk coordinates of `n` vertices with the boundary on the unit circle,
/// each boundary vertex at the middle of its arc of measure `omega`, in
/// boundary order; interior vertices at the origin.
fn boundary_on_circle(boundary: &[u32], omega: &[f64], n: usize) -> Vec<[f64; 2]> {
    let total: f64 = omega.iter().sum();
    let mut uv = vec![[0.0; 2]; n];
    let mut acc = 0.0;
    for (&b, &w) in boundary.iter().zip(omega) {
        let theta = std::f64::consts::TAU * (acc + 0.5 * w) / total;
        acc += w;
        uv[b as usize] = [theta.cos(), theta.sin()];
    }
    uv
}

/// Harmonic extension of the boundary positions in `uv` to the interior
/// vertices, with the factorization of the interior block.
fn harmonic_extension(
    factor: &SpdFactor,
    interior_index: &[Option<usize>],
    m: usize,
    weights: &[((u32, u32), f64)],
    uv: &mut [[f64; 2]],
) -> Result<(), FlattenError> {
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
    Ok(())
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
