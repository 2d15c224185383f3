//! The JSON API (`/api/v1/…`) and `/healthz`. Field names are stable and
//! documented in the README; a scan is the `morphoid results --json` form
//! plus `created_at_ms`, `finished_at_ms` and its curators' `review`.

use super::auth::{identify, may_read, writer, CSRF_HEADER};
use super::error::ApiError;
use super::query::scan_query;
use super::state::AppState;
use crate::store::{Decision, NewReview, ReviewRecord, ScanQuery, ScanRecord, DEFAULT_NEAREST};
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, RawQuery, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::{Deserialize, Deserializer};
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::sync::Arc;

/// A scan id from the path (`/scans/{id}`): digits only, so nothing else
/// in a path ever reaches a query.
pub(super) fn scan_id(text: &str) -> Result<i64, ApiError> {
    text.parse::<i64>()
        .ok()
        .filter(|id| *id > 0 && text.bytes().all(|b| b.is_ascii_digit()))
        .ok_or_else(|| {
            ApiError::NotFound(format!("no scan {text:?} (scans are found by their id)"))
        })
}

/// A scan's API form: its result form ([`ScanRecord`]'s JSON) with
/// `created_at_ms`, `finished_at_ms` and `review` (its latest decision,
/// or null).
pub(super) fn scan_json(record: &ScanRecord, review: Option<&ReviewRecord>) -> Value {
    let mut value = serde_json::to_value(record).unwrap_or(Value::Null);
    if let Value::Object(map) = &mut value {
        map.insert("created_at_ms".into(), json!(record.created_at_ms));
        map.insert("finished_at_ms".into(), json!(record.finished_at_ms));
        map.insert("review".into(), json!(review));
    }
    value
}

/// `GET /api/v1/scans`: a page of scans, newest first, filtered
/// (`query`): `{"scans": […], "next_cursor": id | null, "limit", "offset"}`.
pub(super) async fn list_scans(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
    RawQuery(raw): RawQuery,
) -> Result<Response, ApiError> {
    let identity = identify(&state, &headers).await?;
    may_read(&state, &identity)?;
    let query = scan_query(raw.as_deref(), &state.ranks, &[])?;
    let key = format!("scans?{}", raw.as_deref().unwrap_or(""));
    let body = state
        .answers
        .answer(key, {
            let state = Arc::clone(&state);
            move || async move { scans_page_json(&state, query).await }
        })
        .await?;
    Ok((
        [(header::CONTENT_TYPE, "application/json")],
        body.to_string(),
    )
        .into_response())
}

/// The body of `GET /api/v1/scans` for `query`: the same for every
/// reader, so it is kept until the database changes.
async fn scans_page_json(state: &AppState, query: ScanQuery) -> Result<String, ApiError> {
    let (limit, offset) = (query.limit, query.offset);
    let (page, reviews) = state
        .pool
        .run(move |store| {
            let page = store.search_scans(&query)?;
            let reviews = page
                .scans
                .iter()
                .map(|s| store.latest_review(s.id))
                .collect::<Result<Vec<_>, _>>()?;
            Ok::<_, ApiError>((page, reviews))
        })
        .await?;
    let scans: Vec<Value> = page
        .scans
        .iter()
        .zip(&reviews)
        .map(|(s, r)| scan_json(s, r.as_ref()))
        .collect();
    Ok(json!({
        "scans": scans,
        "next_cursor": page.next_cursor,
        "limit": limit,
        "offset": offset,
    })
    .to_string())
}

/// `GET /api/v1/scans/{id}`: one scan, with `reviews` (every decision,
/// first to last).
pub(super) async fn get_scan(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Json<Value>, ApiError> {
    let identity = identify(&state, &headers).await?;
    may_read(&state, &identity)?;
    let id = scan_id(&id)?;
    let (record, reviews) = state
        .pool
        .run(move |store| {
            let record = store
                .scan(id, DEFAULT_NEAREST)?
                .ok_or_else(|| ApiError::NotFound(format!("no scan with id {id}")))?;
            Ok::<_, ApiError>((record, store.reviews_of(id)?))
        })
        .await?;
    let mut value = scan_json(&record, reviews.last());
    if let Value::Object(map) = &mut value {
        map.insert("reviews".into(), json!(reviews));
    }
    Ok(Json(value))
}

/// `GET /api/v1/references`: the library as recorded:
/// `{"references": [{"name", "labels", "state", …}], "count", "calibration"}`.
pub(super) async fn references(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
) -> Result<Json<Value>, ApiError> {
    let identity = identify(&state, &headers).await?;
    may_read(&state, &identity)?;
    let refs = state.pool.run(|store| store.references()).await?;
    Ok(Json(json!({
        "count": refs.len(),
        "calibration": state.live.snapshot().calibration,
        "references": refs,
    })))
}

/// `GET /api/v1/status`: the daemon's state ([`super::DaemonStatus`]'s
/// fields) with `version`, `queue_length`, `counts` (scans per status) and
/// `changes` (see [`changes`]).
pub(super) async fn status(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
) -> Result<Json<Value>, ApiError> {
    let identity = identify(&state, &headers).await?;
    may_read(&state, &identity)?;
    let (counts, changes) = state
        .pool
        .run(|store| Ok::<_, ApiError>((store.counts()?, store.changes_fingerprint()?)))
        .await?;
    let mut value = serde_json::to_value(state.live.snapshot()).unwrap_or(Value::Null);
    if let Value::Object(map) = &mut value {
        map.insert("version".into(), json!(env!("CARGO_PKG_VERSION")));
        map.insert("queue_length".into(), json!(counts.pending));
        map.insert("counts".into(), json!(counts));
        map.insert("changes".into(), json!(changes));
    }
    Ok(Json(value))
}

/// `GET /api/v1/changes`: `{"changes": "…"}`, a text that changes whenever
/// a scan is queued, starts, finishes or is reviewed (what the live
/// overview polls).
pub(super) async fn changes(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
) -> Result<Json<Value>, ApiError> {
    let identity = identify(&state, &headers).await?;
    may_read(&state, &identity)?;
    let changes = state.pool.run(|store| store.changes_fingerprint()).await?;
    Ok(Json(json!({ "changes": changes })))
}

/// `GET /healthz`: `{"status": "ok"}` while the database can be read,
/// else 503. Needs no login (it says nothing else).
pub(super) async fn healthz(State(state): State<Arc<AppState>>) -> Response {
    match state.pool.run(|store| store.counts()).await {
        Ok(_) => Json(json!({"status": "ok"})).into_response(),
        Err(e) => (
            StatusCode::SERVICE_UNAVAILABLE,
            Json(json!({"status": "unavailable", "error": e.to_string()})),
        )
            .into_response(),
    }
}

/// The body of `POST /api/v1/scans/{id}/review`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ReviewBody {
    /// `confirm`, `correct` or `reject`.
    pub decision: String,
    /// For `correct`: the taxon per rank.
    #[serde(default)]
    pub taxa: BTreeMap<String, String>,
    /// Why.
    #[serde(default)]
    pub comment: Option<String>,
    /// The id of the latest decision the client saw (`null`: none); when
    /// another came since, 409 and nothing is recorded. Absent: no check.
    #[serde(default, deserialize_with = "present")]
    pub expected_latest: Option<Option<i64>>,
}

/// A field that may be absent (`None`), null (`Some(None)`) or a value.
fn present<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Option<i64>>, D::Error> {
    Option::<i64>::deserialize(d).map(Some)
}

/// A decision from its name and taxa.
pub(super) fn decision_of(
    name: &str,
    taxa: BTreeMap<String, String>,
) -> Result<Decision, ApiError> {
    match name {
        "confirm" | "reject" if !taxa.is_empty() => Err(ApiError::BadRequest(format!(
            "taxa go with decision \"correct\", not {name:?}"
        ))),
        "confirm" => Ok(Decision::Confirm),
        "reject" => Ok(Decision::Reject),
        "correct" => Ok(Decision::Correct(taxa)),
        other => Err(ApiError::BadRequest(format!(
            "decision {other:?}: confirm, correct or reject"
        ))),
    }
}

/// Record a decision by `curator` (who must still exist) and log it.
pub(super) async fn record_decision(
    state: &Arc<AppState>,
    curator: String,
    scan_id: i64,
    decision: Decision,
    comment: Option<String>,
    expected_latest: Option<Option<i64>>,
) -> Result<ReviewRecord, ApiError> {
    let ranks = state.ranks.clone();
    let who = curator.clone();
    let record = state
        .pool
        .run(move |store| {
            if !store.curator_exists(&who)? {
                return Err(ApiError::Unauthorized(format!(
                    "user {who:?} no longer exists"
                )));
            }
            let comment = comment.as_deref().map(str::trim).filter(|c| !c.is_empty());
            Ok(store.record_review(&NewReview {
                scan_id,
                curator: &who,
                decision,
                comment,
                expected_latest,
                ranks: &ranks,
            })?)
        })
        .await;
    // Whether it was recorded or not, no list from before is shown again.
    state.answers.forget();
    let record = record?;
    tracing::info!(
        "scan {scan_id}: {} by {curator} (decision #{}, {} of the scan)",
        record.decision,
        record.id,
        record.seq
    );
    Ok(record)
}

/// `POST /api/v1/scans/{id}/review`: record a curator's decision
/// ([`ReviewBody`]); 201 with the decision as recorded. Needs an API token,
/// or a session and its CSRF token in `X-CSRF-Token`.
pub(super) async fn review(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
    Path(id): Path<String>,
    body: Result<Json<ReviewBody>, JsonRejection>,
) -> Result<(StatusCode, Json<ReviewRecord>), ApiError> {
    let identity = identify(&state, &headers).await?;
    let csrf = headers.get(CSRF_HEADER).and_then(|v| v.to_str().ok());
    let curator = writer(&identity, csrf)?.to_string();
    let id = scan_id(&id)?;
    let Json(body) = body.map_err(|e| {
        if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
            ApiError::TooLarge(e.body_text())
        } else {
            ApiError::BadRequest(e.body_text())
        }
    })?;
    let decision = decision_of(&body.decision, body.taxa)?;
    let record = record_decision(
        &state,
        curator,
        id,
        decision,
        body.comment,
        body.expected_latest,
    )
    .await?;
    Ok((StatusCode::CREATED, Json(record)))
}

/// The body of `POST /api/v1/scans/{id}/add-to-library` (may be empty).
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct AddBody {
    /// The reference's name (default: from the scan's file name).
    #[serde(default)]
    pub name: Option<String>,
}

/// `POST /api/v1/scans/{id}/add-to-library`: the scan's original file and
/// the taxa of its latest decision (a confirmation or a correction) become
/// a reference of the library; the daemon reloads it. 201 with
/// `{"scan_id", "reference", "labels", "review_id"}`. One addition at a
/// time.
pub(super) async fn add_to_library(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
    Path(id): Path<String>,
    body: axum::body::Bytes,
) -> Result<(StatusCode, Json<Value>), ApiError> {
    let identity = identify(&state, &headers).await?;
    let csrf = headers.get(CSRF_HEADER).and_then(|v| v.to_str().ok());
    let curator = writer(&identity, csrf)?.to_string();
    let id = scan_id(&id)?;
    let AddBody { name } = if body.iter().all(u8::is_ascii_whitespace) {
        AddBody::default()
    } else {
        serde_json::from_slice(&body).map_err(|e| ApiError::BadRequest(format!("body: {e}")))?
    };
    let _one_at_a_time = state.adding.lock().await;
    let (library, ranks) = (state.library.clone(), state.ranks.clone());
    let who = curator.clone();
    let added = state
        .pool
        .run(move |store| {
            if !store.curator_exists(&who)? {
                return Err(ApiError::Unauthorized(format!(
                    "user {who:?} no longer exists"
                )));
            }
            super::grow::add_scan_to_library(store, &library, &ranks, id, name.as_deref())
                .map_err(ApiError::from)
        })
        .await;
    state.answers.forget();
    let added = added?;
    tracing::info!(
        "scan {id} added to the library as {} by {curator} (labels from decision #{}); reloading",
        added.reference,
        added.review_id
    );
    state.live.request_reload();
    Ok((StatusCode::CREATED, Json(json!(added))))
}

/// Anything else: 404 as JSON.
pub(super) async fn not_found() -> ApiError {
    ApiError::NotFound("no such page or endpoint (see /api/v1/openapi.json)".into())
}
