//! `GET /api/v1/openapi.json`: the API described in OpenAPI 3.0 (written
//! by hand; the README's *Web console and API* holds the same field names).

use axum::Json;
use serde_json::{json, Value};

/// The OpenAPI document.
pub(super) async fn openapi() -> Json<Value> {
    Json(document())
}

/// A query parameter of type string.
fn param(name: &str, description: &str) -> Value {
    json!({"name": name, "in": "query", "required": false,
           "schema": {"type": "string"}, "description": description})
}

/// The document itself.
pub(super) fn document() -> Value {
    json!({
        "openapi": "3.0.3",
        "info": {
            "title": "morphoid",
            "version": env!("CARGO_PKG_VERSION"),
            "description": "Scans identified by morphoid run, the reference library, the daemon's state, and curators' decisions. Reads need a login or an API token unless [http] public_read = true; writes always need one (a session also sends its CSRF token in X-CSRF-Token)."
        },
        "components": components(),
        "security": [{"token": []}, {"session": []}],
        "paths": paths(),
    })
}

/// The document's components: the security schemes and the schemas
/// of the scans, ranks, decisions and references.
fn components() -> Value {
    json!({
        "securitySchemes": {
            "token": {"type": "http", "scheme": "bearer", "description": "morphoid user token NAME"},
            "session": {"type": "apiKey", "in": "cookie", "name": "morphoid_session"}
        },
        "schemas": {
            "Error": {"type": "object", "required": ["error"], "properties": {"error": {"type": "string"}}},
            "Rank": {"type": "object", "properties": {
                "taxon": {"type": "string"}, "reference": {"type": "string"},
                "distance": {"type": "number"}, "runner_up": {"type": "string", "nullable": true},
                "margin": {"type": "number", "nullable": true},
                "probability": {"type": "number", "nullable": true},
                "novelty": {"type": "number", "nullable": true},
                "novelty_threshold": {"type": "number", "nullable": true},
                "no_close_match": {"type": "boolean", "nullable": true}}},
            "Review": {"type": "object", "properties": {
                "id": {"type": "integer"}, "scan_id": {"type": "integer"},
                "seq": {"type": "integer", "description": "the scan's n-th decision"},
                "previous_id": {"type": "integer", "nullable": true},
                "curator": {"type": "string"}, "decided_at_ms": {"type": "integer"},
                "decision": {"type": "string", "enum": ["confirm", "correct", "reject"]},
                "taxa": {"type": "object", "additionalProperties": {"type": "string"}},
                "identified": {"type": "object", "additionalProperties": {"type": "string"}},
                "comment": {"type": "string", "nullable": true},
                "content_hash": {"type": "string"}, "path": {"type": "string"}}},
            "Scan": {"type": "object", "required": ["id", "scan", "status"], "properties": {
                "id": {"type": "integer"}, "scan": {"type": "string", "description": "the file's path"},
                "status": {"type": "string", "enum": ["pending", "running", "ok", "error", "duplicate", "superseded"]},
                "ranks": {"type": "object", "additionalProperties": {"$ref": "#/components/schemas/Rank"}},
                "no_close_match": {"type": "boolean", "nullable": true},
                "calibrating": {"type": "boolean"},
                "nearest": {"type": "array", "items": {"type": "object", "properties": {"reference": {"type": "string"}, "distance": {"type": "number"}}}},
                "cleaning": {"type": "object"}, "timings_ms": {"type": "object"},
                "landmarks": {"type": "array", "items": {"type": "object"}},
                "landmarks_reference": {"type": "string"},
                "error": {"type": "string"}, "files_error": {"type": "string"},
                "duplicate_of": {"type": "object"}, "superseded_by": {"type": "integer", "nullable": true},
                "parent": {"type": "integer"}, "specimen": {"type": "integer"}, "position": {"type": "object"},
                "segmentation": {"type": "object"},
                "specimens": {"type": "array", "items": {"$ref": "#/components/schemas/Scan"}},
                "created_at_ms": {"type": "integer"}, "finished_at_ms": {"type": "integer", "nullable": true},
                "review": {"allOf": [{"$ref": "#/components/schemas/Review"}], "nullable": true},
                "reviews": {"type": "array", "items": {"$ref": "#/components/schemas/Review"}, "description": "GET /api/v1/scans/{id} only"}}},
            "Reference": {"type": "object", "properties": {
                "id": {"type": "integer"}, "name": {"type": "string"}, "content_hash": {"type": "string"},
                "labels": {"type": "object", "additionalProperties": {"type": "string", "nullable": true}},
                "state": {"type": "string", "enum": ["pending", "prepared", "failed"]},
                "error": {"type": "string", "nullable": true},
                "added_at_ms": {"type": "integer"}, "prepared_at_ms": {"type": "integer", "nullable": true}}}
        }
    })
}

/// The document's paths: every endpoint with its parameters, bodies
/// and answers.
fn paths() -> Value {
    let mut all = scan_paths();
    if let (Value::Object(a), Value::Object(b)) = (&mut all, service_paths()) {
        a.extend(b);
    }
    all
}

/// `ok` (an operation's answers) with the answers every read can give.
fn with_errors(mut ok: Value) -> Value {
    let errors = json!({
        "401": {"description": "no or wrong credentials (`public_read` off)", "content": {"application/json": {"schema": {"$ref": "#/components/schemas/Error"}}}},
        "503": {"description": "the database is unavailable", "content": {"application/json": {"schema": {"$ref": "#/components/schemas/Error"}}}}
    });
    if let (Value::Object(o), Value::Object(e)) = (&mut ok, errors) {
        o.extend(e);
    }
    ok
}

/// The scans' paths: the list, one scan, a decision, an addition to the
/// library.
fn scan_paths() -> Value {
    let id_param = json!({"name": "id", "in": "path", "required": true,
                          "schema": {"type": "integer", "minimum": 1}});
    json!({
        "/api/v1/scans": {"get": {
            "summary": "Scans, newest first, filtered and paged",
            "parameters": [
                param("status", "pending, running, ok, error, duplicate or superseded"),
                param("<rank>", "a taxon at that rank, e.g. genus=Ateles (any of the library's ranks)"),
                param("rank", "with taxon: the same as <rank>=<taxon>"),
                param("taxon", "with rank"),
                param("no_close_match", "true or false"),
                param("reviewed", "true or false"),
                param("since", "queued at or after: a UTC day YYYY-MM-DD or Unix milliseconds"),
                param("until", "queued before: a UTC day YYYY-MM-DD (included) or Unix milliseconds"),
                param("name", "a piece of the file's path, any case"),
                param("limit", "scans per page, 1 to 500 (default 50)"),
                param("offset", "scans skipped"),
                param("cursor", "next_cursor of the page before")
            ],
            "responses": with_errors(json!({"200": {"description": "a page", "content": {"application/json": {"schema": {
                "type": "object", "properties": {
                    "scans": {"type": "array", "items": {"$ref": "#/components/schemas/Scan"}},
                    "next_cursor": {"type": "integer", "nullable": true},
                    "limit": {"type": "integer"}, "offset": {"type": "integer"}}}}}},
                "400": {"description": "an unknown parameter or a bad value"}}))
        }},
        "/api/v1/scans/{id}": {"get": {
            "summary": "One scan, with every decision on it",
            "parameters": [id_param.clone()],
            "responses": with_errors(json!({"200": {"description": "the scan", "content": {"application/json": {"schema": {"$ref": "#/components/schemas/Scan"}}}},
                "404": {"description": "no such scan"}}))
        }},
        "/api/v1/scans/{id}/review": {"post": {
            "summary": "A curator's decision: confirm, correct (a taxon per rank) or reject",
            "parameters": [id_param, {"name": "X-CSRF-Token", "in": "header", "required": false, "schema": {"type": "string"}, "description": "a session's CSRF token (not with a Bearer token)"}],
            "requestBody": {"required": true, "content": {"application/json": {"schema": {
                "type": "object", "required": ["decision"], "additionalProperties": false, "properties": {
                    "decision": {"type": "string", "enum": ["confirm", "correct", "reject"]},
                    "taxa": {"type": "object", "additionalProperties": {"type": "string"}, "description": "correct only"},
                    "comment": {"type": "string"},
                    "expected_latest": {"type": "integer", "nullable": true, "description": "the latest decision's id as the client saw it (null: none); 409 if another came since"}}}}}},
            "responses": with_errors(json!({"201": {"description": "recorded", "content": {"application/json": {"schema": {"$ref": "#/components/schemas/Review"}}}},
                "400": {"description": "a bad decision, rank or taxon"},
                "403": {"description": "a session without its CSRF token"},
                "404": {"description": "no such scan"},
                "409": {"description": "not reviewable now, nothing to confirm, or reviewed meanwhile"},
                "413": {"description": "body larger than [http] max_body_bytes"}}))
        }},
        "/api/v1/scans/{id}/add-to-library": {"post": {
            "summary": "A confirmed or corrected scan becomes a reference: its original file and the taxa of its latest decision; the daemon reloads the library",
            "parameters": [{"name": "id", "in": "path", "required": true, "schema": {"type": "integer", "minimum": 1}}],
            "requestBody": {"required": false, "content": {"application/json": {"schema": {
                "type": "object", "additionalProperties": false, "properties": {
                    "name": {"type": "string", "description": "the reference's name (default: the file's stem)"}}}}}},
            "responses": with_errors(json!({"201": {"description": "added", "content": {"application/json": {"schema": {
                "type": "object", "properties": {
                    "scan_id": {"type": "integer"}, "reference": {"type": "string"},
                    "labels": {"type": "object", "additionalProperties": {"type": "string"}},
                    "review_id": {"type": "integer"}}}}}},
                "400": {"description": "a bad name"},
                "404": {"description": "no such scan"},
                "409": {"description": "not confirmed or corrected, not a surface file, the file changed or is gone, or the name is taken"}}))
        }}
    })
}

/// The other paths: the library, the daemon, changes, this document,
/// health and metrics.
fn service_paths() -> Value {
    json!({
        "/api/v1/references": {"get": {
            "summary": "The reference library as recorded",
            "responses": with_errors(json!({"200": {"description": "references", "content": {"application/json": {"schema": {
                "type": "object", "properties": {
                    "count": {"type": "integer"}, "calibration": {"type": "string"},
                    "references": {"type": "array", "items": {"$ref": "#/components/schemas/Reference"}}}}}}}}))
        }},
        "/api/v1/status": {"get": {
            "summary": "The daemon's state",
            "responses": with_errors(json!({"200": {"description": "state", "content": {"application/json": {"schema": {
                "type": "object", "properties": {
                    "version": {"type": "string"}, "running": {"type": "boolean"},
                    "current_scan": {"type": "integer", "nullable": true},
                    "references": {"type": "integer"},
                    "calibration": {"type": "string", "enum": ["", "off", "calibrating", "ready", "failed"]},
                    "degraded": {"type": "string", "nullable": true},
                    "serial": {"type": "object", "nullable": true, "properties": {"port": {"type": "string"}, "baud": {"type": "integer"}, "trigger": {"type": "string"}}},
                    "status_line": {"type": "string"}, "watching": {"type": "string"}, "library": {"type": "string"},
                    "updated_at_ms": {"type": "integer"}, "queue_length": {"type": "integer"},
                    "counts": {"type": "object", "additionalProperties": {"type": "integer"}},
                    "changes": {"type": "string"}}}}}}}))
        }},
        "/api/v1/changes": {"get": {
            "summary": "A text that changes when a scan is queued, starts, finishes or is reviewed",
            "responses": with_errors(json!({"200": {"description": "fingerprint", "content": {"application/json": {"schema": {"type": "object", "properties": {"changes": {"type": "string"}}}}}}}))
        }},
        "/api/v1/openapi.json": {"get": {"summary": "This document", "security": [], "responses": {"200": {"description": "OpenAPI 3.0"}}}},
        "/healthz": {"get": {"summary": "Whether the database can be read", "security": [], "responses": {"200": {"description": "{\"status\": \"ok\"}"}, "503": {"description": "unavailable"}}}},
        "/metrics": {"get": {"summary": "Prometheus text format, names prefixed morphoid_", "responses": {"200": {"description": "metrics", "content": {"text/plain": {}}}}}}
    })
}
