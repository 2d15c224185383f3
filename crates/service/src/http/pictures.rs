//! The pictures and the 3D view of a scan's report in the console: the
//! scene drawn again from the scan's file by the daemon's own library
//! (`Classifier::scene_of_record`). The file is the one the scan's record
//! names, never a path from the request, and it must still hold the
//! identified content. Drawing prepares the scan again (about a second),
//! so it runs on the console's blocking threads one scene at a time, and
//! the last few scenes shown are kept.

use crate::classify::{Classifier, SceneError};
use crate::report::Scene;
use crate::store::ScanRecord;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use tokio::sync::Semaphore;

/// Scenes kept: a curator going back and forth between a few reports.
const KEPT: usize = 8;

/// A scan's scene is the same while the scan and its content are.
type Key = (i64, String);

/// Why a report's pictures are not drawn; the message is the report's
/// note.
#[derive(Debug, thiserror::Error)]
pub(super) enum NoPictures {
    /// The console runs without a daemon, so it has no library to draw
    /// with.
    #[error(
        "no daemon runs with this console, so the pictures are not drawn; \
         `morphoid report SCAN_ID` draws them"
    )]
    NoDaemon,
    /// The server is stopping (no more turns to draw are given).
    #[error("the server is stopping")]
    Stopping(#[source] tokio::sync::AcquireError),
    /// The drawing task failed (it panicked, or was cancelled).
    #[error("drawing failed: {0}")]
    Drawing(#[source] tokio::task::JoinError),
    /// The scene cannot be drawn again (the file is gone or changed, or
    /// preparing it failed).
    #[error(transparent)]
    Scene(#[from] SceneError),
}

/// Scenes drawn, one at a time, and the last [`KEPT`] of them.
#[derive(Debug)]
pub(super) struct Pictures {
    drawing: Semaphore,
    kept: Mutex<VecDeque<(Key, Arc<Scene>)>>,
}

impl Pictures {
    /// None drawn yet.
    pub(super) fn new() -> Self {
        Pictures {
            drawing: Semaphore::new(1),
            kept: Mutex::new(VecDeque::new()),
        }
    }

    /// The scene of `record`, drawn with `classifier`; or why there is
    /// none (its message is the report's note).
    pub(super) async fn scene(
        &self,
        classifier: Option<Arc<Classifier>>,
        record: &ScanRecord,
    ) -> Result<Arc<Scene>, NoPictures> {
        let Some(classifier) = classifier else {
            return Err(NoPictures::NoDaemon);
        };
        let key = (record.id, record.content_hash.clone());
        if let Some(scene) = self.kept(&key) {
            return Ok(scene);
        }
        let _turn = self.drawing.acquire().await.map_err(NoPictures::Stopping)?;
        // Drawn while this request waited its turn?
        if let Some(scene) = self.kept(&key) {
            return Ok(scene);
        }
        let owned = record.clone();
        let drawn = tokio::task::spawn_blocking(move || classifier.scene_of_record(&owned))
            .await
            .map_err(NoPictures::Drawing)??;
        let scene = Arc::new(drawn);
        let mut kept = self.kept.lock().unwrap_or_else(|p| p.into_inner());
        if kept.len() >= KEPT {
            kept.pop_front();
        }
        kept.push_back((key, Arc::clone(&scene)));
        Ok(scene)
    }

    /// The kept scene of `key`.
    fn kept(&self, key: &Key) -> Option<Arc<Scene>> {
        let kept = self.kept.lock().unwrap_or_else(|p| p.into_inner());
        kept.iter()
            .find(|(k, _)| k == key)
            .map(|(_, s)| Arc::clone(s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_notes_read_as_before() {
        assert_eq!(
            NoPictures::NoDaemon.to_string(),
            "no daemon runs with this console, so the pictures are not drawn; `morphoid \
             report SCAN_ID` draws them"
        );
        let runtime = tokio::runtime::Builder::new_current_thread()
            .build()
            .unwrap();
        let closed = Semaphore::new(1);
        closed.close();
        let stopping = runtime.block_on(closed.acquire()).map(|_| ()).unwrap_err();
        assert_eq!(
            NoPictures::Stopping(stopping).to_string(),
            "the server is stopping"
        );
    }
}
