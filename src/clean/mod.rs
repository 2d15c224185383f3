//! Cleaning: from a raw scan to a clean disk-type triangle mesh.
//!
//! (interface sketch; to be implemented)

use crate::mesh::Mesh;

/// Parameters of the cleaning pipeline.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct CleanOptions {
    /// Working resolution: the cleaned mesh has about this many vertices.
    pub target_vertices: usize,
}

impl Default for CleanOptions {
    fn default() -> Self {
        Self {
            target_vertices: 5000,
        }
    }
}

/// What cleaning changed.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct CleanReport {
    /// Vertices merged into others by welding.
    pub welded_vertices: usize,
    /// Degenerate or duplicate faces removed.
    pub removed_faces: usize,
    /// Connected components dropped (debris).
    pub dropped_components: usize,
    /// Holes filled.
    pub filled_holes: usize,
}

/// A cleaned mesh and the report of what was done.
#[derive(Debug, Clone)]
pub struct Cleaned {
    /// The clean, disk-type mesh.
    pub mesh: Mesh,
    /// What was changed.
    pub report: CleanReport,
}

/// Why a surface cannot be made disk-type.
#[derive(Debug, thiserror::Error)]
pub enum CleanError {
    /// The surface is closed (no boundary).
    #[error("the surface is closed (no boundary loop); a disk-type surface is needed")]
    Closed,
}

/// Run the whole cleaning pipeline.
pub fn clean(mesh: &Mesh, opts: &CleanOptions) -> Result<Cleaned, CleanError> {
    let _ = (mesh, opts);
    todo!()
}
