//! A triangulated unit disk: the fixed domain on which numerical code
//! discretizes problems posed on the disk (e.g. Moser's flow), and the
//! footprint the synthetic crowns are lifted from.

use super::Mesh;
use std::f64::consts::TAU;

/// A flat, triangulated unit disk in the plane z = 0 with about
/// `target_vertices` vertices (at least 7): concentric rings with 6k
/// vertices on ring k, so triangles are near-equilateral. Faces are
/// counter-clockwise seen from +z. The boundary is the outermost ring.
pub fn unit_disk(target_vertices: usize) -> Mesh {
    ring_disk(target_vertices, &[])
}

/// Number of rings for about `n` vertices: a disk of K rings has
/// 1 + 3K(K+1) vertices.
pub fn ring_count(n: usize) -> usize {
    let k = ((n.max(7) as f64 / 3.0).sqrt() - 0.5).round() as usize;
    k.max(1)
}

/// Concentric-ring disk; `phases[k]` (if given) rotates ring k by that
/// fraction of its vertex spacing.
pub fn ring_disk(target_vertices: usize, phases: &[f64]) -> Mesh {
    let rings = ring_count(target_vertices);
    let mut vertices = vec![[0.0, 0.0, 0.0]];
    // First vertex index and size of each ring (ring 0 is the centre).
    let mut starts = vec![(0usize, 1usize)];
    for k in 1..=rings {
        let n = 6 * k;
        let phase = phases.get(k).copied().unwrap_or(0.0);
        let r = k as f64 / rings as f64;
        starts.push((vertices.len(), n));
        for i in 0..n {
            let a = TAU * (i as f64 + phase) / n as f64;
            vertices.push([r * a.cos(), r * a.sin(), 0.0]);
        }
    }
    let mut faces = Vec::with_capacity(6 * rings * rings);
    for k in 1..=rings {
        let (inner, m) = starts[k - 1];
        let (outer, n) = starts[k];
        let angle = |start: usize, len: usize, i: usize| {
            // Unwrapped angle of the i-th vertex of a ring (i may equal len).
            let base = vertices[start + i % len];
            let a = base[1].atan2(base[0]).rem_euclid(TAU);
            a + TAU * (i / len) as f64
        };
        if m == 1 {
            for j in 0..n {
                faces.push([
                    inner as u32,
                    (outer + j) as u32,
                    (outer + (j + 1) % n) as u32,
                ]);
            }
            continue;
        }
        // Merge the two rings by angle; both start near angle 0 because
        // phases are below one spacing.
        let (mut i, mut j) = (0usize, 0usize);
        while i < m || j < n {
            let advance_inner =
                j == n || (i < m && angle(inner, m, i + 1) <= angle(outer, n, j + 1));
            let a = (inner + i % m) as u32;
            let b = (outer + j % n) as u32;
            if advance_inner {
                faces.push([a, b, (inner + (i + 1) % m) as u32]);
                i += 1;
            } else {
                faces.push([a, b, (outer + (j + 1) % n) as u32]);
                j += 1;
            }
        }
    }
    Mesh::new(vertices, faces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{boundary_loops, euler_characteristic, triangle_normal2};

    #[test]
    fn unit_disk_is_a_ccw_disk() {
        for n in [7, 50, 500, 5000] {
            let m = unit_disk(n);
            assert_eq!(euler_characteristic(&m), 1);
            let loops = boundary_loops(&m);
            assert_eq!(loops.len(), 1);
            let k = ring_count(n);
            assert_eq!(m.vertices.len(), 1 + 3 * k * (k + 1));
            assert_eq!(loops[0].len(), 6 * k);
            for f in &m.faces {
                let p = |i: usize| m.vertices[f[i] as usize];
                assert!(triangle_normal2(p(0), p(1), p(2))[2] > 0.0);
            }
        }
    }
}
