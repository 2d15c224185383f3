//! The reference library as recorded: one row per version (name +
//! content) of each specimen, so that recorded distances stay attached to
//! the content they were measured on.

use super::{
    from_json, now_ms, to_json, Labels, ReferenceRecord, ReferenceState, Store, StoreError,
};
use rusqlite::{params, OptionalExtension, Row, TransactionBehavior};

/// The condition of a current version (not superseded, not removed).
const CURRENT: &str = "state NOT IN ('superseded', 'removed')";

impl Store {
    /// Register reference `name` with the given content and labels, as the
    /// current version of that name. Same name and content: labels updated,
    /// state kept (a removed one becomes pending again). New content: a new
    /// pending row, and the previous version is marked superseded (its
    /// recorded distances stay attached to the content they were measured
    /// on). Returns the row id.
    pub fn register_reference(
        &mut self,
        name: &str,
        content_hash: &str,
        labels: &Labels,
    ) -> Result<i64, StoreError> {
        let labels_json = to_json("reference.labels", labels)?;
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let id = register_in(&tx, name, content_hash, &labels_json)?;
        tx.commit()?;
        Ok(id)
    }

    /// Record a prepared library at once: each of `references` (name,
    /// content hash, labels) registered as [`Store::register_reference`]
    /// and marked prepared as [`Store::mark_reference_prepared`] do, and
    /// every other current reference marked removed. One transaction, so
    /// that a library of thousands is recorded in one write, and a reader
    /// never sees half of it.
    pub fn record_prepared_library(
        &mut self,
        references: &[(&str, &str, Labels)],
    ) -> Result<(), StoreError> {
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let now = now_ms();
        for (name, content_hash, labels) in references {
            let labels_json = to_json("reference.labels", labels)?;
            let id = register_in(&tx, name, content_hash, &labels_json)?;
            tx.execute(
                "UPDATE reference SET state = 'prepared', error = NULL, prepared_at = ?2
                 WHERE id = ?1",
                params![id, now],
            )?;
        }
        let keep: Vec<&str> = references.iter().map(|(name, _, _)| *name).collect();
        remove_except_in(&tx, &keep)?;
        tx.commit()?;
        Ok(())
    }

    /// Mark the current version of `name` prepared (now).
    pub fn mark_reference_prepared(&mut self, name: &str) -> Result<(), StoreError> {
        let n = self.conn.execute(
            &format!(
                "UPDATE reference SET state = 'prepared', error = NULL, prepared_at = ?2
                 WHERE name = ?1 AND {CURRENT}"
            ),
            params![name, now_ms()],
        )?;
        one_reference_updated(n, name)
    }

    /// Mark the current version of `name` failed, with the reason.
    pub fn mark_reference_failed(&mut self, name: &str, message: &str) -> Result<(), StoreError> {
        let n = self.conn.execute(
            &format!(
                "UPDATE reference SET state = 'failed', error = ?2 WHERE name = ?1 AND {CURRENT}"
            ),
            params![name, message],
        )?;
        one_reference_updated(n, name)
    }

    /// Mark every current reference whose name is not in `keep` removed
    /// (its mesh left the library folder). Returns how many were removed.
    pub fn remove_references_except(&mut self, keep: &[&str]) -> Result<usize, StoreError> {
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let n = remove_except_in(&tx, keep)?;
        tx.commit()?;
        Ok(n)
    }

    /// The current references (not superseded, not removed), by name.
    pub fn references(&self) -> Result<Vec<ReferenceRecord>, StoreError> {
        let mut stmt = self.conn.prepare(&format!(
            "SELECT id, name, content_hash, labels, state, error, added_at, prepared_at
             FROM reference WHERE {CURRENT} ORDER BY name"
        ))?;
        let mut rows = stmt.query([])?;
        let mut out = Vec::new();
        while let Some(row) = rows.next()? {
            out.push(reference_from_row(row)?);
        }
        Ok(out)
    }
}

/// A `reference` row as a record.
fn reference_from_row(r: &Row<'_>) -> Result<ReferenceRecord, StoreError> {
    let state: String = r.get("state")?;
    let labels: String = r.get("labels")?;
    Ok(ReferenceRecord {
        id: r.get("id")?,
        name: r.get("name")?,
        content_hash: r.get("content_hash")?,
        labels: from_json("reference.labels", &labels)?,
        state: ReferenceState::parse(&state)
            .ok_or_else(|| StoreError::Corrupt(format!("reference state {state:?}")))?,
        error: r.get("error")?,
        added_at_ms: r.get("added_at")?,
        prepared_at_ms: r.get("prepared_at")?,
    })
}

/// An update of the current version of `name` that changed `n` rows:
/// none means the store has no such reference.
fn one_reference_updated(n: usize, name: &str) -> Result<(), StoreError> {
    if n == 0 {
        return Err(StoreError::UnknownReference(name.to_string()));
    }
    Ok(())
}

/// [`Store::register_reference`] inside the transaction `tx`.
fn register_in(
    tx: &rusqlite::Transaction<'_>,
    name: &str,
    content_hash: &str,
    labels_json: &str,
) -> Result<i64, StoreError> {
    tx.execute(
        &format!(
            "UPDATE reference SET state = 'superseded'
             WHERE name = ?1 AND content_hash <> ?2 AND {CURRENT}"
        ),
        params![name, content_hash],
    )?;
    let existing: Option<(i64, String)> = tx
        .query_row(
            "SELECT id, state FROM reference WHERE name = ?1 AND content_hash = ?2",
            params![name, content_hash],
            |r| Ok((r.get("id")?, r.get("state")?)),
        )
        .optional()?;
    Ok(match existing {
        Some((id, state)) => {
            let revived = if state == "superseded" || state == "removed" {
                "pending"
            } else {
                state.as_str()
            };
            tx.execute(
                "UPDATE reference SET labels = ?2, state = ?3 WHERE id = ?1",
                params![id, labels_json, revived],
            )?;
            id
        }
        None => {
            tx.execute(
                "INSERT INTO reference (name, content_hash, labels, state, added_at)
                 VALUES (?1, ?2, ?3, 'pending', ?4)",
                params![name, content_hash, labels_json, now_ms()],
            )?;
            tx.last_insert_rowid()
        }
    })
}

/// [`Store::remove_references_except`] inside the transaction `tx`.
fn remove_except_in(tx: &rusqlite::Transaction<'_>, keep: &[&str]) -> Result<usize, StoreError> {
    tx.execute_batch("CREATE TEMP TABLE IF NOT EXISTS keep_name (name TEXT PRIMARY KEY)")?;
    tx.execute("DELETE FROM temp.keep_name", [])?;
    {
        let mut insert = tx.prepare("INSERT OR IGNORE INTO temp.keep_name (name) VALUES (?1)")?;
        for name in keep {
            insert.execute([name])?;
        }
    }
    let n = tx.execute(
        &format!(
            "UPDATE reference SET state = 'removed'
             WHERE {CURRENT} AND name NOT IN (SELECT name FROM temp.keep_name)"
        ),
        [],
    )?;
    tx.execute("DELETE FROM temp.keep_name", [])?;
    Ok(n)
}
