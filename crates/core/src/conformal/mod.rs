//! Normalization and conformal flattening onto the unit disk.
//!
//! A disk-type surface is mapped conformally onto the unit disk with its
//! most central vertex at the origin: the discrete Green's function of the
//! cotangent Laplacian gives the harmonic measure of the boundary seen from
//! that vertex, which is exactly the boundary correspondence of the
//! conformal map; the harmonic extension of those boundary positions is the
//! map itself. One sparse Cholesky factorization serves all three solves.
//!
//! - [`normalize`]: centroid to the origin, area 1;
//! - [`flatten_to_disk`]: the conformal map to the disk;
//! - [`conformal_factor`], [`hyperbolic_density`]: the area distortion;
//! - [`quasi_conformal_ratios`], [`flipped_triangles`]: quality measures.

mod cholesky;
mod factor;
mod flatten;
mod intrinsic;
mod laplacian;
mod normalize;
mod quality;
mod validate;

pub(crate) use cholesky::CholeskyError;
pub use cholesky::SpdFactor;
pub use factor::conformal_factor;
pub(crate) use factor::hyperbolic_density;
pub use flatten::{
    central_vertex, flatten_to_disk, flatten_to_disk_with, DiskMap, LaplacianWeights,
};
pub use laplacian::cotangent_edge_weights;
pub(crate) use laplacian::shifted_stiffness;
pub use normalize::{normalize, Normalization};
pub use quality::{flipped_triangles, quasi_conformal_ratios};
pub use validate::check_disk_topology;

/// Why a surface could not be normalized or flattened.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FlattenError {
    /// The mesh has no faces or no vertices.
    #[error("the mesh is empty (no faces)")]
    Empty,
    /// A face refers to a vertex that does not exist, or repeats a vertex.
    #[error("face {face} is invalid: {reason}")]
    InvalidFace {
        /// Index of the face.
        face: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFinite {
        /// Index of the vertex.
        vertex: usize,
    },
    /// A vertex is used by no face.
    #[error("vertex {vertex} is not used by any face (clean the mesh first)")]
    UnreferencedVertex {
        /// Index of the vertex.
        vertex: usize,
    },
    /// An edge is shared by more than two faces, or a vertex is not a
    /// manifold vertex.
    #[error("the mesh is not manifold: {reason}")]
    NonManifold {
        /// Where and how.
        reason: String,
    },
    /// Two faces sharing an edge traverse it in the same direction.
    #[error("face orientation is inconsistent at edge {a}-{b}")]
    InconsistentOrientation {
        /// One end of the edge.
        a: u32,
        /// The other end.
        b: u32,
    },
    /// The surface is not a topological disk (one boundary loop, Euler
    /// characteristic 1).
    #[error(
        "the surface is not a topological disk: {boundary_loops} boundary loop(s), \
         Euler characteristic {euler_characteristic} (a disk has 1 and 1)"
    )]
    NotDisk {
        /// Number of boundary loops found.
        boundary_loops: usize,
        /// V − E + F.
        euler_characteristic: i64,
    },
    /// Zero area, zero-area faces or another degeneracy.
    #[error("degenerate geometry: {reason}")]
    Degenerate {
        /// What is degenerate.
        reason: String,
    },
    /// The linear solver failed.
    #[error("linear solve failed: {reason}")]
    Solve {
        /// The solver's message.
        reason: String,
    },
    /// The computed map folds over: some triangles change orientation.
    #[error("the disk map has {count} flipped triangle(s)")]
    Flipped {
        /// Number of triangles with non-positive signed area in the disk.
        count: usize,
    },
}

impl From<CholeskyError> for FlattenError {
    fn from(e: CholeskyError) -> Self {
        FlattenError::Solve {
            reason: e.to_string(),
        }
    }
}
