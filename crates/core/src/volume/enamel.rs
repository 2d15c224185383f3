//! The crown of a segmented tooth from its enamel: the part of the outer
//! surface that lies over the brighter material, cut along the level where
//! the density just inside the surface crosses the enamel threshold.

use crate::clean::largest_component_by_area;
use crate::mesh::Grid;
use crate::mesh::{edge_key, vertex_adjacency, EdgeKey, Mesh};
use rustc_hash::FxHashMap;

/// For every vertex, the mean of `grid` sampled at `depths` (physical
/// units) inward along the vertex normal, minus `threshold`: positive over
/// material brighter than the threshold.
pub(super) fn density_below_surface(
    mesh: &Mesh,
    normals: &[[f64; 3]],
    grid: &Grid,
    depths: &[f64],
    threshold: f64,
) -> Vec<f64> {
    mesh.vertices
        .iter()
        .zip(normals)
        .map(|(p, n)| {
            let sum: f64 = depths
                .iter()
                .map(|d| {
                    f64::from(grid.trilinear([p[0] - d * n[0], p[1] - d * n[1], p[2] - d * n[2]]))
                })
                .sum();
            sum / depths.len().max(1) as f64 - threshold
        })
        .collect()
}

/// One round of averaging each vertex value with its neighbours' (so a cut
/// along the zero level follows the material's edge, not voxel noise).
pub(super) fn smooth_vertex_values(mesh: &Mesh, values: &[f64]) -> Vec<f64> {
    let adjacency = vertex_adjacency(mesh);
    values
        .iter()
        .enumerate()
        .map(|(v, &x)| {
            let nb = &adjacency[v];
            (x + nb.iter().map(|&u| values[u as usize]).sum::<f64>()) / (1 + nb.len()) as f64
        })
        .collect()
}

/// The part of `mesh` where the piecewise-linear vertex function `values`
/// is ≥ 0, with the triangles crossing the zero level split along it.
/// Orientation is kept; vertices outside the part are dropped.
pub(crate) fn cut_at_zero_level(mesh: &Mesh, values: &[f64]) -> Mesh {
    let mut vertices: Vec<[f64; 3]> = Vec::new();
    let mut kept: Vec<u32> = vec![u32::MAX; mesh.vertices.len()];
    let mut crossing: FxHashMap<EdgeKey, u32> = FxHashMap::default();
    let mut faces = Vec::new();
    let mut keep = |v: u32, vertices: &mut Vec<[f64; 3]>| -> u32 {
        if kept[v as usize] == u32::MAX {
            vertices.push(mesh.vertices[v as usize]);
            kept[v as usize] = (vertices.len() - 1) as u32;
        }
        kept[v as usize]
    };
    let mut cross_at = |a: u32, b: u32, vertices: &mut Vec<[f64; 3]>| -> u32 {
        *crossing.entry(edge_key(a, b)).or_insert_with(|| {
            let (sa, sb) = (values[a as usize], values[b as usize]);
            let t = (sa / (sa - sb)).clamp(1e-3, 1.0 - 1e-3);
            let (pa, pb) = (mesh.vertices[a as usize], mesh.vertices[b as usize]);
            vertices.push([0, 1, 2].map(|k| pa[k] + t * (pb[k] - pa[k])));
            (vertices.len() - 1) as u32
        })
    };
    for f in &mesh.faces {
        let pos = f.map(|v| values[v as usize] >= 0.0);
        let count = pos.iter().filter(|&&p| p).count();
        if count == 0 {
            continue;
        }
        if count == 3 {
            faces.push(f.map(|v| keep(v, &mut vertices)));
            continue;
        }
        // Rotate so the vertex on its own side comes first.
        let lone = (0..3)
            .find(|&i| pos[i] != pos[(i + 1) % 3] && pos[i] != pos[(i + 2) % 3])
            .unwrap_or(0);
        let [a, b, c] = [f[lone], f[(lone + 1) % 3], f[(lone + 2) % 3]];
        if count == 1 {
            let ka = keep(a, &mut vertices);
            let ab = cross_at(a, b, &mut vertices);
            let ac = cross_at(a, c, &mut vertices);
            faces.push([ka, ab, ac]);
        } else {
            let kb = keep(b, &mut vertices);
            let kc = keep(c, &mut vertices);
            let ab = cross_at(a, b, &mut vertices);
            let ca = cross_at(c, a, &mut vertices);
            faces.push([ab, kb, kc]);
            faces.push([ab, kc, ca]);
        }
    }
    Mesh::new(vertices, faces)
}

/// The connected part (faces joined through shared vertices) of largest
/// area ([`largest_component_by_area`]), with unused vertices dropped, and
/// how many parts there were.
pub(crate) fn largest_part(mesh: &Mesh) -> (Mesh, usize) {
    let (part, dropped) = largest_component_by_area(mesh);
    let parts = if mesh.faces.is_empty() {
        0
    } else {
        dropped + 1
    };
    // Renumbered in the order the faces first use them (not the cleaning's
    // index order): the vertex order the crown has always had, which the
    // cleaning after it sees.
    let mut map = vec![u32::MAX; part.vertices.len()];
    let mut vertices = Vec::new();
    let faces = part
        .faces
        .iter()
        .map(|f| {
            f.map(|v| {
                if map[v as usize] == u32::MAX {
                    vertices.push(part.vertices[v as usize]);
                    map[v as usize] = (vertices.len() - 1) as u32;
                }
                map[v as usize]
            })
        })
        .collect();
    (Mesh::new(vertices, faces), parts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{boundary_loops, surface_area};
    use crate::testing::synth::closed_sphere;

    #[test]
    fn cutting_a_sphere_at_its_equator_keeps_a_hemisphere() {
        let s = closed_sphere(4000);
        let values: Vec<f64> = s.vertices.iter().map(|p| p[2] - 0.1).collect();
        let cut = cut_at_zero_level(&s, &values);
        let (part, parts) = largest_part(&cut);
        assert_eq!(parts, 1);
        assert_eq!(boundary_loops(&part).len(), 1);
        assert!(part.vertices.iter().all(|p| p[2] >= 0.1 - 1e-9));
        let r = s
            .vertices
            .iter()
            .map(|p| crate::mesh::norm(*p))
            .sum::<f64>()
            / s.vertices.len() as f64;
        let cap = 2.0 * std::f64::consts::PI * r * (r - 0.1);
        assert!((surface_area(&part) / cap - 1.0).abs() < 0.03);
    }
}
