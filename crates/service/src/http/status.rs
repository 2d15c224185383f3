//! What the daemon tells the console about itself: a snapshot it updates
//! on its housekeeping tick and the console reads on each request.

use crate::classify::{CalibrationState, Classifier};
use serde::Serialize;
use std::sync::{Arc, RwLock};
use tokio::sync::Notify;

/// The daemon's state as the console shows it (`GET /api/v1/status`).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DaemonStatus {
    /// Whether a daemon is running and updating this snapshot (false when
    /// the console runs without one, as in tests).
    pub running: bool,
    /// The scan being identified, if any.
    pub current_scan: Option<i64>,
    /// References in the loaded library.
    pub references: usize,
    /// The library's calibration: `off`, `calibrating`, `ready` or
    /// `failed` ([`calibration_name`]).
    pub calibration: String,
    /// What is wrong with the storage, if anything (the status line's
    /// `degraded: …`).
    pub degraded: Option<String>,
    /// The serial trigger line, when configured.
    pub serial: Option<SerialStatus>,
    /// The systemd status line.
    pub status_line: String,
    /// The export folder watched.
    pub watching: String,
    /// The library folder.
    pub library: String,
    /// When the daemon last updated this (Unix milliseconds).
    pub updated_at_ms: i64,
}

/// The configured serial trigger line.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct SerialStatus {
    /// The device.
    pub port: String,
    /// Its baud rate.
    pub baud: u32,
    /// The regular expression a trigger line matches.
    pub trigger: String,
}

/// The shared snapshot: the daemon writes, the console reads; and the
/// console's request that the daemon reload its library (a reference was
/// added).
#[derive(Debug, Clone, Default)]
pub struct LiveStatus {
    status: Arc<RwLock<DaemonStatus>>,
    reload: Arc<Notify>,
    /// The daemon's library, with which the console draws a report's
    /// pictures.
    classifier: Arc<RwLock<Option<Arc<Classifier>>>>,
}

impl LiveStatus {
    /// A snapshot saying no daemon runs.
    pub fn new() -> Self {
        LiveStatus::default()
    }

    /// Change the snapshot (a panic elsewhere never makes it unusable).
    pub fn update(&self, change: impl FnOnce(&mut DaemonStatus)) {
        let mut guard = self.status.write().unwrap_or_else(|p| p.into_inner());
        change(&mut guard);
    }

    /// A copy of the snapshot.
    pub fn snapshot(&self) -> DaemonStatus {
        self.status
            .read()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }

    /// Ask the daemon to reload its library (kept until it looks).
    pub fn request_reload(&self) {
        self.reload.notify_one();
    }

    /// The library the daemon identifies with now (a clone: it shares the
    /// prepared references).
    pub(crate) fn set_classifier(&self, classifier: &Classifier) {
        let mut guard = self.classifier.write().unwrap_or_else(|p| p.into_inner());
        *guard = Some(Arc::new(classifier.clone()));
    }

    /// The daemon's library, when a daemon runs.
    pub(crate) fn classifier(&self) -> Option<Arc<Classifier>> {
        self.classifier
            .read()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }

    /// What the daemon waits on for [`LiveStatus::request_reload`].
    pub fn reload_signal(&self) -> Arc<Notify> {
        Arc::clone(&self.reload)
    }
}

/// The name the console and the API give a calibration state.
pub(crate) fn calibration_name(state: CalibrationState) -> &'static str {
    match state {
        CalibrationState::Off => "off",
        CalibrationState::Calibrating => "calibrating",
        CalibrationState::Ready => "ready",
        CalibrationState::Failed => "failed",
    }
}
