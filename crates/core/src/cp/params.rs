//! Parameters of the cP engine: what [`prepare`](super::prepare) uses
//! ([`PrepareParams`]: they shape the prepared surface, so they key the
//! cache of prepared surfaces) and what the comparison uses
//! ([`CompareParams`]: changing them never prepares a surface again).
//! [`ScreenParams`] say when a library is screened by signature before
//! the cP distance is computed. The `[cp]` configuration section keeps all
//! three in one flat table.

use serde::{Deserialize, Serialize};
use std::fmt;

/// Parameters of [`prepare`](super::prepare).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PrepareParams {
    /// Number of samples spread over each surface for the map search.
    pub samples: usize,
    /// At most this many feature points per surface.
    pub max_features: usize,
    /// Smoothing steps (one-ring averaging) of the conformal density before
    /// its maxima are taken.
    pub density_smoothing: usize,
    /// Minimal distance between two features (surface of area 1).
    pub feature_separation: f64,
    /// Features lie within this radius of the disk (away from the boundary).
    pub feature_max_radius: f64,
}

impl Default for PrepareParams {
    fn default() -> Self {
        Self {
            samples: 150,
            max_features: 5,
            density_smoothing: 3,
            feature_separation: 0.1,
            feature_max_radius: 0.9,
        }
    }
}

/// Parameters of [`compare`](super::compare) and the directed comparisons.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CompareParams {
    /// The first (farthest-point) samples used to score the coarse search
    /// over feature pairs and angles; refinement uses all samples.
    pub coarse_samples: usize,
    /// Rotation angles tried for each feature pair.
    pub angles: usize,
    /// Candidates (best by sample score) that are refined; as many of the
    /// other orientation are added when these are all of one.
    pub refine_candidates: usize,
    /// Objective evaluations of the local refinement of each candidate.
    pub refine_evaluations: usize,
    /// Whether maps are followed by a smooth deformation ϱ bringing
    /// features onto their mutually nearest features.
    pub feature_warp: bool,
    /// Whether every candidate of the search is scored after its own
    /// deformation, as in the paper (otherwise only the best map is
    /// deformed, and the deformation kept when it lowers the distance).
    pub search_warp: bool,
    /// Candidates of the coarse search that bring fewer than this many
    /// features onto mutually nearest features are left out (capped by the
    /// feature counts; if no map qualifies, none is left out).
    pub min_feature_matches: usize,
    /// Width of that deformation's Gaussian kernel (disk units).
    pub warp_width: f64,
    /// Features farther apart than this (hyperbolic distance) are not
    /// matched by the deformation.
    pub warp_max_match: f64,
    /// Whether orientation-reversing maps (mirror images) are searched.
    pub reflections: bool,
    /// Whether the final map is made area preserving (Moser's flow) before
    /// it is evaluated.
    pub area_correction: bool,
    /// Steps of the final descent: Gauss–Newton steps that lower the
    /// area-corrected map's residual, each made area preserving again
    /// (needs `area_correction`; 0 turns it off).
    pub descent_steps: usize,
    /// Smoothing steps (face averaging over the source surface) of each
    /// descent step's displacement field, which keep the map regular.
    pub descent_smoothing: usize,
    /// Fraction of the Gauss–Newton step taken.
    pub descent_damping: f64,
    /// Whether `compare` descends both directed maps (otherwise only the
    /// one with the smaller distance after the search).
    pub descent_both_directions: bool,
    /// Vertices farther than this from the centre of the disk weigh less
    /// in the distance, their weight falling linearly to
    /// `boundary_taper_weight` at the rim: the band along the cut, where
    /// two crops of one tooth differ most.
    pub boundary_taper_from: f64,
    /// The weight at the rim, relative to the centre (1 turns the taper
    /// off).
    pub boundary_taper_weight: f64,
}

impl Default for CompareParams {
    fn default() -> Self {
        Self {
            coarse_samples: 40,
            angles: 12,
            refine_candidates: 2,
            refine_evaluations: 60,
            feature_warp: true,
            search_warp: true,
            min_feature_matches: 3,
            warp_width: 0.25,
            warp_max_match: 1.0,
            reflections: true,
            area_correction: true,
            descent_steps: 2,
            descent_smoothing: 10,
            descent_damping: 0.5,
            descent_both_directions: false,
            boundary_taper_from: 0.7,
            boundary_taper_weight: 0.2,
        }
    }
}

/// When identification screens the library by signature
/// ([`shape_signature`](super::shape_signature)) before the cP distance.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Screening {
    /// Screen libraries of more than [`ScreenParams::screen_from`]
    /// references; compare a smaller one with every reference.
    #[default]
    Auto,
    /// Always screen.
    On,
    /// Never screen: every reference is compared (exhaustive search).
    Off,
}

/// Parameters of the screen that picks the references a scan is compared
/// with in a large library.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ScreenParams {
    /// Whether to screen ([`Screening`]).
    pub screening: Screening,
    /// The cP distance is computed for this many references nearest by
    /// signature,
    pub screen_keep: usize,
    /// and for every other whose signature distance is within this
    /// fraction of the last one kept.
    pub screen_margin: f64,
    /// Under [`Screening::Auto`], libraries of more references than this
    /// are screened.
    pub screen_from: usize,
}

impl Default for ScreenParams {
    fn default() -> Self {
        Self {
            screening: Screening::Auto,
            screen_keep: 32,
            screen_margin: 0.1,
            screen_from: 200,
        }
    }
}

impl ScreenParams {
    /// Whether a library of `references` references is screened.
    pub fn screens(&self, references: usize) -> bool {
        match self.screening {
            Screening::On => true,
            Screening::Off => false,
            Screening::Auto => references > self.screen_from,
        }
    }

    /// Check every value; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ParamError> {
        at_least_one("screen_keep", self.screen_keep)?;
        let margin = self.screen_margin;
        check(
            "screen_margin",
            margin,
            Requirement::NonNegative,
            margin.is_finite() && margin >= 0.0,
        )
    }
}

/// How an identification cuts a crown found on a whole tooth again along
/// its nearest references' crop lines ([`cut_along_rim`](super::cut_along_rim)).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RecutParams {
    /// A crown cut from a closed surface or a volume is cut again along
    /// the crop line of each of this many nearest references and compared
    /// with it once more; 0 turns this off, and with it the library's
    /// choice among the margins the cleaning found. Crowns as files are
    /// never cut again.
    pub recut_nearest: usize,
    /// The crowns of the other margins, and the crowns cut where the
    /// nearest references' crop lines agree, are compared with this many
    /// references nearest the scan so far (and those whose lines voted);
    /// 0: with every reference the screen keeps for each crown (about 40
    /// of the 116 teeth). 16 by default: on the real teeth as whole teeth
    /// of each kind (two-rooted, smooth-necked, mounted, in batches) the
    /// same genus figures as 0, with a third fewer comparisons.
    pub recut_among: usize,
}

impl Default for RecutParams {
    fn default() -> Self {
        Self {
            recut_nearest: 5,
            recut_among: 16,
        }
    }
}

/// All parameters of the cP engine (the `[cp]` configuration section).
/// Written and read as one flat table: the split into preparation and
/// comparison parameters is not the user's concern.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(from = "FlatParams", into = "FlatParams")]
pub struct CpParams {
    /// What preparation uses.
    pub prepare: PrepareParams,
    /// What comparison uses.
    pub compare: CompareParams,
    /// When a library is screened before comparison.
    pub screen: ScreenParams,
    /// Whether a crown found on a whole tooth is cut again.
    pub recut: RecutParams,
}

/// The `[cp]` table as the user writes it; every key optional. (serde's
/// `flatten` cannot be combined with `deny_unknown_fields`, so the two
/// parts are spelled out here.)
#[derive(Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct FlatParams {
    samples: usize,
    coarse_samples: usize,
    max_features: usize,
    density_smoothing: usize,
    feature_separation: f64,
    feature_max_radius: f64,
    angles: usize,
    refine_candidates: usize,
    refine_evaluations: usize,
    feature_warp: bool,
    search_warp: bool,
    min_feature_matches: usize,
    warp_width: f64,
    warp_max_match: f64,
    reflections: bool,
    area_correction: bool,
    descent_steps: usize,
    descent_smoothing: usize,
    descent_damping: f64,
    descent_both_directions: bool,
    boundary_taper_from: f64,
    boundary_taper_weight: f64,
    screening: Screening,
    screen_keep: usize,
    screen_margin: f64,
    screen_from: usize,
    recut_nearest: usize,
    recut_among: usize,
}

impl Default for FlatParams {
    fn default() -> Self {
        CpParams::default().into()
    }
}

impl From<CpParams> for FlatParams {
    fn from(p: CpParams) -> Self {
        let PrepareParams {
            samples,
            max_features,
            density_smoothing,
            feature_separation,
            feature_max_radius,
        } = p.prepare;
        let CompareParams {
            coarse_samples,
            angles,
            refine_candidates,
            refine_evaluations,
            feature_warp,
            search_warp,
            min_feature_matches,
            warp_width,
            warp_max_match,
            reflections,
            area_correction,
            descent_steps,
            descent_smoothing,
            descent_damping,
            descent_both_directions,
            boundary_taper_from,
            boundary_taper_weight,
        } = p.compare;
        let ScreenParams {
            screening,
            screen_keep,
            screen_margin,
            screen_from,
        } = p.screen;
        let RecutParams {
            recut_nearest,
            recut_among,
        } = p.recut;
        FlatParams {
            samples,
            coarse_samples,
            max_features,
            density_smoothing,
            feature_separation,
            feature_max_radius,
            angles,
            refine_candidates,
            refine_evaluations,
            feature_warp,
            search_warp,
            min_feature_matches,
            warp_width,
            warp_max_match,
            reflections,
            area_correction,
            descent_steps,
            descent_smoothing,
            descent_damping,
            descent_both_directions,
            boundary_taper_from,
            boundary_taper_weight,
            screening,
            screen_keep,
            screen_margin,
            screen_from,
            recut_nearest,
            recut_among,
        }
    }
}

impl From<FlatParams> for CpParams {
    fn from(f: FlatParams) -> Self {
        CpParams {
            prepare: PrepareParams {
                samples: f.samples,
                max_features: f.max_features,
                density_smoothing: f.density_smoothing,
                feature_separation: f.feature_separation,
                feature_max_radius: f.feature_max_radius,
            },
            compare: CompareParams {
                coarse_samples: f.coarse_samples,
                angles: f.angles,
                refine_candidates: f.refine_candidates,
                refine_evaluations: f.refine_evaluations,
                feature_warp: f.feature_warp,
                search_warp: f.search_warp,
                min_feature_matches: f.min_feature_matches,
                warp_width: f.warp_width,
                warp_max_match: f.warp_max_match,
                reflections: f.reflections,
                area_correction: f.area_correction,
                descent_steps: f.descent_steps,
                descent_smoothing: f.descent_smoothing,
                descent_damping: f.descent_damping,
                descent_both_directions: f.descent_both_directions,
                boundary_taper_from: f.boundary_taper_from,
                boundary_taper_weight: f.boundary_taper_weight,
            },
            screen: ScreenParams {
                screening: f.screening,
                screen_keep: f.screen_keep,
                screen_margin: f.screen_margin,
                screen_from: f.screen_from,
            },
            recut: RecutParams {
                recut_nearest: f.recut_nearest,
                recut_among: f.recut_among,
            },
        }
    }
}

/// The condition a parameter's value must meet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Requirement {
    /// A whole number of at least 1.
    AtLeastOne,
    /// A finite number above 0.
    Positive,
    /// A finite number of at least 0.
    NonNegative,
    /// A number strictly between 0 and 1.
    OpenUnitInterval,
    /// A number above 0 and at most 1.
    HalfOpenUnitInterval,
    /// At most `samples` (the coarse samples are the first samples).
    AtMostSamples,
    /// A whole number from `min` to `max`.
    Between {
        /// The smallest value allowed.
        min: u32,
        /// The largest value allowed.
        max: u32,
    },
}

impl fmt::Display for Requirement {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text = match self {
            Requirement::AtLeastOne => "must be at least 1",
            Requirement::Positive => "must be a finite number > 0",
            Requirement::NonNegative => "must be a finite number >= 0",
            Requirement::OpenUnitInterval => "must be between 0 and 1 (both excluded)",
            Requirement::HalfOpenUnitInterval => "must be > 0 and <= 1",
            Requirement::AtMostSamples => "must not exceed samples",
            Requirement::Between { min, max } => {
                return write!(f, "must be from {min} to {max}");
            }
        };
        f.write_str(text)
    }
}

/// A parameter whose value cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key} = {value}: {requirement}")]
pub struct ParamError {
    /// The key, as in the configuration file.
    pub key: &'static str,
    /// The value given (whole numbers as numbers too).
    pub value: f64,
    /// What the value must be.
    pub requirement: Requirement,
}

/// `Ok` if the whole number `value` lies in `min..=max`, else the error
/// naming `key` and `value`.
pub(crate) fn check_count(
    key: &'static str,
    value: usize,
    min: u32,
    max: u32,
) -> Result<(), ParamError> {
    check(
        key,
        value as f64,
        Requirement::Between { min, max },
        (min as usize..=max as usize).contains(&value),
    )
}

/// `Ok` if `holds`, else the error naming `key` and `value`.
pub(crate) fn check(
    key: &'static str,
    value: f64,
    requirement: Requirement,
    holds: bool,
) -> Result<(), ParamError> {
    if holds {
        Ok(())
    } else {
        Err(ParamError {
            key,
            value,
            requirement,
        })
    }
}

/// Check a count against [`Requirement::AtLeastOne`].
fn at_least_one(key: &'static str, value: usize) -> Result<(), ParamError> {
    check(key, value as f64, Requirement::AtLeastOne, value >= 1)
}

impl PrepareParams {
    /// Check every value; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ParamError> {
        at_least_one("samples", self.samples)?;
        let separation = self.feature_separation;
        check(
            "feature_separation",
            separation,
            Requirement::NonNegative,
            separation.is_finite() && separation >= 0.0,
        )?;
        let radius = self.feature_max_radius;
        check(
            "feature_max_radius",
            radius,
            Requirement::OpenUnitInterval,
            radius > 0.0 && radius < 1.0,
        )
    }
}

impl CompareParams {
    /// Check every value; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ParamError> {
        at_least_one("coarse_samples", self.coarse_samples)?;
        at_least_one("angles", self.angles)?;
        at_least_one("refine_candidates", self.refine_candidates)?;
        for (key, value) in [
            ("warp_width", self.warp_width),
            ("warp_max_match", self.warp_max_match),
        ] {
            check(
                key,
                value,
                Requirement::Positive,
                value.is_finite() && value > 0.0,
            )?;
        }
        let damping = self.descent_damping;
        check(
            "descent_damping",
            damping,
            Requirement::HalfOpenUnitInterval,
            damping > 0.0 && damping <= 1.0,
        )?;
        let from = self.boundary_taper_from;
        check(
            "boundary_taper_from",
            from,
            Requirement::OpenUnitInterval,
            from > 0.0 && from < 1.0,
        )?;
        let rim = self.boundary_taper_weight;
        check(
            "boundary_taper_weight",
            rim,
            Requirement::HalfOpenUnitInterval,
            rim > 0.0 && rim <= 1.0,
        )
    }
}

impl CpParams {
    /// Check every value, and that the coarse samples are among the
    /// samples; the error names the first bad key.
    pub fn validate(&self) -> Result<(), ParamError> {
        self.prepare.validate()?;
        self.compare.validate()?;
        self.screen.validate()?;
        let coarse = self.compare.coarse_samples;
        check(
            "coarse_samples",
            coarse as f64,
            Requirement::AtMostSamples,
            coarse <= self.prepare.samples,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat_keys(json: &serde_json::Value) -> Vec<String> {
        let mut keys: Vec<String> = json
            .as_object()
            .expect("a flat table")
            .keys()
            .cloned()
            .collect();
        keys.sort();
        keys
    }

    #[test]
    fn the_section_is_one_flat_table_with_every_key() {
        let json = serde_json::to_value(CpParams::default()).unwrap();
        let mut want: Vec<String> = [
            serde_json::to_value(PrepareParams::default()).unwrap(),
            serde_json::to_value(CompareParams::default()).unwrap(),
            serde_json::to_value(ScreenParams::default()).unwrap(),
            serde_json::to_value(RecutParams::default()).unwrap(),
        ]
        .iter()
        .flat_map(flat_keys)
        .collect();
        want.sort();
        assert_eq!(flat_keys(&json), want);
        assert_eq!(want.len(), 28);
        assert!(json.as_object().unwrap().values().all(|v| !v.is_object()));
    }

    #[test]
    fn keys_are_read_into_their_part_and_the_rest_keep_defaults() {
        let p: CpParams = toml::from_str("samples = 90\ndescent_steps = 0\n").unwrap();
        assert_eq!(p.prepare.samples, 90);
        assert_eq!(p.compare.descent_steps, 0);
        assert_eq!(
            p.prepare.max_features,
            PrepareParams::default().max_features
        );
        assert_eq!(p.compare.angles, CompareParams::default().angles);
        let back: CpParams = toml::from_str(&toml::to_string(&p).unwrap()).unwrap();
        assert_eq!(back, p);
    }

    #[test]
    fn unknown_keys_are_refused_by_name() {
        let e = toml::from_str::<CpParams>("descent_stepz = 1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("descent_stepz"), "{e}");
        // The parts are not nested tables of the section.
        assert!(toml::from_str::<CpParams>("[compare]\nangles = 3\n").is_err());
    }

    #[test]
    fn the_defaults_are_valid() {
        assert_eq!(CpParams::default().validate(), Ok(()));
    }

    #[test]
    fn each_bad_value_is_named_with_its_key() {
        let bad: Vec<(&str, CpParams)> = vec![
            ("warp_width = 0: must be a finite number > 0", {
                let mut p = CpParams::default();
                p.compare.warp_width = 0.0;
                p
            }),
            ("warp_width = -0.5", {
                let mut p = CpParams::default();
                p.compare.warp_width = -0.5;
                p
            }),
            ("warp_max_match = inf", {
                let mut p = CpParams::default();
                p.compare.warp_max_match = f64::INFINITY;
                p
            }),
            ("descent_damping = NaN", {
                let mut p = CpParams::default();
                p.compare.descent_damping = f64::NAN;
                p
            }),
            ("descent_damping = 1.5", {
                let mut p = CpParams::default();
                p.compare.descent_damping = 1.5;
                p
            }),
            ("descent_damping = 0", {
                let mut p = CpParams::default();
                p.compare.descent_damping = 0.0;
                p
            }),
            ("angles = 0: must be at least 1", {
                let mut p = CpParams::default();
                p.compare.angles = 0;
                p
            }),
            ("refine_candidates = 0", {
                let mut p = CpParams::default();
                p.compare.refine_candidates = 0;
                p
            }),
            ("coarse_samples = 0", {
                let mut p = CpParams::default();
                p.compare.coarse_samples = 0;
                p
            }),
            ("coarse_samples = 40: must not exceed samples", {
                let mut p = CpParams::default();
                p.prepare.samples = 30;
                p
            }),
            ("samples = 0", {
                let mut p = CpParams::default();
                p.prepare.samples = 0;
                p
            }),
            ("feature_max_radius = 1: must be between 0 and 1", {
                let mut p = CpParams::default();
                p.prepare.feature_max_radius = 1.0;
                p
            }),
            ("feature_max_radius = 0", {
                let mut p = CpParams::default();
                p.prepare.feature_max_radius = 0.0;
                p
            }),
            ("feature_separation = NaN", {
                let mut p = CpParams::default();
                p.prepare.feature_separation = f64::NAN;
                p
            }),
            ("feature_separation = -1", {
                let mut p = CpParams::default();
                p.prepare.feature_separation = -1.0;
                p
            }),
            ("boundary_taper_from = 1: must be between 0 and 1", {
                let mut p = CpParams::default();
                p.compare.boundary_taper_from = 1.0;
                p
            }),
            ("boundary_taper_weight = 0: must be > 0 and <= 1", {
                let mut p = CpParams::default();
                p.compare.boundary_taper_weight = 0.0;
                p
            }),
            ("boundary_taper_weight = NaN", {
                let mut p = CpParams::default();
                p.compare.boundary_taper_weight = f64::NAN;
                p
            }),
        ];
        for (want, p) in bad {
            let e = p.validate().expect_err(want).to_string();
            assert!(e.starts_with(want), "{e} (want {want})");
        }
    }

    #[test]
    fn edge_values_that_make_sense_are_accepted() {
        let mut p = CpParams::default();
        p.compare.descent_damping = 1.0;
        p.compare.coarse_samples = p.prepare.samples;
        p.compare.descent_steps = 0;
        p.compare.refine_evaluations = 0;
        p.prepare.feature_separation = 0.0;
        // A rim weight of 1: no taper.
        p.compare.boundary_taper_weight = 1.0;
        assert_eq!(p.validate(), Ok(()));
    }
}
