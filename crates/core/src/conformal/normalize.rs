//! Translation to the area centroid and scaling to unit area.

use super::FlattenError;
use crate::mesh::{triangle_area, Mesh};

/// A surface translated and scaled to unit area, with the transformation.
#[derive(Debug, Clone, PartialEq)]
pub struct Normalization {
    /// `(input − centroid) / scale`: area-weighted centroid at the origin,
    /// total area 1.
    pub mesh: Mesh,
    /// Area-weighted centroid of the input surface.
    pub centroid: [f64; 3],
    /// Square root of the input's surface area (the size that was divided
    /// out; lengths in the input are `scale` times those in `mesh`).
    pub scale: f64,
}

/// Translate the area-weighted centroid of `mesh` to the origin and scale it
/// to total area 1.
///
/// Fails on an empty mesh, out-of-range indices, non-finite coordinates and
/// zero total area.
pub fn normalize(mesh: &Mesh) -> Result<Normalization, FlattenError> {
    if mesh.faces.is_empty() || mesh.vertices.is_empty() {
        return Err(FlattenError::Empty);
    }
    if let Some(vertex) = mesh.first_non_finite_vertex() {
        return Err(FlattenError::NonFinite { vertex });
    }
    let n = mesh.vertices.len();
    let mut area = 0.0;
    let mut moment = [0.0; 3];
    for (fi, f) in mesh.faces.iter().enumerate() {
        if f.iter().any(|&v| v as usize >= n) {
            return Err(FlattenError::InvalidFace {
                face: fi,
                reason: format!("vertex index out of range (mesh has {n} vertices)"),
            });
        }
        let p = f.map(|v| mesh.vertices[v as usize]);
        let a = triangle_area(p[0], p[1], p[2]);
        area += a;
        for k in 0..3 {
            moment[k] += a * (p[0][k] + p[1][k] + p[2][k]) / 3.0;
        }
    }
    if !(area.is_finite() && area > 0.0) {
        return Err(FlattenError::Degenerate {
            reason: format!("total surface area is {area}"),
        });
    }
    let centroid = moment.map(|m| m / area);
    let scale = area.sqrt();
    let vertices = mesh
        .vertices
        .iter()
        .map(|p| [0, 1, 2].map(|k| (p[k] - centroid[k]) / scale))
        .collect();
    Ok(Normalization {
        mesh: Mesh::new(vertices, mesh.faces.clone()),
        centroid,
        scale,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::surface_area;

    #[test]
    fn unit_area_and_centred() {
        // A 2 × 3 rectangle at (5, 7, 1), made of two triangles.
        let m = Mesh::new(
            vec![[5., 7., 1.], [7., 7., 1.], [7., 10., 1.], [5., 10., 1.]],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let nm = normalize(&m).unwrap();
        assert!((surface_area(&nm.mesh) - 1.0).abs() < 1e-12);
        assert!((nm.scale - 6f64.sqrt()).abs() < 1e-12);
        for (c, e) in nm.centroid.iter().zip([6.0, 8.5, 1.0]) {
            assert!((c - e).abs() < 1e-12);
        }
        // Back to the input.
        for (p, q) in nm.mesh.vertices.iter().zip(&m.vertices) {
            for k in 0..3 {
                assert!((p[k] * nm.scale + nm.centroid[k] - q[k]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn degenerate_inputs_fail() {
        assert_eq!(normalize(&Mesh::default()), Err(FlattenError::Empty));
        let flat = Mesh::new(
            vec![[0., 0., 0.], [1., 0., 0.], [2., 0., 0.]],
            vec![[0, 1, 2]],
        );
        assert!(matches!(
            normalize(&flat),
            Err(FlattenError::Degenerate { .. })
        ));
    }
}
