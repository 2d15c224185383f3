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

/// A reader that yields the slices of a volume in order.
pub(crate) trait SliceSource {
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
    reader: Box<dyn Read>,
    bytes: Vec<u8>,
    /// The hash of the file's bytes as they are read, when asked for.
    hash: Option<SharedHash>,
}

impl RawSlices {
    /// The slices that `reader` (of the file `path`, its header read)
    /// holds: samples of `kind`, little- or big-endian; `hash` is what the
    /// file's bytes are hashed into below `reader` (if anything).
    pub(crate) fn new(
        info: VolumeInfo,
        path: &Path,
        kind: SampleType,
        little: bool,
        reader: Box<dyn Read>,
        hash: Option<SharedHash>,
    ) -> Self {
        Self {
            info,
            path: path.to_path_buf(),
            kind,
            little,
            reader,
            bytes: Vec::new(),
            hash,
        }
    }
}

impl SliceSource for RawSlices {
    fn info(&self) -> &VolumeInfo {
        &self.info
    }

    /// One slice of raw samples; a short read is a truncated file.
    fn next_slice(&mut self, out: &mut Vec<f32>) -> Result<(), VolumeError> {
        let dims = self.info.dims;
        self.bytes.resize(dims[0] * dims[1] * self.kind.bytes(), 0);
        self.reader.read_exact(&mut self.bytes).map_err(|source| {
            if source.kind() == std::io::ErrorKind::UnexpectedEof {
                VolumeError::Invalid {
                    path: self.path.clone(),
                    problem: "the data ends before the last slice (truncated file)".into(),
                }
            } else {
                VolumeError::Io {
                    path: self.path.clone(),
                    source,
                }
            }
        })?;
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
