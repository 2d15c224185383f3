//! Finding the specimen among mounting material: the densest large object.
//!
//! Candidate levels come from multi-level Otsu thresholds (3, 4 and 5
//! classes) and the two-class foreground threshold. At each level the
//! samples above it are opened by a small cube ([`THIN_RADIUS`]), which
//! cuts off thin parts (tube walls, straws, pins, strands of foam), and
//! split into 6-connected objects. From the highest level down, the first
//! large object that neither spans the field of view nor is textured like
//! foam is the seed (enamel, or the whole tooth). Going down the levels,
//! the object containing it grows by its own dense materials (dentine
//! under enamel) and the search stops where it would take in mounting
//! material or background, recognised by what it is rather than where it
//! reaches: what the object gains is much lighter than the specimen's own
//! material ([`DENSE_SHARE`]: foam, plastic, wax), porous next to it
//! ([`POROUS`]) or textured for its own contrast (foam), whatever the
//! height of the mount; or the object spans the field of view (foam in a
//! tube, the tube, the background). A level that adds only a thin layer
//! (the blur at the specimen's edge) is passed over. The final level lies
//! between the specimen's material and what surrounds it, within the
//! levels that kept the specimen alone; there, another large object is a
//! specimen too unless it is mounting material by the same rules.

use super::segment::{connected_components, fill_cavities, SegmentReport};
use super::shape::{
    dilate_cube, erode_cube, local_variation, object_stats, open_cube, quantile, ObjectStats,
};
use super::split::{separate_at_necks, Separation};
use super::threshold::{foreground_threshold, multi_otsu, Histogram};
use rayon::prelude::*;

/// Half-side (working samples) of the cube opening that separates thin
/// parts: what is thinner than `2 * THIN_RADIUS + 1` samples everywhere is
/// a thin shell or rod.
pub(crate) const THIN_RADIUS: usize = 2;

/// Samples (working resolution) an object needs to be a specimen.
pub(crate) const MIN_SPECIMEN_VOXELS: usize = 1000;

/// An object at the specimens' level that is not mounting material is a
/// specimen of its own when it holds at least this share of the largest
/// one's samples, else a fragment (a broken cusp, debris): teeth scanned
/// together differ in volume by less than this factor, fragments by more.
pub(crate) const SPECIMEN_SHARE: f64 = 0.2;

/// Below the specimen's level, objects are listed from this many times
/// [`MIN_SPECIMEN_VOXELS`] up.
const LISTED_BELOW: usize = 10;

/// At most this many dropped objects are listed, the largest.
const LISTED_DROPPED: usize = 24;

/// Objects smaller than this are counted, not listed.
const REPORT_VOXELS: usize = 64;

/// Local variation (median neighbour difference over the contrast above
/// the darkest class) above which a material is textured like foam;
/// dentine under scanner noise measures 0.02–0.12, foam 0.25 and more.
pub(crate) const TEXTURED: f64 = 0.2;

/// Edge contrast (the specimen's lower quartile less the upper quartile
/// of its surroundings, over its contrast above the darkest class) under
/// which an object does not stand out: a tooth measures 0.4 and more
/// (enamel over dentine too), the brighter patches of foam's texture or of
/// noise 0.1 and less.
pub(crate) const STANDS_OUT: f64 = 0.25;

/// Robust spread over the contrast above the darkest class above which
/// the material a lower level adds around the specimen is foam: dentine,
/// even with cupping, measures under 0.1; foam 0.2 and more.
pub(crate) const UNEVEN: f64 = 0.2;

/// Share of the specimen's own contrast above the darkest class (the
/// median of its deep samples) under which a material is too light to be
/// the specimen's: mineralised tissue is dense (dentine shows 0.55 to 0.7
/// of enamel's contrast), mounting materials are not (foam, plastic, wax
/// 0.35 of dentine's and less, whatever height the mount has).
pub(crate) const DENSE_SHARE: f64 = 0.5;

/// Local variation of a material over that of the specimen's own material
/// above which it is porous like foam: the specimen's variation is the
/// scanner's noise on a homogeneous material, foam adds its texture to it
/// (twice and more, even when block averaging has smoothed the texture
/// below [`TEXTURED`]).
pub(crate) const POROUS: f64 = 2.0;

/// Fraction of the grown object that the samples added at a lower level
/// must hold more than [`THIN_RADIUS`] deep for the level to add a
/// material rather than the blur at the specimen's edge.
const MATERIAL_FRACTION: f64 = 0.05;

/// Why an object found in a volume was not taken as the specimen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DropReason {
    /// Mounting material or background: below the specimen's level,
    /// spanning the field of view, textured like foam, or much lighter
    /// than the specimen's material.
    BackgroundClass,
    /// Thinner than `2 * THIN_RADIUS + 1` samples everywhere: a tube or
    /// straw wall, a pin.
    ThinShell,
    /// Fewer than [`MIN_SPECIMEN_VOXELS`] samples.
    TooSmall,
    /// A large object, but another one is larger (reports written before
    /// batch scans were identified specimen by specimen).
    NotDensestLarge,
    /// Not mounting material, but under [`SPECIMEN_SHARE`] of the largest
    /// specimen: a fragment or debris, reported and not identified.
    Fragment,
}

/// One object found in a volume, kept or dropped.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SegmentObject {
    /// Whether it is the specimen.
    pub kept: bool,
    /// Why it was dropped (`None` when kept).
    pub reason: Option<DropReason>,
    /// What was seen, in words.
    pub detail: String,
    /// The threshold it was found above (grey values of the file).
    pub level: f64,
    /// Its mean grey value.
    pub mean: f64,
    /// Its samples at the working resolution.
    pub voxels: usize,
    /// First and last voxel along x, y, z, inclusive (working samples
    /// here; the volume report gives them in the input's voxels).
    pub bbox: [[usize; 3]; 2],
}

/// The specimens found in a working grid (one, or several in a batch
/// scan).
#[derive(Debug, Clone)]
pub struct Specimen {
    /// Each specimen's samples, cavities filled, in order along the grid's
    /// longest axis (the order of the kept objects in the report).
    pub masks: Vec<Vec<bool>>,
    /// The threshold it was cut at.
    pub level: f64,
    /// What was kept, dropped and filled.
    pub report: SegmentReport,
}

/// Why no specimen was found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpecimenError {
    /// Every sample has the same value.
    #[error("the volume is uniform (all background): no specimen to segment")]
    Uniform,
    /// Nothing is large and dense and not mounting material (the text says
    /// what was found instead).
    #[error("no specimen found: {0}")]
    NotFound(String),
}

/// The objects above one level.
struct Level {
    level: f64,
    mask: Vec<bool>,
    opened: Vec<bool>,
    labels: Vec<u32>,
    stats: Vec<ObjectStats>,
    /// For each object, the axis along which it spans the field of view
    /// together with everything touching it before the opening (foam
    /// through the tube wall it fills).
    joined_span: Vec<Option<usize>>,
}

fn level_view(values: &[f32], dims: [usize; 3], level: f64) -> Level {
    let mask: Vec<bool> = values.iter().map(|&v| f64::from(v) > level).collect();
    // The objects of the opened mask and those of the mask as it is are
    // independent: found side by side (the volume's other steps leave a
    // core idle).
    let ((opened, labels, sizes, stats), (raw_labels, raw_span)) = rayon::join(
        || {
            let opened = open_cube(&mask, dims, THIN_RADIUS);
            let (labels, sizes) = connected_components(&opened, dims);
            let stats = object_stats(&labels, sizes.len(), values, dims);
            (opened, labels, sizes, stats)
        },
        || {
            let (raw_labels, raw_sizes) = connected_components(&mask, dims);
            let raw_span: Vec<Option<usize>> =
                object_stats(&raw_labels, raw_sizes.len(), values, dims)
                    .iter()
                    .map(|s| s.spanned_axis(dims))
                    .collect();
            (raw_labels, raw_span)
        },
    );
    let mut joined_span = vec![None; sizes.len()];
    let mut seen = vec![false; sizes.len()];
    for (i, &l) in labels.iter().enumerate() {
        if l != u32::MAX && !seen[l as usize] {
            seen[l as usize] = true;
            joined_span[l as usize] = raw_span[raw_labels[i] as usize];
        }
    }
    Level {
        level,
        mask,
        opened,
        labels,
        stats,
        joined_span,
    }
}

impl Level {
    /// The axis along which object `l` spans the field of view, alone or
    /// with what touches it.
    fn spans(&self, l: u32, dims: [usize; 3]) -> Option<(usize, bool)> {
        let s = &self.stats[l as usize];
        s.spanned_axis(dims)
            .map(|a| (a, false))
            .or(self.joined_span[l as usize].map(|a| (a, true)))
    }
}

fn span_detail((axis, joined): (usize, bool)) -> String {
    if joined {
        format!(
            "spans the field of view along {} with the thin parts touching it",
            AXES[axis]
        )
    } else {
        format!("spans the field of view along {}", AXES[axis])
    }
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// Why object `l` of `view` cannot be the specimen, if it cannot.
fn mount_like(
    values: &[f32],
    dims: [usize; 3],
    region: &[bool],
    view: &Level,
    l: u32,
    background: f64,
) -> Option<String> {
    if let Some(span) = view.spans(l, dims) {
        return Some(span_detail(span));
    }
    if let (Some(inner), Some(outer)) = inner_and_ring(values, dims, region) {
        let edge = (inner - outer) / (inner - background).max(f64::MIN_POSITIVE);
        if edge < STANDS_OUT {
            return Some(format!(
                "does not stand out from what surrounds it (edge contrast {edge:.2} of its \
                 contrast, under {STANDS_OUT}): texture of foam or noise"
            ));
        }
    }
    textured(values, dims, region, background).map(|v| {
        format!("textured like foam (local variation {v:.2} of its contrast, over {TEXTURED})")
    })
}

/// The local variation of `region`'s deep samples over their contrast
/// above `background`, when it exceeds [`TEXTURED`].
fn textured(values: &[f32], dims: [usize; 3], region: &[bool], background: f64) -> Option<f64> {
    let deep = erode_cube(region, dims, THIN_RADIUS);
    let (variation, mean) = local_variation(values, &deep, dims)?;
    let contrast = mean - background;
    let ratio = if contrast > 0.0 {
        variation / contrast
    } else {
        f64::INFINITY
    };
    (ratio > TEXTURED).then_some(ratio)
}

/// The robust spread (interquartile range / 1.349) of `region`'s deep
/// samples over their contrast above `background`, when it exceeds
/// [`UNEVEN`]: a material added around the specimen that varies this much
/// is foam, not dentine.
fn uneven(values: &[f32], dims: [usize; 3], region: &[bool], background: f64) -> Option<f64> {
    let deep: Vec<f32> = erode_cube(region, dims, THIN_RADIUS)
        .iter()
        .zip(values)
        .filter_map(|(&b, &v)| b.then_some(v))
        .collect();
    if deep.len() < 16 {
        return None;
    }
    let mean = deep.iter().map(|&v| f64::from(v)).sum::<f64>() / deep.len() as f64;
    let q1 = quantile(deep.clone(), 0.25)?;
    let q3 = quantile(deep, 0.75)?;
    let contrast = mean - background;
    let ratio = if contrast > 0.0 {
        (q3 - q1) / 1.349 / contrast
    } else {
        f64::INFINITY
    };
    (ratio > UNEVEN).then_some(ratio)
}

/// The lower quartile of `region`'s deep samples and the upper quartile
/// of the ring 2 to 4 samples outside it: the specimen's material and what
/// surrounds it, each away from the blur at the edge.
fn inner_and_ring(values: &[f32], dims: [usize; 3], region: &[bool]) -> (Option<f64>, Option<f64>) {
    let inner: Vec<f32> = erode_cube(region, dims, THIN_RADIUS)
        .iter()
        .zip(values)
        .filter_map(|(&b, &v)| b.then_some(v))
        .collect();
    let near = dilate_cube(region, dims, 1);
    let ring: Vec<f32> = dilate_cube(region, dims, 4)
        .iter()
        .zip(&near)
        .zip(values)
        .filter_map(|((&far, &n), &v)| (far && !n).then_some(v))
        .collect();
    (quantile(inner, 0.25), quantile(ring, 0.75))
}

fn select(labels: &[u32], label: u32) -> Vec<bool> {
    labels.iter().map(|&l| l == label).collect()
}

fn bbox(s: &ObjectStats) -> [[usize; 3]; 2] {
    [s.min, s.max]
}

/// The candidate levels, highest first, at least 1 % of the value range
/// apart, and the mean of the darkest class.
fn candidate_levels(values: &[f32]) -> Option<(Vec<f64>, f64)> {
    const BINS: usize = 512;
    let hist = Histogram::of(values, BINS);
    if hist.is_flat() {
        return None;
    }
    let mut levels: Vec<f64> = (3..=5)
        .flat_map(|k| multi_otsu(&hist, k))
        .map(|b| hist.edge(b))
        .collect();
    levels.extend(foreground_threshold(values));
    let cuts = multi_otsu(&hist, 4);
    let background = hist.mean(0..cuts[0] + 1)?;
    let (lo, hi) = values
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    let range = f64::from(hi) - f64::from(lo);
    levels.sort_by(|a, b| b.total_cmp(a));
    let mut out: Vec<f64> = Vec::new();
    for t in levels {
        if out.last().is_none_or(|&p| p - t > 0.01 * range) {
            out.push(t);
        }
    }
    Some((out, background))
}

/// The specimen in `values` on a grid of `dims` (see the module
/// documentation), or why there is none.
pub(crate) fn find_specimen(values: &[f32], dims: [usize; 3]) -> Result<Specimen, SpecimenError> {
    let (levels, background) = candidate_levels(values).ok_or(SpecimenError::Uniform)?;
    let mut views: Vec<Option<Level>> = (0..levels.len()).map(|_| None).collect();
    let (seed_j, seed_region) = seed_object(values, dims, &levels, background, &mut views)?;
    let probe = seed_region.iter().position(|&b| b).unwrap_or(0);
    let growth = grow_down_levels(
        values,
        dims,
        &levels,
        background,
        (seed_j, seed_region),
        probe,
        &mut views,
    );
    let level = final_level(values, dims, &levels, &growth);
    let view = level_view(values, dims, level);
    let spec_label = view.labels[probe];
    if spec_label == u32::MAX {
        // Cannot happen (the opened masks are nested); said plainly if it does.
        return Err(SpecimenError::NotFound(
            "the specimen vanished at its own level".into(),
        ));
    }
    let mut report = SegmentReport {
        levels: levels.clone(),
        ..Default::default()
    };
    let (kept_labels, mount) = classify_objects(values, dims, &view, spec_label, background);
    let cores = cut_at_necks(&view, &kept_labels, dims, &mut report.warnings);
    let (mut specimens, claimed) = grow_back_cores(&cores, &view, dims);
    drop(cores);
    // Boxes before the thin parts are given back: they decide both which
    // thin parts stay within reach and the specimens' order.
    let boxes: Vec<Option<[[usize; 3]; 2]>> = specimens.iter().map(|s| bbox_of(s, dims)).collect();
    let thin = give_back_thin_parts(values, dims, &view, &mut specimens, &claimed, &boxes);
    let specimens = in_order_along_longest_axis(specimens, &boxes, dims);
    report_kept(&mut report, values, dims, &specimens, level);
    let kept_count = specimens.len();
    report_dropped_at_level(&mut report, &view, &kept_labels, mount, level);
    report_thin_parts(&mut report, &thin, dims, level);
    let around = around_specimens(&specimens, dims, values.len());
    for (i, container) in levels_below(&levels, level, growth.stop) {
        let v = views[i]
            .take()
            .unwrap_or_else(|| level_view(values, dims, levels[i]));
        report_below(&mut report, values, dims, &v, &around, probe, container);
    }
    list_largest_dropped(&mut report, kept_count);
    let masks = fill_specimen_cavities(specimens, dims, &mut report);
    Ok(Specimen {
        masks,
        level,
        report,
    })
}

/// The seed, from the highest level down: the first large object, largest
/// first, that is not mounting material; its level's index and samples.
/// When there is none, the error says what was found instead.
fn seed_object(
    values: &[f32],
    dims: [usize; 3],
    levels: &[f64],
    background: f64,
    views: &mut [Option<Level>],
) -> Result<(usize, Vec<bool>), SpecimenError> {
    let mut rejected: Vec<(f64, usize, String)> = Vec::new();
    for (j, &t) in levels.iter().enumerate() {
        let v = level_view(values, dims, t);
        let mut order: Vec<usize> = (0..v.stats.len())
            .filter(|&l| v.stats[l].voxels >= MIN_SPECIMEN_VOXELS)
            .collect();
        order.sort_by_key(|&l| std::cmp::Reverse(v.stats[l].voxels));
        let mut seed = None;
        for l in order {
            let region = select(&v.labels, l as u32);
            match mount_like(values, dims, &region, &v, l as u32, background) {
                None => {
                    seed = Some(region);
                    break;
                }
                Some(why) => rejected.push((t, v.stats[l].voxels, why)),
            }
        }
        keep_if_lowest(views, j, v);
        if let Some(region) = seed {
            return Ok((j, region));
        }
    }
    Err(SpecimenError::NotFound(not_found_reason(
        values, dims, levels, &rejected,
    )))
}

/// Where going down the levels stopped short of the lowest: the level's
/// index, the object there that holds the specimen, and why it is
/// mounting material or background.
struct Stop {
    index: usize,
    label: u32,
    why: String,
}

/// What going down the levels from the seed found.
struct Growth {
    /// The index of the lowest level whose object was the specimen's own
    /// material.
    accepted_j: usize,
    /// That object's samples.
    accepted: Vec<bool>,
    /// The index of the lowest level that kept the specimen alone (it may
    /// add only the blur at its edge).
    lowest_ok: usize,
    /// Where and why the search stopped, if at a level that took in
    /// mounting material or background.
    stop: Option<Stop>,
}

/// Down the levels from the seed while the object holding sample `probe`
/// grows by its own material (see the module documentation).
fn grow_down_levels(
    values: &[f32],
    dims: [usize; 3],
    levels: &[f64],
    background: f64,
    (seed_j, seed_region): (usize, Vec<bool>),
    probe: usize,
    views: &mut [Option<Level>],
) -> Growth {
    let mut growth = Growth {
        accepted_j: seed_j,
        accepted: seed_region,
        lowest_ok: seed_j,
        stop: None,
    };
    for (i, &t) in levels.iter().enumerate().skip(seed_j + 1) {
        let v = level_view(values, dims, t);
        let l = v.labels[probe];
        if l == u32::MAX {
            keep_if_lowest(views, i, v);
            break;
        }
        let st = &v.stats[l as usize];
        if let Some(span) = v.spans(l, dims) {
            growth.stop = Some(Stop {
                index: i,
                label: l,
                why: format!("{}: mounting material or background", span_detail(span)),
            });
            views[i] = Some(v);
            break;
        }
        let grown = select(&v.labels, l);
        let added = added_samples(&grown, &growth.accepted, values, levels[growth.accepted_j]);
        if !adds_material(&added, dims, st.voxels) {
            // Only the blur at the edge: an admissible level, not a material.
            growth.lowest_ok = i;
            keep_if_lowest(views, i, v);
            continue;
        }
        let own = material_of(values, dims, &growth.accepted);
        if let Some(why) = mounting_material(values, dims, &added, own.as_ref(), background) {
            growth.stop = Some(Stop {
                index: i,
                label: l,
                why: format!("what lies around the specimen is mounting material ({why})"),
            });
            views[i] = Some(v);
            break;
        }
        growth.accepted_j = i;
        growth.accepted = grown;
        growth.lowest_ok = i;
        keep_if_lowest(views, i, v);
    }
    growth
}

/// What a lower level's object `grown` adds to the `accepted` one: its
/// samples no higher than the accepted level `below` (brighter ones are
/// the specimen's own, cut off by the opening before).
fn added_samples(grown: &[bool], accepted: &[bool], values: &[f32], below: f64) -> Vec<bool> {
    grown
        .iter()
        .zip(accepted)
        .zip(values)
        .map(|((&g, &a), &x)| g && !a && f64::from(x) <= below)
        .collect()
}

/// Whether the `added` samples hold a material rather than the blur at the
/// edge of an object of `voxels` samples: more than
/// [`MATERIAL_FRACTION`] of it lies more than [`THIN_RADIUS`] deep.
fn adds_material(added: &[bool], dims: [usize; 3], voxels: usize) -> bool {
    let deep = erode_cube(added, dims, THIN_RADIUS)
        .iter()
        .filter(|&&b| b)
        .count();
    (deep as f64) >= MATERIAL_FRACTION * voxels as f64
}

/// The typical grey and sample-to-sample variation of a material: the
/// median of `region`'s deep samples (more than [`THIN_RADIUS`] inside,
/// away from the blur at its edge) and their local variation.
struct Material {
    median: f64,
    variation: Option<f64>,
}

/// The material of `region` (see [`Material`]); `None` when nothing of it
/// lies deep inside.
fn material_of(values: &[f32], dims: [usize; 3], region: &[bool]) -> Option<Material> {
    let deep = erode_cube(region, dims, THIN_RADIUS);
    let samples: Vec<f32> = deep
        .iter()
        .zip(values)
        .filter_map(|(&b, &v)| b.then_some(v))
        .collect();
    Some(Material {
        median: quantile(samples, 0.5)?,
        variation: local_variation(values, &deep, dims).map(|(v, _)| v),
    })
}

/// The contrast of `material` above `background` as a share of the
/// specimen's (`own`), when it is under [`DENSE_SHARE`]: too light to be
/// the specimen's own material.
fn too_light(material: &Material, own: &Material, background: f64) -> Option<f64> {
    let share = (material.median - background) / (own.median - background).max(f64::MIN_POSITIVE);
    (share < DENSE_SHARE).then_some(share)
}

/// The local variation of `material` over the specimen's (`own`), when
/// it exceeds [`POROUS`]: porous like foam, where the specimen's material
/// shows only the scanner's noise.
fn porous(material: &Material, own: &Material) -> Option<f64> {
    let ratio = material.variation? / own.variation?.max(f64::MIN_POSITIVE);
    (ratio > POROUS).then_some(ratio)
}

/// Why the material of `region` is mounting material rather than the
/// specimen's (whose material is `own`), if it is: much lighter than the
/// specimen's, porous next to it, or textured or uneven for its own
/// contrast.
fn mounting_material(
    values: &[f32],
    dims: [usize; 3],
    region: &[bool],
    own: Option<&Material>,
    background: f64,
) -> Option<String> {
    let compared = own.zip(material_of(values, dims, region));
    compared
        .as_ref()
        .and_then(|(own, m)| too_light(m, own, background))
        .map(|r| {
            format!(
                "lighter than the specimen's material: {r:.2} of its contrast, under {DENSE_SHARE}"
            )
        })
        .or_else(|| {
            compared
                .as_ref()
                .and_then(|(own, m)| porous(m, own))
                .map(|r| {
                    format!(
                    "porous: local variation {r:.2} times the specimen's material's, over {POROUS}"
                )
                })
        })
        .or_else(|| {
            textured(values, dims, region, background).map(|r| {
                format!("textured: local variation {r:.2} of its contrast, over {TEXTURED}")
            })
        })
        .or_else(|| {
            uneven(values, dims, region, background)
                .map(|r| format!("uneven: spread {r:.2} of its contrast, over {UNEVEN}"))
        })
}

/// The level the specimen is cut at: between its material and what
/// surrounds it, within the levels that kept it alone.
fn final_level(values: &[f32], dims: [usize; 3], levels: &[f64], growth: &Growth) -> f64 {
    let (top, bottom) = (levels[growth.accepted_j], levels[growth.lowest_ok]);
    match inner_and_ring(values, dims, &growth.accepted) {
        (Some(a), Some(b)) => (0.5 * (a + b)).clamp(bottom, top),
        _ => top,
    }
}

/// The specimens at the final level: the seed's object `spec_label` and
/// every other object that is large, not mounting material (nor much
/// lighter than the seed's material), and at least
/// [`SPECIMEN_SHARE`] of the largest of them (batch scans); smaller ones
/// are fragments. Also why each large object is mounting material, if it
/// is.
fn classify_objects(
    values: &[f32],
    dims: [usize; 3],
    view: &Level,
    spec_label: u32,
    background: f64,
) -> (Vec<u32>, Vec<Option<String>>) {
    let mut candidates: Vec<u32> = vec![spec_label];
    let mut mount: Vec<Option<String>> = vec![None; view.stats.len()];
    let own = material_of(values, dims, &select(&view.labels, spec_label));
    // Each object judged on its own (side by side), then taken in order.
    let judged: Vec<(usize, Option<String>)> = view
        .stats
        .par_iter()
        .enumerate()
        .filter(|&(l, s)| l as u32 != spec_label && s.voxels >= MIN_SPECIMEN_VOXELS)
        .map(|(l, _)| {
            let region = select(&view.labels, l as u32);
            // Another specimen is of the same dense material; a lump of
            // mounting material that reaches this level is much lighter.
            let why = mount_like(values, dims, &region, view, l as u32, background).or_else(|| {
                let m = material_of(values, dims, &region)?;
                too_light(&m, own.as_ref()?, background).map(|r| {
                    format!(
                        "lighter than the specimen's material ({r:.2} of its contrast, under \
                         {DENSE_SHARE}): mounting material"
                    )
                })
            });
            (l, why)
        })
        .collect();
    for (l, why) in judged {
        if why.is_none() {
            candidates.push(l as u32);
        }
        if let Some(m) = mount.get_mut(l) {
            *m = why;
        }
    }
    let largest = candidates
        .iter()
        .map(|&l| view.stats[l as usize].voxels)
        .max()
        .unwrap_or(0);
    let share = |l: u32| view.stats[l as usize].voxels as f64 >= SPECIMEN_SHARE * largest as f64;
    let kept_labels: Vec<u32> = candidates.iter().copied().filter(|&l| share(l)).collect();
    (kept_labels, mount)
}

/// Each kept object's samples, cut at its thin necks (touching
/// specimens), with a warning for each cut or possibly fused object.
fn cut_at_necks(
    view: &Level,
    kept_labels: &[u32],
    dims: [usize; 3],
    warnings: &mut Vec<String>,
) -> Vec<Vec<bool>> {
    let mut cores: Vec<Vec<bool>> = Vec::new();
    // Each object's necks looked for on their own (side by side), then
    // taken in order.
    let separated: Vec<(u32, Vec<bool>, Separation)> = kept_labels
        .par_iter()
        .map(|&l| {
            let core = select(&view.labels, l);
            let separation = separate_at_necks(&core, dims);
            (l, core, separation)
        })
        .collect();
    for (l, core, separation) in separated {
        match separation {
            Separation::Cut { parts, radius } => {
                warnings.push(format!(
                    "an object of {} samples was cut at a neck {} samples wide into {} \
                     specimens",
                    view.stats[l as usize].voxels,
                    2 * radius + 1,
                    parts.len()
                ));
                cores.extend(parts);
            }
            Separation::Fused { radius } => {
                warnings.push(format!(
                    "an object of {} samples may be two specimens fused over a junction \
                     about {} samples wide (no thin neck to cut it at): identified as one",
                    view.stats[l as usize].voxels,
                    2 * radius + 1
                ));
                cores.push(core);
            }
            Separation::Whole => cores.push(core),
        }
    }
    cores
}

/// Each specimen: its core grown back over the opening's reach within the
/// level's mask, a sample two share going to the first (the parts of a cut
/// object do not take each other's samples); and all the samples claimed.
fn grow_back_cores(
    cores: &[Vec<bool>],
    view: &Level,
    dims: [usize; 3],
) -> (Vec<Vec<bool>>, Vec<bool>) {
    let mut specimens: Vec<Vec<bool>> = cores
        .iter()
        .map(|core| {
            dilate_cube(core, dims, THIN_RADIUS)
                .iter()
                .zip(&view.mask)
                .zip(core)
                .map(|((&d, &m), &c)| c || (d && m))
                .collect()
        })
        .collect();
    let mut claimed = vec![false; view.mask.len()];
    for s in &specimens {
        for (c, &b) in claimed.iter_mut().zip(s) {
            *c |= b;
        }
    }
    // Cores never overlap, so the first holder keeps its own samples.
    let mut seen = vec![false; view.mask.len()];
    for s in &mut specimens {
        for (b, v) in s.iter_mut().zip(seen.iter_mut()) {
            if *b && *v {
                *b = false;
            }
            *v |= *b;
        }
    }
    (specimens, claimed)
}

/// The thin parts at the final level: what the opening cut off and its
/// dilation does not give back, with the specimen each is given back to.
struct ThinParts {
    stats: Vec<ObjectStats>,
    joins: Vec<Option<usize>>,
}

/// The thin parts at the final level (see [`ThinParts`]), each that lies
/// on a specimen and stays within its reach (a cusp tip, a root apex, an
/// enamel edge) added to that specimen; one that leads away from it (a
/// pin, a tube wall it touches) is not. `boxes` are the specimens' boxes.
fn give_back_thin_parts(
    values: &[f32],
    dims: [usize; 3],
    view: &Level,
    specimens: &mut [Vec<bool>],
    claimed: &[bool],
    boxes: &[Option<[[usize; 3]; 2]>],
) -> ThinParts {
    let thick_back = dilate_cube(&view.opened, dims, THIN_RADIUS);
    let residue: Vec<bool> = view
        .mask
        .iter()
        .zip(&thick_back)
        .map(|(&m, &t)| m && !t)
        .collect();
    let (res_labels, res_sizes) = connected_components(&residue, dims);
    let stats = object_stats(&res_labels, res_sizes.len(), values, dims);
    // Which specimen each thin part touches first.
    let mut touches: Vec<Option<usize>> = vec![None; res_sizes.len()];
    for (i, &l) in res_labels.iter().enumerate() {
        if l == u32::MAX || touches[l as usize].is_some() || !neighbours_any(i, dims, claimed) {
            continue;
        }
        touches[l as usize] = specimens.iter().position(|s| neighbours_any(i, dims, s));
    }
    let reach = 4 * THIN_RADIUS + 1;
    let joins: Vec<Option<usize>> = stats
        .iter()
        .zip(&touches)
        .map(|(s, &t)| {
            let k = t?;
            let b = boxes[k]?;
            (0..3)
                .all(|a| s.min[a] + reach >= b[0][a] && s.max[a] <= b[1][a] + reach)
                .then_some(k)
        })
        .collect();
    for (i, &l) in res_labels.iter().enumerate() {
        if l != u32::MAX {
            if let Some(k) = joins[l as usize] {
                specimens[k][i] = true;
            }
        }
    }
    ThinParts { stats, joins }
}

/// The specimens in order along the volume's longest axis (physical extent
/// is the caller's: here the grid's longest), by the centre of each of
/// `boxes`.
fn in_order_along_longest_axis(
    specimens: Vec<Vec<bool>>,
    boxes: &[Option<[[usize; 3]; 2]>],
    dims: [usize; 3],
) -> Vec<Vec<bool>> {
    let axis = (0..3)
        .max_by_key(|&a| (dims[a], usize::MAX - a))
        .unwrap_or(0);
    let mut order: Vec<usize> = (0..specimens.len()).collect();
    let centre = |k: usize| boxes[k].map_or(0, |b| b[0][axis] + b[1][axis]);
    order.sort_by_key(|&k| (centre(k), k));
    let mut slots: Vec<Option<Vec<bool>>> = specimens.into_iter().map(Some).collect();
    order.iter().filter_map(|&k| slots[k].take()).collect()
}

/// The kept specimens, listed first in `report`.
fn report_kept(
    report: &mut SegmentReport,
    values: &[f32],
    dims: [usize; 3],
    specimens: &[Vec<bool>],
    level: f64,
) {
    for s in specimens {
        let voxels = s.iter().filter(|&&b| b).count();
        report.objects.push(SegmentObject {
            kept: true,
            reason: None,
            detail: if specimens.len() == 1 {
                "the densest large object".into()
            } else {
                "one of the specimens: dense, large, not mounting material".into()
            },
            level,
            mean: mean_of(values, s),
            voxels,
            bbox: bbox_of(s, dims).unwrap_or([[0; 3]; 2]),
        });
        report.kept_voxels += voxels;
    }
}

/// The other objects at the specimens' level, dropped: too small, mounting
/// material (`mount` says why), or fragments.
fn report_dropped_at_level(
    report: &mut SegmentReport,
    view: &Level,
    kept_labels: &[u32],
    mut mount: Vec<Option<String>>,
    level: f64,
) {
    for (l, s) in view.stats.iter().enumerate() {
        if kept_labels.contains(&(l as u32)) {
            continue;
        }
        report.dropped_components += 1;
        report.dropped_voxels += s.voxels;
        let (reason, detail) = if s.voxels < MIN_SPECIMEN_VOXELS {
            (
                DropReason::TooSmall,
                format!("under {MIN_SPECIMEN_VOXELS} samples"),
            )
        } else {
            match mount[l].take() {
                Some(why) => (DropReason::BackgroundClass, why),
                None => (
                    DropReason::Fragment,
                    format!(
                        "under {:.0} % of the largest specimen: a fragment or debris",
                        SPECIMEN_SHARE * 100.0
                    ),
                ),
            }
        };
        push_object(report, reason, detail, level, s);
    }
}

/// The thin parts not given back to a specimen, dropped as thin shells.
fn report_thin_parts(report: &mut SegmentReport, thin: &ThinParts, dims: [usize; 3], level: f64) {
    for (s, join) in thin.stats.iter().zip(&thin.joins) {
        if join.is_some() {
            continue;
        }
        report.dropped_components += 1;
        report.dropped_voxels += s.voxels;
        push_object(
            report,
            DropReason::ThinShell,
            thin_detail(s, dims),
            level,
            s,
        );
    }
}

/// The specimens' samples and those within the blur at their edge: what
/// the levels below leave out of their objects.
fn around_specimens(specimens: &[Vec<bool>], dims: [usize; 3], len: usize) -> Vec<bool> {
    let specimen: Vec<bool> = specimens.iter().fold(vec![false; len], |mut acc, s| {
        for (a, &b) in acc.iter_mut().zip(s) {
            *a |= b;
        }
        acc
    });
    dilate_cube(&specimen, dims, THIN_RADIUS + 1)
}

/// The levels below the specimens' whose objects are reported, by index:
/// the one that stopped the search, with the object there holding the
/// specimen and why, then the lowest (the foam as a whole, the tube) when
/// it is another and lies below `level`.
fn levels_below(
    levels: &[f64],
    level: f64,
    stop: Option<Stop>,
) -> Vec<(usize, Option<(u32, String)>)> {
    let last = levels.len() - 1;
    let mut below = Vec::new();
    let stopped_at_last = stop.as_ref().is_some_and(|s| s.index == last);
    if let Some(Stop { index, label, why }) = stop {
        below.push((index, Some((label, why))));
    }
    if !stopped_at_last && level > levels[last] {
        below.push((last, None));
    }
    below
}

/// The largest dropped objects listed (those after the first `kept_count`
/// kept ones), the rest counted: foam bright enough to reach the
/// specimen's level would crowd the list.
fn list_largest_dropped(report: &mut SegmentReport, kept_count: usize) {
    let mut dropped = report.objects.split_off(kept_count);
    dropped.sort_by_key(|o| std::cmp::Reverse(o.voxels));
    for o in dropped.split_off(dropped.len().min(LISTED_DROPPED)) {
        report.small_objects += 1;
        report.small_voxels += o.voxels;
    }
    report.objects.extend(dropped);
}

/// Each specimen's mask with its internal cavities filled, counted in
/// `report`.
fn fill_specimen_cavities(
    specimens: Vec<Vec<bool>>,
    dims: [usize; 3],
    report: &mut SegmentReport,
) -> Vec<Vec<bool>> {
    // Each specimen's cavities on their own (a batch's side by side).
    let per_specimen: Vec<(Vec<bool>, usize, usize)> = specimens
        .into_par_iter()
        .map(|s| fill_cavities(s, dims))
        .collect();
    per_specimen
        .into_iter()
        .map(|(mask, cavities, voxels)| {
            report.filled_cavities += cavities;
            report.filled_voxels += voxels;
            mask
        })
        .collect()
}

/// The objects of `v` (a level below the specimen's) outside `around`
/// (the specimen and its edge): `container` is the one holding the
/// specimen (else the one holding sample `probe`) and why it was not taken
/// with it.
fn report_below(
    report: &mut SegmentReport,
    values: &[f32],
    dims: [usize; 3],
    v: &Level,
    around: &[bool],
    probe: usize,
    container: Option<(u32, String)>,
) {
    let below = "below the specimen's level: mounting material or background";
    let holder = container
        .as_ref()
        .map(|c| c.0)
        .or((v.labels[probe] != u32::MAX).then_some(v.labels[probe]));
    // Below the specimen's level only what is large counts: the foam as a
    // whole, the tube; its crumbs would only crowd the list.
    let large = LISTED_BELOW * MIN_SPECIMEN_VOXELS;
    for (k, s) in v.stats.iter().enumerate() {
        if Some(k as u32) != holder && s.voxels < large {
            continue;
        }
        if Some(k as u32) == holder {
            let rest: Vec<bool> = v
                .labels
                .iter()
                .zip(around)
                .map(|(&x, &a)| x == k as u32 && !a)
                .collect();
            if let Some(s) = stats_of(values, &rest, dims).filter(|s| s.voxels >= large) {
                let why = match &container {
                    Some((_, why)) => why.clone(),
                    None => match v.spans(k as u32, dims) {
                        Some(span) => format!("{below}; {}", span_detail(span)),
                        None => below.into(),
                    },
                };
                push_object(report, DropReason::BackgroundClass, why, v.level, &s);
            }
        } else {
            let why = match v.spans(k as u32, dims) {
                Some(span) => format!("{below}; {}", span_detail(span)),
                None => below.into(),
            };
            push_object(report, DropReason::BackgroundClass, why, v.level, s);
        }
    }
    let back = dilate_cube(&v.opened, dims, THIN_RADIUS);
    let thin: Vec<bool> = v
        .mask
        .iter()
        .zip(&back)
        .zip(around)
        .map(|((&m, &b), &a)| m && !b && !a)
        .collect();
    let (tl, ts) = connected_components(&thin, dims);
    for s in object_stats(&tl, ts.len(), values, dims) {
        if s.voxels >= large {
            push_object(
                report,
                DropReason::ThinShell,
                thin_detail(&s, dims),
                v.level,
                &s,
            );
        }
    }
}

/// Keep the objects of level `i` only if it is the lowest (the report
/// looks at it again); the others would hold memory for nothing.
fn keep_if_lowest(views: &mut [Option<Level>], i: usize, v: Level) {
    if i + 1 == views.len() {
        views[i] = Some(v);
    }
}

fn push_object(
    report: &mut SegmentReport,
    reason: DropReason,
    detail: String,
    level: f64,
    s: &ObjectStats,
) {
    if s.voxels < REPORT_VOXELS {
        report.small_objects += 1;
        report.small_voxels += s.voxels;
        return;
    }
    let reason = if s.voxels < MIN_SPECIMEN_VOXELS {
        DropReason::TooSmall
    } else {
        reason
    };
    report.objects.push(SegmentObject {
        kept: false,
        reason: Some(reason),
        detail,
        level,
        mean: s.mean,
        voxels: s.voxels,
        bbox: bbox(s),
    });
}

fn thin_detail(s: &ObjectStats, dims: [usize; 3]) -> String {
    let thin = 2 * THIN_RADIUS + 1;
    match s.spanned_axis(dims) {
        Some(a) => format!(
            "thinner than {thin} samples, spanning the field of view along {}: a tube or \
             straw wall",
            AXES[a]
        ),
        None => format!("thinner than {thin} samples everywhere: a wall, straw or pin"),
    }
}

fn neighbours_any(i: usize, dims: [usize; 3], set: &[bool]) -> bool {
    let [nx, ny, nz] = dims;
    let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
    let plane = nx * ny;
    (x > 0 && set[i - 1])
        || (x + 1 < nx && set[i + 1])
        || (y > 0 && set[i - nx])
        || (y + 1 < ny && set[i + nx])
        || (z > 0 && set[i - plane])
        || (z + 1 < nz && set[i + plane])
}

fn mean_of(values: &[f32], mask: &[bool]) -> f64 {
    let (n, s) = mask
        .iter()
        .zip(values)
        .filter(|(&m, _)| m)
        .fold((0usize, 0.0f64), |(n, s), (_, &v)| {
            (n + 1, s + f64::from(v))
        });
    s / n.max(1) as f64
}

fn bbox_of(mask: &[bool], dims: [usize; 3]) -> Option<[[usize; 3]; 2]> {
    stats_of(&vec![0.0; mask.len()], mask, dims).map(|s| bbox(&s))
}

fn stats_of(values: &[f32], mask: &[bool], dims: [usize; 3]) -> Option<ObjectStats> {
    let labels: Vec<u32> = mask.iter().map(|&m| if m { 0 } else { u32::MAX }).collect();
    object_stats(&labels, 1, values, dims)
        .pop()
        .filter(|s| s.voxels > 0)
}

/// What was found instead of a specimen, for the error message.
fn not_found_reason(
    values: &[f32],
    dims: [usize; 3],
    levels: &[f64],
    rejected: &[(f64, usize, String)],
) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut seen: Vec<&str> = Vec::new();
    for (t, n, why) in rejected {
        let kind = why.split(':').next().unwrap_or(why);
        if seen.contains(&kind) || parts.len() >= 3 {
            continue;
        }
        seen.push(kind);
        parts.push(format!("above {t:.6}, an object of {n} samples that {why}"));
    }
    // Thin shells at the lowest level (a tube with nothing in it).
    if let Some(&t) = levels.last() {
        let v = level_view(values, dims, t);
        let back = dilate_cube(&v.opened, dims, THIN_RADIUS);
        let thin: Vec<bool> = v.mask.iter().zip(&back).map(|(&m, &b)| m && !b).collect();
        let (tl, ts) = connected_components(&thin, dims);
        let stats = object_stats(&tl, ts.len(), values, dims);
        if let Some(s) = stats.iter().max_by_key(|s| s.voxels) {
            if s.voxels >= MIN_SPECIMEN_VOXELS {
                parts.push(format!(
                    "above {t:.6}, a thin shell of {} samples ({})",
                    s.voxels,
                    thin_detail(s, dims)
                ));
            }
        }
    }
    if parts.is_empty() {
        format!(
            "nothing of {MIN_SPECIMEN_VOXELS} samples or more at the working resolution stands \
             out at any level (an all-background volume?)"
        )
    } else {
        format!(
            "nothing dense and large enough that is not mounting material or background: {}",
            parts.join("; ")
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// A ball of dentine with an enamel cap, in textured foam filling a
    /// thin tube along z, with noise.
    fn mounted(n: usize, tooth: bool, seed: u64) -> (Vec<f32>, [usize; 3], Vec<bool>) {
        let dims = [n, n, n];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let c = n as f64 / 2.0;
        let mut values = vec![0.05f32; n * n * n];
        let mut truth = vec![false; n * n * n];
        // Foam texture: cells 4 samples wide of random grey.
        let cells: Vec<f32> = (0..(n / 4 + 1).pow(3))
            .map(|_| rng.gen_range(0.1..0.3))
            .collect();
        let m = n / 4 + 1;
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let i = x + n * (y + n * z);
                    let r = ((x as f64 - c).powi(2) + (y as f64 - c).powi(2)).sqrt();
                    if r < 0.4 * n as f64 && z < n * 2 / 3 {
                        values[i] = cells[x / 4 + m * (y / 4 + m * (z / 4))];
                    }
                    if (0.4 * n as f64..0.4 * n as f64 + 2.0).contains(&r) {
                        values[i] = 0.3;
                    }
                    let d =
                        ((x as f64 - c).powi(2) + (y as f64 - c).powi(2) + (z as f64 - c).powi(2))
                            .sqrt();
                    if tooth && d < 0.22 * n as f64 {
                        truth[i] = true;
                        values[i] = if d > 0.15 * n as f64 && z as f64 > c {
                            0.85
                        } else {
                            0.5
                        };
                    }
                }
            }
        }
        for v in &mut values {
            *v += rng.gen_range(-0.03..0.03);
        }
        (values, dims, truth)
    }

    #[test]
    fn the_tooth_is_found_in_foam_and_a_tube_and_both_are_dropped() {
        let (values, dims, truth) = mounted(48, true, 1);
        let s = find_specimen(&values, dims).unwrap();
        assert_eq!(s.masks.len(), 1);
        let wrong = s.masks[0]
            .iter()
            .zip(&truth)
            .filter(|(a, b)| a != b)
            .count();
        let size = truth.iter().filter(|&&b| b).count();
        assert!(wrong * 10 < size, "{wrong} of {size} wrong: {:?}", s.report);
        let reasons: Vec<_> = s.report.objects.iter().map(|o| o.reason).collect();
        assert_eq!(reasons[0], None);
        assert!(
            reasons.contains(&Some(DropReason::BackgroundClass)),
            "{:?}",
            s.report.objects
        );
        assert!(s.level > 0.3 && s.level < 0.5, "{}", s.level);
    }

    /// A ball of dentine with an enamel cap standing in a block of smooth
    /// foam (scanner noise only, no texture) that reaches neither end of
    /// the grid along any axis, as a short mount in a taller stack.
    fn in_a_short_foam_block(n: usize, seed: u64) -> (Vec<f32>, [usize; 3], Vec<bool>) {
        let dims = [n, n, n];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let c = n as f64 / 2.0;
        let mut values = vec![0.05f32; n * n * n];
        let mut truth = vec![false; n * n * n];
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let i = x + n * (y + n * z);
                    let r = ((x as f64 - c).powi(2) + (y as f64 - c).powi(2)).sqrt();
                    if r < 0.4 * n as f64 && (n / 8..n * 3 / 5).contains(&z) {
                        values[i] = 0.22;
                    }
                    let d = (r * r + (z as f64 - c).powi(2)).sqrt();
                    if d < 0.22 * n as f64 {
                        truth[i] = true;
                        values[i] = if d > 0.15 * n as f64 && z as f64 > c {
                            0.85
                        } else {
                            0.5
                        };
                    }
                }
            }
        }
        for v in &mut values {
            *v += rng.gen_range(-0.03..0.03);
        }
        (values, dims, truth)
    }

    #[test]
    fn a_tooth_in_foam_that_spans_nothing_is_found_without_the_foam() {
        let (values, dims, truth) = in_a_short_foam_block(48, 3);
        let s = find_specimen(&values, dims).unwrap();
        assert_eq!(s.masks.len(), 1);
        let wrong = s.masks[0]
            .iter()
            .zip(&truth)
            .filter(|(a, b)| a != b)
            .count();
        let size = truth.iter().filter(|&&b| b).count();
        assert!(wrong * 10 < size, "{wrong} of {size} wrong: {:?}", s.report);
        assert!(s.level > 0.25 && s.level < 0.5, "{}", s.level);
    }

    #[test]
    fn foam_in_a_tube_alone_is_no_specimen() {
        let (values, dims, _) = mounted(48, false, 2);
        let e = find_specimen(&values, dims).unwrap_err();
        assert!(
            matches!(&e, SpecimenError::NotFound(why) if why.contains("spans the field of view")),
            "{e}"
        );
        assert_eq!(
            find_specimen(&[1.0; 64], [4, 4, 4]).unwrap_err(),
            SpecimenError::Uniform
        );
    }
}
