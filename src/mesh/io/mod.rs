//! Reading and writing OBJ, PLY, STL and OFF.
//!
//! (interface sketch; to be implemented)

use super::Mesh;
use std::path::{Path, PathBuf};

/// A surface file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// Wavefront OBJ.
    Obj,
    /// Stanford PLY (ASCII or binary).
    Ply,
    /// STL (ASCII or binary).
    Stl,
    /// Object File Format.
    Off,
}

/// A mesh as read from a file, with the format it came in.
#[derive(Debug, Clone)]
pub struct LoadedMesh {
    /// The vertices and faces as stored (faces empty for a point cloud).
    pub mesh: Mesh,
    /// The detected format.
    pub format: Format,
}

/// Why a file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// Any failure, with the file it concerns.
    #[error("{path}: {message}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong (and where, line or byte offset).
        message: String,
    },
}

/// Read a mesh, choosing the reader from the file extension.
pub fn load(path: &Path) -> Result<LoadedMesh, LoadError> {
    let _ = path;
    todo!()
}
