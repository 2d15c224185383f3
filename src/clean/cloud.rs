//! Triangulation of a point cloud into a surface that follows the points.

use crate::mesh::{dot, norm, sub, Mesh};
use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

/// A projected point remembering its index in the cloud.
#[derive(Debug, Clone, Copy)]
struct Indexed {
    position: Point2<f64>,
    index: u32,
}

impl HasPosition for Indexed {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.position
    }
}

/// Principal axes of a point set: `(centroid, [axis of largest spread,
/// second, normal])`, the normal being the axis of least spread. `None`
/// for fewer than three points.
pub fn principal_axes(points: &[[f64; 3]]) -> Option<([f64; 3], [[f64; 3]; 3])> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let mut c = [0.0; 3];
    for p in points {
        for d in 0..3 {
            c[d] += p[d] / n;
        }
    }
    let mut cov = nalgebra::Matrix3::<f64>::zeros();
    for p in points {
        let q = nalgebra::Vector3::new(p[0] - c[0], p[1] - c[1], p[2] - c[2]);
        cov += q * q.transpose();
    }
    let eig = nalgebra::SymmetricEigen::new(cov);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let axis = |k: usize| {
        let col = eig.eigenvectors.column(order[k]);
        [col[0], col[1], col[2]]
    };
    let (u, v) = (axis(0), axis(1));
    // Right-handed frame: the normal is u × v.
    let w = crate::mesh::cross(u, v);
    Some((c, [u, v, w]))
}

/// Coordinates of the points in their best-fit (PCA) plane.
pub fn planar_coordinates(points: &[[f64; 3]]) -> Option<Vec<[f64; 2]>> {
    let (c, [u, v, _]) = principal_axes(points)?;
    Some(
        points
            .iter()
            .map(|p| {
                let q = sub(*p, c);
                [dot(q, u), dot(q, v)]
            })
            .collect(),
    )
}

/// Coordinates of the directions from a viewpoint to the points, mapped to
/// the plane by stereographic projection from the pole `-up` (`up` = ±the
/// PCA normal). A dome-like surface (a crown, even with overhanging walls)
/// is star-shaped from a point inside it, so its points map one to one; the
/// open side faces the pole, far from every point. Stereographic projection
/// maps circles to circles, so the planar Delaunay triangulation is the
/// spherical one of the directions.
pub fn stereographic_coordinates(points: &[[f64; 3]], up_sign: f64) -> Option<Vec<[f64; 2]>> {
    let (c, [u, v, w]) = principal_axes(points)?;
    let w = w.map(|x| x * up_sign);
    let v = v.map(|x| x * up_sign);
    // Viewpoint: on the axis, below the lowest point by as much again (the
    // open side of a dome, e.g. below the cervical margin of a crown), so
    // that overhanging walls are seen from below.
    let low = points
        .iter()
        .map(|p| dot(sub(*p, c), w))
        .fold(0.0f64, f64::min);
    let eye = [0, 1, 2].map(|d| c[d] + 2.0 * low * w[d]);
    Some(
        points
            .iter()
            .map(|p| {
                let q = sub(*p, eye);
                let r = norm(q);
                if r <= 0.0 {
                    return [0.0, 0.0];
                }
                let (x, y, z) = (dot(q, u) / r, dot(q, v) / r, dot(q, w) / r);
                // Directions next to the pole go far out (capped).
                let den = (1.0 + z).max(1e-9);
                [x / den, y / den]
            })
            .collect(),
    )
}

/// 2D Delaunay triangulation of `coords` (one per point), improved by
/// Delaunay edge flips in 3D, keeping the triangles whose longest edge, in
/// 3D, is at most `max_edge_factor` times the median 3D edge length. `None` when the coordinates span no
/// area.
pub fn delaunay_surface(
    points: &[[f64; 3]],
    coords: &[[f64; 2]],
    max_edge_factor: f64,
) -> Option<Mesh> {
    let projected: Vec<Indexed> = coords
        .iter()
        .enumerate()
        .map(|(i, q)| Indexed {
            position: Point2::new(q[0], q[1]),
            index: i as u32,
        })
        .collect();
    let dt: DelaunayTriangulation<Indexed> =
        DelaunayTriangulation::bulk_load_stable(projected).ok()?;
    let mut tris: Vec<[u32; 3]> = dt
        .inner_faces()
        .map(|f| f.vertices().map(|h| h.data().index))
        .collect();
    // Canonical order for determinism.
    for t in &mut tris {
        let m = (0..3).min_by_key(|&k| t[k]).unwrap_or(0);
        t.rotate_left(m);
    }
    tris.sort_unstable();
    if tris.is_empty() {
        return None;
    }
    // Delaunay flips in 3D repair what the projection got wrong where the
    // surface is steep: the 2D triangulation joins far-apart points there.
    tris =
        super::resample::flip_to_delaunay(&Mesh::new(points.to_vec(), tris), 150f64.to_radians())
            .0
            .faces;
    let edge =
        |t: &[u32; 3], k: usize| norm(sub(points[t[k] as usize], points[t[(k + 1) % 3] as usize]));
    let mut lengths: Vec<f64> = tris
        .iter()
        .flat_map(|t| (0..3).map(move |k| edge(t, k)))
        .collect();
    lengths.sort_by(f64::total_cmp);
    let limit = max_edge_factor * lengths[lengths.len() / 2];
    let faces: Vec<[u32; 3]> = tris
        .into_iter()
        .filter(|t| (0..3).all(|k| edge(t, k) <= limit))
        .collect();
    Some(Mesh::new(points.to_vec(), faces))
}

/// Triangulate a point cloud that samples a disk-like surface. Three
/// candidate triangulations are built with [`delaunay_surface`]: from the
/// best-fit plane ([`planar_coordinates`], right for flat-ish patches) and
/// from the stereographic map of directions seen from the centroid, with
/// the open side on either side of the plane
/// ([`stereographic_coordinates`], right for domes whose walls fold over
/// in a planar projection). Triangles that bridge gaps or layers are gone;
/// the candidate whose largest connected piece has the most triangles wins.
/// The result may still have small pieces and holes: the cleaning pipeline
/// keeps the largest piece and fills its holes. `None` when the points span
/// no plane.
pub fn triangulate_point_cloud(points: &[[f64; 3]], max_edge_factor: f64) -> Option<Mesh> {
    let candidates = [
        planar_coordinates(points),
        stereographic_coordinates(points, 1.0),
        stereographic_coordinates(points, -1.0),
    ];
    let mut best: Option<(usize, Mesh)> = None;
    for coords in candidates.into_iter().flatten() {
        let Some(m) = delaunay_surface(points, &coords, max_edge_factor) else {
            continue;
        };
        let (piece, _) = super::components::largest_component_by_area(&m);
        // Coverage = triangles in the largest piece (area would reward
        // triangles that bridge over a concave side).
        let count = piece.faces.len();
        if best.as_ref().is_none_or(|(c, _)| count > *c) {
            best = Some((count, m));
        }
    }
    best.map(|(_, m)| m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::euler_characteristic;

    #[test]
    fn cloud_of_a_cap_becomes_a_disk() {
        // Points on a spherical cap, on a jittered grid.
        let mut pts = Vec::new();
        for i in 0..15 {
            for j in 0..15 {
                let x = (i as f64 - 7.0) / 7.0 + 0.01 * ((i * 7 + j * 3) as f64).sin();
                let y = (j as f64 - 7.0) / 7.0 + 0.01 * ((i * 5 + j * 11) as f64).cos();
                if x * x + y * y <= 1.0 {
                    pts.push([x, y, (2.0 - x * x - y * y).sqrt()]);
                }
            }
        }
        let m = triangulate_point_cloud(&pts, 3.0).expect("triangulation");
        assert!(m.faces.len() > pts.len());
        assert_eq!(euler_characteristic(&m), 1);
        // Outward-pointing normal of the plane (cap bulges along it).
        let (_, [_, _, w]) = principal_axes(&pts).expect("axes");
        assert!(w[2].abs() > 0.99);
    }
}
