//! The continuous Procrustes distance between two prepared surfaces.

use super::locate::{Location, NO_TRIANGLE};
use super::mobius::Mobius;
use super::moser::{area_preserving_correction, FLOW_STEPS};
use super::prepare::{CpParams, Prepared};
use super::procrustes::{Handedness, Moments, RigidFit};
use super::warp::{mutually_nearest, DiskWarp};
use serde::{Deserialize, Serialize};

/// For each vertex of a source surface: a face of the target and the
/// barycentric coordinates of the vertex's image in it.
pub type Correspondence = Vec<(u32, [f64; 3])>;

/// The result of one directed comparison `S → S′`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Directed {
    /// `d(S, S′)`: root of the area-weighted mean squared residual over all
    /// vertices of S after the optimal rigid motion (surfaces of area 1).
    pub distance: f64,
    /// Whether the map reverses orientation (a mirror-image match, with an
    /// improper rigid motion).
    pub reflected: bool,
    /// The disk map from S's disk to S′'s disk.
    pub mobius: Mobius,
    /// The feature-aligning deformation applied after `mobius`, if it
    /// lowered the distance.
    pub warp: Option<DiskWarp>,
    /// The distance of the best map of the search, before the final steps
    /// (the deformation of that map alone, when candidates are not warped,
    /// and the area correction χ).
    pub search_distance: f64,
    /// The optimal orthogonal matrix (row-major) applied to S.
    pub rotation: [[f64; 3]; 3],
    /// The optimal translation applied to S after the rotation.
    pub translation: [f64; 3],
    /// For each vertex of S: the face of S′ and barycentric coordinates of
    /// its image.
    pub correspondence: Vec<(u32, [f64; 3])>,
}

/// Both directed comparisons and the symmetric distance.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Comparison {
    /// `min(d(S, S′), d(S′, S))`.
    pub distance: f64,
    /// `S → S′`.
    pub forward: Directed,
    /// `S′ → S`.
    pub backward: Directed,
    /// Whether the better direction matched a mirror image.
    pub reflected: bool,
}

#[inline]
fn handedness(m: &Mobius) -> Handedness {
    if m.reverses_orientation() {
        Handedness::Improper
    } else {
        Handedness::Proper
    }
}

/// Locate `z` in `t`'s disk, walking from the triangle `hint` (see
/// [`LocateGrid::locate_near`](super::LocateGrid::locate_near)), and
/// interpolate the 3D position there.
#[inline]
fn image(t: &Prepared, z: [f64; 2], hint: u32) -> Option<(Location, [f64; 3])> {
    let loc = t.grid.locate_near(&t.uv, &t.faces, z, hint)?;
    let f = t.faces.get(loc.face as usize)?;
    let mut y = [0.0; 3];
    for (k, &v) in f.iter().enumerate() {
        let p = t.vertices.get(v as usize)?;
        for d in 0..3 {
            y[d] += loc.bary[k] * p[d];
        }
    }
    Some((loc, y))
}

/// Weighted Procrustes residual of the first `hints.len()` samples of `s`
/// and their images in `t` under the disk map `map` (of the given
/// handedness). `hints[i]` is a triangle of `t` near
/// the image of sample `i` (or [`NO_TRIANGLE`]); each is replaced by the
/// triangle found, so that a search moving the map a little locates the
/// next images cheaply.
pub fn sample_residual(
    s: &Prepared,
    t: &Prepared,
    map: impl Fn([f64; 2]) -> [f64; 2],
    handedness: Handedness,
    hints: &mut [u32],
) -> f64 {
    let mut mom = Moments::default();
    for ((&v, &w), hint) in s.samples.iter().zip(&s.sample_weights).zip(hints) {
        let (Some(&z), Some(&x)) = (s.uv.get(v as usize), s.vertices.get(v as usize)) else {
            return f64::MAX;
        };
        match image(t, map(z), *hint) {
            Some((loc, y)) => {
                *hint = loc.face;
                mom.add(x, y, w)
            }
            None => return f64::MAX,
        }
    }
    mom.residual(handedness)
}

/// Evaluate a disk map (`map`, of the given handedness) on all vertices of
/// `s` weighted by vertex area: the optimal rigid motion, its residual and
/// the correspondence.
pub fn evaluate_map(
    s: &Prepared,
    t: &Prepared,
    map: impl Fn([f64; 2]) -> [f64; 2],
    handedness: Handedness,
) -> Option<(RigidFit, Correspondence)> {
    let images: Vec<[f64; 2]> = s.uv.iter().map(|&z| map(z)).collect();
    evaluate_images(s, t, &images, handedness)
}

/// Evaluate given images (points of `t`'s disk, one per vertex of `s`) as
/// in [`evaluate_map`].
pub fn evaluate_images(
    s: &Prepared,
    t: &Prepared,
    images: &[[f64; 2]],
    handedness: Handedness,
) -> Option<(RigidFit, Correspondence)> {
    let mut mom = Moments::default();
    let mut corr: Correspondence = vec![(NO_TRIANGLE, [0.0; 3]); s.vertices.len()];
    // Each vertex's image is searched from its sweep parent's triangle, one
    // edge away.
    for &[v, parent] in &s.sweep {
        let hint = corr.get(parent as usize).map_or(NO_TRIANGLE, |c| c.0);
        let (Some(&w), Some(&x), Some(&a)) = (
            images.get(v as usize),
            s.vertices.get(v as usize),
            s.vertex_areas.get(v as usize),
        ) else {
            return None;
        };
        let (loc, y) = image(t, w, hint)?;
        mom.add(x, y, a);
        *corr.get_mut(v as usize)? = (loc.face, loc.bary);
    }
    if corr.iter().any(|c| c.0 == NO_TRIANGLE) {
        return None;
    }
    Some((mom.fit(handedness), corr))
}

/// Disk positions of the features of both surfaces of a directed
/// comparison, taken once for all the maps it tries.
struct FeaturePoints {
    source: Vec<[f64; 2]>,
    target: Vec<[f64; 2]>,
}

/// A feature of `S` carried into `S′`'s disk and the feature of `S′` it is
/// matched with: `(from, to)`.
type FeatureMatch = ([f64; 2], [f64; 2]);

impl FeaturePoints {
    fn of(s: &Prepared, t: &Prepared) -> Self {
        let on_disk = |p: &Prepared| -> Vec<[f64; 2]> {
            p.features
                .iter()
                .filter_map(|&v| p.uv.get(v as usize))
                .copied()
                .collect()
        };
        Self {
            source: on_disk(s),
            target: on_disk(t),
        }
    }

    /// The source features carried by `m`, paired with their mutually
    /// nearest target features (hyperbolic distance below
    /// `params.warp_max_match`).
    fn matched(&self, m: &Mobius, params: &CpParams) -> Vec<FeatureMatch> {
        let zs: Vec<[f64; 2]> = self.source.iter().map(|&z| m.apply(z)).collect();
        mutually_nearest(&zs, &self.target, params.warp_max_match)
            .into_iter()
            .map(|(i, j)| (zs[i], self.target[j]))
            .collect()
    }
}

/// The deformation ϱ that moves matched features onto each other.
fn feature_warp(matches: &[FeatureMatch], params: &CpParams) -> Option<DiskWarp> {
    let (mut from, mut to) = (Vec::new(), Vec::new());
    for &(a, b) in matches {
        // Large moves would fold the disk; leave those features alone.
        if (a[0] - b[0]).hypot(a[1] - b[1]) < 0.5 * params.warp_width {
            from.push(a);
            to.push(b);
        }
    }
    DiskWarp::interpolating(&from, &to, params.warp_width)
}

/// Whether every map of the search is followed by its feature deformation.
fn warps_candidates(params: &CpParams) -> bool {
    params.feature_warp && params.search_warp
}

/// A map between disks: a Möbius map, followed by a deformation when the
/// search warps every candidate.
#[derive(Debug, Clone)]
struct DiskMap {
    mobius: Mobius,
    warp: Option<DiskWarp>,
}

impl DiskMap {
    /// `m`, followed by the deformation of the given feature matches when
    /// the search warps every candidate.
    fn with_matches(m: Mobius, matches: &[FeatureMatch], params: &CpParams) -> Self {
        let warp = if warps_candidates(params) {
            feature_warp(matches, params)
        } else {
            None
        };
        Self { mobius: m, warp }
    }

    /// `m`, followed by its feature deformation when the search warps every
    /// candidate.
    fn for_candidate(m: Mobius, features: &FeaturePoints, params: &CpParams) -> Self {
        if warps_candidates(params) {
            Self::with_matches(m, &features.matched(&m, params), params)
        } else {
            Self {
                mobius: m,
                warp: None,
            }
        }
    }

    fn apply(&self, z: [f64; 2]) -> [f64; 2] {
        let w = self.mobius.apply(z);
        match &self.warp {
            Some(d) => d.apply(w),
            None => w,
        }
    }

    fn residual(&self, s: &Prepared, t: &Prepared, hints: &mut [u32]) -> f64 {
        sample_residual(s, t, |z| self.apply(z), handedness(&self.mobius), hints)
    }
}

/// Relative spread of the simplex's values at which the refinement stops:
/// the objective is a squared distance, so this settles the distance to
/// about 5e-5 of itself, far below what separates two specimens.
const NELDER_MEAD_TOLERANCE: f64 = 1e-4;

/// Minimize `f` over R³ from `x0` with the Nelder–Mead simplex method,
/// initial steps `step`, at most `max_evals` evaluations (fewer once the
/// simplex's values agree to [`NELDER_MEAD_TOLERANCE`]).
pub fn nelder_mead(
    mut f: impl FnMut([f64; 3]) -> f64,
    x0: [f64; 3],
    step: [f64; 3],
    max_evals: usize,
) -> ([f64; 3], f64) {
    let mut simplex: Vec<([f64; 3], f64)> = Vec::with_capacity(4);
    simplex.push((x0, f(x0)));
    for k in 0..3 {
        let mut x = x0;
        x[k] += step[k];
        simplex.push((x, f(x)));
    }
    let mut evals = 4;
    let lerp = |a: [f64; 3], b: [f64; 3], t: f64| [0, 1, 2].map(|k| a[k] + t * (b[k] - a[k]));
    while evals + 2 <= max_evals {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let worst = simplex[3];
        let centroid =
            [0, 1, 2].map(|k| (simplex[0].0[k] + simplex[1].0[k] + simplex[2].0[k]) / 3.0);
        let xr = lerp(centroid, worst.0, -1.0);
        let fr = f(xr);
        evals += 1;
        if fr < simplex[0].1 {
            let xe = lerp(centroid, worst.0, -2.0);
            let fe = f(xe);
            evals += 1;
            simplex[3] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < simplex[2].1 {
            simplex[3] = (xr, fr);
        } else {
            let xc = if fr < worst.1 {
                lerp(centroid, xr, 0.5)
            } else {
                lerp(centroid, worst.0, 0.5)
            };
            let fc = f(xc);
            evals += 1;
            if fc < worst.1.min(fr) {
                simplex[3] = (xc, fc);
            } else {
                // Shrink towards the best vertex.
                let best = simplex[0].0;
                for s in simplex.iter_mut().skip(1) {
                    let x = lerp(best, s.0, 0.5);
                    *s = (x, f(x));
                    evals += 1;
                }
            }
        }
        let spread = simplex
            .iter()
            .map(|s| s.1)
            .fold(f64::NEG_INFINITY, f64::max)
            - simplex.iter().map(|s| s.1).fold(f64::INFINITY, f64::min);
        if spread <= NELDER_MEAD_TOLERANCE * simplex[0].1.abs().max(1e-300) {
            break;
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    simplex[0]
}

/// `m ∘ φ` with φ the automorphism of parameters `(Re a, Im a, θ)`.
fn perturbed(m: &Mobius, x: [f64; 3]) -> Option<Mobius> {
    if x[0].hypot(x[1]) >= 0.9 || !x.iter().all(|v| v.is_finite()) {
        return None;
    }
    Some(m.compose(&Mobius::from_point_rotation([x[0], x[1]], x[2])))
}

/// A refined map whose residual on all samples exceeds the best refined
/// map's by more than this factor is not evaluated on all vertices: the
/// samples carry Voronoi-area weights, so the two residuals agree far more
/// closely than this.
const FULL_EVALUATION_MARGIN: f64 = 1.3;

/// Refine the candidate map `m0` by Nelder–Mead over `m0 ∘ φ` (φ a disk
/// automorphism, initial steps `step` in `(Re a, Im a, θ)`), scored by the
/// residual on all samples. Returns that residual and the refined map (`m0`
/// itself if refinement does not improve it).
fn refine(
    s: &Prepared,
    t: &Prepared,
    features: &FeaturePoints,
    m0: Mobius,
    step: [f64; 3],
    params: &CpParams,
) -> (f64, DiskMap) {
    let mut hints = vec![NO_TRIANGLE; s.samples.len()];
    let start = DiskMap::for_candidate(m0, features, params);
    let score = start.residual(s, t, &mut hints);
    if params.refine_evaluations == 0 {
        return (score, start);
    }
    let obj = |x: [f64; 3]| {
        perturbed(&m0, x).map_or(f64::MAX, |m| {
            DiskMap::for_candidate(m, features, params).residual(s, t, &mut hints)
        })
    };
    let (x, fx) = nelder_mead(obj, [0.0; 3], step, params.refine_evaluations);
    match perturbed(&m0, x) {
        Some(m) if fx < score => (fx, DiskMap::for_candidate(m, features, params)),
        _ => (score, start),
    }
}

/// The coarse search: for each feature pair, orientation and rotation
/// angle, the Möbius map sending one feature to the other, scored on the
/// first samples. Maps that bring fewer than `required` features onto
/// mutually nearest features are left out. Each candidate is
/// `(score, index in search order, map)`.
fn coarse_candidates(
    s: &Prepared,
    t: &Prepared,
    features: &FeaturePoints,
    params: &CpParams,
    required: usize,
) -> Vec<(f64, usize, Mobius)> {
    let orientations: &[bool] = if params.reflections {
        &[false, true]
    } else {
        &[false]
    };
    let angles = params.angles.max(1);
    let coarse = params.coarse_samples.max(1);
    let mut coarse_hints = vec![NO_TRIANGLE; coarse.min(s.samples.len())];
    let mut cands = Vec::new();
    let mut index = 0usize;
    for &p in &s.features {
        for &q in &t.features {
            let (Some(&zp), Some(&zq)) = (s.uv.get(p as usize), t.uv.get(q as usize)) else {
                continue;
            };
            for &refl in orientations {
                for k in 0..angles {
                    let th = k as f64 / angles as f64 * std::f64::consts::TAU;
                    let m = Mobius::sending(zp, zq, th, refl);
                    index += 1;
                    let matches = if required > 1 || warps_candidates(params) {
                        features.matched(&m, params)
                    } else {
                        Vec::new()
                    };
                    if required > 1 && matches.len() < required {
                        continue;
                    }
                    // Candidates are far apart: no hints between them.
                    coarse_hints.fill(NO_TRIANGLE);
                    let score = DiskMap::with_matches(m, &matches, params).residual(
                        s,
                        t,
                        &mut coarse_hints,
                    );
                    cands.push((score, index, m));
                }
            }
        }
    }
    cands
}

/// The directed comparison `S → S′`: the searched map (see
/// [`search_directed`]) lowered by the final descent.
pub fn compare_directed(s: &Prepared, t: &Prepared, params: &CpParams) -> Directed {
    let mut d = search_directed(s, t, params);
    procrustes_descent(s, t, &mut d, params);
    d
}

/// The directed comparison `S → S′` up to the final descent: the search
/// over Möbius maps and feature deformations, and the area correction χ
/// of the best map.
pub fn search_directed(s: &Prepared, t: &Prepared, params: &CpParams) -> Directed {
    let angles = params.angles.max(1);
    // Surfaces with few features cannot meet the full requirement; when no
    // map meets it, the search runs unconstrained.
    let required = params
        .min_feature_matches
        .min(s.features.len())
        .min(t.features.len());
    let features = FeaturePoints::of(s, t);
    let mut cands = coarse_candidates(s, t, &features, params, required);
    if cands.is_empty() && required > 1 {
        cands = coarse_candidates(s, t, &features, params, 0);
    }
    if cands.is_empty() {
        cands.push((0.0, 0, Mobius::identity()));
    }
    cands.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let step = std::f64::consts::TAU / angles as f64;
    let refined: Vec<(f64, DiskMap)> = cands
        .iter()
        .take(params.refine_candidates.max(1))
        .map(|&(_, _, m0)| refine(s, t, &features, m0, [0.05, 0.05, 0.5 * step], params))
        .collect();
    // Only maps whose sample residual is near the best one's can have the
    // smallest residual over all vertices; the others are not evaluated.
    let best_sampled = refined.iter().map(|r| r.0).fold(f64::INFINITY, f64::min);
    let mut evaluated: Vec<(f64, DiskMap, RigidFit, Correspondence)> = Vec::new();
    for (score, dm) in refined {
        if score > FULL_EVALUATION_MARGIN * best_sampled {
            continue;
        }
        if let Some((fit, corr)) = evaluate_map(s, t, |z| dm.apply(z), handedness(&dm.mobius)) {
            evaluated.push((fit.residual, dm, fit, corr));
        }
    }
    evaluated.sort_by(|a, b| a.0.total_cmp(&b.0));
    let search_residual = evaluated.first().map_or(f64::MAX, |b| b.0);
    if let Some(first) = evaluated.first_mut() {
        let m = first.1.mobius;
        let alternative = if first.1.warp.is_some() {
            // The deformation interpolates feature positions, which carry
            // the noise of the meshing: the Möbius part alone competes with
            // it (on a remeshed copy of a surface, it wins).
            Some(DiskMap {
                mobius: m,
                warp: None,
            })
        } else if params.feature_warp && !params.search_warp {
            // Only the best map is deformed so that features land on
            // features.
            feature_warp(&features.matched(&m, params), params).map(|w| DiskMap {
                mobius: m,
                warp: Some(w),
            })
        } else {
            None
        };
        // Either way, the alternative is kept only when it lowers the
        // distance.
        if let Some(dm) = alternative {
            if let Some((fit, corr)) = evaluate_map(s, t, |z| dm.apply(z), handedness(&m)) {
                if fit.residual < first.0 {
                    *first = (fit.residual, dm, fit, corr);
                }
            }
        }
    }
    // Make the final map area preserving (χ); its distance is the result.
    if params.area_correction {
        if let Some(first) = evaluated.first_mut() {
            let dm = &first.1;
            let images: Vec<[f64; 2]> = s.uv.iter().map(|&z| dm.apply(z)).collect();
            if let Some(moved) =
                area_preserving_correction(t, &images, &s.vertex_areas, &s.sweep, FLOW_STEPS)
            {
                if let Some((fit, corr)) = evaluate_images(s, t, &moved, handedness(&dm.mobius)) {
                    first.0 = fit.residual;
                    first.2 = fit;
                    first.3 = corr;
                }
            }
        }
    }
    let best = evaluated
        .into_iter()
        .next()
        .map(|(res, dm, fit, corr)| (res, dm.mobius, fit, corr, dm.warp));
    match best {
        Some((res, m, fit, corr, warp)) => Directed {
            distance: res.max(0.0).sqrt(),
            reflected: m.reverses_orientation(),
            mobius: m,
            warp,
            search_distance: search_residual.max(0.0).sqrt(),
            rotation: fit.rotation,
            translation: fit.translation,
            correspondence: corr,
        },
        // Only reachable for a target with no triangles, which prepare
        // rejects; report the largest distance rather than NaN.
        None => Directed {
            distance: f64::MAX,
            reflected: false,
            mobius: Mobius::identity(),
            warp: None,
            search_distance: f64::MAX,
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation: [0.0; 3],
            correspondence: Vec::new(),
        },
    }
}

/// Flow steps of the area correction after a descent step: the step moves
/// an area-preserving map only a little, so the flow that undoes its area
/// change is short.
const DESCENT_FLOW_STEPS: usize = 1;

/// Lower the distance of a directed comparison by up to
/// `params.descent_steps` Gauss–Newton steps over the images of `s`'s
/// vertices, each made area preserving again by χ and kept only when it
/// lowers the residual. The cP distance is an infimum over area-preserving
/// maps; the corrected map of the search is one such map, not the best, and
/// this moves it towards a better one.
fn procrustes_descent(s: &Prepared, t: &Prepared, d: &mut Directed, params: &CpParams) {
    if !params.area_correction || d.correspondence.len() != s.vertices.len() {
        return;
    }
    let h = handedness(&d.mobius);
    let mut fit = RigidFit {
        rotation: d.rotation,
        translation: d.translation,
        residual: d.distance * d.distance,
    };
    for _ in 0..params.descent_steps {
        let Some(moved) = gauss_newton_step(s, t, &fit, &d.correspondence, params) else {
            break;
        };
        let Some(corrected) =
            area_preserving_correction(t, &moved, &s.vertex_areas, &s.sweep, DESCENT_FLOW_STEPS)
        else {
            break;
        };
        match evaluate_images(s, t, &corrected, h) {
            Some((f, corr)) if f.residual < fit.residual => {
                fit = f;
                d.correspondence = corr;
            }
            _ => break,
        }
    }
    d.distance = fit.residual.max(0.0).sqrt();
    d.rotation = fit.rotation;
    d.translation = fit.translation;
}

/// The images of `s`'s vertices after one Gauss–Newton step of the
/// residual `Σ a |R x + t − S′(y)|²` in the images y (points of `t`'s disk,
/// given by the correspondence `corr`), with the rigid motion `fit` held
/// fixed. Each vertex's step solves the linearized problem in its image's
/// triangle; the step field is then smoothed over `s` and damped, so that
/// the map stays regular. `None` if the correspondence is inconsistent.
fn gauss_newton_step(
    s: &Prepared,
    t: &Prepared,
    fit: &RigidFit,
    corr: &Correspondence,
    params: &CpParams,
) -> Option<Vec<[f64; 2]>> {
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut images = Vec::with_capacity(corr.len());
    let mut step = Vec::with_capacity(corr.len());
    for (&x, &(f, b)) in s.vertices.iter().zip(corr) {
        let f = t.faces.get(f as usize)?;
        let mut p = [[0.0; 3]; 3];
        let mut u = [[0.0; 2]; 3];
        for k in 0..3 {
            p[k] = *t.vertices.get(f[k] as usize)?;
            u[k] = *t.uv.get(f[k] as usize)?;
        }
        let y: [f64; 3] = [0, 1, 2].map(|d| b[0] * p[0][d] + b[1] * p[1][d] + b[2] * p[2][d]);
        images.push([0, 1].map(|d| b[0] * u[0][d] + b[1] * u[1][d] + b[2] * u[2][d]));
        let r = fit.rotation;
        let e: [f64; 3] = [0, 1, 2].map(|d| dot(r[d], x) + fit.translation[d] - y[d]);
        // The residual's least-squares step in the triangle's barycentric
        // directions, carried into the disk.
        let e1: [f64; 3] = [0, 1, 2].map(|d| p[1][d] - p[0][d]);
        let e2: [f64; 3] = [0, 1, 2].map(|d| p[2][d] - p[0][d]);
        let (g11, g12, g22) = (dot(e1, e1), dot(e1, e2), dot(e2, e2));
        let det = g11 * g22 - g12 * g12;
        if det <= f64::MIN_POSITIVE {
            step.push([0.0; 2]);
            continue;
        }
        let (b1, b2) = (dot(e1, e), dot(e2, e));
        let c1 = (g22 * b1 - g12 * b2) / det;
        let c2 = (g11 * b2 - g12 * b1) / det;
        step.push([0, 1].map(|d| c1 * (u[1][d] - u[0][d]) + c2 * (u[2][d] - u[0][d])));
    }
    let step = smooth_on_faces(&s.faces, &s.vertex_areas, step, params.descent_smoothing);
    Some(
        images
            .iter()
            .zip(&step)
            .map(|(z, d)| {
                let w = [0, 1].map(|k| z[k] + params.descent_damping * d[k]);
                let r = w[0].hypot(w[1]);
                if r > 1.0 {
                    [w[0] / r, w[1] / r]
                } else {
                    w
                }
            })
            .collect(),
    )
}

/// `iterations` steps of averaging a vector field over the faces around
/// each vertex, weighted by face area (vertex areas summed).
fn smooth_on_faces(
    faces: &[[u32; 3]],
    areas: &[f64],
    mut field: Vec<[f64; 2]>,
    iterations: usize,
) -> Vec<[f64; 2]> {
    let n = field.len();
    // Faces with their weights, and each vertex's total weight, once.
    let weighted: Vec<([usize; 3], f64)> = faces
        .iter()
        .map(|f| f.map(|v| v as usize))
        .filter(|idx| idx.iter().all(|&v| v < n && v < areas.len()))
        .map(|idx| (idx, idx.iter().map(|&v| areas[v]).sum::<f64>() / 3.0))
        .collect();
    let mut weight = vec![0.0; n];
    for (idx, a) in &weighted {
        for &v in idx {
            weight[v] += 3.0 * a;
        }
    }
    let mut sum = vec![[0.0; 2]; n];
    for _ in 0..iterations {
        sum.fill([0.0; 2]);
        for (idx, a) in &weighted {
            // The face's area times the mean of its three values.
            let m = [0, 1].map(|d| a * (field[idx[0]][d] + field[idx[1]][d] + field[idx[2]][d]));
            for &v in idx {
                sum[v][0] += m[0];
                sum[v][1] += m[1];
            }
        }
        for ((f, s), w) in field.iter_mut().zip(&sum).zip(&weight) {
            if *w > 0.0 {
                *f = [s[0] / w, s[1] / w];
            }
        }
    }
    field
}

/// The cP distance between two prepared surfaces: both directed
/// comparisons and the smaller of the two. Only the direction with the
/// smaller distance after the search goes through the final descent
/// (unless `descent_both_directions`); the other's distance is that of its
/// searched map, an upper bound.
pub fn compare(s: &Prepared, t: &Prepared, params: &CpParams) -> Comparison {
    let mut forward = search_directed(s, t, params);
    let mut backward = search_directed(t, s, params);
    // The descent is the dearest final step, and it lowers both directions
    // by similar amounts: the direction that is better after the search is
    // the one the distance comes from, so by default only it is descended.
    let forward_better = forward.distance <= backward.distance;
    if params.descent_both_directions || forward_better {
        procrustes_descent(s, t, &mut forward, params);
    }
    if params.descent_both_directions || !forward_better {
        procrustes_descent(t, s, &mut backward, params);
    }
    let (distance, reflected) = if forward.distance <= backward.distance {
        (forward.distance, forward.reflected)
    } else {
        (backward.distance, backward.reflected)
    };
    Comparison {
        distance,
        forward,
        backward,
        reflected,
    }
}
