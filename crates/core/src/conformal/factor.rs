//! The conformal factor: how much area the flattening shrinks or expands.

use super::quality::signed_area_2d;
use crate::mesh::{triangle_area, vertex_adjacency, Mesh};

/// Conformal factor `f` at each vertex: surface area over disk area of the
/// faces around it (so that `f dx dy` is the surface's area element), then
/// lightly smoothed: one step averaging `log f` half with the mean over the
/// vertex's one-ring ([`vertex_adjacency`]).
///
/// Vertices whose star has no positive disk area (or no face) get the
/// global ratio (surface area / disk area); the result is always finite and
/// positive when the mesh has positive area, and never NaN.
pub fn conformal_factor(mesh: &Mesh, uv: &[[f64; 2]]) -> Vec<f64> {
    let n = mesh.vertices.len();
    let mut surf = vec![0.0; n];
    let mut disk = vec![0.0; n];
    let (mut surf_total, mut disk_total) = (0.0, 0.0);
    for f in &mesh.faces {
        let idx = f.map(|v| v as usize);
        if idx.iter().any(|&i| i >= n || i >= uv.len()) {
            continue;
        }
        let a3 = triangle_area(
            mesh.vertices[idx[0]],
            mesh.vertices[idx[1]],
            mesh.vertices[idx[2]],
        );
        let a2 = signed_area_2d(uv[idx[0]], uv[idx[1]], uv[idx[2]]).max(0.0);
        if !(a3.is_finite() && a2.is_finite()) {
            continue;
        }
        surf_total += a3;
        disk_total += a2;
        for k in 0..3 {
            surf[idx[k]] += a3;
            disk[idx[k]] += a2;
        }
    }
    let global = if surf_total > 0.0 && disk_total > 0.0 {
        surf_total / disk_total
    } else {
        1.0
    };
    let log_f: Vec<f64> = surf
        .iter()
        .zip(&disk)
        .map(|(&s, &d)| {
            let r = s / d;
            if d > 0.0 && s > 0.0 && r.is_finite() {
                r.ln()
            } else {
                global.ln()
            }
        })
        .collect();
    vertex_adjacency(mesh)
        .iter()
        .enumerate()
        .map(|(v, nb)| {
            if nb.is_empty() {
                return log_f[v].exp();
            }
            let mean = nb.iter().map(|&u| log_f[u as usize]).sum::<f64>() / nb.len() as f64;
            (0.5 * log_f[v] + 0.5 * mean).exp()
        })
        .collect()
}

/// The density `𝐟 = (1 − |z|²)² f` of the surface's area with respect to the
/// hyperbolic measure `dη = (1 − |z|²)⁻² dx dy` of the disk, so that
/// `𝐟 dη = f dx dy`. Points on or outside the unit circle get 0; a missing
/// factor counts as 0.
pub(crate) fn hyperbolic_density(uv: &[[f64; 2]], factor: &[f64]) -> Vec<f64> {
    uv.iter()
        .enumerate()
        .map(|(i, z)| {
            let t = (1.0 - (z[0] * z[0] + z[1] * z[1])).max(0.0);
            let f = factor.get(i).copied().unwrap_or(0.0);
            let d = t * t * f;
            if d.is_finite() {
                d
            } else {
                0.0
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_scaling_gives_constant_factor() {
        // A planar grid mapped by z ↦ z / 4: f = 16 everywhere.
        let m = crate::testing::synth::square_grid(3);
        let uv: Vec<[f64; 2]> = m
            .vertices
            .iter()
            .map(|p| [p[0] / 4.0, p[1] / 4.0])
            .collect();
        for x in conformal_factor(&m, &uv) {
            assert!((x - 16.0).abs() < 1e-9);
        }
        let d = hyperbolic_density(&[[0.0, 0.0], [0.6, 0.0], [1.0, 0.0]], &[2.0, 2.0, 2.0]);
        assert!((d[0] - 2.0).abs() < 1e-12);
        assert!((d[1] - 2.0 * 0.64 * 0.64).abs() < 1e-12);
        assert_eq!(d[2], 0.0);
    }

    #[test]
    fn collapsed_map_gives_finite_factor() {
        let m = Mesh::new(
            vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]],
            vec![[0, 1, 2]],
        );
        let f = conformal_factor(&m, &[[0.0, 0.0]; 3]);
        assert!(f.iter().all(|x| x.is_finite() && *x > 0.0));
    }
}
