//! Quality measures of a planar parametrization: orientation and angle
//! distortion.

use crate::mesh::{cross, dot, norm, sub, Mesh};

/// Signed area of the planar triangle `abc` (positive when counter-clockwise).
#[inline]
pub(crate) fn signed_area_2d(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
}

/// Number of faces whose image under `uv` is not strictly counter-clockwise
/// (signed area ≤ 0 or not finite). A face with an index outside `uv` counts
/// as flipped.
pub fn flipped_triangles(faces: &[[u32; 3]], uv: &[[f64; 2]]) -> usize {
    faces
        .iter()
        .filter(|f| {
            match (
                uv.get(f[0] as usize),
                uv.get(f[1] as usize),
                uv.get(f[2] as usize),
            ) {
                (Some(&a), Some(&b), Some(&c)) => {
                    let s = signed_area_2d(a, b, c);
                    s.is_nan() || s <= 0.0
                }
                _ => true,
            }
        })
        .count()
}

/// Ratio `σ₁/σ₂ ≥ 1` of the singular values of the affine map from each
/// surface triangle to its image in the plane: 1 for a conformal (similarity)
/// map. Faces that are degenerate on either side, or refer to missing
/// vertices, get `f64::INFINITY`. A reflected image has a finite ratio too
/// (see [`flipped_triangles`] for orientation).
pub fn quasi_conformal_ratios(mesh: &Mesh, uv: &[[f64; 2]]) -> Vec<f64> {
    mesh.faces
        .iter()
        .map(|f| {
            let idx = f.map(|v| v as usize);
            match (
                idx.iter().all(|&i| i < mesh.vertices.len()),
                idx.iter().all(|&i| i < uv.len()),
            ) {
                (true, true) => {
                    triangle_qc_ratio(idx.map(|i| mesh.vertices[i]), idx.map(|i| uv[i]))
                }
                _ => f64::INFINITY,
            }
        })
        .collect()
}

/// `σ₁/σ₂` of the affine map taking the space triangle `p` to the planar
/// triangle `q`.
fn triangle_qc_ratio(p: [[f64; 3]; 3], q: [[f64; 2]; 3]) -> f64 {
    // Isometric 2D coordinates of the space triangle: p0 at the origin, p1 on
    // the x axis.
    let e1 = sub(p[1], p[0]);
    let e2 = sub(p[2], p[0]);
    let l1 = norm(e1);
    let n = cross(e1, e2);
    let y = cross(n, e1);
    let ly = norm(y);
    if !(l1 > 0.0 && ly > 0.0) {
        return f64::INFINITY;
    }
    let (ax, bx, by) = (l1, dot(e2, e1) / l1, dot(e2, y) / ly);
    if by.is_nan() || by <= 1e-14 * l1 {
        return f64::INFINITY;
    }
    // J = T S⁻¹ with S = [[ax, bx], [0, by]] and T = [q1 − q0, q2 − q0].
    let t = [
        [q[1][0] - q[0][0], q[2][0] - q[0][0]],
        [q[1][1] - q[0][1], q[2][1] - q[0][1]],
    ];
    let inv = [[1.0 / ax, -bx / (ax * by)], [0.0, 1.0 / by]];
    let j = [
        [
            t[0][0] * inv[0][0] + t[0][1] * inv[1][0],
            t[0][0] * inv[0][1] + t[0][1] * inv[1][1],
        ],
        [
            t[1][0] * inv[0][0] + t[1][1] * inv[1][0],
            t[1][0] * inv[0][1] + t[1][1] * inv[1][1],
        ],
    ];
    // Split into conformal (P) and anti-conformal (Q) parts: σ₁ = P + Q,
    // σ₂ = |P − Q|.
    let p_ = 0.5 * (j[0][0] + j[1][1]).hypot(j[1][0] - j[0][1]);
    let q_ = 0.5 * (j[0][0] - j[1][1]).hypot(j[1][0] + j[0][1]);
    let s1 = p_ + q_;
    let s2 = (p_ - q_).abs();
    if !(s1.is_finite() && s2 > 1e-14 * s1) {
        return f64::INFINITY;
    }
    s1 / s2
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> Mesh {
        Mesh::new(
            vec![[0., 0., 1.], [2., 0., 1.], [0.5, 1.5, 1.]],
            vec![[0, 1, 2]],
        )
    }

    #[test]
    fn similarity_has_ratio_one_and_stretch_its_factor() {
        let m = tri();
        // Rotation by 30° and scaling by 0.3 of the xy coordinates.
        let (s, c) = (0.3 * 0.5f64, 0.3 * 0.75f64.sqrt());
        let uv: Vec<[f64; 2]> = m
            .vertices
            .iter()
            .map(|p| [c * p[0] - s * p[1], s * p[0] + c * p[1]])
            .collect();
        assert!((quasi_conformal_ratios(&m, &uv)[0] - 1.0).abs() < 1e-12);
        assert_eq!(flipped_triangles(&m.faces, &uv), 0);
        // Stretch x by 3: ratio 3. Mirror: flipped, ratio still 1.
        let uv: Vec<[f64; 2]> = m.vertices.iter().map(|p| [3.0 * p[0], p[1]]).collect();
        assert!((quasi_conformal_ratios(&m, &uv)[0] - 3.0).abs() < 1e-12);
        let uv: Vec<[f64; 2]> = m.vertices.iter().map(|p| [-p[0], p[1]]).collect();
        assert!((quasi_conformal_ratios(&m, &uv)[0] - 1.0).abs() < 1e-12);
        assert_eq!(flipped_triangles(&m.faces, &uv), 1);
    }

    #[test]
    fn degenerate_images_are_infinite_and_flipped() {
        let m = tri();
        let uv = vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]];
        assert_eq!(quasi_conformal_ratios(&m, &uv)[0], f64::INFINITY);
        assert_eq!(flipped_triangles(&m.faces, &uv), 1);
        assert_eq!(flipped_triangles(&m.faces, &uv[..2]), 1);
    }
}
