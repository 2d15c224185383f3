//! Synthetic surfaces for tests and the demo.
//!
//! The main generator makes crown-like disk-type surfaces: a triangulated
//! elliptical disk (concentric rings, near-equilateral triangles) lifted by
//! a height field made of a shallow dome and Gaussian cusps. A few fixed
//! cusp configurations ([`CROWN_GENERA`]) play the role of genera; a seed
//! gives each individual its own jitter of cusp positions, heights and
//! widths, overall scale and a slight smooth noise. Everything is
//! deterministic for a given seed.
//!
//! The footprint is [`morphoid_core::mesh::unit_disk`]'s triangulation with
//! rotated rings: the generator builds on the numerical modules, never the
//! other way round.
//!
//! [`transform`] holds pure functions that move, damage or resample a mesh
//! (rigid motions, mirror images, flipped faces, triangle soups, debris,
//! holes, point clouds, a closed sphere), [`scanner`] scanner-like
//! point clouds (noise, outliers) and a crown with overhanging walls, and [`bad_inputs`]
//! writes the malformed files the daemon must survive; [`library`] writes a
//! labelled reference library of crowns. [`whole_tooth`] builds a closed
//! whole tooth (crown, neck, roots) below a crown. [`unit_disk`] and
//! [`subdivide_midpoint`] are re-exported from [`morphoid_core::mesh`] for the
//! generator's users.

mod bad_inputs;
mod library;
mod scanner;
mod transform;
mod whole_tooth;

// The type the generators make, named here for the core's own unit tests
// (which see the core as a second crate through this one).
pub use bad_inputs::write_bad_inputs;
pub use library::{specimen_mesh, write_synthetic_library, LibrarySpec, Specimen};
pub use morphoid_core::mesh::{unit_disk, Mesh};
pub use scanner::{overhanging_crown, scanner_cloud, ScannerCloud};
pub use transform::{
    add_debris, closed_sphere, flip_faces, mirror, punch_hole, rigid_motion, scale,
    subdivide_midpoint, to_point_cloud, triangle_soup, RigidMotion,
};
pub(crate) use whole_tooth::WholeTooth;
pub use whole_tooth::{whole_tooth, WholeToothParams};

use morphoid_core::mesh::{ring_count, ring_disk};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::TAU;

/// One cusp of a crown configuration, in units of the footprint radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cusp {
    /// Position of the apex, x.
    pub x: f64,
    /// Position of the apex, y.
    pub y: f64,
    /// Height above the base dome.
    pub height: f64,
    /// Standard deviation of the Gaussian across its short axis.
    pub width: f64,
    /// Ratio of long to short axis (1 = round cusp, > 1 = a ridge).
    pub elongation: f64,
    /// Direction of the long axis (radians from +x).
    pub angle: f64,
}

/// A crown configuration: the "genus" of a synthetic specimen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrownGenus {
    /// Genus name, used as the taxon label.
    pub name: &'static str,
    /// Family the genus is filed under in synthetic libraries.
    pub family: &'static str,
    /// Order the family is filed under in synthetic libraries.
    pub order: &'static str,
    /// The cusps.
    pub cusps: &'static [Cusp],
    /// Footprint half-axis along x (the y half-axis is 1).
    pub aspect: f64,
    /// Height of the dome under the cusps at the centre.
    pub dome: f64,
}

const fn cusp(x: f64, y: f64, height: f64, width: f64) -> Cusp {
    Cusp {
        x,
        y,
        height,
        width,
        elongation: 1.0,
        angle: 0.0,
    }
}

const fn ridge(x: f64, y: f64, height: f64, width: f64, elongation: f64, angle: f64) -> Cusp {
    Cusp {
        x,
        y,
        height,
        width,
        elongation,
        angle,
    }
}

/// The built-in crown configurations, clearly different from each other:
/// three cusps in a triangle, four in a square, five (four and a distal
/// one), two transverse ridges, and one tall cusp with two small ones.
/// They are filed in three families and two orders, so that a synthetic
/// library has several taxonomic ranks.
pub const CROWN_GENERA: [CrownGenus; 5] = [
    CrownGenus {
        name: "Tricuspis",
        family: "Tricuspidae",
        order: "Synthoformes",
        cusps: &[
            cusp(0.0, 0.5, 0.42, 0.22),
            cusp(-0.45, -0.27, 0.36, 0.22),
            cusp(0.45, -0.27, 0.36, 0.22),
        ],
        aspect: 1.0,
        dome: 0.12,
    },
    CrownGenus {
        name: "Quadricuspis",
        family: "Quadricuspidae",
        order: "Fictiformes",
        cusps: &[
            cusp(0.5, 0.4, 0.32, 0.2),
            cusp(-0.5, 0.4, 0.32, 0.2),
            cusp(0.5, -0.4, 0.32, 0.2),
            cusp(-0.5, -0.4, 0.32, 0.2),
        ],
        aspect: 1.25,
        dome: 0.1,
    },
    CrownGenus {
        name: "Quinquecuspis",
        family: "Quadricuspidae",
        order: "Fictiformes",
        cusps: &[
            cusp(0.45, 0.38, 0.3, 0.18),
            cusp(-0.2, 0.42, 0.3, 0.18),
            cusp(0.45, -0.38, 0.25, 0.18),
            cusp(-0.2, -0.42, 0.25, 0.18),
            cusp(-0.75, 0.0, 0.2, 0.16),
        ],
        aspect: 1.35,
        dome: 0.1,
    },
    CrownGenus {
        name: "Lophodon",
        family: "Lophodontidae",
        order: "Fictiformes",
        cusps: &[
            ridge(0.45, 0.0, 0.3, 0.13, 3.5, std::f64::consts::FRAC_PI_2),
            ridge(-0.45, 0.0, 0.3, 0.13, 3.5, std::f64::consts::FRAC_PI_2),
        ],
        aspect: 1.3,
        dome: 0.08,
    },
    CrownGenus {
        name: "Monocuspis",
        family: "Tricuspidae",
        order: "Synthoformes",
        cusps: &[
            cusp(0.2, 0.05, 0.6, 0.26),
            cusp(-0.5, 0.4, 0.15, 0.15),
            cusp(-0.5, -0.4, 0.15, 0.15),
        ],
        aspect: 1.1,
        dome: 0.1,
    },
];

/// Look up a built-in configuration by name (case-insensitive).
pub fn crown_genus(name: &str) -> Option<&'static CrownGenus> {
    CROWN_GENERA
        .iter()
        .find(|g| g.name.eq_ignore_ascii_case(name))
}

/// A uniform sample in `[-1, 1]`.
fn sym(rng: &mut ChaCha8Rng) -> f64 {
    rng.gen_range(-1.0..=1.0)
}

/// A crown-like disk-type surface of the given configuration with about
/// `target_vertices` vertices. The seed fixes the individual: cusp
/// positions (±0.04), heights and widths (±8 %), overall scale (±8 %),
/// footprint aspect (±3 %) and a slight smooth noise (at most 0.4 % of
/// the radius). The crown's occlusal surface faces +z, footprint radius
/// about 1.
pub fn crown(genus: &CrownGenus, seed: u64, target_vertices: usize) -> Mesh {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let overall = 1.0 + 0.08 * sym(&mut rng);
    let aspect = genus.aspect * (1.0 + 0.03 * sym(&mut rng));
    let cusps: Vec<Cusp> = genus
        .cusps
        .iter()
        .map(|c| Cusp {
            x: c.x + 0.04 * sym(&mut rng),
            y: c.y + 0.04 * sym(&mut rng),
            height: c.height * (1.0 + 0.08 * sym(&mut rng)),
            width: c.width * (1.0 + 0.08 * sym(&mut rng)),
            elongation: c.elongation,
            angle: c.angle + 0.05 * sym(&mut rng),
        })
        .collect();
    // Smooth noise: a few plane waves of low frequency.
    let waves: Vec<([f64; 2], f64)> = (0..4)
        .map(|_| {
            let dir = rng.gen_range(0.0..TAU);
            let freq = rng.gen_range(3.0..7.0);
            (
                [freq * dir.cos(), freq * dir.sin()],
                rng.gen_range(0.0..TAU),
            )
        })
        .collect();
    let rings = ring_count(target_vertices);
    let phases: Vec<f64> = (0..=rings).map(|_| rng.gen_range(0.0..0.5)).collect();
    let mut mesh = ring_disk(target_vertices, &phases);
    for v in &mut mesh.vertices {
        let (x, y) = (v[0] * aspect, v[1]);
        let rho2 = v[0] * v[0] + v[1] * v[1];
        let mut z = genus.dome * (1.0 - rho2);
        for c in &cusps {
            let (dx, dy) = (x - c.x, y - c.y);
            let (s, co) = c.angle.sin_cos();
            let along = dx * co + dy * s;
            let across = -dx * s + dy * co;
            let long = c.width * c.elongation;
            z += c.height
                * (-0.5 * (along * along / (long * long) + across * across / (c.width * c.width)))
                    .exp();
        }
        for (k, phase) in &waves {
            z += 0.001 * (k[0] * x + k[1] * y + phase).sin();
        }
        *v = [overall * x, overall * y, overall * z];
    }
    mesh
}

/// An `n` × `n` grid of unit squares in the plane z = 0, two triangles
/// each; vertex `(n + 1) j + i` is at `(i, j)`. A disk for unit tests.
pub fn square_grid(n: u32) -> Mesh {
    let mut v = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            v.push([i as f64, j as f64, 0.0]);
        }
    }
    let mut f = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            f.push([a, a + 1, a + n + 2]);
            f.push([a, a + n + 2, a + n + 1]);
        }
    }
    Mesh::new(v, f)
}

/// A square annulus: the 3 × 3 grid of unit squares without the middle one
/// (vertices 5, 6, 10, 9), so the hole is short and the rim long; vertex
/// `4j + i` is at `(i, j)`. Two boundary loops, for unit tests.
pub fn square_annulus() -> Mesh {
    let mut v = Vec::new();
    for j in 0..4 {
        for i in 0..4 {
            v.push([i as f64, j as f64, 0.0]);
        }
    }
    let mut f = Vec::new();
    for j in 0..3u32 {
        for i in 0..3u32 {
            if (i, j) == (1, 1) {
                continue;
            }
            let a = j * 4 + i;
            f.push([a, a + 1, a + 5]);
            f.push([a, a + 5, a + 4]);
        }
    }
    Mesh::new(v, f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_count_follows_the_target() {
        for n in [200, 1000, 5000, 20000] {
            let m = crown(&CROWN_GENERA[0], 1, n);
            let ratio = m.vertices.len() as f64 / n as f64;
            assert!((0.85..1.2).contains(&ratio), "{n}: {}", m.vertices.len());
        }
    }
}
