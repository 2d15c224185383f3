//! The web console's curators and their API tokens (migration 8). The
//! store keeps what it is given: the password's argon2 hash (a PHC string)
//! and each token's SHA-256; hashing and checking are `crate::http`'s.

use super::{now_ms, Store, StoreError};
use rusqlite::{params, OptionalExtension, TransactionBehavior};
use serde::Serialize;

/// Longest curator name.
pub(super) const MAX_NAME_CHARS: usize = 64;

/// Why a curator or a token could not be added or removed.
#[derive(Debug, thiserror::Error)]
pub enum UserError {
    /// The name is empty, too long, or holds characters other than
    /// letters, digits, `.`, `_`, `-` and `@`.
    #[error(
        "{0:?} is not a valid user name (1 to {MAX_NAME_CHARS} letters, digits, '.', '_', '-' or '@')"
    )]
    InvalidName(String),
    /// A curator of that name exists.
    #[error("user {0:?} exists already")]
    Exists(String),
    /// No curator has that name.
    #[error("no user {0:?}")]
    NoSuchUser(String),
    /// The database failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

impl From<rusqlite::Error> for UserError {
    fn from(e: rusqlite::Error) -> Self {
        UserError::Store(e.into())
    }
}

/// A curator as listed (never the password hash).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct CuratorRecord {
    /// Login name.
    pub name: String,
    /// Added at (Unix milliseconds).
    pub created_at_ms: i64,
    /// API tokens issued to the curator.
    pub tokens: u32,
}

/// Whether `name` can be a curator's name: short, and made of characters
/// that need no quoting in a log line, an audit row or a cookie.
pub(super) fn valid_user_name(name: &str) -> bool {
    !name.is_empty()
        && name.chars().count() <= MAX_NAME_CHARS
        && name
            .chars()
            .all(|c| c.is_alphanumeric() || matches!(c, '.' | '_' | '-' | '@'))
}

impl Store {
    /// Add the curator `name` with the argon2 hash of their password.
    pub fn add_curator(&mut self, name: &str, password_hash: &str) -> Result<(), UserError> {
        if !valid_user_name(name) {
            return Err(UserError::InvalidName(name.to_string()));
        }
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let exists: bool = tx.query_row(
            "SELECT EXISTS (SELECT 1 FROM curator WHERE name = ?1)",
            [name],
            |r| r.get(0),
        )?;
        if exists {
            return Err(UserError::Exists(name.to_string()));
        }
        tx.execute(
            "INSERT INTO curator (name, password_hash, created_at) VALUES (?1, ?2, ?3)",
            params![name, password_hash, now_ms()],
        )?;
        tx.commit()?;
        Ok(())
    }

    /// Remove the curator `name` and their API tokens. Their decisions stay
    /// in the audit trail under their name.
    pub fn remove_curator(&mut self, name: &str) -> Result<(), UserError> {
        let n = self
            .conn
            .execute("DELETE FROM curator WHERE name = ?1", [name])?;
        if n == 0 {
            return Err(UserError::NoSuchUser(name.to_string()));
        }
        Ok(())
    }

    /// The curators, by name.
    pub fn curators(&self) -> Result<Vec<CuratorRecord>, StoreError> {
        let mut stmt = self.conn.prepare(
            "SELECT name, created_at,
                    (SELECT count(*) FROM api_token WHERE curator_id = curator.id) AS tokens
             FROM curator ORDER BY name",
        )?;
        let rows = stmt.query_map([], |r| {
            Ok(CuratorRecord {
                name: r.get("name")?,
                created_at_ms: r.get("created_at")?,
                tokens: u32::try_from(r.get::<_, i64>("tokens")?).unwrap_or(u32::MAX),
            })
        })?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// How many curators there are (a server on a non-loopback address
    /// needs one).
    pub fn curator_count(&self) -> Result<u64, StoreError> {
        let n: i64 = self
            .conn
            .query_row("SELECT count(*) FROM curator", [], |r| r.get(0))?;
        Ok(u64::try_from(n).unwrap_or(0))
    }

    /// The password hash of the curator `name` (`None`: no such curator).
    pub fn curator_password_hash(&self, name: &str) -> Result<Option<String>, StoreError> {
        Ok(self
            .conn
            .query_row(
                "SELECT password_hash FROM curator WHERE name = ?1",
                [name],
                |r| r.get(0),
            )
            .optional()?)
    }

    /// Whether the curator `name` exists.
    pub fn curator_exists(&self, name: &str) -> Result<bool, StoreError> {
        Ok(self.conn.query_row(
            "SELECT EXISTS (SELECT 1 FROM curator WHERE name = ?1)",
            [name],
            |r| r.get(0),
        )?)
    }

    /// Record an API token of the curator `name` by its hash.
    pub fn add_api_token(
        &mut self,
        name: &str,
        token_hash: &str,
        label: &str,
    ) -> Result<(), UserError> {
        let n = self.conn.execute(
            "INSERT INTO api_token (curator_id, token_hash, label, created_at)
             SELECT id, ?2, ?3, ?4 FROM curator WHERE name = ?1",
            params![name, token_hash, label, now_ms()],
        )?;
        if n == 0 {
            return Err(UserError::NoSuchUser(name.to_string()));
        }
        Ok(())
    }

    /// Remove every API token of the curator `name`; returns how many.
    pub fn revoke_api_tokens(&mut self, name: &str) -> Result<usize, UserError> {
        if !self.curator_exists(name)? {
            return Err(UserError::NoSuchUser(name.to_string()));
        }
        Ok(self.conn.execute(
            "DELETE FROM api_token WHERE curator_id = (SELECT id FROM curator WHERE name = ?1)",
            [name],
        )?)
    }

    /// The curator holding the token of this hash, if any.
    pub fn curator_of_token(&self, token_hash: &str) -> Result<Option<String>, StoreError> {
        Ok(self
            .conn
            .query_row(
                "SELECT curator.name FROM api_token JOIN curator ON curator.id = api_token.curator_id
                 WHERE api_token.token_hash = ?1",
                [token_hash],
                |r| r.get(0),
            )
            .optional()?)
    }
}

#[cfg(test)]
mod tests {
    use super::valid_user_name;

    #[test]
    fn user_names_are_short_and_plain() {
        assert!(valid_user_name("ana.lima-2@lab"));
        assert!(valid_user_name("Zoë"));
        for bad in ["", "a b", "x;y", "a\"b", "<script>", &"x".repeat(65)] {
            assert!(!valid_user_name(bad), "{bad:?}");
        }
    }
}
