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
pub(crate) fn from_reader<R: BufRead + Send + 'static>(
    path: &Path,
    mut reader: R,
    hash: Option<SharedHash>,
) -> Result<RawSlices, VolumeError> {
    let header = read_header(path, &mut reader)?;
    let kind = header
        .kind
        .ok_or_else(|| VolumeError::invalid(path, "no \"type\" field".into()))?;
    let dims = header
        .dims
        .ok_or_else(|| VolumeError::invalid(path, "no \"sizes\" field".into()))?;
    let reader = decoded(path, reader, &header.encoding)?;
    let info = VolumeInfo {
        format: VolumeFormat::Nrrd,
        dims,
        voxel_size: header.spacing,
        unit: header.unit,
        bits: (kind.bytes() * 8) as u16,
    };
    RawSlices::new(info, path, kind, header.little, reader, hash)
}

/// What an NRRD header says about the data, as far as it has been read.
struct Header {
    /// `type`.
    kind: Option<SampleType>,
    /// `sizes`.
    dims: Option<[usize; 3]>,
    /// `encoding`.
    encoding: String,
    /// Not `endian: big`.
    little: bool,
    /// From `spacings` or the lengths of `space directions` (1 where they
    /// say nothing usable).
    spacing: [f64; 3],
    /// `space units`; `unknown` for spacings without one.
    unit: String,
}

impl Default for Header {
    /// What a header without the optional fields means: raw
    /// little-endian samples one voxel apart.
    fn default() -> Self {
        Header {
            kind: None,
            dims: None,
            encoding: String::from("raw"),
            little: true,
            spacing: [1.0; 3],
            unit: String::from("voxel"),
        }
    }
}

/// The header read from `reader` (the magic line, then fields up to the
/// blank line before the data), leaving `reader` at the data.
fn read_header<R: BufRead>(path: &Path, reader: &mut R) -> Result<Header, VolumeError> {
    let io = |source| VolumeError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut line = String::new();
    reader.read_line(&mut line).map_err(io)?;
    if !line.starts_with("NRRD000") {
        return Err(VolumeError::invalid(
            path,
            "not an NRRD file (no NRRD000x magic)".into(),
        ));
    }
    let mut header = Header::default();
    let mut header_bytes = line.len();
    loop {
        line.clear();
        let n = reader.read_line(&mut line).map_err(io)?;
        header_bytes += n;
        if n == 0 {
            return Err(VolumeError::invalid(
                path,
                "the header has no end (no blank line before the data)".into(),
            ));
        }
        if header_bytes > 1 << 20 {
            return Err(VolumeError::invalid(
                path,
                "header longer than 1 MiB".into(),
            ));
        }
        let l = line.trim_end_matches(['\n', '\r']);
        if l.is_empty() {
            return Ok(header);
        }
        if l.starts_with('#') {
            continue;
        }
        let Some((key, value)) = l.split_once(':') else {
            continue;
        };
        let value = value.trim_start_matches('=').trim();
        header.take_field(path, key.trim(), value)?;
    }
}

impl Header {
    /// Take the field `key: value` into the header; an error for a field
    /// that rules the file out (another dimension, an unknown type,
    /// detached data).
    fn take_field(&mut self, path: &Path, key: &str, value: &str) -> Result<(), VolumeError> {
        match key {
            "type" => {
                self.kind = Some(sample_type(value).ok_or_else(|| {
                    VolumeError::invalid(path, format!("unsupported type \"{value}\""))
                })?)
            }
            "dimension" if value != "3" => {
                return Err(VolumeError::invalid(
                    path,
                    format!("dimension {value}; a 3D volume is needed"),
                ))
            }
            "sizes" => self.dims = Some(sizes(path, value)?),
            "encoding" => self.encoding = value.to_string(),
            "endian" => self.little = value != "big",
            "spacings" => {
                for (k, t) in value.split_whitespace().take(3).enumerate() {
                    self.spacing[k] = t
                        .parse::<f64>()
                        .ok()
                        .filter(|&v| super::source::plausible_voxel_size(v))
                        .unwrap_or(1.0);
                }
                self.unit = "unknown".into();
            }
            "space directions" => {
                for (k, &l) in direction_lengths(value).iter().take(3).enumerate() {
                    if super::source::plausible_voxel_size(l) {
                        self.spacing[k] = l;
                    }
                }
                self.unit = "unknown".into();
            }
            "space units" => {
                if let Some(u) = value.split('"').nth(1) {
                    self.unit = u.to_string();
                }
            }
            "data file" | "datafile" => {
                return Err(VolumeError::invalid(
                    path,
                    "detached data files are not supported; save as a single .nrrd".into(),
                ))
            }
            _ => {}
        }
        Ok(())
    }
}

/// The three positive sizes of a `sizes` field.
fn sizes(path: &Path, value: &str) -> Result<[usize; 3], VolumeError> {
    let s: Vec<usize> = value
        .split_whitespace()
        .map(|t| {
            t.parse()
                .map_err(|_| VolumeError::invalid(path, format!("bad sizes \"{value}\"")))
        })
        .collect::<Result<_, _>>()?;
    if s.len() != 3 || s.contains(&0) {
        return Err(VolumeError::invalid(
            path,
            format!("sizes \"{value}\": three positive sizes needed"),
        ));
    }
    Ok([s[0], s[1], s[2]])
}

/// The lengths of the vectors `(x,y,z)` of a `space directions` field
/// (`none` entries have none; unreadable components count as 0).
fn direction_lengths(value: &str) -> Vec<f64> {
    value
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
        .collect()
}

/// The samples that follow the header in `reader`, decoded as `encoding`
/// says (raw or gzip).
fn decoded<R: BufRead + Send + 'static>(
    path: &Path,
    reader: R,
    encoding: &str,
) -> Result<Box<dyn Read + Send>, VolumeError> {
    Ok(match encoding {
        "raw" => Box::new(reader),
        "gzip" | "gz" => Box::new(flate2::bufread::MultiGzDecoder::new(reader)),
        other => {
            return Err(VolumeError::invalid(
                path,
                format!("unsupported encoding \"{other}\" (raw or gzip)"),
            ))
        }
    })
}
