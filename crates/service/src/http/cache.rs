//! Answers of the console's busiest reads (the overview's rows, a page of
//! `GET /api/v1/scans`), kept until the database changes. Querying and
//! drawing a page of a 100,000-scan database costs about 3 ms of CPU; two
//! hundred open overviews asking again would take the cores
//! identification needs, although the answer changes only when a scan or
//! a decision is recorded.
//!
//! An answer is tagged with the database's generation: the file's device
//! and inode, and SQLite's `data_version` as seen by a connection of the
//! cache's own that never writes, so that any commit by any other
//! connection (the daemon, `morphoid review` in another process) changes
//! it. An answer of an older generation is still given for [`FRESH_FOR`]
//! after it was made: while scans are identified the daemon commits
//! several times a second, and each key would otherwise be computed again
//! for almost every request. The console's own writes forget every answer
//! at once, so that a curator sees their decision. Requests for the same
//! key at the same moment share one computation.

use super::error::ApiError;
use crate::store::Store;
use std::collections::HashMap;
use std::future::Future;
use std::os::unix::fs::MetadataExt as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::OnceCell;

/// How long an answer is given after the database changed. The live
/// overview asks again on the poll after a change, so that it never stays
/// behind.
pub(super) const FRESH_FOR: Duration = Duration::from_millis(800);

/// How long a reading of the database's generation is used before it is
/// read again (at most `fresh_for`): a `stat` and a pragma on the blocking
/// pool for every request cost a thread hand-off each, which under two
/// hundred connections was a large part of the console's CPU. With
/// [`FRESH_FOR`] and the time to draw a page, the lists are about 1 s
/// behind the daemon at most.
const GENERATION_READ_EVERY: Duration = Duration::from_millis(100);

/// Keys kept at most: beyond that, answers of older generations go first,
/// then all.
const MAX_ENTRIES: usize = 512;

/// The database's state an answer was computed from: device, inode and
/// `data_version`.
type Generation = (u64, u64, i64);

/// One key's answer, of one generation.
#[derive(Debug)]
struct Entry {
    generation: Generation,
    /// When it was asked for first.
    made: Instant,
    /// The console's writes before it ([`AnswerCache::forget`]).
    epoch: u64,
    answer: Arc<OnceCell<Arc<str>>>,
    /// The key's last answer before this generation's (of the same
    /// epoch): given while this one is computed.
    previous: Option<Arc<str>>,
    /// Whether this generation's answer is being computed.
    computing: Arc<AtomicBool>,
}

/// What [`AnswerCache::cell`] gives for a key: its entry's cell, the
/// answer to give meanwhile, and the flag of a computation under way.
struct Slot {
    answer: Arc<OnceCell<Arc<str>>>,
    previous: Option<Arc<str>>,
    computing: Arc<AtomicBool>,
}

/// Answers by key, each valid for one generation of the database.
#[derive(Debug)]
pub(super) struct AnswerCache {
    path: PathBuf,
    /// The connection that reads `data_version`, with the identity of the
    /// file it has open.
    watch: Mutex<Option<(Store, (u64, u64))>>,
    entries: Mutex<HashMap<String, Entry>>,
    /// How long an answer outlives a change ([`FRESH_FOR`]).
    fresh_for: Duration,
    /// Counts the console's own writes.
    epoch: AtomicU64,
    /// The last reading of the generation, and when it was taken.
    last_generation: Mutex<Option<(Instant, Generation)>>,
}

/// Device and inode of the file at `path`.
fn file_identity(path: &Path) -> Option<(u64, u64)> {
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

impl AnswerCache {
    /// A cache of answers read from the database at `path`, each given
    /// for `fresh_for` after the database changed.
    pub(super) fn new(path: &Path, fresh_for: Duration) -> Self {
        AnswerCache {
            path: path.to_path_buf(),
            watch: Mutex::new(None),
            entries: Mutex::new(HashMap::new()),
            fresh_for,
            epoch: AtomicU64::new(0),
            last_generation: Mutex::new(None),
        }
    }

    /// The console wrote to the database: no answer from before is given
    /// again.
    pub(super) fn forget(&self) {
        self.epoch.fetch_add(1, Ordering::SeqCst);
    }

    /// The database's generation now, or `None` when it cannot be read
    /// (then nothing is cached). Blocking, but short: a `stat` and a
    /// pragma that reads the shared-memory index.
    fn generation(&self) -> Option<Generation> {
        let now = file_identity(&self.path)?;
        let mut watch = self.watch.lock().unwrap_or_else(|p| p.into_inner());
        if watch.as_ref().is_none_or(|(_, identity)| *identity != now) {
            // A replaced file (the daemon put back a deleted database) is
            // watched afresh.
            *watch = Some((Store::open(&self.path).ok()?, now));
        }
        let (store, _) = watch.as_ref()?;
        match store.data_version() {
            Ok(version) => Some((now.0, now.1, version)),
            Err(_) => {
                *watch = None;
                None
            }
        }
    }

    /// The answer for `key` under the database's present generation:
    /// kept, or computed now by `compute` (requests for the same key at the
    /// same moment wait for one computation). When the key has an answer
    /// from before the last change, that one is given at once and the new
    /// one is computed in the background: under many connections a
    /// request never waits for a page to be drawn, and a list is at most
    /// one computation later than [`FRESH_FOR`] behind. An error is
    /// returned, never kept.
    pub(super) async fn answer<F, Fut>(
        self: &Arc<Self>,
        key: String,
        compute: F,
    ) -> Result<Arc<str>, ApiError>
    where
        F: FnOnce() -> Fut + Send + 'static,
        Fut: Future<Output = Result<String, ApiError>> + Send + 'static,
    {
        let Some(generation) = self.recent_generation().await else {
            return compute().await.map(Arc::from);
        };
        let slot = self.cell(key, generation);
        if let Some(done) = slot.answer.get() {
            return Ok(Arc::clone(done));
        }
        let Some(previous) = slot.previous else {
            return slot
                .answer
                .get_or_try_init(|| async { compute().await.map(Arc::from) })
                .await
                .cloned();
        };
        if !slot.computing.swap(true, Ordering::SeqCst) {
            let (cell, computing) = (slot.answer, slot.computing);
            tokio::spawn(async move {
                let made = cell
                    .get_or_try_init(|| async { compute().await.map(Arc::from) })
                    .await;
                if let Err(e) = made {
                    // The next request tries again; until then the answer
                    // from before is given.
                    tracing::debug!("http: a kept answer could not be renewed: {e}");
                    computing.store(false, Ordering::SeqCst);
                }
            });
        }
        Ok(previous)
    }

    /// The database's generation as read less than
    /// [`GENERATION_READ_EVERY`] (and `fresh_for`) ago, else read now on
    /// the blocking pool.
    async fn recent_generation(self: &Arc<Self>) -> Option<Generation> {
        let reuse_for = GENERATION_READ_EVERY.min(self.fresh_for);
        let last = *self
            .last_generation
            .lock()
            .unwrap_or_else(|p| p.into_inner());
        if let Some((read, generation)) = last {
            if read.elapsed() < reuse_for {
                return Some(generation);
            }
        }
        let cache = Arc::clone(self);
        let read = Instant::now();
        let generation = tokio::task::spawn_blocking(move || cache.generation())
            .await
            .ok()
            .flatten();
        let mut last = self
            .last_generation
            .lock()
            .unwrap_or_else(|p| p.into_inner());
        *last = generation.map(|g| (read, g));
        generation
    }

    /// The cell holding `key`'s answer of `generation`, or of an earlier
    /// one made less than `fresh_for` ago and after the console's last
    /// write; else a new, empty one, with the key's last answer of the
    /// same epoch to give meanwhile.
    fn cell(&self, key: String, generation: Generation) -> Slot {
        let epoch = self.epoch.load(Ordering::SeqCst);
        let mut entries = self.entries.lock().unwrap_or_else(|p| p.into_inner());
        let mut previous = None;
        if let Some(entry) = entries.get(&key) {
            let fresh = entry.epoch == epoch && entry.made.elapsed() < self.fresh_for;
            if (entry.generation == generation && entry.epoch == epoch) || fresh {
                return Slot {
                    answer: Arc::clone(&entry.answer),
                    previous: entry.previous.clone(),
                    computing: Arc::clone(&entry.computing),
                };
            }
            // (A cache allowed no delay gives none.)
            if entry.epoch == epoch && !self.fresh_for.is_zero() {
                previous = entry.answer.get().cloned().or(entry.previous.clone());
            }
        }
        if entries.len() >= MAX_ENTRIES {
            entries.retain(|_, e| e.generation == generation);
            if entries.len() >= MAX_ENTRIES {
                entries.clear();
            }
        }
        let answer = Arc::new(OnceCell::new());
        let computing = Arc::new(AtomicBool::new(false));
        entries.insert(
            key,
            Entry {
                generation,
                made: Instant::now(),
                epoch,
                answer: Arc::clone(&answer),
                previous: previous.clone(),
                computing: Arc::clone(&computing),
            },
        );
        Slot {
            answer,
            previous,
            computing,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    fn runtime() -> tokio::runtime::Runtime {
        tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()
            .unwrap()
    }

    /// `cache.answer("k")`, counting computations in `computed`.
    fn ask(cache: &Arc<AnswerCache>, computed: &Arc<AtomicUsize>) -> String {
        let computed = Arc::clone(computed);
        let answer = runtime().block_on(cache.answer("k".into(), move || async move {
            let n = computed.fetch_add(1, Ordering::SeqCst) + 1;
            Ok(format!("answer {n}"))
        }));
        answer.unwrap().to_string()
    }

    #[test]
    fn an_answer_outlives_a_change_for_its_time_but_not_the_consoles_own_write() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("ids.sqlite");
        let mut writer = Store::open(&db).unwrap();
        let cache = Arc::new(AnswerCache::new(&db, Duration::from_secs(3600)));
        let computed = Arc::new(AtomicUsize::new(0));
        assert_eq!(ask(&cache, &computed), "answer 1");
        writer.enqueue("/scans/a.ply", "00aa", 1).unwrap();
        assert_eq!(ask(&cache, &computed), "answer 1");
        cache.forget();
        assert_eq!(ask(&cache, &computed), "answer 2");
        assert_eq!(ask(&cache, &computed), "answer 2");
    }

    #[test]
    fn an_answer_is_kept_until_another_connection_commits() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("ids.sqlite");
        let mut writer = Store::open(&db).unwrap();
        let cache = Arc::new(AnswerCache::new(&db, Duration::ZERO));
        let computed = Arc::new(AtomicUsize::new(0));
        assert_eq!(ask(&cache, &computed), "answer 1");
        assert_eq!(ask(&cache, &computed), "answer 1");
        writer.enqueue("/scans/a.ply", "00aa", 1).unwrap();
        assert_eq!(ask(&cache, &computed), "answer 2");
        assert_eq!(ask(&cache, &computed), "answer 2");
    }

    #[test]
    fn after_a_change_the_answer_from_before_is_given_while_the_new_one_is_computed() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("ids.sqlite");
        let mut writer = Store::open(&db).unwrap();
        let fresh_for = Duration::from_millis(50);
        let cache = Arc::new(AnswerCache::new(&db, fresh_for));
        let computed = Arc::new(AtomicUsize::new(0));
        let rt = runtime();
        let ask = || {
            let computed = Arc::clone(&computed);
            rt.block_on(cache.answer("k".into(), move || async move {
                tokio::time::sleep(Duration::from_secs(1)).await;
                let n = computed.fetch_add(1, Ordering::SeqCst) + 1;
                Ok(format!("answer {n}"))
            }))
            .unwrap()
            .to_string()
        };
        assert_eq!(ask(), "answer 1");
        writer.enqueue("/scans/a.ply", "00aa", 1).unwrap();
        std::thread::sleep(fresh_for * 3);
        // Given at once, although the new answer takes 1 s.
        let asked = Instant::now();
        assert_eq!(ask(), "answer 1");
        assert!(asked.elapsed() < Duration::from_millis(500));
        let renewed = (0..500).any(|_| {
            std::thread::sleep(Duration::from_millis(20));
            ask() == "answer 2"
        });
        assert!(renewed, "the new answer never came");
        // One computation, however many requests came meanwhile.
        assert_eq!(computed.load(Ordering::SeqCst), 2);
        // The console's own write is never answered from before.
        cache.forget();
        assert_eq!(ask(), "answer 3");
    }

    #[test]
    fn requests_at_the_same_moment_share_one_computation_and_errors_are_not_kept() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("ids.sqlite");
        Store::open(&db).unwrap();
        let cache = Arc::new(AnswerCache::new(&db, FRESH_FOR));
        let computed = Arc::new(AtomicUsize::new(0));
        let rt = runtime();
        let answers: Vec<_> = rt.block_on(async {
            let tasks: Vec<_> = (0..20)
                .map(|_| {
                    let (cache, computed) = (Arc::clone(&cache), Arc::clone(&computed));
                    tokio::spawn(async move {
                        cache
                            .answer("k".into(), move || async move {
                                computed.fetch_add(1, Ordering::SeqCst);
                                tokio::time::sleep(std::time::Duration::from_millis(50)).await;
                                Ok("shared".to_string())
                            })
                            .await
                    })
                })
                .collect();
            let mut out = Vec::new();
            for t in tasks {
                out.push(t.await.unwrap().unwrap());
            }
            out
        });
        assert!(answers.iter().all(|a| &**a == "shared"));
        assert_eq!(computed.load(Ordering::SeqCst), 1);

        let failed = rt.block_on(cache.answer("e".into(), || async {
            Err(ApiError::BadRequest("no".into()))
        }));
        assert!(failed.is_err());
        let again = rt.block_on(cache.answer("e".into(), || async { Ok("now".to_string()) }));
        assert_eq!(&*again.unwrap(), "now");
    }
}
