//! The plain geometry the crown extraction reads: face normals, areas and
//! centroids, the signed turn across every interior edge, area-weighted
//! principal axes and cylindrical coordinates about an axis.

use crate::mesh::{cross, dot, norm, perpendicular_frame, sub, triangle_normal2, EdgeMap, Mesh};
use rayon::prelude::*;

/// Per-face and per-edge geometry of a closed, consistently oriented mesh.
pub(super) struct SurfaceGeometry {
    /// Area of every face.
    pub areas: Vec<f64>,
    /// Centroid of every face.
    pub centroids: Vec<[f64; 3]>,
    /// The edges with their faces.
    pub edges: EdgeMap,
    /// Signed turn angle (radians) across every edge shared by exactly two
    /// faces: positive where the surface is convex (a ridge), negative
    /// where it is concave (a crease), 0 elsewhere.
    pub turn: Vec<f64>,
}

impl SurfaceGeometry {
    pub(super) fn new(mesh: &Mesh) -> Self {
        let mut normals = Vec::with_capacity(mesh.faces.len());
        let mut areas = Vec::with_capacity(mesh.faces.len());
        let mut centroids = Vec::with_capacity(mesh.faces.len());
        for f in &mesh.faces {
            let p = f.map(|v| mesh.vertices[v as usize]);
            let n2 = triangle_normal2(p[0], p[1], p[2]);
            let len = norm(n2);
            normals.push(if len > 0.0 {
                n2.map(|x| x / len)
            } else {
                [0.0; 3]
            });
            areas.push(0.5 * len);
            centroids.push([0, 1, 2].map(|d| (p[0][d] + p[1][d] + p[2][d]) / 3.0));
        }
        let edges = EdgeMap::new(&mesh.faces);
        let turn = (0..edges.len())
            .map(|e| match edges.faces_of(e) {
                &[f, g] => signed_turn(mesh, &normals, f as usize, g as usize, edges.edge(e)),
                _ => 0.0,
            })
            .collect();
        Self {
            areas,
            centroids,
            edges,
            turn,
        }
    }
}

/// The vertex of face `f` that is not on the edge `(a, b)`.
fn opposite(face: [u32; 3], (a, b): (u32, u32)) -> u32 {
    face.into_iter()
        .find(|&v| v != a && v != b)
        .unwrap_or(face[0])
}

/// Angle between the normals of faces `f` and `g` across their shared
/// edge, positive when `g` bends away below `f`'s plane (convex).
fn signed_turn(mesh: &Mesh, normals: &[[f64; 3]], f: usize, g: usize, edge: (u32, u32)) -> f64 {
    let (nf, ng) = (normals[f], normals[g]);
    let angle = norm(cross(nf, ng)).atan2(dot(nf, ng));
    let o = opposite(mesh.faces[g], edge);
    let side = dot(
        nf,
        sub(mesh.vertices[o as usize], mesh.vertices[edge.0 as usize]),
    );
    if side < 0.0 {
        angle
    } else {
        -angle
    }
}

/// Six times the signed volume enclosed by a closed surface (positive when
/// its normals point outward).
pub(super) fn signed_volume6(mesh: &Mesh) -> f64 {
    mesh.faces
        .iter()
        .map(|f| {
            let p = f.map(|v| mesh.vertices[v as usize]);
            dot(p[0], cross(p[1], p[2]))
        })
        .sum()
}

/// Area-weighted centroid and principal axes of a surface (face centroids
/// weighted by face area), largest spread first.
pub(super) fn area_weighted_axes(geo: &SurfaceGeometry) -> Option<([f64; 3], [[f64; 3]; 3])> {
    let pa = crate::mesh::weighted_principal_axes(
        geo.centroids.iter().copied().zip(geo.areas.iter().copied()),
    )?;
    Some((pa.centroid, pa.axes))
}

/// Cylindrical coordinates about the axis through `centre` along the unit
/// vector `axis`: `(angle, radius, height)`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Cylinder {
    centre: [f64; 3],
    axis: [f64; 3],
    u: [f64; 3],
    v: [f64; 3],
}

impl Cylinder {
    pub(super) fn new(centre: [f64; 3], axis: [f64; 3]) -> Self {
        let [u, v] = perpendicular_frame(axis);
        Self { centre, axis, u, v }
    }

    pub(super) fn axis(&self) -> [f64; 3] {
        self.axis
    }

    pub(super) fn height(&self, p: [f64; 3]) -> f64 {
        dot(sub(p, self.centre), self.axis)
    }

    /// `(angle in (−π, π], distance from the axis)`.
    pub(super) fn polar(&self, p: [f64; 3]) -> (f64, f64) {
        let d = sub(p, self.centre);
        let (x, y) = (dot(d, self.u), dot(d, self.v));
        (y.atan2(x), x.hypot(y))
    }
}

/// The vertices of `mesh` after `iterations` rounds of Taubin's λ|μ
/// smoothing (uniform weights): the voxel staircase of an isosurface and
/// scanner noise go, the shape's larger bends stay, and, unlike plain
/// Laplacian smoothing, the surface does not shrink.
pub(super) fn taubin_smoothed(mesh: &Mesh, iterations: usize) -> Vec<[f64; 3]> {
    const LAMBDA: f64 = 0.5;
    const MU: f64 = -0.53;
    let adjacency = crate::mesh::vertex_adjacency(mesh);
    let mut points = mesh.vertices.clone();
    // Each vertex's new position reads the old ones only: the vertices are
    // moved in parallel, with the same result, into a second buffer (a
    // million-vertex export is smoothed sixty times).
    let mut moved = points.clone();
    for _ in 0..iterations {
        for factor in [LAMBDA, MU] {
            moved
                .par_iter_mut()
                .zip(points.par_iter().zip(adjacency.par_iter()))
                .for_each(|(out, (&p, near))| *out = taubin_step(&points, p, near, factor));
            std::mem::swap(&mut points, &mut moved);
        }
    }
    points
}

/// `p` moved by `factor` towards the mean of its neighbours `near` (their
/// positions in `points`); unmoved without neighbours.
fn taubin_step(points: &[[f64; 3]], p: [f64; 3], near: &[u32], factor: f64) -> [f64; 3] {
    if near.is_empty() {
        return p;
    }
    let n = near.len() as f64;
    let mean = near.iter().fold([0.0; 3], |acc, &q| {
        let q = points[q as usize];
        [acc[0] + q[0], acc[1] + q[1], acc[2] + q[2]]
    });
    [0, 1, 2].map(|d| p[d] + factor * (mean[d] / n - p[d]))
}

/// The directed Hausdorff distance from `points` to `from`: the farthest
/// any of `points` lies from its nearest point of `from` (0 when either is
/// empty).
pub(super) fn directed_hausdorff(points: &[[f64; 3]], from: &[[f64; 3]]) -> f64 {
    use kiddo::immutable::float::kdtree::ImmutableKdTree;
    use kiddo::SquaredEuclidean;
    if from.is_empty() {
        return 0.0;
    }
    let tree: ImmutableKdTree<f64, u32, 3, 32> = ImmutableKdTree::new_from_slice(from);
    points
        .par_iter()
        .map(|p| tree.nearest_one::<SquaredEuclidean>(p).distance)
        .reduce(|| 0.0, f64::max)
        .sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directed_hausdorff_is_the_farthest_nearest_distance_one_way() {
        let points = [[0.0, 0.0, 0.0], [3.0, 4.0, 0.0], [1.0, 0.0, 0.0]];
        let from = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        // (3, 4, 0) is √(2² + 4²) from (1, 0, 0), its nearest.
        assert!((directed_hausdorff(&points, &from) - 20f64.sqrt()).abs() < 1e-12);
        // The other way every point of `from` is in `points`.
        assert_eq!(directed_hausdorff(&from, &points), 0.0);
        assert_eq!(directed_hausdorff(&points, &[]), 0.0);
    }
}
