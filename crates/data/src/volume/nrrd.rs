//! Single-file NRRD (raw or gzip encoding, 3 dimensions): a small header
//! parser, then the samples streamed slice by slice.

use super::source::{RawSlices, SampleType, VolumeFormat, VolumeInfo};
use super::VolumeError;
use crate::hash::{HashingReader, SharedHash};
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

fn sample_type(name: &str) -> Option<SampleType> {
    Some(match name {
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => SampleType::U8,
        "signed char" | "int8" | "int8_t" => SampleType::I8,
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => {
            SampleType::U16
        }
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
            SampleType::I16
        }
        "uint" | "unsigned int" | "uint32" | "uint32_t" => SampleType::U32,
        "int" | "signed int" | "int32" | "int32_t" => SampleType::I32,
        "float" => SampleType::F32,
        "double" => SampleType::F64,
        _ => return None,
    })
}

/// Read the header of the NRRD file `path` and position at the first
/// slice; with `hash`, every byte of the file read is hashed into it.
pub(crate) fn open(path: &Path, hash: Option<SharedHash>) -> Result<RawSlices, VolumeError> {
    let file = std::fs::File::open(path).map_err(|source| VolumeError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let reader = BufReader::new(HashingReader::maybe(file, hash.clone()));
    from_reader(path, reader, hash)
}

/// Read an NRRD header from `reader` (the file `path`, which names
/// errors) and position at the first slice; `hash` is what the bytes are
/// hashed into below `reader` (if anything).
pub(crate) fn from_reader<R: BufRead + 'static>(
    path: &Path,
    mut reader: R,
    hash: Option<SharedHash>,
) -> Result<RawSlices, VolumeError> {
    let invalid = |problem: String| VolumeError::Invalid {
        path: path.to_path_buf(),
        problem,
    };
    let io = |source| VolumeError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut line = String::new();
    reader.read_line(&mut line).map_err(io)?;
    if !line.starts_with("NRRD000") {
        return Err(invalid("not an NRRD file (no NRRD000x magic)".into()));
    }
    let (mut kind, mut dims, mut encoding, mut little) = (None, None, String::from("raw"), true);
    let mut spacing = [1.0f64; 3];
    let mut unit = String::from("voxel");
    let mut header_bytes = line.len();
    loop {
        line.clear();
        let n = reader.read_line(&mut line).map_err(io)?;
        header_bytes += n;
        if n == 0 {
            return Err(invalid(
                "the header has no end (no blank line before the data)".into(),
            ));
        }
        if header_bytes > 1 << 20 {
            return Err(invalid("header longer than 1 MiB".into()));
        }
        let l = line.trim_end_matches(['\n', '\r']);
        if l.is_empty() {
            break;
        }
        if l.starts_with('#') {
            continue;
        }
        let Some((key, value)) = l.split_once(':') else {
            continue;
        };
        let value = value.trim_start_matches('=').trim();
        match key.trim() {
            "type" => {
                kind = Some(
                    sample_type(value)
                        .ok_or_else(|| invalid(format!("unsupported type \"{value}\"")))?,
                )
            }
            "dimension" if value != "3" => {
                return Err(invalid(format!("dimension {value}; a 3D volume is needed")))
            }
            "sizes" => {
                let s: Vec<usize> = value
                    .split_whitespace()
                    .map(|t| {
                        t.parse()
                            .map_err(|_| invalid(format!("bad sizes \"{value}\"")))
                    })
                    .collect::<Result<_, _>>()?;
                if s.len() != 3 || s.contains(&0) {
                    return Err(invalid(format!(
                        "sizes \"{value}\": three positive sizes needed"
                    )));
                }
                dims = Some([s[0], s[1], s[2]]);
            }
            "encoding" => encoding = value.to_string(),
            "endian" => little = value != "big",
            "spacings" => {
                for (k, t) in value.split_whitespace().take(3).enumerate() {
                    spacing[k] = t
                        .parse::<f64>()
                        .ok()
                        .filter(|&v| super::source::plausible_voxel_size(v))
                        .unwrap_or(1.0);
                }
                unit = "unknown".into();
            }
            "space directions" => {
                let vectors: Vec<f64> = value
                    .split(')')
                    .filter(|t| t.contains('('))
                    .map(|t| {
                        t.trim()
                            .trim_start_matches('(')
                            .split(',')
                            .filter_map(|c| c.trim().parse::<f64>().ok())
                            .map(|c| c * c)
                            .sum::<f64>()
                            .sqrt()
                    })
                    .collect();
                for (k, &l) in vectors.iter().take(3).enumerate() {
                    if super::source::plausible_voxel_size(l) {
                        spacing[k] = l;
                    }
                }
                unit = "unknown".into();
            }
            "space units" => {
                if let Some(u) = value.split('"').nth(1) {
                    unit = u.to_string();
                }
            }
            "data file" | "datafile" => {
                return Err(invalid(
                    "detached data files are not supported; save as a single .nrrd".into(),
                ))
            }
            _ => {}
        }
    }
    let kind = kind.ok_or_else(|| invalid("no \"type\" field".into()))?;
    let dims = dims.ok_or_else(|| invalid("no \"sizes\" field".into()))?;
    let reader: Box<dyn Read> = match encoding.as_str() {
        "raw" => Box::new(reader),
        "gzip" | "gz" => Box::new(flate2::bufread::MultiGzDecoder::new(reader)),
        other => {
            return Err(invalid(format!(
                "unsupported encoding \"{other}\" (raw or gzip)"
            )))
        }
    };
    let info = VolumeInfo {
        format: VolumeFormat::Nrrd,
        dims,
        voxel_size: spacing,
        unit,
        bits: (kind.bytes() * 8) as u16,
    };
    RawSlices::new(info, path, kind, little, reader, hash)
}
