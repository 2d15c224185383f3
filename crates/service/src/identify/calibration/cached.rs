//! The distances among a library's references, computed once and kept in
//! the library's cache folder, keyed by the references' names and content
//! hashes and by the preparation and comparison settings (both change the
//! distances), so a changed, added or removed reference or changed
//! settings compute them again.

use super::shard::CalibrationShardError;
use super::share::CalibrationTurn;
use super::{median_sample, ReferenceDistances};
use crate::identify::screened_references;
use morphoid_core::cp::{compare, ScreenParams, Signature};
use morphoid_data::atomic_write::write_atomic;
use morphoid_data::hash::hex;
use morphoid_data::library::{Cache, CachedReference};
use morphoid_data::pipeline::Settings;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::PathBuf;

/// Most references held out in the calibration: a larger library holds
/// out this many (those whose content hash sorts first, a fixed sample),
/// each compared with every reference, instead of every pair.
pub(crate) const CALIBRATION_SAMPLE: usize = 200;

/// Bumped whenever the file's layout or the meaning of the distances
/// changes (2: rows of a screened library leave NaN where no comparison
/// was made; each file names its references' content and its settings,
/// so that a changed library reuses what it can; 3: a library of more
/// than [`CALIBRATION_SAMPLE`] compares the median sample chosen by name).
const FORMAT: u32 = 3;

/// Formats whose distances a changed library may reuse: every cP distance
/// they hold is one this version computes (NaN where none was).
const REUSABLE_FORMATS: [u32; 2] = [2, FORMAT];

/// File name prefix and extension of the cached distances.
const PREFIX: &str = "calibration-";
const EXTENSION: &str = "dist";

/// [`Entry`] as written (the same layout, borrowed).
#[derive(Serialize)]
struct EntryOut<'a> {
    format: u32,
    key: &'a str,
    settings: &'a str,
    hashes: Vec<&'a str>,
    distances: &'a ReferenceDistances,
}

#[derive(Deserialize)]
struct Entry {
    format: u32,
    key: String,
    /// [`settings_key`] of the settings the distances were made with.
    settings: String,
    /// The content hash of each reference, in the order of the names.
    hashes: Vec<String>,
    distances: ReferenceDistances,
}

/// The distances an earlier calibration file holds, by the name and
/// content of both references: what a library that has changed since
/// (a reference added, removed or replaced) need not compute again.
#[derive(Default)]
pub(super) struct Known {
    index: std::collections::HashMap<(String, String), usize>,
    distances: Option<ReferenceDistances>,
}

impl Known {
    /// Each of `references`' index in the earlier file, if it is there
    /// with the same content (looked up once, not once per pair).
    fn indices(&self, references: &[CachedReference]) -> Vec<Option<usize>> {
        references
            .iter()
            .map(|r| {
                let key = (r.name().to_string(), r.content_hash().to_string());
                self.index.get(&key).copied()
            })
            .collect()
    }

    /// The distance between the earlier file's references `i` and `j`, if
    /// it has it.
    fn get(&self, i: Option<usize>, j: Option<usize>) -> Option<f64> {
        let (d, i, j) = (self.distances.as_ref()?, i?, j?);
        let row = |i: usize, j: usize| d.row(i).and_then(|r| r.get(j)).copied();
        [row(i, j), row(j, i)]
            .into_iter()
            .flatten()
            .find(|v| v.is_finite())
    }
}

/// Whether `name` is a calibration file's name.
fn is_calibration_file(name: &str) -> bool {
    name.starts_with(PREFIX) && name.ends_with(&format!(".{EXTENSION}"))
}

/// The key of the settings the distances depend on (not the re-cut of
/// crowns found on whole teeth: the references are crowns as given).
fn settings_key(settings: &Settings) -> String {
    let cp = &settings.cp;
    let params = serde_json::to_string(&(&settings.clean, &cp.prepare, &cp.compare, &cp.screen))
        .unwrap_or_default();
    hex(&Sha256::digest(params.as_bytes())[..16])
}

/// The distances of the calibration files in `cache` made with the same
/// settings (the newest, when several are there).
pub(super) fn known_distances(cache: &Cache, settings: &Settings) -> Known {
    let want = settings_key(settings);
    let Ok(entries) = std::fs::read_dir(cache.dir()) else {
        return Known::default();
    };
    let newest = entries
        .flatten()
        .filter(|e| is_calibration_file(&e.file_name().to_string_lossy()))
        .filter_map(|e| Some((e.metadata().ok()?.modified().ok()?, e.path())))
        .max();
    let Some(entry) = newest
        .and_then(|(_, path)| std::fs::read(path).ok())
        .and_then(|bytes| postcard::from_bytes::<Entry>(&bytes).ok())
        .filter(|e| REUSABLE_FORMATS.contains(&e.format) && e.settings == want)
        .filter(|e| e.hashes.len() == e.distances.names.len())
    else {
        return Known::default();
    };
    let index = entry
        .distances
        .names
        .iter()
        .cloned()
        .zip(entry.hashes.iter().cloned())
        .enumerate()
        .map(|(i, k)| (k, i))
        .collect();
    Known {
        index,
        distances: Some(entry.distances),
    }
}

/// The key of a library's distances: its references (name and content, in
/// order) and every setting the distances depend on.
pub(super) fn key(references: &[CachedReference], settings: &Settings) -> String {
    let mut h = Sha256::new();
    h.update(FORMAT.to_le_bytes());
    for r in references {
        h.update(r.name().as_bytes());
        h.update([0]);
        h.update(r.content_hash().as_bytes());
        h.update([0]);
    }
    h.update(settings_key(settings).as_bytes());
    hex(&h.finalize()[..16])
}

/// The references held out: all of them up to [`CALIBRATION_SAMPLE`], else
/// the sample whose content hashes sort first (ascending indices).
fn held_out(references: &[CachedReference]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..references.len()).collect();
    if order.len() > CALIBRATION_SAMPLE {
        order.sort_by(|&a, &b| {
            (&references[a].content_hash(), &references[a].name())
                .cmp(&(&references[b].content_hash(), &references[b].name()))
        });
        order.truncate(CALIBRATION_SAMPLE);
        order.sort_unstable();
    }
    order
}

/// The pairs (each unordered pair once, `i < j`) whose distances the
/// calibration reads: every pair with a held-out reference; in a library
/// that is screened and larger than [`CALIBRATION_SAMPLE`], only each
/// held-out reference with those the screen keeps for it and with the
/// median sample, as its identification would compare.
fn calibration_pairs_of(
    references: &[CachedReference],
    held: &[usize],
    settings: &Settings,
) -> Vec<(usize, usize)> {
    let n = references.len();
    let screen = &settings.cp.screen;
    if n <= CALIBRATION_SAMPLE || !screen.screens(n) {
        let is_held: Vec<bool> = (0..n).map(|i| held.binary_search(&i).is_ok()).collect();
        return (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .filter(|&(i, j)| is_held[i] || is_held[j])
            .collect();
    }
    let signatures: Vec<Signature> = references.iter().map(|r| r.signature().clone()).collect();
    let names: Vec<&str> = references.iter().map(|r| r.name()).collect();
    let always = median_sample(&names);
    let mut pairs: Vec<(usize, usize)> = held
        .iter()
        .flat_map(|&h| {
            // The held-out reference itself is the nearest by signature;
            // one more is kept so that it leaves `screen_keep` others.
            let params = ScreenParams {
                screen_keep: screen.screen_keep + 1,
                ..screen.clone()
            };
            screened_references(&signatures[h], &signatures, &params, &always)
                .into_iter()
                .filter(move |&j| j != h)
                .map(move |j| (h.min(j), h.max(j)))
        })
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

/// What a calibration compares: the held-out references (ascending) and
/// the pairs [`calibration_pairs_of`] names, in ascending order.
pub(super) struct CalibrationPlan {
    held: Vec<usize>,
    pub(super) pairs: Vec<(usize, usize)>,
}

impl CalibrationPlan {
    pub(super) fn of(references: &[CachedReference], settings: &Settings) -> Self {
        let held = held_out(references);
        let pairs = calibration_pairs_of(references, &held, settings);
        CalibrationPlan { held, pairs }
    }
}

/// The cP distances of `pairs`, in parallel (each unordered pair once),
/// those `known` holds taken from it; `progress` gets the number of pairs
/// done and of pairs to compute.
pub(super) fn pair_distances(
    references: &[CachedReference],
    pairs: &[(usize, usize)],
    settings: &Settings,
    known: &Known,
    turn: Option<&CalibrationTurn>,
    progress: &(impl Fn(usize, usize) + Sync),
) -> Vec<f64> {
    let old = known.indices(references);
    let reused: Vec<Option<f64>> = pairs
        .iter()
        .map(|&(i, j)| known.get(old[i], old[j]))
        .collect();
    let to_compute = reused.iter().filter(|v| v.is_none()).count();
    if to_compute < pairs.len() {
        tracing::info!(
            reused = pairs.len() - to_compute,
            computed = to_compute,
            "the calibration reuses the distances of the library's earlier calibration"
        );
    }
    let done = std::sync::atomic::AtomicUsize::new(0);
    let warned = std::sync::atomic::AtomicBool::new(false);
    pairs
        .par_iter()
        .zip(&reused)
        .map(|(&(i, j), known)| {
            if let Some(v) = *known {
                return v;
            }
            let (a, b) = (&references[i], &references[j]);
            if let Some(turn) = turn {
                // Superseded: the rest is left to the newer calibration.
                if turn.superseded() {
                    return f64::NAN;
                }
                if let Some(v) = turn.get(a, b) {
                    return v;
                }
            }
            let distance = match (a.prepared(), b.prepared()) {
                (Ok(pa), Ok(pb)) => {
                    let d = compare(&pa, &pb, &settings.cp.compare).distance;
                    if let Some(turn) = turn {
                        turn.put(a, b, d);
                    }
                    d
                }
                // An entry gone from the cache since the library was
                // opened: the pair counts as not compared (one log line).
                (Err(e), _) | (_, Err(e)) => {
                    if !warned.swap(true, std::sync::atomic::Ordering::Relaxed) {
                        tracing::warn!("the calibration leaves pairs out: {e}");
                    }
                    f64::NAN
                }
            };
            progress(
                done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1,
                to_compute,
            );
            distance
        })
        .collect()
}

/// The table of `plan`'s held-out references: row `k` holds the distances
/// of `plan.held[k]` to every reference (0 to itself, NaN where no pair
/// was compared), from `values`, one per pair of `plan.pairs`.
pub(super) fn distance_table(
    references: &[CachedReference],
    plan: CalibrationPlan,
    values: &[f64],
) -> ReferenceDistances {
    let n = references.len();
    let CalibrationPlan { held, pairs } = plan;
    let slot: Vec<Option<usize>> = {
        let mut s = vec![None; n];
        for (k, &h) in held.iter().enumerate() {
            s[h] = Some(k);
        }
        s
    };
    let mut rows = vec![vec![f64::NAN; n]; held.len()];
    for (k, &h) in held.iter().enumerate() {
        rows[k][h] = 0.0;
    }
    for (&(i, j), &v) in pairs.iter().zip(values) {
        if let Some(k) = slot[i] {
            rows[k][j] = v;
        }
        if let Some(k) = slot[j] {
            rows[k][i] = v;
        }
    }
    let names = references.iter().map(|r| r.name().to_string()).collect();
    // The shape holds by construction; an error here would be a bug.
    ReferenceDistances { names, held, rows }
}

/// The calibration's distances among `references`, computed now (those
/// `known` or `turn`'s share holds taken from there); `None` when `turn`
/// was superseded meanwhile.
fn compute(
    references: &[CachedReference],
    settings: &Settings,
    known: &Known,
    turn: Option<&CalibrationTurn>,
    progress: &(impl Fn(usize, usize) + Sync),
) -> Option<ReferenceDistances> {
    let plan = CalibrationPlan::of(references, settings);
    let values = pair_distances(references, &plan.pairs, settings, known, turn, progress);
    if turn.is_some_and(CalibrationTurn::superseded) {
        return None;
    }
    Some(distance_table(references, plan, &values))
}

/// The distances among `references` (prepared with `settings`) from
/// `cache` when it holds them for exactly these references and settings,
/// else computed now (see [`CALIBRATION_SAMPLE`]) and stored there,
/// replacing older ones; `progress` gets the comparisons done and in all.
/// A library that changed since its last calibration (a reference added,
/// removed or replaced) computes only the pairs its earlier file lacks:
/// adding one reference to a library of n costs n comparisons, not all of
/// them again. The cache only saves time: a file that cannot be read or written is
/// logged and the distances are computed.
pub fn reference_distances(
    references: &[CachedReference],
    settings: &Settings,
    cache: Option<&Cache>,
    progress: impl Fn(usize, usize) + Sync,
) -> ReferenceDistances {
    match reference_distances_in_turn(references, settings, cache, None, progress) {
        Some(d) => d,
        // Without a turn nothing supersedes the calibration.
        None => distance_table(references, CalibrationPlan::of(references, settings), &[]),
    }
}

/// [`reference_distances`] as one of a daemon's background calibrations:
/// the pair distances `turn`'s share holds are taken from it and those
/// computed are added to it; `None` (nothing stored) once a later turn has
/// started.
pub(crate) fn reference_distances_in_turn(
    references: &[CachedReference],
    settings: &Settings,
    cache: Option<&Cache>,
    turn: Option<&CalibrationTurn>,
    progress: impl Fn(usize, usize) + Sync,
) -> Option<ReferenceDistances> {
    let key = key(references, settings);
    let path = cache.map(|c| calibration_path(c, references, settings));
    if let Some(path) = &path {
        if let Ok(bytes) = std::fs::read(path) {
            match postcard::from_bytes::<Entry>(&bytes) {
                Ok(e) if e.format == FORMAT && e.key == key && e.distances.fits(references) => {
                    return Some(e.distances);
                }
                Ok(_) => {
                    tracing::warn!(file = %path.display(), "ignoring a stale calibration file")
                }
                Err(e) => {
                    tracing::warn!(file = %path.display(), "ignoring an unreadable calibration file: {e}")
                }
            }
        }
    }
    let distances = {
        let _span = tracing::info_span!("calibration", references = references.len()).entered();
        tracing::info!(
            "comparing the references with each other for the calibration (once per library)"
        );
        let known = cache.map_or_else(Known::default, |c| known_distances(c, settings));
        compute(references, settings, &known, turn, &progress)?
    };
    if let Some(cache) = cache {
        if let Err(e) = store(cache, references, settings, &distances) {
            tracing::warn!("calibration not stored in the cache: {e}");
        }
    }
    Some(distances)
}

/// The file in `cache` that holds the distances of `references` under
/// `settings`.
fn calibration_path(cache: &Cache, references: &[CachedReference], settings: &Settings) -> PathBuf {
    let key = key(references, settings);
    cache.dir().join(format!("{PREFIX}{key}.{EXTENSION}"))
}

/// Store `distances` (of `references` under `settings`) in `cache`,
/// replacing the library's older calibration files.
pub(super) fn store(
    cache: &Cache,
    references: &[CachedReference],
    settings: &Settings,
    distances: &ReferenceDistances,
) -> Result<(), CalibrationShardError> {
    let path = calibration_path(cache, references, settings);
    let entry = EntryOut {
        format: FORMAT,
        key: &key(references, settings),
        settings: &settings_key(settings),
        hashes: references.iter().map(|r| r.content_hash()).collect(),
        distances,
    };
    let bytes = postcard::to_stdvec(&entry).map_err(CalibrationShardError::Encode)?;
    write_atomic(&path, &bytes)?;
    remove_others(cache, &path);
    Ok(())
}

/// Delete the calibration files of `cache` other than `keep` (older
/// libraries or settings).
fn remove_others(cache: &Cache, keep: &std::path::Path) {
    let Ok(entries) = std::fs::read_dir(cache.dir()) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().into_owned();
        if is_calibration_file(&name) && path != keep {
            if let Err(e) = std::fs::remove_file(&path) {
                tracing::warn!(file = %path.display(), "old calibration file not removed: {e}");
            }
        }
    }
}

impl ReferenceDistances {
    /// Whether the table is of these references, in this order.
    fn fits(&self, references: &[CachedReference]) -> bool {
        self.names.len() == references.len()
            && self
                .names
                .iter()
                .zip(references)
                .all(|(n, r)| *n == r.name())
            && self.rows.iter().all(|r| r.len() == references.len())
            && self.held.len() == self.rows.len()
            && self.held.iter().all(|&h| h < references.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identify::calibration::share::{CalibrationShare, CalibrationTurn};
    use morphoid_data::library::{self, Library};
    use morphoid_synth::mesh::{self as synth, LibrarySpec};
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// The references of a synthetic library (two crowns of each genus,
    /// made with `seed`) prepared into a cache: the folder holding both,
    /// the cache, the settings and the references.
    fn synthetic_references(
        seed: u64,
    ) -> (tempfile::TempDir, Cache, Settings, Vec<CachedReference>) {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("library");
        let spec = LibrarySpec {
            per_genus: 2,
            target_vertices: 500,
            seed,
            random_pose: false,
        };
        synth::write_synthetic_library(&dir, &spec).unwrap();
        let lib = Library::open(&dir, None).unwrap();
        let cache = Cache::open(&tmp.path().join("cache")).unwrap();
        let mut settings = Settings::default();
        settings.clean.target_vertices = 500;
        let mut built = library::build(&lib, &cache, &settings, |_| {}).unwrap();
        let (all, _) = built.take_references();
        (tmp, cache, settings, all)
    }

    /// Calibrations of one share: a later one takes what an earlier one
    /// computed, and an earlier one stops once a later one has started.
    #[test]
    fn a_later_calibration_takes_the_pairs_an_earlier_one_computed() {
        let (_tmp, _cache, settings, all) = synthetic_references(13);
        let n = all.len();
        let share = CalibrationShare::default();
        let counted = |turn: &CalibrationTurn| {
            let count = AtomicUsize::new(0);
            let d = reference_distances_in_turn(&all, &settings, None, Some(turn), |_, _| {
                count.fetch_add(1, Ordering::Relaxed);
            });
            (d, count.into_inner())
        };
        let first = share.next_turn();
        let (d1, c1) = counted(&first);
        assert_eq!(c1, n * (n - 1) / 2);
        let second = share.next_turn();
        assert!(first.superseded() && !second.superseded());
        let (d2, c2) = counted(&second);
        assert_eq!(c2, 0, "every pair from the share");
        assert_eq!(d1, d2);
        assert_eq!(
            d2.unwrap(),
            reference_distances(&all, &settings, None, |_, _| {})
        );
        // Superseded before it starts: nothing computed, nothing stored.
        let (d3, c3) = counted(&first);
        assert_eq!((d3, c3), (None, 0));
    }

    #[test]
    fn a_library_with_one_reference_more_computes_only_that_references_pairs() {
        let (_tmp, cache, settings, all) = synthetic_references(11);
        let n = all.len();
        let computed = |refs: &[CachedReference], cache: Option<&Cache>| {
            let count = AtomicUsize::new(0);
            let d = reference_distances(refs, &settings, cache, |_, _| {
                count.fetch_add(1, Ordering::Relaxed);
            });
            (d, count.into_inner())
        };
        let (_, first) = computed(&all[..n - 1], Some(&cache));
        assert_eq!(first, (n - 1) * (n - 2) / 2);
        let (grown, second) = computed(&all, Some(&cache));
        assert_eq!(second, n - 1, "only the new reference's pairs");
        // The same table as one computed from nothing.
        let (fresh, _) = computed(&all, None);
        assert_eq!(grown, fresh);
        // Unchanged: nothing computed, from the file.
        assert_eq!(computed(&all, Some(&cache)).1, 0);
    }
}
