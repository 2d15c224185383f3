//! The search for the map of a directed comparison `S → S′`: Möbius maps
//! sending a feature to a feature, over feature pairs × rotation angles ×
//! orientations (each optionally followed by the deformation that brings
//! features onto features), scored on the first samples; the best few
//! refined by Nelder–Mead over nearby disk automorphisms on all samples;
//! the best of those evaluated on every vertex and made area preserving.

use super::comparison::{Correspondence, Directed};
use super::evaluate::{
    boundary_tapered_areas, evaluate_images, evaluate_map, handedness, sample_residual,
};
use super::locate::NO_TRIANGLE;
use super::mobius::Mobius;
use super::moser::{area_preserving_correction, FLOW_STEPS};
use super::optimize::{nelder_mead_unless, GiveUp};
use super::params::CompareParams;
use super::prepared::Prepared;
use super::procrustes::RigidFit;
use super::warp::{mutually_nearest, DiskWarp};

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
    fn matched(&self, m: &Mobius, params: &CompareParams) -> Vec<FeatureMatch> {
        let zs: Vec<[f64; 2]> = self.source.iter().map(|&z| m.apply(z)).collect();
        mutually_nearest(&zs, &self.target, params.warp_max_match)
            .into_iter()
            .map(|(i, j)| (zs[i], self.target[j]))
            .collect()
    }
}

/// The deformation ϱ that moves matched features onto each other.
fn feature_warp(matches: &[FeatureMatch], params: &CompareParams) -> Option<DiskWarp> {
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
fn warps_candidates(params: &CompareParams) -> bool {
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
    /// `m` alone.
    fn mobius(m: Mobius) -> Self {
        Self {
            mobius: m,
            warp: None,
        }
    }

    /// `m`, followed by the deformation of the given feature matches when
    /// the search warps every candidate.
    fn with_matches(m: Mobius, matches: &[FeatureMatch], params: &CompareParams) -> Self {
        let warp = if warps_candidates(params) {
            feature_warp(matches, params)
        } else {
            None
        };
        Self { mobius: m, warp }
    }

    /// `m`, followed by its feature deformation when the search warps every
    /// candidate.
    fn for_candidate(m: Mobius, features: &FeaturePoints, params: &CompareParams) -> Self {
        if warps_candidates(params) {
            Self::with_matches(m, &features.matched(&m, params), params)
        } else {
            Self::mobius(m)
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

    /// The map evaluated on every vertex of `s`, with `weights`.
    fn evaluate(self, s: &Prepared, t: &Prepared, weights: &[f64]) -> Option<Evaluated> {
        let (fit, corr) = evaluate_map(s, t, |z| self.apply(z), handedness(&self.mobius), weights)?;
        Some(Evaluated {
            residual: fit.residual,
            map: self,
            fit,
            corr,
        })
    }
}

/// A candidate of the coarse search: its score on the first samples, its
/// place in the search order (which breaks ties) and the map.
type Candidate = (f64, usize, Mobius);

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

/// A refinement that is not the first gives up after this share of
/// `refine_evaluations` when its residual is still above
/// [`GIVE_UP_MARGIN`] times the best refined residual so far. Most later
/// starts are of the wrong orientation or in another basin and are far
/// behind by then; a start that is not given up runs exactly as before.
/// Measured on the directed pairs among every 4th real tooth (29 teeth):
/// 8 % less CPU time, one distance of 406 changed (0.0675 → 0.0667); with
/// a margin of 1.3 (the full-evaluation margin), 17 changed, by up to
/// 0.008.
const GIVE_UP_SHARE: f64 = 0.25;

/// See [`GIVE_UP_SHARE`].
const GIVE_UP_MARGIN: f64 = 2.0;

/// The samples' triangles under the maps a refinement evaluated last,
/// each with its parameters. Nelder–Mead's next point lies near one of its
/// simplex's vertices, not near the point it evaluated last (a reflection
/// lands across the simplex): its samples are located starting from the
/// triangles of the evaluated point nearest it (4.4 walk steps a sample
/// on two real teeth instead of 6.4 from the point tried last).
struct NearestHints {
    recent: Vec<([f64; 3], Vec<u32>)>,
    next: usize,
}

/// Evaluated points kept by [`NearestHints`]: a simplex's four vertices
/// and the points tried since it last changed.
const RECENT_POINTS: usize = 8;

impl NearestHints {
    fn new(x: [f64; 3], hints: Vec<u32>) -> Self {
        NearestHints {
            recent: vec![(x, hints)],
            next: 1,
        }
    }

    /// A copy of the triangles of the evaluated point nearest `x` (there
    /// is always one: [`NearestHints::new`] takes the first).
    fn nearest(&self, x: [f64; 3]) -> Vec<u32> {
        let d2 = |y: &[f64; 3]| (0..3).map(|k| (x[k] - y[k]).powi(2)).sum::<f64>();
        self.recent
            .iter()
            .min_by(|a, b| d2(&a.0).total_cmp(&d2(&b.0)))
            .map(|r| r.1.clone())
            .unwrap_or_default()
    }

    /// Keep `x`'s triangles, in place of the oldest once full.
    fn add(&mut self, x: [f64; 3], hints: Vec<u32>) {
        if self.recent.len() < RECENT_POINTS {
            self.recent.push((x, hints));
        } else if let Some(slot) = self.recent.get_mut(self.next % RECENT_POINTS) {
            *slot = (x, hints);
        }
        self.next += 1;
    }
}

/// Refine the candidate map `m0` by Nelder–Mead over `m0 ∘ φ` (φ a disk
/// automorphism, initial steps `step` in `(Re a, Im a, θ)`), scored by the
/// residual on all samples, given up as `give_up` says. Returns that
/// residual and the refined map (`m0` itself if refinement does not
/// improve it).
fn refine(
    s: &Prepared,
    t: &Prepared,
    features: &FeaturePoints,
    m0: Mobius,
    step: [f64; 3],
    params: &CompareParams,
    give_up: Option<GiveUp>,
) -> (f64, DiskMap) {
    let mut hints = vec![NO_TRIANGLE; s.samples.len()];
    let start = DiskMap::for_candidate(m0, features, params);
    let score = start.residual(s, t, &mut hints);
    if params.refine_evaluations == 0 {
        return (score, start);
    }
    let mut near = NearestHints::new([0.0; 3], hints);
    let obj = |x: [f64; 3]| {
        perturbed(&m0, x).map_or(f64::MAX, |m| {
            let mut hints = near.nearest(x);
            let r = DiskMap::for_candidate(m, features, params).residual(s, t, &mut hints);
            near.add(x, hints);
            r
        })
    };
    let (x, fx) = nelder_mead_unless(obj, [0.0; 3], step, params.refine_evaluations, give_up);
    match perturbed(&m0, x) {
        Some(m) if fx < score => (fx, DiskMap::for_candidate(m, features, params)),
        _ => (score, start),
    }
}

/// The coarse search: for each feature pair, orientation and rotation
/// angle, the Möbius map sending one feature to the other, scored on the
/// first samples. Maps that bring fewer than `required` features onto
/// mutually nearest features are left out.
fn coarse_candidates(
    s: &Prepared,
    t: &Prepared,
    features: &FeaturePoints,
    params: &CompareParams,
    required: usize,
) -> Vec<Candidate> {
    let coarse = params.coarse_samples.max(1);
    let mut coarse_hints = vec![NO_TRIANGLE; coarse.min(s.samples.len())];
    let mut cands = Vec::new();
    for (k, m) in candidate_maps(s, t, params.angles, params.reflections)
        .into_iter()
        .enumerate()
    {
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
        let score = DiskMap::with_matches(m, &matches, params).residual(s, t, &mut coarse_hints);
        cands.push((score, k + 1, m));
    }
    cands
}

/// The maps the search starts from, in search order: for each feature
/// pair `(p, q)` of `s` and `t`, orientation (reversing ones only with
/// `reflections`) and one of `angles` rotation angles, the Möbius map
/// sending `p` to `q` (the cW search starts from the same maps).
pub(crate) fn candidate_maps(
    s: &Prepared,
    t: &Prepared,
    angles: usize,
    reflections: bool,
) -> Vec<Mobius> {
    let orientations: &[bool] = if reflections {
        &[false, true]
    } else {
        &[false]
    };
    let angles = angles.max(1);
    let mut maps = Vec::new();
    for &p in &s.features {
        for &q in &t.features {
            let (Some(&zp), Some(&zq)) = (s.uv.get(p as usize), t.uv.get(q as usize)) else {
                continue;
            };
            for &refl in orientations {
                for k in 0..angles {
                    let th = k as f64 / angles as f64 * std::f64::consts::TAU;
                    maps.push(Mobius::sending(zp, zq, th, refl));
                }
            }
        }
    }
    maps
}

/// The candidates of the coarse search, best first. Maps must bring
/// `min_feature_matches` features onto features; surfaces with few
/// features cannot meet the full requirement, and when no map meets it,
/// the search runs unconstrained. With no candidate at all, the identity.
fn ranked_candidates(
    s: &Prepared,
    t: &Prepared,
    features: &FeaturePoints,
    params: &CompareParams,
) -> Vec<Candidate> {
    let required = params
        .min_feature_matches
        .min(s.features.len())
        .min(t.features.len());
    let mut cands = coarse_candidates(s, t, features, params, required);
    if cands.is_empty() && required > 1 {
        cands = coarse_candidates(s, t, features, params, 0);
    }
    if cands.is_empty() {
        cands.push((0.0, 0, Mobius::identity()));
    }
    cands.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    cands
}

/// The maps the refinement starts from: the `n` best candidates, and when
/// they are all of one orientation, also the `n` best of the other. The
/// coarse score does not tell a near-symmetric crown's mirror image from
/// the right map: on moved, remeshed copies of one synthetic crown (16
/// poses, 240 directed pairs), the 2 best candidates were both mirror
/// images in 34 pairs (with the best right-handed one added, still in 6),
/// though the right map, once refined, is far better (0.0011 against
/// 0.0047); with the 2 best of the other orientation added, in none.
fn refine_starts(cands: &[Candidate], n: usize) -> Vec<Mobius> {
    let mut starts: Vec<Mobius> = cands.iter().take(n).map(|c| c.2).collect();
    for reversed in [false, true] {
        if starts.iter().any(|m| m.reverses_orientation() == reversed) {
            continue;
        }
        let other: Vec<Mobius> = cands
            .iter()
            .filter(|c| c.2.reverses_orientation() == reversed)
            .take(n)
            .map(|c| c.2)
            .collect();
        starts.extend(other);
    }
    starts
}

/// A map evaluated on every vertex: its residual, the map, the optimal
/// rigid motion and the correspondence.
struct Evaluated {
    residual: f64,
    map: DiskMap,
    fit: RigidFit,
    corr: Correspondence,
}

/// The refined maps evaluated on every vertex, best first. Only maps whose
/// sample residual is near the best one's can have the smallest residual
/// over all vertices; the others are not evaluated.
fn evaluate_refined(
    s: &Prepared,
    t: &Prepared,
    refined: Vec<(f64, DiskMap)>,
    weights: &[f64],
) -> Vec<Evaluated> {
    let best_sampled = refined.iter().map(|r| r.0).fold(f64::INFINITY, f64::min);
    let mut evaluated: Vec<Evaluated> = Vec::new();
    for (score, map) in refined {
        if score > FULL_EVALUATION_MARGIN * best_sampled {
            continue;
        }
        evaluated.extend(map.evaluate(s, t, weights));
    }
    evaluated.sort_by(|a, b| a.residual.total_cmp(&b.residual));
    evaluated
}

/// The other form of the best map, which competes with it: its Möbius
/// part alone when it is deformed (the deformation interpolates feature
/// positions, which carry the noise of the meshing: on a remeshed copy of
/// a surface, the Möbius map alone wins); its deformation when only the
/// best map is deformed so that features land on features.
fn alternative(
    best: &DiskMap,
    features: &FeaturePoints,
    params: &CompareParams,
) -> Option<DiskMap> {
    let m = best.mobius;
    if best.warp.is_some() {
        Some(DiskMap::mobius(m))
    } else if params.feature_warp && !params.search_warp {
        feature_warp(&features.matched(&m, params), params).map(|w| DiskMap {
            mobius: m,
            warp: Some(w),
        })
    } else {
        None
    }
}

/// Make the map of `e` area preserving (χ) and evaluate it again; `e` is
/// left as it is when the correction cannot be computed.
fn area_correct(s: &Prepared, t: &Prepared, e: &mut Evaluated, weights: &[f64]) {
    let images: Vec<[f64; 2]> = s.uv.iter().map(|&z| e.map.apply(z)).collect();
    let Some(target) = t.disk_measure() else {
        return;
    };
    let Some(moved) =
        area_preserving_correction(&target, &images, &s.vertex_areas, &s.sweep, FLOW_STEPS)
    else {
        return;
    };
    if let Some((fit, corr)) = evaluate_images(
        s,
        t,
        &moved,
        handedness(&e.map.mobius),
        weights,
        Some(&e.corr),
    ) {
        e.residual = fit.residual;
        e.fit = fit;
        e.corr = corr;
    }
}

/// The Möbius map `m` alone as a directed result `S → S′`: evaluated on
/// every vertex of `s` (the optimal rigid motion, the residual as its
/// distance, the correspondence), with no deformation or area correction
/// (the cW distance returns its map this way). `None` only for a target
/// without triangles.
pub(crate) fn directed_for_mobius(s: &Prepared, t: &Prepared, m: Mobius) -> Option<Directed> {
    let e = DiskMap::mobius(m).evaluate(s, t, &s.vertex_areas)?;
    let distance = e.residual.max(0.0).sqrt();
    Some(Directed {
        distance,
        reflected: m.reverses_orientation(),
        mobius: m,
        warp: None,
        search_distance: distance,
        rotation: e.fit.rotation,
        translation: e.fit.translation,
        correspondence: e.corr,
    })
}

/// The directed comparison `S → S′` up to the final descent: the search
/// over Möbius maps and feature deformations, and the area correction χ
/// of the best map.
pub(crate) fn search_directed(s: &Prepared, t: &Prepared, params: &CompareParams) -> Directed {
    let features = FeaturePoints::of(s, t);
    let weights =
        boundary_tapered_areas(s, params.boundary_taper_from, params.boundary_taper_weight);
    let cands = ranked_candidates(s, t, &features, params);
    let angle_step = std::f64::consts::TAU / params.angles.max(1) as f64;
    let step = [0.05, 0.05, 0.5 * angle_step];
    let after = (GIVE_UP_SHARE * params.refine_evaluations as f64).ceil() as usize;
    let mut refined: Vec<(f64, DiskMap)> = Vec::new();
    for m0 in refine_starts(&cands, params.refine_candidates.max(1)) {
        let best = refined.iter().map(|r| r.0).fold(f64::INFINITY, f64::min);
        let give_up = best.is_finite().then_some(GiveUp {
            after,
            above: GIVE_UP_MARGIN * best,
        });
        refined.push(refine(s, t, &features, m0, step, params, give_up));
    }
    let mut evaluated = evaluate_refined(s, t, refined, &weights);
    let search_residual = evaluated.first().map_or(f64::MAX, |b| b.residual);
    if let Some(first) = evaluated.first_mut() {
        // The alternative is kept only when it lowers the distance.
        if let Some(other) = alternative(&first.map, &features, params) {
            if let Some(e) = other.evaluate(s, t, &weights) {
                if e.residual < first.residual {
                    *first = e;
                }
            }
        }
        // The final map is made area preserving; its distance is the
        // result.
        if params.area_correction {
            area_correct(s, t, first, &weights);
        }
    }
    match evaluated.into_iter().next() {
        Some(best) => Directed {
            distance: best.residual.max(0.0).sqrt(),
            reflected: best.map.mobius.reverses_orientation(),
            mobius: best.map.mobius,
            warp: best.map.warp,
            search_distance: search_residual.max(0.0).sqrt(),
            rotation: best.fit.rotation,
            translation: best.fit.translation,
            correspondence: best.corr,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cp::{prepare, PrepareParams};
    use crate::testing::synth::{self, CROWN_GENERA};

    use crate::cp::test_crown as crown;

    #[test]
    fn perturbations_stay_inside_the_disk_and_zero_changes_nothing() {
        let m = Mobius::sending([0.1, -0.2], [0.3, 0.1], 0.4, false);
        let same = perturbed(&m, [0.0; 3]).expect("inside");
        for z in [[0.0, 0.0], [0.5, -0.3], [-0.7, 0.2]] {
            let (a, b) = (m.apply(z), same.apply(z));
            assert!((a[0] - b[0]).hypot(a[1] - b[1]) < 1e-12);
        }
        assert!(perturbed(&m, [0.9, 0.0, 0.0]).is_none());
        assert!(perturbed(&m, [0.1, f64::NAN, 0.0]).is_none());
    }

    #[test]
    fn features_match_themselves_and_far_moves_are_not_warped() {
        let s = crown(0, 1);
        let features = FeaturePoints::of(&s, &s);
        let params = CompareParams::default();
        let matches = features.matched(&Mobius::identity(), &params);
        assert_eq!(matches.len(), s.features.len());
        assert!(matches.iter().all(|(a, b)| a == b));
        // A move of half the kernel width or more would fold the disk.
        let far = [([0.0, 0.0], [0.6 * params.warp_width, 0.0])];
        assert!(feature_warp(&far, &params).is_none());
        let near = [([0.0, 0.0], [0.2 * params.warp_width, 0.0])];
        let w = feature_warp(&near, &params).expect("a warp");
        let moved = w.apply([0.0, 0.0]);
        assert!((moved[0] - 0.2 * params.warp_width).abs() < 1e-12 && moved[1].abs() < 1e-12);
    }

    #[test]
    fn candidates_are_ranked_and_respect_the_orientations_asked_for() {
        let (s, t) = (crown(0, 1), crown(1, 2));
        let features = FeaturePoints::of(&s, &t);
        let params = CompareParams::default();
        let cands = ranked_candidates(&s, &t, &features, &params);
        assert!(!cands.is_empty());
        assert!(cands.windows(2).all(|w| w[0].0 <= w[1].0));
        let proper = CompareParams {
            reflections: false,
            min_feature_matches: 0,
            ..params.clone()
        };
        let cands = ranked_candidates(&s, &t, &features, &proper);
        let all = s.features.len() * t.features.len() * proper.angles;
        assert_eq!(cands.len(), all);
        assert!(cands.iter().all(|c| !c.2.reverses_orientation()));
        // The requirement is capped by the feature counts; when no map
        // meets it, the whole search is ranked.
        let strict = CompareParams {
            min_feature_matches: 1000,
            ..proper
        };
        let required = s.features.len().min(t.features.len());
        let meeting = coarse_candidates(&s, &t, &features, &strict, required).len();
        let ranked = ranked_candidates(&s, &t, &features, &strict).len();
        assert_eq!(ranked, if meeting == 0 { all } else { meeting });
        assert!(meeting < all);
    }

    #[test]
    fn hints_come_from_the_nearest_point_evaluated_and_the_oldest_goes() {
        let mut near = NearestHints::new([0.0; 3], vec![0]);
        near.add([1.0, 0.0, 0.0], vec![1]);
        near.add([0.0, 0.0, 2.0], vec![2]);
        assert_eq!(near.nearest([0.9, 0.1, 0.0]), vec![1]);
        assert_eq!(near.nearest([0.0, 0.0, 1.6]), vec![2]);
        assert_eq!(near.nearest([0.1, 0.0, 0.1]), vec![0]);
        // Once full, each new point takes the oldest one's place.
        for k in 3..=RECENT_POINTS {
            near.add([10.0 * k as f64, 0.0, 0.0], vec![k as u32]);
        }
        assert_eq!(near.nearest([0.1, 0.0, 0.1]), vec![1]);
    }

    #[test]
    fn refinement_starts_from_both_orientations() {
        let map = |k: usize, reflect: bool| {
            let th = k as f64 * 0.1;
            (
                k as f64,
                k,
                Mobius::sending([0.0; 2], [0.0; 2], th, reflect),
            )
        };
        let orientations = |starts: &[Mobius]| -> Vec<bool> {
            starts.iter().map(|m| m.reverses_orientation()).collect()
        };
        // The two best are mirror images: the two best proper maps join.
        let cands = [
            map(0, true),
            map(1, true),
            map(2, true),
            map(3, false),
            map(4, false),
            map(5, false),
        ];
        let starts = refine_starts(&cands, 2);
        assert_eq!(orientations(&starts), [true, true, false, false]);
        assert_eq!(starts[2], cands[3].2);
        assert_eq!(starts[3], cands[4].2);
        // Both orientations among the best: nothing is added.
        let cands = [map(0, false), map(1, true), map(2, true), map(3, false)];
        assert_eq!(orientations(&refine_starts(&cands, 2)), [false, true]);
        // One orientation only (reflections off): the best two.
        let cands = [map(0, false), map(1, false), map(2, false)];
        assert_eq!(refine_starts(&cands, 2).len(), 2);
    }

    #[test]
    fn a_surface_and_its_moved_copy_are_found_to_match() {
        let m = synth::crown(&CROWN_GENERA[2], 4, 1500);
        let s = prepare(&m, &PrepareParams::default()).expect("prepare");
        let moved = synth::rigid_motion(&m, 3);
        let t = prepare(&moved, &PrepareParams::default()).expect("prepare");
        let d = search_directed(&s, &t, &CompareParams::default());
        assert!(d.distance < 1e-3, "{}", d.distance);
        assert!(!d.reflected);
        assert_eq!(d.correspondence.len(), s.vertices.len());
        assert!(d.search_distance.is_finite());
    }
}
