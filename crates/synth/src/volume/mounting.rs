//! Slice stacks of a real tooth mounted as loose teeth are scanned: the
//! roots pushed into floral foam inside a plastic tube, perhaps with wax
//! or clay beside it and a metal pin glued to a root, with the scanner's
//! ring artefacts, cupping, grey offset and noise. Written as 16-bit TIFF
//! slices, to be read back through the normal volume path.
//!
//! Built independently of the segmentation it tests: the tooth is
//! voxelized from the real crown surface (closed with a cap over its rim
//! and filled by ray parity along z) on top of a tapering two-rooted
//! dentine root grown from the rim's outline, enamel brighter than
//! dentine within a thickness of the crown's outside that thins to nothing
//! at the rim (exact Euclidean distance), and the mounting materials are
//! painted in by their geometry; nothing here thresholds, labels or
//! measures shapes the way the library does.

use super::{write_volume, StackSpec, SynthFormat};
use morphoid_core::mesh::Grid;
use morphoid_core::mesh::{boundary_loops, cross, dot, sub, unit, Mesh};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::path::Path;

/// Why a mounted scan could not be made.
#[derive(Debug, thiserror::Error)]
pub enum MountingError {
    /// The surface given has no rim: mounting builds a root below an open
    /// crown's rim.
    #[error("the crown has no rim: mounting needs an open crown surface")]
    NoRim,
    /// The slices could not be written.
    #[error("writing the mounted scan's slices")]
    Write(#[from] std::io::Error),
}

/// Grey of air (0..1 before the offset).
const AIR: f32 = 0.04;

/// Floral foam: a noisy, textured fill of the tube from the bottom up.
#[derive(Debug, Clone, PartialEq)]
pub struct Foam {
    /// Mean grey (between air and dentine).
    pub grey: f32,
    /// Standard deviation of its texture (grey units).
    pub texture: f32,
    /// Correlation length of the texture, voxels.
    pub grain: f64,
    /// Height of the foam's top over the tooth's lowest point, as a fraction
    /// of the tooth's height in the stack (over 1: the tooth is covered).
    pub fill: f64,
}

/// A plastic tube (or straw) along z, from the end of the stack the roots
/// point to.
#[derive(Debug, Clone, PartialEq)]
pub struct Tube {
    /// Inner radius over the tooth's largest distance from the tube axis.
    pub clearance: f64,
    /// Wall thickness, voxels.
    pub wall: f64,
    /// Grey of the wall (a little above foam).
    pub grey: f32,
    /// Fraction of the mount's height the tube covers (1: the whole stack;
    /// less: a short tube, the rest of the tooth in air or foam above it).
    pub length: f64,
}

/// How a tooth is mounted and scanned.
#[derive(Debug, Clone, PartialEq)]
pub struct Mount {
    /// Voxels across the crown's longest horizontal extent.
    pub voxels_across: usize,
    /// Whether there is a tooth (false: the mount with nothing in it).
    pub tooth: bool,
    /// Foam filling the tube (or a block of foam without one).
    pub foam: Option<Foam>,
    /// The tube.
    pub tube: Option<Tube>,
    /// Blobs of wax or clay in the foam, clear of the tooth.
    pub wax_blobs: usize,
    /// A metal pin glued to a root, running to the end of the stack.
    pub pin: bool,
    /// Amplitude of the ring artefacts (grey).
    pub rings: f32,
    /// Grey offset added to everything.
    pub offset: f32,
    /// Relative darkening at the centre of the field (beam hardening).
    pub cupping: f32,
    /// Standard deviation of the scanner's Gaussian noise (grey).
    pub noise: f32,
    /// Tilt of the tooth's axis from the slice normal, degrees.
    pub tilt_deg: f64,
    /// Crown down (towards slice 0) rather than up.
    pub crown_down: bool,
    /// Seed of every random choice.
    pub seed: u64,
}

impl Default for Mount {
    fn default() -> Self {
        Mount {
            voxels_across: 150,
            tooth: true,
            foam: Some(Foam {
                grey: 0.17,
                texture: 0.05,
                grain: 3.0,
                fill: 0.55,
            }),
            tube: Some(Tube {
                clearance: 1.25,
                wall: 3.0,
                grey: 0.27,
                length: 1.0,
            }),
            wax_blobs: 0,
            pin: false,
            rings: 0.02,
            offset: 0.05,
            cupping: 0.12,
            noise: 0.03,
            tilt_deg: 10.0,
            crown_down: false,
            seed: 1,
        }
    }
}

impl Mount {
    /// A mount varied by `seed` within the ranges real scans show:
    /// resolution `across`, tube size and wall, foam level, grey and
    /// texture, noise, tilt, orientation, wax, a pin.
    pub fn varied(seed: u64, across: usize) -> Mount {
        let mut r = ChaCha8Rng::seed_from_u64(seed ^ 0x006d_6f75_6e74);
        Mount {
            voxels_across: across,
            tooth: true,
            foam: Some(Foam {
                grey: r.gen_range(0.13..0.22),
                texture: r.gen_range(0.035..0.07),
                grain: r.gen_range(2.0..5.0),
                fill: r.gen_range(0.35..1.15),
            }),
            tube: Some(Tube {
                clearance: r.gen_range(1.08..1.6),
                wall: r.gen_range(2.0..4.5),
                grey: r.gen_range(0.24..0.32),
                length: 1.0,
            }),
            wax_blobs: r.gen_range(0..3),
            pin: r.gen_bool(0.4),
            rings: r.gen_range(0.0..0.04),
            offset: r.gen_range(0.0..0.12),
            cupping: r.gen_range(0.0..0.2),
            noise: r.gen_range(0.02..0.05),
            tilt_deg: r.gen_range(0.0..25.0),
            crown_down: r.gen_bool(0.25),
            seed,
        }
    }
}

/// What was written, for checking what segmentation found.
#[derive(Debug, Clone)]
pub struct Mounted {
    /// The crown surface in the stack's voxel coordinates (sample (x, y, z)
    /// at (x, y, z)); empty without a tooth.
    pub crown: Mesh,
    /// The whole tooth's box (crown and root; lowest and highest corner)
    /// in the stack's voxel coordinates.
    pub tooth_box: [[f64; 3]; 2],
    /// Samples along x, y, z.
    pub dims: [usize; 3],
}

/// The crown's frame: rim centroid, axis (towards the occlusal side) and
/// two in-plane axes (the first along the rim's longest extent).
struct Frame {
    centre: [f64; 3],
    axes: [[f64; 3]; 3],
}

/// The rim (longest boundary loop) of an open crown; `None` for a closed
/// surface.
fn rim(crown: &Mesh) -> Option<Vec<[f64; 3]>> {
    let loops = boundary_loops(crown);
    let longest = loops.iter().max_by_key(|l| l.len())?;
    longest
        .iter()
        .map(|&v| crown.vertices.get(v as usize).copied())
        .collect()
}

fn frame(crown: &Mesh, rim: &[[f64; 3]]) -> Frame {
    let n = rim.len() as f64;
    let centre = [0, 1, 2].map(|a| rim.iter().map(|p| p[a]).sum::<f64>() / n);
    // Newell's normal of the rim polygon.
    let mut normal = [0.0; 3];
    for (i, p) in rim.iter().enumerate() {
        let q = rim[(i + 1) % rim.len()];
        normal = [0, 1, 2].map(|a| normal[a] + cross(sub(*p, centre), sub(q, centre))[a]);
    }
    let mut normal = unit(normal);
    let side: f64 = crown
        .vertices
        .iter()
        .map(|v| dot(sub(*v, centre), normal))
        .sum();
    if side < 0.0 {
        normal = normal.map(|c| -c);
    }
    // In-plane principal direction of the rim (2x2 covariance, closed form).
    let helper = if normal[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = unit(cross(normal, helper));
    let v = cross(normal, u);
    let (mut suu, mut svv, mut suv) = (0.0, 0.0, 0.0);
    for p in rim {
        let d = sub(*p, centre);
        let (a, b) = (dot(d, u), dot(d, v));
        suu += a * a;
        svv += b * b;
        suv += a * b;
    }
    let angle = 0.5 * (2.0 * suv).atan2(suu - svv);
    let e1 = [0, 1, 2].map(|k| angle.cos() * u[k] + angle.sin() * v[k]);
    let e2 = cross(normal, e1);
    Frame {
        centre,
        axes: [e1, e2, normal],
    }
}

/// Distance from the rim's centroid to its outline along each of 360
/// directions in the rim plane (frame coordinates).
fn rim_radii(rim2: &[[f64; 2]]) -> Vec<f64> {
    (0..360)
        .map(|k| {
            let t = (k as f64 + 0.5) * std::f64::consts::TAU / 360.0;
            let d = [t.cos(), t.sin()];
            let mut best = 0.0f64;
            for (i, a) in rim2.iter().enumerate() {
                let b = rim2[(i + 1) % rim2.len()];
                // Solve s d = a + w (b - a), 0 <= w <= 1, s > 0.
                let e = [b[0] - a[0], b[1] - a[1]];
                let det = d[0] * (-e[1]) - d[1] * (-e[0]);
                if det.abs() < 1e-300 {
                    continue;
                }
                let s = (a[0] * (-e[1]) - a[1] * (-e[0])) / det;
                let w = (d[0] * a[1] - d[1] * a[0]) / det;
                if (0.0..=1.0).contains(&w) && s > 0.0 {
                    best = best.max(s);
                }
            }
            best
        })
        .collect()
}

/// Squared Euclidean distance from every sample to the nearest sample
/// where `inside` is false (0 outside), by the separable lower-envelope
/// method of Felzenszwalb and Huttenlocher.
fn squared_distance_to_outside(inside: &[bool], dims: [usize; 3]) -> Vec<f32> {
    const FAR: f32 = 1e12;
    let mut d: Vec<f32> = inside.iter().map(|&i| if i { FAR } else { 0.0 }).collect();
    let strides = [1, dims[0], dims[0] * dims[1]];
    for axis in 0..3 {
        let n = dims[axis];
        let lines: Vec<usize> = (0..d.len())
            .filter(|&i| (i / strides[axis]).is_multiple_of(n))
            .collect();
        for chunk in lines.chunks(4096) {
            let out: Vec<(usize, Vec<f64>)> = chunk
                .par_iter()
                .map(|&start| {
                    let f: Vec<f64> = (0..n)
                        .map(|k| f64::from(d[start + k * strides[axis]]))
                        .collect();
                    (start, envelope(&f))
                })
                .collect();
            for (start, line) in out {
                for (k, v) in line.into_iter().enumerate() {
                    d[start + k * strides[axis]] = v as f32;
                }
            }
        }
    }
    d
}

/// One dimension of the distance transform: min over q of f(q) + (p - q)².
fn envelope(f: &[f64]) -> Vec<f64> {
    let n = f.len();
    let mut v = vec![0usize; n];
    let mut z = vec![0.0f64; n + 1];
    let mut k = 0usize;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    let meet = |q: usize, p: usize| {
        ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q - p) as f64)
    };
    for q in 1..n {
        let mut s = meet(q, v[k]);
        while s <= z[k] {
            k -= 1;
            s = meet(q, v[k]);
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    let mut out = vec![0.0; n];
    let mut k = 0;
    for (p, o) in out.iter_mut().enumerate() {
        while z[k + 1] < p as f64 {
            k += 1;
        }
        let q = v[k];
        *o = (p as f64 - q as f64).powi(2) + f[q];
    }
    out
}

/// Which sample centres lie inside the closed `mesh` (voxel coordinates):
/// crossings of a ray along z through each column, in parity.
fn inside_by_parity(mesh: &Mesh, dims: [usize; 3]) -> Vec<bool> {
    let [nx, ny, nz] = dims;
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); nx * ny];
    for (fi, f) in mesh.faces.iter().enumerate() {
        let ps = f.map(|v| mesh.vertices[v as usize]);
        let lo = |a: usize| {
            ps.iter()
                .map(|p| p[a])
                .fold(f64::MAX, f64::min)
                .ceil()
                .max(0.0)
        };
        let hi = |a: usize, n: usize| {
            ps.iter()
                .map(|p| p[a])
                .fold(f64::MIN, f64::max)
                .floor()
                .min(n as f64 - 1.0)
        };
        let (x0, x1, y0, y1) = (lo(0), hi(0, nx), lo(1), hi(1, ny));
        if x1 < x0 || y1 < y0 {
            continue;
        }
        for y in y0 as usize..=y1 as usize {
            for x in x0 as usize..=x1 as usize {
                bins[x + nx * y].push(fi as u32);
            }
        }
    }
    let columns: Vec<Vec<bool>> = (0..nx * ny)
        .into_par_iter()
        .map(|c| {
            // Off the lattice by an irrational fraction: no ray meets an edge.
            let px = (c % nx) as f64 + 0.000_123_457;
            let py = (c / nx) as f64 + 0.000_234_568;
            let mut zs: Vec<f64> = bins[c]
                .iter()
                .filter_map(|&fi| {
                    let [a, b, q] = mesh.faces[fi as usize].map(|v| mesh.vertices[v as usize]);
                    let det = (b[0] - a[0]) * (q[1] - a[1]) - (q[0] - a[0]) * (b[1] - a[1]);
                    if det.abs() < 1e-300 {
                        return None;
                    }
                    let u = ((px - a[0]) * (q[1] - a[1]) - (q[0] - a[0]) * (py - a[1])) / det;
                    let v = ((b[0] - a[0]) * (py - a[1]) - (px - a[0]) * (b[1] - a[1])) / det;
                    (u >= 0.0 && v >= 0.0 && u + v <= 1.0)
                        .then(|| a[2] + u * (b[2] - a[2]) + v * (q[2] - a[2]))
                })
                .collect();
            zs.sort_by(f64::total_cmp);
            let mut col = vec![false; nz];
            for pair in zs.chunks_exact(2) {
                let lo = pair[0].ceil().max(0.0) as usize;
                let hi = pair[1].floor();
                if hi < 0.0 {
                    continue;
                }
                for v in col.iter_mut().take((hi as usize + 1).min(nz)).skip(lo) {
                    *v = true;
                }
            }
            col
        })
        .collect();
    let mut out = vec![false; nx * ny * nz];
    for (c, col) in columns.iter().enumerate() {
        for (z, &v) in col.iter().enumerate() {
            out[c + nx * ny * z] = v;
        }
    }
    out
}

/// Smooth value noise of unit standard deviation: normal values on a
/// lattice `grain` samples apart, interpolated with smoothstep weights.
fn value_noise(dims: [usize; 3], grain: f64, rng: &mut ChaCha8Rng) -> Vec<f32> {
    let g = grain.max(1.0);
    let lat = dims.map(|d| (d as f64 / g).ceil() as usize + 2);
    let lattice: Vec<f32> = (0..lat[0] * lat[1] * lat[2])
        .map(|_| {
            let u1: f32 = rng.gen_range(f32::EPSILON..1.0);
            let u2: f32 = rng.gen();
            (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
        })
        .collect();
    let at = |i: usize, j: usize, k: usize| lattice[i + lat[0] * (j + lat[1] * k)];
    let smooth = |t: f64| (t * t * (3.0 - 2.0 * t)) as f32;
    let mut out = vec![0f32; dims[0] * dims[1] * dims[2]];
    out.par_chunks_mut(dims[0] * dims[1])
        .enumerate()
        .for_each(|(z, plane)| {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let p = [x as f64 / g, y as f64 / g, z as f64 / g];
                    let b = p.map(|c| c.floor() as usize);
                    let w = [0, 1, 2].map(|a| smooth(p[a] - b[a] as f64));
                    let mut acc = 0.0;
                    for c in 0..8usize {
                        let (dx, dy, dz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
                        let wt = (if dx == 1 { w[0] } else { 1.0 - w[0] })
                            * (if dy == 1 { w[1] } else { 1.0 - w[1] })
                            * (if dz == 1 { w[2] } else { 1.0 - w[2] });
                        acc += wt * at(b[0] + dx, b[1] + dy, b[2] + dz);
                    }
                    plane[x + dims[0] * y] = acc;
                }
            }
        });
    let n = out.len() as f64;
    let mean = out.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
    let sd = (out
        .iter()
        .map(|&v| (f64::from(v) - mean).powi(2))
        .sum::<f64>()
        / n)
        .sqrt()
        .max(1e-9);
    out.par_iter_mut()
        .for_each(|v| *v = ((f64::from(*v) - mean) / sd) as f32);
    out
}

/// Separable Gaussian blur, standard deviation `sigma` samples.
fn blur(values: &mut [f32], dims: [usize; 3], sigma: f64) {
    let r = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let total: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / total).collect();
    let strides = [1, dims[0], dims[0] * dims[1]];
    for axis in 0..3 {
        let n = dims[axis] as i64;
        let src = values.to_vec();
        values.par_iter_mut().enumerate().for_each(|(i, out)| {
            let pos = ((i / strides[axis]) % dims[axis]) as i64;
            let mut acc = 0.0;
            for (k, w) in kernel.iter().enumerate() {
                let j = (pos + k as i64 - r).clamp(0, n - 1);
                acc += w * src[(i as i64 + (j - pos) * strides[axis] as i64) as usize];
            }
            *out = acc;
        });
    }
}

/// Write `crown` (an open crown surface) mounted as `mount` says, as a
/// folder of 16-bit TIFF slices at `path`.
pub fn write_mounted(crown: &Mesh, mount: &Mount, path: &Path) -> Result<Mounted, MountingError> {
    let (grid, mounted) = mounted_grid(crown, mount)?;
    write_scan(&grid, mount, path)?;
    Ok(mounted)
}

/// `grid` as 16-bit TIFF slices at `path`, with the scanner noise of
/// `mount`.
fn write_scan(grid: &Grid, mount: &Mount, path: &Path) -> std::io::Result<[f64; 3]> {
    let spec = StackSpec {
        noise: mount.noise,
        seed: mount.seed,
        ..Default::default()
    };
    write_volume(grid, path, SynthFormat::Tiff16, &spec)
}

/// Several teeth scanned together (batch scanning): each mounted as its
/// `Mount` says (its own foam and tube), the mounts standing side by side
/// along x, `gap` voxels apart (a negative gap pushes them into each
/// other: tubes and foam merge, the brighter material wins), aligned at
/// the bottom, in one stack of 16-bit TIFF slices at `path`. Returns each
/// tooth's crown in the stack's voxel coordinates, in order along x
/// (none, and nothing written, for no teeth).
pub fn write_batch(
    teeth: &[(&Mesh, Mount)],
    gap: i64,
    path: &Path,
) -> Result<Vec<Mounted>, MountingError> {
    write_batch_in(teeth, gap, [0; 3], path)
}

/// [`write_batch`] into a stack of at least `min_dims` voxels: the row of
/// mounts centred in x and y, air around it and above it.
pub fn write_batch_in(
    teeth: &[(&Mesh, Mount)],
    gap: i64,
    min_dims: [usize; 3],
    path: &Path,
) -> Result<Vec<Mounted>, MountingError> {
    let Some((_, first)) = teeth.first() else {
        return Ok(Vec::new());
    };
    let parts: Vec<(Grid, Mounted)> = teeth
        .iter()
        .map(|(crown, mount)| mounted_grid(crown, mount))
        .collect::<Result<_, _>>()?;
    let width: i64 =
        parts.iter().map(|(g, _)| g.dims[0] as i64).sum::<i64>() + gap * (parts.len() as i64 - 1);
    let tallest = |a: usize| {
        let part = parts.iter().map(|(g, _)| g.dims[a]).max().unwrap_or(1);
        part.max(min_dims[a])
    };
    let dims = [
        (width.max(1) as usize).max(min_dims[0]),
        tallest(1),
        tallest(2),
    ];
    // Air of the first mount's scan everywhere no mount reaches.
    let air = parts.first().map_or(AIR, |(g, _)| g.values[0]);
    let mut values = vec![f32::MIN; dims[0] * dims[1] * dims[2]];
    let mut out = Vec::new();
    let mut x0: i64 = (dims[0] as i64 - width).max(0) / 2;
    for (g, mounted) in parts {
        let y0 = (dims[1] - g.dims[1]) / 2;
        for z in 0..g.dims[2] {
            for y in 0..g.dims[1] {
                for x in 0..g.dims[0] {
                    let tx = x0 + x as i64;
                    if tx < 0 || tx >= dims[0] as i64 {
                        continue;
                    }
                    let i = tx as usize + dims[0] * (y + y0 + dims[1] * z);
                    values[i] = values[i].max(g.values[g.index(x, y, z)]);
                }
            }
        }
        let crown: Vec<[f64; 3]> = mounted
            .crown
            .vertices
            .iter()
            .map(|p| [p[0] + x0 as f64, p[1] + y0 as f64, p[2]])
            .collect();
        let offset = [x0 as f64, y0 as f64, 0.0];
        out.push(Mounted {
            crown: Mesh::new(crown, mounted.crown.faces.clone()),
            tooth_box: mounted
                .tooth_box
                .map(|c| [0, 1, 2].map(|a| c[a] + offset[a])),
            dims,
        });
        x0 += g.dims[0] as i64 + gap;
    }
    for v in &mut values {
        if *v == f32::MIN {
            *v = air;
        }
    }
    let grid = Grid {
        dims,
        origin: [0.0; 3],
        spacing: [1.0; 3],
        values,
    };
    write_scan(&grid, first, path)?;
    Ok(out)
}

/// The grey values of `crown` mounted as `mount` says (before the
/// scanner's noise, which the writer adds), and what was placed.
fn mounted_grid(crown: &Mesh, mount: &Mount) -> Result<(Grid, Mounted), MountingError> {
    let mut rng = ChaCha8Rng::seed_from_u64(mount.seed);
    let rim = rim(crown).ok_or(MountingError::NoRim)?;
    let fr = frame(crown, &rim);
    let local = |p: [f64; 3]| fr.axes.map(|e| dot(sub(p, fr.centre), e));
    let crown_local: Vec<[f64; 3]> = crown.vertices.iter().map(|&p| local(p)).collect();
    let rim_local: Vec<[f64; 3]> = rim.iter().map(|&p| local(p)).collect();
    let length = {
        let (lo, hi) = crown_local
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p[0]), b.max(p[0])));
        hi - lo
    };
    let height = crown_local.iter().map(|p| p[2]).fold(0.0, f64::max);
    // Everything below in voxels of the stack.
    let h = length / mount.voxels_across as f64;
    let crown_vox: Vec<[f64; 3]> = crown_local.iter().map(|p| p.map(|c| c / h)).collect();
    let rim2: Vec<[f64; 2]> = rim_local.iter().map(|p| [p[0] / h, p[1] / h]).collect();
    let radii = rim_radii(&rim2);
    let height = height / h;
    let root_length = mount.voxels_across as f64 * rng.gen_range(0.75..1.0);
    let half_length = radii[0].max(radii[180]);

    // The tooth's orientation in the stack: spin about its axis, tilt,
    // and crown up or down.
    let spin = rng.gen_range(0.0..std::f64::consts::TAU);
    let tilt = mount.tilt_deg.to_radians();
    let tilt_dir = rng.gen_range(0.0..std::f64::consts::TAU);
    let rot = {
        let (cs, ss) = (spin.cos(), spin.sin());
        let spin_m = [[cs, -ss, 0.0], [ss, cs, 0.0], [0.0, 0.0, 1.0]];
        let k = [tilt_dir.cos(), tilt_dir.sin(), 0.0];
        let (ct, st) = (tilt.cos(), tilt.sin());
        // Rodrigues' rotation about the horizontal axis k.
        let kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
        let mut tilt_m = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                let kk: f64 = (0..3).map(|l| kx[i][l] * kx[l][j]).sum();
                tilt_m[i][j] = f64::from(u8::from(i == j)) + st * kx[i][j] + (1.0 - ct) * kk;
            }
        }
        let flip = if mount.crown_down { -1.0 } else { 1.0 };
        let flip_m = [[1.0, 0.0, 0.0], [0.0, flip, 0.0], [0.0, 0.0, flip]];
        let mul = |a: [[f64; 3]; 3], b: [[f64; 3]; 3]| {
            let mut m = [[0.0; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    m[i][j] = (0..3).map(|l| a[i][l] * b[l][j]).sum();
                }
            }
            m
        };
        mul(flip_m, mul(tilt_m, spin_m))
    };
    let apply = |m: &[[f64; 3]; 3], p: [f64; 3]| [0, 1, 2].map(|i| dot(m[i], p));
    let transpose = |m: &[[f64; 3]; 3]| [0, 1, 2].map(|i| [m[0][i], m[1][i], m[2][i]]);
    let rot_t = transpose(&rot);

    // Extent of the tooth: the crown and the root's outline.
    let mut points: Vec<[f64; 3]> = crown_vox.iter().map(|&p| apply(&rot, p)).collect();
    for k in (0..360).step_by(6) {
        let t = (k as f64 + 0.5) * std::f64::consts::TAU / 360.0;
        for s in 0..=10 {
            let z = -root_length * s as f64 / 10.0;
            let r = radii[k] * root_scale(s as f64 / 10.0);
            points.push(apply(&rot, [r * t.cos(), r * t.sin(), z]));
        }
    }
    let lo = [0, 1, 2].map(|a| points.iter().map(|p| p[a]).fold(f64::MAX, f64::min));
    let hi = [0, 1, 2].map(|a| points.iter().map(|p| p[a]).fold(f64::MIN, f64::max));
    let axis_xy = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    let reach = points
        .iter()
        .map(|p| ((p[0] - axis_xy[0]).powi(2) + (p[1] - axis_xy[1]).powi(2)).sqrt())
        .fold(0.0, f64::max);
    let (clearance, wall) = mount
        .tube
        .as_ref()
        .map(|t| (t.clearance, t.wall))
        .unwrap_or((1.25, 0.0));
    let inner = reach * clearance + 2.0;
    let margin_xy = 6.0;
    let side = (2.0 * (inner + wall + margin_xy)).ceil() as usize;
    let tall = hi[2] - lo[2];
    let (below, above) = (0.12 * tall + 6.0, 0.1 * tall + 6.0);
    let dims = [side, side, (tall + below + above).ceil() as usize];
    let centre = [side as f64 / 2.0, side as f64 / 2.0];
    // Stack position of the tooth-frame origin (the rim's centroid).
    let shift = [
        centre[0] - axis_xy[0],
        centre[1] - axis_xy[1],
        below - lo[2],
    ];
    let to_stack = |p: [f64; 3]| {
        let q = apply(&rot, p);
        [q[0] + shift[0], q[1] + shift[1], q[2] + shift[2]]
    };
    let to_tooth = |x: usize, y: usize, z: usize| {
        let q = [
            x as f64 - shift[0],
            y as f64 - shift[1],
            z as f64 - shift[2],
        ];
        apply(&rot_t, q)
    };

    // The crown closed by a fan over its rim, in stack voxels.
    let crown_stack: Vec<[f64; 3]> = crown_vox.iter().map(|&p| to_stack(p)).collect();
    let mut closed = Mesh::new(crown_stack.clone(), crown.faces.clone());
    let apex = closed.vertices.len() as u32;
    closed.vertices.push(to_stack([0.0, 0.0, 0.0]));
    let loop_ids = {
        let loops = boundary_loops(crown);
        loops
            .into_iter()
            .max_by_key(|l| l.len())
            .unwrap_or_default()
    };
    for (i, &a) in loop_ids.iter().enumerate() {
        let b = loop_ids[(i + 1) % loop_ids.len()];
        closed.faces.push([a, b, apex]);
    }
    let n = dims[0] * dims[1] * dims[2];
    let crown_inside = if mount.tooth {
        inside_by_parity(&closed, dims)
    } else {
        vec![false; n]
    };
    // The root below the rim: the rim's outline, narrowed at the neck and
    // tapering, split in two (mesial and distal) below the furcation.
    let furcation = 0.3;
    let in_root = |q: [f64; 3]| -> bool {
        if q[2] > 0.25 * height || q[2] < -root_length {
            return false;
        }
        let u = (-q[2] / root_length).max(0.0);
        let r = (q[0] * q[0] + q[1] * q[1]).sqrt();
        let theta = q[1].atan2(q[0]).rem_euclid(std::f64::consts::TAU);
        let k = ((theta / std::f64::consts::TAU * 360.0) as usize).min(359);
        if r > radii[k] * root_scale(u) {
            return false;
        }
        if u > furcation {
            let w = ((u - furcation) / (1.0 - furcation)).powf(0.6);
            if q[0].abs() < 0.45 * half_length * root_scale(u) * w {
                return false;
            }
        }
        true
    };
    let tooth: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|i| {
            if !mount.tooth {
                return false;
            }
            if crown_inside[i] {
                return true;
            }
            let (x, y, z) = (
                i % dims[0],
                (i / dims[0]) % dims[1],
                i / (dims[0] * dims[1]),
            );
            in_root(to_tooth(x, y, z))
        })
        .collect();
    // Enamel: the crown's outside layer, thinning to nothing at the rim.
    let thickness = 0.045 * mount.voxels_across as f64;
    let depth2 = squared_distance_to_outside(&tooth, dims);
    let enamel: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|i| {
            if !crown_inside[i] {
                return false;
            }
            let (x, y, z) = (
                i % dims[0],
                (i / dims[0]) % dims[1],
                i / (dims[0] * dims[1]),
            );
            let q = to_tooth(x, y, z);
            let t = thickness * (q[2] / (0.35 * height)).clamp(0.0, 1.0);
            f64::from(depth2[i]) < t * t
        })
        .collect();
    drop(depth2);

    // Mounting materials.
    let radial = |i: usize| {
        let (x, y) = ((i % dims[0]) as f64, ((i / dims[0]) % dims[1]) as f64);
        ((x - centre[0]).powi(2) + (y - centre[1]).powi(2)).sqrt()
    };
    let mut values = vec![AIR; n];
    if let Some(foam) = &mount.foam {
        let texture = value_noise(dims, foam.grain, &mut rng);
        let top = below + foam.fill * tall;
        values.par_iter_mut().enumerate().for_each(|(i, v)| {
            let z = (i / (dims[0] * dims[1])) as f64;
            let below_top = if mount.crown_down {
                z > dims[2] as f64 - top
            } else {
                z < top
            };
            if radial(i) < inner && below_top {
                *v = (foam.grey + foam.texture * texture[i]).max(AIR);
            }
        });
    }
    if let Some(tube) = &mount.tube {
        let end = tube.length * dims[2] as f64;
        values.par_iter_mut().enumerate().for_each(|(i, v)| {
            let r = radial(i);
            let z = (i / (dims[0] * dims[1])) as f64;
            let along = if mount.crown_down {
                z >= dims[2] as f64 - end
            } else {
                z < end
            };
            if r >= inner && r < inner + tube.wall && along {
                *v = tube.grey;
            }
        });
    }
    for _ in 0..mount.wax_blobs {
        let grey = rng.gen_range(0.34..0.42f32);
        let radius = rng.gen_range(0.06..0.12) * mount.voxels_across as f64;
        for _attempt in 0..60 {
            let r = rng.gen_range(0.0..(inner - radius - 1.0).max(0.0));
            let t = rng.gen_range(0.0..std::f64::consts::TAU);
            let c = [
                centre[0] + r * t.cos(),
                centre[1] + r * t.sin(),
                rng.gen_range(radius + 2.0..(dims[2] as f64 - radius - 2.0).max(radius + 3.0)),
            ];
            let lo = c.map(|v| (v - radius - 3.0).floor().max(0.0) as usize);
            let hi = [0, 1, 2].map(|a| ((c[a] + radius + 3.0).ceil() as usize).min(dims[a] - 1));
            let mut clear = true;
            'check: for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        if tooth[x + dims[0] * (y + dims[1] * z)] {
                            clear = false;
                            break 'check;
                        }
                    }
                }
            }
            if !clear {
                continue;
            }
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let d2 = (x as f64 - c[0]).powi(2)
                            + (y as f64 - c[1]).powi(2)
                            + ((z as f64 - c[2]) * 1.3).powi(2);
                        if d2 < radius * radius {
                            values[x + dims[0] * (y + dims[1] * z)] = grey;
                        }
                    }
                }
            }
            break;
        }
    }
    for i in 0..n {
        if tooth[i] {
            values[i] = if enamel[i] { 0.75 } else { 0.45 };
        }
    }
    if mount.pin && mount.tooth {
        // Glued to the tip of the first root, running straight to the end
        // of the stack away from the crown.
        let tip = to_stack([
            0.6 * half_length * root_scale(0.95),
            0.0,
            -0.95 * root_length,
        ]);
        let radius = rng.gen_range(1.5..3.0);
        let (z0, z1) = if mount.crown_down {
            (tip[2].floor().max(0.0) as usize, dims[2])
        } else {
            (0, (tip[2].ceil() as usize).min(dims[2]))
        };
        for z in z0..z1 {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let d2 = (x as f64 - tip[0]).powi(2) + (y as f64 - tip[1]).powi(2);
                    if d2 < radius * radius {
                        values[x + dims[0] * (y + dims[1] * z)] = 1.0;
                    }
                }
            }
        }
    }
    // The scanner: point spread, cupping, rings, offset (noise is added as
    // the slices are written).
    blur(&mut values, dims, 0.8);
    let field = centre[0];
    let mut ring_radii: Vec<(f64, f32)> = (0..12)
        .map(|_| {
            (
                rng.gen_range(2.0..field),
                mount.rings * rng.gen_range(-1.0..1.0f32),
            )
        })
        .collect();
    ring_radii.sort_by(|a, b| a.0.total_cmp(&b.0));
    values.par_iter_mut().enumerate().for_each(|(i, v)| {
        let r = radial(i);
        let dip = mount.cupping * (1.0 - (r / field).powi(2)).max(0.0) as f32;
        let mut out = AIR + (*v - AIR) * (1.0 - dip);
        for &(rr, a) in &ring_radii {
            out += a * (-((r - rr).powi(2)) / 0.5).exp() as f32;
        }
        *v = out + mount.offset;
    });
    let grid = Grid {
        dims,
        origin: [0.0; 3],
        spacing: [1.0; 3],
        values,
    };
    let mounted = Mounted {
        crown: if mount.tooth {
            Mesh::new(crown_stack, crown.faces.clone())
        } else {
            Mesh::new(Vec::new(), Vec::new())
        },
        tooth_box: [lo, hi].map(|c| [0, 1, 2].map(|a| c[a] + shift[a])),
        dims,
    };
    Ok((grid, mounted))
}

/// The root's width as a fraction of the rim's at `u` (0 at the rim, 1 at
/// the apex): a neck just below the rim, then a taper.
fn root_scale(u: f64) -> f64 {
    let neck = 0.95 - 0.1 * (u / 0.12).clamp(0.0, 1.0).powi(2);
    neck * (1.0 - 0.55 * u.clamp(0.0, 1.0).powf(1.3))
}

/// The mounts of `count` teeth scanned together, varied by `seed`, at
/// `across` voxels across each crown: one scan of one kind of mount (the
/// same foam and tube material, offset, noise and rings for every tooth),
/// each mount its own size, foam level, tilt and orientation.
pub fn batch_mounts(seed: u64, across: usize, count: usize) -> Vec<Mount> {
    let first = Mount::varied(seed, across);
    (0..count)
        .map(|i| {
            let mut m = Mount::varied(seed + 17 * i as u64, across);
            if let (Some(f), Some(f0)) = (&mut m.foam, &first.foam) {
                f.grey = f0.grey;
                f.texture = f0.texture;
                f.grain = f0.grain;
            }
            if let (Some(t), Some(t0)) = (&mut m.tube, &first.tube) {
                t.grey = t0.grey;
            }
            m.offset = first.offset;
            m.noise = first.noise;
            m.rings = first.rings;
            m.cupping = first.cupping.min(0.08);
            m
        })
        .collect()
}
