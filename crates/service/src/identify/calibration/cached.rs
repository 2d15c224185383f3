//! The distances among a library's references, computed once and kept in
//! the library's cache folder, keyed by the references' names and content
//! hashes and by the preparation and comparison settings (both change the
//! distances), so a changed, added or removed reference or changed
//! settings compute them again.

use super::ReferenceDistances;
use morphoid_core::cp::compare;
use morphoid_data::atomic_write::write_atomic;
use morphoid_data::hash::hex;
use morphoid_data::library::{Cache, CachedReference};
use morphoid_data::pipeline::Settings;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// Most references held out in the calibration: a larger library holds
/// out this many (those whose content hash sorts first, a fixed sample),
/// each compared with every reference, instead of every pair.
pub(crate) const CALIBRATION_SAMPLE: usize = 200;

/// How many comparisons the distances among `n` references take: every
/// pair up to [`CALIBRATION_SAMPLE`] references, else the pairs with at
/// least one of the sample.
pub(crate) fn calibration_pairs(n: usize) -> usize {
    let held = n.min(CALIBRATION_SAMPLE);
    let rest = n - held;
    held * held.saturating_sub(1) / 2 + held * rest
}

/// Bumped whenever the file's layout or the meaning of the distances
/// changes.
const FORMAT: u32 = 1;

/// File name prefix and extension of the cached distances.
const PREFIX: &str = "calibration-";
const EXTENSION: &str = "dist";

#[derive(Serialize, Deserialize)]
struct Entry {
    format: u32,
    key: String,
    distances: ReferenceDistances,
}

/// The key of a library's distances: its references (name and content, in
/// order) and every setting the distances depend on.
fn key(references: &[CachedReference], settings: &Settings) -> String {
    let mut h = Sha256::new();
    h.update(FORMAT.to_le_bytes());
    for r in references {
        h.update(r.name().as_bytes());
        h.update([0]);
        h.update(r.content_hash().as_bytes());
        h.update([0]);
    }
    let params = serde_json::to_string(&(&settings.clean, &settings.cp)).unwrap_or_default();
    h.update(params.as_bytes());
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

/// The cP distances between the held-out references and every reference,
/// pairs in parallel (each unordered pair once); `progress` gets the
/// number of pairs done.
fn compute(
    references: &[CachedReference],
    settings: &Settings,
    progress: &(impl Fn(usize) + Sync),
) -> ReferenceDistances {
    let n = references.len();
    let held = held_out(references);
    let is_held: Vec<bool> = (0..n).map(|i| held.binary_search(&i).is_ok()).collect();
    let pairs: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .filter(|&(i, j)| is_held[i] || is_held[j])
        .collect();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let values: Vec<f64> = pairs
        .par_iter()
        .map(|&(i, j)| {
            let c = compare(
                references[i].prepared(),
                references[j].prepared(),
                &settings.cp.compare,
            );
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
            c.distance
        })
        .collect();
    let slot: Vec<Option<usize>> = {
        let mut s = vec![None; n];
        for (k, &h) in held.iter().enumerate() {
            s[h] = Some(k);
        }
        s
    };
    let mut rows = vec![vec![0.0; n]; held.len()];
    for (&(i, j), &v) in pairs.iter().zip(&values) {
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

/// The distances among `references` (prepared with `settings`) from
/// `cache` when it holds them for exactly these references and settings,
/// else computed now (see [`CALIBRATION_SAMPLE`]) and stored there,
/// replacing older ones. The cache only saves time: a file that cannot be
/// read or written is logged and the distances are computed.
pub fn reference_distances(
    references: &[CachedReference],
    settings: &Settings,
    cache: Option<&Cache>,
    progress: impl Fn(usize) + Sync,
) -> ReferenceDistances {
    let key = key(references, settings);
    let path = cache.map(|c| c.dir().join(format!("{PREFIX}{key}.{EXTENSION}")));
    if let Some(path) = &path {
        if let Ok(bytes) = std::fs::read(path) {
            match postcard::from_bytes::<Entry>(&bytes) {
                Ok(e) if e.format == FORMAT && e.key == key && e.distances.fits(references) => {
                    return e.distances;
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
        compute(references, settings, &progress)
    };
    if let (Some(cache), Some(path)) = (cache, &path) {
        let entry = Entry {
            format: FORMAT,
            key,
            distances,
        };
        let stored = postcard::to_stdvec(&entry)
            .map_err(|e| e.to_string())
            .and_then(|bytes| write_atomic(path, &bytes).map_err(|e| e.to_string()));
        match stored {
            Ok(()) => remove_others(cache, path),
            Err(e) => tracing::warn!("calibration not stored in the cache: {e}"),
        }
        return entry.distances;
    }
    distances
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
        let ours = name.starts_with(PREFIX) && name.ends_with(&format!(".{EXTENSION}"));
        if ours && path != keep {
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

    #[test]
    fn pairs_of_a_whole_and_of_a_sampled_library() {
        assert_eq!(calibration_pairs(0), 0);
        assert_eq!(calibration_pairs(5), 10);
        assert_eq!(calibration_pairs(116), 6670);
        let (n, h) = (250, CALIBRATION_SAMPLE);
        // Pairs among the sample, and each of the sample with the rest.
        assert_eq!(calibration_pairs(n), h * (h - 1) / 2 + h * (n - h));
    }
}
