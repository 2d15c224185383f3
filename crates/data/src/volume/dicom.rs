//! A DICOM series: a folder of single-frame DICOM files (with the `DICM`
//! file meta header), one slice each, read through dicom-object. Only
//! native (uncompressed) pixel data is taken, so no codec library is
//! needed; a compressed series is refused with its transfer syntax named.
//!
//! Opening reads every file's header (not its pixels): the files must be
//! one series, one size, one orientation. Slices are ordered by their
//! position along the slice normal (else by instance number, else by
//! name); the slice spacing is the median step between positions, and a
//! step more than 1.5 times the median is a missing slice. Pixels are read
//! one file at a time with the rescale slope and intercept applied.

use super::source::{SliceSource, VolumeFormat, VolumeInfo};
use super::VolumeError;
use crate::hash::{Content, FolderHash};
use dicom_core::value::{PrimitiveValue, Value};
use dicom_dictionary_std::tags;
use dicom_object::{InMemDicomObject, Tag};
use std::io::Read;
use std::path::{Path, PathBuf};

/// Whether the file at `path` carries the DICOM magic (`DICM` at byte 128).
pub(crate) fn has_dicom_magic(path: &Path) -> bool {
    let mut head = [0u8; 132];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && &head[128..] == b"DICM"
}

/// Transfer syntaxes whose pixel data is stored as plain samples, little
/// endian: implicit VR, explicit VR, and deflated explicit VR (the whole
/// data set is deflated; the pixels inside are plain).
const NATIVE_SYNTAXES: &[&str] = &[
    "1.2.840.10008.1.2",
    "1.2.840.10008.1.2.1",
    "1.2.840.10008.1.2.1.99",
];

/// Explicit VR big endian (retired).
const BIG_ENDIAN_SYNTAX: &str = "1.2.840.10008.1.2.2";

/// How one file stores its samples and maps them to values.
#[derive(Debug, Clone, PartialEq)]
struct PixelLayout {
    bits_allocated: u16,
    bits_stored: u16,
    signed: bool,
    /// Lowest value shown white: negated so that denser is higher, as the
    /// segmentation expects.
    inverted: bool,
    slope: f64,
    intercept: f64,
}

/// What the header of one file says about its slice.
#[derive(Debug, Clone, PartialEq)]
struct SliceHeader {
    path: PathBuf,
    series: Option<String>,
    rows: usize,
    columns: usize,
    position: Option<[f64; 3]>,
    orientation: Option<[f64; 6]>,
    instance: Option<i64>,
    /// Row spacing, column spacing (PixelSpacing), mm.
    pixel_spacing: Option<[f64; 2]>,
    /// SpacingBetweenSlices, else SliceThickness, mm.
    thickness: Option<f64>,
    layout: PixelLayout,
}

fn element(obj: &InMemDicomObject, tag: Tag) -> Option<&dicom_object::mem::InMemElement> {
    obj.element_opt(tag).ok().flatten()
}

fn text(obj: &InMemDicomObject, tag: Tag) -> Option<String> {
    let s = element(obj, tag)?.to_str().ok()?;
    let s = s.trim_end_matches(['\0', ' ']).trim();
    (!s.is_empty()).then(|| s.to_string())
}

fn int(obj: &InMemDicomObject, tag: Tag) -> Option<i64> {
    element(obj, tag)?.to_int::<i64>().ok()
}

fn floats(obj: &InMemDicomObject, tag: Tag) -> Option<Vec<f64>> {
    let v = element(obj, tag)?.to_multi_float64().ok()?;
    v.iter().all(|x| x.is_finite()).then_some(v)
}

fn float(obj: &InMemDicomObject, tag: Tag) -> Option<f64> {
    floats(obj, tag)?.first().copied()
}

fn name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The data set of the DICOM file `bytes` (of the file `path`, which
/// names errors), up to (`header_only`) or including its pixel data, and
/// its transfer syntax; a file that ends early is reported as truncated.
fn open_object(
    path: &Path,
    bytes: &[u8],
    header_only: bool,
) -> Result<(InMemDicomObject, String), VolumeError> {
    // dicom-object allocates every declared length before reading it, so
    // the framing is walked first, other syntaxes refused unread, and the
    // parser given the data set exactly where the walk found it (its own
    // reading of a malformed file meta group may start elsewhere).
    let data = super::dicom_scan::data_set_checked(bytes)
        .map_err(|source| VolumeError::DicomFraming {
            path: path.to_path_buf(),
            source,
        })?
        .ok_or_else(|| {
            VolumeError::invalid(
                path,
                "no DICOM file meta group with a transfer syntax (not a DICOM file, \
                 or its header is corrupt)"
                    .into(),
            )
        })?;
    check_syntax(path, &data.syntax)?;
    let body = match data.pixel_data {
        Some(at) if header_only => &data.bytes[..at],
        _ => &data.bytes[..],
    };
    use dicom_transfer_syntax_registry::{TransferSyntaxIndex, TransferSyntaxRegistry};
    let ts = TransferSyntaxRegistry.get(data.encoding).ok_or_else(|| {
        VolumeError::invalid(
            path,
            format!("transfer syntax {} is not registered", data.encoding),
        )
    })?;
    let obj = InMemDicomObject::read_dataset_with_ts(body, ts).map_err(|source| {
        if ends_early(&source) {
            VolumeError::invalid(
                path,
                "the file ends before its data does (truncated file)".into(),
            )
        } else {
            VolumeError::Dicom {
                path: path.to_path_buf(),
                source: Box::new(source),
            }
        }
    })?;
    Ok((obj, data.syntax))
}

/// Whether a read error comes from the file ending early.
fn ends_early(e: &(dyn std::error::Error + 'static)) -> bool {
    let mut cur = Some(e);
    while let Some(err) = cur {
        if let Some(io) = err.downcast_ref::<std::io::Error>() {
            if io.kind() == std::io::ErrorKind::UnexpectedEof {
                return true;
            }
        }
        cur = err.source();
    }
    false
}

/// The bytes of the DICOM file `path`, read once: what is parsed is what
/// is hashed.
fn read_file(path: &Path) -> Result<Vec<u8>, VolumeError> {
    std::fs::read(path).map_err(|source| VolumeError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Error unless the transfer syntax `syntax` stores plain samples, little
/// endian (see [`NATIVE_SYNTAXES`]); the error says how to export instead.
fn check_syntax(path: &Path, syntax: &str) -> Result<(), VolumeError> {
    if syntax == BIG_ENDIAN_SYNTAX {
        return Err(VolumeError::invalid(
            path,
            format!(
                "transfer syntax Explicit VR Big Endian ({syntax}) is not read; \
                 export the series uncompressed, little endian (Explicit VR Little Endian)"
            ),
        ));
    }
    if !NATIVE_SYNTAXES.contains(&syntax) {
        return Err(VolumeError::invalid(
            path,
            format!(
                "compressed transfer syntax {} ({syntax}); export the series uncompressed \
                 (Explicit or Implicit VR Little Endian) to read it",
                syntax_name(syntax)
            ),
        ));
    }
    Ok(())
}

/// The header of the DICOM file `bytes` (of `path`): its transfer syntax
/// checked, the pixel description and geometry read.
fn read_header(path: &Path, bytes: &[u8]) -> Result<SliceHeader, VolumeError> {
    let (file, _) = open_object(path, bytes, true)?;
    let obj: &InMemDicomObject = &file;
    let frames = int(obj, tags::NUMBER_OF_FRAMES).unwrap_or(1);
    if frames > 1 {
        return Err(VolumeError::invalid(
            path,
            format!("a multi-frame image ({frames} frames); one slice per file is needed"),
        ));
    }
    let samples = int(obj, tags::SAMPLES_PER_PIXEL).unwrap_or(1);
    if samples != 1 {
        return Err(VolumeError::invalid(
            path,
            format!("{samples} samples per pixel (colour); greyscale slices are needed"),
        ));
    }
    let photometric = text(obj, tags::PHOTOMETRIC_INTERPRETATION);
    let inverted = match photometric.as_deref() {
        None | Some("MONOCHROME2") => false,
        Some("MONOCHROME1") => true,
        Some(other) => {
            return Err(VolumeError::invalid(
                path,
                format!("photometric interpretation {other}; greyscale slices are needed"),
            ))
        }
    };
    let rows = int(obj, tags::ROWS).filter(|&r| r > 0);
    let columns = int(obj, tags::COLUMNS).filter(|&c| c > 0);
    let (Some(rows), Some(columns)) = (rows, columns) else {
        return Err(VolumeError::invalid(
            path,
            "no Rows/Columns: not an image (a report or index?)".into(),
        ));
    };
    super::source::check_slice_size(path, columns as u64, rows as u64)?;
    let bits_allocated = int(obj, tags::BITS_ALLOCATED).unwrap_or(0);
    if bits_allocated != 8 && bits_allocated != 16 {
        return Err(VolumeError::invalid(
            path,
            format!("{bits_allocated} bits allocated per sample; 8 or 16 are read"),
        ));
    }
    let bits_stored = int(obj, tags::BITS_STORED)
        .filter(|b| (1..=bits_allocated).contains(b))
        .unwrap_or(bits_allocated);
    let orientation = floats(obj, tags::IMAGE_ORIENTATION_PATIENT)
        .filter(|v| v.len() == 6)
        .map(|v| [v[0], v[1], v[2], v[3], v[4], v[5]]);
    Ok(SliceHeader {
        path: path.to_path_buf(),
        series: text(obj, tags::SERIES_INSTANCE_UID),
        rows: rows as usize,
        columns: columns as usize,
        position: floats(obj, tags::IMAGE_POSITION_PATIENT)
            .filter(|v| v.len() == 3)
            .map(|v| [v[0], v[1], v[2]]),
        orientation,
        instance: int(obj, tags::INSTANCE_NUMBER),
        pixel_spacing: floats(obj, tags::PIXEL_SPACING)
            .filter(|v| v.len() == 2 && v.iter().all(|&s| super::source::plausible_voxel_size(s)))
            .map(|v| [v[0], v[1]]),
        thickness: float(obj, tags::SPACING_BETWEEN_SLICES)
            .or_else(|| float(obj, tags::SLICE_THICKNESS))
            .filter(|&t| super::source::plausible_voxel_size(t)),
        layout: PixelLayout {
            bits_allocated: bits_allocated as u16,
            bits_stored: bits_stored as u16,
            signed: int(obj, tags::PIXEL_REPRESENTATION) == Some(1),
            inverted,
            slope: float(obj, tags::RESCALE_SLOPE)
                .filter(|&s| s != 0.0)
                .unwrap_or(1.0),
            intercept: float(obj, tags::RESCALE_INTERCEPT).unwrap_or(0.0),
        },
    })
}

/// The registry's name of a transfer syntax, else "unknown".
fn syntax_name(uid: &str) -> String {
    use dicom_transfer_syntax_registry::{TransferSyntaxIndex, TransferSyntaxRegistry};
    TransferSyntaxRegistry
        .get(uid)
        .map(|ts| ts.name().to_string())
        .unwrap_or_else(|| "unknown".into())
}

/// The slices in order and the spacing between them (mm) where the
/// positions give it.
#[derive(Debug, Clone, PartialEq)]
struct Ordering {
    order: Vec<usize>,
    spacing: Option<f64>,
}

/// Unit normal of the slice plane: row direction × column direction.
fn slice_normal(o: &[f64; 6]) -> Option<[f64; 3]> {
    let n = morphoid_core::mesh::cross([o[0], o[1], o[2]], [o[3], o[4], o[5]]);
    let l = morphoid_core::mesh::norm(n);
    (l > 1e-6).then(|| n.map(|c| c / l))
}

/// Order the slices of `dir` (headers in name order): by position along
/// the normal when every slice has one, else by instance number when every
/// slice has a distinct one, else as named. Positions must step evenly:
/// two slices at one place, or a step over 1.5 times the median (a
/// missing slice), are errors naming the files.
fn order_slices(dir: &Path, headers: &[SliceHeader]) -> Result<Ordering, VolumeError> {
    let normal = headers[0].orientation.as_ref().and_then(slice_normal);
    let along: Option<Vec<f64>> = normal.and_then(|n| {
        headers
            .iter()
            .map(|h| h.position.map(|p| morphoid_core::mesh::dot(p, n)))
            .collect()
    });
    if let Some(along) = along {
        let mut order: Vec<usize> = (0..headers.len()).collect();
        order.sort_by(|&a, &b| along[a].total_cmp(&along[b]));
        let steps: Vec<f64> = order
            .windows(2)
            .map(|w| along[w[1]] - along[w[0]])
            .collect();
        let mut sorted = steps.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        let pair = |k: usize| {
            (
                name(&headers[order[k]].path),
                name(&headers[order[k + 1]].path),
            )
        };
        for (k, &s) in steps.iter().enumerate() {
            if s <= 1e-6 * median.max(1e-3) {
                let (a, b) = pair(k);
                return Err(VolumeError::invalid(
                    dir,
                    format!("{a} and {b} lie at the same position: a slice is duplicated"),
                ));
            }
            if s > 1.5 * median {
                let (a, b) = pair(k);
                return Err(VolumeError::invalid(
                    dir,
                    format!(
                        "slices missing between {a} and {b}: they lie {s:.4} mm apart, \
                         {:.1} times the median spacing of {median:.4} mm",
                        s / median
                    ),
                ));
            }
        }
        return Ok(Ordering {
            order,
            spacing: Some(median),
        });
    }
    let numbers: Option<Vec<i64>> = headers.iter().map(|h| h.instance).collect();
    let mut order: Vec<usize> = (0..headers.len()).collect();
    if let Some(n) = numbers {
        let mut distinct = n.clone();
        distinct.sort_unstable();
        distinct.dedup();
        if distinct.len() == n.len() {
            order.sort_by_key(|&i| n[i]);
        }
    }
    Ok(Ordering {
        order,
        spacing: None,
    })
}

/// The positions along their common slice normal of the DICOM `files`
/// (read from their headers, not their pixels), for telling from the
/// positions whether slices are missing
/// ([`crate::completeness::dicom_positions`]). `None` when a file cannot
/// be read as a DICOM slice or lacks its position or orientation: the
/// reader then says what is wrong.
pub(crate) fn slice_positions_along_normal(files: &[PathBuf]) -> Option<Vec<f64>> {
    let mut normal = None;
    let mut along = Vec::with_capacity(files.len());
    for p in files {
        let bytes = std::fs::read(p).ok()?;
        let h = read_header(p, &bytes).ok()?;
        if normal.is_none() {
            normal = Some(slice_normal(h.orientation.as_ref()?)?);
        }
        along.push(morphoid_core::mesh::dot(h.position?, normal?));
    }
    Some(along)
}

/// An open DICOM series, positioned at the next slice.
pub(crate) struct DicomSeries {
    info: VolumeInfo,
    slices: Vec<SliceHeader>,
    next: usize,
    /// When hashed: the folder's content (of the files as their headers
    /// were read, in name order), and each file's own hash by path, which
    /// its second reading (for the pixels) must match.
    hashed: Option<(Content, Vec<(PathBuf, String)>)>,
}

impl DicomSeries {
    /// Read and check the headers of the DICOM `files` of `dir` (in name
    /// order) and order the slices. With `hashed`, each file's bytes are
    /// hashed as read ([`SliceSource::content`]); the pixels are read
    /// later, by position, from a second reading that must hold the same
    /// bytes.
    pub(crate) fn open(
        dir: &Path,
        files: Vec<PathBuf>,
        hashed: bool,
    ) -> Result<DicomSeries, VolumeError> {
        let mut folder = hashed.then(FolderHash::new);
        let mut each = Vec::new();
        let mut headers = Vec::with_capacity(files.len());
        for p in &files {
            let bytes = read_file(p)?;
            if let Some(f) = &mut folder {
                f.slice(&name(p), &bytes);
                each.push((p.clone(), crate::hash::content_hash(&bytes)));
            }
            headers.push(read_header(p, &bytes)?);
        }
        check_one_series(dir, &headers)?;
        let first = &headers[0];
        for h in &headers[1..] {
            if [h.columns, h.rows] != [first.columns, first.rows] {
                return Err(VolumeError::invalid(
                    &h.path,
                    format!(
                        "slice is {}×{}, the first slice ({}) is {}×{}: slices of unequal size",
                        h.columns,
                        h.rows,
                        name(&first.path),
                        first.columns,
                        first.rows
                    ),
                ));
            }
            let turned = match (h.orientation, first.orientation) {
                (Some(a), Some(b)) => a.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-3),
                (a, b) => a.is_some() != b.is_some(),
            };
            if turned {
                return Err(VolumeError::invalid(
                    &h.path,
                    format!(
                        "its orientation differs from the first slice's ({})",
                        name(&first.path)
                    ),
                ));
            }
        }
        let Ordering { order, spacing } = order_slices(dir, &headers)?;
        let (voxel_size, unit) = match first.pixel_spacing {
            Some([row, column]) => {
                let z = spacing
                    .filter(|&s| super::source::plausible_voxel_size(s))
                    .or(first.thickness)
                    .unwrap_or(1.0);
                ([column, row, z], "mm")
            }
            None => ([1.0; 3], "voxel"),
        };
        let info = VolumeInfo {
            format: VolumeFormat::Dicom,
            dims: [first.columns, first.rows, headers.len()],
            voxel_size,
            unit: unit.into(),
            bits: first.layout.bits_allocated,
        };
        let mut slots: Vec<Option<SliceHeader>> = headers.into_iter().map(Some).collect();
        let slices = order.iter().filter_map(|&i| slots[i].take()).collect();
        Ok(DicomSeries {
            info,
            slices,
            next: 0,
            hashed: folder.map(|f| (f.finish(), each)),
        })
    }
}

/// Every file must belong to one series: otherwise name each series, how
/// many files it has and one of them.
fn check_one_series(dir: &Path, headers: &[SliceHeader]) -> Result<(), VolumeError> {
    let mut series: Vec<(Option<&str>, usize, &Path)> = Vec::new();
    for h in headers {
        let uid = h.series.as_deref();
        match series.iter_mut().find(|(u, _, _)| *u == uid) {
            Some(s) => s.1 += 1,
            None => series.push((uid, 1, &h.path)),
        }
    }
    if series.len() < 2 {
        return Ok(());
    }
    let list: Vec<String> = series
        .iter()
        .map(|(uid, n, p)| {
            format!(
                "{} ({n} file{}, e.g. {})",
                uid.unwrap_or("no SeriesInstanceUID"),
                if *n == 1 { "" } else { "s" },
                name(p)
            )
        })
        .collect();
    Err(VolumeError::invalid(
        dir,
        format!(
            "{} DICOM series in one folder: {}; put each series in a folder of its own",
            series.len(),
            list.join(", ")
        ),
    ))
}

/// The raw samples of native pixel data as unsigned integers, whatever
/// value type the parser gave them (bytes for OB, 16-bit words for OW).
fn raw_samples(value: &PrimitiveValue, bits: u16, out: &mut Vec<u32>) {
    out.clear();
    match (value, bits) {
        (PrimitiveValue::U8(b), 8) => out.extend(b.iter().map(|&v| u32::from(v))),
        (PrimitiveValue::U8(b), _) => out.extend(
            b.chunks_exact(2)
                .map(|c| u32::from(u16::from_le_bytes([c[0], c[1]]))),
        ),
        (PrimitiveValue::U16(w), 16) => out.extend(w.iter().map(|&v| u32::from(v))),
        (PrimitiveValue::I16(w), 16) => out.extend(w.iter().map(|&v| u32::from(v as u16))),
        // 8-bit samples read as little-endian words: low byte first.
        (PrimitiveValue::U16(w), _) => {
            out.extend(w.iter().flat_map(|v| v.to_le_bytes()).map(u32::from))
        }
        (PrimitiveValue::I16(w), _) => {
            out.extend(w.iter().flat_map(|v| v.to_le_bytes()).map(u32::from))
        }
        _ => {}
    }
}

/// A stored sample as a value: masked to the stored bits, sign-extended
/// where signed, rescaled, negated where the image is inverted.
fn sample_value(raw: u32, layout: &PixelLayout) -> f32 {
    let bits = u32::from(layout.bits_stored);
    let masked = raw & ((1u32 << bits) - 1);
    let v = if layout.signed && masked & (1 << (bits - 1)) != 0 {
        i64::from(masked) - (1i64 << bits)
    } else {
        i64::from(masked)
    };
    let v = layout.slope * v as f64 + layout.intercept;
    (if layout.inverted { -v } else { v }) as f32
}

/// The pixels of the DICOM file `bytes`, whose header `h` describes, as
/// values (rescaled, inverted where shown white-low) into `out`.
fn pixels(h: &SliceHeader, bytes: &[u8], out: &mut Vec<f32>) -> Result<(), VolumeError> {
    let (file, _) = open_object(&h.path, bytes, false)?;
    let value = match element(&file, tags::PIXEL_DATA).map(|e| e.value()) {
        Some(Value::Primitive(v)) => v,
        Some(_) => {
            return Err(VolumeError::invalid(
                &h.path,
                "the pixel data is encapsulated (compressed); \
                     export the series uncompressed to read it"
                    .into(),
            ))
        }
        None => return Err(VolumeError::invalid(&h.path, "no pixel data".into())),
    };
    let mut raw = Vec::new();
    raw_samples(value, h.layout.bits_allocated, &mut raw);
    let n = h.rows * h.columns;
    if raw.len() < n {
        return Err(VolumeError::invalid(
            &h.path,
            format!(
                "the pixel data holds {} of the {n} samples of a {}×{} slice (truncated file)",
                raw.len(),
                h.columns,
                h.rows
            ),
        ));
    }
    out.clear();
    out.extend(raw[..n].iter().map(|&r| sample_value(r, &h.layout)));
    Ok(())
}

/// One DICOM file `bytes` (of the file `path`, which names errors) as a
/// slice: its header checked as a series' files are, then its pixels.
pub(crate) fn decode_file(
    path: &Path,
    bytes: &[u8],
) -> Result<([usize; 2], Vec<f32>), VolumeError> {
    let h = read_header(path, bytes)?;
    let mut values = Vec::new();
    pixels(&h, bytes, &mut values)?;
    Ok(([h.columns, h.rows], values))
}

impl SliceSource for DicomSeries {
    fn info(&self) -> &VolumeInfo {
        &self.info
    }

    fn next_slice(&mut self, out: &mut Vec<f32>) -> Result<(), VolumeError> {
        let i = self.next;
        self.next += 1;
        let h = self.slices.get(i).ok_or_else(|| VolumeError::Invalid {
            path: self
                .slices
                .last()
                .map(|h| h.path.clone())
                .unwrap_or_default(),
            problem: "read past the last slice".into(),
        })?;
        let bytes = read_file(&h.path)?;
        if let Some((_, each)) = &self.hashed {
            let first = each.iter().find(|(p, _)| *p == h.path).map(|(_, x)| x);
            if first != Some(&crate::hash::content_hash(&bytes)) {
                return Err(VolumeError::invalid(
                    &h.path,
                    "the file changed while the series was being read".into(),
                ));
            }
        }
        pixels(h, &bytes, out)
    }

    fn content(&mut self) -> Result<Option<Content>, VolumeError> {
        Ok(self.hashed.take().map(|(content, _)| content))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(name: &str, position: Option<f64>, instance: Option<i64>) -> SliceHeader {
        SliceHeader {
            path: PathBuf::from(name),
            series: Some("1.2.3".into()),
            rows: 4,
            columns: 5,
            // Slices stacked along -x: the normal of this orientation.
            position: position.map(|p| [-p, 10.0, 3.0]),
            orientation: Some([0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
            instance,
            pixel_spacing: Some([0.5, 0.25]),
            thickness: Some(0.7),
            layout: PixelLayout {
                bits_allocated: 16,
                bits_stored: 12,
                signed: true,
                inverted: false,
                slope: 2.0,
                intercept: -10.0,
            },
        }
    }

    fn order_of(headers: &[SliceHeader]) -> Vec<&str> {
        order_slices(Path::new("d"), headers)
            .unwrap()
            .order
            .iter()
            .map(|&i| headers[i].path.to_str().unwrap())
            .collect()
    }

    #[test]
    fn slices_order_by_position_along_the_normal_then_instance_then_name() {
        // Normal (0,1,0)×(0,0,1) = (1,0,0); positions are -p along x, so
        // larger p comes first.
        let h = vec![
            header("a", Some(0.3), Some(1)),
            header("b", Some(0.9), Some(2)),
            header("c", Some(0.6), Some(3)),
        ];
        assert_eq!(order_of(&h), ["b", "c", "a"]);
        let o = order_slices(Path::new("d"), &h).unwrap();
        assert!((o.spacing.unwrap() - 0.3).abs() < 1e-9, "{o:?}");
        // One slice without a position: instance numbers decide.
        let mut h2 = h.clone();
        h2[1].position = None;
        h2[0].instance = Some(9);
        assert_eq!(order_of(&h2), ["b", "c", "a"]);
        assert_eq!(order_slices(Path::new("d"), &h2).unwrap().spacing, None);
        // Repeated instance numbers: name order.
        h2[2].instance = Some(9);
        assert_eq!(order_of(&h2), ["a", "b", "c"]);
    }

    #[test]
    fn a_gap_or_a_repeated_position_is_an_error_naming_the_files() {
        let gap = [0.0, 0.5, 1.0, 2.0, 2.5].map(|p| header(&format!("s{p}"), Some(p), None));
        let e = order_slices(Path::new("series"), &gap)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("series")
                && e.contains("missing between s2 and s1")
                && e.contains("2.0 times"),
            "{e}"
        );
        // A step of 1.4 times the median is uneven spacing, not a gap.
        let uneven = [0.0, 0.5, 1.0, 1.7, 2.2].map(|p| header(&format!("s{p}"), Some(p), None));
        assert!(order_slices(Path::new("d"), &uneven).is_ok());
        let twice = [0.0, 0.5, 0.5, 1.0].map(|p| header(&format!("s{p}"), Some(p), None));
        let e = order_slices(Path::new("d"), &twice)
            .unwrap_err()
            .to_string();
        assert!(e.contains("same position"), "{e}");
    }

    #[test]
    fn mixed_series_are_named_with_their_counts() {
        let mut h: Vec<SliceHeader> = (0..5)
            .map(|i| header(&format!("f{i}"), Some(i as f64), None))
            .collect();
        h[3].series = Some("9.9".into());
        h[4].series = Some("9.9".into());
        let e = check_one_series(Path::new("scan"), &h)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("2 DICOM series")
                && e.contains("1.2.3 (3 files, e.g. f0)")
                && e.contains("9.9 (2 files, e.g. f3)"),
            "{e}"
        );
    }

    #[test]
    fn samples_are_masked_sign_extended_and_rescaled() {
        let l = header("a", None, None).layout;
        // 12 stored bits: 0xFFF is -1, high bits ignored.
        assert_eq!(sample_value(0xFFFF, &l), -2.0 - 10.0);
        assert_eq!(sample_value(0x07FF, &l), 2.0 * 2047.0 - 10.0);
        let u = PixelLayout {
            bits_allocated: 8,
            bits_stored: 8,
            signed: false,
            inverted: true,
            slope: 1.0,
            intercept: 0.0,
        };
        assert_eq!(sample_value(200, &u), -200.0);
        let mut raw = Vec::new();
        raw_samples(&PrimitiveValue::U16(vec![0x0201u16].into()), 8, &mut raw);
        assert_eq!(raw, [1, 2]);
        raw_samples(&PrimitiveValue::U8(vec![1u8, 2].into()), 16, &mut raw);
        assert_eq!(raw, [0x0201]);
    }

    /// A 5×4×6 ramp written as a DICOM series by the synthetic writer.
    fn write_ramp(
        dir: &Path,
        bits: u16,
        signed: bool,
        implicit: bool,
    ) -> morphoid_core::mesh::Grid {
        use morphoid_synth::volume::{write_volume, StackSpec, SynthFormat};
        let mut g =
            morphoid_core::mesh::Grid::filled([5, 4, 6], [1.0, 2.0, 3.0], [0.2, 0.3, 0.4], 0.0);
        for (i, v) in g.values.iter_mut().enumerate() {
            *v = (i % 7) as f32 / 7.0 + (i / 20) as f32 * 0.02;
        }
        let spec = StackSpec {
            noise: 0.0,
            ..Default::default()
        };
        let format = SynthFormat::Dicom {
            bits,
            signed,
            implicit,
        };
        write_volume(&g, dir, format, &spec).unwrap();
        g
    }

    fn read_all(dir: &Path) -> Result<(VolumeInfo, Vec<Vec<f32>>), VolumeError> {
        let (files, format) = super::super::stack::slice_files(dir)?;
        assert_eq!(format, VolumeFormat::Dicom);
        let mut series = DicomSeries::open(dir, files, false)?;
        let info = series.info().clone();
        let mut slices = Vec::new();
        for _ in 0..info.dims[2] {
            let mut s = Vec::new();
            series.next_slice(&mut s)?;
            slices.push(s);
        }
        Ok((info, slices))
    }

    #[test]
    fn written_series_read_back_in_every_sample_layout() {
        for (bits, signed, implicit) in [
            (16, false, false),
            (16, true, true),
            (8, false, true),
            (8, true, false),
        ] {
            let d = tempfile::tempdir().unwrap();
            let g = write_ramp(d.path(), bits, signed, implicit);
            // Names that sort against the slice order: the positions decide.
            let mut files = super::super::stack::slice_paths(d.path()).unwrap();
            files.reverse();
            for (k, f) in files.iter().enumerate() {
                std::fs::rename(f, d.path().join(format!("x{k}"))).unwrap();
            }
            let (info, slices) = read_all(d.path()).unwrap();
            let case = format!("{bits} bits, signed {signed}, implicit {implicit}");
            assert_eq!(info.dims, [5, 4, 6], "{case}");
            assert_eq!(info.unit, "mm");
            for (got, want) in info.voxel_size.iter().zip([0.2, 0.3, 0.4]) {
                assert!((got - want).abs() < 1e-5, "{case}: {info:?}");
            }
            let full = if bits == 8 { 255.0 } else { 4095.0 };
            for (z, s) in slices.iter().enumerate() {
                for (k, &v) in s.iter().enumerate() {
                    let want = 0.5 * f64::from(g.values[z * 20 + k]) * full - 1024.0;
                    assert!(
                        (f64::from(v) - want).abs() <= 0.26,
                        "{case}: {z} {k}: {v} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn truncated_and_compressed_files_are_named_errors() {
        let d = tempfile::tempdir().unwrap();
        write_ramp(d.path(), 16, false, false);
        let files = super::super::stack::slice_paths(d.path()).unwrap();
        let cut = &files[2];
        let bytes = std::fs::read(cut).unwrap();
        std::fs::write(cut, &bytes[..bytes.len() - 7]).unwrap();
        let e = read_all(d.path()).unwrap_err().to_string();
        assert!(e.contains(&name(cut)) && e.contains("truncated"), "{e}");

        let d = tempfile::tempdir().unwrap();
        write_ramp(d.path(), 16, false, false);
        let files = super::super::stack::slice_paths(d.path()).unwrap();
        let obj = dicom_object::open_file(&files[1]).unwrap().into_inner();
        let jpeg2000 = "1.2.840.10008.1.2.4.90";
        obj.with_meta(dicom_object::FileMetaTableBuilder::new().transfer_syntax(jpeg2000))
            .unwrap()
            .write_to_file(&files[1])
            .unwrap();
        let e = read_all(d.path()).unwrap_err().to_string();
        assert!(
            e.contains(&name(&files[1]))
                && e.contains("JPEG 2000")
                && e.contains(jpeg2000)
                && e.contains("uncompressed"),
            "{e}"
        );
    }

    #[test]
    fn a_deflated_series_reads_as_the_plain_one() {
        let d = tempfile::tempdir().unwrap();
        write_ramp(d.path(), 16, false, false);
        let (_, plain) = read_all(d.path()).unwrap();
        for f in super::super::stack::slice_paths(d.path()).unwrap() {
            let obj = dicom_object::open_file(&f).unwrap().into_inner();
            let deflated = "1.2.840.10008.1.2.1.99";
            obj.with_meta(dicom_object::FileMetaTableBuilder::new().transfer_syntax(deflated))
                .unwrap()
                .write_to_file(&f)
                .unwrap();
        }
        let (_, read) = read_all(d.path()).unwrap();
        assert_eq!(read, plain);
    }

    #[test]
    fn dicom_files_are_told_by_extension_or_magic_and_dicomdir_is_not_a_slice() {
        let d = tempfile::tempdir().unwrap();
        write_ramp(d.path(), 8, false, false);
        let files = super::super::stack::slice_paths(d.path()).unwrap();
        std::fs::copy(&files[0], d.path().join("DICOMDIR")).unwrap();
        std::fs::copy(&files[0], d.path().join("1.2.826.0.77")).unwrap();
        std::fs::copy(&files[0], d.path().join("noext")).unwrap();
        std::fs::write(d.path().join("notes"), b"short").unwrap();
        std::fs::write(d.path().join("scan.log"), [b'x'; 200]).unwrap();
        let names: Vec<String> = super::super::stack::slice_paths(d.path())
            .unwrap()
            .iter()
            .map(|p| name(p))
            .collect();
        assert_eq!(names.len(), files.len() + 2, "{names:?}");
        assert!(names.contains(&"1.2.826.0.77".into()) && names.contains(&"noext".into()));
        assert!(!names
            .iter()
            .any(|n| n == "DICOMDIR" || n == "notes" || n == "scan.log"));
    }
}
