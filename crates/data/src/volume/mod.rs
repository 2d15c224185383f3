//! Slice stacks and volumes (a folder of TIFF/PNG/BMP slices, a DICOM
//! series, NRRD, NIfTI-1) to a surface the cleaning step takes.
//!
//! A reader yields slices one at a time (`stack`, `dicom`, `nrrd`,
//! `nifti`), each hashed as it is read; they are averaged into the working
//! grid on the fly (memory is the working grid, a finer detail grid and one
//! slice), and `morphoid_core::volume::grid_surface` makes the specimens'
//! surfaces from it. Each closed surface is returned for the cleaning
//! step's crown extraction.

mod dicom;
mod dicom_scan;
mod nifti;
mod nrrd;
mod source;
mod stack;

pub(crate) use dicom::slice_positions_along_normal;
pub use dicom_scan::{BrokenFraming, DicomFramingError};
pub use source::VolumeFormat;
pub(crate) use source::VolumeInfo;
pub use stack::{slice_format, slice_paths};

use crate::hash::Content;
use morphoid_core::mesh::Grid;
use morphoid_core::mesh::Mesh;
use morphoid_core::volume::{
    grid_surface, reduction_factor, BlockAverage, GridSurfaces, SegmentReport, Thresholds,
    VolumeOptions,
};
use source::SliceSource;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What was done to turn a volume into a surface.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VolumeReport {
    /// Size and sampling of the volume as read.
    pub input: VolumeInfo,
    /// Block size of the reduction to the working grid.
    pub reduction_factor: usize,
    /// Samples of the working grid.
    pub working_dims: [usize; 3],
    /// Thresholds found, in the file's grey values.
    pub thresholds: Thresholds,
    /// Components and cavities.
    pub segmentation: SegmentReport,
    /// Triangles of the closed isosurface.
    pub isosurface_faces: usize,
    /// Area of the closed isosurface (units of `input.unit`²).
    pub isosurface_area: f64,
    /// Whether the crown was cut over enamel.
    pub enamel_found: bool,
    /// Area of the crown kept over enamel (0 without enamel).
    pub crown_area: f64,
    /// Separate regions over enamel (the largest is the crown).
    pub enamel_regions: usize,
    /// Milliseconds: reading and reduction, segmentation, isosurface, crown.
    pub timings_ms: VolumeTimings,
}

/// Wall time of each volume stage, in milliseconds.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VolumeTimings {
    /// Reading every slice and averaging it into the working grid.
    pub read: f64,
    /// Thresholds, components, cavities.
    pub segment: f64,
    /// The closed isosurface.
    pub isosurface: f64,
    /// Sampling under the surface and cutting the crown.
    pub crown: f64,
}

/// One specimen's surface made from a volume.
#[derive(Debug, Clone)]
pub struct VolumeSpecimen {
    /// The crown (open) where enamel was found, else the closed surface.
    pub mesh: Mesh,
    /// First and last voxel along x, y, z, inclusive, in the input's voxels.
    pub voxels: [[usize; 3]; 2],
}

/// The surfaces made from a volume and how.
#[derive(Debug, Clone)]
pub struct VolumeSurface {
    /// The specimens, in order along the grid's longest axis (one for a
    /// single specimen).
    pub specimens: Vec<VolumeSpecimen>,
    /// What was done.
    pub report: VolumeReport,
}

/// Why a volume could not be made into a surface; every message names the
/// file or folder.
#[derive(Debug, thiserror::Error)]
pub enum VolumeError {
    /// Reading failed.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A TIFF slice could not be decoded (truncated or malformed).
    #[error("{path}: cannot decode the TIFF slice: {source}")]
    Tiff {
        /// The slice file.
        path: PathBuf,
        /// The decoder's error.
        source: tiff::TiffError,
    },
    /// A PNG or BMP slice could not be decoded.
    #[error("{path}: cannot decode the slice: {source}")]
    Image {
        /// The slice file.
        path: PathBuf,
        /// The decoder's error.
        source: image::ImageError,
    },
    /// A DICOM file could not be parsed.
    #[error("{path}: cannot read the DICOM file: {source}")]
    Dicom {
        /// The file.
        path: PathBuf,
        /// The parser's error.
        source: Box<dicom_object::ReadError>,
    },
    /// A DICOM file's framing is corrupt: a length runs past the end or
    /// splits a value, or the framing cannot be followed (checked before
    /// the parser reads the file).
    #[error("{path}: {source}")]
    DicomFraming {
        /// The file.
        path: PathBuf,
        /// What is wrong with the framing.
        source: DicomFramingError,
    },
    /// The volume is malformed or unusable (the problem says why).
    #[error("{path}: {problem}")]
    Invalid {
        /// The file or folder.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}

impl VolumeError {
    /// The error for an unusable file or folder `path`; `problem` says why.
    pub(crate) fn invalid(path: &Path, problem: String) -> VolumeError {
        VolumeError::Invalid {
            path: path.to_path_buf(),
            problem,
        }
    }
}

/// Whether `path` names a volume: a folder, or a `.nrrd`, `.nii`, `.nii.gz`.
pub fn is_volume_path(path: &Path) -> bool {
    path.is_dir() || volume_file_format(path).is_some()
}

fn volume_file_format(path: &Path) -> Option<VolumeFormat> {
    let name = path.file_name()?.to_str()?.to_ascii_lowercase();
    if name.ends_with(".nrrd") {
        Some(VolumeFormat::Nrrd)
    } else if name.ends_with(".nii") || name.ends_with(".nii.gz") {
        Some(VolumeFormat::Nifti)
    } else {
        None
    }
}

/// The reader of the volume at `path`; with `hashed`, one that hashes the
/// bytes it reads.
fn open(path: &Path, hashed: bool) -> Result<Box<dyn SliceSource>, VolumeError> {
    let hash = hashed.then(crate::hash::SharedHash::new);
    Ok(match volume_file_format(path) {
        Some(VolumeFormat::Nrrd) => Box::new(nrrd::open(path, hash)?),
        Some(_) => Box::new(nifti::open(path, hash)?),
        None => {
            let (files, format) = stack::slice_files(path)?;
            if format == VolumeFormat::Dicom {
                Box::new(dicom::DicomSeries::open(path, files, hashed)?)
            } else {
                Box::new(stack::SliceFolder::open(files, format, hashed)?)
            }
        }
    })
}

/// The working grid of a volume as read, its block size, the finer detail
/// grid (when finer than the working grid), and the content read when
/// hashed.
type WorkingGrid = (Grid, VolumeInfo, usize, Option<Grid>, Option<Content>);

/// Read the volume at `path` slice by slice into the working grid.
fn read_working_grid(
    path: &Path,
    opts: &VolumeOptions,
    hashed: bool,
) -> Result<WorkingGrid, VolumeError> {
    reduce_source(open(path, hashed)?, path, opts)
}

/// Read every slice of `source` (the volume at `path`, which names
/// errors) into the working grid.
fn reduce_source(
    mut source: Box<dyn SliceSource>,
    path: &Path,
    opts: &VolumeOptions,
) -> Result<WorkingGrid, VolumeError> {
    let info = source.info().clone();
    if info.dims[2] < 2 {
        return Err(VolumeError::Invalid {
            path: path.to_path_buf(),
            problem: "only one slice: a volume needs at least two".into(),
        });
    }
    let factor = reduction_factor(info.dims, opts.working_voxels);
    let mut reducer = BlockAverage::new(info.dims, info.voxel_size, factor);
    // A batch's specimens are each made again from a finer grid.
    let fine = morphoid_core::volume::detail_factor(info.dims);
    let mut detail = (fine < factor).then(|| BlockAverage::new(info.dims, info.voxel_size, fine));
    let expected = info.dims[0] * info.dims[1];
    let check = |slice: &[f32]| {
        if slice.len() == expected {
            Ok(())
        } else {
            Err(VolumeError::Invalid {
                path: path.to_path_buf(),
                problem: format!("a slice has {} samples, {expected} expected", slice.len()),
            })
        }
    };
    let (mut slice, mut next) = (Vec::new(), Vec::new());
    source.next_slice(&mut slice)?;
    check(&slice)?;
    for k in 0..info.dims[2] {
        let more = k + 1 < info.dims[2];
        // The next slice is read (decoded, hashed) while this one is
        // added into the grids: the two take about as long.
        let (read, ()) = rayon::join(
            || {
                if more {
                    source.next_slice(&mut next)
                } else {
                    Ok(())
                }
            },
            || {
                reducer.push(&slice);
                if let Some(d) = &mut detail {
                    d.push(&slice);
                }
            },
        );
        read?;
        if more {
            check(&next)?;
            std::mem::swap(&mut slice, &mut next);
        }
    }
    let content = source.content()?;
    Ok((
        reducer.finish(),
        info,
        factor,
        detail.map(BlockAverage::finish),
        content,
    ))
}

/// Decode one slice file held in memory, as a slice folder or a DICOM
/// series decodes each of its files: a TIFF, PNG or BMP image, or a
/// single-frame DICOM file (header checked, rescaled). Returns the width
/// and height and the values, x fastest; `name` only labels errors. NRRD
/// and NIfTI hold whole volumes: see [`working_grid_from_bytes`].
pub fn decode_slice_bytes(
    bytes: &[u8],
    format: VolumeFormat,
    name: &Path,
) -> Result<([usize; 2], Vec<f32>), VolumeError> {
    match format {
        VolumeFormat::Dicom => dicom::decode_file(name, bytes),
        VolumeFormat::Tiff | VolumeFormat::Png | VolumeFormat::Bmp => {
            let (w, h, _, values) = stack::decode_slice(name, bytes, format)?;
            Ok(([w, h], values))
        }
        VolumeFormat::Nrrd | VolumeFormat::Nifti => Err(VolumeError::Invalid {
            path: name.to_path_buf(),
            problem: format!("{format:?} is a volume file, not a slice"),
        }),
    }
}

/// Read a single-file volume held in memory into the working grid, as
/// [`surface_from_path`] reads the file `name`: NRRD for `.nrrd`, NIfTI-1
/// for `.nii` and `.nii.gz` (gzipped). `name` picks the format and labels
/// errors; it is never opened.
pub fn working_grid_from_bytes(
    bytes: &[u8],
    name: &Path,
    opts: &VolumeOptions,
) -> Result<(Grid, VolumeInfo), VolumeError> {
    let reader = std::io::Cursor::new(bytes.to_vec());
    let source: Box<dyn SliceSource> = match volume_file_format(name) {
        Some(VolumeFormat::Nrrd) => Box::new(nrrd::from_reader(name, reader, None)?),
        Some(_) => Box::new(nifti::from_reader(name, reader, None)?),
        None => {
            return Err(VolumeError::Invalid {
                path: name.to_path_buf(),
                problem: "not a volume file name (.nrrd, .nii, .nii.gz)".into(),
            })
        }
    };
    let (grid, info, _, _, _) = reduce_source(source, name, opts)?;
    Ok((grid, info))
}

/// The surfaces of the specimens in a working grid: the stages of
/// [`surface_from_path`] after reading (segmentation, isosurface, and
/// with `enamel` the crown cut over enamel). `name` only labels errors.
pub fn surface_from_grid(
    grid: &Grid,
    opts: &VolumeOptions,
    name: &Path,
) -> Result<Vec<Mesh>, VolumeError> {
    grid_surface(grid, None, opts)
        .map(|found| found.specimens.into_iter().map(|(mesh, _)| mesh).collect())
        .map_err(|e| VolumeError::Invalid {
            path: name.to_path_buf(),
            problem: e.to_string(),
        })
}

/// Read the volume at `path` and make its surface: the closed surface,
/// or with `opts.enamel` the crown over enamel where the scan shows it.
pub fn surface_from_path(path: &Path, opts: &VolumeOptions) -> Result<VolumeSurface, VolumeError> {
    surface_from_path_as(path, opts, false).map(|(surface, _)| surface)
}

/// [`surface_from_path`], and the content of exactly the bytes that were
/// read (each slice file or the volume file read once, hashed as read:
/// [`crate::hash::content_hash_file`] of what the surface is made from).
pub(crate) fn surface_from_path_hashed(
    path: &Path,
    opts: &VolumeOptions,
) -> Result<(VolumeSurface, Content), VolumeError> {
    let (surface, content) = surface_from_path_as(path, opts, true)?;
    let content = content.ok_or_else(|| VolumeError::Invalid {
        path: path.to_path_buf(),
        problem: "the reader did not hash what it read".into(),
    })?;
    Ok((surface, content))
}

fn surface_from_path_as(
    path: &Path,
    opts: &VolumeOptions,
    hashed: bool,
) -> Result<(VolumeSurface, Option<Content>), VolumeError> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let t = Instant::now();
    let (grid, info, factor, detail, content) = {
        let _s = tracing::debug_span!("volume_read", scan = %name).entered();
        read_working_grid(path, opts, hashed)?
    };
    let read_ms = ms(t);
    let GridSurfaces {
        specimens: found,
        thresholds: th,
        segmentation: seg,
        report: r,
    } = {
        let _s = tracing::debug_span!("volume_surface", scan = %name).entered();
        grid_surface(&grid, detail.as_ref(), opts).map_err(|e| VolumeError::Invalid {
            path: path.to_path_buf(),
            problem: e.to_string(),
        })?
    };
    let mut seg = seg;
    // Bounding boxes in the input's voxels, as a user finds them in the file.
    let input_box = |b: [[usize; 3]; 2]| {
        [
            b[0].map(|v| v * factor),
            [0, 1, 2].map(|a| ((b[1][a] + 1) * factor).min(info.dims[a]).max(1) - 1),
        ]
    };
    for o in &mut seg.objects {
        o.bbox = input_box(o.bbox);
    }
    for w in &seg.warnings {
        tracing::warn!("{}: {w}", path.display());
    }
    let specimens = found
        .into_iter()
        .map(|(mesh, b)| VolumeSpecimen {
            mesh,
            voxels: input_box(b),
        })
        .collect();
    for o in seg.objects.iter().filter(|o| o.kept) {
        tracing::info!(
            "{}: kept a specimen of grey {:.1}, {} voxels at the working resolution, voxels \
             {:?}..{:?}",
            path.display(),
            o.mean,
            o.voxels,
            o.bbox[0],
            o.bbox[1]
        );
    }
    for o in seg.objects.iter().filter(|o| !o.kept) {
        tracing::info!(
            "{}: dropped an object of grey {:.1}, {} voxels at the working resolution, \
             voxels {:?}..{:?}: {}",
            path.display(),
            o.mean,
            o.voxels,
            o.bbox[0],
            o.bbox[1],
            o.detail
        );
    }
    let surface = VolumeSurface {
        specimens,
        report: VolumeReport {
            input: info,
            reduction_factor: factor,
            working_dims: grid.dims,
            thresholds: th,
            segmentation: seg,
            isosurface_faces: r.isosurface_faces,
            isosurface_area: r.isosurface_area,
            enamel_found: r.enamel_found,
            crown_area: r.crown_area,
            enamel_regions: r.enamel_regions,
            timings_ms: VolumeTimings {
                read: read_ms,
                segment: r.segment_ms,
                isosurface: r.isosurface_ms,
                crown: r.crown_ms,
            },
        },
    };
    Ok((surface, content))
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
