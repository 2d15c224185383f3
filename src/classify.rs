//! Identification of scans against a prepared reference library: the path
//! every scan takes, whether it comes from `morphoid classify`, the demo or
//! the daemon. [`Classifier`] holds the prepared references (loaded once);
//! [`run_job`] identifies one queued scan and records the outcome in the
//! store in one transaction.

use crate::cp;
use crate::eval::Labels;
use crate::library::{self, BuildOutcome, Cache, CacheError, CachedReference, Library};
use crate::mesh::io::{self, Format, LoadError};
use crate::pipeline::{self, PipelineError, Settings};
use crate::store::{self, DistanceRow, Job, ScanOutcome, ScanStatus, Store, StoreError};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How many nearest references a result lists.
pub const NEAREST: usize = store::DEFAULT_NEAREST;

/// A prepared library, ready to identify scans.
#[derive(Debug, Clone)]
pub struct Classifier {
    /// The prepared references, by name.
    pub references: Vec<CachedReference>,
    /// Their labels at the configured ranks.
    pub labels: Labels,
    /// Preparation and engine settings (the same for scans and references).
    pub settings: Settings,
}

/// Why a scan could not be identified; the message names the file.
#[derive(Debug, thiserror::Error)]
pub enum ClassifyError {
    /// Loading, cleaning or preparing failed.
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The library has no usable reference.
    #[error("the reference library has no prepared reference")]
    EmptyLibrary,
}

impl Classifier {
    /// Prepare (or take from the cache) every reference of `library`.
    /// References that fail are left out and reported in the outcome.
    pub fn build(
        library: &Library,
        cache: &Cache,
        settings: &Settings,
        progress: impl Fn(&str) + Sync,
    ) -> Result<(Self, BuildOutcome), CacheError> {
        let outcome = library::build(library, cache, settings, progress)?;
        let classifier = Classifier {
            references: outcome.references.clone(),
            labels: library.labels.clone(),
            settings: settings.clone(),
        };
        Ok((classifier, outcome))
    }

    /// Record the references in the store (names, content, labels, state),
    /// so that results can point at them.
    pub fn register(&self, store: &mut Store, outcome: &BuildOutcome) -> Result<(), StoreError> {
        for r in &self.references {
            let labels: store::Labels = self
                .labels
                .ranks
                .iter()
                .map(|rank| {
                    (
                        rank.clone(),
                        self.labels.get(&r.name, rank).map(str::to_string),
                    )
                })
                .collect();
            store.register_reference(&r.name, &r.content_hash, &labels)?;
            store.mark_reference_prepared(&r.name)?;
        }
        let names: Vec<&str> = self.references.iter().map(|r| r.name.as_str()).collect();
        store.remove_references_except(&names)?;
        for (name, why) in &outcome.failures {
            tracing::warn!(reference = %name, "reference left out: {why}");
        }
        Ok(())
    }

    /// Identify the surface in the file `path`.
    pub fn classify_file(&self, path: &Path) -> Result<ScanOutcome, ClassifyError> {
        let bytes = std::fs::read(path).map_err(|source| ClassifyError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        self.classify_bytes(path, &bytes)
    }

    /// Identify a surface given as the bytes of the file `path`.
    pub fn classify_bytes(&self, path: &Path, bytes: &[u8]) -> Result<ScanOutcome, ClassifyError> {
        if self.references.is_empty() {
            return Err(ClassifyError::EmptyLibrary);
        }
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let _span = tracing::info_span!("scan", scan = %name).entered();
        let t = Instant::now();
        let format = Format::from_path(path).ok_or_else(|| {
            PipelineError::Load(LoadError::UnknownFormat {
                path: path.to_path_buf(),
            })
        })?;
        let loaded = io::load_bytes(bytes, format, path).map_err(PipelineError::from)?;
        let load_ms = t.elapsed().as_secs_f64() * 1e3;
        let surface =
            pipeline::prepare_mesh(&loaded.mesh, &name, &self.settings).map_err(|e| match e {
                pipeline::MeshError::Clean(source) => PipelineError::Clean {
                    path: path.to_path_buf(),
                    source,
                },
                pipeline::MeshError::Prepare(source) => PipelineError::Prepare {
                    path: path.to_path_buf(),
                    source,
                },
            })?;
        let t = Instant::now();
        let distances: Vec<DistanceRow> = {
            let _s =
                tracing::info_span!("compare", scan = %name, references = self.references.len())
                    .entered();
            self.references
                .par_iter()
                .map(|r| {
                    let c = cp::compare(&surface.prepared, &r.prepared, &self.settings.cp);
                    DistanceRow {
                        reference: r.name.clone(),
                        forward: c.forward.distance,
                        backward: c.backward.distance,
                        distance: c.distance,
                        reflected: c.reflected,
                    }
                })
                .collect()
        };
        let compare_ms = t.elapsed().as_secs_f64() * 1e3;
        let id = library::identify(&distances, &self.labels, NEAREST);
        let timings_ms = BTreeMap::from([
            ("load".to_string(), load_ms),
            ("clean".to_string(), surface.timings.clean),
            ("prepare".to_string(), surface.timings.prepare),
            ("compare".to_string(), compare_ms),
        ]);
        Ok(ScanOutcome {
            ranks: id.ranks,
            distances,
            cleaning: serde_json::to_value(&surface.cleaning).unwrap_or_default(),
            timings_ms,
        })
    }
}

/// Identify a claimed job and record the outcome: `ok` with the whole
/// result, or `error` with the message. Returns the final status; only a
/// database failure is an error (the job then stays `running` and is
/// requeued at the next start).
pub fn run_job(
    store: &mut Store,
    classifier: &Classifier,
    job: &Job,
) -> Result<ScanStatus, StoreError> {
    let path = Path::new(&job.path);
    let started = Instant::now();
    match classifier.classify_file(path) {
        Ok(mut outcome) => {
            outcome
                .timings_ms
                .insert("total".into(), started.elapsed().as_secs_f64() * 1e3);
            store.complete(job.scan_id, &outcome)?;
            Ok(ScanStatus::Ok)
        }
        Err(e) => {
            store.fail(job.scan_id, &e.to_string())?;
            Ok(ScanStatus::Error)
        }
    }
}
