//! Feature points: local maxima of the smoothed hyperbolic conformal
//! density (on a tooth, the cusps).

use crate::mesh::Mesh;

/// Per-vertex conformal factor: surface area over disk area of the faces
/// around the vertex.
pub fn vertex_conformal_factor(mesh: &Mesh, uv: &[[f64; 2]]) -> Vec<f64> {
    let n = mesh.vertices.len();
    let mut a3 = vec![0.0; n];
    let mut a2 = vec![0.0; n];
    for f in &mesh.faces {
        let [i, j, k] = f.map(|v| v as usize);
        let s = crate::mesh::triangle_area(mesh.vertices[i], mesh.vertices[j], mesh.vertices[k]);
        let (p, q, r) = (uv[i], uv[j], uv[k]);
        let d = 0.5 * ((q[0] - p[0]) * (r[1] - p[1]) - (r[0] - p[0]) * (q[1] - p[1])).abs();
        for v in [i, j, k] {
            a3[v] += s;
            a2[v] += d;
        }
    }
    a3.iter()
        .zip(&a2)
        .map(|(&s, &d)| if d > 0.0 { s / d } else { 0.0 })
        .collect()
}

/// Hyperbolic density `(1 − |z|²)² f`: the conformal factor with respect to
/// the hyperbolic measure of the disk, invariant under disk automorphisms.
pub fn hyperbolic_density(uv: &[[f64; 2]], factor: &[f64]) -> Vec<f64> {
    uv.iter()
        .zip(factor)
        .map(|(z, &f)| {
            let s = (1.0 - z[0] * z[0] - z[1] * z[1]).max(0.0);
            s * s * f
        })
        .collect()
}

/// `iterations` steps of area-weighted averaging over the closed one-ring.
pub fn smooth_vertex_function(
    adjacency: &[Vec<u32>],
    areas: &[f64],
    values: &[f64],
    iterations: usize,
) -> Vec<f64> {
    let mut cur = values.to_vec();
    for _ in 0..iterations {
        let next: Vec<f64> = (0..cur.len())
            .map(|i| {
                let mut s = areas[i] * cur[i];
                let mut w = areas[i];
                for &j in &adjacency[i] {
                    s += areas[j as usize] * cur[j as usize];
                    w += areas[j as usize];
                }
                if w > 0.0 {
                    s / w
                } else {
                    cur[i]
                }
            })
            .collect();
        cur = next;
    }
    cur
}

/// Local maxima of `values` over `rings`-ring neighbourhoods, among the
/// vertices where `eligible` holds, strongest first (ties: smaller index),
/// at most `max_count`, no two closer than `min_separation` by `distance`.
pub fn local_maxima(
    adjacency: &[Vec<u32>],
    values: &[f64],
    eligible: &[bool],
    max_count: usize,
    min_separation: f64,
    distance: impl Fn(u32, u32) -> f64,
) -> Vec<u32> {
    let mut cands: Vec<u32> = (0..values.len() as u32)
        .filter(|&i| {
            let v = values[i as usize];
            eligible[i as usize]
                && adjacency[i as usize].iter().all(|&j| {
                    let w = values[j as usize];
                    v > w || (v == w && i < j)
                })
        })
        .collect();
    cands.sort_by(|&a, &b| {
        values[b as usize]
            .total_cmp(&values[a as usize])
            .then(a.cmp(&b))
    });
    let mut out: Vec<u32> = Vec::new();
    for c in cands {
        if out.len() >= max_count {
            break;
        }
        if out.iter().all(|&o| distance(o, c) >= min_separation) {
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maxima_are_found_strongest_first_and_separated() {
        // A path graph 0-1-2-3-4-5-6 with peaks at 1 and 5.
        let adj: Vec<Vec<u32>> = (0..7u32)
            .map(|i| {
                let mut v = Vec::new();
                if i > 0 {
                    v.push(i - 1);
                }
                if i < 6 {
                    v.push(i + 1);
                }
                v
            })
            .collect();
        let vals = [0.0, 2.0, 1.0, 0.5, 1.0, 3.0, 0.0];
        let elig = [true; 7];
        let m = local_maxima(&adj, &vals, &elig, 5, 0.0, |a, b| {
            (a as f64 - b as f64).abs()
        });
        assert_eq!(m, vec![5, 1]);
        let m = local_maxima(&adj, &vals, &elig, 5, 5.0, |a, b| {
            (a as f64 - b as f64).abs()
        });
        assert_eq!(m, vec![5]);
        let m = local_maxima(&adj, &vals, &elig, 1, 0.0, |a, b| {
            (a as f64 - b as f64).abs()
        });
        assert_eq!(m, vec![5]);
    }

    #[test]
    fn hyperbolic_density_vanishes_on_the_circle() {
        let d = hyperbolic_density(&[[0.0, 0.0], [1.0, 0.0], [0.5, 0.0]], &[2.0, 2.0, 2.0]);
        assert_eq!(d[0], 2.0);
        assert_eq!(d[1], 0.0);
        assert!((d[2] - 2.0 * 0.75 * 0.75).abs() < 1e-15);
    }
}
