//! Landmark propagation through cP correspondences.
//!
//! A landmark `L` on the source surface is located on it (closest point:
//! a triangle and barycentric coordinates), carried through the
//! correspondence (the images of that triangle's three vertices, each a
//! point of the target given as a target triangle and barycentric
//! coordinates, interpolated with `L`'s barycentric coordinates) and
//! projected onto the target surface (closest point), so that the result
//! lies on the target, inside a triangle, not only at a vertex. Along a
//! path of specimens the same step is repeated from surface to surface.

use super::Landmarks;
use crate::pipeline::PreparedSurface;
use morphoid_core::clean::TriangleGrid;
use morphoid_core::cp::Prepared;
use morphoid_core::mesh::{dot, sub, Mesh};

/// Why landmarks cannot be propagated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PropagateError {
    /// A surface has no triangles or refers to missing vertices.
    #[error("the surface has no valid triangles")]
    InvalidSurface,
    /// The cleaned and the prepared forms of a surface disagree.
    #[error("the prepared surface has {prepared} vertices, the cleaned one {cleaned}")]
    Inconsistent {
        /// Vertices of the prepared surface.
        prepared: usize,
        /// Vertices of the cleaned surface.
        cleaned: usize,
    },
    /// The correspondence does not have one entry per source vertex.
    #[error("the correspondence has {found} entries for a source of {expected} vertices")]
    CorrespondenceLength {
        /// Source vertices.
        expected: usize,
        /// Correspondence entries.
        found: usize,
    },
    /// The correspondence names a triangle the target does not have.
    #[error("the correspondence names triangle {face}, the target has {faces}")]
    FaceOutOfRange {
        /// The triangle index.
        face: u32,
        /// Triangles of the target.
        faces: usize,
    },
    /// A landmark coordinate is NaN or infinite.
    #[error("landmark {0} has a non-finite coordinate")]
    NonFinite(usize),
    /// The path of surfaces and maps do not fit together.
    #[error("a path of {surfaces} surfaces needs {expected} maps, got {found}")]
    PathLength {
        /// Surfaces on the path.
        surfaces: usize,
        /// Maps needed.
        expected: usize,
        /// Maps given.
        found: usize,
    },
}

/// A triangle mesh in file units with a closest-point index.
#[derive(Debug, Clone)]
pub struct Surface {
    mesh: Mesh,
    grid: TriangleGrid,
}

impl Surface {
    /// Index a mesh; it must have at least one valid triangle.
    pub fn new(mesh: Mesh) -> Result<Self, PropagateError> {
        let grid = TriangleGrid::new(&mesh).ok_or(PropagateError::InvalidSurface)?;
        Ok(Self { mesh, grid })
    }

    /// The surface a correspondence of `ps.prepared` refers to, in the
    /// file's units: the cleaned vertices (the prepared ones are the same
    /// vertices normalized) with the prepared triangles (whose corner order
    /// the correspondence's barycentric coordinates follow).
    pub fn from_prepared(ps: &PreparedSurface) -> Result<Self, PropagateError> {
        let (prepared, cleaned) = (ps.prepared.vertices().len(), ps.cleaned.vertices.len());
        if prepared != cleaned {
            return Err(PropagateError::Inconsistent { prepared, cleaned });
        }
        Self::new(Mesh::new(
            ps.cleaned.vertices.clone(),
            ps.prepared.faces().to_vec(),
        ))
    }

    /// The surface of a prepared form alone (e.g. a cached reference, whose
    /// cleaned mesh is not kept), in the file's units: the normalized
    /// vertices scaled and translated back (`v · scale + centroid`), with
    /// the prepared triangles.
    pub fn from_normalized(p: &Prepared) -> Result<Self, PropagateError> {
        Self::new(Mesh::new(p.vertices_in_file_units(), p.faces().to_vec()))
    }

    /// The mesh.
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// The corners of triangle `face`.
    fn triangle(&self, face: u32) -> Option<[[f64; 3]; 3]> {
        let f = self.mesh.faces.get(face as usize)?;
        let v = &self.mesh.vertices;
        Some([
            *v.get(f[0] as usize)?,
            *v.get(f[1] as usize)?,
            *v.get(f[2] as usize)?,
        ])
    }

    /// The point of the surface closest to `p`.
    pub fn closest(&self, p: [f64; 3]) -> [f64; 3] {
        self.grid.closest_point(p).point
    }

    /// The point of triangle `face` with barycentric coordinates `bary`.
    pub fn point(&self, face: u32, bary: [f64; 3]) -> Option<[f64; 3]> {
        let t = self.triangle(face)?;
        Some(interpolate(&t, bary))
    }
}

/// A point on a surface: a triangle and barycentric coordinates in it
/// (in the triangle's corner order).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Triangle index.
    pub face: u32,
    /// Barycentric coordinates (non-negative, sum 1).
    pub bary: [f64; 3],
    /// Distance from the query point to the surface.
    pub distance: f64,
}

/// Landmarks carried to a target, with how far each input was from the
/// source surface (a large offset means the landmarks do not belong to
/// that surface or are in other coordinates).
#[derive(Debug, Clone, PartialEq)]
pub struct Propagated {
    /// The landmarks on the target, in the target's file units.
    pub landmarks: Landmarks,
    /// Distance of each input landmark to the source surface.
    pub source_offsets: Vec<f64>,
}

fn interpolate(t: &[[f64; 3]; 3], b: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|d| b[0] * t[0][d] + b[1] * t[1][d] + b[2] * t[2][d])
}

/// Barycentric coordinates of `p` (a point of the triangle's plane, or its
/// projection onto it) in the triangle `abc`, clamped to the triangle; a
/// degenerate triangle gives its first corner.
fn barycentric_coordinates(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let (e0, e1, ep) = (sub(b, a), sub(c, a), sub(p, a));
    let (d00, d01, d11) = (dot(e0, e0), dot(e0, e1), dot(e1, e1));
    let (d20, d21) = (dot(ep, e0), dot(ep, e1));
    let den = d00 * d11 - d01 * d01;
    if den.is_nan() || den <= f64::EPSILON * d00 * d11 || !den.is_finite() {
        return [1.0, 0.0, 0.0];
    }
    let v = (d11 * d20 - d01 * d21) / den;
    let w = (d00 * d21 - d01 * d20) / den;
    let mut bary = [1.0 - v - w, v, w].map(|x| if x.is_finite() { x.max(0.0) } else { 0.0 });
    let sum: f64 = bary.iter().sum();
    if sum > 0.0 {
        bary = bary.map(|x| x / sum);
    } else {
        bary = [1.0, 0.0, 0.0];
    }
    bary
}

/// The point of `surface` closest to `p`, as a triangle and barycentric
/// coordinates.
pub fn surface_point(surface: &Surface, p: [f64; 3]) -> SurfacePoint {
    let cp = surface.grid.closest_point(p);
    let bary = surface
        .triangle(cp.face)
        .map_or([1.0, 0.0, 0.0], |[a, b, c]| {
            barycentric_coordinates(cp.point, a, b, c)
        });
    SurfacePoint {
        face: cp.face,
        bary,
        distance: cp.distance,
    }
}

/// Check that `map` has one entry per vertex of `source` and names only
/// triangles of `target`.
fn check_map(
    source: &Surface,
    target: &Surface,
    map: &[(u32, [f64; 3])],
) -> Result<(), PropagateError> {
    if map.len() != source.mesh.vertices.len() {
        return Err(PropagateError::CorrespondenceLength {
            expected: source.mesh.vertices.len(),
            found: map.len(),
        });
    }
    let faces = target.mesh.faces.len();
    if let Some(&(face, _)) = map.iter().find(|(f, _)| *f as usize >= faces) {
        return Err(PropagateError::FaceOutOfRange { face, faces });
    }
    Ok(())
}

/// The image under `map` of the point `at` of `source`, before projection:
/// the barycentric combination of the images of the triangle's corners.
fn carry(
    source: &Surface,
    target: &Surface,
    map: &[(u32, [f64; 3])],
    at: SurfacePoint,
) -> Option<[f64; 3]> {
    let f = source.mesh.faces.get(at.face as usize)?;
    let mut images = [[0.0; 3]; 3];
    for (k, &v) in f.iter().enumerate() {
        let &(tf, tb) = map.get(v as usize)?;
        images[k] = target.point(tf, tb)?;
    }
    let p = interpolate(&images, at.bary);
    p.iter().all(|x| x.is_finite()).then_some(p)
}

/// Propagate `landmarks` (on `source`, in its file units) to `target`
/// through `map`, the correspondence source → target (for each source
/// vertex: a target triangle and barycentric coordinates). The results lie
/// on the target surface and keep their labels.
pub fn propagate(
    landmarks: &Landmarks,
    source: &Surface,
    target: &Surface,
    map: &[(u32, [f64; 3])],
) -> Result<Propagated, PropagateError> {
    check_map(source, target, map)?;
    let mut out = Landmarks {
        points: Vec::with_capacity(landmarks.len()),
        labels: landmarks.labels.clone(),
    };
    out.labels.resize(landmarks.len(), None);
    let mut offsets = Vec::with_capacity(landmarks.len());
    for (i, &p) in landmarks.points.iter().enumerate() {
        if !p.iter().all(|x| x.is_finite()) {
            return Err(PropagateError::NonFinite(i));
        }
        let at = surface_point(source, p);
        offsets.push(at.distance);
        // check_map has validated every index `carry` follows.
        let image = carry(source, target, map, at).ok_or(PropagateError::InvalidSurface)?;
        out.points.push(target.grid.closest_point(image).point);
    }
    Ok(Propagated {
        landmarks: out,
        source_offsets: offsets,
    })
}

/// Propagate `landmarks` step by step along `path` (the source first, the
/// target last) with `maps[k]` the correspondence `path[k] → path[k+1]`.
/// The offsets reported are those on the first surface.
pub fn propagate_along(
    landmarks: &Landmarks,
    path: &[&Surface],
    maps: &[&[(u32, [f64; 3])]],
) -> Result<Propagated, PropagateError> {
    if path.len() < 2 || maps.len() + 1 != path.len() {
        return Err(PropagateError::PathLength {
            surfaces: path.len(),
            expected: path.len().saturating_sub(1),
            found: maps.len(),
        });
    }
    let mut current = landmarks.clone();
    let mut first_offsets = None;
    for (k, map) in maps.iter().enumerate() {
        let step = propagate(&current, path[k], path[k + 1], map)?;
        first_offsets.get_or_insert(step.source_offsets);
        current = step.landmarks;
    }
    Ok(Propagated {
        landmarks: current,
        source_offsets: first_offsets.unwrap_or_default(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use morphoid_core::mesh::norm;

    fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
        norm(sub(a, b))
    }

    /// A unit square in the plane z = 0 made of two triangles.
    fn square(offset: [f64; 3]) -> Surface {
        let v = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]]
            .map(|p| [p[0] + offset[0], p[1] + offset[1], p[2] + offset[2]]);
        Surface::new(Mesh::new(v.to_vec(), vec![[0, 1, 2], [0, 2, 3]])).unwrap()
    }

    #[test]
    fn barycentric_coordinates_reproduce_the_point() {
        let (a, b, c) = ([0., 0., 0.], [2., 0., 0.], [0., 3., 1.]);
        let bary = [0.2, 0.5, 0.3];
        let p = interpolate(&[a, b, c], bary);
        let got = barycentric_coordinates(p, a, b, c);
        for k in 0..3 {
            assert!((got[k] - bary[k]).abs() < 1e-12);
        }
        // Outside: clamped into the triangle; degenerate: the first corner.
        let out = barycentric_coordinates([-1., -1., 0.], a, b, c);
        assert!(out.iter().all(|&x| x >= 0.0) && (out.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert_eq!(barycentric_coordinates(p, a, a, a), [1.0, 0.0, 0.0]);
    }

    #[test]
    fn identity_map_keeps_points_inside_triangles() {
        let s = square([0.0; 3]);
        // Each vertex maps onto itself: vertex 0 = corner 0 of face 0, …
        let map = vec![
            (0, [1.0, 0.0, 0.0]),
            (0, [0.0, 1.0, 0.0]),
            (0, [0.0, 0.0, 1.0]),
            (1, [0.0, 0.0, 1.0]),
        ];
        let mut lm = Landmarks::default();
        lm.push([0.3, 0.6, 0.2], Some("a".into()));
        lm.push([0.9, 0.25, -0.1], None);
        let out = propagate(&lm, &s, &s, &map).unwrap();
        assert!((distance(out.landmarks.points[0], [0.3, 0.6, 0.0])) < 1e-12);
        assert!((distance(out.landmarks.points[1], [0.9, 0.25, 0.0])) < 1e-12);
        assert_eq!(out.landmarks.labels, lm.labels);
        assert!((out.source_offsets[0] - 0.2).abs() < 1e-12);
    }

    #[test]
    fn translation_through_a_path() {
        let (a, b, c) = (
            square([0.0; 3]),
            square([5.0, 0.0, 0.0]),
            square([0.0, 7.0, 1.0]),
        );
        let map = vec![
            (0, [1.0, 0.0, 0.0]),
            (0, [0.0, 1.0, 0.0]),
            (0, [0.0, 0.0, 1.0]),
            (1, [0.0, 0.0, 1.0]),
        ];
        let lm = Landmarks::from_points(vec![[0.25, 0.5, 0.0]]);
        let out = propagate_along(&lm, &[&a, &b, &c], &[&map, &map]).unwrap();
        assert!(distance(out.landmarks.points[0], [0.25, 7.5, 1.0]) < 1e-12);
        assert!(matches!(
            propagate_along(&lm, &[&a, &b], &[&map, &map]),
            Err(PropagateError::PathLength { .. })
        ));
    }

    #[test]
    fn bad_maps_and_landmarks_are_errors() {
        let s = square([0.0; 3]);
        let lm = Landmarks::from_points(vec![[0.5, 0.5, 0.0]]);
        assert!(matches!(
            propagate(&lm, &s, &s, &[(0, [1.0, 0.0, 0.0])]),
            Err(PropagateError::CorrespondenceLength { .. })
        ));
        let map = vec![(9, [1.0, 0.0, 0.0]); 4];
        assert!(matches!(
            propagate(&lm, &s, &s, &map),
            Err(PropagateError::FaceOutOfRange { face: 9, .. })
        ));
        let map = vec![(0, [1.0, 0.0, 0.0]); 4];
        let nan = Landmarks::from_points(vec![[f64::NAN, 0.0, 0.0]]);
        assert!(matches!(
            propagate(&nan, &s, &s, &map),
            Err(PropagateError::NonFinite(0))
        ));
        assert!(Surface::new(Mesh::new(vec![[0.0; 3]], vec![])).is_err());
    }
}
