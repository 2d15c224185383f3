//! A folder of 2D slices (TIFF 8/16-bit greyscale, PNG, BMP), one file
//! per slice, in natural name order (`s2` before `s10`). Files of other
//! kinds (logs, reports) are ignored; the slices must be of one kind, one
//! size, and numbered without gaps. The listing also finds DICOM files,
//! which `dicom` orders by their own metadata.

use super::source::{SliceSource, VolumeFormat, VolumeInfo};
use super::VolumeError;
use crate::hash::{Content, FolderHash};
use std::cmp::Ordering;
use std::path::{Path, PathBuf};

/// The slice format of a file: TIFF, PNG or BMP by extension; DICOM by
/// the `.dcm`/`.dicom` extension or, for any other name, the `DICM` magic
/// at byte 128 (DICOM exports often have no extension). A DICOMDIR index
/// is not a slice.
pub fn slice_format(path: &Path) -> Option<VolumeFormat> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("tif" | "tiff") => Some(VolumeFormat::Tiff),
        Some("png") => Some(VolumeFormat::Png),
        Some("bmp") => Some(VolumeFormat::Bmp),
        Some("dcm" | "dicom") => Some(VolumeFormat::Dicom),
        _ if is_dicomdir(path) => None,
        // Only names that could be a DICOM slice are opened: surface and
        // volume files, logs and reports are recognised by name.
        Some(e) if KNOWN_OTHER.contains(&e) => None,
        _ => super::dicom::has_dicom_magic(path).then_some(VolumeFormat::Dicom),
    }
}

/// Extensions of files found beside slices that are never DICOM, so their
/// bytes need not be looked at.
const KNOWN_OTHER: &[&str] = &[
    "txt", "log", "csv", "xml", "json", "ini", "cfg", "pdf", "htm", "html", "jpg", "jpeg", "ply",
    "stl", "obj", "off", "nrrd", "nii", "gz", "raw", "vol", "zip",
];

fn is_dicomdir(path: &Path) -> bool {
    path.file_name()
        .is_some_and(|n| n.eq_ignore_ascii_case("DICOMDIR"))
}

/// Compare names so that runs of digits compare as numbers.
pub(crate) fn natural_order(a: &str, b: &str) -> Ordering {
    let (mut x, mut y) = (a.as_bytes(), b.as_bytes());
    loop {
        match (x.first(), y.first()) {
            (None, None) => return Ordering::Equal,
            (None, _) => return Ordering::Less,
            (_, None) => return Ordering::Greater,
            (Some(p), Some(q)) if p.is_ascii_digit() && q.is_ascii_digit() => {
                let dx = x.iter().take_while(|c| c.is_ascii_digit()).count();
                let dy = y.iter().take_while(|c| c.is_ascii_digit()).count();
                let (nx, ny) = (trim_zeros(&x[..dx]), trim_zeros(&y[..dy]));
                let o = nx.len().cmp(&ny.len()).then(nx.cmp(ny)).then(dx.cmp(&dy));
                if o != Ordering::Equal {
                    return o;
                }
                x = &x[dx..];
                y = &y[dy..];
            }
            (Some(p), Some(q)) => {
                if p != q {
                    return p.cmp(q);
                }
                x = &x[1..];
                y = &y[1..];
            }
        }
    }
}

fn trim_zeros(d: &[u8]) -> &[u8] {
    let z = d.iter().take_while(|&&c| c == b'0').count();
    &d[z.min(d.len().saturating_sub(1))..]
}

/// The number at the end of a file stem (`slice_0042` → 42), if any.
fn slice_number(path: &Path) -> Option<u64> {
    let stem = path.file_stem()?.to_str()?;
    let digits: String = stem
        .chars()
        .rev()
        .take_while(|c| c.is_ascii_digit())
        .collect::<Vec<_>>()
        .into_iter()
        .rev()
        .collect();
    digits.parse().ok()
}

/// The files of `dir` whose extension names a slice format (hidden files
/// and other kinds left out), in natural name order, unchecked.
pub fn slice_paths(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .filter(|p| {
            !p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with('.'))
        })
        .filter(|p| slice_format(p).is_some())
        .collect();
    files.sort_by(|a, b| natural_order(&a.to_string_lossy(), &b.to_string_lossy()));
    Ok(files)
}

/// The slice files of `dir` in natural order, checked: one kind, at least
/// two, numbered without gaps (where numbered).
pub(super) fn slice_files(dir: &Path) -> Result<(Vec<PathBuf>, VolumeFormat), VolumeError> {
    let files: Vec<(PathBuf, VolumeFormat)> = slice_paths(dir)
        .map_err(|source| VolumeError::Io {
            path: dir.to_path_buf(),
            source,
        })?
        .into_iter()
        .filter_map(|p| slice_format(&p).map(|f| (p, f)))
        .collect();
    let invalid = |problem: String| VolumeError::Invalid {
        path: dir.to_path_buf(),
        problem,
    };
    let Some(&(_, format)) = files.first() else {
        return Err(invalid(
            "no slice files (.tif, .tiff, .png, .bmp, DICOM) in the folder".into(),
        ));
    };
    if let Some((p, f)) = files.iter().find(|(_, f)| *f != format) {
        return Err(invalid(format!(
            "slices of mixed kinds ({format:?} and {f:?}, e.g. {})",
            p.display()
        )));
    }
    if files.len() < 2 {
        return Err(invalid(format!(
            "only {} slice: a volume needs at least two",
            files.len()
        )));
    }
    let numbers: Vec<Option<u64>> = files.iter().map(|(p, _)| slice_number(p)).collect();
    // A DICOM series is ordered by its own metadata, not by file names.
    if format != VolumeFormat::Dicom && numbers.iter().all(Option::is_some) {
        for (w, pair) in numbers.windows(2).zip(files.windows(2)) {
            let (a, b) = (w[0].unwrap_or(0), w[1].unwrap_or(0));
            if b != a + 1 {
                return Err(invalid(format!(
                    "slice numbering jumps from {a} ({}) to {b} ({}): {} missing or duplicated",
                    name(&pair[0].0),
                    name(&pair[1].0),
                    if b > a + 1 { "slices" } else { "a slice is" }
                )));
            }
        }
    }
    Ok((files.into_iter().map(|(p, _)| p).collect(), format))
}

fn name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// One decoded slice: width, height, bits per sample, values.
type Slice = (usize, usize, u16, Vec<f32>);

/// The bytes of the slice file `path`, read once: what is decoded is what
/// is hashed.
fn read_slice_file(path: &Path) -> Result<Vec<u8>, VolumeError> {
    std::fs::read(path).map_err(|source| VolumeError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// The most one image decoder may allocate: an RGBA slice of 32 M pixels.
const MAX_DECODE_BYTES: u64 = 128 << 20;

/// Decode the slice `bytes` (of the file `path`, which names errors).
pub(crate) fn decode_slice(
    path: &Path,
    bytes: &[u8],
    format: VolumeFormat,
) -> Result<Slice, VolumeError> {
    match format {
        VolumeFormat::Tiff => read_tiff(path, bytes),
        _ => read_other(path, bytes),
    }
}

fn read_tiff(path: &Path, bytes: &[u8]) -> Result<Slice, VolumeError> {
    use tiff::decoder::{Decoder, DecodingResult};
    let err = |source: tiff::TiffError| VolumeError::Tiff {
        path: path.to_path_buf(),
        source,
    };
    let mut limits = tiff::decoder::Limits::default();
    limits.decoding_buffer_size = MAX_DECODE_BYTES as usize;
    limits.intermediate_buffer_size = MAX_DECODE_BYTES as usize;
    let mut dec = Decoder::new(std::io::Cursor::new(bytes))
        .map_err(err)?
        .with_limits(limits);
    let (w, h) = dec.dimensions().map_err(err)?;
    super::source::check_slice_size(path, w.into(), h.into())?;
    let colour = dec.colortype().map_err(err)?;
    let channels = match colour {
        tiff::ColorType::Gray(_) => 1,
        tiff::ColorType::RGB(_) => 3,
        tiff::ColorType::RGBA(_) => 4,
        other => {
            return Err(VolumeError::Invalid {
                path: path.to_path_buf(),
                problem: format!("unsupported TIFF colour type {other:?}; greyscale is expected"),
            })
        }
    };
    let image = dec.read_image().map_err(err)?;
    let (bits, values): (u16, Vec<f32>) = match image {
        DecodingResult::U8(v) => (8, v.into_iter().map(f32::from).collect()),
        DecodingResult::U16(v) => (16, v.into_iter().map(f32::from).collect()),
        DecodingResult::I16(v) => (16, v.into_iter().map(f32::from).collect()),
        DecodingResult::U32(v) => (32, v.into_iter().map(|x| x as f32).collect()),
        DecodingResult::F32(v) => (32, v),
        _ => {
            return Err(VolumeError::Invalid {
                path: path.to_path_buf(),
                problem: "unsupported TIFF sample type".into(),
            })
        }
    };
    let (w, h) = (w as usize, h as usize);
    let values = if channels == 1 {
        values
    } else {
        values
            .chunks_exact(channels)
            .map(|c| (c[0] + c[1] + c[2]) / 3.0)
            .collect()
    };
    if values.len() != w * h {
        return Err(VolumeError::Invalid {
            path: path.to_path_buf(),
            problem: format!("{} samples for a {w}×{h} image", values.len()),
        });
    }
    Ok((w, h, bits, values))
}

fn read_other(path: &Path, bytes: &[u8]) -> Result<Slice, VolumeError> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes));
    if let Ok(format) = image::ImageFormat::from_path(path) {
        reader.set_format(format);
    }
    let mut reader = reader
        .with_guessed_format()
        .map_err(|source| VolumeError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    // The decoder's own allocation is capped, and so is the image's size:
    // the conversions below make up to two more copies of it.
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_DECODE_BYTES);
    limits.max_image_width = Some(1 << 16);
    limits.max_image_height = Some(1 << 16);
    reader.limits(limits);
    let img = reader.decode().map_err(|source| VolumeError::Image {
        path: path.to_path_buf(),
        source,
    })?;
    super::source::check_slice_size(path, img.width().into(), img.height().into())?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let (bits, values) = match img {
        image::DynamicImage::ImageLuma8(g) => {
            (8, g.into_raw().into_iter().map(f32::from).collect())
        }
        image::DynamicImage::ImageLuma16(g) => {
            (16, g.into_raw().into_iter().map(f32::from).collect())
        }
        other if other.color().bytes_per_pixel() / other.color().channel_count() == 1 => (
            8,
            other
                .to_luma8()
                .into_raw()
                .into_iter()
                .map(f32::from)
                .collect(),
        ),
        other => (
            16,
            other
                .to_luma16()
                .into_raw()
                .into_iter()
                .map(f32::from)
                .collect(),
        ),
    };
    Ok((w, h, bits, values))
}

/// A folder of slices, read one file at a time.
pub(crate) struct SliceFolder {
    info: VolumeInfo,
    files: Vec<PathBuf>,
    next: usize,
    first: Option<Vec<f32>>,
    /// The folder's hash over the slices read so far, when asked for.
    hash: Option<FolderHash>,
}

impl SliceFolder {
    /// Open the checked slice `files` of a folder (from [`slice_files`]):
    /// read the first for the size. With `hashed`, each slice's bytes as
    /// read are hashed ([`SliceSource::content`]).
    pub(crate) fn open(
        files: Vec<PathBuf>,
        format: VolumeFormat,
        hashed: bool,
    ) -> Result<SliceFolder, VolumeError> {
        let mut hash = hashed.then(FolderHash::new);
        let bytes = read_slice_file(&files[0])?;
        if let Some(h) = &mut hash {
            h.slice(&name(&files[0]), &bytes);
        }
        let (w, h, bits, first) = decode_slice(&files[0], &bytes, format)?;
        Ok(SliceFolder {
            info: VolumeInfo {
                format,
                dims: [w, h, files.len()],
                voxel_size: [1.0; 3],
                unit: "voxel".into(),
                bits,
            },
            files,
            next: 0,
            first: Some(first),
            hash,
        })
    }
}

impl SliceSource for SliceFolder {
    fn info(&self) -> &VolumeInfo {
        &self.info
    }

    fn next_slice(&mut self, out: &mut Vec<f32>) -> Result<(), VolumeError> {
        let i = self.next;
        self.next += 1;
        if let Some(first) = self.first.take() {
            *out = first;
            return Ok(());
        }
        let path = self.files.get(i).ok_or_else(|| VolumeError::Invalid {
            path: self.files.last().cloned().unwrap_or_default(),
            problem: "read past the last slice".into(),
        })?;
        let bytes = read_slice_file(path)?;
        if let Some(hash) = &mut self.hash {
            hash.slice(&name(path), &bytes);
        }
        let (w, h, _, values) = decode_slice(path, &bytes, self.info.format)?;
        if [w, h] != [self.info.dims[0], self.info.dims[1]] {
            return Err(VolumeError::Invalid {
                path: path.clone(),
                problem: format!(
                    "slice is {w}×{h}, the first slice ({}) is {}×{}: slices of unequal size",
                    name(&self.files[0]),
                    self.info.dims[0],
                    self.info.dims[1]
                ),
            });
        }
        *out = values;
        Ok(())
    }

    fn content(&mut self) -> Result<Option<Content>, VolumeError> {
        Ok(self.hash.take().map(FolderHash::finish))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_sort_naturally() {
        let mut v = vec!["s10.tif", "s2.tif", "s1.tif", "s02b.tif"];
        v.sort_by(|a, b| natural_order(a, b));
        assert_eq!(v, vec!["s1.tif", "s2.tif", "s02b.tif", "s10.tif"]);
        assert_eq!(slice_number(Path::new("a/img_0042.tif")), Some(42));
        assert_eq!(slice_number(Path::new("a/img.tif")), None);
    }
}

#[cfg(test)]
mod bad_input_tests {
    use super::*;

    fn open_folder(dir: &Path) -> SliceFolder {
        let (files, format) = slice_files(dir).unwrap();
        SliceFolder::open(files, format, false).unwrap()
    }

    fn write_png(dir: &Path, name: &str, w: u32, h: u32) {
        image::GrayImage::from_pixel(w, h, image::Luma([7u8]))
            .save(dir.join(name))
            .unwrap();
    }

    #[test]
    fn gaps_single_slices_unequal_sizes_and_truncation_are_named_errors() {
        let d = tempfile::tempdir().unwrap();
        write_png(d.path(), "s_001.png", 4, 4);
        let e = slice_files(d.path()).unwrap_err().to_string();
        assert!(e.contains("only 1 slice"), "{e}");
        write_png(d.path(), "s_003.png", 4, 4);
        let e = slice_files(d.path()).unwrap_err().to_string();
        assert!(e.contains("jumps from 1") && e.contains("s_003.png"), "{e}");
        write_png(d.path(), "s_002.png", 5, 4);
        let mut folder = open_folder(d.path());
        let mut s = Vec::new();
        folder.next_slice(&mut s).unwrap();
        let e = folder.next_slice(&mut s).unwrap_err().to_string();
        assert!(e.contains("s_002.png") && e.contains("unequal size"), "{e}");

        let t = tempfile::tempdir().unwrap();
        for z in 0..2 {
            let f = std::fs::File::create(t.path().join(format!("a{z}.tif"))).unwrap();
            let mut enc = tiff::encoder::TiffEncoder::new(f).unwrap();
            enc.write_image::<tiff::encoder::colortype::Gray16>(8, 8, &[9u16; 64])
                .unwrap();
        }
        let p = t.path().join("a1.tif");
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
        let mut folder = open_folder(t.path());
        folder.next_slice(&mut s).unwrap();
        let e = folder.next_slice(&mut s).unwrap_err().to_string();
        assert!(e.contains("a1.tif"), "{e}");
    }
}
