//! The preparation pipeline every surface goes through, from a file to a
//! [`Prepared`] surface: load, clean, prepare. One function so that the
//! command line, the library build and the daemon treat a scan the same way.

use crate::mesh_io::{self, LoadError};
use crate::volume;
use crate::volume::{VolumeError, VolumeReport};
use morphoid_core::clean::{self, CleanError, CleanOptions, CleanReport};
use morphoid_core::cp::{self, CpError, CpParams, Prepared};
use morphoid_core::mesh::Mesh;
use morphoid_core::volume::VolumeOptions;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Parameters of the whole preparation.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Settings {
    /// Cleaning parameters.
    pub clean: CleanOptions,
    /// cP engine parameters.
    pub cp: CpParams,
    /// Slice stacks and volume files.
    #[serde(default)]
    pub volume: VolumeOptions,
}

/// Wall time of each stage, in milliseconds.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct StageTimings {
    /// Reading the file.
    pub load: f64,
    /// Cleaning and resampling.
    pub clean: f64,
    /// Normalization, flattening, features and samples.
    pub prepare: f64,
}

/// A surface ready for comparisons, with what was done to get there.
#[derive(Debug, Clone)]
pub struct PreparedSurface {
    /// The cleaned surface in the units of the file.
    pub cleaned: Mesh,
    /// The prepared form the cP engine compares.
    pub prepared: Prepared,
    /// What cleaning changed.
    pub cleaning: CleanReport,
    /// Time spent in each stage.
    pub timings: StageTimings,
    /// What was done to a volume (slice folder, NRRD, NIfTI); `None` for
    /// a surface file.
    pub volume: Option<VolumeReport>,
    /// For a crown cut from a whole tooth, the crowns of the other margins
    /// found ([`clean::Cleaned::alternatives`]), prepared; empty when the
    /// cut is not to be judged by the library (`[cp] recut_nearest = 0`).
    pub alternatives: Vec<AlternativeCut>,
}

/// Another crown cut from the same whole tooth, cleaned and prepared.
#[derive(Debug, Clone)]
pub struct AlternativeCut {
    /// The cleaned crown.
    pub cleaned: Mesh,
    /// Its prepared form.
    pub prepared: Prepared,
}

impl PreparedSurface {
    /// Take alternative `k` for the scan's crown: it becomes `cleaned` and
    /// `prepared`, and the crown it replaces takes its place among the
    /// alternatives.
    pub fn take_alternative(&mut self, k: usize) {
        if let Some(a) = self.alternatives.get_mut(k) {
            std::mem::swap(&mut self.cleaned, &mut a.cleaned);
            std::mem::swap(&mut self.prepared, &mut a.prepared);
        }
    }
}

/// Why a file could not be prepared; every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The file could not be read (the message names the file).
    #[error(transparent)]
    Load(#[from] LoadError),
    /// The volume could not be read or segmented (the message names it).
    #[error(transparent)]
    Volume(#[from] VolumeError),
    /// The surface could not be made disk-type.
    #[error("{path}: {source}")]
    Clean {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        source: CleanError,
    },
    /// The surface could not be flattened or prepared.
    #[error("{path}: {source}")]
    Prepare {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        source: CpError,
    },
    /// The file holds several specimens where one was expected (a
    /// reference, or a caller that takes one surface).
    #[error(
        "{path}: holds {count} specimens; one surface was expected here (identify a batch \
         scan with `classify` or the daemon, which take its specimens one by one)"
    )]
    Several {
        /// The file.
        path: PathBuf,
        /// How many specimens it holds.
        count: usize,
    },
}

/// The specimen name of a surface file: its stem (`a/B03.ply` → `B03`).
pub fn specimen_name(path: &Path) -> String {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    // `x.nii.gz` is specimen `x`.
    match stem.strip_suffix(".nii") {
        Some(s)
            if path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("gz")) =>
        {
            s.to_string()
        }
        _ => stem,
    }
}

/// Load, clean and prepare the surface in `path`; the prepared surface is
/// named after the file stem. A folder of slices, `.nrrd`, `.nii` or
/// `.nii.gz` is a volume: it is segmented into a surface first
/// ([`volume::surface_from_path`]), and its report is kept.
pub fn prepare_file(path: &Path, settings: &Settings) -> Result<PreparedSurface, PipelineError> {
    let loaded = load(path, settings, false)?;
    prepare_loaded(loaded, path, settings)
}

/// Where one specimen lies in its scan.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Position {
    /// First and last voxel along x, y, z (inclusive) in the input's
    /// voxels; `None` for a surface file.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub voxels: Option<[[usize; 3]; 2]>,
    /// The specimen's bounding box (lowest and highest corner) in the
    /// file's coordinates.
    pub bounds: [[f64; 3]; 2],
}

/// One specimen of a scan, as read.
#[derive(Debug, Clone)]
pub struct LoadedSpecimen {
    /// Its surface as read (or made from the volume).
    pub mesh: Mesh,
    /// Where it lies in the scan.
    pub position: Position,
}

/// A scan as read, before cleaning: the surface of each specimen (from a
/// volume, with its report) and, when asked for, the content of exactly
/// the bytes read.
#[derive(Debug, Clone)]
pub struct LoadedScan {
    /// The specimens, in their documented order (along the volume's or the
    /// file's longest axis); one for a single specimen.
    pub specimens: Vec<LoadedSpecimen>,
    /// What was done to a volume; `None` for a surface file.
    pub volume: Option<VolumeReport>,
    /// For a surface file of several specimens, what was split off.
    pub split: Option<SplitReport>,
    /// The surface file's format; `None` for a volume.
    pub format: Option<mesh_io::Format>,
    /// The content read ([`load_hashed`]; `None` from [`prepare_file`]'s
    /// path, which does not hash).
    pub content: Option<crate::hash::Content>,
    /// Milliseconds spent reading.
    pub load_ms: f64,
}

/// What the split of a surface file into specimens dropped.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SplitReport {
    /// Specimens found.
    pub specimens: usize,
    /// Components dropped as debris or fragments.
    pub debris: usize,
    /// Closed components inside a specimen (cavities, canals, cracks).
    pub nested: usize,
}

/// The first step of [`prepare_file`], hashing as it reads: the file (or
/// every slice of a folder) is read once, and the surface and
/// [`LoadedScan::content`] are of the same bytes, however the file changes
/// meanwhile. What the daemon identifies is thus the content it records.
pub fn load_hashed(path: &Path, settings: &Settings) -> Result<LoadedScan, PipelineError> {
    load(path, settings, true)
}

/// [`load_hashed`] without hashing.
pub fn load_scan(path: &Path, settings: &Settings) -> Result<LoadedScan, PipelineError> {
    load(path, settings, false)
}

fn load(path: &Path, settings: &Settings, hashed: bool) -> Result<LoadedScan, PipelineError> {
    let name = specimen_name(path);
    let t = Instant::now();
    let mut format = None;
    let (specimens, volume, split, content) = if volume::is_volume_path(path) {
        let _s = tracing::debug_span!("volume", scan = %name).entered();
        let (s, content) = if hashed {
            let (s, content) = volume::surface_from_path_hashed(path, &settings.volume)?;
            (s, Some(content))
        } else {
            (volume::surface_from_path(path, &settings.volume)?, None)
        };
        let specimens = s
            .specimens
            .into_iter()
            .map(|v| LoadedSpecimen {
                position: Position {
                    voxels: Some(v.voxels),
                    bounds: bounds_of(&v.mesh),
                },
                mesh: v.mesh,
            })
            .collect();
        (specimens, Some(s.report), None, content)
    } else {
        let _s = tracing::debug_span!("load", scan = %name).entered();
        let (loaded, content) = if hashed {
            let (m, content) = mesh_io::load_hashed(path)?;
            (m, Some(content))
        } else {
            (mesh_io::load(path)?, None)
        };
        format = Some(loaded.format);
        let mesh = loaded.mesh;
        match clean::surface_specimens(&mesh, settings.clean.weld_tolerance) {
            Some(found) => {
                let split = SplitReport {
                    specimens: found.parts.len(),
                    debris: found.debris,
                    nested: found.nested,
                };
                let specimens = found
                    .parts
                    .into_iter()
                    .map(|mesh| LoadedSpecimen {
                        position: Position {
                            voxels: None,
                            bounds: bounds_of(&mesh),
                        },
                        mesh,
                    })
                    .collect();
                (specimens, None, Some(split), content)
            }
            None => {
                let position = Position {
                    voxels: None,
                    bounds: bounds_of(&mesh),
                };
                (vec![LoadedSpecimen { mesh, position }], None, None, content)
            }
        }
    };
    Ok(LoadedScan {
        specimens,
        volume,
        split,
        format,
        content,
        load_ms: ms(t),
    })
}

fn bounds_of(mesh: &Mesh) -> [[f64; 3]; 2] {
    morphoid_core::mesh::bounding_box(mesh).map_or([[0.0; 3]; 2], |(lo, hi)| [lo, hi])
}

/// The rest of [`prepare_file`] for a scan of one specimen: clean and
/// prepare it (`path` names it and its errors). A scan of several
/// specimens is an error here ([`PipelineError::Several`]); take them one
/// by one with [`prepare_specimens`].
pub fn prepare_loaded(
    loaded: LoadedScan,
    path: &Path,
    settings: &Settings,
) -> Result<PreparedSurface, PipelineError> {
    if loaded.specimens.len() != 1 {
        return Err(PipelineError::Several {
            path: path.to_path_buf(),
            count: loaded.specimens.len(),
        });
    }
    prepare_specimens(loaded, path, settings)
        .pop()
        .map(|(_, prepared)| prepared)
        .unwrap_or(Err(PipelineError::Several {
            path: path.to_path_buf(),
            count: 0,
        }))
}

/// Clean and prepare each specimen of a scan read from `path`, in order,
/// each with its position: one failing does not stop the others. A
/// specimen of a scan of several is named `<stem>#n` (1-based).
#[allow(clippy::type_complexity)]
pub fn prepare_specimens(
    loaded: LoadedScan,
    path: &Path,
    settings: &Settings,
) -> Vec<(Position, Result<PreparedSurface, PipelineError>)> {
    let stem = specimen_name(path);
    let LoadedScan {
        specimens,
        volume: volume_report,
        load_ms,
        ..
    } = loaded;
    let several = specimens.len() > 1;
    // The specimens of a batch are cleaned side by side.
    specimens
        .into_par_iter()
        .enumerate()
        .map(|(i, s)| {
            let name = if several {
                format!("{stem}#{}", i + 1)
            } else {
                stem.clone()
            };
            let _span = several.then(|| tracing::info_span!("specimen", scan = %name).entered());
            let prepared = prepare_mesh(&s.mesh, &name, settings)
                .map(|mut p| {
                    p.timings.load = load_ms;
                    p.volume = volume_report.clone();
                    p
                })
                .map_err(|e| {
                    let path = if several {
                        PathBuf::from(format!("{}#{}", path.display(), i + 1))
                    } else {
                        path.to_path_buf()
                    };
                    match e {
                        MeshError::Clean(source) => PipelineError::Clean { path, source },
                        MeshError::Prepare(source) => PipelineError::Prepare { path, source },
                    }
                });
            (s.position, prepared)
        })
        .collect()
}

/// Why a mesh could not be prepared (no file involved).
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The surface could not be made disk-type.
    #[error(transparent)]
    Clean(#[from] CleanError),
    /// The surface could not be flattened or prepared.
    #[error(transparent)]
    Prepare(#[from] CpError),
}

/// Clean and prepare a mesh already in memory, naming the result `name`.
pub fn prepare_mesh(
    mesh: &Mesh,
    name: &str,
    settings: &Settings,
) -> Result<PreparedSurface, MeshError> {
    let t = Instant::now();
    let cleaned = {
        let _s = tracing::debug_span!("clean", scan = %name).entered();
        clean::clean(mesh, &settings.clean)?
    };
    let clean_ms = ms(t);
    let t = Instant::now();
    // The other crowns found are prepared beside the chosen one.
    let (prepared, alternatives) = rayon::join(
        || {
            let _s = tracing::debug_span!("prepare", scan = %name).entered();
            cp::prepare(&cleaned.mesh, &settings.cp.prepare)
        },
        || {
            if settings.cp.recut.recut_nearest > 0 {
                alternative_cuts(cleaned.alternatives, name, &settings.cp)
            } else {
                Vec::new()
            }
        },
    );
    let mut prepared = prepared?;
    prepared.set_name(name);
    Ok(PreparedSurface {
        cleaned: cleaned.mesh,
        prepared,
        cleaning: cleaned.report,
        timings: StageTimings {
            load: 0.0,
            clean: clean_ms,
            prepare: ms(t),
        },
        volume: None,
        alternatives,
    })
}

/// The crowns of `alternatives` prepared, named `name`; one that cannot
/// be prepared is left out (the crown the cleaning chose stands).
fn alternative_cuts(alternatives: Vec<Mesh>, name: &str, params: &CpParams) -> Vec<AlternativeCut> {
    alternatives
        .into_par_iter()
        .filter_map(|cleaned| {
            let mut prepared = cp::prepare(&cleaned, &params.prepare).ok()?;
            prepared.set_name(name);
            Some(AlternativeCut { cleaned, prepared })
        })
        .collect()
}

/// [`prepare_file`] for several files, in parallel, in their order; the
/// first failure stops it.
pub fn prepare_files(
    paths: &[&Path],
    settings: &Settings,
) -> Result<Vec<PreparedSurface>, PipelineError> {
    paths
        .par_iter()
        .map(|p| prepare_file(p, settings))
        .collect()
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
