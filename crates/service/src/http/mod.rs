//! The web console and JSON API inside `morphoid run` (issue 32): pages a
//! technician reads in a browser (the live overview with its filters, each
//! scan's report from the database, the library, the daemon's state), the
//! JSON API scripts use (`/api/v1/…`, described by `/api/v1/openapi.json`),
//! `/healthz`, Prometheus `/metrics`, and the curators' decisions on
//! identifications (the append-only `review` table).
//!
//! The server runs on a multi-thread tokio runtime of its own, on its own
//! thread (`server`): the daemon's control loop is a current-thread
//! runtime that blocks during a library reload and on the shared database
//! connection, which would stall every request; and requests never hold
//! up the loop's signals and timers. It opens its own SQLite connections
//! (`pool`; WAL lets them read while the daemon writes). No request names
//! a file: scans are found by id, and nothing under `src/http` opens a
//! path taken from a request.
//!
//! Security (`auth`): reads need a logged-in curator unless
//! `[http] public_read`; every write needs one — a session cookie (with a
//! CSRF token on every form and API write) or an API token (`Bearer`).
//! Curators are managed with `morphoid user`; passwords are argon2 hashes.
//! A server on any address but loopback refuses to start without a
//! curator.
//!
//! Modules: `server` (listener, connections, limits), `state`, `pool`,
//! `cache` (the busiest reads' answers, kept until the database changes),
//! `pictures` (a report's scene, drawn again by the daemon's library),
//! `auth`, `query` (the scan filters), `api`, `pages`, `metrics`,
//! `openapi`, `status` (what the daemon tells the console), `error`.

mod api;
mod auth;
mod cache;
mod error;
mod grow;
mod metrics;
mod openapi;
mod pages;
mod pictures;
mod pool;
mod query;
mod server;
mod state;
mod status;

pub use auth::{hash_password, new_api_token, token_hash, PasswordError};
pub use grow::{add_scan_to_library, AddedReference, GrowError};
pub use server::{HttpError, Server, Sources};
pub(crate) use status::calibration_name;
pub use status::{DaemonStatus, LiveStatus, SerialStatus};
