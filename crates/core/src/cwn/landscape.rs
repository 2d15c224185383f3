//! Conformal landscapes: the hyperbolic density of a surface seen from each
//! of its sample points, and the neighbourhood dissimilarity of two such
//! views.
//!
//! For a point `z` of the disk, `T_z(w) = (w − z)/(1 − z̄ w)` is a disk
//! automorphism sending `z` to 0, so the hyperbolic disc `N(z, R)` is
//! `T_z⁻¹(N(0, R))` and, the measure `dη` being Möbius-invariant,
//!
//! ```text
//! ∫_{N(z,R)} |𝐟(w) − 𝐟′(m(w))| dη(w) = ∫_{|u|<R} |𝐟(T_z⁻¹ u) − 𝐟′(T_{z′}⁻¹ ρ u)| dη(u)
//! ```
//!
//! for every `m` with `m(z) = z′`, written `m = T_{z′}⁻¹ ∘ ρ ∘ T_z` with
//! `ρ` a rotation about 0 (or a rotation composed with `u ↦ ū` for the
//! orientation-reversing maps). So each point's *landscape*
//! `u ↦ 𝐟(T_z⁻¹ u)` is sampled once on a fixed polar quadrature of
//! `N(0, R)`; rotations by multiples of the angular step are then cyclic
//! shifts of the samples and reflection is reversal of the angle index, and
//! the infimum over `m` becomes a minimum over shifts with no interpolation
//! at comparison time.

use super::{CwnError, CwnParams};
use crate::cp::Prepared;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// A polar quadrature of the hyperbolic disc `N(0, R) = {|u| < R}`:
/// `rings` circles at radii `R (k + ½)/rings`, `angles` equally spaced
/// points on each (angle 0 included, so the grid is symmetric under
/// `u ↦ ū`), each point weighted by the hyperbolic area of its cell.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct Quadrature {
    /// Euclidean radius `R` of the disc about the origin (0 < R < 1).
    pub radius: f64,
    /// Number of rings.
    pub rings: usize,
    /// Points per ring.
    pub angles: usize,
    /// Hyperbolic area of one cell of ring `k` (all cells of a ring are
    /// equal): `(2π/angles) · ½ [1/(1 − r²)]` between the ring's bounds.
    pub weights: Vec<f64>,
}

impl Quadrature {
    /// The quadrature of `params` (checked).
    pub(super) fn new(params: &CwnParams) -> Result<Self, CwnError> {
        params.validate()?;
        let (radius, rings, angles) = (params.radius, params.rings, params.angles);
        let band = |t: f64| 0.5 / (1.0 - t * t);
        let step = std::f64::consts::TAU / angles as f64;
        let weights = (0..rings)
            .map(|k| {
                let lo = radius * k as f64 / rings as f64;
                let hi = radius * (k + 1) as f64 / rings as f64;
                // ∫ r dr / (1 − r²)² = ½ / (1 − r²).
                step * (band(hi) - band(lo))
            })
            .collect();
        Ok(Self {
            radius,
            rings,
            angles,
            weights,
        })
    }

    /// The quadrature point of ring `k` and angle index `j`.
    pub(super) fn point(&self, k: usize, j: usize) -> [f64; 2] {
        let r = self.radius * (k as f64 + 0.5) / self.rings as f64;
        let t = std::f64::consts::TAU * j as f64 / self.angles as f64;
        [r * t.cos(), r * t.sin()]
    }

    /// Number of quadrature points.
    pub(super) fn len(&self) -> usize {
        self.rings * self.angles
    }
}

/// A surface as cWn sees it: its samples (with their area as mass) and,
/// at each, the hyperbolic density over the neighbourhood `N(z, R)` pulled
/// back to `N(0, R)` and sampled on a fixed polar quadrature.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Landscape {
    /// Name of the specimen (copied from the prepared surface).
    pub(super) name: String,
    /// The quadrature every landscape of a comparison must share.
    pub(super) quadrature: Quadrature,
    /// Disk position of each sample.
    pub(super) points: Vec<[f64; 2]>,
    /// Mass of each sample: the area of its Voronoi cell (sum 1), i.e.
    /// `𝐟 dη` lumped at the samples.
    pub(super) masses: Vec<f64>,
    /// Per sample, `rings × angles` values `w_k 𝐟(T_z⁻¹ u_kj)` (ring-major),
    /// already multiplied by the cell weights so that an L1 distance of two
    /// such vectors is the quadrature of `∫ |𝐟 − 𝐟′| dη`.
    pub(super) values: Vec<f32>,
    /// The same values with each ring written twice in a row, so that the
    /// landscape rotated by `s` steps is the contiguous window `s..s+angles`
    /// of each ring.
    pub(super) turned: Vec<f32>,
    /// As `turned`, for the reflected landscape `u ↦ ū` (angle index
    /// `j ↦ −j`).
    pub(super) mirrored: Vec<f32>,
    /// Per sample, the angular profile: the weighted values summed over
    /// the rings (`angles` numbers). By the triangle inequality the L1
    /// distance of two rotated profiles is a lower bound of the full one,
    /// which lets most rotations be skipped exactly.
    pub(super) profile: Vec<f32>,
    /// The profiles, each written twice in a row (see `turned`).
    pub(super) profile_turned: Vec<f32>,
    /// The reflected profiles, each written twice in a row.
    pub(super) profile_mirrored: Vec<f32>,
}

impl Landscape {
    /// The surface's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.masses.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.masses.is_empty()
    }

    fn values_of(&self, i: usize) -> &[f32] {
        let q = self.quadrature.len();
        &self.values[i * q..(i + 1) * q]
    }

    fn turned_of(&self, i: usize, mirrored: bool) -> &[f32] {
        let q = 2 * self.quadrature.len();
        let v = if mirrored {
            &self.mirrored
        } else {
            &self.turned
        };
        &v[i * q..(i + 1) * q]
    }

    fn profile_of(&self, i: usize) -> &[f32] {
        let a = self.quadrature.angles;
        &self.profile[i * a..(i + 1) * a]
    }

    fn profile_turned_of(&self, i: usize, mirrored: bool) -> &[f32] {
        let a = 2 * self.quadrature.angles;
        let v = if mirrored {
            &self.profile_mirrored
        } else {
            &self.profile_turned
        };
        &v[i * a..(i + 1) * a]
    }
}

/// Inverse of `T_z`: `u ↦ (u + z)/(1 + z̄ u)`, sending 0 to `z`.
#[inline]
fn from_origin(z: [f64; 2], u: [f64; 2]) -> [f64; 2] {
    // numerator u + z, denominator 1 + conj(z)·u.
    let (nr, ni) = (u[0] + z[0], u[1] + z[1]);
    let dr = 1.0 + z[0] * u[0] + z[1] * u[1];
    let di = z[0] * u[1] - z[1] * u[0];
    let d2 = dr * dr + di * di;
    [(nr * dr + ni * di) / d2, (ni * dr - nr * di) / d2]
}

/// The (smoothed) hyperbolic density of `p` at the disk point `w`, linear
/// in the triangle of the flattening that holds `w`.
fn density_at(p: &Prepared, w: [f64; 2]) -> Option<f64> {
    let loc = p.locate(w)?;
    let f = p.faces().get(loc.face as usize)?;
    let mut d = 0.0;
    for (k, &v) in f.iter().enumerate() {
        d += loc.bary[k] * p.density().get(v as usize)?;
    }
    Some(d.max(0.0))
}

/// Build the landscape of a prepared surface: sample the density around
/// every sample point on the quadrature of `params` (samples in parallel;
/// the result does not depend on the number of threads).
pub(super) fn landscape(p: &Prepared, params: &CwnParams) -> Result<Landscape, CwnError> {
    p.validate()?;
    let quad = Quadrature::new(params)?;
    let (rings, angles) = (quad.rings, quad.angles);
    let offsets: Vec<[f64; 2]> = (0..rings)
        .flat_map(|k| (0..angles).map(move |j| (k, j)))
        .map(|(k, j)| quad.point(k, j))
        .collect();
    let points: Vec<[f64; 2]> = p.samples().iter().map(|&v| p.uv()[v as usize]).collect();
    let per_sample: Vec<Option<Vec<f32>>> = points
        .par_iter()
        .map(|&z| {
            offsets
                .iter()
                .enumerate()
                .map(|(q, &u)| {
                    let d = density_at(p, from_origin(z, u))?;
                    Some((quad.weights[q / angles] * d) as f32)
                })
                .collect()
        })
        .collect();
    let mut values = Vec::with_capacity(points.len() * quad.len());
    for v in per_sample {
        values.extend(v.ok_or(CwnError::Locate)?);
    }
    let (turned, mirrored) = doubled(&values, angles);
    let mut profile = vec![0.0f32; points.len() * angles];
    for (i, sample) in values.chunks_exact(quad.len()).enumerate() {
        for ring in sample.chunks_exact(angles) {
            for (p, v) in profile[i * angles..(i + 1) * angles].iter_mut().zip(ring) {
                *p += v;
            }
        }
    }
    let (profile_turned, profile_mirrored) = doubled(&profile, angles);
    Ok(Landscape {
        name: p.name().to_string(),
        quadrature: quad,
        points,
        masses: p.sample_weights().to_vec(),
        values,
        turned,
        mirrored,
        profile,
        profile_turned,
        profile_mirrored,
    })
}

/// Each run of `angles` values written twice in a row, as is and with the
/// angle index reversed (`j ↦ −j mod angles`).
fn doubled(values: &[f32], angles: usize) -> (Vec<f32>, Vec<f32>) {
    let mut turned = Vec::with_capacity(2 * values.len());
    let mut mirrored = Vec::with_capacity(2 * values.len());
    for ring in values.chunks_exact(angles) {
        for t in 0..2 * angles {
            turned.push(ring[t % angles]);
            mirrored.push(ring[(2 * angles - t) % angles]);
        }
    }
    (turned, mirrored)
}

/// `Σ |a_k − b_k|` with eight independent partial sums, so that the loop
/// vectorizes (a single float accumulator would force sequential adds).
#[inline]
fn l1(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            acc[l] += (x[l] - y[l]).abs();
        }
    }
    let mut s: f32 = ra.iter().zip(rb).map(|(x, y)| (x - y).abs()).sum();
    for v in acc {
        s += v;
    }
    s
}

/// The neighbourhood dissimilarity `d^R(z_i, z′_j)`: the minimum over the
/// rotations of the quadrature (and, with `reflections`, the reflected
/// rotations) of `∫_{N(0,R)} |𝐟(T_{z_i}⁻¹ u) − 𝐟′(T_{z′_j}⁻¹ ρ u)| dη(u)`.
/// Returns the value and whether the minimum is orientation-reversing.
///
/// Exact pruning, for speed: the L1 distance of the angular profiles
/// (values summed over rings) bounds each rotation's sum from below, so the
/// rotation with the smallest bound is evaluated first and any rotation
/// whose bound reaches the best sum so far is skipped; a full sum is also
/// abandoned ring by ring once it reaches the best.
pub(super) fn neighbourhood_dissimilarity(
    a: &Landscape,
    i: usize,
    b: &Landscape,
    j: usize,
    reflections: bool,
) -> (f32, bool) {
    let angles = a.quadrature.angles;
    let x = a.values_of(i);
    let px = a.profile_of(i);
    let orientations: &[bool] = if reflections {
        &[false, true]
    } else {
        &[false]
    };
    // Lower bounds of every (orientation, shift), at most 2 × 720.
    let mut bounds: Vec<(f32, bool, usize)> = Vec::with_capacity(2 * angles);
    for &mirrored in orientations {
        let py = b.profile_turned_of(j, mirrored);
        for s in 0..angles {
            bounds.push((l1(px, &py[s..s + angles]), mirrored, s));
        }
    }
    let full = |mirrored: bool, s: usize, best: f32| -> f32 {
        let y = b.turned_of(j, mirrored);
        let mut sum = 0.0f32;
        for (k, ring) in x.chunks_exact(angles).enumerate() {
            let w = &y[2 * angles * k + s..2 * angles * k + s + angles];
            sum += l1(ring, w);
            if sum >= best {
                break;
            }
        }
        sum
    };
    let Some(&(_, m0, s0)) = bounds.iter().min_by(|p, q| p.0.total_cmp(&q.0)) else {
        return (f32::INFINITY, false);
    };
    let mut best = (full(m0, s0, f32::INFINITY), m0);
    for &(bound, mirrored, s) in &bounds {
        if bound >= best.0 || (mirrored, s) == (m0, s0) {
            continue;
        }
        let sum = full(mirrored, s, best.0);
        if sum < best.0 {
            best = (sum, mirrored);
        }
    }
    best
}

/// The cost matrix of the transport problem: `d^R(z_i, z′_j)` for every
/// sample `i` of `a` and `j` of `b` (row-major), and whether each minimum
/// was orientation-reversing. Rows are computed in parallel.
pub(super) fn dissimilarity_matrix(
    a: &Landscape,
    b: &Landscape,
    reflections: bool,
) -> (Vec<f64>, Vec<bool>) {
    let m = b.len();
    let rows: Vec<Vec<(f32, bool)>> = (0..a.len())
        .into_par_iter()
        .map(|i| {
            (0..m)
                .map(|j| neighbourhood_dissimilarity(a, i, b, j, reflections))
                .collect()
        })
        .collect();
    let mut cost = Vec::with_capacity(a.len() * m);
    let mut mirrored = Vec::with_capacity(a.len() * m);
    for (c, r) in rows.into_iter().flatten() {
        cost.push(c as f64);
        mirrored.push(r);
    }
    (cost, mirrored)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadrature_weights_sum_to_the_hyperbolic_area() {
        let params = CwnParams::default();
        let q = Quadrature::new(&params).unwrap();
        let total: f64 = q.weights.iter().sum::<f64>() * q.angles as f64;
        let r = params.radius;
        // Hyperbolic area of {|u| < R} for dη = (1 − |u|²)⁻² dx dy.
        let want = std::f64::consts::PI * r * r / (1.0 - r * r);
        assert!((total - want).abs() < 1e-12 * want);
    }

    #[test]
    fn from_origin_inverts_the_centring_map() {
        let z = [0.3, -0.5];
        for u in [[0.0, 0.0], [0.2, 0.1], [-0.4, 0.3]] {
            let w = from_origin(z, u);
            // T_z(w) = (w − z)/(1 − z̄ w) must give back u.
            let (nr, ni) = (w[0] - z[0], w[1] - z[1]);
            let dr = 1.0 - (z[0] * w[0] + z[1] * w[1]);
            let di = -(z[0] * w[1] - z[1] * w[0]);
            let d2 = dr * dr + di * di;
            let back = [(nr * dr + ni * di) / d2, (ni * dr - nr * di) / d2];
            assert!((back[0] - u[0]).abs() < 1e-12 && (back[1] - u[1]).abs() < 1e-12);
        }
        assert_eq!(from_origin(z, [0.0, 0.0]), z);
    }

    #[test]
    fn pruned_search_equals_trying_every_rotation() {
        use crate::cp::{self, PrepareParams};
        use crate::testing::synth::{crown, CROWN_GENERA};
        let params = CwnParams::default();
        let land = |g: usize| {
            let p =
                cp::prepare(&crown(&CROWN_GENERA[g], 5, 1500), &PrepareParams::default()).unwrap();
            landscape(&p, &params).unwrap()
        };
        let (a, b) = (land(0), land(4));
        let angles = a.quadrature.angles;
        let q = a.quadrature.len();
        for i in (0..a.len()).step_by(7) {
            for j in (0..b.len()).step_by(5) {
                let x = &a.values[i * q..(i + 1) * q];
                let mut want = (f32::INFINITY, false);
                for mirrored in [false, true] {
                    for s in 0..angles {
                        let mut sum = 0.0f64;
                        for k in 0..a.quadrature.rings {
                            for t in 0..angles {
                                let u = if mirrored {
                                    (2 * angles - (t + s)) % angles
                                } else {
                                    (t + s) % angles
                                };
                                sum += (x[k * angles + t] - b.values[j * q + k * angles + u]).abs()
                                    as f64;
                            }
                        }
                        if (sum as f32) < want.0 {
                            want = (sum as f32, mirrored);
                        }
                    }
                }
                let got = neighbourhood_dissimilarity(&a, i, &b, j, true);
                assert!(
                    (got.0 - want.0).abs() <= 1e-5 * want.0.max(1e-6),
                    "{got:?} {want:?}"
                );
            }
        }
    }

    #[test]
    fn l1_matches_the_plain_sum() {
        let a: Vec<f32> = (0..27).map(|k| (k as f32 * 0.37).sin()).collect();
        let b: Vec<f32> = (0..27).map(|k| (k as f32 * 0.11).cos()).collect();
        let want: f32 = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).sum();
        assert!((l1(&a, &b) - want).abs() < 1e-5);
    }
}
