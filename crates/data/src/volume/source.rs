//! What every reader gives: the stack's size and voxel size, and its
//! slices one after another, as `f32` grey values.

use super::VolumeError;
use crate::hash::{Content, SharedHash};
use std::io::Read;
use std::path::{Path, PathBuf};

/// The file format of a volume.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum VolumeFormat {
    /// A folder of TIFF slices.
    Tiff,
    /// A folder of PNG slices.
    Png,
    /// A folder of BMP slices.
    Bmp,
    /// A folder of DICOM files, one slice each (a series).
    Dicom,
    /// A single-file NRRD.
    Nrrd,
    /// A NIfTI-1 file (`.nii`, `.nii.gz`).
    Nifti,
}

/// A volume's size and sampling as its metadata gives them.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VolumeInfo {
    /// The format read.
    pub format: VolumeFormat,
    /// Voxels along x, y and slices.
    pub dims: [usize; 3],
    /// Voxel size along x, y, z (1 where the file gives none).
    pub voxel_size: [f64; 3],
    /// Unit of `voxel_size` ("voxel" where the file gives none).
    pub unit: String,
    /// Bits per sample as stored.
    pub bits: u16,
}

/// The most pixels one slice may have: 8192 × 8192, beyond any µCT
/// detector. A header may declare far more than its file holds
/// (compressed data expands); the cap keeps one slice's values (4 bytes a
/// pixel) within 256 MB.
pub(crate) const MAX_SLICE_PIXELS: u64 = 1 << 26;

/// The most slices a volume may have.
pub(crate) const MAX_SLICES: u64 = 1 << 17;

/// Error unless a `w`×`h` slice of the file `path` is within
/// [`MAX_SLICE_PIXELS`].
pub(crate) fn check_slice_size(path: &Path, w: u64, h: u64) -> Result<(), VolumeError> {
    if w.saturating_mul(h) > MAX_SLICE_PIXELS {
        return Err(VolumeError::Invalid {
            path: path.to_path_buf(),
            problem: format!(
                "the header declares slices of {w}×{h} pixels, more than the \
                 {MAX_SLICE_PIXELS} a slice may have"
            ),
        });
    }
    Ok(())
}

/// Error unless the volume `path` of `dims` has slices within
/// [`MAX_SLICE_PIXELS`] and at most [`MAX_SLICES`] of them.
pub(crate) fn check_volume_size(path: &Path, dims: [usize; 3]) -> Result<(), VolumeError> {
    check_slice_size(path, dims[0] as u64, dims[1] as u64)?;
    if dims[2] as u64 > MAX_SLICES {
        return Err(VolumeError::Invalid {
            path: path.to_path_buf(),
            problem: format!(
                "the header declares {} slices, more than the {MAX_SLICES} a volume may have",
                dims[2]
            ),
        });
    }
    Ok(())
}

/// Whether `v` is usable as a voxel size: positive, finite, and neither
/// so small nor so large that products of it leave `f64`'s range.
pub(crate) fn plausible_voxel_size(v: f64) -> bool {
    v.is_finite() && (1e-9..=1e9).contains(&v)
}

/// A reader that yields the slices of a volume in order (on any thread:
/// the next slice is read while the last is reduced).
pub(crate) trait SliceSource: Send {
    /// Size and sampling.
    fn info(&self) -> &VolumeInfo;
    /// Read the next slice (`dims[0] * dims[1]` values, x fastest) into `out`.
    fn next_slice(&mut self, out: &mut Vec<f32>) -> Result<(), VolumeError>;
    /// After the last slice: the content of every byte that was read
    /// (the rest of a file is read to its end first), when the source was
    /// opened to hash; `None` otherwise.
    fn content(&mut self) -> Result<Option<Content>, VolumeError>;
}

/// How samples are stored in a raw volume file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SampleType {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    F32,
    F64,
}

impl SampleType {
    /// Bytes per sample.
    pub(crate) fn bytes(self) -> usize {
        match self {
            SampleType::U8 | SampleType::I8 => 1,
            SampleType::U16 | SampleType::I16 => 2,
            SampleType::U32 | SampleType::I32 | SampleType::F32 => 4,
            SampleType::F64 => 8,
        }
    }
}

/// Decode `bytes` (whole samples of `kind`, little- or big-endian) into `out`.
pub(crate) fn decode_samples(bytes: &[u8], kind: SampleType, little: bool, out: &mut Vec<f32>) {
    out.clear();
    let n = kind.bytes();
    for s in bytes.chunks_exact(n) {
        let mut b = [0u8; 8];
        b[..n].copy_from_slice(s);
        if !little {
            b[..n].reverse();
        }
        let v = match kind {
            SampleType::U8 => f32::from(b[0]),
            SampleType::I8 => f32::from(b[0] as i8),
            SampleType::U16 => f32::from(u16::from_le_bytes([b[0], b[1]])),
            SampleType::I16 => f32::from(i16::from_le_bytes([b[0], b[1]])),
            SampleType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            SampleType::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            SampleType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            SampleType::F64 => f64::from_le_bytes(b) as f32,
        };
        out.push(if v.is_finite() { v } else { 0.0 });
    }
}

/// A raw volume file (NRRD, NIfTI) positioned at its first slice: the
/// samples follow one another, slice after slice, as the header says.
pub(crate) struct RawSlices {
    info: VolumeInfo,
    path: PathBuf,
    kind: SampleType,
    little: bool,
    reader: Box<dyn Read + Send>,
    bytes: Vec<u8>,
    /// The hash of the file's bytes as they are read, when asked for.
    hash: Option<SharedHash>,
}

impl RawSlices {
    /// The slices that `reader` (of the file `path`, its header read)
    /// holds: samples of `kind`, little- or big-endian; `hash` is what the
    /// file's bytes are hashed into below `reader` (if anything). Error
    /// when the header declares a volume too large or an unusable voxel
    /// size.
    pub(crate) fn new(
        info: VolumeInfo,
        path: &Path,
        kind: SampleType,
        little: bool,
        reader: Box<dyn Read + Send>,
        hash: Option<SharedHash>,
    ) -> Result<Self, VolumeError> {
        check_volume_size(path, info.dims)?;
        if !info.voxel_size.iter().all(|&v| plausible_voxel_size(v)) {
            return Err(VolumeError::Invalid {
                path: path.to_path_buf(),
                problem: format!("voxel size {:?} is not usable", info.voxel_size),
            });
        }
        Ok(Self {
            info,
            path: path.to_path_buf(),
            kind,
            little,
            reader,
            bytes: Vec::new(),
            hash,
        })
    }
}

impl SliceSource for RawSlices {
    fn info(&self) -> &VolumeInfo {
        &self.info
    }

    /// One slice of raw samples; a short read is a truncated file.
    fn next_slice(&mut self, out: &mut Vec<f32>) -> Result<(), VolumeError> {
        let dims = self.info.dims;
        let n = (dims[0] * dims[1] * self.kind.bytes()) as u64;
        // Read as the bytes come, not into a buffer of the declared size:
        // a header may declare far more than the file holds.
        self.bytes.clear();
        let got = (&mut self.reader)
            .take(n)
            .read_to_end(&mut self.bytes)
            .map_err(|source| VolumeError::Io {
                path: self.path.clone(),
                source,
            })?;
        if (got as u64) < n {
            return Err(VolumeError::Invalid {
                path: self.path.clone(),
                problem: "the data ends before the last slice (truncated file)".into(),
            });
        }
        decode_samples(&self.bytes, self.kind, self.little, out);
        Ok(())
    }

    fn content(&mut self) -> Result<Option<Content>, VolumeError> {
        let Some(hash) = &self.hash else {
            return Ok(None);
        };
        // The rest of the file is part of its content: read to the end.
        std::io::copy(&mut self.reader, &mut std::io::sink()).map_err(|source| {
            VolumeError::Io {
                path: self.path.clone(),
                source,
            }
        })?;
        Ok(Some(hash.content()))
    }
}
