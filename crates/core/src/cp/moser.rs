//! The area-preserving correction χ of a disk map (Moser's method).
//!
//! A disk map `a` from S's disk to S′'s disk pushes S's area forward to
//! some measure on S′'s disk; the cP distance wants that measure to be
//! S′'s own area. Moser's flow moves the first into the second: with the
//! densities `ρ₀` (pushed forward) and `ρ₁` (S′'s), interpolated linearly
//! in time, the velocity `v = ∇u / ρ_t` where `Δu = ρ₀ − ρ₁` (Neumann)
//! satisfies the continuity equation, and its time-1 flow χ carries `ρ₀`
//! onto `ρ₁`. Points of S, already mapped by `a`, are moved along it.
//!
//! The flow lives on the unit disk, the same domain for every surface, so
//! it is discretized on one fixed triangulation of the disk whose Poisson
//! problem is factored once per process: no per-surface factor to compute
//! or keep in memory (a library of hundreds would hold hundreds).

use super::locate::{LocateGrid, Location, NO_TRIANGLE};
use crate::conformal::{cotangent_edge_weights, shifted_stiffness, SpdFactor};
use crate::mesh::unit_disk;
use std::sync::OnceLock;

/// Time steps of the flow integration (midpoint rule) for a map that is
/// far from area preserving. The final descent after it corrects what this
/// coarse integration leaves: on the 116 PNAS teeth, two steps and four
/// give the same leave-one-out figures, and two take half the point
/// locations.
pub(super) const FLOW_STEPS: usize = 2;

/// Vertices of the fixed disk triangulation: about as fine as a prepared
/// surface's own.
const DISK_VERTICES: usize = 4000;

/// The fixed triangulation of the unit disk and its factored Poisson
/// problem (stiffness matrix, slightly shifted so it is definite).
struct DiskPoisson {
    uv: Vec<[f64; 2]>,
    faces: Vec<[u32; 3]>,
    grid: LocateGrid,
    factor: SpdFactor,
    dual_areas: Vec<f64>,
}

impl DiskPoisson {
    fn new() -> Option<Self> {
        let disk = unit_disk(DISK_VERTICES);
        let uv: Vec<[f64; 2]> = disk.vertices.iter().map(|p| [p[0], p[1]]).collect();
        let k = shifted_stiffness(uv.len(), &cotangent_edge_weights(&disk), 1e-9);
        Some(DiskPoisson {
            grid: LocateGrid::build(&uv, &disk.faces),
            factor: SpdFactor::new(&k).ok()?,
            dual_areas: disk_vertex_areas(&uv, &disk.faces),
            faces: disk.faces,
            uv,
        })
    }

    /// The one instance, built on first use.
    fn shared() -> Option<&'static DiskPoisson> {
        static DISK: OnceLock<Option<DiskPoisson>> = OnceLock::new();
        DISK.get_or_init(DiskPoisson::new).as_ref()
    }

    /// Locate `z`, walking from the triangle `hint` ([`NO_TRIANGLE`] for
    /// none; points move little between steps).
    fn locate(&self, z: [f64; 2], hint: u32) -> Option<Location> {
        self.grid.locate_near(&self.uv, &self.faces, z, hint)
    }

    /// The measure that points `w` carrying `mass` put on the vertices
    /// (each point's mass split by its barycentric coordinates), normalized
    /// to total 1, with the points' locations. The points are located in
    /// the order of `sweep` (see [`Prepared::sweep`]), each from its
    /// parent's triangle.
    fn splat(
        &self,
        w: &[[f64; 2]],
        mass: &[f64],
        sweep: &[[u32; 2]],
    ) -> Option<(Vec<Location>, Vec<f64>)> {
        let mut found: Vec<Option<Location>> = vec![None; w.len()];
        for &[v, parent] in sweep {
            let hint = found
                .get(parent as usize)
                .copied()
                .flatten()
                .map_or(NO_TRIANGLE, |l| l.face);
            let z = *w.get(v as usize)?;
            *found.get_mut(v as usize)? = Some(self.locate(z, hint)?);
        }
        let locs: Vec<Location> = found.into_iter().collect::<Option<_>>()?;
        let mut splat = vec![0.0; self.uv.len()];
        for (loc, &m) in locs.iter().zip(mass) {
            let f = self.faces.get(loc.face as usize)?;
            for (&v, b) in f.iter().zip(loc.bary) {
                splat[v as usize] += m * b;
            }
        }
        let total: f64 = splat.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        for p in &mut splat {
            *p /= total;
        }
        Some((locs, splat))
    }

    /// Gradient of the piecewise-linear `u` on each triangle.
    fn face_gradients(&self, u: &[f64]) -> Vec<[f64; 2]> {
        self.faces
            .iter()
            .map(|f| {
                let [p, q, r] = f.map(|v| self.uv[v as usize]);
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
}

/// Area of a disk triangulation per vertex (one third of the incident
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

/// The area of a surface flattened to `uv` (vertex areas `areas`, vertex
/// order `sweep` as in [`Prepared::sweep`](super::Prepared)) as a measure
/// of total 1 on the vertices of the fixed disk triangulation. `None` if
/// it cannot be computed (the correction is then skipped).
pub(super) fn disk_measure(uv: &[[f64; 2]], areas: &[f64], sweep: &[[u32; 2]]) -> Option<Vec<f64>> {
    let disk = DiskPoisson::shared()?;
    disk.splat(uv, areas, sweep).map(|(_, m)| m)
}

/// Whether `measure` has one value per vertex of the fixed disk
/// triangulation, as [`disk_measure`] gives.
pub(super) fn is_disk_measure(measure: &[f64]) -> bool {
    DiskPoisson::shared().is_some_and(|disk| measure.len() == disk.uv.len())
}

/// Move the images `w` (points of S′'s disk, images of S's vertices with
/// areas `mass`, visited in S's `sweep` order) along Moser's flow so that
/// the area they carry spreads like `target`, S′'s own area as a
/// [`disk_measure`]. Returns the moved points, or `None` when the solve
/// fails or `target` is no disk measure (the caller keeps the uncorrected
/// map). The flow is integrated in `steps` midpoint steps (at least one;
/// see [`FLOW_STEPS`]).
pub(super) fn area_preserving_correction(
    target: &[f64],
    w: &[[f64; 2]],
    mass: &[f64],
    sweep: &[[u32; 2]],
    steps: usize,
) -> Option<Vec<[f64; 2]>> {
    let steps = steps.max(1);
    let disk = DiskPoisson::shared()?;
    if target.len() != disk.uv.len() {
        return None;
    }
    let (locs, pushed) = disk.splat(w, mass, sweep)?;
    // K u = target − pushed, K the stiffness matrix of the disk.
    let mut rhs = vec![target
        .iter()
        .zip(&pushed)
        .map(|(a, b)| a - b)
        .collect::<Vec<f64>>()];
    disk.factor.solve_columns(&mut rhs).ok()?;
    let grad = disk.face_gradients(&rhs[0]);
    // Densities per unit disk area at the vertices, floored so that the
    // velocity stays bounded where the pushed mass is thin.
    let density = |m: &[f64]| -> Vec<f64> {
        m.iter()
            .zip(&disk.dual_areas)
            .map(|(m, a)| m / a.max(1e-300))
            .collect()
    };
    let (rho0, rho1) = (density(&pushed), density(target));
    let floor = 0.2 / std::f64::consts::PI;
    let velocity = |z: [f64; 2], time: f64, hint: &mut u32| -> [f64; 2] {
        let Some(loc) = disk.locate(z, *hint) else {
            return [0.0, 0.0];
        };
        *hint = loc.face;
        let Some(f) = disk.faces.get(loc.face as usize) else {
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
    // Keep points inside the disk (squared radius first: this runs for
    // every point at every half step).
    const RADIUS: f64 = 1.0 - 1e-9;
    let clamp = |z: [f64; 2]| -> [f64; 2] {
        let r2 = z[0] * z[0] + z[1] * z[1];
        if r2 > RADIUS * RADIUS {
            let s = RADIUS / r2.sqrt();
            [z[0] * s, z[1] * s]
        } else {
            z
        }
    };
    let h = 1.0 / steps as f64;
    let moved = w
        .iter()
        .zip(&locs)
        .map(|(&z0, loc)| {
            let mut z = z0;
            let mut hint = loc.face;
            for s in 0..steps {
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
    use crate::cp::{prepare, Mobius, PrepareParams, Prepared};
    use crate::testing::synth;

    /// Total variation between the area that points `w` carrying `mass`
    /// put in 32 equal-area sectors of the disk and the area `t` has
    /// there (0 when the map that produced them preserves area).
    fn area_mismatch(t: &Prepared, w: &[[f64; 2]], mass: &[f64]) -> f64 {
        let bins = |pts: &[[f64; 2]], m: &[f64]| -> [f64; 32] {
            let mut b = [0.0; 32];
            let total: f64 = m.iter().sum();
            for (z, &x) in pts.iter().zip(m) {
                let ring = ((z[0] * z[0] + z[1] * z[1]) * 4.0).min(3.0) as usize;
                let angle = z[1].atan2(z[0]) + std::f64::consts::PI;
                let sector = ((angle / std::f64::consts::TAU * 8.0) as usize).min(7);
                b[ring * 8 + sector] += x / total;
            }
            b
        };
        let (p, q) = (bins(w, mass), bins(t.uv(), t.vertex_areas()));
        p.iter().zip(&q).map(|(a, b)| (a - b).abs()).sum()
    }

    fn crown() -> Prepared {
        let genus = &synth::CROWN_GENERA[0];
        prepare(&synth::crown(genus, 3, 3000), &PrepareParams::default()).expect("prepare")
    }

    /// χ of the images `w` of `t`'s own vertices onto `t`.
    fn corrected(t: &Prepared, w: &[[f64; 2]], steps: usize) -> Option<Vec<[f64; 2]>> {
        let target = t.disk_measure()?;
        area_preserving_correction(&target, w, &t.vertex_areas, &t.sweep, steps)
    }

    #[test]
    fn an_area_preserving_map_is_left_in_place() {
        let t = crown();
        let moved = corrected(&t, &t.uv, FLOW_STEPS).expect("correction");
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
        let w: Vec<[f64; 2]> = t.uv().iter().map(|&z| m.apply(z)).collect();
        let before = area_mismatch(&t, &w, &t.vertex_areas);
        let moved = corrected(&t, &w, FLOW_STEPS).expect("correction");
        let after = area_mismatch(&t, &moved, &t.vertex_areas);
        assert!(moved.iter().all(|z| z[0].hypot(z[1]) < 1.0));
        assert!(after < 0.25 * before, "mismatch {before:.3} -> {after:.3}");
        eprintln!("sector mismatch {before:.3} -> {after:.3}");
    }

    #[test]
    fn one_flow_step_corrects_a_small_area_change() {
        // The final descent moves an area-preserving map a little and
        // corrects it with a single flow step.
        let t = crown();
        let m = Mobius::from_point_rotation([0.06, 0.03], 0.0);
        let w: Vec<[f64; 2]> = t.uv().iter().map(|&z| m.apply(z)).collect();
        let before = area_mismatch(&t, &w, &t.vertex_areas);
        let moved = corrected(&t, &w, 1).expect("correction");
        let after = area_mismatch(&t, &moved, &t.vertex_areas);
        assert!(after < 0.35 * before, "mismatch {before:.4} -> {after:.4}");
        eprintln!("one step: sector mismatch {before:.4} -> {after:.4}");
    }
}
