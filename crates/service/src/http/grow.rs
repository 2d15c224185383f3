//! A reviewed scan into the library (`POST /api/v1/scans/{id}/add-to-library`,
//! `morphoid library add`): its original file and the taxa its latest
//! decision settled (a confirmation: the identification's; a correction:
//! the identification's with the corrected ranks replaced). The file is
//! the one the database recorded, checked to hold the content reviewed;
//! nothing in a request names a path.

use crate::store::{ReviewRecord, Store, StoreError};
use morphoid_data::library::{add_reference, reference_name_for, AddError, NewReference};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Why a scan was not added to the library.
#[derive(Debug, thiserror::Error)]
pub enum GrowError {
    /// No scan has this id.
    #[error("no scan with id {0}")]
    NoSuchScan(i64),
    /// The scan's latest decision is not a confirmation or a correction.
    #[error("scan {0} is not confirmed or corrected (its latest decision must be one)")]
    NotSettled(i64),
    /// A scan of several specimens, or one specimen of one: its file holds
    /// more than the reference would.
    #[error("scan {0} is part of a scan of several specimens; its file cannot be one reference")]
    Specimens(i64),
    /// The library refused it.
    #[error(transparent)]
    Add(#[from] AddError),
    /// The database failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// A reference added from a scan.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AddedReference {
    /// The scan it came from.
    pub scan_id: i64,
    /// The reference's name.
    pub reference: String,
    /// Its taxon per rank.
    pub labels: BTreeMap<String, String>,
    /// The decision its labels come from.
    pub review_id: i64,
    /// The new surface file in the library.
    #[serde(skip)]
    pub file: PathBuf,
}

/// The labels a settled decision gives (`None`: not confirmed or
/// corrected).
pub(crate) fn settled_labels(review: &ReviewRecord) -> Option<BTreeMap<String, String>> {
    match review.decision.as_str() {
        "confirm" | "correct" => {
            let mut labels = review.identified.clone();
            labels.extend(review.taxa.clone());
            Some(labels)
        }
        _ => None,
    }
}

/// Add scan `scan_id` to the library at `library` (`ranks`: its rank
/// columns, empty for all) as `name` (default: from its file name).
pub fn add_scan_to_library(
    store: &Store,
    library: &Path,
    ranks: &[String],
    scan_id: i64,
    name: Option<&str>,
) -> Result<AddedReference, GrowError> {
    let scan = store
        .scan(scan_id, 0)?
        .ok_or(GrowError::NoSuchScan(scan_id))?;
    if scan.parent.is_some() || scan.specimen_count.is_some() {
        return Err(GrowError::Specimens(scan_id));
    }
    let review = store
        .latest_review(scan_id)?
        .ok_or(GrowError::NotSettled(scan_id))?;
    let labels = settled_labels(&review).ok_or(GrowError::NotSettled(scan_id))?;
    let reference = name.map_or_else(|| reference_name_for(&scan.path), str::to_string);
    let ranks = (!ranks.is_empty()).then_some(ranks);
    let file = add_reference(
        library,
        ranks,
        &NewReference {
            name: &reference,
            source: Path::new(&scan.path),
            content_hash: &scan.content_hash,
            taxa: &labels,
        },
    )?;
    Ok(AddedReference {
        scan_id,
        reference,
        labels,
        review_id: review.id,
        file,
    })
}
