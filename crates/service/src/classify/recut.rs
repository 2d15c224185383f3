//! A crown found on a whole tooth, cut again where the library's crowns
//! end.
//!
//! The margin found on the geometry of a whole tooth lies below the hand
//! crop on some sides of a smooth neck, and no geometry of the scan says
//! where the crop rises; the references' crop lines do. Two stages, after
//! the first comparison:
//! - **each of the nearest references**: the scan is cut along that
//!   reference's crop line, moved onto it by their comparison, and compared
//!   with it again; twice, since the first alignment is pulled by the very
//!   neck the cut removes ([`RECUT_ROUNDS`]);
//! - **the line they agree on**: the scan keeps the faces that lie above
//!   the crop lines of at least half of those references, and that crown is
//!   compared with the references the screen keeps for it (its signature
//!   is the crown's, no longer the neck's), or with the `[cp] recut_among`
//!   references nearest the scan so far; its nearest references then
//!   vote on the next such cut ([`CONSENSUS_ROUNDS`]). A reference of
//!   the scan's genus that was not among the first nearest gets a crown cut
//!   as its own kind is cut.
//!
//! Every row keeps the smallest distance it was given. The crown the last
//! common line left becomes the scan's crown (what its report shows and
//! its landmarks are carried onto). Only crowns the cleaning cut from a
//! closed surface or a volume are cut again.

use super::{distance_row, Classifier};
use crate::identify::DistanceRow;
use morphoid_core::cp;
use morphoid_core::mesh::Mesh;
use morphoid_data::pipeline::{self, PreparedSurface};
use rayon::prelude::*;

/// Rounds of cutting a crown again along one reference's crop line: the
/// second cut is aligned without the neck the first removed (on a crown
/// given a neck, the first leaves a third of it, the second none).
const RECUT_ROUNDS: usize = 2;

/// Rounds of cutting the crown along the line its nearest references
/// agree on, each voted by the nearest of the round before (on the
/// crowns first cut from the smooth-necked exports, genus 77 of 100
/// without, 81 after one round, 84 after two).
const CONSENSUS_ROUNDS: usize = 2;

/// A reference whose crop line the crown was cut along again, and its
/// distance before and after.
#[derive(Debug, Clone, serde::Serialize)]
struct Recut {
    reference: String,
    before: f64,
    after: f64,
}

/// One cut along the line the nearest references agree on: who voted, the
/// faces it kept of the prepared crown it cut (of the scan's first, then
/// of the round before's), how many references it was compared with, and
/// the nearest reference after it.
#[derive(Debug, Clone, serde::Serialize)]
struct ConsensusCut {
    references: Vec<String>,
    faces: usize,
    compared: usize,
    nearest: String,
    distance: f64,
}

/// One cut along a common line: the crown it left, prepared, and the
/// triangles of its cleaned form; the faces it kept; and the rows compared
/// with that crown.
struct CommonLineCut {
    crown: cp::Prepared,
    cleaned_faces: Vec<[u32; 3]>,
    kept: usize,
    compared: Vec<(usize, cp::Comparison)>,
}

/// What the re-cut did (the result's `cleaning.recut`).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub(super) struct RecutReport {
    /// Each of the nearest references, cut along alone.
    references: Vec<Recut>,
    /// Each round of the cut they agree on.
    consensus: Vec<ConsensusCut>,
}

impl RecutReport {
    /// Whether nothing was cut again.
    pub(super) fn is_empty(&self) -> bool {
        self.references.is_empty() && self.consensus.is_empty()
    }
}

/// The indices of the `k` nearest of `rows` (smallest distance, ties by
/// name).
pub(super) fn nearest_rows(rows: &[DistanceRow], k: usize) -> Vec<usize> {
    let distances: Vec<Option<f64>> = rows.iter().map(|r| Some(r.distance)).collect();
    let names: Vec<&str> = rows.iter().map(|r| r.reference.as_str()).collect();
    nearest_k(&distances, &names, k)
}

/// The indices of the `k` smallest of `distances` (`None`: not compared),
/// ties by `names`.
fn nearest_k(distances: &[Option<f64>], names: &[&str], k: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..distances.len())
        .filter(|&i| distances[i].is_some())
        .collect();
    order.sort_by(|&a, &b| {
        distances[a]
            .unwrap_or(f64::INFINITY)
            .total_cmp(&distances[b].unwrap_or(f64::INFINITY))
            .then_with(|| names[a].cmp(names[b]))
    });
    order.truncate(k);
    order
}

impl Classifier {
    /// For a crown cut from a whole tooth (or a volume): the two stages of
    /// the module's documentation, with `[cp] recut_nearest` references.
    /// `found[k]` is the reference index and alignment of `rows[k]`; rows
    /// take the smaller distances; the last common line's crown replaces
    /// `surface`'s. Returns what was cut, for the result.
    pub(super) fn recut(
        &self,
        name: &str,
        surface: &mut PreparedSurface,
        found: &[(usize, cp::Alignment)],
        rows: &mut [DistanceRow],
    ) -> RecutReport {
        let k = self.settings.cp.recut.recut_nearest;
        let mut report = RecutReport::default();
        if k == 0 || surface.cleaning.crown.is_none() {
            return report;
        }
        let _s = tracing::info_span!("recut", scan = %name, references = k).entered();
        let names: Vec<String> = rows.iter().map(|r| r.reference.clone()).collect();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        let refined: Vec<(usize, cp::Comparison, cp::Alignment, cp::RimProfile)> =
            nearest_rows(rows, k)
                .par_iter()
                .filter_map(|&row| {
                    let (i, alignment) = found[row];
                    let (c, a, rim) = self.recut_along(name, &surface.prepared, i, alignment)?;
                    Some((row, c, a, rim))
                })
                .collect();
        let mut voters = Vec::with_capacity(refined.len());
        for (row, c, alignment, rim) in refined {
            let before = rows[row].distance;
            if c.distance < before {
                rows[row] = distance_row(names[row], &c);
            }
            report.references.push(Recut {
                reference: names[row].to_string(),
                before,
                after: c.distance,
            });
            voters.push((row, alignment, rim));
        }
        // Each common cut's crown refers to the file's units, as the
        // scan's own does.
        let mut base = surface.prepared.clone();
        let mut last_faces = None;
        for _ in 0..CONSENSUS_ROUNDS {
            if voters.is_empty() {
                break;
            }
            let among = match self.settings.cp.recut.recut_among {
                0 => None,
                k => Some(nearest_rows(rows, k)),
            };
            let Some(round) =
                self.cut_along_common_line(name, &base, found, &voters, among, &names)
            else {
                break;
            };
            let mut distances = vec![None; rows.len()];
            let mut alignments = vec![None; rows.len()];
            for (row, c) in &round.compared {
                distances[*row] = Some(c.distance);
                alignments[*row] = Some(cp::Alignment::of(c));
                if c.distance < rows[*row].distance {
                    rows[*row] = distance_row(names[*row], c);
                }
            }
            let next = nearest_k(&distances, &names, k);
            let Some(&nearest) = next.first() else {
                break;
            };
            report.consensus.push(ConsensusCut {
                references: voters.iter().map(|v| names[v.0].to_string()).collect(),
                faces: round.kept,
                compared: round.compared.len(),
                nearest: names[nearest].to_string(),
                distance: distances[nearest].unwrap_or(f64::NAN),
            });
            voters = next
                .into_iter()
                .filter_map(|row| {
                    let reference = self.references[found[row].0].prepared().ok()?;
                    Some((row, alignments[row]?, cp::RimProfile::of(&reference)?))
                })
                .collect();
            let (scale, centroid) = (base.scale(), base.centroid());
            last_faces = Some(round.cleaned_faces);
            base = round.crown;
            base.refer_to_file_units(scale, centroid);
        }
        if let Some(faces) = last_faces {
            // The crown the last common line left is the scan's crown from
            // here on (its report, its landmarks): of the cuts tried, it is
            // the one nearest where the library's crowns end.
            surface.cleaned = Mesh::new(base.vertices_in_file_units(), faces);
            surface.prepared = base;
        }
        report
    }

    /// `base` cut where at least half of the `voters`' crop lines agree,
    /// prepared, and compared with the rows `among` (`None`: those
    /// [`Classifier::screened_rows`] keeps for it) and the voters' rows;
    /// `None` when the cut cannot be prepared.
    fn cut_along_common_line(
        &self,
        name: &str,
        base: &cp::Prepared,
        found: &[(usize, cp::Alignment)],
        voters: &[(usize, cp::Alignment, cp::RimProfile)],
        among: Option<Vec<usize>>,
        names: &[&str],
    ) -> Option<CommonLineCut> {
        let lines: Vec<(cp::Alignment, cp::RimProfile)> =
            voters.iter().map(|(_, a, r)| (*a, r.clone())).collect();
        let cut = cp::cut_along_rims(base, &lines);
        let kept = cut.faces.len();
        let part = pipeline::prepare_mesh(&cut, name, &self.settings).ok()?;
        let mut rows = among.unwrap_or_else(|| self.screened_rows(&part.prepared, found));
        rows.extend(voters.iter().map(|v| v.0));
        rows.sort_unstable();
        rows.dedup();
        let compared = rows
            .into_par_iter()
            .filter_map(|row| {
                let reference = match self.references[found[row].0].prepared() {
                    Ok(p) => p,
                    Err(e) => {
                        tracing::warn!(reference = %names[row], "left out of the re-cut: {e}");
                        return None;
                    }
                };
                let c = cp::compare(&part.prepared, &reference, &self.settings.cp.compare);
                Some((row, c))
            })
            .collect();
        Some(CommonLineCut {
            crown: part.prepared,
            cleaned_faces: part.cleaned.faces,
            kept,
            compared,
        })
    }

    /// The rows of `found` the screen keeps for a crown cut again
    /// (screening on, whatever the library's size: the crown's own
    /// signature, now that its neck is gone, and the screen's settings).
    fn screened_rows(&self, crown: &cp::Prepared, found: &[(usize, cp::Alignment)]) -> Vec<usize> {
        let signatures: Vec<&cp::Signature> =
            found.iter().map(|&(i, _)| &self.signatures[i]).collect();
        self.screened_crown(crown, &signatures)
    }

    /// The scan cut along the crop line of reference `i`, starting from
    /// `alignment` (scan onto reference), [`RECUT_ROUNDS`] times: the last
    /// comparison, the alignment it gives the scan, and the line.
    fn recut_along(
        &self,
        name: &str,
        scan: &cp::Prepared,
        i: usize,
        mut alignment: cp::Alignment,
    ) -> Option<(cp::Comparison, cp::Alignment, cp::RimProfile)> {
        let reference = self.references[i].prepared().ok()?;
        let rim = cp::RimProfile::of(&reference)?;
        let mut last = None;
        for _ in 0..RECUT_ROUNDS {
            let cut = cp::cut_along_rim(scan, &alignment, &rim);
            let Ok(part) = pipeline::prepare_mesh(&cut, name, &self.settings) else {
                break;
            };
            let c = cp::compare(&part.prepared, &reference, &self.settings.cp.compare);
            alignment = cp::Alignment::of(&c).of_unnormalized(&part.prepared);
            last = Some(c);
        }
        last.map(|c| (c, alignment, rim))
    }
}
