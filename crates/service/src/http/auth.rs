//! Who is asking: curators' passwords (argon2id hashes), API tokens
//! (random, stored as their SHA-256), login sessions (random cookie
//! values held in memory, each with its CSRF token), and the limit on
//! failed logins.

use super::error::ApiError;
use super::state::AppState;
use argon2::password_hash::{PasswordHash, PasswordHasher, PasswordVerifier, SaltString};
use argon2::Argon2;
use axum::http::{header, HeaderMap};
use rand::RngCore;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The session cookie's name.
pub(super) const SESSION_COOKIE: &str = "morphoid_session";

/// The login form's CSRF cookie (set with the form, compared on submit).
pub(super) const LOGIN_CSRF_COOKIE: &str = "morphoid_login_csrf";

/// The header a session's API write carries its CSRF token in.
pub(super) const CSRF_HEADER: &str = "x-csrf-token";

/// Sessions kept at most; past it, expired ones go, then the oldest.
const MAX_SESSIONS: usize = 10_000;

/// Addresses and names whose failed logins are counted at most.
const MAX_LIMITED_KEYS: usize = 10_000;

/// The window failed logins are counted in.
const LOGIN_WINDOW: Duration = Duration::from_secs(60);

/// Why a password could not be hashed.
#[derive(Debug, thiserror::Error)]
pub enum PasswordError {
    /// The password is empty or too long.
    #[error("a password is 8 to 1024 characters long")]
    Length,
    /// argon2 failed.
    #[error("cannot hash the password: {0}")]
    Hash(String),
}

/// `n` random bytes from the operating system, as lowercase hex.
pub(super) fn random_hex(n: usize) -> String {
    let mut bytes = vec![0u8; n];
    rand::rngs::OsRng.fill_bytes(&mut bytes);
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The argon2id hash of `password` with a random salt, as a PHC string.
pub fn hash_password(password: &str) -> Result<String, PasswordError> {
    let chars = password.chars().count();
    if !(8..=1024).contains(&chars) {
        return Err(PasswordError::Length);
    }
    let mut salt = [0u8; 16];
    rand::rngs::OsRng.fill_bytes(&mut salt);
    let salt = SaltString::encode_b64(&salt).map_err(|e| PasswordError::Hash(e.to_string()))?;
    Argon2::default()
        .hash_password(password.as_bytes(), &salt)
        .map(|h| h.to_string())
        .map_err(|e| PasswordError::Hash(e.to_string()))
}

/// Whether `password` matches the PHC string `hash` (a malformed hash
/// matches nothing).
pub(crate) fn verify_password(password: &str, hash: &str) -> bool {
    match PasswordHash::new(hash) {
        Ok(parsed) => Argon2::default()
            .verify_password(password.as_bytes(), &parsed)
            .is_ok(),
        Err(_) => false,
    }
}

/// A new API token: `mph_` and 64 random hex digits. Only its
/// [`token_hash`] is stored.
pub fn new_api_token() -> String {
    format!("mph_{}", random_hex(32))
}

/// The SHA-256 of a token or session value (hex): what is stored and
/// looked up, so a copy of the database or of memory holds no credential.
pub fn token_hash(token: &str) -> String {
    morphoid_data::hash::content_hash(token.as_bytes())
}

/// Whether two secrets are equal, in time independent of where they
/// differ.
pub(super) fn same_secret(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}

/// A logged-in browser.
#[derive(Debug, Clone)]
pub(super) struct Session {
    /// The curator.
    pub user: String,
    /// The token every form and API write of this session carries.
    pub csrf: String,
    expires: Instant,
}

/// The login sessions, by the hash of their cookie value.
#[derive(Debug)]
pub(super) struct Sessions {
    map: Mutex<HashMap<String, Session>>,
    ttl: Duration,
}

impl Sessions {
    /// Sessions that end after `ttl` without use.
    pub(super) fn new(ttl: Duration) -> Self {
        Sessions {
            map: Mutex::new(HashMap::new()),
            ttl,
        }
    }

    /// Start a session for `user`: the cookie value and the session.
    pub(super) fn create(&self, user: &str) -> (String, Session) {
        let value = random_hex(32);
        let session = Session {
            user: user.to_string(),
            csrf: random_hex(32),
            expires: Instant::now() + self.ttl,
        };
        let mut map = self.map.lock().unwrap_or_else(|p| p.into_inner());
        if map.len() >= MAX_SESSIONS {
            let now = Instant::now();
            map.retain(|_, s| s.expires > now);
            if map.len() >= MAX_SESSIONS {
                if let Some(oldest) = map
                    .iter()
                    .min_by_key(|(_, s)| s.expires)
                    .map(|(k, _)| k.clone())
                {
                    map.remove(&oldest);
                }
            }
        }
        map.insert(token_hash(&value), session.clone());
        (value, session)
    }

    /// The live session of this cookie value (its life extended).
    pub(super) fn get(&self, value: &str) -> Option<Session> {
        let mut map = self.map.lock().unwrap_or_else(|p| p.into_inner());
        let key = token_hash(value);
        let now = Instant::now();
        match map.get_mut(&key) {
            Some(s) if s.expires > now => {
                s.expires = now + self.ttl;
                Some(s.clone())
            }
            Some(_) => {
                map.remove(&key);
                None
            }
            None => None,
        }
    }

    /// End the session of this cookie value.
    pub(super) fn end(&self, value: &str) {
        let mut map = self.map.lock().unwrap_or_else(|p| p.into_inner());
        map.remove(&token_hash(value));
    }
}

/// Failed logins per client address and per user name, in fixed windows
/// of a minute.
#[derive(Debug)]
pub(super) struct LoginLimiter {
    per_minute: u32,
    failures: Mutex<HashMap<String, (Instant, u32)>>,
}

impl LoginLimiter {
    /// At most `per_minute` failures per key and minute.
    pub(super) fn new(per_minute: u32) -> Self {
        LoginLimiter {
            per_minute: per_minute.max(1),
            failures: Mutex::new(HashMap::new()),
        }
    }

    /// `Err(seconds to wait)` when any of `keys` used up its failures.
    pub(super) fn check(&self, keys: &[String]) -> Result<(), u64> {
        let map = self.failures.lock().unwrap_or_else(|p| p.into_inner());
        let now = Instant::now();
        let wait = keys
            .iter()
            .filter_map(|k| map.get(k))
            .filter(|(start, n)| *n >= self.per_minute && now < *start + LOGIN_WINDOW)
            .map(|(start, _)| (*start + LOGIN_WINDOW - now).as_secs() + 1)
            .max();
        wait.map_or(Ok(()), Err)
    }

    /// Count a failed login against each of `keys`.
    pub(super) fn failed(&self, keys: &[String]) {
        let mut map = self.failures.lock().unwrap_or_else(|p| p.into_inner());
        let now = Instant::now();
        if map.len() >= MAX_LIMITED_KEYS {
            map.retain(|_, (start, _)| now < *start + LOGIN_WINDOW);
        }
        for key in keys {
            let entry = map.entry(key.clone()).or_insert((now, 0));
            if now >= entry.0 + LOGIN_WINDOW {
                *entry = (now, 0);
            }
            entry.1 = entry.1.saturating_add(1);
        }
    }
}

/// Who sent a request.
#[derive(Debug, Clone)]
pub(super) enum Identity {
    /// No credentials.
    Anonymous,
    /// A browser logged in with a session cookie.
    Session(Session),
    /// A script with an API token.
    Token {
        /// The token's curator.
        user: String,
    },
}

impl Identity {
    /// The curator, if any.
    pub(super) fn user(&self) -> Option<&str> {
        match self {
            Identity::Anonymous => None,
            Identity::Session(s) => Some(&s.user),
            Identity::Token { user } => Some(user),
        }
    }

    /// The CSRF token forms of this identity carry (sessions only).
    pub(super) fn csrf(&self) -> Option<&str> {
        match self {
            Identity::Session(s) => Some(&s.csrf),
            _ => None,
        }
    }
}

/// The value of the cookie `name` in the request's `Cookie` headers.
pub(super) fn cookie(headers: &HeaderMap, name: &str) -> Option<String> {
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(';'))
        .filter_map(|pair| pair.trim().split_once('='))
        .find(|(k, _)| *k == name)
        .map(|(_, v)| v.trim_matches('"').to_string())
}

/// A `Set-Cookie` value: HttpOnly, SameSite=Strict, `Secure` when served
/// over TLS; `max_age` 0 deletes it.
pub(super) fn set_cookie(
    name: &str,
    value: &str,
    path: &str,
    max_age: u64,
    secure: bool,
) -> String {
    format!(
        "{name}={value}; Path={path}; Max-Age={max_age}; HttpOnly; SameSite=Strict{}",
        if secure { "; Secure" } else { "" }
    )
}

/// Who sent the request: an API token in `Authorization: Bearer` (a wrong
/// one is refused, never taken as anonymous), else a session cookie (of a
/// curator who still exists), else anonymous.
pub(super) async fn identify(
    state: &Arc<AppState>,
    headers: &HeaderMap,
) -> Result<Identity, ApiError> {
    if let Some(auth) = headers.get(header::AUTHORIZATION) {
        let token = auth
            .to_str()
            .ok()
            .and_then(|v| v.strip_prefix("Bearer "))
            .map(str::trim)
            .filter(|t| !t.is_empty())
            .ok_or_else(|| {
                ApiError::Unauthorized("Authorization must be `Bearer <token>`".into())
            })?;
        let hash = token_hash(token);
        let user = state
            .pool
            .run(move |store| store.curator_of_token(&hash))
            .await?;
        return match user {
            Some(user) => Ok(Identity::Token { user }),
            None => Err(ApiError::Unauthorized("unknown API token".into())),
        };
    }
    if let Some(value) = cookie(headers, SESSION_COOKIE) {
        if let Some(session) = state.sessions.get(&value) {
            // A curator removed meanwhile is logged out.
            let user = session.user.clone();
            if state
                .pool
                .run(move |store| store.curator_exists(&user))
                .await?
            {
                return Ok(Identity::Session(session));
            }
            state.sessions.end(&value);
        }
    }
    Ok(Identity::Anonymous)
}

/// Refuse a read by someone who may not read (`public_read` off and no
/// curator).
pub(super) fn may_read(state: &AppState, identity: &Identity) -> Result<(), ApiError> {
    if state.settings.public_read || identity.user().is_some() {
        Ok(())
    } else {
        Err(ApiError::Unauthorized(
            "log in or send an API token (`[http] public_read` is off)".into(),
        ))
    }
}

/// The curator allowed to write: a token's, or a session's whose CSRF
/// token `csrf` carries.
pub(super) fn writer<'a>(identity: &'a Identity, csrf: Option<&str>) -> Result<&'a str, ApiError> {
    match identity {
        Identity::Anonymous => Err(ApiError::Unauthorized(
            "a change needs a logged-in curator or an API token".into(),
        )),
        Identity::Token { user } => Ok(user),
        Identity::Session(s) => match csrf {
            Some(c) if same_secret(c, &s.csrf) => Ok(&s.user),
            _ => Err(ApiError::Forbidden(
                "missing or wrong CSRF token (reload the page)".into(),
            )),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_password_matches_its_hash_only() {
        let hash = hash_password("correct horse").unwrap();
        assert!(hash.starts_with("$argon2id$"), "{hash}");
        assert!(verify_password("correct horse", &hash));
        assert!(!verify_password("correct horsf", &hash));
        assert!(!verify_password("correct horse", "not a hash"));
        assert!(matches!(hash_password("short"), Err(PasswordError::Length)));
    }

    #[test]
    fn failed_logins_past_the_limit_wait_for_the_window() {
        let limiter = LoginLimiter::new(2);
        let keys = vec!["ip:1".to_string()];
        assert!(limiter.check(&keys).is_ok());
        limiter.failed(&keys);
        assert!(limiter.check(&keys).is_ok());
        limiter.failed(&keys);
        let wait = limiter.check(&keys).unwrap_err();
        assert!((1..=61).contains(&wait), "{wait}");
        assert!(limiter.check(&["ip:2".to_string()]).is_ok());
    }

    #[test]
    fn cookies_are_found_by_name() {
        let mut h = HeaderMap::new();
        h.insert(
            header::COOKIE,
            "a=1; morphoid_session=xyz; b=2".parse().unwrap(),
        );
        assert_eq!(cookie(&h, SESSION_COOKIE).as_deref(), Some("xyz"));
        assert_eq!(cookie(&h, "c"), None);
        assert!(same_secret("abc", "abc") && !same_secret("abc", "abd") && !same_secret("a", "ab"));
    }
}
