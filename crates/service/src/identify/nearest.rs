//! Nearest-neighbour identification at each rank, and the plain data an
//! identification produces ([`ScanOutcome`]), which the store records.

use morphoid_data::pipeline::PipelineError;
use morphoid_data::table::Labels;
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::Arc;

/// Nearest taxon at one rank.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RankResult {
    /// Rank name (`genus`, …).
    pub rank: String,
    /// The nearest reference's taxon at this rank.
    pub taxon: String,
    /// Name of the nearest reference with a known taxon at this rank.
    pub reference: String,
    /// Its distance.
    pub distance: f64,
    /// The nearest other taxon at this rank, if any.
    pub runner_up: Option<String>,
    /// Distance to the runner-up minus `distance`.
    pub margin: Option<f64>,
    /// How far the answer can be trusted, when the library is calibrated
    /// (see [`Calibration`](super::Calibration)).
    pub confidence: Option<Confidence>,
}

/// The calibrated confidence of the answer at one rank.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Confidence {
    /// Probability that the nearest taxon is right, from the library's
    /// own leave-one-out.
    pub probability: f64,
    /// The novelty score ([`novelty_score`](super::novelty_score)): larger
    /// is farther from the library than its own members are.
    pub novelty: f64,
    /// The score above which a scan is "no close match" (`None`: the
    /// library has too few members of shared taxa to set one).
    pub novelty_threshold: Option<f64>,
    /// Whether the scan is farther from the library than a member of a
    /// taxon it holds would be (`None` without a threshold).
    pub no_close_match: Option<bool>,
}

/// Distance between the scan and one reference.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DistanceRow {
    /// Reference name.
    pub reference: String,
    /// d(scan, reference).
    pub forward: f64,
    /// d(reference, scan).
    pub backward: f64,
    /// The reported distance (the smaller direction).
    pub distance: f64,
    /// Whether the best map reverses orientation (mirror image).
    pub reflected: bool,
}

/// A reference and its distance, for the `nearest` list.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Nearest {
    /// Reference name.
    pub reference: String,
    /// Reported distance.
    pub distance: f64,
}

/// One landmark carried onto a scan, in the scan file's coordinates.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LandmarkPoint {
    /// The label of the reference's landmark, if it had one.
    pub label: Option<String>,
    /// x coordinate.
    pub x: f64,
    /// y coordinate.
    pub y: f64,
    /// z coordinate.
    pub z: f64,
}

/// The landmarks of a reference carried onto a scan through the cP
/// correspondence, in the order of the reference's landmark file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ScanLandmarks {
    /// The reference whose landmarks were carried over.
    pub reference: String,
    /// The landmarks on the scan.
    pub points: Vec<LandmarkPoint>,
}

/// Everything an identification produced, recorded by the store in one
/// transaction (`Store::complete`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ScanOutcome {
    /// Nearest taxon per rank, broadest rank first.
    pub ranks: Vec<RankResult>,
    /// Distances to every reference compared.
    pub distances: Vec<DistanceRow>,
    /// The cleaning report, as JSON.
    pub cleaning: serde_json::Value,
    /// Milliseconds per stage (`load`, `clean`, `flatten`, `compare`, …).
    pub timings_ms: BTreeMap<String, f64>,
    /// The nearest reference's landmarks carried onto the scan, when that
    /// reference has landmarks.
    pub landmarks: Option<ScanLandmarks>,
    /// Identified while the library's calibration was still running, so
    /// the ranks carry no confidence yet.
    pub calibrating: bool,
}

/// One specimen of a scan of several: where it lies and its
/// identification, or why it has none.
#[derive(Debug, Clone)]
pub struct SpecimenOutcome {
    /// Where it lies in the scan.
    pub position: morphoid_data::pipeline::Position,
    /// Its identification, or why it could not be made (shared: an
    /// outcome is cloned to be recorded).
    pub result: Result<ScanOutcome, Arc<PipelineError>>,
}

/// Everything the identification of a scan of several specimens produced,
/// recorded by the store in one transaction (`Store::complete_specimens`).
#[derive(Debug, Clone)]
pub struct SpecimensOutcome {
    /// The specimens, in their documented order (along the scan's longest
    /// axis).
    pub specimens: Vec<SpecimenOutcome>,
    /// What the scan's segmentation or split found (each object, what was
    /// dropped and why), as JSON.
    pub segmentation: serde_json::Value,
    /// Milliseconds per stage of the whole scan (`load`, `total`).
    pub timings_ms: BTreeMap<String, f64>,
}

/// The identification of one scan.
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    /// One result per rank known for at least one reference, broadest first.
    pub ranks: Vec<RankResult>,
    /// The nearest references, nearest first.
    pub nearest: Vec<Nearest>,
}

/// Identify a scan from its distances to the references: at each rank the
/// taxon of the nearest reference known at that rank, the runner-up taxon
/// and the margin; plus the `nearest_count` nearest references. Ties go to
/// the reference that comes first by name, so the answer never depends on
/// input order. The confidence is left to
/// [`Calibration::assess`](super::Calibration::assess).
pub fn identify(
    distances: &[DistanceRow],
    labels: &Labels,
    nearest_count: usize,
) -> Identification {
    let mut sorted: Vec<&DistanceRow> = distances
        .iter()
        .filter(|n| n.distance.is_finite())
        .collect();
    sorted.sort_by(|a, b| {
        a.distance
            .total_cmp(&b.distance)
            .then_with(|| a.reference.cmp(&b.reference))
    });
    let ranks = labels
        .ranks()
        .iter()
        .filter_map(|rank| {
            let mut known = sorted
                .iter()
                .filter_map(|n| labels.get(&n.reference, rank).map(|t| (*n, t)));
            let (best, taxon) = known.next()?;
            let runner = known.find(|(_, t)| *t != taxon);
            Some(RankResult {
                rank: rank.clone(),
                taxon: taxon.to_string(),
                reference: best.reference.clone(),
                distance: best.distance,
                runner_up: runner.map(|(_, t)| t.to_string()),
                margin: runner.map(|(n, _)| n.distance - best.distance),
                confidence: None,
            })
        })
        .collect();
    Identification {
        ranks,
        nearest: sorted
            .into_iter()
            .take(nearest_count)
            .map(|d| Nearest {
                reference: d.reference.clone(),
                distance: d.distance,
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn n(r: &str, d: f64) -> DistanceRow {
        DistanceRow {
            reference: r.into(),
            forward: d,
            backward: d,
            distance: d,
            reflected: false,
        }
    }

    fn near(r: &str, d: f64) -> Nearest {
        Nearest {
            reference: r.into(),
            distance: d,
        }
    }

    #[test]
    fn nearest_known_taxon_runner_up_and_margin_per_rank() {
        let labels = Labels::parse(
            "name,order,genus\na,P,G1\nb,P,NA\nc,P,G2\nd,Q,G3\n",
            None,
            Path::new("labels.csv"),
        )
        .unwrap();
        let d = [n("a", 0.05), n("b", 0.01), n("c", 0.04), n("d", 0.09)];
        let id = identify(&d, &labels, 2);
        assert_eq!(id.nearest, vec![near("b", 0.01), near("c", 0.04)]);
        let order = &id.ranks[0];
        assert_eq!((order.taxon.as_str(), order.reference.as_str()), ("P", "b"));
        assert_eq!(order.runner_up.as_deref(), Some("Q"));
        assert!((order.margin.unwrap() - 0.08).abs() < 1e-12);
        // b is unknown at genus, so c decides; the runner-up is a's G1.
        let genus = &id.ranks[1];
        assert_eq!(
            (genus.taxon.as_str(), genus.reference.as_str()),
            ("G2", "c")
        );
        assert_eq!(genus.runner_up.as_deref(), Some("G1"));
        assert!((genus.margin.unwrap() - 0.01).abs() < 1e-12);
    }

    #[test]
    fn ties_do_not_depend_on_input_order() {
        let labels = Labels::parse("name,genus\na,G1\nb,G2\n", None, Path::new("l.csv")).unwrap();
        let x = identify(&[n("b", 0.1), n("a", 0.1)], &labels, 1);
        let y = identify(&[n("a", 0.1), n("b", 0.1)], &labels, 1);
        assert_eq!(x, y);
        assert_eq!(x.ranks[0].taxon, "G1");
    }
}
