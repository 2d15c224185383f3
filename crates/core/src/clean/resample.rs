//! Resampling to the working resolution and triangle-quality improvement.

use super::closest::TriangleGrid;
use crate::mesh::{
    boundary_vertices, bounding_box, cross, dot, edge_face_map, edge_key, norm, sub,
    subdivide_midpoint, triangle_normal2, EdgeKey, EdgeMap, Mesh,
};
use rayon::prelude::*;
use rustc_hash::FxHashMap as HashMap;

/// Vertex positions in single precision for the simplifier, with copies of
/// one position (left by splitting non-manifold vertices) moved 1 % of the
/// way towards the centroid of their incident faces: the simplifier welds
/// vertices that share a position, which would rebuild the non-manifold
/// vertex and leave zero-area triangles.
fn separated_positions(mesh: &Mesh) -> Vec<[f32; 3]> {
    let mut positions: Vec<[f32; 3]> = mesh.vertices.iter().map(|p| p.map(|x| x as f32)).collect();
    let mut order: Vec<u32> = (0..positions.len() as u32).collect();
    let bits = |i: u32| positions[i as usize].map(f32::to_bits);
    order.sort_by_key(|&i| (bits(i), i));
    let mut moved = Vec::new();
    for w in order.windows(2) {
        if bits(w[0]) == bits(w[1]) {
            moved.push(w[1]);
        }
    }
    if moved.is_empty() {
        return positions;
    }
    let mut centroid = vec![[0.0f64; 3]; mesh.vertices.len()];
    let mut count = vec![0usize; mesh.vertices.len()];
    for f in &mesh.faces {
        let c =
            [0, 1, 2].map(|d| f.iter().map(|&v| mesh.vertices[v as usize][d]).sum::<f64>() / 3.0);
        for &v in f {
            for d in 0..3 {
                centroid[v as usize][d] += c[d];
            }
            count[v as usize] += 1;
        }
    }
    for v in moved {
        let v = v as usize;
        if count[v] > 0 {
            let p = mesh.vertices[v];
            positions[v] =
                [0, 1, 2].map(|d| (p[d] + 0.01 * (centroid[v][d] / count[v] as f64 - p[d])) as f32);
        }
    }
    positions
}

/// One pass of meshoptimizer's simplifier (quadric error) of `mesh` (its
/// positions and flattened indices given) towards `target_faces` faces;
/// unreferenced vertices dropped.
fn simplify(
    mesh: &Mesh,
    positions: &[[f32; 3]],
    indices: &[u32],
    target_faces: usize,
    options: meshopt::SimplifyOptions,
) -> Mesh {
    // The simplifier asserts (aborting the process) when asked for more
    // indices than it is given.
    let out = meshopt::simplify_decoder(
        indices,
        positions,
        (3 * target_faces.max(1)).min(indices.len()),
        1.0,
        options,
        None,
    );
    let faces: Vec<[u32; 3]> = out.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    super::faces::referenced_vertices(&mesh.vertices, faces)
}

/// Faces per piece when a surface of millions of faces is decimated piece
/// by piece ([`decimate_in_pieces`]).
const PIECE_FACES: usize = 1 << 18;

/// Quadric-error edge-collapse decimation of `mesh` to about `target_faces`
/// faces, for surfaces far above the working resolution (see
/// [`decimate_to_vertex_count`] for the properties kept). A surface of
/// more than twice [`PIECE_FACES`] faces is first decimated piece by piece
/// to twice the target ([`decimate_in_pieces`]), then as a whole.
pub(super) fn decimate_to_face_count(mesh: &Mesh, target_faces: usize) -> Mesh {
    let pieces = (mesh.faces.len() > 2 * PIECE_FACES && target_faces < PIECE_FACES)
        .then(|| decimate_in_pieces(mesh, 2 * target_faces, PIECE_FACES))
        .flatten();
    let mesh = pieces.as_ref().unwrap_or(mesh);
    let positions = separated_positions(mesh);
    let indices: Vec<u32> = mesh.faces.iter().flatten().copied().collect();
    simplify(
        mesh,
        &positions,
        &indices,
        target_faces,
        meshopt::SimplifyOptions::Regularize,
    )
}

/// Decimate `mesh` to about `target_faces` faces in slabs of about
/// `piece_faces` faces each, in parallel: the simplifier's working
/// memory (edge adjacency, quadrics, collapse lists: about a hundred bytes
/// per face) is then that of one slab per thread, not of millions of
/// faces, and the slabs share the cores. Vertices used by two slabs, and
/// their neighbours, are locked, so the slabs still fit together; the
/// caller decimates the result again as a whole, which frees them. `None` when the surface
/// cannot be cut (no extent).
fn decimate_in_pieces(mesh: &Mesh, target_faces: usize, piece_faces: usize) -> Option<Mesh> {
    let n = mesh.faces.len();
    let count = n.div_ceil(piece_faces).min(usize::from(u16::MAX));
    let piece = slabs(mesh, count)?;
    let mut owner = vec![u16::MAX; mesh.vertices.len()];
    let mut locked = vec![false; mesh.vertices.len()];
    let mut sizes = vec![0usize; count];
    for (f, &p) in mesh.faces.iter().zip(&piece) {
        sizes[usize::from(p)] += 1;
        for &v in f {
            let o = &mut owner[v as usize];
            if *o == u16::MAX {
                *o = p;
            } else if *o != p {
                locked[v as usize] = true;
            }
        }
    }
    drop(owner);
    // Their neighbours too: a collapse then never joins two shared
    // vertices by an edge, which both slabs could make (an edge of four
    // faces), and the faces along a cut stay as they are on both sides.
    let mut near_cut = vec![false; mesh.vertices.len()];
    for f in &mesh.faces {
        if f.iter().any(|&v| locked[v as usize]) {
            for &v in f {
                near_cut[v as usize] = true;
            }
        }
    }
    drop(locked);
    let locked = near_cut;
    let positions = separated_positions(mesh);
    // Stride 12 divides the length and offset 0 is inside it: cannot fail.
    let adapter =
        meshopt::VertexDataAdapter::new(meshopt::typed_to_bytes(&positions), 12, 0).ok()?;
    let decimated: Vec<Vec<u32>> = (0..count)
        .into_par_iter()
        .map(|p| {
            let indices: Vec<u32> = mesh
                .faces
                .iter()
                .zip(&piece)
                .filter(|&(_, &q)| usize::from(q) == p)
                .flat_map(|(f, _)| *f)
                .collect();
            let target = (target_faces * sizes[p]).div_ceil(n).max(1);
            // Sparse: the simplifier sizes its work by the slab's vertices.
            // Regularized as the whole surface was: without it, the
            // simplifier leaves slivers and folds on flat, evenly
            // subdivided parts.
            meshopt::simplify_with_locks(
                &indices,
                &adapter,
                &locked,
                3 * target,
                1.0,
                meshopt::SimplifyOptions::Sparse | meshopt::SimplifyOptions::Regularize,
                None,
            )
        })
        .collect();
    let faces: Vec<[u32; 3]> = decimated
        .iter()
        .flat_map(|d| d.chunks_exact(3).map(|c| [c[0], c[1], c[2]]))
        .collect();
    Some(super::faces::referenced_vertices(&mesh.vertices, faces))
}

/// The slab of each face: `count` slabs across the longest side of the
/// bounding box, holding about as many face centroids each (counted in
/// 4096 bins, so no sort). `None` without extent.
fn slabs(mesh: &Mesh, count: usize) -> Option<Vec<u16>> {
    const BINS: usize = 4096;
    let (lo, hi) = bounding_box(mesh)?;
    let axis = (0..3).max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))?;
    let width = hi[axis] - lo[axis];
    if !(width > 0.0 && width.is_finite()) {
        return None;
    }
    let v = &mesh.vertices;
    let mut slab: Vec<u16> = mesh
        .faces
        .iter()
        .map(|f| {
            let c = f.iter().map(|&i| v[i as usize][axis]).sum::<f64>() / 3.0;
            // In [0, BINS): BINS fits u16.
            ((c - lo[axis]) / width * BINS as f64).clamp(0.0, (BINS - 1) as f64) as u16
        })
        .collect();
    let mut histogram = vec![0usize; BINS];
    for &b in &slab {
        histogram[usize::from(b)] += 1;
    }
    let n = slab.len().max(1);
    let mut below = 0usize;
    let slab_of_bin: Vec<u16> = histogram
        .iter()
        .map(|&h| {
            let s = (below * count / n).min(count - 1);
            below += h;
            s as u16
        })
        .collect();
    for s in &mut slab {
        *s = slab_of_bin[usize::from(*s)];
    }
    Some(slab)
}

/// Quadric-error edge-collapse decimation (meshoptimizer's simplifier, with
/// its regularizing option for even triangle sizes) to about
/// `target_vertices` vertices. Boundary vertices only slide along the
/// boundary; decimated vertices are a subset of the input vertices, so the
/// result stays on the input surface. The face target is corrected a few
/// times from the vertex count obtained; the closest result is kept.
fn decimate_to_vertex_count(mesh: &Mesh, target_vertices: usize) -> Mesh {
    let positions = separated_positions(mesh);
    let indices: Vec<u32> = mesh.faces.iter().flatten().copied().collect();
    let mut target_faces = (2 * target_vertices).max(1) as f64;
    let mut best: Option<(usize, Mesh)> = None;
    for _ in 0..6 {
        let m = simplify(
            mesh,
            &positions,
            &indices,
            target_faces.round() as usize,
            meshopt::SimplifyOptions::Regularize,
        );
        let nv = m.vertices.len();
        let err = nv.abs_diff(target_vertices);
        let better = best.as_ref().is_none_or(|(e, _)| err < *e);
        if better {
            best = Some((err, m));
        }
        if (err as f64) < 0.03 * target_vertices as f64 || nv == 0 {
            break;
        }
        target_faces *= target_vertices as f64 / nv as f64;
    }
    best.map_or_else(|| mesh.clone(), |(_, m)| m)
}

/// Angle (radians) beyond which a triangle counts as a cap.
const CAP_ANGLE: f64 = 150.0 * std::f64::consts::PI / 180.0;

/// Angle (radians) below which a boundary ear counts as a sliver.
const EAR_ANGLE: f64 = 10.0 * std::f64::consts::PI / 180.0;

/// No face.
const NONE: u32 = u32::MAX;

fn angle_at(p: [f64; 3], q: [f64; 3], r: [f64; 3]) -> f64 {
    // Angle at p in triangle pqr.
    let (u, v) = (sub(q, p), sub(r, p));
    norm(cross(u, v)).atan2(dot(u, v))
}

/// Edge flips towards a Delaunay triangulation: an interior edge whose two
/// opposite angles sum to more than π is flipped, provided its two faces
/// are nearly coplanar (normals within `max_dihedral` radians, so the shape
/// is kept), the flipped faces keep their orientation and the edge's end
/// vertices keep at least three edges. A face with an angle over 150° at
/// the edge (a cap) is flipped whatever the dihedral angle. Returns the mesh
/// and the flip count.
fn flip_to_delaunay(mesh: &Mesh, max_dihedral: f64) -> (Mesh, usize) {
    let ef = edge_face_map(mesh);
    let mut faces = mesh.faces.clone();
    let (mut e2f, mut degree) = edge_faces_and_degrees(&ef, mesh.vertices.len());
    let cos_max = max_dihedral.cos();
    let v = &mesh.vertices;
    let mut stack: Vec<(u32, u32)> = ef
        .edges()
        .iter()
        .rev()
        .copied()
        .filter(|&(a, b)| e2f.get(&edge_key(a, b)).is_some_and(|fs| fs[1] != NONE))
        .collect();
    let mut flips = 0usize;
    let budget = 20 * ef.len() + 16;
    let mut steps = 0usize;
    while let Some((x, y)) = stack.pop() {
        steps += 1;
        if steps > budget {
            break;
        }
        let Some(quad) = quad_around_edge(&faces, &e2f, x, y) else {
            continue;
        };
        let EdgeQuad { a, b, c, d, .. } = quad;
        if c == d
            || e2f.contains_key(&edge_key(c, d))
            || degree[a as usize] <= 3
            || degree[b as usize] <= 3
        {
            continue;
        }
        let (pa, pb, pc, pd) = (v[a as usize], v[b as usize], v[c as usize], v[d as usize]);
        if angle_at(pc, pa, pb) + angle_at(pd, pa, pb) <= std::f64::consts::PI + 1e-9 {
            continue;
        }
        let Some(n) = flip_reference_normal(pa, pb, pc, pd, cos_max) else {
            continue;
        };
        if flipped_faces_turn_away(pa, pb, pc, pd, n) {
            continue;
        }
        flip_quad(&mut faces, &mut e2f, &mut degree, quad);
        flips += 1;
        stack.extend([(a, d), (d, b), (b, c), (c, a)]);
    }
    (Mesh::new(mesh.vertices.clone(), faces), flips)
}

/// The two faces of each edge by its key and each vertex's edge count.
fn edge_faces_and_degrees(ef: &EdgeMap, vertices: usize) -> (HashMap<EdgeKey, [u32; 2]>, Vec<u32>) {
    let mut e2f: HashMap<EdgeKey, [u32; 2]> =
        HashMap::with_capacity_and_hasher(ef.len(), Default::default());
    let mut degree = vec![0u32; vertices];
    for e in 0..ef.len() {
        let (a, b) = ef.edge(e);
        degree[a as usize] += 1;
        degree[b as usize] += 1;
        let fs = ef.faces_of(e);
        // Boundary edges are kept with NONE as second face: they must block
        // flips that would create them again, but are never flipped.
        let second = if fs.len() == 2 { fs[1] } else { NONE };
        e2f.insert(edge_key(a, b), [fs[0], second]);
    }
    (e2f, degree)
}

/// An interior edge `a`–`b` with its two faces: `f` runs a → b → c, `g`
/// runs b → a → d.
#[derive(Debug, Clone, Copy)]
struct EdgeQuad {
    f: u32,
    g: u32,
    a: u32,
    b: u32,
    c: u32,
    d: u32,
}

/// The quad around the edge `x`–`y`, oriented by its first face; `None`
/// when the edge is gone, on the boundary, or its faces do not run it in
/// opposite directions.
fn quad_around_edge(
    faces: &[[u32; 3]],
    e2f: &HashMap<EdgeKey, [u32; 2]>,
    x: u32,
    y: u32,
) -> Option<EdgeQuad> {
    let &[f, g] = e2f.get(&edge_key(x, y))?;
    if g == NONE {
        return None;
    }
    // Orient so that face f runs a → b.
    let (ff, gg) = (faces[f as usize], faces[g as usize]);
    let k = (0..3)
        .find(|&k| (ff[k] == x && ff[(k + 1) % 3] == y) || (ff[k] == y && ff[(k + 1) % 3] == x))?;
    let (a, b, c) = (ff[k], ff[(k + 1) % 3], ff[(k + 2) % 3]);
    let d = (0..3)
        .find(|&j| gg[j] == b && gg[(j + 1) % 3] == a)
        .map(|j| gg[(j + 2) % 3])?;
    Some(EdgeQuad { f, g, a, b, c, d })
}

/// The direction the flipped faces of the quad `a b c d` are checked
/// against: the sum of the two faces' unit normals, or a cap's
/// neighbour's unit normal; `None` when the faces are degenerate or their
/// normals further apart than the angle whose cosine is `cos_max`.
fn flip_reference_normal(
    pa: [f64; 3],
    pb: [f64; 3],
    pc: [f64; 3],
    pd: [f64; 3],
    cos_max: f64,
) -> Option<[f64; 3]> {
    let (n1, n2) = (triangle_normal2(pa, pb, pc), triangle_normal2(pb, pa, pd));
    let (l1, l2) = (norm(n1), norm(n2));
    // A cap (an angle near 180°) has no reliable normal: flip it away
    // whatever the dihedral angle, judging by its neighbour's normal.
    let cap1 = angle_at(pc, pa, pb) > CAP_ANGLE;
    let cap2 = angle_at(pd, pa, pb) > CAP_ANGLE;
    if cap1 && !cap2 && l2 > 0.0 {
        Some(n2.map(|x| x / l2))
    } else if cap2 && !cap1 && l1 > 0.0 {
        Some(n1.map(|x| x / l1))
    } else if l1 <= 0.0 || l2 <= 0.0 || dot(n1, n2) < cos_max * l1 * l2 {
        None
    } else {
        Some([0, 1, 2].map(|i| n1[i] / l1 + n2[i] / l2))
    }
}

/// Whether a face of the flipped quad (`a d c`, `d b c`) is degenerate or
/// turned 60° or more away from the direction `n`.
fn flipped_faces_turn_away(
    pa: [f64; 3],
    pb: [f64; 3],
    pc: [f64; 3],
    pd: [f64; 3],
    n: [f64; 3],
) -> bool {
    let (m1, m2) = (triangle_normal2(pa, pd, pc), triangle_normal2(pd, pb, pc));
    let (k1, k2) = (norm(m1), norm(m2));
    k1 <= 0.0 || k2 <= 0.0 || dot(m1, n) <= 0.5 * k1 || dot(m2, n) <= 0.5 * k2
}

/// Replace the quad's edge `a`–`b` by `c`–`d`: its two faces, the edge
/// table and the four vertices' edge counts.
fn flip_quad(
    faces: &mut [[u32; 3]],
    e2f: &mut HashMap<EdgeKey, [u32; 2]>,
    degree: &mut [u32],
    quad: EdgeQuad,
) {
    let EdgeQuad { f, g, a, b, c, d } = quad;
    faces[f as usize] = [a, d, c];
    faces[g as usize] = [d, b, c];
    e2f.remove(&edge_key(a, b));
    e2f.insert(edge_key(c, d), [f, g]);
    for (e, from, to) in [(edge_key(a, d), g, f), (edge_key(b, c), f, g)] {
        if let Some(fs) = e2f.get_mut(&e) {
            for s in fs.iter_mut() {
                if *s == from {
                    *s = to;
                }
            }
        }
    }
    degree[a as usize] -= 1;
    degree[b as usize] -= 1;
    degree[c as usize] += 1;
    degree[d as usize] += 1;
}

/// The surface that relaxed vertices are projected back onto: its
/// triangles (for interior vertices) and its boundary segments (for
/// boundary vertices, which thereby stay on the original boundary).
#[derive(Debug, Clone)]
pub(super) struct SurfaceReference {
    grid: TriangleGrid,
    boundary: Vec<[[f64; 3]; 2]>,
}

impl SurfaceReference {
    /// Reference of `mesh`; `None` without faces.
    pub(super) fn new(mesh: &Mesh) -> Option<Self> {
        let grid = TriangleGrid::new(mesh)?;
        let ef = edge_face_map(mesh);
        let boundary = (0..ef.len())
            .filter(|&e| ef.faces_of(e).len() == 1)
            .map(|e| {
                let (a, b) = ef.edge(e);
                [mesh.vertices[a as usize], mesh.vertices[b as usize]]
            })
            .collect();
        Some(Self { grid, boundary })
    }

    /// Closest point of the surface.
    pub(super) fn closest_point(&self, p: [f64; 3]) -> [f64; 3] {
        self.grid.closest_point(p).point
    }

    /// Closest point of the boundary (`p` itself when there is none).
    fn closest_boundary_point(&self, p: [f64; 3]) -> [f64; 3] {
        let mut best = (f64::INFINITY, p);
        for &[a, b] in &self.boundary {
            let ab = sub(b, a);
            let l2 = dot(ab, ab);
            let t = if l2 > 0.0 {
                (dot(sub(p, a), ab) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let q = [0, 1, 2].map(|d| a[d] + t * ab[d]);
            let d = sub(q, p);
            let d2 = dot(d, d);
            if d2 < best.0 {
                best = (d2, q);
            }
        }
        best.1
    }
}

/// One step of tangential relaxation: every interior vertex moves by
/// `lambda` towards the area-weighted centroid of its incident triangles,
/// with the normal component of the move removed, then onto the closest
/// point of the reference surface. A boundary vertex moves by `lambda`
/// towards the midpoint of its two boundary neighbours, then onto the
/// closest point of the reference boundary; where the boundary turns by
/// more than 60° it stays (corners are kept). A move that would turn an
/// incident triangle over (or shrink it below a tenth of its area) is
/// dropped. Jacobi update: the result does not depend on vertex order.
fn relax_tangential(mesh: &Mesh, reference: &SurfaceReference, lambda: f64) -> Mesh {
    let n = mesh.vertices.len();
    let v = &mesh.vertices;
    // Boundary neighbours (u32::MAX = none); a third one marks a pinch.
    let mut bnbr = vec![[u32::MAX; 3]; n];
    let ef = edge_face_map(mesh);
    for e in 0..ef.len() {
        if ef.faces_of(e).len() == 1 {
            let (a, b) = ef.edge(e);
            for (x, y) in [(a, b), (b, a)] {
                if let Some(slot) = bnbr[x as usize].iter_mut().find(|s| **s == u32::MAX) {
                    *slot = y;
                }
            }
        }
    }
    let mut centroid = vec![[0.0; 3]; n];
    let mut weight = vec![0.0; n];
    let mut normal = vec![[0.0; 3]; n];
    let mut incident: Vec<Vec<u32>> = vec![Vec::new(); n];
    for (fi, f) in mesh.faces.iter().enumerate() {
        let p = f.map(|i| v[i as usize]);
        let n2 = triangle_normal2(p[0], p[1], p[2]);
        let a = 0.5 * norm(n2);
        let c = [0, 1, 2].map(|d| (p[0][d] + p[1][d] + p[2][d]) / 3.0);
        for &i in f {
            let i = i as usize;
            for d in 0..3 {
                centroid[i][d] += a * c[d];
                normal[i][d] += n2[d];
            }
            weight[i] += a;
            incident[i].push(fi as u32);
        }
    }
    let target = |i: usize| -> Option<[f64; 3]> {
        let p = v[i];
        let nb = bnbr[i];
        if nb[0] != u32::MAX {
            // Boundary vertex: exactly two boundary neighbours, gentle turn.
            if nb[1] == u32::MAX || nb[2] != u32::MAX {
                return None;
            }
            let (pa, pb) = (v[nb[0] as usize], v[nb[1] as usize]);
            let (u, w) = (sub(p, pa), sub(pb, p));
            if dot(u, w) < 0.5 * norm(u) * norm(w) {
                return None;
            }
            let d = [0, 1, 2].map(|k| lambda * (0.5 * (pa[k] + pb[k]) - p[k]));
            return Some(reference.closest_boundary_point([p[0] + d[0], p[1] + d[1], p[2] + d[2]]));
        }
        let nl = norm(normal[i]);
        if weight[i] <= 0.0 || nl <= 0.0 {
            return None;
        }
        let nn = normal[i].map(|x| x / nl);
        let c = centroid[i].map(|x| x / weight[i]);
        let mut d = sub(c, p);
        let dn = dot(d, nn);
        d = [0, 1, 2].map(|k| lambda * (d[k] - dn * nn[k]));
        Some(reference.closest_point([p[0] + d[0], p[1] + d[1], p[2] + d[2]]))
    };
    let moved: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let p = v[i];
            let Some(q) = target(i) else {
                return p;
            };
            // Reject moves that fold or crush an incident triangle.
            for &fi in &incident[i] {
                let f = mesh.faces[fi as usize];
                let old = f.map(|j| v[j as usize]);
                let new = f.map(|j| if j as usize == i { q } else { v[j as usize] });
                let n0 = triangle_normal2(old[0], old[1], old[2]);
                let n1 = triangle_normal2(new[0], new[1], new[2]);
                if dot(n0, n1) <= 0.1 * dot(n0, n0) {
                    return p;
                }
            }
            q
        })
        .collect();
    Mesh::new(moved, mesh.faces.clone())
}

/// Bring a mesh to about `target_vertices` vertices: midpoint subdivision
/// while it is coarser than 90 % of the target, then quadric decimation when
/// it is finer than 110 %. Unchanged when already within ±10 %.
pub(super) fn resample_to_vertex_count(mesh: &Mesh, target_vertices: usize) -> Mesh {
    let mut m = mesh.clone();
    let lo = (0.9 * target_vertices as f64) as usize;
    let hi = (1.1 * target_vertices as f64) as usize;
    let mut guard = 0;
    while m.vertices.len() < lo && guard < 8 && !m.faces.is_empty() {
        m = subdivide_midpoint(&m, 1);
        guard += 1;
    }
    if m.vertices.len() > hi {
        m = decimate_to_vertex_count(&m, target_vertices);
    }
    m
}

/// Remove boundary slivers that no flip can fix, in up to three passes:
/// - a cap, a face whose boundary edge faces an angle over 150° at an
///   interior vertex: dropping it moves the boundary onto its two other
///   edges (by less than the cap's height) and the vertex joins the
///   boundary;
/// - an ear with an angle under 10°, a face with two boundary edges: its
///   tip vertex goes with it.
///
/// Returns the mesh and the number of faces removed.
fn remove_boundary_caps(mesh: &Mesh) -> (Mesh, usize) {
    let mut m = mesh.clone();
    let mut total = 0;
    for _ in 0..3 {
        let (next, removed) = remove_boundary_slivers_once(&m);
        if removed == 0 {
            break;
        }
        m = next;
        total += removed;
    }
    (m, total)
}

fn remove_boundary_slivers_once(mesh: &Mesh) -> (Mesh, usize) {
    let ef = edge_face_map(mesh);
    let mut on_boundary = boundary_vertices(mesh);
    let mut boundary_edges = vec![0u8; mesh.faces.len()];
    for e in 0..ef.len() {
        if let [f] = ef.faces_of(e) {
            boundary_edges[*f as usize] += 1;
        }
    }
    let v = &mesh.vertices;
    let mut remove = vec![false; mesh.faces.len()];
    for e in 0..ef.len() {
        let fs = ef.faces_of(e);
        if fs.len() != 1 {
            continue;
        }
        let fi = fs[0] as usize;
        let (a, b) = ef.edge(e);
        let f = mesh.faces[fi];
        let Some(&c) = f.iter().find(|&&x| x != a && x != b) else {
            continue;
        };
        if remove[fi] {
            continue;
        }
        let (pa, pb, pc) = (v[a as usize], v[b as usize], v[c as usize]);
        let cap = !on_boundary[c as usize] && angle_at(pc, pa, pb) > CAP_ANGLE;
        let min_angle = angle_at(pa, pb, pc)
            .min(angle_at(pb, pc, pa))
            .min(angle_at(pc, pa, pb));
        // Only one face per vertex fan changes per pass (ears must not
        // share a vertex with another removal, or a pinch could appear).
        let ear = boundary_edges[fi] == 2 && min_angle < EAR_ANGLE;
        if cap || ear {
            remove[fi] = true;
            on_boundary[c as usize] = true;
        }
    }
    let faces: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .zip(&remove)
        .filter_map(|(f, &r)| (!r).then_some(*f))
        .collect();
    let removed = mesh.faces.len() - faces.len();
    if removed == 0 {
        return (mesh.clone(), 0);
    }
    let m = super::faces::remove_unreferenced_vertices(&Mesh::new(mesh.vertices.clone(), faces));
    (m, removed)
}

/// Improve the triangles of `mesh` without changing its vertex count or
/// topology: `iterations` rounds of Delaunay edge flips (faces within 30°
/// of coplanar) and tangential relaxation projected onto `reference`, then
/// a final round of flips. Returns the mesh and the number of flips.
pub(super) fn improve_triangles(
    mesh: &Mesh,
    reference: &SurfaceReference,
    iterations: usize,
) -> (Mesh, usize) {
    let dihedral = 30f64.to_radians();
    let (mut m, _) = remove_boundary_caps(mesh);
    let mut flips = 0;
    for _ in 0..iterations {
        let (f, k) = flip_to_delaunay(&m, dihedral);
        flips += k;
        m = relax_tangential(&f, reference, 0.5);
    }
    let (f, k) = flip_to_delaunay(&m, dihedral);
    let (f, _) = remove_boundary_caps(&f);
    (f, flips + k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{euler_characteristic, surface_area};

    use crate::testing::synth::square_grid as grid;

    #[test]
    fn obtuse_pair_is_flipped() {
        // A flat rhombus split along its long diagonal: opposite angles > 90°.
        let m = Mesh::new(
            vec![
                [0., 0., 0.],
                [4., 0., 0.],
                [2., 0.5, 0.],
                [2., -0.5, 0.],
                [2., 3., 0.],
                [2., -3., 0.],
            ],
            vec![
                [0, 1, 2],
                [1, 0, 3],
                [0, 2, 4],
                [2, 1, 4],
                [3, 0, 5],
                [1, 3, 5],
            ],
        );
        let (f, flips) = flip_to_delaunay(&m, 0.5);
        assert!(flips >= 1);
        assert!(f.faces.iter().any(|t| t.contains(&2) && t.contains(&3)));
        assert_eq!(euler_characteristic(&f), 1);
        assert!((surface_area(&f) - surface_area(&m)).abs() < 1e-12);
    }

    #[test]
    fn boundary_cap_is_removed() {
        // Square grid with an interior vertex pulled next to the bottom edge.
        let mut m = grid(2);
        m.vertices[4] = [0.5, 0.02, 0.0];
        let (c, removed) = remove_boundary_caps(&m);
        assert_eq!(removed, 1);
        assert_eq!(euler_characteristic(&c), 1);
        assert_eq!(crate::mesh::boundary_loops(&c).len(), 1);
    }

    #[test]
    fn slabs_decimated_apart_fit_together_on_the_input_surface() {
        // A curved sheet of 12,800 faces cut into seven slabs of ~2,000.
        let flat = subdivide_midpoint(&grid(40), 1);
        let bend = |p: [f64; 3]| [p[0], p[1], 0.2 * (3.0 * p[0]).sin() * (2.0 * p[1]).cos()];
        let m = Mesh::new(flat.vertices.iter().map(|&p| bend(p)).collect(), flat.faces);
        let d = decimate_in_pieces(&m, 1000, 2000).expect("the sheet has extent");
        let nf = d.faces.len();
        // The vertices along the cuts stay: more faces than asked, but
        // far fewer than the input's.
        assert!((1000..4000).contains(&nf), "{nf} faces");
        // One sheet without gaps or non-manifold edges along the cuts.
        assert_eq!(euler_characteristic(&d), 1);
        assert_eq!(crate::mesh::boundary_loops(&d).len(), 1);
        let ef = edge_face_map(&d);
        assert!((0..ef.len()).all(|e| ef.faces_of(e).len() <= 2));
        assert!(d.vertices.iter().all(|p| m.vertices.contains(p)));
        // Chords of the curved sheet: a little less area, never more.
        let (a, a0) = (surface_area(&d), surface_area(&m));
        assert!(a <= a0 && a > 0.97 * a0, "area {a} of {a0}");
        // Decimated again as a whole, the cuts are freed.
        let whole = decimate_to_face_count(&d, 500);
        assert!(whole.faces.len() < 700, "{}", whole.faces.len());
        assert!(whole.vertices.iter().all(|p| m.vertices.contains(p)));
    }

    #[test]
    fn decimation_hits_the_target() {
        let m = subdivide_midpoint(&grid(20), 2);
        let d = decimate_to_vertex_count(&m, 1000);
        let nv = d.vertices.len() as f64;
        assert!((nv - 1000.0).abs() < 100.0, "{nv}");
        assert_eq!(euler_characteristic(&d), 1);
    }
}
