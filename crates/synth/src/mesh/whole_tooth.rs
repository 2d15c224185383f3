//! Closed whole teeth (crown, cervical neck, root trunk) built below a
//! disk-type crown, as a µCT isosurface of a segmented tooth would show
//! them.
//!
//! The crown is kept vertex for vertex. Below its boundary loop (the crop
//! line, which need not be planar) come, ring after ring with the loop's
//! vertex count:
//! - the enamel edge: the surface turns inward from the crown's wall by a
//!   clear angle over a short step (the enamel bulges over the neck), which
//!   makes a convex edge along the whole cervical margin and a concave
//!   crease just below it;
//! - the neck, constricting below the margin to a waist, its rings going
//!   from the margin's (uneven) heights to a level one;
//! - a root trunk that flares slightly, then tapers to a closed apex, with
//!   one to three root lobes (grooves deepening towards the apex), a slight
//!   bend and smooth noise.
//!
//! The seed draws the shape within [`WholeToothParams`]' ranges.

use morphoid_core::mesh::{
    bbox_diagonal, cross, dot, longest_boundary_loop, norm, sub, triangle_normal2, Mesh,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::TAU;

/// Ranges the seed draws a whole tooth's shape from; lengths are fractions
/// of the crown height above its lowest boundary point, radii fractions of
/// the local crown radius at the margin.
#[derive(Debug, Clone, PartialEq)]
pub struct WholeToothParams {
    /// Angle (degrees) by which the surface turns inward from the crown's
    /// wall at the margin.
    pub enamel_turn_degrees: [f64; 2],
    /// Length of the inward step below the margin (fraction of the mean
    /// crown radius).
    pub enamel_step: [f64; 2],
    /// Neck length from the lowest margin point to the waist.
    pub neck_length: [f64; 2],
    /// Radius lost from the margin to the waist.
    pub constriction: [f64; 2],
    /// Root length from the waist to the apex.
    pub root_length: [f64; 2],
    /// Number of root lobes (1 to 3), inclusive range.
    pub root_count: [u32; 2],
    /// Depth of the grooves between root lobes at the apex.
    pub lobe_depth: [f64; 2],
    /// Smooth radial noise amplitude.
    pub noise: f64,
}

impl Default for WholeToothParams {
    fn default() -> Self {
        Self {
            enamel_turn_degrees: [35.0, 60.0],
            enamel_step: [0.02, 0.05],
            neck_length: [0.15, 0.35],
            constriction: [0.08, 0.2],
            root_length: [1.0, 2.0],
            root_count: [1, 3],
            lobe_depth: [0.15, 0.35],
            noise: 0.01,
        }
    }
}

/// A closed whole tooth and where its crown is.
#[derive(Debug, Clone, PartialEq)]
pub struct WholeTooth {
    /// The closed, manifold, outward-oriented surface.
    pub mesh: Mesh,
    /// For every face of `mesh`: whether it is a face of the input crown
    /// (the crown's faces come first, in their order).
    pub crown_faces: Vec<bool>,
    /// Unit occlusal direction (from the roots towards the crown).
    pub occlusal: [f64; 3],
}

/// Why a whole tooth cannot be built on a mesh.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WholeToothError {
    /// The crown has no boundary loop, or more than one.
    #[error("the crown must be a disk with one boundary loop ({0} found)")]
    NotDisk(usize),
    /// Too small or flat to define a crown height or an occlusal side.
    #[error("the crown is degenerate (no height above its boundary loop)")]
    Degenerate,
}

fn scale3(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

fn add3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn unit(a: [f64; 3]) -> Option<[f64; 3]> {
    let n = norm(a);
    (n > 0.0 && n.is_finite()).then(|| scale3(a, 1.0 / n))
}

fn draw(rng: &mut ChaCha8Rng, r: [f64; 2]) -> f64 {
    if r[1] > r[0] {
        rng.gen_range(r[0]..=r[1])
    } else {
        r[0]
    }
}

/// Occlusal axis of a crown: the normal of its boundary loop's vector area,
/// signed towards the crown's body.
fn occlusal_axis(crown: &Mesh, lp: &[u32]) -> Option<([f64; 3], [f64; 3])> {
    let pts: Vec<[f64; 3]> = lp.iter().map(|&v| crown.vertices[v as usize]).collect();
    let n = pts.len() as f64;
    let c = pts
        .iter()
        .fold([0.0; 3], |acc, p| add3(acc, scale3(*p, 1.0 / n)));
    let mut area = [0.0; 3];
    for i in 0..pts.len() {
        area = add3(
            area,
            cross(sub(pts[i], c), sub(pts[(i + 1) % pts.len()], c)),
        );
    }
    let mut axis = unit(area)?;
    let vn = crown.vertices.len() as f64;
    let body = crown
        .vertices
        .iter()
        .fold([0.0; 3], |acc, p| add3(acc, scale3(*p, 1.0 / vn)));
    if dot(sub(body, c), axis) < 0.0 {
        axis = scale3(axis, -1.0);
    }
    Some((axis, c))
}

/// Two unit vectors completing `a` to an orthonormal frame.
fn frame(a: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let helper = if a[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = unit(cross(a, helper)).unwrap_or([0.0, 1.0, 0.0]);
    (u, cross(a, u))
}

impl WholeTooth {
    /// The same tooth turned so that its occlusal direction is +z (crown
    /// up, roots down), as loose teeth are mounted for a scan.
    pub fn upright(&self) -> WholeTooth {
        let a = self.occlusal;
        let z = [0.0, 0.0, 1.0];
        let k = cross(a, z);
        let s = (k[0] * k[0] + k[1] * k[1] + k[2] * k[2]).sqrt();
        let c = dot(a, z);
        // Rodrigues' rotation taking `a` to +z (or a half turn about x).
        let rotate = |p: [f64; 3]| -> [f64; 3] {
            if s < 1e-12 {
                return if c > 0.0 { p } else { [p[0], -p[1], -p[2]] };
            }
            let k = k.map(|v| v / s);
            let kxp = cross(k, p);
            let kdp = dot(k, p);
            [0, 1, 2].map(|i| p[i] * c + kxp[i] * s + k[i] * kdp * (1.0 - c))
        };
        WholeTooth {
            mesh: Mesh::new(
                self.mesh.vertices.iter().map(|&p| rotate(p)).collect(),
                self.mesh.faces.clone(),
            ),
            crown_faces: self.crown_faces.clone(),
            occlusal: z,
        }
    }
}

/// Build a closed whole tooth below `crown` (see the module documentation).
/// The crown's faces are kept (reversed, all together, if the crown's
/// normals pointed inward) and its vertices are unchanged.
pub fn whole_tooth(
    crown: &Mesh,
    params: &WholeToothParams,
    seed: u64,
) -> Result<WholeTooth, WholeToothError> {
    let loops = morphoid_core::mesh::boundary_loops(crown).len();
    if loops != 1 {
        return Err(WholeToothError::NotDisk(loops));
    }
    let lp = longest_boundary_loop(crown).ok_or(WholeToothError::NotDisk(0))?;
    let (axis, centre) = occlusal_axis(crown, &lp).ok_or(WholeToothError::Degenerate)?;
    let (eu, ev) = frame(axis);
    let axes = Axes {
        axis,
        centre,
        eu,
        ev,
    };
    let crown_height = crown_height(crown, &lp, &axes)?;
    let shape = draw_shape(params, crown_height, seed);
    let margin = margin_directions(crown, &lp, &axes);
    let outward = faces_point_outward(crown, axis);

    let mut vertices = crown.vertices.clone();
    let mut faces: Vec<[u32; 3]> = if outward {
        crown.faces.clone()
    } else {
        morphoid_core::mesh::reversed_winding(&crown.faces)
    };
    let crown_face_count = faces.len();
    // With inward faces the loop's half-edges run the other way.
    let n = lp.len();
    let (ring0, order): (Vec<u32>, Vec<usize>) = if outward {
        (lp.clone(), (0..n).collect())
    } else {
        (lp.iter().rev().copied().collect(), (0..n).rev().collect())
    };
    let ring1 = enamel_edge(&margin, &order, outward, &shape, axis, &mut vertices);
    let ring1_polar: Vec<(f64, f64, f64)> = ring1
        .iter()
        .map(|&v| {
            let p = vertices[v as usize];
            let (t, r) = axes.radial(p);
            (t, r, axes.height(p))
        })
        .collect();
    let mut rings = vec![ring0, ring1];
    rings.extend(neck_and_root_rings(
        &axes,
        &shape,
        crown_height,
        params.noise,
        margin.edge_len,
        &ring1_polar,
        &mut vertices,
    ));
    stitch_rings(&rings, &mut faces);
    close_apex(&rings, axis, margin.edge_len, &mut vertices, &mut faces);
    let mut crown_faces = vec![false; faces.len()];
    crown_faces[..crown_face_count].fill(true);
    Ok(WholeTooth {
        mesh: Mesh::new(vertices, faces),
        crown_faces,
        occlusal: axis,
    })
}

/// The crown's frame: the occlusal axis, the centre of its boundary loop
/// and two unit vectors across the axis.
struct Axes {
    axis: [f64; 3],
    centre: [f64; 3],
    eu: [f64; 3],
    ev: [f64; 3],
}

impl Axes {
    /// The height of `p` along the axis above the centre.
    fn height(&self, p: [f64; 3]) -> f64 {
        dot(sub(p, self.centre), self.axis)
    }

    /// The angle and radius of `p` about the axis.
    fn radial(&self, p: [f64; 3]) -> (f64, f64) {
        let d = sub(p, self.centre);
        let (x, y) = (dot(d, self.eu), dot(d, self.ev));
        (y.atan2(x), (x * x + y * y).sqrt())
    }
}

/// The crown's height above the lowest point of its boundary loop `lp`,
/// or why it has none.
fn crown_height(crown: &Mesh, lp: &[u32], axes: &Axes) -> Result<f64, WholeToothError> {
    let top = crown
        .vertices
        .iter()
        .map(|&p| axes.height(p))
        .fold(f64::MIN, f64::max);
    let low = lp
        .iter()
        .map(|&v| axes.height(crown.vertices[v as usize]))
        .fold(f64::MAX, f64::min);
    let crown_height = top - low;
    let min_height = 1e-9 * bbox_diagonal(crown).max(f64::MIN_POSITIVE);
    if crown_height.is_nan() || crown_height <= min_height {
        return Err(WholeToothError::Degenerate);
    }
    Ok(crown_height)
}

/// The shape below the crown, drawn from the seed.
struct Shape {
    /// Inward turn of the enamel edge, radians.
    turn: f64,
    /// The enamel step over the mean crown radius.
    step_frac: f64,
    neck_len: f64,
    constriction: f64,
    root_len: f64,
    lobes: u32,
    lobe_depth: f64,
    lobe_phase: f64,
    flare: f64,
    taper_power: f64,
    bend: [f64; 2],
    /// Smooth noise: (angular order, vertical frequency, phase, amplitude).
    waves: Vec<(u32, f64, f64, f64)>,
}

/// The shape below the crown drawn within `params`' ranges (lengths
/// scaled by `crown_height`); the draws keep their order, so a seed gives
/// the same tooth.
fn draw_shape(params: &WholeToothParams, crown_height: f64, seed: u64) -> Shape {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let turn = draw(&mut rng, params.enamel_turn_degrees).to_radians();
    let step_frac = draw(&mut rng, params.enamel_step);
    let neck_len = draw(&mut rng, params.neck_length) * crown_height;
    let constriction = draw(&mut rng, params.constriction);
    let root_len = draw(&mut rng, params.root_length) * crown_height;
    let lobes = if params.root_count[1] > params.root_count[0] {
        rng.gen_range(params.root_count[0]..=params.root_count[1])
    } else {
        params.root_count[0]
    }
    .clamp(1, 3);
    let lobe_depth = if lobes > 1 {
        draw(&mut rng, params.lobe_depth)
    } else {
        0.0
    };
    let lobe_phase = rng.gen_range(0.0..TAU);
    let flare = rng.gen_range(0.0..0.08);
    let taper_power = rng.gen_range(1.5..2.5);
    let bend = [rng.gen_range(-0.15..0.15), rng.gen_range(-0.15..0.15)];
    let waves: Vec<(u32, f64, f64, f64)> = (0..4)
        .map(|_| {
            (
                rng.gen_range(1..5u32),
                rng.gen_range(0.5..3.0),
                rng.gen_range(0.0..TAU),
                rng.gen_range(-1.0..1.0),
            )
        })
        .collect();
    Shape {
        turn,
        step_frac,
        neck_len,
        constriction,
        root_len,
        lobes,
        lobe_depth,
        lobe_phase,
        flare,
        taper_power,
        bend,
        waves,
    }
}

/// The crown at its boundary loop, per loop vertex.
struct Margin {
    /// Positions.
    pos: Vec<[f64; 3]>,
    /// The crown's outward direction along its wall (in the face plane,
    /// perpendicular to the boundary edge), summed over the edges' faces.
    wall: Vec<[f64; 3]>,
    /// The crown's normal, summed over the same faces.
    normal: Vec<[f64; 3]>,
    /// The loop's mean radius about the axis.
    mean_radius: f64,
    /// The loop's mean edge length.
    edge_len: f64,
}

/// The crown's wall and normal directions at each vertex of its boundary
/// loop `lp`, with the loop's mean radius and edge length.
fn margin_directions(crown: &Mesh, lp: &[u32], axes: &Axes) -> Margin {
    let n = lp.len();
    let pos: Vec<[f64; 3]> = lp.iter().map(|&v| crown.vertices[v as usize]).collect();
    let polar: Vec<(f64, f64)> = pos.iter().map(|&p| axes.radial(p)).collect();
    let mean_radius = polar.iter().map(|p| p.1).sum::<f64>() / n as f64;
    let mut wall = vec![[0.0; 3]; n];
    let mut normal = vec![[0.0; 3]; n];
    let index_of: std::collections::HashMap<u32, usize> =
        lp.iter().enumerate().map(|(i, &v)| (v, i)).collect();
    let next_of = |v: u32| lp[(index_of[&v] + 1) % n];
    for f in &crown.faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            if !index_of.contains_key(&a) || next_of(a) != b {
                continue;
            }
            let c = f[(k + 2) % 3];
            let (pa, pb, pc) = (
                crown.vertices[a as usize],
                crown.vertices[b as usize],
                crown.vertices[c as usize],
            );
            let nrm = triangle_normal2(pa, pb, pc);
            let e = sub(pb, pa);
            // In the face plane, perpendicular to the edge, away from c.
            let mut out = cross(e, nrm);
            if dot(out, sub(pc, pa)) > 0.0 {
                out = scale3(out, -1.0);
            }
            if let Some(o) = unit(out) {
                for v in [a, b] {
                    let i = index_of[&v];
                    wall[i] = add3(wall[i], o);
                    normal[i] = add3(normal[i], nrm);
                }
            }
        }
    }
    let edge_len = (0..n)
        .map(|i| norm(sub(pos[(i + 1) % n], pos[i])))
        .sum::<f64>()
        / n as f64;
    Margin {
        pos,
        wall,
        normal,
        mean_radius,
        edge_len,
    }
}

/// Whether the crown's faces point outward: their vector area points from
/// the boundary towards the body, along `axis`.
fn faces_point_outward(crown: &Mesh, axis: [f64; 3]) -> bool {
    let vector_area = crown.faces.iter().fold([0.0; 3], |acc, f| {
        add3(
            acc,
            triangle_normal2(
                crown.vertices[f[0] as usize],
                crown.vertices[f[1] as usize],
                crown.vertices[f[2] as usize],
            ),
        )
    });
    dot(vector_area, axis) >= 0.0
}

/// Ring 1, the enamel edge: from each loop vertex (in `order`), a short
/// step turned inward from the wall by the shape's angle, kept going down
/// the tooth. Its vertices are added to `vertices`.
fn enamel_edge(
    margin: &Margin,
    order: &[usize],
    outward: bool,
    shape: &Shape,
    axis: [f64; 3],
    vertices: &mut Vec<[f64; 3]>,
) -> Vec<u32> {
    let step = shape.step_frac * margin.mean_radius;
    let turn = shape.turn;
    let mut ring1 = Vec::with_capacity(order.len());
    for &i in order {
        let w = unit(margin.wall[i]).unwrap_or(scale3(axis, -1.0));
        let mut nv = unit(margin.normal[i]).unwrap_or([0.0; 3]);
        if !outward {
            nv = scale3(nv, -1.0);
        }
        let mut d = add3(scale3(w, turn.cos()), scale3(nv, -turn.sin()));
        // Keep the step going down the tooth.
        if dot(d, axis) > -0.3 {
            d = add3(d, scale3(axis, -0.3 - dot(d, axis)));
        }
        let d = unit(d).unwrap_or(scale3(axis, -1.0));
        ring1.push(vertices.len() as u32);
        vertices.push(add3(margin.pos[i], scale3(d, step)));
    }
    ring1
}

/// The radii of the enamel edge (`ring1_polar`: angle, radius, height)
/// averaged circularly over a twelfth of the ring: the root is rounder
/// than the margin.
fn smoothed_radii(ring1_polar: &[(f64, f64, f64)]) -> Vec<f64> {
    let n = ring1_polar.len();
    (0..n)
        .map(|i| {
            let w = (n / 12).max(1);
            let s: f64 = (0..=2 * w)
                .map(|k| ring1_polar[(i + n + k - w) % n].1)
                .sum();
            s / (2 * w + 1) as f64
        })
        .collect()
}

/// The rings below the enamel edge: the neck down to its waist, then the
/// root trunk to just above the apex. Their vertices are added to
/// `vertices`.
fn neck_and_root_rings(
    axes: &Axes,
    shape: &Shape,
    crown_height: f64,
    noise: f64,
    edge_len: f64,
    ring1_polar: &[(f64, f64, f64)],
    vertices: &mut Vec<[f64; 3]>,
) -> Vec<Vec<u32>> {
    let n = ring1_polar.len();
    let smooth = smoothed_radii(ring1_polar);
    let neck_bottom = ring1_polar.iter().map(|p| p.2).fold(f64::MAX, f64::min) - shape.neck_len;
    let neck_rings = ((shape.neck_len / edge_len).ceil() as usize).clamp(3, 60);
    let root_rings = ((shape.root_len / edge_len).ceil() as usize).clamp(6, 300);
    let total = neck_rings + root_rings;
    let mut rings = Vec::with_capacity(total);
    for k in 1..=total {
        let mut ring = Vec::with_capacity(n);
        for (i, &(theta, r1, z1)) in ring1_polar.iter().enumerate() {
            let (z, r, u) = if k <= neck_rings {
                let t = k as f64 / neck_rings as f64;
                // Constrict fast below the crease, level off at the waist.
                let shrink = 1.0 - shape.constriction * (t * std::f64::consts::FRAC_PI_2).sin();
                let base = r1 + (smooth[i] - r1) * t;
                (z1 + (neck_bottom - z1) * t, base * shrink, 0.0)
            } else {
                let u = (k - neck_rings) as f64 / root_rings as f64;
                root_profile(shape, smooth[i], theta, u, neck_bottom)
            };
            let wobble: f64 = shape
                .waves
                .iter()
                .map(|&(m, fz, ph, amp)| {
                    amp * (m as f64 * theta + fz * TAU * (neck_bottom - z) / crown_height + ph)
                        .sin()
                })
                .sum::<f64>()
                * noise
                * (k as f64 / total as f64).min(1.0)
                / 2.0;
            let r = r * (1.0 + wobble);
            let off = [
                shape.bend[0] * u * u * crown_height,
                shape.bend[1] * u * u * crown_height,
            ];
            let p = add3(
                add3(axes.centre, scale3(axes.axis, z)),
                add3(
                    scale3(axes.eu, r * theta.cos() + off[0]),
                    scale3(axes.ev, r * theta.sin() + off[1]),
                ),
            );
            ring.push(vertices.len() as u32);
            vertices.push(p);
        }
        rings.push(ring);
    }
    rings
}

/// Height, radius and the fraction `u` of the root's length at angle
/// `theta`, `u` of the way from the waist (below a smoothed margin radius
/// `smooth`) to the apex: flared, tapering, grooved between the lobes.
fn root_profile(
    shape: &Shape,
    smooth: f64,
    theta: f64,
    u: f64,
    neck_bottom: f64,
) -> (f64, f64, f64) {
    let waist = smooth * (1.0 - shape.constriction);
    let flared = waist * (1.0 + shape.flare * (std::f64::consts::PI * u).sin());
    let taper = 1.0 - 0.85 * u.powf(shape.taper_power);
    let groove = shape.lobe_depth
        * u
        * (0.5 - 0.5 * (shape.lobes as f64 * (theta - shape.lobe_phase)).cos());
    (
        neck_bottom - shape.root_len * u,
        flared * taper * (1.0 - groove),
        u,
    )
}

/// Two faces between each pair of consecutive vertices of each pair of
/// consecutive rings, wound outward.
fn stitch_rings(rings: &[Vec<u32>], faces: &mut Vec<[u32; 3]>) {
    for w in rings.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        let n = a.len();
        for i in 0..n {
            let j = (i + 1) % n;
            faces.push([a[j], a[i], b[i]]);
            faces.push([a[j], b[i], b[j]]);
        }
    }
}

/// The apex: a vertex half an edge below the centre of the last ring,
/// joined to it by a fan of faces.
fn close_apex(
    rings: &[Vec<u32>],
    axis: [f64; 3],
    edge_len: f64,
    vertices: &mut Vec<[f64; 3]>,
    faces: &mut Vec<[u32; 3]>,
) {
    let n = rings[0].len();
    let last = rings.last().cloned().unwrap_or_default();
    let apex_centre = last.iter().fold([0.0; 3], |acc, &v| {
        add3(acc, scale3(vertices[v as usize], 1.0 / n as f64))
    });
    let apex = add3(apex_centre, scale3(axis, -0.5 * edge_len));
    let ai = vertices.len() as u32;
    vertices.push(apex);
    for i in 0..n {
        faces.push([last[(i + 1) % n], last[i], ai]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{crown, CROWN_GENERA};
    use morphoid_core::mesh::{boundary_loops, euler_characteristic};

    fn signed_volume(m: &Mesh) -> f64 {
        m.faces
            .iter()
            .map(|f| {
                let p = f.map(|v| m.vertices[v as usize]);
                dot(p[0], cross(p[1], p[2])) / 6.0
            })
            .sum()
    }

    #[test]
    fn whole_tooth_is_closed_outward_and_keeps_the_crown() {
        for (g, genus) in CROWN_GENERA.iter().enumerate() {
            let c = crown(genus, 7 + g as u64, 1500);
            for seed in 0..3 {
                let t = whole_tooth(&c, &WholeToothParams::default(), seed).unwrap();
                assert!(boundary_loops(&t.mesh).is_empty());
                assert_eq!(euler_characteristic(&t.mesh), 2);
                assert!(signed_volume(&t.mesh) > 0.0);
                assert_eq!(&t.mesh.vertices[..c.vertices.len()], &c.vertices[..]);
                let kept: Vec<[u32; 3]> = t
                    .mesh
                    .faces
                    .iter()
                    .zip(&t.crown_faces)
                    .filter_map(|(f, &k)| k.then_some(*f))
                    .collect();
                assert_eq!(kept, c.faces);
                // The synthetic crowns face +z.
                assert!(t.occlusal[2] > 0.95, "{:?}", t.occlusal);
                // Every edge is shared by exactly two faces, once each way.
                let mut dir = std::collections::HashSet::new();
                for f in &t.mesh.faces {
                    for k in 0..3 {
                        assert!(dir.insert((f[k], f[(k + 1) % 3])));
                    }
                }
                for &(a, b) in &dir {
                    assert!(dir.contains(&(b, a)));
                }
            }
        }
    }

    #[test]
    fn inward_crowns_give_outward_teeth_and_the_seed_varies_the_shape() {
        let c = crown(&CROWN_GENERA[1], 3, 1200);
        let flipped = Mesh::new(
            c.vertices.clone(),
            morphoid_core::mesh::reversed_winding(&c.faces),
        );
        let t = whole_tooth(&flipped, &WholeToothParams::default(), 1).unwrap();
        assert!(signed_volume(&t.mesh) > 0.0);
        assert!(t.occlusal[2] > 0.95);
        let a = whole_tooth(&c, &WholeToothParams::default(), 1).unwrap();
        let b = whole_tooth(&c, &WholeToothParams::default(), 2).unwrap();
        assert_ne!(a.mesh.vertices, b.mesh.vertices);
        let closed = whole_tooth(&a.mesh, &WholeToothParams::default(), 1);
        assert_eq!(closed, Err(WholeToothError::NotDisk(0)));
    }
}
