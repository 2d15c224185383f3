//! Triangle meshes: the plain data type every stage shares, its elementary
//! geometry, and in submodules:
//! - `topology`: the one definition of each combinatorial concept (the
//!   edge map, boundary loops and the longest one, the Euler
//!   characteristic, the genus, vertex and triangle adjacency);
//! - `graph`: edge-path distances and breadth-first orders;
//! - `subdivide`: midpoint subdivision;
//! - `disk`: the triangulated unit disk;
//! - `grid`, `isosurface`: a scalar field on a regular grid and its
//!   closed isosurface (marching tetrahedra);
//! - [`io`]: reading and writing files;
//! - [`synth`]: the synthetic surface generator (tests and the demo only;
//!   nothing numerical depends on it).

mod axes;
mod disk;
mod farthest;
mod graph;
mod grid;
mod isosurface;
mod subdivide;
mod topology;

pub use axes::principal_axes;
pub(crate) use axes::weighted_principal_axes;
pub use disk::{ring_count, ring_disk, unit_disk};
pub use farthest::farthest_point_order;
pub(crate) use graph::HeapItem;
pub(crate) use graph::{breadth_first_tree, graph_distance};
pub(crate) use grid::point_inside_by_parity;
pub use grid::{inside_by_parity, Grid};
pub use isosurface::isosurface;
pub use subdivide::subdivide_midpoint;
pub use topology::{
    boundary_loops, boundary_vertices, edge_face_map, euler_characteristic, genus,
    longest_boundary_loop, widest_boundary_loop_extent,
};
pub(crate) use topology::{
    boundary_loops_by_length, edge_key, sort_distinct, triangle_adjacency, vertex_adjacency,
    EdgeKey, EdgeMap, HalfEdges, NO_TRIANGLE,
};
pub(crate) use topology::{half_edge_ends, has_directed_edge};

/// A triangle mesh (or, with no faces, a point cloud).
///
/// Plain data: positions in the units of the source file, faces as
/// counter-clockwise vertex index triples (outward normal by the right-hand
/// rule, once orientation has been made consistent by cleaning).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as indices into `vertices`.
    pub faces: Vec<[u32; 3]>,
}

impl Mesh {
    /// A mesh from vertices and faces, unchecked.
    pub fn new(vertices: Vec<[f64; 3]>, faces: Vec<[u32; 3]>) -> Self {
        Self { vertices, faces }
    }

    /// True when the mesh has no faces (a point cloud).
    pub fn is_point_cloud(&self) -> bool {
        self.faces.is_empty()
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.vertices.len()
    }

    /// Number of faces.
    pub fn face_count(&self) -> usize {
        self.faces.len()
    }

    /// The first vertex with a non-finite coordinate, if any.
    pub fn first_non_finite_vertex(&self) -> Option<usize> {
        self.vertices
            .iter()
            .position(|p| p.iter().any(|c| !c.is_finite()))
    }

    /// The first face that refers to a vertex past the last one, and that
    /// index, if any.
    pub fn first_face_out_of_range(&self) -> Option<(usize, u32)> {
        let n = self.vertices.len();
        self.faces
            .iter()
            .enumerate()
            .find_map(|(fi, f)| f.iter().find(|&&v| v as usize >= n).map(|&bad| (fi, bad)))
    }
}

/// Vector difference `a - b`.
#[inline]
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Cross product `a × b`.
#[inline]
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Dot product.
#[inline]
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Euclidean norm.
#[inline]
pub fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// `a` scaled to length one (zero stays zero).
pub fn unit(a: [f64; 3]) -> [f64; 3] {
    let l = norm(a);
    if l > 0.0 {
        a.map(|x| x / l)
    } else {
        a
    }
}

/// Two unit vectors that make a right-handed orthonormal frame with the
/// unit vector `axis` (`[u, v]`, `u × v = axis`); the same frame each
/// time for the same axis.
pub fn perpendicular_frame(axis: [f64; 3]) -> [[f64; 3]; 2] {
    // Far from parallel to the axis, so the cross product is never zero.
    let helper = if axis[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = unit(cross(axis, helper));
    [u, cross(axis, u)]
}

/// Unit vertex normals: the sum of the (area-weighted) normals of the
/// faces around each vertex; zero for a vertex in no face. Faces with an
/// index out of range are skipped.
pub fn vertex_normals(vertices: &[[f64; 3]], faces: &[[u32; 3]]) -> Vec<[f64; 3]> {
    let mut n = vec![[0.0; 3]; vertices.len()];
    for f in faces {
        let [a, b, c] = f.map(|i| i as usize);
        let (Some(&pa), Some(&pb), Some(&pc)) = (vertices.get(a), vertices.get(b), vertices.get(c))
        else {
            continue;
        };
        let face = triangle_normal2(pa, pb, pc);
        for v in [a, b, c] {
            for d in 0..3 {
                n[v][d] += face[d];
            }
        }
    }
    n.into_iter().map(unit).collect()
}

/// Area-weighted (unnormalized) normal of a triangle: `(b - a) × (c - a)`,
/// whose length is twice the triangle's area.
#[inline]
pub fn triangle_normal2(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    cross(sub(b, a), sub(c, a))
}

/// Area of the triangle `abc`.
#[inline]
pub(crate) fn triangle_area(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    0.5 * norm(triangle_normal2(a, b, c))
}

/// Area of every face.
pub fn face_areas(mesh: &Mesh) -> Vec<f64> {
    mesh.faces
        .iter()
        .map(|f| {
            triangle_area(
                mesh.vertices[f[0] as usize],
                mesh.vertices[f[1] as usize],
                mesh.vertices[f[2] as usize],
            )
        })
        .collect()
}

/// Total surface area.
pub fn surface_area(mesh: &Mesh) -> f64 {
    face_areas(mesh).iter().sum()
}

/// Barycentric vertex areas: a third of the area of each incident face.
pub(crate) fn vertex_areas(mesh: &Mesh) -> Vec<f64> {
    let mut areas = vec![0.0; mesh.vertices.len()];
    for (f, a) in mesh.faces.iter().zip(face_areas(mesh)) {
        for &v in f {
            areas[v as usize] += a / 3.0;
        }
    }
    areas
}

/// Axis-aligned bounding box `(min, max)` of `points`; `None` when there
/// is no point.
pub(crate) fn points_bounding_box(
    points: impl IntoIterator<Item = [f64; 3]>,
) -> Option<([f64; 3], [f64; 3])> {
    let mut points = points.into_iter();
    let first = points.next()?;
    let (mut lo, mut hi) = (first, first);
    for v in points {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    Some((lo, hi))
}

/// Axis-aligned bounding box `(min, max)` of the vertices; `None` for an
/// empty mesh.
pub fn bounding_box(mesh: &Mesh) -> Option<([f64; 3], [f64; 3])> {
    points_bounding_box(mesh.vertices.iter().copied())
}

/// The triangles with their winding reversed: every normal flipped.
pub fn reversed_winding(faces: &[[u32; 3]]) -> Vec<[u32; 3]> {
    faces.iter().map(|f| [f[0], f[2], f[1]]).collect()
}

/// Length of the bounding-box diagonal (0 for an empty mesh).
pub fn bbox_diagonal(mesh: &Mesh) -> f64 {
    bounding_box(mesh).map_or(0.0, |(lo, hi)| norm(sub(hi, lo)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_bad_vertex_and_face_are_found() {
        let mut m = Mesh::new(
            vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            vec![[0, 1, 2], [2, 1, 0]],
        );
        assert_eq!(m.first_non_finite_vertex(), None);
        assert_eq!(m.first_face_out_of_range(), None);
        m.vertices[2][1] = f64::NAN;
        m.vertices[1][0] = f64::INFINITY;
        assert_eq!(m.first_non_finite_vertex(), Some(1));
        m.faces.push([0, 7, 3]);
        m.faces.push([5, 0, 1]);
        assert_eq!(m.first_face_out_of_range(), Some((2, 7)));
    }
}
