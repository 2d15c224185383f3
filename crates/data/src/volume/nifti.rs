//! NIfTI-1 single files (`.nii`, `.nii.gz`): the 348-byte header read by
//! hand (the `nifti` crate reads a whole volume into memory; here slices
//! are streamed), then the samples slice by slice.

use super::source::{RawSlices, SampleType, VolumeFormat, VolumeInfo};
use super::VolumeError;
use crate::hash::{HashingReader, SharedHash};
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

/// Read the header of the NIfTI-1 file `path` and position at the first
/// slice; with `hash`, every byte of the file read is hashed into it.
pub(crate) fn open(path: &Path, hash: Option<SharedHash>) -> Result<RawSlices, VolumeError> {
    let file = std::fs::File::open(path).map_err(|source| VolumeError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let file = BufReader::new(HashingReader::maybe(file, hash.clone()));
    from_reader(path, file, hash)
}

/// Read a NIfTI-1 header from `file` (the file `path`: gzipped when its
/// name ends in `.gz`; it names errors) and position at the first slice;
/// `hash` is what the bytes are hashed into below `file` (if anything).
pub(crate) fn from_reader<R: BufRead + Send + 'static>(
    path: &Path,
    file: R,
    hash: Option<SharedHash>,
) -> Result<RawSlices, VolumeError> {
    let gz = path.to_string_lossy().to_ascii_lowercase().ends_with(".gz");
    let mut reader: Box<dyn Read + Send> = if gz {
        Box::new(flate2::bufread::MultiGzDecoder::new(file))
    } else {
        Box::new(file)
    };
    let mut bytes = [0u8; 348];
    reader
        .read_exact(&mut bytes)
        .map_err(|e| header_read_error(path, e))?;
    let h = Header::new(path, &bytes)?;
    let dims = h.dims()?;
    let kind = h.sample_type()?;
    let voxel_size = h.voxel_size();
    let unit = h.unit();
    let skip = h.bytes_to_data()?;
    std::io::copy(&mut reader.by_ref().take(skip), &mut std::io::sink())
        .map_err(|e| header_read_error(path, e))?;
    let info = VolumeInfo {
        format: VolumeFormat::Nifti,
        dims,
        voxel_size,
        unit: unit.into(),
        bits: (kind.bytes() * 8) as u16,
    };
    RawSlices::new(info, path, kind, h.little, reader, hash)
}

/// The error for `source`, met reading the header of `path` (or skipping
/// to the data): an end of file there is a truncated file.
fn header_read_error(path: &Path, source: std::io::Error) -> VolumeError {
    if source.kind() == std::io::ErrorKind::UnexpectedEof {
        VolumeError::invalid(
            path,
            "the file ends inside the header (truncated file)".into(),
        )
    } else {
        VolumeError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// The 348 bytes of a NIfTI-1 header (of the file `path`, which names
/// errors) and their byte order.
struct Header<'a> {
    path: &'a Path,
    bytes: &'a [u8; 348],
    /// Little-endian (`sizeof_hdr` reads 348 that way).
    little: bool,
}

impl<'a> Header<'a> {
    /// The header in `bytes`, its byte order found from `sizeof_hdr`; an
    /// error unless it is a single-file NIfTI-1 header.
    fn new(path: &'a Path, bytes: &'a [u8; 348]) -> Result<Self, VolumeError> {
        let h = bytes;
        let little = match (
            i32::from_le_bytes([h[0], h[1], h[2], h[3]]),
            i32::from_be_bytes([h[0], h[1], h[2], h[3]]),
        ) {
            (348, _) => true,
            (_, 348) => false,
            _ => {
                return Err(VolumeError::invalid(
                    path,
                    "not a NIfTI-1 file (sizeof_hdr is not 348)".into(),
                ))
            }
        };
        if &h[344..347] != b"n+1" {
            return Err(VolumeError::invalid(
                path,
                "not a single-file NIfTI-1 (magic is not \"n+1\")".into(),
            ));
        }
        Ok(Header {
            path,
            bytes,
            little,
        })
    }

    /// The 16-bit integer at byte `o`.
    fn i16_at(&self, o: usize) -> i16 {
        let b = [self.bytes[o], self.bytes[o + 1]];
        if self.little {
            i16::from_le_bytes(b)
        } else {
            i16::from_be_bytes(b)
        }
    }

    /// The 32-bit float at byte `o`.
    fn f32_at(&self, o: usize) -> f32 {
        let h = self.bytes;
        let b = [h[o], h[o + 1], h[o + 2], h[o + 3]];
        if self.little {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        }
    }

    /// The three sizes of `dim`; an error unless it describes a single 3D
    /// volume (every size past the third 1).
    fn dims(&self) -> Result<[usize; 3], VolumeError> {
        let ndim = self.i16_at(40);
        let d: Vec<i16> = (1..=7).map(|k| self.i16_at(40 + 2 * k)).collect();
        if !(3..=7).contains(&ndim)
            || d[..3].iter().any(|&x| x < 1)
            || d[3..(ndim as usize)].iter().any(|&x| x > 1)
        {
            return Err(VolumeError::invalid(
                self.path,
                format!(
                    "dimensions {:?}: a single 3D volume is needed",
                    &d[..ndim.clamp(0, 7) as usize]
                ),
            ));
        }
        Ok([d[0] as usize, d[1] as usize, d[2] as usize])
    }

    /// The sample type of the `datatype` code.
    fn sample_type(&self) -> Result<SampleType, VolumeError> {
        Ok(match self.i16_at(70) {
            2 => SampleType::U8,
            4 => SampleType::I16,
            8 => SampleType::I32,
            16 => SampleType::F32,
            64 => SampleType::F64,
            256 => SampleType::I8,
            512 => SampleType::U16,
            768 => SampleType::U32,
            t => {
                return Err(VolumeError::invalid(
                    self.path,
                    format!("unsupported datatype code {t}"),
                ))
            }
        })
    }

    /// The voxel size of `pixdim[1..=3]` (1 where it is not plausible).
    fn voxel_size(&self) -> [f64; 3] {
        [1, 2, 3].map(|k| {
            let v = f64::from(self.f32_at(76 + 4 * k)).abs();
            if super::source::plausible_voxel_size(v) {
                v
            } else {
                1.0
            }
        })
    }

    /// The spatial unit of `xyzt_units`.
    fn unit(&self) -> &'static str {
        match self.bytes[123] & 0x07 {
            1 => "m",
            2 => "mm",
            3 => "um",
            _ => "unknown",
        }
    }

    /// How many bytes lie between the header's end and the data
    /// (`vox_offset` − 348); an error when `vox_offset` lies inside the
    /// header or past 4 GiB.
    fn bytes_to_data(&self) -> Result<u64, VolumeError> {
        let offset = self.f32_at(108);
        if !(offset >= 348.0 && offset < (1u64 << 32) as f32) {
            return Err(VolumeError::invalid(
                self.path,
                format!("vox_offset {offset} lies inside the header"),
            ));
        }
        Ok(offset as u64 - 348)
    }
}
