//! Pure functions that move, damage or resample a mesh, to build test
//! inputs: every function returns a new mesh and is deterministic for a
//! given seed.

pub use morphoid_core::mesh::subdivide_midpoint;
use morphoid_core::mesh::{bbox_diagonal, norm, reversed_winding, sub, Mesh};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::TAU;

/// A rotation (orthonormal, determinant +1) followed by a translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidMotion {
    /// Row-major rotation matrix.
    pub rotation: [[f64; 3]; 3],
    /// Translation applied after the rotation.
    pub translation: [f64; 3],
}

impl RigidMotion {
    /// A uniformly random rotation and a translation with each component
    /// uniform in `[-reach, reach]`.
    pub fn random(seed: u64, reach: f64) -> RigidMotion {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        // Uniform unit quaternion (Shoemake's subgroup algorithm).
        let (u1, u2, u3): (f64, f64, f64) = (rng.gen(), rng.gen(), rng.gen());
        let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
        let (w, x, y, z) = (
            a * (TAU * u2).sin(),
            a * (TAU * u2).cos(),
            b * (TAU * u3).sin(),
            b * (TAU * u3).cos(),
        );
        let rotation = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        let mut translation = [0.0; 3];
        for t in &mut translation {
            *t = reach * rng.gen_range(-1.0..=1.0);
        }
        RigidMotion {
            rotation,
            translation,
        }
    }

    /// Move one point.
    pub fn apply_point(&self, p: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        let mut q = self.translation;
        for (i, qi) in q.iter_mut().enumerate() {
            *qi += r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2];
        }
        q
    }

    /// Move every vertex of a mesh (faces unchanged).
    pub fn apply(&self, mesh: &Mesh) -> Mesh {
        Mesh::new(
            mesh.vertices.iter().map(|&p| self.apply_point(p)).collect(),
            mesh.faces.clone(),
        )
    }
}

/// The mesh after a random rotation and a translation of up to twice its
/// bounding-box diagonal in each coordinate.
pub fn rigid_motion(mesh: &Mesh, seed: u64) -> Mesh {
    RigidMotion::random(seed, 2.0 * bbox_diagonal(mesh)).apply(mesh)
}

/// The mesh scaled by `factor` about the origin.
pub fn scale(mesh: &Mesh, factor: f64) -> Mesh {
    Mesh::new(
        mesh.vertices
            .iter()
            .map(|p| [p[0] * factor, p[1] * factor, p[2] * factor])
            .collect(),
        mesh.faces.clone(),
    )
}

/// The mirror image under x → −x, with every face reversed so that
/// normals still point outward.
pub fn mirror(mesh: &Mesh) -> Mesh {
    Mesh::new(
        mesh.vertices.iter().map(|p| [-p[0], p[1], p[2]]).collect(),
        reversed_winding(&mesh.faces),
    )
}

/// Reverse the winding of `round(fraction · F)` faces chosen at random.
pub fn flip_faces(mesh: &Mesh, fraction: f64, seed: u64) -> Mesh {
    let n = mesh.faces.len();
    let count = ((fraction.clamp(0.0, 1.0) * n as f64).round() as usize).min(n);
    let mut order: Vec<usize> = (0..n).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (chosen, _) = order.partial_shuffle(&mut rng, count);
    let mut faces = mesh.faces.clone();
    for &i in chosen.iter() {
        faces[i].swap(1, 2);
    }
    Mesh::new(mesh.vertices.clone(), faces)
}

/// Three unshared vertices per face, in face order (what STL stores).
pub fn triangle_soup(mesh: &Mesh) -> Mesh {
    let mut vertices = Vec::with_capacity(3 * mesh.faces.len());
    let mut faces = Vec::with_capacity(mesh.faces.len());
    for f in &mesh.faces {
        let b = vertices.len() as u32;
        vertices.extend(f.iter().map(|&i| mesh.vertices[i as usize]));
        faces.push([b, b + 1, b + 2]);
    }
    Mesh::new(vertices, faces)
}

/// The vertices alone (faces dropped).
pub fn to_point_cloud(mesh: &Mesh) -> Mesh {
    Mesh::new(mesh.vertices.clone(), Vec::new())
}

/// Add `count` small closed blobs (icospheres of radius 1 % of the
/// bounding-box diagonal) floating 3–6 % of the diagonal away from random
/// vertices, on the side their normals point to, like loose particles in a
/// scan. The blobs share no vertex with the mesh.
pub fn add_debris(mesh: &Mesh, count: usize, seed: u64) -> Mesh {
    let mut out = mesh.clone();
    if mesh.vertices.is_empty() {
        return out;
    }
    let diag = bbox_diagonal(mesh).max(f64::MIN_POSITIVE);
    let normals = morphoid_core::mesh::vertex_normals(&mesh.vertices, &mesh.faces);
    let blob = closed_sphere(42);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for _ in 0..count {
        let anchor = rng.gen_range(0..mesh.vertices.len());
        let jitter = random_unit_vector(&mut rng);
        let n = normals[anchor];
        let mut dir = [0.0; 3];
        for k in 0..3 {
            dir[k] = n[k] + 0.5 * jitter[k];
        }
        let len = norm(dir);
        let dir = if len > 1e-9 {
            [dir[0] / len, dir[1] / len, dir[2] / len]
        } else {
            jitter
        };
        let dist = diag * rng.gen_range(0.03..0.06);
        let p = mesh.vertices[anchor];
        let centre = [
            p[0] + dist * dir[0],
            p[1] + dist * dir[1],
            p[2] + dist * dir[2],
        ];
        let radius = 0.01 * diag;
        let base = out.vertices.len() as u32;
        out.vertices.extend(blob.vertices.iter().map(|q| {
            [
                centre[0] + radius * q[0],
                centre[1] + radius * q[1],
                centre[2] + radius * q[2],
            ]
        }));
        out.faces.extend(
            blob.faces
                .iter()
                .map(|f| [f[0] + base, f[1] + base, f[2] + base]),
        );
    }
    out
}

fn random_unit_vector(rng: &mut ChaCha8Rng) -> [f64; 3] {
    let z: f64 = rng.gen_range(-1.0..=1.0);
    let a: f64 = rng.gen_range(0.0..TAU);
    let r = (1.0 - z * z).max(0.0).sqrt();
    [r * a.cos(), r * a.sin(), z]
}

/// Remove the faces whose centroid lies within `radius` of `centre`, and
/// the vertices no face uses any more. A centre well inside a disk-type
/// surface makes a hole (a second boundary loop).
pub fn punch_hole(mesh: &Mesh, centre: [f64; 3], radius: f64) -> Mesh {
    let faces: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .copied()
        .filter(|f| {
            let mut c = [0.0; 3];
            for &i in f {
                let p = mesh.vertices[i as usize];
                for k in 0..3 {
                    c[k] += p[k] / 3.0;
                }
            }
            norm(sub(c, centre)) > radius
        })
        .collect();
    compact(&mesh.vertices, faces)
}

/// Keep only the vertices used by `faces`, renumbered in their old order.
fn compact(vertices: &[[f64; 3]], faces: Vec<[u32; 3]>) -> Mesh {
    let mut new_index = vec![u32::MAX; vertices.len()];
    for f in &faces {
        for &i in f {
            new_index[i as usize] = 0;
        }
    }
    let mut kept = Vec::new();
    for (i, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = kept.len() as u32;
            kept.push(vertices[i]);
        }
    }
    let faces = faces
        .iter()
        .map(|f| f.map(|i| new_index[i as usize]))
        .collect();
    Mesh::new(kept, faces)
}

/// A closed unit sphere (icosphere) with about `target_vertices` vertices:
/// the subdivision level whose count 10·4^L + 2 is nearest (at most 6
/// levels). Faces point outward.
pub fn closed_sphere(target_vertices: usize) -> Mesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let raw = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let faces = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let count = |l: u32| 10 * 4usize.pow(l) + 2;
    let level = (0..=6u32)
        .min_by_key(|&l| count(l).abs_diff(target_vertices))
        .unwrap_or(0);
    let mut m = subdivide_midpoint(&Mesh::new(raw.to_vec(), faces), level);
    for p in &mut m.vertices {
        let r = norm(*p);
        *p = [p[0] / r, p[1] / r, p[2] / r];
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{crown, unit_disk, CROWN_GENERA};
    use morphoid_core::mesh::{
        boundary_loops, dot, edge_face_map, euler_characteristic, surface_area, triangle_normal2,
    };

    #[test]
    fn rotation_is_orthonormal_and_preserves_area() {
        let m = crown(&CROWN_GENERA[1], 3, 500);
        let rm = RigidMotion::random(9, 5.0);
        let r = rm.rotation;
        for i in 0..3 {
            for j in 0..3 {
                let d = dot(r[i], r[j]);
                assert!((d - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
        let det = dot(r[0], morphoid_core::mesh::cross(r[1], r[2]));
        assert!((det - 1.0).abs() < 1e-12);
        let moved = rigid_motion(&m, 9);
        assert!((surface_area(&moved) - surface_area(&m)).abs() < 1e-9);
        assert_ne!(moved.vertices, m.vertices);
    }

    #[test]
    fn mirror_keeps_orientation_outward() {
        let m = unit_disk(100);
        let mm = mirror(&m);
        for f in &mm.faces {
            let p = |i: usize| mm.vertices[f[i] as usize];
            assert!(triangle_normal2(p(0), p(1), p(2))[2] > 0.0);
        }
        assert_eq!(mirror(&mm), m);
    }

    #[test]
    fn flip_faces_flips_the_requested_number() {
        let m = unit_disk(500);
        let f = flip_faces(&m, 0.1, 4);
        let flipped = m.faces.iter().zip(&f.faces).filter(|(a, b)| a != b).count();
        assert_eq!(flipped, (0.1 * m.faces.len() as f64).round() as usize);
        assert_eq!(f, flip_faces(&m, 0.1, 4));
    }

    #[test]
    fn sphere_is_closed_and_outward() {
        for (n, expected) in [(0, 12), (42, 42), (600, 642), (2500, 2562)] {
            let s = closed_sphere(n);
            assert_eq!(s.vertices.len(), expected);
            assert_eq!(euler_characteristic(&s), 2);
            assert!(boundary_loops(&s).is_empty());
            assert!(edge_face_map(&s).values().all(|f| f.len() == 2));
            for f in &s.faces {
                let p = |i: usize| s.vertices[f[i] as usize];
                let c = [
                    p(0)[0] + p(1)[0] + p(2)[0],
                    p(0)[1] + p(1)[1] + p(2)[1],
                    p(0)[2] + p(1)[2] + p(2)[2],
                ];
                assert!(dot(triangle_normal2(p(0), p(1), p(2)), c) > 0.0);
            }
        }
    }

    #[test]
    fn hole_adds_a_boundary_loop() {
        let m = unit_disk(2000);
        let h = punch_hole(&m, [0.3, 0.1, 0.0], 0.12);
        assert!(h.faces.len() < m.faces.len());
        assert_eq!(boundary_loops(&h).len(), 2);
        assert_eq!(euler_characteristic(&h), 0);
        assert!(h
            .faces
            .iter()
            .flatten()
            .all(|&i| (i as usize) < h.vertices.len()));
    }

    #[test]
    fn debris_adds_closed_components() {
        let m = crown(&CROWN_GENERA[0], 1, 800);
        let d = add_debris(&m, 3, 2);
        assert_eq!(d.vertices.len(), m.vertices.len() + 3 * 42);
        assert_eq!(d.faces.len(), m.faces.len() + 3 * 80);
        // Still one boundary loop: the blobs are closed.
        assert_eq!(boundary_loops(&d).len(), 1);
        assert_eq!(euler_characteristic(&d), 1 + 3 * 2);
        assert_eq!(d, add_debris(&m, 3, 2));
    }

    #[test]
    fn soup_and_cloud() {
        let m = unit_disk(50);
        let s = triangle_soup(&m);
        assert_eq!(s.vertices.len(), 3 * m.faces.len());
        assert!((surface_area(&s) - surface_area(&m)).abs() < 1e-12);
        let c = to_point_cloud(&m);
        assert!(c.is_point_cloud());
        assert_eq!(c.vertices, m.vertices);
    }
}
