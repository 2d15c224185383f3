//! Claiming one particular scan (for `morphoid classify`, which identifies
//! the files it was given, not whatever happens to be queued).

use super::{now_ms, Job, Store, StoreError};
use rusqlite::OptionalExtension;

impl Store {
    /// Mark the pending scan `scan_id` running and return it as a job;
    /// `None` when it is not pending (someone else took it, or it is done).
    pub fn claim(&mut self, scan_id: i64) -> Result<Option<Job>, StoreError> {
        let row = self
            .conn
            .query_row(
                "UPDATE scan SET status = 'running', started_at = ?1, attempts = attempts + 1
                 WHERE id = ?2 AND status = 'pending'
                 RETURNING path, content_hash, size, attempts",
                rusqlite::params![now_ms(), scan_id],
                |r| {
                    Ok((
                        r.get::<_, String>(0)?,
                        r.get::<_, String>(1)?,
                        r.get::<_, i64>(2)?,
                        r.get::<_, i64>(3)?,
                    ))
                },
            )
            .optional()?;
        let Some((path, content_hash, size, attempts)) = row else {
            return Ok(None);
        };
        Ok(Some(Job {
            scan_id,
            path,
            content_hash,
            size: u64::try_from(size).map_err(|_| StoreError::OutOfRange("scan.size"))?,
            attempts: u32::try_from(attempts).unwrap_or(u32::MAX),
        }))
    }
}
