//! What a comparison returns: the directed results `S → S′` and `S′ → S`
//! and the symmetric distance.

use super::mobius::Mobius;
use super::warp::DiskWarp;
use serde::{Deserialize, Serialize};

/// For each vertex of a source surface: a face of the target and the
/// barycentric coordinates of the vertex's image in it.
pub type Correspondence = Vec<(u32, [f64; 3])>;

/// The result of one directed comparison `S → S′`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Directed {
    /// `d(S, S′)`: root of the area-weighted mean squared residual over all
    /// vertices of S after the optimal rigid motion (surfaces of area 1).
    pub distance: f64,
    /// Whether the map reverses orientation (a mirror-image match, with an
    /// improper rigid motion).
    pub reflected: bool,
    /// The disk map from S's disk to S′'s disk.
    pub mobius: Mobius,
    /// The feature-aligning deformation applied after `mobius`, if it
    /// lowered the distance.
    pub warp: Option<DiskWarp>,
    /// The distance of the best map of the search, before the final steps
    /// (the deformation of that map alone, when candidates are not warped,
    /// and the area correction χ).
    pub search_distance: f64,
    /// The optimal orthogonal matrix (row-major) applied to S.
    pub rotation: [[f64; 3]; 3],
    /// The optimal translation applied to S after the rotation.
    pub translation: [f64; 3],
    /// For each vertex of S: the face of S′ and barycentric coordinates of
    /// its image.
    pub correspondence: Correspondence,
}

/// Both directed comparisons and the symmetric distance.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Comparison {
    /// `min(d(S, S′), d(S′, S))`.
    pub distance: f64,
    /// `S → S′`.
    pub forward: Directed,
    /// `S′ → S`.
    pub backward: Directed,
    /// Whether the better direction matched a mirror image.
    pub reflected: bool,
}
