//! Identification: the nearest taxon at each rank of the library
//! ([`identify`]) and how far it can be trusted ([`Calibration`], learnt
//! from the library's own leave-one-out: a probability and a "no close
//! match" flag); in a large library, the references a scan is compared
//! with ([`screened_references`]).

mod calibration;
mod nearest;
mod screen;

pub(crate) use calibration::{
    calibratable, merge_calibration_shards, reference_distances_in_turn, CalibrationShare, MIN_HELD,
};
pub use calibration::{
    calibration_shard, expected_calibration_error, reference_distances, reliability, roc_auc,
    share_caught_at, Calibration, CalibrationShard, CalibrationShardError, CalibrationTurn,
    ReferenceDistances,
};
pub use nearest::{
    identify, Confidence, DistanceRow, Identification, LandmarkPoint, RankResult, ScanLandmarks,
    ScanOutcome,
};
pub(crate) use nearest::{Nearest, SpecimenOutcome, SpecimensOutcome};
pub use screen::screened_references;
