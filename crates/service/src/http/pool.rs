//! The console's own connections to the daemon's database: a few kept
//! open and reused, each used by one blocking task at a time (SQLite calls
//! block; they never run on the runtime's worker threads). WAL mode lets
//! them read while the daemon writes. A connection to a file that is no
//! longer the one at the path (the daemon put back a deleted database, or
//! it was replaced) is dropped, so the console follows the daemon's file.

use super::error::ApiError;
use crate::store::Store;
use std::os::unix::fs::MetadataExt as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::Semaphore;

/// How long a console write waits for the daemon's lock: the daemon's
/// transactions are short.
const BUSY_TIMEOUT: Duration = Duration::from_secs(5);

/// Device and inode of a file.
type Identity = (u64, u64);

/// A bounded set of connections to one database file.
#[derive(Debug)]
pub(super) struct ReadPool {
    path: PathBuf,
    idle: Mutex<Vec<(Store, Identity)>>,
    permits: Semaphore,
}

/// Device and inode of the file at `path`.
fn identity_of(path: &Path) -> Option<Identity> {
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

impl ReadPool {
    /// A pool of at most `size` connections to the database at `path`
    /// (opened when first needed).
    pub(super) fn new(path: &Path, size: usize) -> Self {
        ReadPool {
            path: path.to_path_buf(),
            idle: Mutex::new(Vec::new()),
            permits: Semaphore::new(size.max(1)),
        }
    }

    /// Run `work` on a connection, on the blocking pool; waits while every
    /// connection is in use.
    pub(super) async fn run<T, E>(
        self: &Arc<Self>,
        work: impl FnOnce(&mut Store) -> Result<T, E> + Send + 'static,
    ) -> Result<T, ApiError>
    where
        T: Send + 'static,
        E: Into<ApiError> + Send + 'static,
    {
        let _permit = self
            .permits
            .acquire()
            .await
            .map_err(|_| ApiError::Unavailable("the server is stopping".into()))?;
        let pool = Arc::clone(self);
        let joined = tokio::task::spawn_blocking(move || {
            let (mut store, identity) = pool.take()?;
            let out = work(&mut store).map_err(Into::into);
            // A connection whose storage failed is not kept: the next use
            // opens the file afresh.
            if !matches!(out, Err(ApiError::Unavailable(_))) {
                pool.give_back(store, identity);
            }
            out
        })
        .await;
        joined.map_err(|e| ApiError::Internal(format!("database task failed: {e}")))?
    }

    /// An idle connection to the file now at the path, or a new one.
    fn take(&self) -> Result<(Store, Identity), ApiError> {
        let now = identity_of(&self.path);
        {
            let mut idle = self.idle.lock().unwrap_or_else(|p| p.into_inner());
            while let Some((store, identity)) = idle.pop() {
                if Some(identity) == now {
                    return Ok((store, identity));
                }
            }
        }
        let mut store = Store::open(&self.path)?;
        store.set_busy_timeout(BUSY_TIMEOUT)?;
        let identity = identity_of(&self.path)
            .ok_or_else(|| ApiError::Unavailable(format!("{} vanished", self.path.display())))?;
        tracing::debug!("http: opened a connection to {}", self.path.display());
        Ok((store, identity))
    }

    fn give_back(&self, store: Store, identity: Identity) {
        let mut idle = self.idle.lock().unwrap_or_else(|p| p.into_inner());
        idle.push((store, identity));
    }
}
