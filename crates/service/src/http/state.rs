//! What every request handler shares.

use super::auth::{LoginLimiter, Sessions};
use super::cache::AnswerCache;
use super::pictures::Pictures;
use super::pool::ReadPool;
use super::server::Sources;
use super::status::LiveStatus;
use crate::config::Http;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Semaphore;

/// Database connections the console keeps at most.
const POOL_SIZE: usize = 4;

/// Password checks run at once: argon2 is slow on purpose, and logins must
/// not take the machine from identification.
const PASSWORD_CHECKS: usize = 1;

/// The server's shared state.
#[derive(Debug)]
pub(super) struct AppState {
    /// `[http]`.
    pub settings: Http,
    /// Connections to the daemon's database.
    pub pool: Arc<ReadPool>,
    /// The overview's and the scan list's answers, until the database
    /// changes.
    pub answers: Arc<AnswerCache>,
    /// Reports' scenes, drawn one at a time.
    pub pictures: Pictures,
    /// What the daemon says of itself.
    pub live: LiveStatus,
    /// Login sessions.
    pub sessions: Sessions,
    /// Failed logins.
    pub limiter: LoginLimiter,
    /// Password checks running.
    pub password_checks: Semaphore,
    /// The library's ranks, broadest first (empty: any rank).
    pub ranks: Vec<String>,
    /// The library folder (references are added to it).
    pub library: std::path::PathBuf,
    /// Held while a reference is added: one at a time.
    pub adding: tokio::sync::Mutex<()>,
    /// Whether cookies are marked `Secure` (served over TLS).
    pub secure_cookies: bool,
    /// A hash no password matches, checked when a login names no curator,
    /// so that a wrong name takes as long as a wrong password.
    pub dummy_hash: String,
}

impl AppState {
    /// The state of a server with these settings on `sources`.
    pub(super) fn new(settings: &Http, sources: Sources) -> Self {
        let Sources {
            db,
            library,
            ranks,
            live,
        } = sources;
        AppState {
            settings: settings.clone(),
            pool: Arc::new(ReadPool::new(&db, POOL_SIZE)),
            answers: Arc::new(AnswerCache::new(&db, super::cache::FRESH_FOR)),
            pictures: Pictures::new(),
            live,
            sessions: Sessions::new(Duration::from_secs_f64(settings.session_hours * 3600.0)),
            limiter: LoginLimiter::new(settings.login_failures_per_minute),
            password_checks: Semaphore::new(PASSWORD_CHECKS),
            ranks,
            library,
            adding: tokio::sync::Mutex::new(()),
            secure_cookies: false,
            dummy_hash: super::auth::hash_password(&super::auth::random_hex(16))
                .unwrap_or_default(),
        }
    }
}
