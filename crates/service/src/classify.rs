//! Identification of scans against a prepared reference library: the path
//! every scan takes, whether it comes from `morphoid classify`, the demo or
//! the daemon. [`Classifier`] holds the prepared references and their
//! landmarks (loaded once); [`run_job`] identifies one queued scan, carries
//! the nearest reference's landmarks onto it, records the outcome in the
//! store in one transaction and, with a results folder ([`ResultFiles`]),
//! writes the result files.

mod files;
mod margin;
mod recut;

pub use files::{ResultFiles, ResultsError};

use crate::identify::{
    self, Calibration, DistanceRow, LandmarkPoint, ScanLandmarks, ScanOutcome, SpecimenOutcome,
    SpecimensOutcome,
};
use crate::report::{Scene, SceneReference};
use crate::store::{self, Job, ScanRecord, ScanStatus, Store, StoreError};
use morphoid_core::cp;
use morphoid_data::landmarks::{self, Landmarks, PropagateError, Surface};
use morphoid_data::library::{self, BuildOutcome, Cache, CacheError, CachedReference, Library};
use morphoid_data::pipeline::{self, PipelineError, PreparedSurface, Settings};
use morphoid_data::present::error_chain;
use morphoid_data::table::Labels;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use std::time::Instant;

/// How many nearest references a result lists.
pub const NEAREST: usize = store::DEFAULT_NEAREST;

/// How many nearest references a report draws beside the scan.
const REPORT_NEAREST: usize = 3;

/// The distance row of reference `name` from comparison `c`.
fn distance_row(name: &str, c: &cp::Comparison) -> DistanceRow {
    DistanceRow {
        reference: name.to_string(),
        forward: c.forward.distance,
        backward: c.backward.distance,
        distance: c.distance,
        reflected: c.reflected,
    }
}

/// Why the pictures of a recorded scan cannot be drawn again.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scan file is no longer where it was recorded.
    #[error(
        "{0}: the scan file is gone, so the scan cannot be drawn (the recorded result stands)"
    )]
    Gone(PathBuf),
    /// The file there now is not the content that was identified.
    #[error("{0}: the file has changed since it was identified, so it is not drawn (the recorded result is of the earlier content)")]
    Changed(PathBuf),
    /// The scan has no result to draw.
    #[error("{0}: not identified, nothing to draw")]
    NotIdentified(String),
    /// Preparing the file again failed.
    #[error(transparent)]
    Classify(#[from] ClassifyError),
}

/// A prepared library, ready to identify scans. Cloning it is cheap: the
/// prepared references are shared, never copied.
#[derive(Debug, Clone)]
pub struct Classifier {
    /// The prepared references, in library order (shared with a
    /// calibration running in the background, so the library is held once).
    references: Arc<Vec<CachedReference>>,
    /// Their screening signatures, in the same order (see
    /// [`identify::screened_references`]).
    signatures: Arc<Vec<cp::Signature>>,
    /// Their labels at the configured ranks.
    labels: Labels,
    /// Preparation and engine settings (the same for scans and references).
    settings: Settings,
    /// Landmarks of the references that have them, by reference name, in
    /// each reference file's coordinates.
    landmarks: BTreeMap<String, Landmarks>,
    /// Where [`run_job`] writes the result files of each scan (`None`:
    /// nowhere).
    results: Option<ResultFiles>,
    /// The library's confidence model.
    calibration: Calibrated,
}

/// The classifier's confidence model: none, fitted, or being fitted by a
/// [`PendingCalibration`] (set once, when it is done).
#[derive(Debug, Clone, Default)]
enum Calibrated {
    #[default]
    Off,
    Ready(Arc<Calibration>),
    /// `Some` once fitted, `None` once it failed; unset while it runs.
    Background(Arc<OnceLock<Option<Calibration>>>),
}

/// Where a classifier's confidence model stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CalibrationState {
    /// No calibration: `[library] calibrate = false`, or too few references.
    Off,
    /// Being fitted in the background; answers carry no confidence yet.
    Calibrating,
    /// Fitted: answers carry their confidence.
    Ready,
    /// The calibration failed; answers carry no confidence.
    Failed,
}

impl Calibrated {
    fn get(&self) -> Option<&Calibration> {
        match self {
            Calibrated::Off => None,
            Calibrated::Ready(c) => Some(c),
            Calibrated::Background(slot) => slot.get()?.as_ref(),
        }
    }

    fn state(&self) -> CalibrationState {
        match self {
            Calibrated::Off => CalibrationState::Off,
            Calibrated::Ready(_) => CalibrationState::Ready,
            Calibrated::Background(slot) => match slot.get() {
                None => CalibrationState::Calibrating,
                Some(Some(_)) => CalibrationState::Ready,
                Some(None) => CalibrationState::Failed,
            },
        }
    }
}

/// A cheap handle on a classifier's [`CalibrationState`], for whoever
/// reports on it (the daemon's status line) while the classifier works
/// elsewhere.
#[derive(Debug, Clone)]
pub struct CalibrationProbe(Calibrated);

impl CalibrationProbe {
    /// Where the calibration stands now.
    pub fn state(&self) -> CalibrationState {
        self.0.state()
    }
}

/// Why a [`PendingCalibration`] failed.
#[derive(Debug, thiserror::Error)]
#[error("the calibration of the library failed: {0}")]
pub struct CalibrationFailed(String);

/// The calibration of a classifier, to fit elsewhere (the daemon runs it
/// on a thread of its own so that scans are identified meanwhile). It
/// shares the classifier's prepared references. Until [`run`](Self::run)
/// is done the classifier's answers carry no confidence and are marked
/// as identified while calibrating; dropped without running, the
/// calibration counts as failed.
#[derive(Debug)]
pub struct PendingCalibration {
    references: Arc<Vec<CachedReference>>,
    labels: Labels,
    settings: Settings,
    cache: Option<Cache>,
    slot: Arc<OnceLock<Option<Calibration>>>,
    /// Its place among the daemon's calibrations, if it has one.
    turn: Option<identify::CalibrationTurn>,
}

/// What a [`PendingCalibration`] came to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Fitted {
    /// Fitted: what it says per rank, for one log line ("genus 110/116
    /// right, …").
    Ranks(String),
    /// Stopped because a newer library's calibration started (its
    /// distances are left to that one); the classifier goes without.
    Superseded,
}

impl PendingCalibration {
    /// How many references the calibration compares with each other.
    pub fn references(&self) -> usize {
        self.references.len()
    }

    /// The same calibration as one of the daemon's background
    /// calibrations (`turn` of their [`identify::CalibrationShare`]): it
    /// stops once a later one starts, and the pair distances they compute
    /// are shared.
    pub fn in_turn(mut self, turn: identify::CalibrationTurn) -> Self {
        self.turn = Some(turn);
        self
    }

    /// Fit the calibration (the distances among the references from the
    /// cache, or computed on the current rayon pool and stored there) and
    /// hand it to the classifier. A panic while fitting is caught and
    /// returned: the classifier then goes on without confidence.
    pub fn run(self) -> Result<Fitted, CalibrationFailed> {
        let fitted = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let distances = identify::reference_distances_in_turn(
                &self.references,
                &self.settings,
                self.cache.as_ref(),
                self.turn.as_ref(),
                |_, _| {},
            )?;
            Some(Calibration::fit(distances, &self.labels))
        }));
        match fitted {
            Ok(None) => {
                let _ = self.slot.set(None);
                Ok(Fitted::Superseded)
            }
            Ok(Some(calibration)) => {
                let ranks: Vec<String> = calibration
                    .ranks()
                    .iter()
                    .map(|r| format!("{} {}/{} right", r.rank, r.right, r.held))
                    .collect();
                let _ = self.slot.set(Some(calibration));
                Ok(Fitted::Ranks(if ranks.is_empty() {
                    "no rank has enough references to calibrate".into()
                } else {
                    format!("held out: {}", ranks.join(", "))
                }))
            }
            Err(panic) => {
                let _ = self.slot.set(None);
                let why = panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "a panic without a message".into());
                Err(CalibrationFailed(why))
            }
        }
    }
}

impl Drop for PendingCalibration {
    fn drop(&mut self) {
        // Never run (e.g. its thread could not start): failed, not pending
        // for ever. A no-op after `run`.
        let _ = self.slot.set(None);
    }
}

/// The calibration of `references` (leave-one-out among them), their
/// distances from `cache` or computed; with `log_ranks`, one info line per
/// rank.
fn fit_calibration(
    references: &[CachedReference],
    labels: &Labels,
    settings: &Settings,
    cache: Option<&Cache>,
    log_ranks: bool,
) -> Calibration {
    let distances = identify::reference_distances(references, settings, cache, |_, _| {});
    let calibration = identify::Calibration::fit(distances, labels);
    for r in calibration.ranks().iter().filter(|_| log_ranks) {
        tracing::info!(
            rank = %r.rank,
            held = r.held,
            right = r.right,
            threshold = ?r.threshold,
            "calibrated"
        );
    }
    calibration
}

/// The screening signature of each reference, in order.
fn signatures_of(references: &[CachedReference]) -> Vec<cp::Signature> {
    references
        .par_iter()
        .map(|r| r.signature().clone())
        .collect()
}

/// Why a scan could not be identified; the message names the file.
#[derive(Debug, thiserror::Error)]
pub enum ClassifyError {
    /// Loading, cleaning or preparing failed.
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    /// The library has no usable reference.
    #[error("the reference library has no prepared reference")]
    EmptyLibrary,
    /// The scan was read without the content hash asked for (a fault of
    /// the reader: what was identified would not be known).
    #[error("{}: read without its content hash", shown(.path))]
    Unhashed {
        /// The scan file or folder.
        path: PathBuf,
    },
}

/// A path as a one-line message shows it (control characters escaped, as
/// the mesh readers' messages do).
fn shown(path: &Path) -> String {
    path.display().to_string().escape_debug().to_string()
}

impl Classifier {
    /// A classifier of `references` (prepared with `settings`) labelled by
    /// `labels`, without landmarks or result files.
    pub fn new(references: Vec<CachedReference>, labels: Labels, settings: Settings) -> Self {
        Classifier {
            signatures: Arc::new(signatures_of(&references)),
            references: Arc::new(references),
            labels,
            settings,
            landmarks: BTreeMap::new(),
            results: None,
            calibration: Calibrated::Off,
        }
    }

    /// Prepare (or take from the cache) every reference of `library`, and
    /// calibrate the confidence on the prepared references (their
    /// distances to each other come from the cache when the references
    /// and settings are unchanged; see [`identify::Calibration`]).
    /// References that fail are left out and reported in the outcome.
    /// The prepared references and their landmarks move into the
    /// classifier: the outcome comes back without them (a prepared library
    /// is large, and one copy is enough), holding what the build reports.
    pub fn build(
        library: &Library,
        cache: &Cache,
        settings: &Settings,
        progress: impl Fn(&str) + Sync,
    ) -> Result<(Self, BuildOutcome), CacheError> {
        let (classifier, outcome) = Self::build_uncalibrated(library, cache, settings, progress)?;
        Ok((classifier.calibrated(Some(cache)), outcome))
    }

    /// [`Classifier::build`] with the configuration's settings, calibrated
    /// unless `[library] calibrate = false`.
    pub fn build_with(
        library: &Library,
        cache: &Cache,
        config: &crate::config::Config,
        progress: impl Fn(&str) + Sync,
    ) -> Result<(Self, BuildOutcome), CacheError> {
        let settings = config.settings();
        if config.library.calibrate {
            Self::build(library, cache, &settings, progress)
        } else {
            Self::build_uncalibrated(library, cache, &settings, progress)
        }
    }

    /// [`Classifier::build`] without the calibration (`[library] calibrate
    /// = false`): answers carry no confidence, and a library that is new
    /// to the cache starts without comparing its references with each
    /// other.
    fn build_uncalibrated(
        library: &Library,
        cache: &Cache,
        settings: &Settings,
        progress: impl Fn(&str) + Sync,
    ) -> Result<(Self, BuildOutcome), CacheError> {
        let mut outcome = library::build(library, cache, settings, progress)?;
        let (references, landmarks) = outcome.take_references();
        let classifier = Classifier {
            signatures: Arc::new(signatures_of(&references)),
            references: Arc::new(references),
            labels: library.labels().clone(),
            settings: settings.clone(),
            landmarks,
            results: None,
            calibration: Calibrated::Off,
        };
        Ok((classifier, outcome))
    }

    /// [`Classifier::build_with`], but the calibration is not fitted here:
    /// it comes back as a [`PendingCalibration`] (unless `[library]
    /// calibrate = false` or the library is too small) for the caller to
    /// run where it does not hold up identification — the daemon's path.
    pub fn build_deferred(
        library: &Library,
        cache: &Cache,
        config: &crate::config::Config,
        progress: impl Fn(&str) + Sync,
    ) -> Result<(Self, BuildOutcome, Option<PendingCalibration>), CacheError> {
        let (classifier, outcome) =
            Self::build_uncalibrated(library, cache, &config.settings(), progress)?;
        if !config.library.calibrate {
            return Ok((classifier, outcome, None));
        }
        let (classifier, pending) = classifier.calibrate_later(Some(cache.clone()));
        Ok((classifier, outcome, pending))
    }

    /// The same classifier, its calibration to be fitted by the returned
    /// [`PendingCalibration`] (which shares the prepared references); until
    /// then answers carry no confidence and are marked `calibrating`. A
    /// library of fewer than [`identify::MIN_HELD`] references is left
    /// without calibration (`None`).
    fn calibrate_later(mut self, cache: Option<Cache>) -> (Self, Option<PendingCalibration>) {
        if !identify::calibratable(self.references.len()) {
            self.calibration = Calibrated::Off;
            return (self, None);
        }
        let slot = Arc::new(OnceLock::new());
        self.calibration = Calibrated::Background(Arc::clone(&slot));
        let pending = PendingCalibration {
            references: Arc::clone(&self.references),
            labels: self.labels.clone(),
            settings: self.settings.clone(),
            cache,
            slot,
            turn: None,
        };
        (self, Some(pending))
    }

    /// The same classifier with its confidence calibrated on its own
    /// references (leave-one-out), the distances among them taken from
    /// `cache` or computed (and stored there). A library of fewer than
    /// [`identify::MIN_HELD`] references is left without calibration.
    pub fn calibrated(mut self, cache: Option<&Cache>) -> Self {
        if !identify::calibratable(self.references.len()) {
            self.calibration = Calibrated::Off;
            return self;
        }
        let calibration =
            fit_calibration(&self.references, &self.labels, &self.settings, cache, true);
        self.calibration = Calibrated::Ready(Arc::new(calibration));
        self
    }

    /// The library's confidence model, if calibrated (and, when it is
    /// fitted in the background, once it is ready).
    pub fn calibration(&self) -> Option<&Calibration> {
        self.calibration.get()
    }

    /// Where the confidence model stands.
    #[cfg(test)]
    fn calibration_state(&self) -> CalibrationState {
        self.calibration.state()
    }

    /// A handle that follows where the confidence model stands, from
    /// elsewhere.
    pub fn calibration_probe(&self) -> CalibrationProbe {
        CalibrationProbe(self.calibration.clone())
    }

    /// The same classifier writing result files (`None`: none).
    pub fn with_result_files(mut self, results: Option<ResultFiles>) -> Self {
        self.results = results;
        self
    }

    /// The same references compared under other settings. The preparation
    /// settings must stay those the references were prepared with; only
    /// the comparison may differ. The calibration is kept as it is: call
    /// [`Classifier::calibrated`] again to fit it to the new settings.
    pub fn with_settings(mut self, settings: Settings) -> Self {
        self.settings = settings;
        self
    }

    /// The prepared references, in library order.
    pub fn references(&self) -> &[CachedReference] {
        &self.references
    }

    /// The settings scans are prepared and compared with.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Record the references in the store (names, content, labels, state),
    /// so that results can point at them, and log what the build left out.
    pub fn register(&self, store: &mut Store, outcome: &BuildOutcome) -> Result<(), StoreError> {
        self.register_references(store)?;
        for f in outcome.failures() {
            tracing::warn!(reference = %f.name(), "reference left out: {}", f.error());
        }
        for (name, why) in outcome.landmarks().problems() {
            tracing::warn!(reference = %name, "landmarks left out: {why}");
        }
        Ok(())
    }

    /// Record the references in the store (names, content, labels, state)
    /// and mark the others removed: what a new or replaced database needs
    /// before results can point at them. Registering again changes nothing.
    pub fn register_references(&self, store: &mut Store) -> Result<(), StoreError> {
        let records: Vec<(&str, &str, store::Labels)> = self
            .references
            .iter()
            .map(|r| {
                let labels: store::Labels = self
                    .labels
                    .ranks()
                    .iter()
                    .map(|rank| {
                        (
                            rank.clone(),
                            self.labels.get(r.name(), rank).map(str::to_string),
                        )
                    })
                    .collect();
                (r.name(), r.content_hash(), labels)
            })
            .collect();
        store.record_prepared_library(&records)
    }

    /// Identify the surface in the file `path`, or the volume (slice
    /// folder, NRRD, NIfTI) there.
    pub fn classify_file(&self, path: &Path) -> Result<ScanOutcome, ClassifyError> {
        self.identify_path(path).map(|(outcome, _)| outcome)
    }

    /// Identify a surface already prepared (the research tools' and the
    /// evaluations' path: the same comparison, re-cut and answer as a
    /// file's, without reading it again).
    /// A crown the library weighs better than the cleaning's choice among
    /// the margins it found is swapped into `surface` (`cleaning.margins`).
    pub fn classify_prepared(&self, surface: &mut PreparedSurface) -> ScanOutcome {
        let name = surface.prepared.name().to_string();
        let _span = tracing::info_span!("scan", scan = %name).entered();
        self.compare_prepared(&name, surface, surface.timings.load)
    }

    /// Identify the scan at `path` only if what is read there is the
    /// content `expected` (a content hash): the file, or every slice of a
    /// folder, is read once and hashed as read, and exactly those bytes
    /// are identified. Other content comes back as [`Read::Other`],
    /// unidentified; so does a file that cannot be read or parsed when it
    /// no longer holds `expected` (it changed meanwhile: its error is not
    /// the queued content's).
    fn identify_content(&self, path: &Path, expected: &str) -> Result<Read, ClassifyError> {
        if self.references.is_empty() {
            return Err(ClassifyError::EmptyLibrary);
        }
        let name = pipeline::specimen_name(path);
        let _span = tracing::info_span!("scan", scan = %name).entered();
        let loaded = match pipeline::load_hashed(path, &self.settings) {
            Ok(loaded) => loaded,
            Err(e) => {
                return match morphoid_data::hash::content_hash_file(path) {
                    Ok((hash, size)) if hash != expected => {
                        Ok(Read::Other(morphoid_data::hash::Content { hash, size }))
                    }
                    _ => Err(e.into()),
                }
            }
        };
        match loaded.content.clone() {
            Some(content) if content.hash == expected => {}
            Some(content) => return Ok(Read::Other(content)),
            None => {
                return Err(ClassifyError::Unhashed {
                    path: path.to_path_buf(),
                })
            }
        }
        if loaded.specimens.len() == 1 {
            let mut surface = pipeline::prepare_loaded(loaded, path, &self.settings)?;
            let load_ms = surface.timings.load;
            let outcome = self.compare_prepared(&name, &mut surface, load_ms);
            return Ok(Read::Identified(Box::new((outcome, surface))));
        }
        // Several specimens: each identified on its own.
        let segmentation = serde_json::json!({
            "specimens": loaded.specimens.len(),
            "volume": loaded.volume.as_ref().map(|v| &v.segmentation),
            "split": loaded.split,
        });
        let load_ms = loaded.load_ms;
        tracing::info!(
            "{}: {} specimens, each identified on its own",
            path.display(),
            loaded.specimens.len()
        );
        // Side by side: one specimen's serial steps (cutting, preparing a
        // crown again) leave a core to another's comparisons.
        let specimens = pipeline::prepare_specimens(loaded, path, &self.settings)
            .into_par_iter()
            .enumerate()
            .map(|(i, (position, prepared))| {
                let result = prepared
                    .map(|mut surface| {
                        let name = format!("{name}#{}", i + 1);
                        let outcome = self.compare_prepared(&name, &mut surface, load_ms);
                        (outcome, surface)
                    })
                    .map_err(Arc::new);
                (position, result)
            })
            .collect();
        Ok(Read::Specimens {
            specimens,
            segmentation,
            load_ms,
        })
    }

    /// The prepared specimen `n` (1-based) of the scan at `path` as it is
    /// read now, and the content read.
    fn prepare_specimen(
        &self,
        path: &Path,
        n: u32,
    ) -> Result<(PreparedSurface, morphoid_data::hash::Content), ClassifyError> {
        let loaded = pipeline::load_hashed(path, &self.settings)?;
        let content = loaded
            .content
            .clone()
            .ok_or_else(|| ClassifyError::Unhashed {
                path: path.to_path_buf(),
            })?;
        let count = loaded.specimens.len();
        let found = pipeline::prepare_specimens(loaded, path, &self.settings)
            .into_iter()
            .nth(n.saturating_sub(1) as usize)
            .ok_or(PipelineError::Several {
                path: path.to_path_buf(),
                count,
            })?;
        Ok((found.1?, content))
    }

    /// [`classify_file`](Self::classify_file), with the prepared scan.
    fn identify_path(&self, path: &Path) -> Result<(ScanOutcome, PreparedSurface), ClassifyError> {
        if self.references.is_empty() {
            return Err(ClassifyError::EmptyLibrary);
        }
        let name = pipeline::specimen_name(path);
        let _span = tracing::info_span!("scan", scan = %name).entered();
        // From the file, not its bytes in memory: a binary STL export of
        // hundreds of megabytes is read record by record.
        let mut surface = pipeline::prepare_file(path, &self.settings)?;
        let load_ms = surface.timings.load;
        let outcome = self.compare_prepared(&name, &mut surface, load_ms);
        Ok((outcome, surface))
    }

    /// What a report draws of the prepared scan `scan`: its
    /// [`REPORT_NEAREST`] nearest references (of `nearest`, nearest
    /// first; names the library no longer holds are skipped), each moved
    /// onto the scan with the correspondence coloured, and the carried
    /// landmarks.
    pub fn scene(
        &self,
        scan: &PreparedSurface,
        nearest: &[(String, f64)],
        landmarks: Option<&ScanLandmarks>,
    ) -> Scene {
        let _span = tracing::info_span!("scene", scan = %scan.prepared.name()).entered();
        let drawn: Vec<(&CachedReference, f64, Arc<cp::Prepared>)> = nearest
            .iter()
            .filter_map(|(name, distance)| {
                let r = self.references.iter().find(|r| r.name() == name)?;
                match r.prepared() {
                    Ok(p) => Some((r, *distance, p)),
                    Err(e) => {
                        tracing::warn!(reference = %name, "not drawn: {e}");
                        None
                    }
                }
            })
            .take(REPORT_NEAREST)
            .collect();
        let references: Vec<SceneReference<'_>> = drawn
            .iter()
            .map(|(r, distance, prepared)| SceneReference {
                name: r.name(),
                distance: *distance,
                prepared,
            })
            .collect();
        let points: Vec<(Option<String>, [f64; 3])> = landmarks
            .map(|lm| {
                lm.points
                    .iter()
                    .map(|p| (p.label.clone(), [p.x, p.y, p.z]))
                    .collect()
            })
            .unwrap_or_default();
        Scene::build(
            &scan.prepared,
            &references,
            &points,
            &self.settings.cp.compare,
        )
    }

    /// The scene of a recorded scan, drawn again from its file: the file
    /// is prepared again (it must still hold the identified content) and
    /// matched with the recorded nearest references.
    pub fn scene_of_record(&self, record: &ScanRecord) -> Result<Scene, SceneError> {
        // A specimen's row names `<scan>#n`: the file is the scan's.
        let file = match record.specimen {
            Some(_) => record
                .path
                .rsplit_once('#')
                .map_or(record.path.as_str(), |(file, _)| file),
            None => record.path.as_str(),
        };
        let path = Path::new(file);
        if record.nearest.is_empty() {
            return Err(SceneError::NotIdentified(record.path.clone()));
        }
        if !path.exists() {
            return Err(SceneError::Gone(path.to_path_buf()));
        }
        match morphoid_data::hash::content_hash_file(path) {
            Ok((hash, _)) if hash == record.content_hash => {}
            Ok(_) => return Err(SceneError::Changed(path.to_path_buf())),
            Err(_) => return Err(SceneError::Gone(path.to_path_buf())),
        }
        let mut surface = match record.specimen {
            Some(n) => {
                let (surface, content) = self.prepare_specimen(path, n)?;
                if content.hash != record.content_hash {
                    return Err(SceneError::Changed(path.to_path_buf()));
                }
                surface
            }
            None => pipeline::prepare_file(path, &self.settings).map_err(ClassifyError::from)?,
        };
        // The crown the identification took among the margins found.
        if let Some(k) = record.cleaning["margins"]["chosen"].as_u64() {
            if k > 0 {
                surface.take_alternative(k as usize - 1);
            }
        }
        let nearest: Vec<(String, f64)> = record
            .nearest
            .iter()
            .map(|n| (n.reference.clone(), n.distance))
            .collect();
        Ok(self.scene(&surface, &nearest, record.landmarks.as_ref()))
    }

    /// Compare a prepared scan named `name` with every reference and
    /// identify it; `load_ms` is the time it took to read.
    fn compare_prepared(
        &self,
        name: &str,
        surface: &mut PreparedSurface,
        load_ms: f64,
    ) -> ScanOutcome {
        let t = Instant::now();
        let mut screened = self.screened(&surface.prepared);
        let screen_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let (mut distances, mut found) = self.compared_rows(name, &surface.prepared, &screened);
        let compare_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let margin = self.choose_margin(surface, &distances, &found);
        if margin.as_ref().is_some_and(|m| m.changed()) {
            screened = self.screened(&surface.prepared);
            (distances, found) = self.compared_rows(name, &surface.prepared, &screened);
        }
        let margin_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let recut = self.recut(name, surface, &found, &mut distances);
        let recut_ms = t.elapsed().as_secs_f64() * 1e3;
        let mut id = identify::identify(&distances, &self.labels, NEAREST);
        let calibration = self.calibration.get();
        if let Some(c) = calibration {
            c.assess(&distances, &mut id.ranks);
        }
        let calibrating =
            calibration.is_none() && self.calibration.state() == CalibrationState::Calibrating;
        let mut timings_ms = BTreeMap::from([
            ("load".to_string(), load_ms),
            ("clean".to_string(), surface.timings.clean),
            ("prepare".to_string(), surface.timings.prepare),
            ("compare".to_string(), compare_ms),
        ]);
        if screened.len() < self.references.len() {
            timings_ms.insert("screen".into(), screen_ms);
        }
        if margin.is_some() {
            timings_ms.insert("margins".into(), margin_ms);
        }
        if !recut.is_empty() {
            timings_ms.insert("recut".into(), recut_ms);
        }
        let t = Instant::now();
        let landmarks = self.nearest_landmarks(&distances, surface);
        if landmarks.is_some() {
            timings_ms.insert("landmarks".into(), t.elapsed().as_secs_f64() * 1e3);
        }
        let mut cleaning = serde_json::to_value(&surface.cleaning).unwrap_or_default();
        // What the segmentation warns of (two specimens that may be fused)
        // goes with the result, where a user reads it.
        if let (Some(v), Some(map)) = (&surface.volume, cleaning.as_object_mut()) {
            if !v.segmentation.warnings.is_empty() {
                map.insert(
                    "warnings".into(),
                    serde_json::json!(v.segmentation.warnings),
                );
            }
        }
        if let (Some(m), Some(map)) = (&margin, cleaning.as_object_mut()) {
            map.insert("margins".into(), serde_json::json!(m));
        }
        if let (false, Some(map)) = (recut.is_empty(), cleaning.as_object_mut()) {
            map.insert("recut".into(), serde_json::json!(recut));
        }
        ScanOutcome {
            ranks: id.ranks,
            distances,
            cleaning,
            timings_ms,
            landmarks,
            calibrating,
        }
    }

    /// `scan` compared with the references `indices`: a distance row and
    /// the reference's index and alignment for each.
    fn compared_rows(
        &self,
        name: &str,
        scan: &cp::Prepared,
        indices: &[usize],
    ) -> (Vec<DistanceRow>, Vec<(usize, cp::Alignment)>) {
        let _s = tracing::info_span!(
            "compare",
            scan = %name,
            references = self.references.len(),
            compared = indices.len()
        )
        .entered();
        let compared: Vec<(DistanceRow, (usize, cp::Alignment))> = indices
            .par_iter()
            .filter_map(|&i| {
                let r = &self.references[i];
                // A cache entry removed or damaged since the library was
                // opened leaves its reference out of this answer (the next
                // library build prepares it again).
                let prepared = match r.prepared() {
                    Ok(p) => p,
                    Err(e) => {
                        tracing::warn!(reference = %r.name(), "left out of the comparison: {e}");
                        return None;
                    }
                };
                let c = cp::compare(scan, &prepared, &self.settings.cp.compare);
                Some((distance_row(r.name(), &c), (i, cp::Alignment::of(&c))))
            })
            .collect();
        compared.into_iter().unzip()
    }

    /// The indices of the references a scan prepared as `scan` is compared
    /// with: those the screen keeps (all, in a library too small to
    /// screen), and, when the answer will carry a confidence, those its
    /// novelty score reads (the calibration's median sample).
    fn screened(&self, scan: &cp::Prepared) -> Vec<usize> {
        let params = &self.settings.cp.screen;
        let n = self.references.len();
        if !params.screens(n) {
            return (0..n).collect();
        }
        // The calibration's sample, in the same library order.
        let always = self
            .calibration
            .get()
            .map(|c| c.median_sample().to_vec())
            .unwrap_or_default();
        identify::screened_references(
            &cp::shape_signature(scan),
            &self.signatures,
            params,
            &always,
        )
    }

    /// The indices into `signatures` the screen keeps for `crown`, a crown
    /// cut from a whole tooth (again): screening on whatever the library's
    /// size, on the crown's own signature.
    fn screened_crown(
        &self,
        crown: &cp::Prepared,
        signatures: &[impl std::borrow::Borrow<cp::Signature>],
    ) -> Vec<usize> {
        let params = cp::ScreenParams {
            screening: cp::Screening::On,
            ..self.settings.cp.screen
        };
        identify::screened_references(&cp::shape_signature(crown), signatures, &params, &[])
    }

    /// The landmarks of the nearest reference (smallest distance, ties by
    /// name) carried onto the scan, when that reference has landmarks.
    /// A failure is logged and leaves the result without landmarks: the
    /// identification stands on its own.
    fn nearest_landmarks(
        &self,
        distances: &[DistanceRow],
        scan: &PreparedSurface,
    ) -> Option<ScanLandmarks> {
        let nearest = distances.iter().min_by(|a, b| {
            a.distance
                .total_cmp(&b.distance)
                .then_with(|| a.reference.cmp(&b.reference))
        })?;
        let lm = self.landmarks.get(&nearest.reference)?;
        let reference = self
            .references
            .iter()
            .find(|r| r.name() == nearest.reference)?;
        let prepared = match reference.prepared() {
            Ok(p) => p,
            Err(e) => {
                tracing::warn!(reference = %reference.name(), "landmarks not carried over: {e}");
                return None;
            }
        };
        match self.carry(&prepared, lm, scan) {
            Ok(points) => Some(ScanLandmarks {
                reference: reference.name().to_string(),
                points,
            }),
            Err(e) => {
                tracing::warn!(reference = %reference.name(), "landmarks not carried over: {e}");
                None
            }
        }
    }

    /// Carry `lm` (on `reference`, in its file's coordinates) onto the
    /// scan through the cP correspondence reference → scan; the points lie
    /// on the cleaned scan surface, in the scan file's coordinates.
    fn carry(
        &self,
        reference: &cp::Prepared,
        lm: &Landmarks,
        scan: &PreparedSurface,
    ) -> Result<Vec<LandmarkPoint>, PropagateError> {
        let map = cp::compare_directed(reference, &scan.prepared, &self.settings.cp.compare);
        let source = Surface::from_normalized(reference)?;
        let target = Surface::from_prepared(scan)?;
        let out = landmarks::propagate(lm, &source, &target, &map.correspondence)?;
        Ok(out
            .landmarks
            .points()
            .iter()
            .enumerate()
            .map(|(i, p)| LandmarkPoint {
                label: out.landmarks.label(i).map(str::to_string),
                x: p[0],
                y: p[1],
                z: p[2],
            })
            .collect())
    }
}

/// One specimen of a scan of several: where it lies, and its
/// identification with the prepared specimen, or why it has none.
type SpecimenRead = (
    pipeline::Position,
    Result<(ScanOutcome, PreparedSurface), Arc<PipelineError>>,
);

/// What [`Classifier::identify_content`] read.
enum Read {
    /// The expected content, identified (and the prepared scan).
    Identified(Box<(ScanOutcome, PreparedSurface)>),
    /// The expected content, several specimens, each identified on its own.
    Specimens {
        /// The specimens in order.
        specimens: Vec<SpecimenRead>,
        /// What the segmentation or split found.
        segmentation: serde_json::Value,
        /// Milliseconds spent reading the scan.
        load_ms: f64,
    },
    /// Other content than expected: not identified.
    Other(morphoid_data::hash::Content),
}

/// What identifying a job came to, before it is recorded: held by the
/// daemon's worker until the database takes it.
#[derive(Debug, Clone)]
pub(crate) enum Finding {
    /// The identification, to record as `ok`.
    Identified(ScanOutcome),
    /// A scan of several specimens, each identified on its own (or not).
    Specimens(SpecimensOutcome),
    /// Why the file cannot be identified, to record as `error`.
    Failed(String),
    /// The file no longer held the queued content when it was read: this
    /// content (not identified) is queued instead, and the job's row is
    /// recorded as `superseded`.
    Superseded(morphoid_data::hash::Content),
}

/// Identify the file of a claimed job (no database access): the outcome
/// with its total time, or the message of why it cannot be identified;
/// with `scene`, also what its report draws, one per specimen (computed
/// while the prepared scan is at hand; empty when not asked for or not
/// identified, `None` for a specimen that was not identified).
pub(crate) fn identify_job(
    classifier: &Classifier,
    job: &Job,
    scene: bool,
) -> (Finding, Vec<Option<Scene>>) {
    let started = Instant::now();
    let draw = |outcome: &ScanOutcome, surface: &PreparedSurface| {
        scene.then(|| {
            let mut nearest: Vec<(String, f64)> = outcome
                .distances
                .iter()
                .map(|d| (d.reference.clone(), d.distance))
                .collect();
            nearest.sort_by(|a, b| a.1.total_cmp(&b.1).then_with(|| a.0.cmp(&b.0)));
            classifier.scene(surface, &nearest, outcome.landmarks.as_ref())
        })
    };
    match classifier.identify_content(Path::new(&job.path), &job.content_hash) {
        Ok(Read::Other(content)) => (Finding::Superseded(content), Vec::new()),
        Ok(Read::Identified(found)) => {
            let (mut outcome, surface) = *found;
            outcome
                .timings_ms
                .insert("total".into(), started.elapsed().as_secs_f64() * 1e3);
            let scene = draw(&outcome, &surface);
            (Finding::Identified(outcome), vec![scene])
        }
        Ok(Read::Specimens {
            specimens,
            segmentation,
            load_ms,
        }) => {
            let mut scenes = Vec::new();
            let specimens = specimens
                .into_iter()
                .map(|(position, result)| {
                    let result = result.map(|(outcome, surface)| {
                        scenes.push(draw(&outcome, &surface));
                        outcome
                    });
                    if result.is_err() {
                        scenes.push(None);
                    }
                    SpecimenOutcome { position, result }
                })
                .collect();
            let timings_ms = BTreeMap::from([
                ("load".to_string(), load_ms),
                ("total".to_string(), started.elapsed().as_secs_f64() * 1e3),
            ]);
            let finding = Finding::Specimens(SpecimensOutcome {
                specimens,
                segmentation,
                timings_ms,
            });
            (finding, if scene { scenes } else { Vec::new() })
        }
        Err(e) => (Finding::Failed(e.to_string()), Vec::new()),
    }
}

/// Record a finding of the running scan `scan_id` in one transaction
/// (`ok` with the whole result, or `error`); returns the status recorded.
/// On a database failure nothing is recorded and the scan stays running.
pub(crate) fn record_finding(
    store: &mut Store,
    scan_id: i64,
    finding: &Finding,
) -> Result<ScanStatus, StoreError> {
    match finding {
        Finding::Identified(outcome) => {
            store.complete(scan_id, outcome)?;
            Ok(ScanStatus::Ok)
        }
        Finding::Specimens(outcome) => {
            store.complete_specimens(scan_id, outcome)?;
            Ok(if outcome.specimens.iter().any(|s| s.result.is_ok()) {
                ScanStatus::Ok
            } else {
                ScanStatus::Error
            })
        }
        Finding::Failed(message) => {
            store.fail(scan_id, message)?;
            Ok(ScanStatus::Error)
        }
        Finding::Superseded(content) => {
            store.supersede(scan_id, &content.hash, content.size)?;
            Ok(ScanStatus::Superseded)
        }
    }
}

/// Identify a claimed job and record the outcome: `ok` with the whole
/// result (landmarks included), or `error` with the message. Returns the
/// final status; only a database failure is an error (the job then stays
/// `running` and is requeued at the next start). With a results folder
/// ([`Classifier::with_result_files`]), the recorded result, its report and
/// the overview are then written there; a failure to write them is logged
/// and does not change the status (the database holds the result).
pub fn run_job(
    store: &mut Store,
    classifier: &Classifier,
    job: &Job,
) -> Result<ScanStatus, StoreError> {
    let (finding, scenes) = identify_job(classifier, job, classifier.results.is_some());
    let status = record_finding(store, job.scan_id, &finding)?;
    if let Some(files) = &classifier.results {
        match store.scan(job.scan_id, NEAREST) {
            Ok(Some(mut record)) => {
                // Each specimen's files first, then the scan's (its page
                // lists them) and the overview.
                for (i, child) in record.specimens.iter().enumerate() {
                    let child = ScanRecord {
                        files_error: None,
                        ..child.clone()
                    };
                    let scene = scenes.get(i).and_then(Option::as_ref);
                    let written = files
                        .write(&child)
                        .and_then(|_| files.write_report(&child, scene, None))
                        .map(|_| ());
                    if let Err(e) = &written {
                        tracing::error!(scan = %child.path, "result files not written: {e}");
                    }
                    record_files_attempt(store, child.id, &written)?;
                }
                let scene = match record.specimen_count {
                    None => scenes.first().and_then(Option::as_ref),
                    Some(_) => None,
                };
                // Written now, so no earlier failure belongs on the page.
                record.files_error = None;
                let written = write_result_files(store, files, &record, scene, None);
                if let Err(e) = &written {
                    tracing::error!(scan = %job.path, "result files not written: {e}");
                }
                record_files_attempt(store, job.scan_id, &written)?;
            }
            Ok(None) => tracing::error!(scan = %job.path, "the scan vanished from the database"),
            Err(e) => tracing::error!(scan = %job.path, "result files not written: {e}"),
        }
    }
    Ok(status)
}

/// Record in the scan's row how writing its result files went: the error
/// (naming the file and the cause) when it failed, nothing left of an
/// earlier failure when it worked. Whether they are due is not changed.
pub fn record_files_attempt(
    store: &mut Store,
    scan_id: i64,
    written: &Result<(), ResultsError>,
) -> Result<(), StoreError> {
    match written {
        Ok(()) => store.clear_files_error(scan_id),
        Err(e) => store.files_failed(scan_id, &error_chain(e)),
    }
}

/// All result files of a recorded scan: the JSON (and landmarks), the
/// report drawing `scene` (with `note` on the page), then the overview.
fn write_result_files(
    store: &mut Store,
    files: &ResultFiles,
    record: &ScanRecord,
    scene: Option<&Scene>,
    note: Option<&str>,
) -> Result<(), ResultsError> {
    files.write(record)?;
    files.write_report(record, scene, note)?;
    files.write_index(store)?;
    Ok(())
}

/// Why [`identify_file`] could not identify a file.
#[derive(Debug, thiserror::Error)]
pub enum IdentifyFileError {
    /// The file cannot be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The database failed.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// The scan's record is gone (another process removed it).
    #[error("{0}: the scan vanished from the database")]
    Vanished(PathBuf),
}

/// Identify the file or slice folder `path` through the store's queue, as the daemon
/// does, and return its record. Content identified before is not
/// identified again (its recorded result is returned); a failed one is
/// retried, and one left running by a process that died (or being run by
/// another) is taken over: if both finish, the store keeps the first
/// result.
pub fn identify_file(
    store: &mut Store,
    classifier: &Classifier,
    path: &Path,
) -> Result<ScanRecord, IdentifyFileError> {
    // Streamed: a scan (or a slice folder) is never read whole to hash it.
    let (hash, size) =
        morphoid_data::hash::content_hash_file(path).map_err(|source| IdentifyFileError::Read {
            path: path.to_path_buf(),
            source,
        })?;
    let shown = path.display().to_string();
    let id = match store.enqueue(&shown, &hash, size)? {
        store::Enqueued::New(id) => id,
        store::Enqueued::Existing(id, ScanStatus::Error) => {
            store.retry(id)?;
            id
        }
        store::Enqueued::Existing(id, ScanStatus::Running) => {
            store.abandon(id)?;
            id
        }
        // The record of a duplicate carries its earlier scan's result.
        store::Enqueued::Existing(id, _) | store::Enqueued::Duplicate { id, .. } => id,
    };
    let mut id = id;
    // A file that changes between hashing and reading is identified as
    // read: its job is superseded by the content read, taken next (a file
    // rewritten all the time ends after a few rounds, superseded).
    for _ in 0..SUPERSEDED_ROUNDS {
        if let Some(job) = store.claim(id)? {
            run_job(store, classifier, &job)?;
        }
        let record = store
            .scan(id, NEAREST)?
            .ok_or_else(|| IdentifyFileError::Vanished(path.to_path_buf()))?;
        match record.superseded_by {
            Some(next) if record.status == ScanStatus::Superseded => id = next,
            _ => return Ok(record),
        }
    }
    store
        .scan(id, NEAREST)?
        .ok_or_else(|| IdentifyFileError::Vanished(path.to_path_buf()))
}

/// How often [`identify_file`] follows a file that changed while it was
/// read before it reports the last row as it stands.
const SUPERSEDED_ROUNDS: usize = 4;

#[cfg(test)]
mod tests {
    use super::*;
    use morphoid_synth::mesh::{self as synth, LibrarySpec};

    #[test]
    fn build_moves_the_prepared_library_into_the_classifier() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("library");
        let spec = LibrarySpec {
            per_genus: 1,
            target_vertices: 600,
            seed: 5,
            random_pose: false,
        };
        synth::write_synthetic_library(&dir, &spec).unwrap();
        let library = Library::open(&dir, None).unwrap();
        let cache = Cache::open(&tmp.path().join("cache")).unwrap();
        let mut settings = Settings::default();
        settings.clean.target_vertices = 600;
        let (classifier, outcome) = Classifier::build(&library, &cache, &settings, |_| {}).unwrap();
        let n = library.members().len();
        assert_eq!((classifier.references().len(), outcome.prepared()), (n, n));
        // One copy of the prepared references, the classifier's: the
        // report a caller keeps must not hold a second one.
        assert!(outcome.references().is_empty());
        assert!(outcome.landmarks().by_name().is_empty());
        assert!(outcome.failures().is_empty());
    }

    /// A synthetic crown of `genus` (`seed`) and the whole tooth built
    /// below it, written as `dir/name`: the crown and the file.
    fn whole_tooth_file(
        dir: &Path,
        name: &str,
        genus: usize,
        seed: u64,
    ) -> (morphoid_core::mesh::Mesh, PathBuf) {
        let crown = synth::crown(&synth::CROWN_GENERA[genus], seed, 600);
        let whole = synth::whole_tooth(&crown, &synth::WholeToothParams::default(), seed).unwrap();
        let path = dir.join(name);
        morphoid_data::mesh_io::save(&path, &whole.mesh).unwrap();
        (crown, path)
    }

    /// An uncalibrated classifier of 10 synthetic crowns (2 per genus).
    fn small_classifier(tmp: &Path) -> (Classifier, Cache) {
        let dir = tmp.join("library");
        let spec = LibrarySpec {
            per_genus: 2,
            target_vertices: 600,
            seed: 7,
            random_pose: false,
        };
        synth::write_synthetic_library(&dir, &spec).unwrap();
        let library = Library::open(&dir, None).unwrap();
        let cache = Cache::open(&tmp.join("cache")).unwrap();
        let mut settings = Settings::default();
        settings.clean.target_vertices = 600;
        let (classifier, _) =
            Classifier::build_uncalibrated(&library, &cache, &settings, |_| {}).unwrap();
        (classifier, cache)
    }

    #[test]
    fn a_calibration_fitted_later_shares_the_library_and_equals_one_fitted_now() {
        let tmp = tempfile::tempdir().unwrap();
        let (classifier, cache) = small_classifier(tmp.path());
        assert_eq!(classifier.calibration_state(), CalibrationState::Off);
        let (later, pending) = classifier.clone().calibrate_later(Some(cache.clone()));
        let pending = pending.unwrap();
        // The references are shared with the calibration, not copied.
        assert!(Arc::ptr_eq(&later.references, &pending.references));
        assert!(Arc::ptr_eq(&later.references, &classifier.references));
        let probe = later.calibration_probe();
        assert_eq!(probe.state(), CalibrationState::Calibrating);
        assert!(later.calibration().is_none());
        let worker = later.clone();
        pending.run().unwrap();
        assert_eq!(probe.state(), CalibrationState::Ready);
        assert_eq!(worker.calibration_state(), CalibrationState::Ready);
        // The same model as the synchronous path (which reads the
        // distances the background run stored in the cache).
        let now = classifier.calibrated(Some(&cache));
        assert!(now.calibration().is_some());
        assert_eq!(worker.calibration(), now.calibration());
    }

    #[test]
    fn a_screened_identification_compares_fewer_references_and_answers_alike() {
        let tmp = tempfile::tempdir().unwrap();
        let (classifier, _) = small_classifier(tmp.path());
        let scan = tmp.path().join("scan.ply");
        let crown = synth::crown(&synth::CROWN_GENERA[2], 99, 600);
        morphoid_data::mesh_io::save(&scan, &crown).unwrap();
        let with = |screening: cp::Screening| {
            let mut settings = classifier.settings().clone();
            settings.cp.screen = cp::ScreenParams {
                screening,
                screen_keep: 3,
                screen_margin: 0.0,
                ..settings.cp.screen
            };
            classifier
                .clone()
                .with_settings(settings)
                .classify_file(&scan)
                .unwrap()
        };
        let exhaustive = with(cp::Screening::Off);
        let screened = with(cp::Screening::On);
        assert_eq!(exhaustive.distances.len(), 10);
        assert_eq!(screened.distances.len(), 3, "only the screen's three");
        assert!(screened.timings_ms.contains_key("screen"));
        assert!(!exhaustive.timings_ms.contains_key("screen"));
        // Every distance the screen kept is the exhaustive one, and the
        // nearest reference is among them.
        for row in &screened.distances {
            assert!(exhaustive.distances.contains(row), "{row:?}");
        }
        let answers = |o: &ScanOutcome| -> Vec<(String, String, f64)> {
            o.ranks
                .iter()
                .map(|r| (r.taxon.clone(), r.reference.clone(), r.distance))
                .collect()
        };
        assert_eq!(answers(&screened), answers(&exhaustive));
        // Under "auto", a library of 10 is compared whole.
        let auto = with(cp::Screening::Auto);
        assert_eq!(auto.distances.len(), 10);
    }

    /// A crown cut from a whole tooth is cut again along each of its
    /// nearest references' crop lines, then along the line they agree on
    /// and compared with every reference; each row keeps its smallest
    /// distance. A crown given as a file is never cut again, nor is any
    /// crown with `recut_nearest = 0`.
    #[test]
    fn a_crown_found_on_a_whole_tooth_is_cut_again_along_its_nearest_references() {
        let tmp = tempfile::tempdir().unwrap();
        let (classifier, _) = small_classifier(tmp.path());
        let (crown, whole_path) = whole_tooth_file(tmp.path(), "whole.stl", 3, 41);
        let crown_path = tmp.path().join("crown.ply");
        morphoid_data::mesh_io::save(&crown_path, &crown).unwrap();
        let with = |nearest: usize, path: &Path| {
            let mut settings = classifier.settings().clone();
            settings.cp.recut.recut_nearest = nearest;
            classifier
                .clone()
                .with_settings(settings)
                .classify_file(path)
                .unwrap()
        };
        let plain = with(0, &whole_path);
        assert!(plain.cleaning.get("recut").is_none());
        let recut = with(3, &whole_path);
        let listed = recut.cleaning["recut"]["references"]
            .as_array()
            .expect("the references re-cut listed");
        assert_eq!(listed.len(), 3);
        // The three were the nearest as first cut, and their rows hold at
        // most the smaller distance.
        let mut nearest: Vec<&DistanceRow> = plain.distances.iter().collect();
        nearest.sort_by(|a, b| a.distance.total_cmp(&b.distance));
        let mut voters = Vec::new();
        for entry in listed {
            let name = entry["reference"].as_str().unwrap();
            let (before, after) = (
                entry["before"].as_f64().unwrap(),
                entry["after"].as_f64().unwrap(),
            );
            assert!(nearest[..3]
                .iter()
                .any(|r| r.reference == name && r.distance == before));
            let row = recut
                .distances
                .iter()
                .find(|r| r.reference == name)
                .unwrap();
            assert!(row.distance <= before.min(after), "{name}");
            voters.push(name.to_string());
        }
        // Those three voted on the first common cut; every reference was
        // compared with it, and no row grew.
        let rounds = recut.cleaning["recut"]["consensus"]
            .as_array()
            .expect("the common cuts listed");
        assert!(!rounds.is_empty() && rounds.len() <= 2, "{rounds:?}");
        let mut first: Vec<String> = rounds[0]["references"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap().to_string())
            .collect();
        first.sort();
        voters.sort();
        assert_eq!(first, voters);
        for round in rounds {
            assert!(round["faces"].as_u64().unwrap() > 0);
            let nearest = round["nearest"].as_str().unwrap();
            let row = recut
                .distances
                .iter()
                .find(|r| r.reference == nearest)
                .unwrap();
            assert!(row.distance <= round["distance"].as_f64().unwrap());
        }
        assert_eq!(recut.distances.len(), plain.distances.len());
        for row in &recut.distances {
            let before = plain
                .distances
                .iter()
                .find(|r| r.reference == row.reference)
                .unwrap();
            assert!(row.distance <= before.distance, "{row:?}");
        }
        assert!(recut.timings_ms.contains_key("recut"));
        assert!(with(3, &crown_path).cleaning.get("recut").is_none());
    }

    /// After the cuts along the references' lines, the scan's crown is the
    /// last common cut's: in the file's units, on the first crown, its
    /// cleaned and prepared forms one surface (what landmarks and the
    /// report take).
    #[test]
    fn the_crown_cut_again_becomes_the_scans_crown_in_the_files_units() {
        let tmp = tempfile::tempdir().unwrap();
        let (classifier, _) = small_classifier(tmp.path());
        let (_, path) = whole_tooth_file(tmp.path(), "whole.ply", 1, 43);
        let mut settings = classifier.settings().clone();
        settings.cp.recut.recut_nearest = 3;
        let classifier = classifier.with_settings(settings);
        let mut surface = pipeline::prepare_file(&path, classifier.settings()).unwrap();
        let first = surface.cleaned.clone();
        let first_faces = surface.prepared.faces().len();
        let outcome = classifier.classify_prepared(&mut surface);
        let rounds = outcome.cleaning["recut"]["consensus"]
            .as_array()
            .expect("the common cuts listed");
        assert!(!rounds.is_empty());
        // The last cut kept part of the crown before it, which kept part
        // of the first.
        let kept = rounds.last().unwrap()["faces"].as_u64().unwrap() as usize;
        assert!(kept <= first_faces);
        let area = |m: &morphoid_core::mesh::Mesh| morphoid_core::mesh::surface_area(m);
        let (now, before) = (area(&surface.cleaned), area(&first));
        assert!(
            now > 0.3 * before && now < 1.02 * before,
            "{now} of {before}"
        );
        // One surface: the prepared vertices, unnormalized, are the cleaned.
        let (scale, centroid) = (surface.prepared.scale(), surface.prepared.centroid());
        assert_eq!(
            surface.prepared.vertices().len(),
            surface.cleaned.vertices.len()
        );
        let diagonal = morphoid_core::mesh::bbox_diagonal(&first);
        for (p, c) in surface
            .prepared
            .vertices()
            .iter()
            .zip(&surface.cleaned.vertices)
        {
            for d in 0..3 {
                assert!((p[d] * scale + centroid[d] - c[d]).abs() < 1e-9 * diagonal);
            }
        }
        // In the file's units, on the first crown.
        for c in &surface.cleaned.vertices {
            let nearest = first
                .vertices
                .iter()
                .map(|v| morphoid_core::mesh::norm(morphoid_core::mesh::sub(*v, *c)))
                .fold(f64::INFINITY, f64::min);
            // (the cut is cleaned again: vertices move by up to an edge)
            assert!(nearest < 0.05 * diagonal, "{nearest} of {diagonal}");
        }
    }

    /// `mesh` with its heights (z) scaled by `factor`: another crown of
    /// the same scan, cut differently.
    fn squashed(mesh: &morphoid_core::mesh::Mesh, factor: f64) -> morphoid_core::mesh::Mesh {
        morphoid_core::mesh::Mesh::new(
            mesh.vertices
                .iter()
                .map(|p| [p[0], p[1], factor * p[2]])
                .collect(),
            mesh.faces.clone(),
        )
    }

    /// Of the crowns the cleaning found on a whole tooth, the one whose
    /// nearest reference is nearest is taken, and the answer is that
    /// crown's: here an alternative that is a reference's own crown (at
    /// distance zero) replaces the cut, while a far one is left aside.
    /// Nothing is weighed with `recut_nearest = 0`.
    #[test]
    fn of_the_margins_found_the_crown_nearest_the_library_is_taken() {
        let tmp = tempfile::tempdir().unwrap();
        let (classifier, _) = small_classifier(tmp.path());
        let (_, path) = whole_tooth_file(tmp.path(), "whole.stl", 2, 57);
        let settings = classifier.settings().clone();
        let cut = pipeline::prepare_file(&path, &settings).unwrap();
        assert!(cut.cleaning.crown.is_some());
        let reference = classifier.references()[4].clone();
        let own = |prepared: &cp::Prepared, cleaned: &morphoid_core::mesh::Mesh| {
            let mut prepared = prepared.clone();
            prepared.set_name(cut.prepared.name());
            pipeline::AlternativeCut {
                cleaned: cleaned.clone(),
                prepared,
            }
        };
        let near = own(&reference.prepared().unwrap(), &cut.cleaned);
        // A far crown: the scan's own, flattened to a tenth of its height.
        let flat = squashed(&cut.cleaned, 0.1);
        let far = own(&cp::prepare(&flat, &settings.cp.prepare).unwrap(), &flat);

        let mut surface = cut.clone();
        surface.alternatives = vec![far.clone(), near.clone()];
        let outcome = classifier.classify_prepared(&mut surface);
        let margin = &outcome.cleaning["margins"];
        assert_eq!(margin["chosen"], 2, "{margin}");
        assert_eq!(margin["crowns"].as_array().unwrap().len(), 3);
        assert_eq!(margin["crowns"][2]["nearest"], reference.name());
        assert!(margin["crowns"][2]["distance"].as_f64().unwrap() < 1e-6);
        // The answer is the taken crown's; the crown it replaced took its
        // place among the alternatives. (The scan's crown is then the one
        // the cuts along the references' lines leave: the test above.)
        let nearest = outcome
            .distances
            .iter()
            .min_by(|a, b| a.distance.total_cmp(&b.distance))
            .unwrap();
        assert_eq!(nearest.reference, reference.name());
        assert_eq!(
            surface.alternatives[1].prepared.faces(),
            cut.prepared.faces()
        );
        assert_eq!(
            surface.alternatives[0].prepared.faces(),
            far.prepared.faces()
        );
        assert!(outcome.timings_ms.contains_key("margins"));

        let mut surface = cut.clone();
        surface.alternatives = vec![far.clone()];
        let outcome = classifier.classify_prepared(&mut surface);
        assert_eq!(outcome.cleaning["margins"]["chosen"], 0);
        assert_eq!(
            surface.alternatives[0].prepared.faces(),
            far.prepared.faces()
        );

        let mut off = settings.clone();
        off.cp.recut.recut_nearest = 0;
        let mut surface = cut.clone();
        surface.alternatives = vec![near];
        let outcome = classifier
            .clone()
            .with_settings(off)
            .classify_prepared(&mut surface);
        assert!(outcome.cleaning.get("margins").is_none());
        assert_eq!(surface.prepared.faces(), cut.prepared.faces());
    }

    /// `[cp] recut_among = k`: the other crowns are compared with the k
    /// references nearest the crown as cut, each common cut with those
    /// nearest so far and the references that voted on it; with 0, each
    /// with the screen's choice (every reference, in a library this
    /// small).
    #[test]
    fn recut_among_bounds_the_references_the_other_crowns_and_common_cuts_meet() {
        let tmp = tempfile::tempdir().unwrap();
        let (classifier, _) = small_classifier(tmp.path());
        let n = classifier.references().len();
        let (_, path) = whole_tooth_file(tmp.path(), "whole.ply", 1, 43);
        let cut = pipeline::prepare_file(&path, classifier.settings()).unwrap();
        assert!(cut.cleaning.crown.is_some());
        // One other crown to weigh: the scan's own, lowered a little.
        let lowered = squashed(&cut.cleaned, 0.8);
        let mut other = cp::prepare(&lowered, &classifier.settings().cp.prepare).unwrap();
        other.set_name(cut.prepared.name());
        let alternative = pipeline::AlternativeCut {
            cleaned: lowered,
            prepared: other,
        };
        let compared = |among: usize| {
            let mut settings = classifier.settings().clone();
            settings.cp.recut.recut_nearest = 3;
            settings.cp.recut.recut_among = among;
            let mut surface = cut.clone();
            surface.alternatives = vec![alternative.clone()];
            let outcome = classifier
                .clone()
                .with_settings(settings)
                .classify_prepared(&mut surface);
            let count = |v: &serde_json::Value| v["compared"].as_u64().unwrap() as usize;
            let crowns = outcome.cleaning["margins"]["crowns"]
                .as_array()
                .unwrap()
                .clone();
            let rounds = outcome.cleaning["recut"]["consensus"]
                .as_array()
                .unwrap()
                .clone();
            assert!(!rounds.is_empty());
            assert_eq!(
                count(&crowns[0]),
                n,
                "the crown as cut meets every reference"
            );
            let voters = |r: &serde_json::Value| r["references"].as_array().unwrap().len();
            (
                crowns[1..].iter().map(count).collect::<Vec<_>>(),
                rounds
                    .iter()
                    .map(|r| (count(r), voters(r)))
                    .collect::<Vec<_>>(),
            )
        };
        let (others, rounds) = compared(2);
        assert_eq!(others, vec![2]);
        for (c, voters) in rounds {
            assert!(
                (2..=2 + voters).contains(&c),
                "{c} compared, {voters} voters"
            );
        }
        let (others, rounds) = compared(0);
        assert_eq!(others, vec![n]);
        assert!(rounds.iter().all(|&(c, _)| c == n), "{rounds:?}");
    }

    /// References are held in the cache, not in memory; one whose entry
    /// is deleted while the classifier runs is left out of the answers,
    /// and the others are compared as before.
    #[test]
    fn a_reference_gone_from_the_cache_is_left_out_of_the_answer() {
        let tmp = tempfile::tempdir().unwrap();
        let (classifier, cache) = small_classifier(tmp.path());
        assert!(classifier.references().iter().all(|r| !r.is_resident()));
        let scan = tmp.path().join("scan.ply");
        let crown = synth::crown(&synth::CROWN_GENERA[1], 98, 600);
        morphoid_data::mesh_io::save(&scan, &crown).unwrap();
        let whole = classifier.classify_file(&scan).unwrap();
        assert_eq!(whole.distances.len(), 10);
        let gone = classifier.references()[0].name().to_string();
        for entry in std::fs::read_dir(cache.dir()).unwrap() {
            let path = entry.unwrap().path();
            if path
                .file_name()
                .is_some_and(|f| f.to_string_lossy().starts_with(&format!("{gone}.")))
            {
                std::fs::remove_file(path).unwrap();
            }
        }
        let without = classifier.classify_file(&scan).unwrap();
        assert_eq!(without.distances.len(), 9);
        assert!(without.distances.iter().all(|d| d.reference != gone));
        for row in &without.distances {
            assert!(whole.distances.contains(row), "{row:?}");
        }
    }

    #[test]
    fn a_calibration_that_never_runs_counts_as_failed() {
        let tmp = tempfile::tempdir().unwrap();
        let (classifier, _) = small_classifier(tmp.path());
        let (later, pending) = classifier.calibrate_later(None);
        assert_eq!(later.calibration_state(), CalibrationState::Calibrating);
        drop(pending);
        assert_eq!(later.calibration_state(), CalibrationState::Failed);
        assert!(later.calibration().is_none());
    }
}
