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
pub(crate) fn from_reader<R: BufRead + 'static>(
    path: &Path,
    file: R,
    hash: Option<SharedHash>,
) -> Result<RawSlices, VolumeError> {
    let invalid = |problem: String| VolumeError::Invalid {
        path: path.to_path_buf(),
        problem,
    };
    let io = |source: std::io::Error| {
        if source.kind() == std::io::ErrorKind::UnexpectedEof {
            VolumeError::Invalid {
                path: path.to_path_buf(),
                problem: "the file ends inside the header (truncated file)".into(),
            }
        } else {
            VolumeError::Io {
                path: path.to_path_buf(),
                source,
            }
        }
    };
    let gz = path.to_string_lossy().to_ascii_lowercase().ends_with(".gz");
    let mut reader: Box<dyn Read> = if gz {
        Box::new(flate2::bufread::MultiGzDecoder::new(file))
    } else {
        Box::new(file)
    };
    let mut h = [0u8; 348];
    reader.read_exact(&mut h).map_err(io)?;
    let little = match (
        i32::from_le_bytes([h[0], h[1], h[2], h[3]]),
        i32::from_be_bytes([h[0], h[1], h[2], h[3]]),
    ) {
        (348, _) => true,
        (_, 348) => false,
        _ => return Err(invalid("not a NIfTI-1 file (sizeof_hdr is not 348)".into())),
    };
    if &h[344..347] != b"n+1" {
        return Err(invalid(
            "not a single-file NIfTI-1 (magic is not \"n+1\")".into(),
        ));
    }
    let i16_at = |o: usize| {
        let b = [h[o], h[o + 1]];
        if little {
            i16::from_le_bytes(b)
        } else {
            i16::from_be_bytes(b)
        }
    };
    let f32_at = |o: usize| {
        let b = [h[o], h[o + 1], h[o + 2], h[o + 3]];
        if little {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        }
    };
    let ndim = i16_at(40);
    let d: Vec<i16> = (1..=7).map(|k| i16_at(40 + 2 * k)).collect();
    if !(3..=7).contains(&ndim)
        || d[..3].iter().any(|&x| x < 1)
        || d[3..(ndim as usize)].iter().any(|&x| x > 1)
    {
        return Err(invalid(format!(
            "dimensions {:?}: a single 3D volume is needed",
            &d[..ndim.clamp(0, 7) as usize]
        )));
    }
    let kind = match i16_at(70) {
        2 => SampleType::U8,
        4 => SampleType::I16,
        8 => SampleType::I32,
        16 => SampleType::F32,
        64 => SampleType::F64,
        256 => SampleType::I8,
        512 => SampleType::U16,
        768 => SampleType::U32,
        t => return Err(invalid(format!("unsupported datatype code {t}"))),
    };
    let voxel_size = [1, 2, 3].map(|k| {
        let v = f64::from(f32_at(76 + 4 * k)).abs();
        if super::source::plausible_voxel_size(v) {
            v
        } else {
            1.0
        }
    });
    let unit = match h[123] & 0x07 {
        1 => "m",
        2 => "mm",
        3 => "um",
        _ => "unknown",
    };
    let offset = f32_at(108);
    if !(offset >= 348.0 && offset < (1u64 << 32) as f32) {
        return Err(invalid(format!(
            "vox_offset {offset} lies inside the header"
        )));
    }
    let skip = offset as u64 - 348;
    std::io::copy(&mut reader.by_ref().take(skip), &mut std::io::sink()).map_err(io)?;
    let info = VolumeInfo {
        format: VolumeFormat::Nifti,
        dims: [d[0] as usize, d[1] as usize, d[2] as usize],
        voxel_size,
        unit: unit.into(),
        bits: (kind.bytes() * 8) as u16,
    };
    RawSlices::new(info, path, kind, little, reader, hash)
}
