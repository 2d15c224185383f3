//! Triangulation of a point cloud into a surface that follows the points.

use crate::mesh::{norm, sub, Mesh};
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

/// Triangulate a point cloud that samples a disk-like surface: project the
/// points onto their best-fit (PCA) plane, build the 2D Delaunay
/// triangulation, and drop the triangles that have an edge longer, in 3D,
/// than `max_edge_factor` times the median 3D edge length (they bridge gaps
/// or layers that the projection brought together). The result may have
/// several pieces and holes; the cleaning pipeline then keeps the largest
/// piece and fills its holes. Returns `None` when the points span no plane.
pub fn triangulate_point_cloud(points: &[[f64; 3]], max_edge_factor: f64) -> Option<Mesh> {
    let (c, [u, v, _]) = principal_axes(points)?;
    let projected: Vec<Indexed> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let q = sub(*p, c);
            Indexed {
                position: Point2::new(crate::mesh::dot(q, u), crate::mesh::dot(q, v)),
                index: i as u32,
            }
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
    let longest = |t: &[u32; 3]| {
        (0..3)
            .map(|k| norm(sub(points[t[k] as usize], points[t[(k + 1) % 3] as usize])))
            .fold(0.0, f64::max)
    };
    let mut lengths: Vec<f64> = tris
        .iter()
        .flat_map(|t| {
            (0..3).map(move |k| norm(sub(points[t[k] as usize], points[t[(k + 1) % 3] as usize])))
        })
        .collect();
    lengths.sort_by(f64::total_cmp);
    let median = lengths[lengths.len() / 2];
    let limit = max_edge_factor * median;
    let faces: Vec<[u32; 3]> = tris.into_iter().filter(|t| longest(t) <= limit).collect();
    Some(Mesh::new(points.to_vec(), faces))
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
