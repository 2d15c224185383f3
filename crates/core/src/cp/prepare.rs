//! Preparation of a surface for comparison: normalization, flattening,
//! conformal factor, features, samples and the point-location grid.

use super::error::CpError;
use super::features::{local_maxima, smooth_vertex_function};
use super::locate::LocateGrid;
use super::moser::disk_measure;
use super::params::PrepareParams;
use super::prepared::Prepared;
use super::samples::farthest_point_samples;
use crate::conformal::{self, conformal_factor, hyperbolic_density};
use crate::mesh::{self, breadth_first_tree, graph_distance, vertex_adjacency, Mesh};

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
pub fn prepare(input: &Mesh, params: &PrepareParams) -> Result<Prepared, CpError> {
    let n = input.vertices.len();
    if n < 4 || input.faces.len() < 2 {
        return Err(CpError::Degenerate {
            vertices: n,
            faces: input.faces.len(),
        });
    }
    for (face, f) in input.faces.iter().enumerate() {
        if let Some(&vertex) = f.iter().find(|&&v| v as usize >= n) {
            return Err(CpError::MissingVertex {
                face,
                vertex,
                vertices: n,
            });
        }
    }
    if let Some(vertex) = input
        .vertices
        .iter()
        .position(|p| p.iter().any(|x| !x.is_finite()))
    {
        return Err(CpError::NonFinite { vertex });
    }
    let norm = conformal::normalize(input)?;
    let (centroid, scale) = (norm.centroid, norm.scale);
    let mut m = norm.mesh;
    let loops = mesh::boundary_loops(&m);
    let boundary = loops.first().ok_or(CpError::NoBoundary)?;
    let reoriented = capped_volume(&m, boundary) < 0.0;
    if reoriented {
        m.faces = mesh::reversed_winding(&m.faces);
    }
    let disk = conformal::flatten_to_disk(&m)?;
    let (uv, center) = (disk.uv, disk.center);
    if uv.len() != n || uv.iter().any(|z| !(z[0].is_finite() && z[1].is_finite())) {
        return Err(CpError::NonFiniteDiskCoordinates);
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
    use crate::testing::synth;

    fn crown() -> Mesh {
        synth::crown(&synth::CROWN_GENERA[0], 1, 1500)
    }

    #[test]
    fn a_crown_is_prepared_with_its_features_and_samples() {
        let params = PrepareParams::default();
        let p = prepare(&crown(), &params).expect("prepare");
        p.validate().expect("consistent");
        assert_eq!(p.samples().len(), params.samples);
        assert!(!p.features().is_empty() && p.features().len() <= params.max_features);
        for &f in p.features() {
            let z = p.uv()[f as usize];
            assert!(z[0].hypot(z[1]) <= params.feature_max_radius);
        }
        let area: f64 = p.vertex_areas().iter().sum();
        assert!((area - 1.0).abs() < 1e-9, "area {area}");
    }

    #[test]
    fn bad_meshes_are_named() {
        let mut m = crown();
        m.faces[7][1] = m.vertices.len() as u32 + 3;
        assert_eq!(
            prepare(&m, &PrepareParams::default()).unwrap_err(),
            CpError::MissingVertex {
                face: 7,
                vertex: m.vertices.len() as u32 + 3,
                vertices: m.vertices.len(),
            }
        );
        let mut m = crown();
        m.vertices[11][2] = f64::NAN;
        assert_eq!(
            prepare(&m, &PrepareParams::default()).unwrap_err(),
            CpError::NonFinite { vertex: 11 }
        );
    }

    #[test]
    fn a_flattening_failure_keeps_its_cause() {
        // Two triangles that share only a vertex: normalization works, the
        // flattening refuses a surface that is not a disk.
        let m = Mesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [-1.0, 0.0, 0.0],
                [0.0, -1.0, 0.0],
            ],
            vec![[0, 1, 2], [0, 3, 4]],
        );
        let e = prepare(&m, &PrepareParams::default()).unwrap_err();
        let CpError::Flatten(cause) = &e else {
            panic!("not a flattening error: {e}");
        };
        let source = std::error::Error::source(&e).map(|s| s.to_string());
        assert_eq!(source, Some(cause.to_string()));
    }
}
