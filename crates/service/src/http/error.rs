//! What a request that fails answers: a status and one line saying why,
//! as JSON for the API (`{"error": "…"}`) and as a small page for the
//! console.

use crate::store::{ReviewError, StoreError};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use morphoid_data::present::escape;

/// Why a request was refused or failed.
#[derive(Debug, thiserror::Error)]
pub(super) enum ApiError {
    /// Nothing at this address, or no such scan.
    #[error("{0}")]
    NotFound(String),
    /// The request is malformed (a query value, a body field).
    #[error("{0}")]
    BadRequest(String),
    /// No credentials, or wrong ones.
    #[error("{0}")]
    Unauthorized(String),
    /// Credentials, but not for this (a missing CSRF token).
    #[error("{0}")]
    Forbidden(String),
    /// The request contradicts the scan's state or a concurrent decision.
    #[error("{0}")]
    Conflict(String),
    /// The request body is larger than `[http] max_body_bytes`.
    #[error("{0}")]
    TooLarge(String),
    /// Too many failed logins; retry after this many seconds.
    #[error("too many failed logins; try again in {0} s")]
    TooManyRequests(u64),
    /// The database cannot be used now (storage fault, busy).
    #[error("the database is unavailable: {0}")]
    Unavailable(String),
    /// Anything else.
    #[error("internal error: {0}")]
    Internal(String),
}

impl ApiError {
    /// The HTTP status of this error.
    pub(super) fn status(&self) -> StatusCode {
        match self {
            ApiError::NotFound(_) => StatusCode::NOT_FOUND,
            ApiError::BadRequest(_) => StatusCode::BAD_REQUEST,
            ApiError::Unauthorized(_) => StatusCode::UNAUTHORIZED,
            ApiError::Forbidden(_) => StatusCode::FORBIDDEN,
            ApiError::Conflict(_) => StatusCode::CONFLICT,
            ApiError::TooLarge(_) => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::TooManyRequests(_) => StatusCode::TOO_MANY_REQUESTS,
            ApiError::Unavailable(_) => StatusCode::SERVICE_UNAVAILABLE,
            ApiError::Internal(_) => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }

    /// The error as a console page (same status).
    pub(super) fn into_page(self) -> Response {
        let status = self.status();
        let body = format!(
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
             <title>morphoid: {code}</title></head><body><h1>{code}</h1>\
             <p id=\"error\">{}</p><p><a href=\"/\">Overview</a></p></body></html>\n",
            escape(&self.to_string()),
            code = status
        );
        let mut response = (status, axum::response::Html(body)).into_response();
        self.add_headers(&mut response);
        response
    }

    /// Headers the status calls for (`WWW-Authenticate`, `Retry-After`).
    fn add_headers(&self, response: &mut Response) {
        match self {
            ApiError::Unauthorized(_) => {
                response.headers_mut().insert(
                    header::WWW_AUTHENTICATE,
                    HeaderValue::from_static("Bearer realm=\"morphoid\""),
                );
            }
            ApiError::TooManyRequests(secs) => {
                if let Ok(v) = HeaderValue::from_str(&secs.to_string()) {
                    response.headers_mut().insert(header::RETRY_AFTER, v);
                }
            }
            _ => {}
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        if matches!(self, ApiError::Internal(_) | ApiError::Unavailable(_)) {
            tracing::warn!("http: {self}");
        }
        let mut response = (
            self.status(),
            axum::Json(serde_json::json!({ "error": self.to_string() })),
        )
            .into_response();
        self.add_headers(&mut response);
        response
    }
}

impl From<StoreError> for ApiError {
    fn from(e: StoreError) -> Self {
        let line = morphoid_data::present::error_chain(&e);
        if e.is_storage_fault() {
            ApiError::Unavailable(line)
        } else {
            ApiError::Internal(line)
        }
    }
}

impl From<super::grow::GrowError> for ApiError {
    fn from(e: super::grow::GrowError) -> Self {
        use super::grow::GrowError as G;
        use morphoid_data::library::AddError as A;
        let text = morphoid_data::present::error_chain(&e);
        match e {
            G::NoSuchScan(_) => ApiError::NotFound(text),
            G::NotSettled(_) | G::Specimens(_) => ApiError::Conflict(text),
            G::Add(A::InvalidName(_)) => ApiError::BadRequest(text),
            G::Add(A::Exists(_) | A::NotASurface(_) | A::Changed(_) | A::Read { .. }) => {
                ApiError::Conflict(text)
            }
            G::Add(A::Library(_) | A::Labels { .. } | A::Write(_) | A::Lock { .. }) => {
                ApiError::Internal(text)
            }
            G::Store(s) => s.into(),
        }
    }
}

impl From<ReviewError> for ApiError {
    fn from(e: ReviewError) -> Self {
        match e {
            ReviewError::NoSuchScan(_) => ApiError::NotFound(e.to_string()),
            ReviewError::Invalid(_) => ApiError::BadRequest(e.to_string()),
            ReviewError::NotReviewable { .. }
            | ReviewError::NothingToConfirm(_)
            | ReviewError::Conflict { .. } => ApiError::Conflict(e.to_string()),
            ReviewError::Store(s) => s.into(),
        }
    }
}
