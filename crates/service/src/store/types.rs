//! Plain data that goes into and comes out of the store.

use crate::identify::{Nearest, RankResult, ScanLandmarks};
use serde::ser::{SerializeMap, Serializer};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt;

/// Taxon per rank of a reference (`None`: unknown, `NA` in `labels.csv`).
pub type Labels = BTreeMap<String, Option<String>>;

/// Where a scan is in its life: `pending` → `running` → `ok` | `error` |
/// `superseded`; a file with the content of an earlier scan is
/// `duplicate` from the start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ScanStatus {
    /// Waiting to be identified.
    Pending,
    /// Claimed by a worker; back to pending if the worker dies.
    Running,
    /// Identified; the result and the distances are recorded.
    Ok,
    /// The scan could not be used; the message says why.
    Error,
    /// The file's content is an earlier scan's: it is not identified
    /// again, its row points at that scan and shares its result.
    Duplicate,
    /// When its job read the file, the file held other content than the
    /// one queued: that content was not identified; the row points at the
    /// row of the content read.
    Superseded,
}

impl ScanStatus {
    /// The name stored in the database and printed in JSON.
    pub fn as_str(self) -> &'static str {
        match self {
            ScanStatus::Pending => "pending",
            ScanStatus::Running => "running",
            ScanStatus::Ok => "ok",
            ScanStatus::Error => "error",
            ScanStatus::Duplicate => "duplicate",
            ScanStatus::Superseded => "superseded",
        }
    }

    /// The status named `s`, if any.
    pub fn parse(s: &str) -> Option<ScanStatus> {
        match s {
            "pending" => Some(ScanStatus::Pending),
            "running" => Some(ScanStatus::Running),
            "ok" => Some(ScanStatus::Ok),
            "error" => Some(ScanStatus::Error),
            "duplicate" => Some(ScanStatus::Duplicate),
            "superseded" => Some(ScanStatus::Superseded),
            _ => None,
        }
    }
}

impl fmt::Display for ScanStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// State of a reference in the library.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ReferenceState {
    /// Registered, not prepared yet.
    Pending,
    /// Prepared (flattened, features, samples) and usable.
    Prepared,
    /// Preparation failed; the error says why.
    Failed,
    /// An older content of a reference whose mesh has changed.
    Superseded,
    /// No longer in the library folder.
    Removed,
}

impl ReferenceState {
    /// The name stored in the database.
    pub fn as_str(self) -> &'static str {
        match self {
            ReferenceState::Pending => "pending",
            ReferenceState::Prepared => "prepared",
            ReferenceState::Failed => "failed",
            ReferenceState::Superseded => "superseded",
            ReferenceState::Removed => "removed",
        }
    }

    /// The state named `s`, if any.
    pub fn parse(s: &str) -> Option<ReferenceState> {
        match s {
            "pending" => Some(ReferenceState::Pending),
            "prepared" => Some(ReferenceState::Prepared),
            "failed" => Some(ReferenceState::Failed),
            "superseded" => Some(ReferenceState::Superseded),
            "removed" => Some(ReferenceState::Removed),
            _ => None,
        }
    }
}

impl fmt::Display for ReferenceState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One version (name + content) of a reference specimen.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReferenceRecord {
    /// Row id.
    pub id: i64,
    /// Mesh file stem, the `name` column of `labels.csv`.
    pub name: String,
    /// Content hash of the mesh file.
    pub content_hash: String,
    /// Taxon per rank.
    pub labels: Labels,
    /// Where it is in preparation.
    pub state: ReferenceState,
    /// Why preparation failed, if it did.
    pub error: Option<String>,
    /// When it was first registered (Unix milliseconds).
    pub added_at_ms: i64,
    /// When it was last prepared (Unix milliseconds).
    pub prepared_at_ms: Option<i64>,
}

/// A claimed job: the scan a worker must identify now.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Job {
    /// Scan row id, to pass to `complete` or `fail`.
    pub scan_id: i64,
    /// File path as enqueued.
    pub path: String,
    /// Content hash as enqueued.
    pub content_hash: String,
    /// File size in bytes as enqueued.
    pub size: u64,
    /// How many times it has been claimed, this time included. More than
    /// one means an earlier worker died on it (a scan that crashes the
    /// worker can be failed instead of retried for ever).
    pub attempts: u32,
}

/// What `enqueue` did.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub enum Enqueued {
    /// A new pending scan with this id.
    New(i64),
    /// This file is already recorded (the same content at the same path,
    /// or a duplicate row of it): that scan's id and status. Nothing was
    /// added.
    Existing(i64, ScanStatus),
    /// The content is an earlier scan's, at another path: a new row with
    /// status `duplicate` was added.
    Duplicate {
        /// The new row.
        id: i64,
        /// The earlier scan of the same content.
        of: i64,
    },
}

impl Enqueued {
    /// The scan id, new or existing.
    pub fn scan_id(&self) -> i64 {
        match *self {
            Enqueued::New(id) | Enqueued::Existing(id, _) | Enqueued::Duplicate { id, .. } => id,
        }
    }
}

/// A scan as recorded, with its result if it has one. Serializes to the
/// JSON of `classify --json` / `results --json` (see [`ScanRecord`]'s
/// `Serialize` impl).
#[derive(Debug, Clone, PartialEq)]
pub struct ScanRecord {
    /// Row id.
    pub id: i64,
    /// File path as enqueued.
    pub path: String,
    /// Content hash.
    pub content_hash: String,
    /// File size in bytes.
    pub size: u64,
    /// Status.
    pub status: ScanStatus,
    /// Error message when `status` is `Error`.
    pub error: Option<String>,
    /// Times claimed.
    pub attempts: u32,
    /// Enqueued at (Unix milliseconds).
    pub created_at_ms: i64,
    /// Last claimed at (Unix milliseconds).
    pub started_at_ms: Option<i64>,
    /// Finished at (Unix milliseconds), for `ok` and `error`.
    pub finished_at_ms: Option<i64>,
    /// Milliseconds per stage.
    pub timings_ms: BTreeMap<String, f64>,
    /// The cleaning report (`Null` when there is none).
    pub cleaning: serde_json::Value,
    /// Nearest taxon per rank, broadest first.
    pub ranks: Vec<RankResult>,
    /// The nearest references, nearest first (a few, not all).
    pub nearest: Vec<Nearest>,
    /// Landmarks carried onto the scan (`None`: the nearest reference has
    /// none, or the scan has no result).
    pub landmarks: Option<ScanLandmarks>,
    /// For a `duplicate`: the earlier scan of the same content, whose
    /// result (ranks, nearest, landmarks, error) this record carries.
    pub duplicate_of: Option<Original>,
    /// Why this scan's result files could not be written by the last
    /// attempt (`None`: written, not due, or not tried yet). The
    /// identification stands either way.
    pub files_error: Option<String>,
    /// The scan was identified while the library's calibration was still
    /// running: its ranks carry no confidence for that reason.
    pub calibrating: bool,
    /// For a `superseded` scan: the row of the content its job read.
    pub superseded_by: Option<i64>,
    /// For one specimen of a scan of several: the scan's row.
    pub parent: Option<i64>,
    /// For one specimen of a scan of several: its number (1-based, in
    /// order along the scan's longest axis).
    pub specimen: Option<u32>,
    /// For one specimen of a scan of several: where it lies.
    pub position: Option<morphoid_data::pipeline::Position>,
    /// For a scan of several specimens: how many.
    pub specimen_count: Option<u32>,
    /// For a scan of several specimens: each one's record, in order.
    pub specimens: Vec<ScanRecord>,
}

impl ScanRecord {
    /// Whether the scan is "no close match" at any rank (`None`: no rank
    /// has a calibrated flag).
    pub fn no_close_match(&self) -> Option<bool> {
        self.ranks
            .iter()
            .filter_map(|r| r.confidence.as_ref()?.no_close_match)
            .reduce(|a, b| a || b)
    }
}

/// The earlier scan a duplicate points at.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Original {
    /// Its row id.
    pub id: i64,
    /// Its file path.
    #[serde(rename = "scan")]
    pub path: String,
    /// Its status (the duplicate's result is known once it is `ok` or
    /// `error`).
    pub status: ScanStatus,
}

/// `{"taxon", "reference", "distance", "runner_up", "margin",
/// "probability", "novelty", "novelty_threshold", "no_close_match"}` of one
/// rank (the last four null when the library is not calibrated).
#[derive(Serialize)]
struct RankJson<'a> {
    taxon: &'a str,
    reference: &'a str,
    distance: f64,
    runner_up: Option<&'a str>,
    margin: Option<f64>,
    probability: Option<f64>,
    novelty: Option<f64>,
    novelty_threshold: Option<f64>,
    no_close_match: Option<bool>,
}

/// The ranks as a JSON object in rank order (broadest first).
struct RanksJson<'a>(&'a [RankResult]);

impl Serialize for RanksJson<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(self.0.len()))?;
        for r in self.0 {
            map.serialize_entry(
                &r.rank,
                &RankJson {
                    taxon: &r.taxon,
                    reference: &r.reference,
                    distance: r.distance,
                    runner_up: r.runner_up.as_deref(),
                    margin: r.margin,
                    probability: r.confidence.as_ref().map(|c| c.probability),
                    novelty: r.confidence.as_ref().map(|c| c.novelty),
                    novelty_threshold: r.confidence.as_ref().and_then(|c| c.novelty_threshold),
                    no_close_match: r.confidence.as_ref().and_then(|c| c.no_close_match),
                },
            )?;
        }
        map.end()
    }
}

/// The design's result form: `{"scan", "status", "ranks",
/// "no_close_match", "nearest", "cleaning", "timings_ms"}` for `ok`
/// (`no_close_match`: [`ScanRecord::no_close_match`]) (plus `"landmarks": [{"label", "x",
/// "y", "z"}, …]` and `"landmarks_reference"` when landmarks were carried
/// onto the scan), `{"scan", "status": "error",
/// "error"}` for an error, `{"scan", "status", "superseded_by"}` (the row
/// of the content read instead) for a superseded scan, `{"scan",
/// "status"}` while pending or running;
/// each with the scan's `id` too; `"files_error"` when its result files
/// could not be written, and `"calibrating": true` for an `ok` scan
/// identified before the library's calibration was ready. A `duplicate` adds `"duplicate_of":
/// {"id", "scan", "status"}` and the earlier scan's result in the same
/// fields (or its `"error"`). A scan of several specimens has, instead of
/// a result, `"segmentation"` (what was found and dropped),
/// `"timings_ms"` and `"specimens"`: each specimen's record as above
/// (`"scan": "<scan>#n"`), with `"parent"` (the scan's id), `"specimen"`
/// (n) and `"position"` (`{"voxels": [[x, y, z], [x, y, z]]` for a volume,
/// `"bounds": [[x, y, z], [x, y, z]]}` in file coordinates).
impl Serialize for ScanRecord {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(None)?;
        map.serialize_entry("scan", &self.path)?;
        map.serialize_entry("id", &self.id)?;
        map.serialize_entry("status", &self.status)?;
        let shown = match (&self.status, &self.duplicate_of) {
            (ScanStatus::Duplicate, Some(original)) => {
                map.serialize_entry("duplicate_of", original)?;
                original.status
            }
            (status, _) => *status,
        };
        if let (Some(parent), Some(n)) = (self.parent, self.specimen) {
            map.serialize_entry("parent", &parent)?;
            map.serialize_entry("specimen", &n)?;
            if let Some(p) = &self.position {
                map.serialize_entry("position", p)?;
            }
        }
        if !self.specimens.is_empty() {
            // A scan of several specimens: each one's result is its own.
            if shown == ScanStatus::Error {
                map.serialize_entry("error", self.error.as_deref().unwrap_or(""))?;
            }
            map.serialize_entry("segmentation", &self.cleaning)?;
            map.serialize_entry("timings_ms", &self.timings_ms)?;
            map.serialize_entry("specimens", &self.specimens)?;
            if let Some(e) = &self.files_error {
                map.serialize_entry("files_error", e)?;
            }
            return map.end();
        }
        match shown {
            ScanStatus::Ok => {
                map.serialize_entry("ranks", &RanksJson(&self.ranks))?;
                map.serialize_entry("no_close_match", &self.no_close_match())?;
                if self.calibrating {
                    map.serialize_entry("calibrating", &true)?;
                }
                map.serialize_entry("nearest", &self.nearest)?;
                map.serialize_entry("cleaning", &self.cleaning)?;
                map.serialize_entry("timings_ms", &self.timings_ms)?;
                if let Some(lm) = &self.landmarks {
                    map.serialize_entry("landmarks", &lm.points)?;
                    map.serialize_entry("landmarks_reference", &lm.reference)?;
                }
            }
            ScanStatus::Error => {
                map.serialize_entry("error", self.error.as_deref().unwrap_or(""))?;
            }
            ScanStatus::Superseded => {
                map.serialize_entry("superseded_by", &self.superseded_by)?;
            }
            ScanStatus::Pending | ScanStatus::Running | ScanStatus::Duplicate => {}
        }
        if let Some(e) = &self.files_error {
            map.serialize_entry("files_error", e)?;
        }
        map.end()
    }
}

/// Number of scans in each status.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct StatusCounts {
    /// Waiting.
    pub pending: u64,
    /// Being identified.
    pub running: u64,
    /// Identified.
    pub ok: u64,
    /// Failed.
    pub error: u64,
    /// Files with the content of an earlier scan.
    pub duplicate: u64,
    /// Queued contents that the file no longer held when read.
    pub superseded: u64,
}
