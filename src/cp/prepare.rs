//! Preparation of a surface for comparison: normalization, flattening,
//! conformal factor, features, samples and the point-location grid.

use super::features::{local_maxima, smooth_vertex_function};
use super::locate::LocateGrid;
use super::moser::disk_measure;
use super::samples::farthest_point_samples;
use crate::conformal::{self, conformal_factor, hyperbolic_density};
use crate::mesh::{self, Mesh};
use crate::mesh::{breadth_first_tree, graph_distance, vertex_adjacency};
use serde::{Deserialize, Serialize};

/// Parameters of the cP engine (the `[cp]` configuration section).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CpParams {
    /// Number of samples spread over each surface for the map search.
    pub samples: usize,
    /// The first (farthest-point) samples used to score the coarse search
    /// over feature pairs and angles; refinement uses all samples.
    pub coarse_samples: usize,
    /// At most this many feature points per surface.
    pub max_features: usize,
    /// Smoothing steps (one-ring averaging) of the conformal density before
    /// its maxima are taken.
    pub density_smoothing: usize,
    /// Minimal distance between two features (surface of area 1).
    pub feature_separation: f64,
    /// Features lie within this radius of the disk (away from the boundary).
    pub feature_max_radius: f64,
    /// Rotation angles tried for each feature pair.
    pub angles: usize,
    /// Candidates (best by sample score) that are refined.
    pub refine_candidates: usize,
    /// Objective evaluations of the local refinement of each candidate.
    pub refine_evaluations: usize,
    /// Whether maps are followed by a smooth deformation ϱ bringing
    /// features onto their mutually nearest features.
    pub feature_warp: bool,
    /// Whether every candidate of the search is scored after its own
    /// deformation, as in the paper (otherwise only the best map is
    /// deformed, and the deformation kept when it lowers the distance).
    pub search_warp: bool,
    /// Candidates of the coarse search that bring fewer than this many
    /// features onto mutually nearest features are left out (capped by the
    /// feature counts; if no map qualifies, none is left out).
    pub min_feature_matches: usize,
    /// Width of that deformation's Gaussian kernel (disk units).
    pub warp_width: f64,
    /// Features farther apart than this (hyperbolic distance) are not
    /// matched by the deformation.
    pub warp_max_match: f64,
    /// Whether orientation-reversing maps (mirror images) are searched.
    pub reflections: bool,
    /// Whether the final map is made area preserving (Moser's flow) before
    /// it is evaluated.
    pub area_correction: bool,
    /// Steps of the final descent: Gauss–Newton steps that lower the
    /// area-corrected map's residual, each made area preserving again
    /// (needs `area_correction`; 0 turns it off).
    pub descent_steps: usize,
    /// Smoothing steps (face averaging over the source surface) of each
    /// descent step's displacement field, which keep the map regular.
    pub descent_smoothing: usize,
    /// Fraction of the Gauss–Newton step taken.
    pub descent_damping: f64,
    /// Whether `compare` descends both directed maps (otherwise only the
    /// one with the smaller distance after the search).
    pub descent_both_directions: bool,
}

impl Default for CpParams {
    fn default() -> Self {
        Self {
            samples: 150,
            coarse_samples: 40,
            max_features: 5,
            density_smoothing: 3,
            feature_separation: 0.1,
            feature_max_radius: 0.9,
            angles: 12,
            refine_candidates: 2,
            refine_evaluations: 60,
            feature_warp: true,
            search_warp: true,
            min_feature_matches: 3,
            warp_width: 0.25,
            warp_max_match: 1.0,
            reflections: true,
            area_correction: true,
            descent_steps: 2,
            descent_smoothing: 10,
            descent_damping: 0.5,
            descent_both_directions: false,
        }
    }
}

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
    /// A face refers to a missing vertex, or a coordinate is not finite.
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
    /// The conformal flattening failed.
    #[error("cannot flatten the surface to the disk: {0}")]
    Flatten(String),
    /// The prepared data is inconsistent (e.g. a corrupted cache entry).
    #[error("inconsistent prepared surface: {0}")]
    Inconsistent(String),
}

/// A surface ready for cP comparisons (cacheable).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Prepared {
    /// Name of the specimen (set by the caller; used for matrices).
    pub name: String,
    /// Vertices after normalization (area-weighted centroid at the origin,
    /// area 1).
    pub vertices: Vec<[f64; 3]>,
    /// Faces, oriented so that the surface capped at its boundary has
    /// positive volume (a canonical orientation).
    pub faces: Vec<[u32; 3]>,
    /// Whether the input faces were reversed to get that orientation.
    pub reoriented: bool,
    /// Area-weighted centroid of the input surface.
    pub centroid: [f64; 3],
    /// Square root of the input surface area (the size that was divided
    /// out).
    pub scale: f64,
    /// Disk coordinates of the vertices.
    pub uv: Vec<[f64; 2]>,
    /// Vertex areas of the normalized surface (sum 1).
    pub vertex_areas: Vec<f64>,
    /// Smoothed hyperbolic conformal density at each vertex.
    pub density: Vec<f64>,
    /// Feature vertices, strongest first.
    pub features: Vec<u32>,
    /// Sample vertices.
    pub samples: Vec<u32>,
    /// Voronoi-cell area of each sample (sum 1).
    pub sample_weights: Vec<f64>,
    /// Point-location grid over the disk triangulation.
    pub grid: LocateGrid,
    /// The vertices in breadth-first order, each as `[vertex, parent]`
    /// with the parent an earlier neighbour: mapping vertices in this
    /// order, each image is searched from a nearby one's triangle.
    pub sweep: Vec<[u32; 2]>,
    /// The surface's area as a measure on the vertices of the fixed disk
    /// triangulation of the area correction (the target of the flow when
    /// this surface is the target); empty if it could not be computed.
    pub disk_mass: Vec<f64>,
}

impl Prepared {
    /// Check internal consistency (lengths and indices), e.g. after reading
    /// a cached copy.
    pub fn validate(&self) -> Result<(), CpError> {
        let n = self.vertices.len();
        let bad = |m: &str| Err(CpError::Inconsistent(m.to_string()));
        if self.uv.len() != n || self.vertex_areas.len() != n || self.density.len() != n {
            return bad("per-vertex arrays differ in length");
        }
        if self.faces.iter().flatten().any(|&v| v as usize >= n)
            || self
                .features
                .iter()
                .chain(&self.samples)
                .any(|&v| v as usize >= n)
        {
            return bad("index out of range");
        }
        if self.samples.len() != self.sample_weights.len() || self.samples.is_empty() {
            return bad("samples and weights differ");
        }
        let r = self.grid.resolution as usize;
        if self.grid.starts.len() != r * r + 1
            || self.grid.starts.last().map(|&s| s as usize) != Some(self.grid.items.len())
            || self
                .grid
                .items
                .iter()
                .any(|&f| f as usize >= self.faces.len())
            || self.grid.adjacency.len() != self.faces.len()
            || self
                .grid
                .adjacency
                .iter()
                .flatten()
                .any(|&f| f != super::locate::NO_TRIANGLE && f as usize >= self.faces.len())
        {
            return bad("location grid does not match the faces");
        }
        let mut seen = vec![false; n];
        for &[v, parent] in &self.sweep {
            let Some(&parent_seen) = seen.get(parent as usize) else {
                return bad("sweep index out of range");
            };
            let Some(s) = seen.get_mut(v as usize) else {
                return bad("sweep index out of range");
            };
            if *s || !(parent_seen || parent == v) {
                return bad("sweep order is not a breadth-first tree");
            }
            *s = true;
        }
        if self.sweep.len() != n {
            return bad("sweep does not visit every vertex");
        }
        Ok(())
    }
}

/// Signed volume of the surface closed by a cone from its boundary
/// centroid (the cone itself contributes nothing from its apex).
fn capped_volume(m: &Mesh, boundary: &[u32]) -> f64 {
    let mut o = [0.0; 3];
    for &b in boundary {
        let p = m.vertices[b as usize];
        for k in 0..3 {
            o[k] += p[k] / boundary.len().max(1) as f64;
        }
    }
    m.faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|v| mesh::sub(m.vertices[v as usize], o));
            mesh::dot(a, mesh::cross(b, c)) / 6.0
        })
        .sum()
}

/// The strongest local maxima of `values` among `eligible` vertices, at
/// most `max_count`, each at least `separation` (graph distance on the
/// surface) from those chosen before it.
fn separated_maxima(
    m: &Mesh,
    adjacency: &[Vec<u32>],
    values: &[f64],
    eligible: &[bool],
    max_count: usize,
    separation: f64,
) -> Vec<u32> {
    let mut cache: std::collections::HashMap<u32, Vec<f64>> = Default::default();
    let cands = local_maxima(adjacency, values, eligible, usize::MAX, 0.0, |_, _| 0.0);
    let mut out: Vec<u32> = Vec::new();
    for c in cands {
        if out.len() >= max_count {
            break;
        }
        let far = out.iter().all(|&o| {
            let d = cache.entry(o).or_insert_with(|| graph_distance(m, &[o]));
            d[c as usize] >= separation
        });
        if far {
            out.push(c);
        }
    }
    out
}

/// Prepare a cleaned disk-type mesh for cP comparisons.
pub fn prepare(input: &Mesh, params: &CpParams) -> Result<Prepared, CpError> {
    let n = input.vertices.len();
    if n < 4 || input.faces.len() < 2 {
        return Err(CpError::Degenerate {
            vertices: n,
            faces: input.faces.len(),
        });
    }
    if input.faces.iter().flatten().any(|&v| v as usize >= n) {
        return Err(CpError::InvalidMesh(
            "a face refers to a missing vertex".into(),
        ));
    }
    if input.vertices.iter().flatten().any(|x| !x.is_finite()) {
        return Err(CpError::InvalidMesh("a coordinate is not finite".into()));
    }
    let norm = conformal::normalize(input).map_err(|e| CpError::Flatten(e.to_string()))?;
    let (centroid, scale) = (norm.centroid, norm.scale);
    let mut m = norm.mesh;
    let loops = mesh::boundary_loops(&m);
    let boundary = loops
        .first()
        .ok_or_else(|| CpError::Flatten("the surface has no boundary (not disk-type)".into()))?;
    let reoriented = capped_volume(&m, boundary) < 0.0;
    if reoriented {
        for f in &mut m.faces {
            f.swap(1, 2);
        }
    }
    let disk = conformal::flatten_to_disk(&m).map_err(|e| CpError::Flatten(e.to_string()))?;
    let (uv, center) = (disk.uv, disk.center);
    if uv.len() != n || uv.iter().any(|z| !(z[0].is_finite() && z[1].is_finite())) {
        return Err(CpError::Flatten("invalid disk coordinates".into()));
    }
    let vertex_areas = mesh::vertex_areas(&m);
    let adjacency = vertex_adjacency(&m);
    let factor = conformal_factor(&m, &uv);
    let density = smooth_vertex_function(
        &adjacency,
        &vertex_areas,
        &hyperbolic_density(&uv, &factor),
        params.density_smoothing,
    );
    let eligible: Vec<bool> = uv
        .iter()
        .map(|z| z[0].hypot(z[1]) <= params.feature_max_radius)
        .collect();
    let features = separated_maxima(
        &m,
        &adjacency,
        &density,
        &eligible,
        params.max_features,
        params.feature_separation,
    );
    let mut seeds = features.clone();
    if seeds.is_empty() {
        seeds.push(center);
    }
    let sampling =
        farthest_point_samples(&m, &adjacency, &vertex_areas, &seeds, params.samples.max(1));
    let grid = LocateGrid::build(&uv, &m.faces);
    let sweep = breadth_first_tree(&adjacency);
    let disk_mass = disk_measure(&uv, &vertex_areas, &sweep).unwrap_or_default();
    let features = if features.is_empty() {
        vec![center]
    } else {
        features
    };
    Ok(Prepared {
        name: String::new(),
        vertices: m.vertices,
        faces: m.faces,
        reoriented,
        centroid,
        scale,
        uv,
        vertex_areas,
        density,
        features,
        samples: sampling.vertices,
        sample_weights: sampling.weights,
        grid,
        sweep,
        disk_mass,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::synth;

    fn crown() -> Prepared {
        let genus = &synth::CROWN_GENERA[0];
        prepare(&synth::crown(genus, 1, 1500), &CpParams::default()).expect("prepare")
    }

    #[test]
    fn a_prepared_surface_is_consistent_and_its_sweep_visits_every_vertex_once() {
        let p = crown();
        p.validate().expect("consistent");
        assert_eq!(p.sweep.len(), p.vertices.len());
        assert_eq!(p.grid.adjacency.len(), p.faces.len());
        let total: f64 = p.disk_mass.iter().sum();
        assert!((total - 1.0).abs() < 1e-9, "disk measure total {total}");
    }

    #[test]
    fn damaged_walk_data_is_caught() {
        let p = crown();
        let mut q = p.clone();
        q.sweep.swap(1, 5);
        q.sweep.swap(0, 4);
        assert!(q.validate().is_err(), "a child before its parent");
        let mut q = p.clone();
        q.sweep.pop();
        assert!(q.validate().is_err(), "a vertex left out");
        let mut q = p.clone();
        q.grid.adjacency[0][0] = q.faces.len() as u32;
        assert!(q.validate().is_err(), "a neighbour out of range");
    }
}
