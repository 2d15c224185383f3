//! The area-preserving correction χ of a disk map (Moser's method).
//!
//! A disk map `a` from S's disk to S′'s disk pushes S's area forward to
//! some measure on S′'s disk; the cP distance wants that measure to be
//! S′'s own area. Moser's flow moves the first into the second: with the
//! densities `ρ₀` (pushed forward) and `ρ₁` (S′'s), interpolated linearly
//! in time, the velocity `v = ∇u / ρ_t` where `Δu = ρ₀ − ρ₁` (Neumann)
//! satisfies the continuity equation, and its time-1 flow χ carries `ρ₀`
//! onto `ρ₁`. Points of S, already mapped by `a`, are moved along it.

use super::locate::{barycentric, Location};
use super::prepare::Prepared;
use crate::conformal::{cotangent_edge_weights, shifted_stiffness, SpdFactor};
use crate::mesh::Mesh;

/// Time steps of the flow integration (midpoint rule). Four keep the
/// images within a small fraction of a triangle of the eight-step flow at
/// half the point locations.
const STEPS: usize = 4;

/// What the correction needs of a target surface, computed once per
/// surface: the factored stiffness matrix of its disk triangulation and
/// the disk area of each vertex's dual cell.
pub struct DiskPoisson {
    factor: SpdFactor,
    dual_areas: Vec<f64>,
}

impl std::fmt::Debug for DiskPoisson {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "DiskPoisson({} vertices)", self.dual_areas.len())
    }
}

impl DiskPoisson {
    /// Factor the (slightly shifted, so definite) stiffness matrix of the
    /// disk triangulation `uv`, `faces`.
    pub fn new(uv: &[[f64; 2]], faces: &[[u32; 3]]) -> Option<Self> {
        let flat = Mesh::new(
            uv.iter().map(|z| [z[0], z[1], 0.0]).collect(),
            faces.to_vec(),
        );
        let k = shifted_stiffness(uv.len(), &cotangent_edge_weights(&flat), 1e-9);
        Some(DiskPoisson {
            factor: SpdFactor::new(&k).ok()?,
            dual_areas: disk_vertex_areas(uv, faces),
        })
    }
}

/// Area of the disk triangulation per vertex (one third of the incident
/// triangles' areas).
fn disk_vertex_areas(uv: &[[f64; 2]], faces: &[[u32; 3]]) -> Vec<f64> {
    let mut a = vec![0.0; uv.len()];
    for f in faces {
        let [p, q, r] = f.map(|v| uv[v as usize]);
        let area = 0.5 * ((q[0] - p[0]) * (r[1] - p[1]) - (r[0] - p[0]) * (q[1] - p[1])).abs();
        for &v in f {
            a[v as usize] += area / 3.0;
        }
    }
    a
}

/// Gradient (in disk coordinates) of the piecewise-linear `u` on each
/// triangle of S′'s disk.
fn face_gradients(t: &Prepared, u: &[f64]) -> Vec<[f64; 2]> {
    t.faces
        .iter()
        .map(|f| {
            let [p, q, r] = f.map(|v| t.uv[v as usize]);
            let [a, b, c] = f.map(|v| u[v as usize]);
            let (e1, e2) = ([q[0] - p[0], q[1] - p[1]], [r[0] - p[0], r[1] - p[1]]);
            let det = e1[0] * e2[1] - e2[0] * e1[1];
            if det.abs() < 1e-300 {
                return [0.0, 0.0];
            }
            let (du1, du2) = (b - a, c - a);
            [
                (du1 * e2[1] - du2 * e1[1]) / det,
                (du2 * e1[0] - du1 * e2[0]) / det,
            ]
        })
        .collect()
}

/// The measure that points `w` of S′'s disk carrying `mass` put on S′'s
/// vertices (each point's mass split by its barycentric coordinates),
/// normalized to total 1, with the points' locations.
pub fn pushed_mass(
    t: &Prepared,
    w: &[[f64; 2]],
    mass: &[f64],
) -> Option<(Vec<Location>, Vec<f64>)> {
    let locs: Vec<Location> = w
        .iter()
        .map(|&z| t.grid.locate(&t.uv, &t.faces, z))
        .collect::<Option<_>>()?;
    let mut pushed = vec![0.0; t.uv.len()];
    for (loc, &m) in locs.iter().zip(mass) {
        let f = t.faces.get(loc.face as usize)?;
        for k in 0..3 {
            pushed[f[k] as usize] += m * loc.bary[k];
        }
    }
    let total: f64 = pushed.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return None;
    }
    for p in &mut pushed {
        *p /= total;
    }
    Some((locs, pushed))
}

/// Move the images `w` (points of S′'s disk, images of S's vertices with
/// areas `mass`) along Moser's flow so that the area they carry spreads
/// like S′'s own area. Returns the moved points, or `None` when the solve
/// fails (the caller keeps the uncorrected map).
pub fn area_preserving_correction(
    t: &Prepared,
    w: &[[f64; 2]],
    mass: &[f64],
) -> Option<Vec<[f64; 2]>> {
    let (locs, pushed) = pushed_mass(t, w, mass)?;
    let target_total: f64 = t.vertex_areas.iter().sum();
    if target_total <= 0.0 {
        return None;
    }
    let target: Vec<f64> = t.vertex_areas.iter().map(|a| a / target_total).collect();
    // K u = target − pushed, K the stiffness matrix of the disk
    // triangulation (a tiny shift fixes the constant).
    let poisson = t.disk_poisson()?;
    let mut rhs = vec![target
        .iter()
        .zip(&pushed)
        .map(|(a, b)| a - b)
        .collect::<Vec<f64>>()];
    poisson.factor.solve_columns(&mut rhs).ok()?;
    let grad = face_gradients(t, &rhs[0]);
    // Densities per unit disk area at the vertices, floored so that the
    // velocity stays bounded where the pushed mass is thin.
    let dual = &poisson.dual_areas;
    let rho0: Vec<f64> = pushed
        .iter()
        .zip(dual)
        .map(|(m, a)| m / a.max(1e-300))
        .collect();
    let rho1: Vec<f64> = target
        .iter()
        .zip(dual)
        .map(|(m, a)| m / a.max(1e-300))
        .collect();
    let mean = 1.0 / std::f64::consts::PI;
    let floor = 0.2 * mean;
    // Points move little per step: try the triangle that held the point
    // last before searching the grid.
    let locate_near = |z: [f64; 2], hint: u32| -> Option<Location> {
        if let Some(f) = t.faces.get(hint as usize) {
            let [a, b, c] = f.map(|v| t.uv[v as usize]);
            if let Some(l) = barycentric(z, a, b, c) {
                if l.iter().all(|&x| x >= 0.0) {
                    return Some(Location {
                        face: hint,
                        bary: l,
                    });
                }
            }
        }
        t.grid.locate(&t.uv, &t.faces, z)
    };
    let velocity = |z: [f64; 2], time: f64, hint: &mut u32| -> [f64; 2] {
        let Some(loc) = locate_near(z, *hint) else {
            return [0.0, 0.0];
        };
        *hint = loc.face;
        let Some(f) = t.faces.get(loc.face as usize) else {
            return [0.0, 0.0];
        };
        let rho: f64 = f
            .iter()
            .zip(loc.bary)
            .map(|(&v, b)| b * ((1.0 - time) * rho0[v as usize] + time * rho1[v as usize]))
            .sum();
        let g = grad[loc.face as usize];
        let rho = rho.max(floor);
        [g[0] / rho, g[1] / rho]
    };
    let clamp = |z: [f64; 2]| -> [f64; 2] {
        let r = z[0].hypot(z[1]);
        if r > 1.0 - 1e-9 {
            let s = (1.0 - 1e-9) / r;
            [z[0] * s, z[1] * s]
        } else {
            z
        }
    };
    let h = 1.0 / STEPS as f64;
    let moved = w
        .iter()
        .zip(&locs)
        .map(|(&z0, loc)| {
            let mut z = z0;
            let mut hint = loc.face;
            for s in 0..STEPS {
                let t0 = s as f64 * h;
                let v0 = velocity(z, t0, &mut hint);
                let mid = clamp([z[0] + 0.5 * h * v0[0], z[1] + 0.5 * h * v0[1]]);
                let v1 = velocity(mid, t0 + 0.5 * h, &mut hint);
                z = clamp([z[0] + h * v1[0], z[1] + h * v1[1]]);
            }
            z
        })
        .collect();
    Some(moved)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cp::{prepare, CpParams, Mobius};
    use crate::mesh::synth;

    /// Total variation between the measure the points carry and the
    /// surface's own area measure (0 when the map preserves area).
    fn area_mismatch(t: &Prepared, w: &[[f64; 2]], mass: &[f64]) -> f64 {
        let (_, pushed) = pushed_mass(t, w, mass).expect("points lie in the disk");
        let total: f64 = t.vertex_areas.iter().sum();
        pushed
            .iter()
            .zip(&t.vertex_areas)
            .map(|(p, a)| (p - a / total).abs())
            .sum()
    }

    fn crown() -> Prepared {
        let genus = &synth::CROWN_GENERA[0];
        prepare(&synth::crown(genus, 3, 3000), &CpParams::default()).expect("prepare")
    }

    #[test]
    fn an_area_preserving_map_is_left_in_place() {
        let t = crown();
        let moved = area_preserving_correction(&t, &t.uv, &t.vertex_areas).expect("correction");
        let worst = moved
            .iter()
            .zip(&t.uv)
            .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "moved by {worst}");
    }

    #[test]
    fn the_correction_carries_area_onto_area() {
        // A disk automorphism moves area towards one side: the corrected
        // map must spread it as the surface does.
        let t = crown();
        let m = Mobius::from_point_rotation([0.35, -0.2], 0.7);
        let w: Vec<[f64; 2]> = t.uv.iter().map(|&z| m.apply(z)).collect();
        let before = area_mismatch(&t, &w, &t.vertex_areas);
        let moved = area_preserving_correction(&t, &w, &t.vertex_areas).expect("correction");
        let after = area_mismatch(&t, &moved, &t.vertex_areas);
        assert!(moved.iter().all(|z| z[0].hypot(z[1]) < 1.0));
        assert!(after < 0.5 * before, "mismatch {before:.3} -> {after:.3}");
    }
}
