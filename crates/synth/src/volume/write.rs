//! Writing a phantom, resampled to any size with noise, in the formats the
//! readers take. Slices are made and written one at a time, so a stack far
//! larger than memory can be written.

use dicom_core::value::{PrimitiveValue, C};
use dicom_core::{DataElement, VR};
use dicom_dictionary_std::tags;
use dicom_object::mem::InMemElement;
use morphoid_core::mesh::Grid;
use rand::{Rng, SeedableRng};
use std::io::Write;
use std::path::Path;

/// The format of a written volume.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SynthFormat {
    /// A folder of 8-bit greyscale TIFF slices.
    Tiff8,
    /// A folder of 16-bit greyscale TIFF slices.
    Tiff16,
    /// A folder of 8-bit greyscale PNG slices.
    Png8,
    /// A folder of 16-bit greyscale PNG slices.
    Png16,
    /// A folder of 8-bit greyscale BMP slices.
    Bmp,
    /// One NRRD file, 16-bit, raw or gzip.
    Nrrd {
        /// gzip encoding.
        gzip: bool,
    },
    /// One NIfTI-1 file, 16-bit, `.nii` or `.nii.gz`.
    Nifti {
        /// gzip the whole file.
        gzip: bool,
    },
    /// A folder of DICOM files (CT image storage, uncompressed, with the
    /// file meta header), one slice each, named `IM_<seed>_<z>.dcm`, with
    /// positions, pixel spacing and a rescale slope and intercept.
    Dicom {
        /// 8 or 16 bits per sample (16 stores 12 bits).
        bits: u16,
        /// Signed samples (PixelRepresentation 1).
        signed: bool,
        /// Implicit VR little endian rather than explicit.
        implicit: bool,
    },
}

/// Size and noise of a written volume.
#[derive(Debug, Clone, PartialEq)]
pub struct StackSpec {
    /// Voxels along x, y, z (the phantom's own size where `None`).
    pub dims: Option<[usize; 3]>,
    /// Standard deviation of the added Gaussian noise, in grey units 0..1.
    pub noise: f32,
    /// Seed of the noise.
    pub seed: u64,
    /// Physical unit written where the format has one.
    pub unit: &'static str,
}

impl Default for StackSpec {
    fn default() -> Self {
        StackSpec {
            dims: None,
            noise: 0.03,
            seed: 1,
            unit: "mm",
        }
    }
}

/// Write `grid` to `path` (a folder for slice formats, created; a file
/// otherwise). Returns the voxel size written.
pub fn write_volume(
    grid: &Grid,
    path: &Path,
    format: SynthFormat,
    spec: &StackSpec,
) -> std::io::Result<[f64; 3]> {
    let dims = spec.dims.unwrap_or(grid.dims);
    let voxel = voxel_size(grid, dims);
    let mut slices = Slices {
        grid,
        dims,
        voxel,
        noise: spec.noise,
        rng: rand_chacha::ChaCha8Rng::seed_from_u64(spec.seed),
    };
    match format {
        SynthFormat::Nrrd { .. } | SynthFormat::Nifti { .. } => {}
        _ => std::fs::create_dir_all(path)?,
    }
    match format {
        SynthFormat::Tiff8 | SynthFormat::Tiff16 => write_tiff_slices(&mut slices, path, format)?,
        SynthFormat::Png8 | SynthFormat::Png16 | SynthFormat::Bmp => {
            write_image_slices(&mut slices, path, format)?
        }
        SynthFormat::Nrrd { gzip } => write_nrrd(&mut slices, path, gzip, spec.unit)?,
        SynthFormat::Nifti { gzip } => write_nifti(&mut slices, path, gzip, spec.unit)?,
        SynthFormat::Dicom {
            bits,
            signed,
            implicit,
        } => {
            let series = DicomSeriesSpec {
                dims,
                voxel,
                origin: grid.origin,
                bits,
                signed,
                implicit,
                seed: spec.seed,
            };
            for z in 0..dims[2] {
                let s = slices.slice(z);
                let file = path.join(format!("IM_{}_{z:04}.dcm", spec.seed));
                write_dicom_slice(&file, &series, z, &s).map_err(other)?;
            }
        }
    }
    Ok(voxel)
}

/// The voxel size of `grid` resampled to `dims` samples, the first and
/// last samples kept where they are.
fn voxel_size(grid: &Grid, dims: [usize; 3]) -> [f64; 3] {
    [0, 1, 2]
        .map(|a| grid.spacing[a] * (grid.dims[a].max(2) - 1) as f64 / (dims[a].max(2) - 1) as f64)
}

/// The slices of a written volume, made one at a time: `grid` resampled
/// to `dims` samples of size `voxel`, with Gaussian noise drawn in slice
/// order from `rng`.
struct Slices<'a> {
    grid: &'a Grid,
    dims: [usize; 3],
    voxel: [f64; 3],
    noise: f32,
    rng: rand_chacha::ChaCha8Rng,
}

impl Slices<'_> {
    /// Slice `z`, grey values clamped to 0..1, x fastest.
    fn slice(&mut self, z: usize) -> Vec<f32> {
        let dims = self.dims;
        let mut out = Vec::with_capacity(dims[0] * dims[1]);
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let p =
                    [0, 1, 2].map(|a| self.grid.origin[a] + [x, y, z][a] as f64 * self.voxel[a]);
                let n: f32 = if self.noise > 0.0 {
                    // Box–Muller.
                    let u1: f32 = self.rng.gen_range(f32::EPSILON..1.0);
                    let u2: f32 = self.rng.gen();
                    (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos() * self.noise
                } else {
                    0.0
                };
                out.push((self.grid.trilinear(p) + n).clamp(0.0, 1.0));
            }
        }
        out
    }

    /// Width and height of a slice.
    fn size(&self) -> (u32, u32) {
        (self.dims[0] as u32, self.dims[1] as u32)
    }
}

/// Grey values 0..1 as 8-bit samples.
fn to8(s: &[f32]) -> Vec<u8> {
    s.iter().map(|v| (v * 255.0).round() as u8).collect()
}

/// Grey values 0..1 as 16-bit samples.
fn to16(s: &[f32]) -> Vec<u16> {
    s.iter().map(|v| (v * 65535.0).round() as u16).collect()
}

/// Grey values 0..1 as 16-bit little-endian bytes.
fn le16_bytes(s: &[f32]) -> Vec<u8> {
    to16(s).iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// An encoder's error as an I/O error.
fn other(e: Box<dyn std::error::Error + Send + Sync>) -> std::io::Error {
    std::io::Error::other(e)
}

/// `out`, gzip-compressed when `gzip`.
fn maybe_gzip<'a>(out: impl Write + 'a, gzip: bool) -> Box<dyn Write + 'a> {
    if gzip {
        Box::new(flate2::write::GzEncoder::new(
            out,
            flate2::Compression::fast(),
        ))
    } else {
        Box::new(out)
    }
}

/// A folder of 8- or 16-bit TIFF slices, `slice_<z>.tif`.
fn write_tiff_slices(slices: &mut Slices, path: &Path, format: SynthFormat) -> std::io::Result<()> {
    let (w, h) = slices.size();
    for z in 0..slices.dims[2] {
        let s = slices.slice(z);
        let file = std::fs::File::create(path.join(format!("slice_{z:04}.tif")))?;
        let mut enc = tiff::encoder::TiffEncoder::new(std::io::BufWriter::new(file))
            .map_err(|e| other(Box::new(e)))?;
        if format == SynthFormat::Tiff8 {
            enc.write_image::<tiff::encoder::colortype::Gray8>(w, h, &to8(&s))
        } else {
            enc.write_image::<tiff::encoder::colortype::Gray16>(w, h, &to16(&s))
        }
        .map_err(|e| other(Box::new(e)))?;
    }
    Ok(())
}

/// A folder of 8- or 16-bit PNG or 8-bit BMP slices,
/// `slice_<z>.<ext>`.
fn write_image_slices(
    slices: &mut Slices,
    path: &Path,
    format: SynthFormat,
) -> std::io::Result<()> {
    let (w, h) = slices.size();
    for z in 0..slices.dims[2] {
        let s = slices.slice(z);
        let (ext, f) = match format {
            SynthFormat::Bmp => ("bmp", image::ImageFormat::Bmp),
            _ => ("png", image::ImageFormat::Png),
        };
        let file = path.join(format!("slice_{z:04}.{ext}"));
        let r = if format == SynthFormat::Png16 {
            image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, to16(&s))
                .map(|b| b.save_with_format(&file, f))
        } else {
            image::ImageBuffer::<image::Luma<u8>, _>::from_raw(w, h, to8(&s))
                .map(|b| b.save_with_format(&file, f))
        };
        r.ok_or_else(|| std::io::Error::other("slice buffer size"))?
            .map_err(|e| other(Box::new(e)))?;
    }
    Ok(())
}

/// One NRRD file of 16-bit samples, raw or gzip-encoded after its header.
fn write_nrrd(slices: &mut Slices, path: &Path, gzip: bool, unit: &str) -> std::io::Result<()> {
    let (dims, voxel) = (slices.dims, slices.voxel);
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    write!(
        out,
        "NRRD0004\ntype: uint16\ndimension: 3\nsizes: {} {} {}\nspacings: {} {} {}\nspace units: \"{u}\" \"{u}\" \"{u}\"\nendian: little\nencoding: {}\n\n",
        dims[0], dims[1], dims[2], voxel[0], voxel[1], voxel[2],
        if gzip { "gzip" } else { "raw" },
        u = unit
    )?;
    let mut sink = maybe_gzip(out, gzip);
    for z in 0..dims[2] {
        sink.write_all(&le16_bytes(&slices.slice(z)))?;
    }
    sink.flush()
}

/// One NIfTI-1 file of 16-bit samples, the whole file gzipped when `gzip`.
fn write_nifti(slices: &mut Slices, path: &Path, gzip: bool, unit: &str) -> std::io::Result<()> {
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let mut sink = maybe_gzip(file, gzip);
    sink.write_all(&nifti_header(slices.dims, slices.voxel, unit))?;
    for z in 0..slices.dims[2] {
        sink.write_all(&le16_bytes(&slices.slice(z)))?;
    }
    sink.flush()
}

/// What every file of a written DICOM series shares.
struct DicomSeriesSpec {
    dims: [usize; 3],
    voxel: [f64; 3],
    origin: [f64; 3],
    bits: u16,
    signed: bool,
    implicit: bool,
    seed: u64,
}

/// Write slice `z` (grey values 0..1) of a series as one DICOM file. The
/// stored values map 0..1 to the sample range (12 bits in 16); the rescale
/// slope and intercept map them back to a CT-like scale.
fn write_dicom_slice(
    path: &Path,
    series: &DicomSeriesSpec,
    z: usize,
    values: &[f32],
) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    use dicom_object::{FileMetaTableBuilder, InMemDicomObject};
    let scale = StoredScale::of(series);
    let obj = InMemDicomObject::from_element_iter(
        dicom_identity(series, z)
            .into_iter()
            .chain(dicom_geometry(series, z))
            .chain(dicom_sample_format(series, &scale))
            .chain([dicom_pixels(series.bits, &scale.stored(values))]),
    );
    let syntax = if series.implicit {
        "1.2.840.10008.1.2"
    } else {
        "1.2.840.10008.1.2.1"
    };
    obj.with_meta(FileMetaTableBuilder::new().transfer_syntax(syntax))?
        .write_to_file(path)?;
    Ok(())
}

/// How grey values 0..1 are stored in a series and mapped back.
struct StoredScale {
    /// The stored value of grey 1 (before the offset).
    full_scale: f64,
    /// Subtracted from the stored values: signed samples are centred on
    /// zero.
    offset: f64,
    /// The rescale slope and intercept (the intercept restores the
    /// offset).
    slope: f64,
    intercept: f64,
}

impl StoredScale {
    /// The scale of `series`' sample format.
    fn of(series: &DicomSeriesSpec) -> StoredScale {
        let full_scale = if series.bits == 8 { 255.0 } else { 4095.0 };
        let offset = if series.signed {
            (full_scale + 1.0) / 2.0
        } else {
            0.0
        };
        let (slope, intercept) = (0.5, -1024.0 + 0.5 * offset);
        StoredScale {
            full_scale,
            offset,
            slope,
            intercept,
        }
    }

    /// The stored values of grey `values`.
    fn stored(&self, values: &[f32]) -> Vec<i32> {
        values
            .iter()
            .map(|&v| (f64::from(v) * self.full_scale - self.offset).round() as i32)
            .collect()
    }
}

/// A decimal string as DICOM writes one.
fn ds(v: f64) -> String {
    format!("{v:.6}")
}

/// Several strings as one value.
fn strs(v: Vec<String>) -> dicom_core::value::PrimitiveValue {
    dicom_core::value::PrimitiveValue::Strs(dicom_core::value::C::from_vec(v))
}

/// The slice's SOP class, modality and UIDs (under the 2.25 root, a
/// UUID-derived integer, from the seed) and its instance number.
fn dicom_identity(series: &DicomSeriesSpec, z: usize) -> Vec<InMemElement> {
    let root = 2_000_000_000_000 + series.seed;
    let study = format!("2.25.{root}1");
    let series_uid = format!("2.25.{root}2");
    let instance = format!("2.25.{root}3.{}", z + 1);
    vec![
        DataElement::new(
            tags::SOP_CLASS_UID,
            VR::UI,
            PrimitiveValue::from(CT_IMAGE_STORAGE),
        ),
        DataElement::new(
            tags::SOP_INSTANCE_UID,
            VR::UI,
            PrimitiveValue::from(instance.as_str()),
        ),
        DataElement::new(tags::MODALITY, VR::CS, PrimitiveValue::from("CT")),
        DataElement::new(
            tags::STUDY_INSTANCE_UID,
            VR::UI,
            PrimitiveValue::from(study.as_str()),
        ),
        DataElement::new(
            tags::SERIES_INSTANCE_UID,
            VR::UI,
            PrimitiveValue::from(series_uid.as_str()),
        ),
        DataElement::new(
            tags::INSTANCE_NUMBER,
            VR::IS,
            PrimitiveValue::from((z + 1).to_string()),
        ),
    ]
}

/// Where slice `z` lies: its position, orientation and thickness.
fn dicom_geometry(series: &DicomSeriesSpec, z: usize) -> Vec<InMemElement> {
    let position = [
        series.origin[0],
        series.origin[1],
        series.origin[2] + z as f64 * series.voxel[2],
    ];
    vec![
        DataElement::new(
            tags::IMAGE_POSITION_PATIENT,
            VR::DS,
            strs(position.iter().map(|&p| ds(p)).collect()),
        ),
        DataElement::new(
            tags::IMAGE_ORIENTATION_PATIENT,
            VR::DS,
            strs(["1", "0", "0", "0", "1", "0"].map(String::from).to_vec()),
        ),
        DataElement::new(
            tags::SLICE_THICKNESS,
            VR::DS,
            PrimitiveValue::from(ds(series.voxel[2])),
        ),
    ]
}

/// The sample format: one grey channel, the slice's size and pixel
/// spacing, the bits, the sign and the rescale to the CT-like scale.
fn dicom_sample_format(series: &DicomSeriesSpec, scale: &StoredScale) -> Vec<InMemElement> {
    let [w, h, _] = series.dims;
    vec![
        DataElement::new(tags::SAMPLES_PER_PIXEL, VR::US, PrimitiveValue::from(1u16)),
        DataElement::new(
            tags::PHOTOMETRIC_INTERPRETATION,
            VR::CS,
            PrimitiveValue::from("MONOCHROME2"),
        ),
        DataElement::new(tags::ROWS, VR::US, PrimitiveValue::from(h as u16)),
        DataElement::new(tags::COLUMNS, VR::US, PrimitiveValue::from(w as u16)),
        // Row spacing (along y), then column spacing (along x).
        DataElement::new(
            tags::PIXEL_SPACING,
            VR::DS,
            strs(vec![ds(series.voxel[1]), ds(series.voxel[0])]),
        ),
        DataElement::new(
            tags::BITS_ALLOCATED,
            VR::US,
            PrimitiveValue::from(series.bits),
        ),
        DataElement::new(
            tags::BITS_STORED,
            VR::US,
            PrimitiveValue::from(if series.bits == 8 { 8u16 } else { 12 }),
        ),
        DataElement::new(
            tags::HIGH_BIT,
            VR::US,
            PrimitiveValue::from(if series.bits == 8 { 7u16 } else { 11 }),
        ),
        DataElement::new(
            tags::PIXEL_REPRESENTATION,
            VR::US,
            PrimitiveValue::from(u16::from(series.signed)),
        ),
        DataElement::new(
            tags::RESCALE_INTERCEPT,
            VR::DS,
            PrimitiveValue::from(ds(scale.intercept)),
        ),
        DataElement::new(
            tags::RESCALE_SLOPE,
            VR::DS,
            PrimitiveValue::from(ds(scale.slope)),
        ),
    ]
}

/// The pixel data: the `stored` values as 8-bit (OB) or 16-bit (OW)
/// samples.
fn dicom_pixels(bits: u16, stored: &[i32]) -> InMemElement {
    if bits == 8 {
        DataElement::new(
            tags::PIXEL_DATA,
            VR::OB,
            PrimitiveValue::U8(C::from_vec(stored.iter().map(|&s| s as u8).collect())),
        )
    } else {
        DataElement::new(
            tags::PIXEL_DATA,
            VR::OW,
            PrimitiveValue::U16(C::from_vec(stored.iter().map(|&s| s as u16).collect())),
        )
    }
}

/// The SOP class of CT images.
const CT_IMAGE_STORAGE: &str = "1.2.840.10008.5.1.4.1.1.2";

/// A little-endian NIfTI-1 header (348 bytes + 4 bytes of extension flag)
/// for unsigned 16-bit samples.
fn nifti_header(dims: [usize; 3], voxel: [f64; 3], unit: &str) -> Vec<u8> {
    let mut h = vec![0u8; 352];
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    let dim: [i16; 8] = [
        3,
        dims[0] as i16,
        dims[1] as i16,
        dims[2] as i16,
        1,
        1,
        1,
        1,
    ];
    for (k, d) in dim.iter().enumerate() {
        h[40 + 2 * k..42 + 2 * k].copy_from_slice(&d.to_le_bytes());
    }
    h[70..72].copy_from_slice(&512i16.to_le_bytes());
    h[72..74].copy_from_slice(&16i16.to_le_bytes());
    let pixdim: [f32; 4] = [1.0, voxel[0] as f32, voxel[1] as f32, voxel[2] as f32];
    for (k, p) in pixdim.iter().enumerate() {
        h[76 + 4 * k..80 + 4 * k].copy_from_slice(&p.to_le_bytes());
    }
    h[108..112].copy_from_slice(&352f32.to_le_bytes());
    h[112..116].copy_from_slice(&1f32.to_le_bytes());
    h[123] = match unit {
        "m" => 1,
        "mm" => 2,
        "um" => 3,
        _ => 0,
    };
    h[344..348].copy_from_slice(b"n+1\0");
    h
}
