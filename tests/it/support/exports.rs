//! Whole teeth as scanners export them, built below the real crowns of
//! `../shared/data/pnas-teeth` for the crown extraction to be tried on.
//!
//! Built the way a tooth is, not the way the extractor looks for a margin:
//! a solid (the crown closed by its crop line, a neck leaving the crop line
//! along the crown's own wall, a root trunk and one to three tapering
//! roots) is sampled on a voxel grid tilted at random against the tooth,
//! optionally blurred (partial volume), and its isosurface taken, with the
//! voxel staircase and the grid's resolution. No crease, curvature or
//! height of the margin is computed here: the crop line is where the crown
//! file ends, and the neck's profile is a smooth curve (or, for the sharp
//! junctions, one with a kink or a ledge) chosen per tooth.

#![allow(dead_code)] // each test module uses some of these

use morphoid_core::mesh::{cross, dot, longest_boundary_loop, norm, sub, Mesh};
use morphoid_core::mesh::{isosurface, Grid};
use morphoid_synth::mesh::{scale, RigidMotion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

/// How the neck leaves the crown at the crop line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Junction {
    /// Along the crown's own wall: no edge at all.
    Smooth,
    /// Turned inward by a few tens of degrees.
    Kinked,
    /// A short inward step (an enamel ledge), then down.
    Ledge,
}

/// The form of one whole tooth.
#[derive(Debug, Clone)]
pub(crate) struct ToothForm {
    /// Roots below the trunk: 1, 2 (lower molars) or 3 (upper molars).
    pub roots: usize,
    /// How the neck leaves the crown.
    pub junction: Junction,
    /// Voxels across the whole tooth's longest side.
    pub voxels: usize,
    /// Gaussian blur of the occupancy before the isosurface, in voxels (0:
    /// the hard staircase of a thresholded binary volume).
    pub blur: f64,
    /// Radius at the bottom of the neck, as a fraction of the crop line's.
    pub constriction: f64,
    /// Neck length below the lowest crop point, as a fraction of the
    /// crown's height.
    pub neck: f64,
    /// Root length below the neck, as a multiple of the crown's height.
    pub root_length: f64,
    /// Depth of the furcation below the neck, as a fraction of the root
    /// length.
    pub furcation: f64,
    /// How far the roots spread apart towards their apices, as a fraction
    /// of the trunk's half-length.
    pub spread: f64,
    /// A pulp cavity inside (an internal closed surface in the export).
    pub pulp: bool,
    /// Seed of the grid's tilt.
    pub seed: u64,
}

impl ToothForm {
    /// A form drawn at random for `roots` roots and `junction`, at about
    /// `voxels` voxels across.
    pub(crate) fn random(seed: u64, roots: usize, junction: Junction, voxels: usize) -> ToothForm {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_7007);
        ToothForm {
            roots,
            junction,
            voxels,
            blur: if rng.gen_bool(0.5) {
                0.0
            } else {
                rng.gen_range(0.4..0.9)
            },
            constriction: rng.gen_range(0.72..0.9),
            neck: rng.gen_range(0.12..0.3),
            root_length: rng.gen_range(1.1..1.8),
            furcation: rng.gen_range(0.15..0.4),
            spread: rng.gen_range(0.0..0.5),
            pulp: rng.gen_bool(0.5),
            seed,
        }
    }
}

/// The seed of the export of the tooth at `index` in the library's
/// order: every test and bench that builds exports of the real teeth
/// builds the same ones.
pub(crate) fn export_seed(index: usize) -> u64 {
    9100 + index as u64
}

/// The form of the export with `seed`: `roots` and `junction` when given,
/// else drawn from the seed (mixed so that neighbouring seeds differ in
/// every respect); `voxels` when above 0, else 140, 200 or 300.
pub(crate) fn form_for(
    seed: u64,
    roots: Option<usize>,
    junction: Option<Junction>,
    voxels: usize,
) -> ToothForm {
    let k = (seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40) as usize;
    let roots = roots.unwrap_or(1 + k % 3);
    let junction =
        junction.unwrap_or([Junction::Smooth, Junction::Kinked, Junction::Ledge][(k / 3) % 3]);
    let voxels = if voxels > 0 {
        voxels
    } else {
        [140, 200, 300][(k / 2) % 3]
    };
    ToothForm::random(seed, roots, junction, voxels)
}

/// Where the export with `seed` of a crown of bounding-box diagonal
/// `diagonal` lies in the scanner's frame: scaled by 0.5–2 and moved at
/// random. The same placement moves the crown it was built on.
pub(crate) struct Placement {
    motion: RigidMotion,
    scale: f64,
}

impl Placement {
    /// The placement of the export with `seed`.
    pub(crate) fn for_seed(seed: u64, diagonal: f64) -> Placement {
        Placement {
            motion: RigidMotion::random(seed, 3.0 * diagonal),
            scale: 2f64.powf(((seed * 7919) % 200) as f64 / 100.0 - 1.0),
        }
    }

    /// `mesh` placed.
    pub(crate) fn apply(&self, mesh: &Mesh) -> Mesh {
        self.motion.apply(&scale(mesh, self.scale))
    }
}

/// A whole tooth built below a crown: the isosurface, in the crown's
/// coordinates, and the grid it was taken from.
pub(crate) struct ExportedTooth {
    /// The closed isosurface (outer surface and, with a pulp, the inner).
    pub mesh: Mesh,
    /// The occupancy (blurred) it was taken from, in the tilted grid's
    /// coordinates; `to_crown` maps them to the crown's.
    pub grid: Grid,
    /// Grid coordinates → the crown's: `p = centre + rows^T q`.
    pub rows: [[f64; 3]; 3],
    /// Origin of the tooth frame in the crown's coordinates.
    pub centre: [f64; 3],
    /// The tooth's frame and the crop line's height in each polar bin:
    /// where the crown was cropped, for [`ExportedTooth::cut_at_crop_line`].
    crop_frame: Frame,
    crop_height: Vec<f64>,
}

impl ExportedTooth {
    /// The faces of the isosurface above the crop line the crown was
    /// built on (by their centroids): the crown a perfect margin finder
    /// would cut, to tell the loss from the cut's place from the loss from
    /// the surface's resolution.
    #[allow(dead_code)] // an experiment's knob (clean_exports.rs)
    pub(crate) fn cut_at_crop_line(&self) -> Mesh {
        let faces: Vec<[u32; 3]> = self
            .mesh
            .faces
            .iter()
            .copied()
            .filter(|f| {
                let c = f.iter().fold([0.0; 3], |a, &v| {
                    let p = self.mesh.vertices[v as usize];
                    [a[0] + p[0] / 3.0, a[1] + p[1] / 3.0, a[2] + p[2] / 3.0]
                });
                let l = self.crop_frame.local(c);
                l[2] > self.crop_height[bin_of(l[1].atan2(l[0]))]
            })
            .collect();
        Mesh::new(self.mesh.vertices.clone(), faces)
    }
}

/// The tooth's frame: centre of the crop line, mesiodistal, buccolingual
/// and occlusal directions (rows), the crop line's points in that frame.
struct Frame {
    centre: [f64; 3],
    rows: [[f64; 3]; 3],
}

impl Frame {
    fn local(&self, p: [f64; 3]) -> [f64; 3] {
        let d = sub(p, self.centre);
        [
            dot(self.rows[0], d),
            dot(self.rows[1], d),
            dot(self.rows[2], d),
        ]
    }
}

/// The crop line's own frame: its vector area's normal (towards the
/// crown's bulk) and its longest in-plane spread.
fn frame_of(crown: &Mesh, rim: &[u32]) -> Option<Frame> {
    let pts: Vec<[f64; 3]> = rim.iter().map(|&v| crown.vertices[v as usize]).collect();
    let n = pts.len() as f64;
    let c = [0, 1, 2].map(|d| pts.iter().map(|p| p[d]).sum::<f64>() / n);
    let mut area = [0.0; 3];
    for i in 0..pts.len() {
        let x = cross(sub(pts[i], c), sub(pts[(i + 1) % pts.len()], c));
        area = [area[0] + x[0], area[1] + x[1], area[2] + x[2]];
    }
    let an = norm(area);
    if an == 0.0 {
        return None;
    }
    let mut z = area.map(|x| x / an);
    let m = crown.vertices.len() as f64;
    let bulk = [0, 1, 2].map(|d| crown.vertices.iter().map(|p| p[d]).sum::<f64>() / m);
    if dot(sub(bulk, c), z) < 0.0 {
        z = z.map(|x| -x);
    }
    // In-plane covariance of the rim: its main direction is mesiodistal.
    let helper = if z[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = unit(cross(z, helper));
    let v = cross(z, u);
    let (mut suu, mut suv, mut svv) = (0.0, 0.0, 0.0);
    for p in &pts {
        let d = sub(*p, c);
        let (a, b) = (dot(d, u), dot(d, v));
        suu += a * a;
        suv += a * b;
        svv += b * b;
    }
    let angle = 0.5 * (2.0 * suv).atan2(suu - svv);
    let x = [0, 1, 2].map(|d| angle.cos() * u[d] + angle.sin() * v[d]);
    let y = cross(z, x);
    Some(Frame {
        centre: c,
        rows: [x, y, z],
    })
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = norm(a);
    a.map(|x| x / n)
}

/// Polar bins of the crop line round the occlusal axis.
const BINS: usize = 720;

/// The crop line in polar bins: radius, height and the crown wall's
/// direction leaving the line downward (radial, axial components).
struct Rim {
    radius: Vec<f64>,
    height: Vec<f64>,
    wall: Vec<(f64, f64)>,
}

fn bin_of(theta: f64) -> usize {
    (((theta + PI) / (2.0 * PI) * BINS as f64) as usize).min(BINS - 1)
}

fn rim_of(crown: &Mesh, rim: &[u32], frame: &Frame) -> Rim {
    let on_rim: std::collections::HashSet<u32> = rim.iter().copied().collect();
    // The crown's wall at each rim vertex: from its inner neighbours to it.
    let mut towards = vec![[0.0f64; 3]; crown.vertices.len()];
    for f in &crown.faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            for (r, o) in [(a, b), (b, a)] {
                if on_rim.contains(&r) && !on_rim.contains(&o) {
                    let d = sub(crown.vertices[r as usize], crown.vertices[o as usize]);
                    let t = &mut towards[r as usize];
                    *t = [t[0] + d[0], t[1] + d[1], t[2] + d[2]];
                }
            }
        }
    }
    let mut samples: Vec<(f64, f64, f64, f64, f64)> = rim
        .iter()
        .map(|&v| {
            let p = frame.local(crown.vertices[v as usize]);
            let theta = p[1].atan2(p[0]);
            let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
            let t = towards[v as usize];
            let tl = [
                dot(frame.rows[0], t),
                dot(frame.rows[1], t),
                dot(frame.rows[2], t),
            ];
            let radial = tl[0] * theta.cos() + tl[1] * theta.sin();
            let axial = tl[2];
            let n = (radial * radial + axial * axial).sqrt().max(1e-12);
            (theta, r, p[2], radial / n, axial / n)
        })
        .collect();
    samples.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out = Rim {
        radius: vec![0.0; BINS],
        height: vec![0.0; BINS],
        wall: vec![(0.0, -1.0); BINS],
    };
    let k = samples.len();
    for b in 0..BINS {
        let theta = -PI + (b as f64 + 0.5) / BINS as f64 * 2.0 * PI;
        // Neighbouring samples in angle, wrapping round.
        let i = samples.partition_point(|s| s.0 < theta);
        let (lo, hi) = (samples[(i + k - 1) % k], samples[i % k]);
        let mut span = hi.0 - lo.0;
        if span <= 0.0 {
            span += 2.0 * PI;
        }
        let mut off = theta - lo.0;
        if off < 0.0 {
            off += 2.0 * PI;
        }
        let t = (off / span).clamp(0.0, 1.0);
        let mix = |a: f64, b: f64| a + t * (b - a);
        out.radius[b] = mix(lo.1, hi.1);
        out.height[b] = mix(lo.2, hi.2);
        // The neck must leave downward: a wall that runs up or flat at the
        // crop line (a crop above the crown's widest outline) is bent down.
        let (mut r, mut a) = (mix(lo.3, hi.3), mix(lo.4, hi.4));
        if a > -0.3 {
            a = -0.3;
        }
        let n = (r * r + a * a).sqrt();
        r /= n;
        a /= n;
        out.wall[b] = (r, a);
    }
    out
}

/// Points `(radius, height)` of one polar bin's neck, from the crop line
/// down to the trunk's top, as a cubic Hermite curve.
fn neck_profile(
    rim: &Rim,
    b: usize,
    z_top: f64,
    form: &ToothForm,
    mean_radius: f64,
) -> Vec<(f64, f64)> {
    let (r0, z0) = (rim.radius[b], rim.height[b]);
    let (r1, z1) = (form.constriction * r0, z_top);
    let span = (z0 - z1).max(1e-9);
    let (mut tr, mut tz) = rim.wall[b];
    let mut start = Vec::new();
    match form.junction {
        Junction::Smooth => {}
        Junction::Kinked => {
            // Turned 35° inward.
            let a = 35f64.to_radians();
            let (c, s) = (a.cos(), a.sin());
            let (nr, nz) = (tr * c + tz * s, -tr * s + tz * c);
            let n = (nr * nr + nz * nz).sqrt();
            tr = nr / n;
            tz = (nz / n).min(-0.3);
        }
        Junction::Ledge => {
            // Straight in by a step, then down along the wall's direction.
            start.push((r0, z0));
            let step = 0.05 * mean_radius;
            start.push((r0 - step, z0 - 0.01 * span));
        }
    }
    let (sr, sz) = start.last().copied().unwrap_or((r0, z0));
    let n = 48;
    let mut out = start;
    for i in 0..=n {
        let u = i as f64 / n as f64;
        let h00 = 2.0 * u * u * u - 3.0 * u * u + 1.0;
        let h10 = u * u * u - 2.0 * u * u + u;
        let h01 = -2.0 * u * u * u + 3.0 * u * u;
        let h11 = u * u * u - u * u;
        let len = sz - z1;
        let r = h00 * sr + h10 * tr * len + h01 * r1;
        let z = h00 * sz + h10 * tz * len + h01 * z1 - h11 * len;
        out.push((r.max(0.0), z));
    }
    out
}

/// Radius of a neck profile at height `z` (the profile runs downward).
fn profile_radius(profile: &[(f64, f64)], z: f64) -> Option<f64> {
    for w in profile.windows(2) {
        let ((ra, za), (rb, zb)) = (w[0], w[1]);
        if (zb..=za).contains(&z) {
            let t = if za > zb { (za - z) / (za - zb) } else { 0.0 };
            return Some(ra + t * (rb - ra));
        }
    }
    None
}

/// The taper of a root from its top (0) to its apex (1): rounded at the
/// apex, vertical at the top.
fn taper(u: f64) -> f64 {
    if !(0.0..1.0).contains(&u) {
        return if u < 0.0 { 1.0 } else { 0.0 };
    }
    (1.0 - 0.35 * u) * (1.0 - u * u).sqrt()
}

/// Build the whole tooth below `crown` (a cleaned, disk-type real crown).
pub(crate) fn exported_tooth(crown: &Mesh, form: &ToothForm) -> Option<ExportedTooth> {
    let rim_loop = longest_boundary_loop(crown)?;
    let frame = frame_of(crown, &rim_loop)?;
    let rim = rim_of(crown, &rim_loop, &frame);
    let local: Vec<[f64; 3]> = crown.vertices.iter().map(|&p| frame.local(p)).collect();
    let crown_top = local.iter().map(|p| p[2]).fold(f64::MIN, f64::max);
    let rim_low = rim.height.iter().copied().fold(f64::MAX, f64::min);
    let crown_height = crown_top - rim_low;
    let mean_radius = rim.radius.iter().sum::<f64>() / BINS as f64;
    let z_top = rim_low - form.neck * crown_height;
    let root_length = form.root_length * crown_height;
    let apex = z_top - root_length;
    let necks: Vec<Vec<(f64, f64)>> = (0..BINS)
        .map(|b| neck_profile(&rim, b, z_top, form, mean_radius))
        .collect();
    // The trunk's outline at its top, for the roots' placement.
    let (mut half_x, mut half_y) = (0.0f64, 0.0f64);
    for b in 0..BINS {
        let theta = -PI + (b as f64 + 0.5) / BINS as f64 * 2.0 * PI;
        let r = form.constriction * rim.radius[b];
        half_x = half_x.max((r * theta.cos()).abs());
        half_y = half_y.max((r * theta.sin()).abs());
    }
    let extent_xy = 1.3 * local.iter().map(|p| p[0].hypot(p[1])).fold(0.0, f64::max);
    let longest = (crown_top - apex).max(2.0 * extent_xy / 1.3);
    let h = longest / form.voxels as f64;
    // Below the furcation the trunk's outline is split into one angular
    // sector per root (two: mesial and distal; three: two buccal, one
    // lingual), and each part shrinks towards its own centre and moves
    // apart as it runs down to its apex: at the furcation the parts still
    // make up the trunk, so the roots leave it without a ledge.
    let sectors: Vec<(f64, f64)> = match form.roots {
        1 => vec![],
        2 => vec![(-0.5 * PI, 0.5 * PI), (0.5 * PI, 1.5 * PI)],
        _ => vec![(-0.5 * PI, 0.25 * PI), (0.25 * PI, PI), (PI, 1.5 * PI)],
    };
    let trunk_at_furcation =
        |theta: f64| form.constriction * rim.radius[bin_of(theta)] * taper(form.furcation);
    let in_sector = |theta: f64, (a, b): (f64, f64)| {
        let mut t = theta;
        while t < a {
            t += 2.0 * PI;
        }
        while t >= a + 2.0 * PI {
            t -= 2.0 * PI;
        }
        t < b
    };
    let centres: Vec<[f64; 2]> = sectors
        .iter()
        .map(|&sector| {
            // Area centroid of the outline's part in the sector.
            let (mut sx, mut sy, mut sa) = (0.0, 0.0, 0.0);
            for b in 0..BINS {
                let theta = -PI + (b as f64 + 0.5) / BINS as f64 * 2.0 * PI;
                if in_sector(theta, sector) {
                    let r = trunk_at_furcation(theta);
                    let a = 0.5 * r * r;
                    sx += a * (2.0 / 3.0) * r * theta.cos();
                    sy += a * (2.0 / 3.0) * r * theta.sin();
                    sa += a;
                }
            }
            [sx / sa, sy / sa]
        })
        .collect();
    let root_solid = |p: [f64; 3]| -> bool {
        let z = p[2];
        if z < apex {
            return false;
        }
        let theta = p[1].atan2(p[0]);
        let b = bin_of(theta);
        let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
        if z >= z_top {
            // The neck (reaching just above the crop line, inside the crown).
            let top = rim.height[b];
            if z > top + 0.004 * crown_height {
                return false;
            }
            let rz = profile_radius(&necks[b], z.min(top)).unwrap_or(rim.radius[b]);
            return r < rz;
        }
        let u = (z_top - z) / root_length;
        if sectors.is_empty() || u < form.furcation {
            return r < form.constriction * rim.radius[b] * taper(u);
        }
        let v = (u - form.furcation) / (1.0 - form.furcation);
        let t = taper(v);
        if t <= 0.0 {
            return false;
        }
        sectors.iter().zip(&centres).any(|(&sector, c)| {
            let moved = [
                c[0] * (1.0 + form.spread * v),
                c[1] * (1.0 + form.spread * v),
            ];
            let q = [c[0] + (p[0] - moved[0]) / t, c[1] + (p[1] - moved[1]) / t];
            let tq = q[1].atan2(q[0]);
            let rq = q[0].hypot(q[1]);
            // Two voxels at least between neighbouring roots: a furcation
            // is an arch, not a crack of partial voxels.
            let to_edge = [sector.0, sector.1]
                .iter()
                .map(|&a| {
                    let d = (tq - a).rem_euclid(2.0 * PI);
                    let d = d.min(2.0 * PI - d);
                    if d < 0.5 * PI {
                        rq * d.sin()
                    } else {
                        rq
                    }
                })
                .fold(f64::MAX, f64::min);
            in_sector(tq, sector) && rq < trunk_at_furcation(tq) && to_edge * t >= h
        })
    };
    // The grid, tilted at random against the tooth.
    let tilt = morphoid_synth::mesh::RigidMotion::random(form.seed, 0.0).rotation;

    let corners: Vec<[f64; 3]> = (0..8)
        .map(|i| {
            [
                if i & 1 == 0 { -extent_xy } else { extent_xy },
                if i & 2 == 0 { -extent_xy } else { extent_xy },
                if i & 4 == 0 { apex } else { crown_top },
            ]
        })
        .collect();
    let q_of = |p: [f64; 3]| -> [f64; 3] { [dot(tilt[0], p), dot(tilt[1], p), dot(tilt[2], p)] };
    let p_of = |q: [f64; 3]| -> [f64; 3] {
        [0, 1, 2].map(|d| tilt[0][d] * q[0] + tilt[1][d] * q[1] + tilt[2][d] * q[2])
    };
    let mut lo = [f64::MAX; 3];
    let mut hi = [f64::MIN; 3];
    for c in &corners {
        let q = q_of(*c);
        for d in 0..3 {
            lo[d] = lo[d].min(q[d]);
            hi[d] = hi[d].max(q[d]);
        }
    }
    // Tighten to the tooth itself: the crown's points and the axis ends.
    let mut tlo = [f64::MAX; 3];
    let mut thi = [f64::MIN; 3];
    for p in local.iter().copied().chain([[0.0, 0.0, apex]]) {
        let q = q_of(p);
        for d in 0..3 {
            tlo[d] = tlo[d].min(q[d]);
            thi[d] = thi[d].max(q[d]);
        }
    }
    for d in 0..3 {
        let pad = 0.35 * extent_xy;
        lo[d] = lo[d].max(tlo[d] - pad) - 3.0 * h;
        hi[d] = hi[d].min(thi[d] + pad) + 3.0 * h;
    }
    let dims = [0, 1, 2].map(|d| ((hi[d] - lo[d]) / h).ceil() as usize + 1);
    let mut grid = Grid::filled(dims, lo, [h; 3], 0.0);
    // The crown closed by a fan over its crop line, filled by ray parity
    // along the grid's z.
    let centre_local = {
        let n = rim_loop.len() as f64;
        let s = rim_loop.iter().fold([0.0; 3], |acc, &v| {
            let p = local[v as usize];
            [acc[0] + p[0], acc[1] + p[1], acc[2] + p[2]]
        });
        s.map(|x| x / n)
    };
    let mut tris: Vec<[[f64; 3]; 3]> = crown
        .faces
        .iter()
        .map(|f| f.map(|v| q_of(local[v as usize])))
        .collect();
    for i in 0..rim_loop.len() {
        let a = local[rim_loop[i] as usize];
        let b = local[rim_loop[(i + 1) % rim_loop.len()] as usize];
        tris.push([q_of(a), q_of(b), q_of(centre_local)]);
    }
    let (nx, ny, nz) = (dims[0], dims[1], dims[2]);
    let mut hits: Vec<Vec<f64>> = vec![Vec::new(); nx * ny];
    // A small irrational offset keeps columns off the triangles' edges.
    let jitter = 0.000_123_457 * h;
    for t in &tris {
        let (minx, maxx) = (
            t.iter().map(|p| p[0]).fold(f64::MAX, f64::min),
            t.iter().map(|p| p[0]).fold(f64::MIN, f64::max),
        );
        let (miny, maxy) = (
            t.iter().map(|p| p[1]).fold(f64::MAX, f64::min),
            t.iter().map(|p| p[1]).fold(f64::MIN, f64::max),
        );
        let i0 = (((minx - lo[0] - jitter) / h).ceil().max(0.0)) as usize;
        let i1 = (((maxx - lo[0] - jitter) / h).floor()) as isize;
        let j0 = (((miny - lo[1] - jitter) / h).ceil().max(0.0)) as usize;
        let j1 = (((maxy - lo[1] - jitter) / h).floor()) as isize;
        let det =
            (t[1][0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[2][0] - t[0][0]) * (t[1][1] - t[0][1]);
        if det.abs() < 1e-300 {
            continue;
        }
        for i in i0..=(i1.max(-1) as usize).min(nx - 1) {
            if i1 < 0 {
                break;
            }
            for j in j0..=(j1.max(-1) as usize).min(ny - 1) {
                if j1 < 0 {
                    break;
                }
                let x = lo[0] + i as f64 * h + jitter;
                let y = lo[1] + j as f64 * h + jitter;
                let l1 = ((x - t[0][0]) * (t[2][1] - t[0][1])
                    - (t[2][0] - t[0][0]) * (y - t[0][1]))
                    / det;
                let l2 = ((t[1][0] - t[0][0]) * (y - t[0][1])
                    - (x - t[0][0]) * (t[1][1] - t[0][1]))
                    / det;
                if l1 < 0.0 || l2 < 0.0 || l1 + l2 > 1.0 {
                    continue;
                }
                let z = t[0][2] + l1 * (t[1][2] - t[0][2]) + l2 * (t[2][2] - t[0][2]);
                hits[i + nx * j].push(z);
            }
        }
    }
    let pulp = |p: [f64; 3]| -> bool {
        // An ellipsoid in the trunk reaching just into the crown, well
        // inside the dentine.
        let cz = rim_low - 0.2 * crown_height;
        let (dx, dy, dz) = (
            p[0] / (0.3 * half_x),
            p[1] / (0.3 * half_y),
            (p[2] - cz) / (0.25 * crown_height),
        );
        dx * dx + dy * dy + dz * dz < 1.0
    };
    for j in 0..ny {
        for i in 0..nx {
            let col = &mut hits[i + nx * j];
            col.sort_by(f64::total_cmp);
            let pairs = col.len() / 2;
            for k in 0..nz {
                let q = [
                    lo[0] + i as f64 * h,
                    lo[1] + j as f64 * h,
                    lo[2] + k as f64 * h,
                ];
                let zq = q[2];
                let in_crown = (0..pairs).any(|m| (col[2 * m]..col[2 * m + 1]).contains(&zq));
                let p = p_of(q);
                let inside = (in_crown || root_solid(p)) && !(form.pulp && pulp(p));
                if inside {
                    let idx = grid.index(i, j, k);
                    grid.values[idx] = 1.0;
                }
            }
        }
    }
    if form.blur > 0.0 {
        gaussian_blur(&mut grid, form.blur);
    }
    let iso = isosurface(&grid, 0.5);
    // Grid coordinates → the crown's.
    let to_crown = |q: [f64; 3]| -> [f64; 3] {
        let p = p_of(q);
        [0, 1, 2].map(|d| {
            frame.centre[d]
                + frame.rows[0][d] * p[0]
                + frame.rows[1][d] * p[1]
                + frame.rows[2][d] * p[2]
        })
    };
    let mesh = Mesh::new(
        iso.vertices.iter().map(|&q| to_crown(q)).collect(),
        iso.faces.clone(),
    );
    let rows = [0, 1, 2].map(|r| {
        // rows^T q = F^T tilt^T q: row r of the composite.
        [0, 1, 2].map(|d| {
            frame.rows[0][d] * tilt[r][0]
                + frame.rows[1][d] * tilt[r][1]
                + frame.rows[2][d] * tilt[r][2]
        })
    });
    Some(ExportedTooth {
        mesh,
        grid,
        rows,
        centre: frame.centre,
        crop_height: rim.height,
        crop_frame: frame,
    })
}

/// Separable Gaussian blur of `sigma` voxels.
fn gaussian_blur(grid: &mut Grid, sigma: f64) {
    let radius = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f32> = {
        let k: Vec<f64> = (-radius..=radius)
            .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
            .collect();
        let s: f64 = k.iter().sum();
        k.iter().map(|x| (x / s) as f32).collect()
    };
    let dims = grid.dims;
    for axis in 0..3 {
        let mut out = vec![0.0f32; grid.values.len()];
        let stride = match axis {
            0 => 1,
            1 => dims[0],
            _ => dims[0] * dims[1],
        };
        let n = dims[axis] as isize;
        for (idx, o) in out.iter_mut().enumerate() {
            let pos = ((idx / stride) % dims[axis]) as isize;
            let mut acc = 0.0f32;
            for (ki, w) in kernel.iter().enumerate() {
                let p = pos + ki as isize - radius;
                if (0..n).contains(&p) {
                    acc += w * grid.values[(idx as isize + (p - pos) * stride as isize) as usize];
                }
            }
            *o = acc;
        }
        grid.values = out;
    }
}
