//! Identification: the nearest taxon at each rank of the library
//! ([`identify`]) and how far it can be trusted ([`Calibration`], learnt
//! from the library's own leave-one-out: a probability and a "no close
//! match" flag).

mod calibration;
mod nearest;

pub use calibration::{
    calibratable, calibration_pairs, expected_calibration_error, fit_logistic, novelty_score,
    reference_distances, reliability, roc_auc, share_caught_at, Calibration, DistancesError,
    Logistic, RankCalibration, ReferenceDistances, ReliabilityBin, CALIBRATION_SAMPLE,
    FALSE_FLAG_RATE, MIN_HELD, MIN_PRESENT,
};
pub use nearest::{
    identify, Confidence, DistanceRow, Identification, LandmarkPoint, Nearest, RankResult,
    ScanLandmarks, ScanOutcome, SpecimenOutcome, SpecimensOutcome,
};
