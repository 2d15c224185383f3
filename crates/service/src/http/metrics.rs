//! `GET /metrics`: Prometheus text format (0.0.4), every name prefixed
//! `morphoid_`. Counted from the database on each scrape (the daemon may
//! have restarted since the last), and the daemon's snapshot.

use super::auth::{identify, may_read};
use super::error::ApiError;
use super::state::AppState;
use super::status::DaemonStatus;
use crate::store::{IdentificationTimes, StatusCounts, IDENTIFICATION_BUCKETS_S};
use axum::extract::State;
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::{IntoResponse, Response};
use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Arc;

/// The exposition format's content type.
const CONTENT_TYPE: &str = "text/plain; version=0.0.4; charset=utf-8";

/// `GET /metrics`.
pub(super) async fn metrics(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let identity = identify(&state, &headers).await?;
    may_read(&state, &identity)?;
    let (counts, times, reviews) = state
        .pool
        .run(|store| {
            Ok::<_, ApiError>((
                store.counts()?,
                store.identification_times()?,
                store.review_counts()?,
            ))
        })
        .await?;
    let live = state.live.snapshot();
    let mut m = String::with_capacity(4096);
    scan_metrics(&mut m, &counts);
    identification_histogram(&mut m, &times);
    daemon_metrics(&mut m, &live);
    review_metrics(&mut m, &reviews);
    let mut response = m.into_response();
    response
        .headers_mut()
        .insert(header::CONTENT_TYPE, HeaderValue::from_static(CONTENT_TYPE));
    Ok(response)
}

/// `morphoid_scans` by status and `morphoid_queue_length`.
fn scan_metrics(m: &mut String, counts: &StatusCounts) {
    family(m, "morphoid_scans", "gauge", "Scans recorded, by status.");
    for (status, n) in [
        ("pending", counts.pending),
        ("running", counts.running),
        ("ok", counts.ok),
        ("error", counts.error),
        ("duplicate", counts.duplicate),
        ("superseded", counts.superseded),
    ] {
        let _ = writeln!(m, "morphoid_scans{{status=\"{status}\"}} {n}");
    }
    family(
        m,
        "morphoid_queue_length",
        "gauge",
        "Scans waiting to be identified.",
    );
    let _ = writeln!(m, "morphoid_queue_length {}", counts.pending);
}

/// `morphoid_identification_seconds`: the histogram of times from claim to recorded identification.
fn identification_histogram(m: &mut String, times: &IdentificationTimes) {
    family(
        m,
        "morphoid_identification_seconds",
        "histogram",
        "Time from a scan's claim to its recorded identification.",
    );
    for (bound, n) in IDENTIFICATION_BUCKETS_S.iter().zip(&times.buckets) {
        let _ = writeln!(
            m,
            "morphoid_identification_seconds_bucket{{le=\"{bound}\"}} {n}"
        );
    }
    let _ = writeln!(
        m,
        "morphoid_identification_seconds_bucket{{le=\"+Inf\"}} {}",
        times.count
    );
    let _ = writeln!(m, "morphoid_identification_seconds_sum {}", times.sum_s);
    let _ = writeln!(m, "morphoid_identification_seconds_count {}", times.count);
}

/// What the daemon says of itself: degraded storage, running, references, calibrating.
fn daemon_metrics(m: &mut String, live: &DaemonStatus) {
    family(
        m,
        "morphoid_degraded",
        "gauge",
        "1 while part of the storage is faulty (the status line's degraded).",
    );
    let _ = writeln!(m, "morphoid_degraded {}", u8::from(live.degraded.is_some()));
    family(
        m,
        "morphoid_daemon_running",
        "gauge",
        "1 while a daemon updates the console.",
    );
    let _ = writeln!(m, "morphoid_daemon_running {}", u8::from(live.running));
    family(
        m,
        "morphoid_references",
        "gauge",
        "References in the loaded library.",
    );
    let _ = writeln!(m, "morphoid_references {}", live.references);
    family(
        m,
        "morphoid_calibrating",
        "gauge",
        "1 while the library's confidence is being calibrated.",
    );
    let _ = writeln!(
        m,
        "morphoid_calibrating {}",
        u8::from(live.calibration == "calibrating")
    );
}

/// `morphoid_reviews`: the curators' decisions by kind.
fn review_metrics(m: &mut String, reviews: &BTreeMap<String, u64>) {
    family(
        m,
        "morphoid_reviews",
        "gauge",
        "Curators' decisions recorded, by kind.",
    );
    for decision in ["confirm", "correct", "reject"] {
        let n = reviews.get(decision).copied().unwrap_or(0);
        let _ = writeln!(m, "morphoid_reviews{{decision=\"{decision}\"}} {n}");
    }
}

/// The `# HELP` and `# TYPE` lines of a metric family.
fn family(m: &mut String, name: &str, kind: &str, help: &str) {
    let _ = writeln!(m, "# HELP {name} {help}\n# TYPE {name} {kind}");
}
