//! Calibrated confidence and "no close match", learnt from the library
//! itself.
//!
//! Each reference in turn is held out and identified against the others
//! (leave-one-out over the distances among the references,
//! [`ReferenceDistances`]). At each rank that gives, per held-out
//! reference, a novelty score ([`novelty_score`]) and whether its nearest
//! taxon was right; and, with its whole taxon held out too, the score of
//! a scan of a taxon the library lacks. [`Calibration::fit`] turns these
//! into
//! - the weight of the score's rank term ([`fit_rank_weight`]: what
//!   flags the most of the second kind at the false-flag rate),
//! - a logistic map from the score to the probability that the nearest
//!   taxon is right ([`Logistic`]), and
//! - the "no close match" threshold: the split-conformal quantile of the
//!   held-out references whose taxon the rest of the library holds
//!   ([`conformal_quantile`]), so that a scan of a taxon the library holds
//!   is flagged with probability at most [`FALSE_FLAG_RATE`].
//!
//! [`Calibration::assess`] scores a scan the same way and fills the
//! [`Confidence`] of each rank. Everything here is pure; the distances
//! among the references are computed and cached by [`cached`].

mod cached;
mod shard;
mod share;
mod statistic;

pub use cached::reference_distances;
pub(crate) use cached::reference_distances_in_turn;
use cached::CALIBRATION_SAMPLE;
pub(crate) use shard::merge_calibration_shards;
pub use shard::{calibration_shard, CalibrationShard, CalibrationShardError};
pub(crate) use share::CalibrationShare;
pub use share::CalibrationTurn;
use statistic::{
    conformal_quantile, fit_rank_weight, mean_within_taxon_rank, rank_term, relative_distance,
};
pub use statistic::{expected_calibration_error, reliability, roc_auc, share_caught_at};
pub(crate) use statistic::{fit_logistic, novelty_score, Logistic};

use super::nearest::{Confidence, DistanceRow, RankResult};
use morphoid_core::stats::upper_median;
use morphoid_data::table::Labels;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::HashMap;

/// The share of scans of a taxon the library holds that may be flagged
/// "no close match" (the threshold is the held-out scores' conformal
/// quantile at this miscoverage).
pub(crate) const FALSE_FLAG_RATE: f64 = 0.05;

/// Fewest held-out references known at a rank for a probability there.
pub(crate) const MIN_HELD: usize = 6;

/// Whether a library of `references` references can be calibrated: the
/// one rule, at least [`MIN_HELD`] of them.
pub(crate) fn calibratable(references: usize) -> bool {
    references >= MIN_HELD
}

/// How many references a scan's median distance to a library of more
/// than [`CALIBRATION_SAMPLE`] references is taken over (see
/// [`median_sample`]).
const MEDIAN_SAMPLE: usize = 48;

/// The references (ascending indices into `names`, the library's order)
/// over which a scan's median distance to the library is taken, in the
/// novelty score: all of them up to [`CALIBRATION_SAMPLE`], else the
/// [`MEDIAN_SAMPLE`] whose names' SHA-256 sorts first. A fixed sample, so
/// that a screened identification, which compares the scan with these and
/// with the references the screen keeps, scores it as the exhaustive one
/// does; chosen by name, so that a reference added to the library changes
/// the sample by at most that reference (the calibration then compares
/// only what involves it).
pub(crate) fn median_sample<S: AsRef<str>>(names: &[S]) -> Vec<usize> {
    if names.len() <= CALIBRATION_SAMPLE {
        return (0..names.len()).collect();
    }
    let mut order: Vec<([u8; 32], usize)> = names
        .iter()
        .enumerate()
        .map(|(i, n)| (Sha256::digest(n.as_ref().as_bytes()).into(), i))
        .collect();
    order.sort_unstable();
    let mut sample: Vec<usize> = order.iter().take(MEDIAN_SAMPLE).map(|&(_, i)| i).collect();
    sample.sort_unstable();
    sample
}

/// Fewest held-out references whose taxon the rest of the library holds,
/// for a "no close match" threshold at a rank.
pub(crate) const MIN_PRESENT: usize = 6;

/// Distances among the references: the whole row of each held-out
/// reference (all of them up to [`CALIBRATION_SAMPLE`], a sample beyond).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReferenceDistances {
    names: Vec<String>,
    /// Indices (into `names`) of the held-out references, ascending.
    held: Vec<usize>,
    /// `rows[k][j]`: distance between `names[held[k]]` and `names[j]`.
    rows: Vec<Vec<f64>>,
}

/// Why distances among references are not a usable table.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DistancesError {
    /// A row's length or a held index does not fit the names.
    #[error("reference distances: {0}")]
    Shape(String),
}

impl ReferenceDistances {
    /// Rows `rows[k]` (distances of `names[held[k]]` to every name) of the
    /// references `held`; checks the shape.
    pub fn new(
        names: Vec<String>,
        held: Vec<usize>,
        rows: Vec<Vec<f64>>,
    ) -> Result<Self, DistancesError> {
        let n = names.len();
        if held.len() != rows.len() {
            return Err(DistancesError::Shape(format!(
                "{} held references but {} rows",
                held.len(),
                rows.len()
            )));
        }
        if let Some(w) = held.windows(2).find(|w| w[0] >= w[1]) {
            return Err(DistancesError::Shape(format!(
                "held indices not ascending at {}",
                w[1]
            )));
        }
        if let Some(&h) = held.iter().find(|&&h| h >= n) {
            return Err(DistancesError::Shape(format!(
                "held index {h} of {n} references"
            )));
        }
        if let Some(r) = rows.iter().find(|r| r.len() != n) {
            return Err(DistancesError::Shape(format!(
                "a row of {} distances for {n} references",
                r.len()
            )));
        }
        Ok(ReferenceDistances { names, held, rows })
    }

    /// Every row of a full square matrix (`values[i][j]` between `names[i]`
    /// and `names[j]`).
    pub fn full(names: Vec<String>, values: Vec<Vec<f64>>) -> Result<Self, DistancesError> {
        let held = (0..names.len()).collect();
        Self::new(names, held, values)
    }

    /// The same table restricted to the references `keep` (indices,
    /// ascending): the library without some of its references.
    pub fn subset(&self, keep: &[usize]) -> Result<Self, DistancesError> {
        let names = keep
            .iter()
            .map(|&i| {
                self.names
                    .get(i)
                    .cloned()
                    .ok_or_else(|| DistancesError::Shape(format!("no reference {i}")))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut held = Vec::new();
        let mut rows = Vec::new();
        for (new, &old) in keep.iter().enumerate() {
            if let Some(row) = self.row(old) {
                held.push(new);
                rows.push(keep.iter().map(|&j| row[j]).collect());
            }
        }
        Self::new(names, held, rows)
    }

    /// The reference names, in library order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Whether every reference has its row (no sampling).
    pub fn is_complete(&self) -> bool {
        self.held.len() == self.names.len()
    }

    /// The distance between references `i` and `j`, when either was held
    /// out (has its row).
    pub fn distance(&self, i: usize, j: usize) -> Option<f64> {
        self.row(i)
            .and_then(|r| r.get(j))
            .or_else(|| self.row(j).and_then(|r| r.get(i)))
            .copied()
    }

    /// The row of reference `i`, if it was held out.
    fn row(&self, i: usize) -> Option<&[f64]> {
        let k = self.held.binary_search(&i).ok()?;
        self.rows.get(k).map(Vec::as_slice)
    }
}

/// What the library's leave-one-out says at one rank.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RankCalibration {
    /// The rank.
    pub rank: String,
    /// Weight of the rank term of the novelty score ([`fit_rank_weight`];
    /// 0 when it cannot be fitted or the library is sampled).
    pub weight: f64,
    /// Score → probability that the nearest taxon is right.
    pub logistic: Logistic,
    /// Scores above this are "no close match" (`None`: too few held-out
    /// references of a taxon the rest holds to set one).
    pub threshold: Option<f64>,
    /// Held-out references known at this rank.
    pub held: usize,
    /// Of them, identified to the right taxon.
    pub right: usize,
}

/// The confidence model of a library (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    index: HashMap<String, usize>,
    distances: ReferenceDistances,
    /// [`median_sample`] of the references.
    sample: Vec<usize>,
    /// Per calibrated rank (same order as `ranks`), the taxon of each
    /// reference.
    taxa: Vec<Vec<Option<String>>>,
    ranks: Vec<RankCalibration>,
}

/// A scan's distances to the library by reference index (`None`: not
/// compared), in the library's order.
type ScanDistances<'a> = &'a [Option<f64>];

/// What the novelty score of a scan at one rank is made of.
#[derive(Debug, Clone, Copy)]
struct Evidence {
    /// The nearest reference known at the rank.
    nearest: usize,
    /// Its distance to the scan.
    distance: f64,
    /// The scan's median distance to the library.
    median: f64,
    /// The scan's mean rank among the members of the nearest reference's
    /// taxon (0 when the library is sampled).
    rank: f64,
}

impl Evidence {
    /// The two terms of the score, for fitting the weight.
    fn terms(&self) -> Option<[f64; 2]> {
        Some([
            relative_distance(self.distance, self.median)?,
            rank_term(self.rank),
        ])
    }

    /// The novelty score with the rank term weighted by `weight`.
    fn score(&self, weight: f64) -> Option<f64> {
        novelty_score(self.distance, self.median, self.rank, weight)
    }
}

impl Calibration {
    /// Fit the calibration of a library from the distances among its
    /// references and their `labels`: leave-one-out over the held-out
    /// references, at every rank of `labels` with at least [`MIN_HELD`]
    /// held-out references known there. The rank term of the score is used
    /// only when every reference has its row (no sampling): it needs the
    /// distances among a taxon's members.
    pub fn fit(distances: ReferenceDistances, labels: &Labels) -> Self {
        let index = distances
            .names
            .iter()
            .enumerate()
            .map(|(i, n)| (n.clone(), i))
            .collect();
        let mut out = Calibration {
            index,
            sample: median_sample(&distances.names),
            distances,
            taxa: Vec::new(),
            ranks: Vec::new(),
        };
        for rank in labels.ranks() {
            let taxa: Vec<Option<&str>> = out
                .distances
                .names
                .iter()
                .map(|n| labels.get(n, rank))
                .collect();
            if let Some(cal) = out.fit_rank(rank, &taxa) {
                out.ranks.push(cal);
                out.taxa
                    .push(taxa.iter().map(|t| t.map(str::to_string)).collect());
            }
        }
        out
    }

    /// The references (ascending indices, library order) a scan's median
    /// distance is taken over ([`median_sample`]): a screened
    /// identification compares them too.
    pub(crate) fn median_sample(&self) -> &[usize] {
        &self.sample
    }

    /// The calibration at `rank` (`taxa`: each reference's taxon there),
    /// if there are enough held-out references.
    fn fit_rank(&self, rank: &str, taxa: &[Option<&str>]) -> Option<RankCalibration> {
        let d = &self.distances;
        // Per held-out reference: its evidence, whether its nearest taxon
        // was right, and whether the rest of the library holds its taxon.
        let mut held = Vec::new();
        // The terms of held-out references scored without their taxon.
        let mut absent = Vec::new();
        for (&h, row) in d.held.iter().zip(&d.rows) {
            let Some(truth) = taxa[h] else { continue };
            let scan: Vec<Option<f64>> = row
                .iter()
                .enumerate()
                .map(|(j, &v)| (j != h).then_some(v))
                .collect();
            let Some(e) = self.evidence(&scan, taxa) else {
                continue;
            };
            let present = taxa
                .iter()
                .enumerate()
                .any(|(j, t)| j != h && *t == Some(truth));
            held.push((e, taxa[e.nearest] == Some(truth), present));
            if d.is_complete() {
                let without: Vec<Option<f64>> = scan
                    .iter()
                    .zip(taxa)
                    .map(|(v, t)| v.filter(|_| *t != Some(truth)))
                    .collect();
                absent.extend(self.evidence(&without, taxa).and_then(|e| e.terms()));
            }
        }
        if held.len() < MIN_HELD {
            return None;
        }
        let present_terms: Vec<[f64; 2]> = held
            .iter()
            .filter(|x| x.2)
            .filter_map(|x| x.0.terms())
            .collect();
        let weight = fit_rank_weight(&present_terms, &absent, FALSE_FLAG_RATE).unwrap_or(0.0);
        let mut scores = Vec::new();
        let mut right = Vec::new();
        let mut present = Vec::new();
        for (e, r, p) in &held {
            let Some(score) = e.score(weight) else {
                continue;
            };
            scores.push(score);
            right.push(*r);
            if *p {
                present.push(score);
            }
        }
        if scores.len() < MIN_HELD {
            return None;
        }
        let logistic = fit_logistic(&scores, &right)?;
        let threshold = (present.len() >= MIN_PRESENT)
            .then(|| conformal_quantile(&present, FALSE_FLAG_RATE))
            .flatten();
        Some(RankCalibration {
            rank: rank.to_string(),
            weight,
            logistic,
            threshold,
            held: scores.len(),
            right: right.iter().filter(|&&r| r).count(),
        })
    }

    /// The evidence of `scan` at the rank (`taxa`) from its nearest
    /// reference known there (ties to the name that sorts first, as in
    /// [`identify`](super::identify)).
    fn evidence(&self, scan: ScanDistances<'_>, taxa: &[Option<&str>]) -> Option<Evidence> {
        let names = &self.distances.names;
        let (nearest, distance) = scan
            .iter()
            .enumerate()
            .filter_map(|(j, v)| Some((j, (*v)?)))
            .filter(|&(j, v)| taxa[j].is_some() && v.is_finite())
            .min_by(|a, b| {
                a.1.total_cmp(&b.1)
                    .then_with(|| names[a.0].cmp(&names[b.0]))
            })?;
        self.evidence_at(scan, taxa, nearest, distance)
    }

    /// The evidence of `scan` whose nearest reference at the rank is
    /// `nearest` at `distance`. The members of its taxon are the
    /// references of that taxon the scan was compared with.
    fn evidence_at(
        &self,
        scan: ScanDistances<'_>,
        taxa: &[Option<&str>],
        nearest: usize,
        distance: f64,
    ) -> Option<Evidence> {
        let sampled: Vec<f64> = self
            .sample
            .iter()
            .filter_map(|&j| scan.get(j).copied().flatten())
            .collect();
        let median = upper_median(&sampled)?;
        let rank = if self.distances.is_complete() {
            let taxon = taxa.get(nearest).copied().flatten()?;
            let members: Vec<(usize, f64)> = scan
                .iter()
                .enumerate()
                .filter(|&(j, _)| taxa[j] == Some(taxon))
                .filter_map(|(j, v)| Some((j, (*v)?)))
                .collect();
            let among = members
                .iter()
                .map(|&(t, _)| {
                    members
                        .iter()
                        .map(|&(u, _)| self.distances.distance(t, u))
                        .collect::<Option<Vec<f64>>>()
                })
                .collect::<Option<Vec<_>>>()?;
            let to_members: Vec<f64> = members.iter().map(|&(_, v)| v).collect();
            mean_within_taxon_rank(&to_members, &among)?
        } else {
            0.0
        };
        Some(Evidence {
            nearest,
            distance,
            median,
            rank,
        })
    }

    /// The calibration per rank, in rank order (ranks with too few
    /// held-out references are missing).
    pub fn ranks(&self) -> &[RankCalibration] {
        &self.ranks
    }

    /// The reference names the calibration was made from.
    pub fn names(&self) -> &[String] {
        self.distances.names()
    }

    /// The confidence of an identification: for each rank of `ranks` that
    /// is calibrated, the novelty score of the scan (its `distances` to
    /// the references) at the rank's nearest reference, the probability
    /// that the taxon is right, and the "no close match" flag. Ranks
    /// without calibration, or whose nearest reference the calibration
    /// does not know, keep `confidence: None`.
    pub fn assess(&self, distances: &[DistanceRow], ranks: &mut [RankResult]) {
        let mut scan = vec![None; self.distances.names.len()];
        for d in distances {
            if let Some(&i) = self.index.get(&d.reference) {
                scan[i] = Some(d.distance).filter(|v| v.is_finite());
            }
        }
        for r in ranks.iter_mut() {
            r.confidence = self.confidence(&scan, r);
        }
    }

    /// The confidence at one rank.
    fn confidence(&self, scan: ScanDistances<'_>, r: &RankResult) -> Option<Confidence> {
        let k = self.ranks.iter().position(|c| c.rank == r.rank)?;
        let cal = &self.ranks[k];
        let taxa: Vec<Option<&str>> = self.taxa.get(k)?.iter().map(|t| t.as_deref()).collect();
        let &nearest = self.index.get(&r.reference)?;
        let novelty = self
            .evidence_at(scan, &taxa, nearest, r.distance)?
            .score(cal.weight)?;
        Some(Confidence {
            probability: cal.logistic.probability(novelty),
            novelty,
            novelty_threshold: cal.threshold,
            no_close_match: cal.threshold.map(|t| novelty > t),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// The median sample of a large library is chosen by name: a reference
    /// added anywhere in the library's order changes it by at most itself.
    #[test]
    fn adding_a_reference_changes_the_median_sample_by_at_most_itself() {
        let names: Vec<String> = (0..1000).map(|i| format!("ref{i:04}")).collect();
        let sample = |names: &[String]| -> Vec<String> {
            median_sample(names)
                .into_iter()
                .map(|i| names[i].clone())
                .collect()
        };
        let before = sample(&names);
        assert_eq!(before.len(), MEDIAN_SAMPLE);
        let mut entered = 0;
        for new in ["aaa", "ref0500x", "zzz", "ref0001a", "m", "q17", "x", "b2"] {
            let mut grown = names.clone();
            grown.push(new.to_string());
            grown.sort();
            let after = sample(&grown);
            assert_eq!(after.len(), MEDIAN_SAMPLE);
            let left: Vec<&String> = before.iter().filter(|n| !after.contains(n)).collect();
            let came: Vec<&String> = after.iter().filter(|n| !before.contains(n)).collect();
            assert!(
                left.len() <= 1 && came.len() == left.len(),
                "{left:?} {came:?}"
            );
            if let Some(c) = came.first() {
                assert_eq!(c.as_str(), new);
                entered += 1;
            }
        }
        assert!(entered < 8, "a new name rarely enters the sample");
        // A small library is its own sample.
        assert_eq!(median_sample(&names[..150]), (0..150).collect::<Vec<_>>());
    }

    /// Points on a line as specimens: genus `G<k>` sits around 10·k, its
    /// members 0.3 apart; distances are |x − y| (plus a floor, as cP
    /// distances are never zero between different surfaces).
    fn line_library(genera: usize, per: usize) -> (Vec<String>, Vec<f64>, Labels) {
        let mut names = Vec::new();
        let mut xs = Vec::new();
        let mut csv = String::from("name,genus\n");
        for g in 0..genera {
            for m in 0..per {
                let name = format!("g{g}m{m}");
                csv += &format!("{name},G{g}\n");
                xs.push(10.0 * g as f64 + 0.3 * m as f64);
                names.push(name);
            }
        }
        let labels = Labels::parse(&csv, None, Path::new("labels.csv")).unwrap();
        (names, xs, labels)
    }

    fn dist(a: f64, b: f64) -> f64 {
        (a - b).abs() + 0.01
    }

    fn table(names: &[String], xs: &[f64]) -> ReferenceDistances {
        let values = xs
            .iter()
            .map(|&a| {
                xs.iter()
                    .map(|&b| if a == b { 0.0 } else { dist(a, b) })
                    .collect()
            })
            .collect();
        ReferenceDistances::full(names.to_vec(), values).unwrap()
    }

    fn rows(names: &[String], xs: &[f64], at: f64) -> Vec<DistanceRow> {
        names
            .iter()
            .zip(xs)
            .map(|(n, &x)| DistanceRow {
                reference: n.clone(),
                forward: dist(at, x),
                backward: dist(at, x),
                distance: dist(at, x),
                reflected: false,
            })
            .collect()
    }

    fn assess_at(
        cal: &Calibration,
        names: &[String],
        xs: &[f64],
        labels: &Labels,
        at: f64,
    ) -> Confidence {
        let d = rows(names, xs, at);
        let mut id = crate::identify::identify(&d, labels, 3);
        cal.assess(&d, &mut id.ranks);
        id.ranks[0].confidence.clone().unwrap()
    }

    #[test]
    fn a_scan_inside_a_genus_is_confident_and_one_between_genera_is_flagged() {
        let (names, xs, labels) = line_library(5, 4);
        let cal = Calibration::fit(table(&names, &xs), &labels);
        let genus = &cal.ranks()[0];
        assert_eq!((genus.held, genus.right), (20, 20));
        assert!(genus.threshold.is_some());
        // Among G2's members: near, and ranking among them like a member.
        let inside = assess_at(&cal, &names, &xs, &labels, 20.45);
        assert_eq!(inside.no_close_match, Some(false), "{inside:?}");
        assert!(inside.probability > 0.9, "{inside:?}");
        assert!(inside.probability < 1.0, "{inside:?}");
        // Halfway between G2 and G3: far from both for a member.
        let between = assess_at(&cal, &names, &xs, &labels, 25.0);
        assert_eq!(between.no_close_match, Some(true), "{between:?}");
        assert!(between.novelty > inside.novelty);
        // Every held-out member was right: the probability is flat.
        assert!(between.probability <= inside.probability + 1e-9);
    }

    #[test]
    fn wrong_held_out_calls_lower_the_probability_of_far_scans() {
        // Two genera interleaved at one end: members there are often
        // called wrong, and they are the far ones from their own genus.
        let (names, mut xs, labels) = line_library(4, 4);
        for (i, x) in xs.iter_mut().enumerate().take(8) {
            *x = 0.25 * i as f64 + if i % 2 == 0 { 0.0 } else { 5.0 };
        }
        let cal = Calibration::fit(table(&names, &xs), &labels);
        let g = &cal.ranks()[0];
        assert!(g.right < g.held, "{g:?}");
        assert!(g.logistic.slope < 0.0, "{g:?}");
    }

    #[test]
    fn too_small_a_library_has_no_calibration_and_subsets_keep_rows() {
        let (names, xs, labels) = line_library(2, 2);
        let cal = Calibration::fit(table(&names, &xs), &labels);
        assert!(cal.ranks().is_empty());
        let mut id = crate::identify::identify(&rows(&names, &xs, 0.1), &labels, 1);
        cal.assess(&rows(&names, &xs, 0.1), &mut id.ranks);
        assert_eq!(id.ranks[0].confidence, None);

        let (names, xs, _) = line_library(3, 3);
        let t = table(&names, &xs);
        let s = t.subset(&[0, 2, 5]).unwrap();
        assert_eq!(s.names(), ["g0m0", "g0m2", "g1m2"]);
        assert!(s.is_complete());
        assert_eq!(s.row(1).unwrap()[2], t.row(2).unwrap()[5]);
        let sampled =
            ReferenceDistances::new(names.clone(), vec![1], vec![t.row(1).unwrap().to_vec()])
                .unwrap();
        assert!(!sampled.is_complete());
        assert_eq!(sampled.subset(&[0, 1]).unwrap().held, vec![1]);
        assert!(ReferenceDistances::new(names.clone(), vec![1], vec![vec![0.0]]).is_err());
        assert!(ReferenceDistances::new(names, vec![2, 1], vec![vec![]; 2]).is_err());
    }
}
