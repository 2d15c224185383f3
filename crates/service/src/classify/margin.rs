//! Which of the margins found on a whole tooth cuts its crown.
//!
//! The cleaning ranks the loops it finds round a whole tooth by geometry
//! alone (crease, neck, rise and fall), and on some smooth-necked and
//! two-rooted exports a loop round a slanted axis outranks the level one
//! at the margin. The references know what a crown is: each other crown
//! the cleaning found ([`PreparedSurface::alternatives`]) is compared with
//! the references the screen keeps for it (or, with `[cp] recut_among`,
//! the references nearest the crown as cut), and the crown whose nearest
//! reference is nearest is the scan's. Only crowns cut from a whole tooth
//! have alternatives.

use super::recut::nearest_rows;
use super::Classifier;
use crate::identify::DistanceRow;
use morphoid_core::cp;
use morphoid_data::pipeline::PreparedSurface;
use rayon::prelude::*;

/// One crown weighed: its faces, its nearest reference with the
/// distance, and how many references it was compared with.
#[derive(Debug, Clone, serde::Serialize)]
struct WeighedCrown {
    faces: usize,
    nearest: String,
    distance: f64,
    compared: usize,
}

/// The crowns weighed (the result's `cleaning.margins`): the cleaning's
/// choice first, then its alternatives (`null`: could not be compared);
/// `chosen` indexes `crowns`.
#[derive(Debug, Clone, serde::Serialize)]
pub(super) struct MarginChoice {
    crowns: Vec<Option<WeighedCrown>>,
    chosen: usize,
}

impl MarginChoice {
    /// Whether a crown other than the cleaning's was taken.
    pub(super) fn changed(&self) -> bool {
        self.chosen != 0
    }
}

impl Classifier {
    /// For a scan whose cleaning found other crowns: each compared with
    /// the references the screen keeps for it (screening on, whatever the
    /// library's size), or with the `[cp] recut_among` references nearest
    /// the crown as cut, beside `rows`, the comparison of the crown as cut
    /// (`found[k]`: the reference index of `rows[k]`). The crown with the
    /// nearest reference is swapped into `surface`. `None` when there was
    /// nothing to weigh.
    pub(super) fn choose_margin(
        &self,
        surface: &mut PreparedSurface,
        rows: &[DistanceRow],
        found: &[(usize, cp::Alignment)],
    ) -> Option<MarginChoice> {
        if surface.alternatives.is_empty() || self.settings.cp.recut.recut_nearest == 0 {
            return None;
        }
        let first = rows
            .iter()
            .min_by(|a, b| a.distance.total_cmp(&b.distance))?;
        let among = match self.settings.cp.recut.recut_among {
            0 => None,
            k => Some(
                nearest_rows(rows, k)
                    .into_iter()
                    .filter_map(|row| found.get(row).map(|f| f.0))
                    .collect::<Vec<usize>>(),
            ),
        };
        let weighed: Vec<Option<WeighedCrown>> = surface
            .alternatives
            .par_iter()
            .map(|a| match &among {
                Some(among) => self.nearest_among(&a.prepared, among),
                None => self.nearest_among(
                    &a.prepared,
                    &self.screened_crown(&a.prepared, &self.signatures),
                ),
            })
            .collect();
        // The alternative with the nearest reference, if nearer than the
        // crown as cut.
        let mut best: Option<(usize, f64)> = None;
        for (k, w) in weighed.iter().enumerate() {
            if let Some(w) = w {
                if w.distance < best.map_or(first.distance, |b| b.1) {
                    best = Some((k, w.distance));
                }
            }
        }
        let mut crowns = vec![Some(WeighedCrown {
            faces: surface.prepared.faces().len(),
            nearest: first.reference.clone(),
            distance: first.distance,
            compared: rows.len(),
        })];
        crowns.extend(weighed);
        if let Some((k, _)) = best {
            surface.take_alternative(k);
        }
        let chosen = best.map_or(0, |(k, _)| k + 1);
        tracing::debug!(
            crowns = crowns.len(),
            chosen,
            "margins weighed by the library"
        );
        Some(MarginChoice { crowns, chosen })
    }

    /// The nearest reference to `crown` among the references `among`;
    /// `None` when none could be compared.
    fn nearest_among(&self, crown: &cp::Prepared, among: &[usize]) -> Option<WeighedCrown> {
        let (distance, i) = among
            .par_iter()
            .copied()
            .filter_map(|i| {
                let reference = self.references[i].prepared().ok()?;
                Some((
                    cp::compare(crown, &reference, &self.settings.cp.compare).distance,
                    i,
                ))
            })
            .min_by(|a, b| {
                a.0.total_cmp(&b.0)
                    .then_with(|| self.references[a.1].name().cmp(self.references[b.1].name()))
            })?;
        Some(WeighedCrown {
            faces: crown.faces().len(),
            nearest: self.references[i].name().to_string(),
            distance,
            compared: among.len(),
        })
    }
}
