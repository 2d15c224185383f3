//! Why a surface cannot be prepared, or a prepared one cannot be used.

use crate::conformal::FlattenError;
use std::fmt;

/// Why a surface cannot be prepared or compared.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CpError {
    /// Too few vertices or faces for a surface.
    #[error("the surface is empty or degenerate ({vertices} vertices, {faces} faces)")]
    Degenerate {
        /// Vertex count.
        vertices: usize,
        /// Face count.
        faces: usize,
    },
    /// A face refers to a vertex the mesh does not have.
    #[error("invalid mesh: face {face} refers to vertex {vertex}, the mesh has {vertices}")]
    MissingVertex {
        /// Index of the face.
        face: usize,
        /// The vertex index it holds.
        vertex: u32,
        /// Vertex count.
        vertices: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("invalid mesh: vertex {vertex} has a coordinate that is not finite")]
    NonFinite {
        /// Index of the vertex.
        vertex: usize,
    },
    /// Normalization or the conformal flattening failed.
    #[error("cannot flatten the surface to the disk: {0}")]
    Flatten(#[from] FlattenError),
    /// The surface has no boundary loop (it is not disk-type).
    #[error("cannot flatten the surface to the disk: it has no boundary (not disk-type)")]
    NoBoundary,
    /// The flattening gave coordinates that are not finite.
    #[error("cannot flatten the surface to the disk: the disk coordinates are not finite")]
    NonFiniteDiskCoordinates,
    /// The prepared data is inconsistent (e.g. a corrupted cache entry).
    #[error("inconsistent prepared surface: {0}")]
    Inconsistent(Inconsistency),
}

/// What is inconsistent in a prepared surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Inconsistency {
    /// The per-vertex arrays differ in length.
    VertexArrays,
    /// A face, feature or sample refers to a vertex that does not exist.
    IndexOutOfRange,
    /// Samples and sample weights differ in number, or there are none.
    Samples,
    /// The point-location grid does not match the faces.
    LocateGrid,
    /// The sweep refers to a vertex that does not exist.
    SweepIndex,
    /// The sweep visits a vertex twice or before its parent.
    SweepOrder,
    /// The sweep leaves vertices out.
    SweepIncomplete,
}

impl fmt::Display for Inconsistency {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Inconsistency::VertexArrays => "per-vertex arrays differ in length",
            Inconsistency::IndexOutOfRange => "index out of range",
            Inconsistency::Samples => "samples and weights differ",
            Inconsistency::LocateGrid => "location grid does not match the faces",
            Inconsistency::SweepIndex => "sweep index out of range",
            Inconsistency::SweepOrder => "sweep order is not a breadth-first tree",
            Inconsistency::SweepIncomplete => "sweep does not visit every vertex",
        })
    }
}
