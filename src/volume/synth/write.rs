//! Writing a phantom, resampled to any size with noise, in the formats the
//! readers take. Slices are made and written one at a time, so a stack far
//! larger than memory can be written.

use super::super::grid::Grid;
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
    let voxel = [0, 1, 2]
        .map(|a| grid.spacing[a] * (grid.dims[a].max(2) - 1) as f64 / (dims[a].max(2) - 1) as f64);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(spec.seed);
    let slice = |z: usize, rng: &mut rand_chacha::ChaCha8Rng| -> Vec<f32> {
        let mut out = Vec::with_capacity(dims[0] * dims[1]);
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let p = [0, 1, 2].map(|a| grid.origin[a] + [x, y, z][a] as f64 * voxel[a]);
                let n: f32 = if spec.noise > 0.0 {
                    // Box–Muller.
                    let u1: f32 = rng.gen_range(f32::EPSILON..1.0);
                    let u2: f32 = rng.gen();
                    (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos() * spec.noise
                } else {
                    0.0
                };
                out.push((grid.trilinear(p) + n).clamp(0.0, 1.0));
            }
        }
        out
    };
    let to8 = |s: &[f32]| {
        s.iter()
            .map(|v| (v * 255.0).round() as u8)
            .collect::<Vec<u8>>()
    };
    let to16 = |s: &[f32]| {
        s.iter()
            .map(|v| (v * 65535.0).round() as u16)
            .collect::<Vec<u16>>()
    };
    let (w, h) = (dims[0] as u32, dims[1] as u32);
    let other = |e: Box<dyn std::error::Error + Send + Sync>| std::io::Error::other(e);
    match format {
        SynthFormat::Nrrd { .. } | SynthFormat::Nifti { .. } => {}
        _ => std::fs::create_dir_all(path)?,
    }
    match format {
        SynthFormat::Tiff8 | SynthFormat::Tiff16 => {
            for z in 0..dims[2] {
                let s = slice(z, &mut rng);
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
        }
        SynthFormat::Png8 | SynthFormat::Png16 | SynthFormat::Bmp => {
            for z in 0..dims[2] {
                let s = slice(z, &mut rng);
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
        }
        SynthFormat::Nrrd { gzip } => {
            let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
            write!(
                out,
                "NRRD0004\ntype: uint16\ndimension: 3\nsizes: {} {} {}\nspacings: {} {} {}\nspace units: \"{u}\" \"{u}\" \"{u}\"\nendian: little\nencoding: {}\n\n",
                dims[0], dims[1], dims[2], voxel[0], voxel[1], voxel[2],
                if gzip { "gzip" } else { "raw" },
                u = spec.unit
            )?;
            let mut sink: Box<dyn Write> = if gzip {
                Box::new(flate2::write::GzEncoder::new(
                    out,
                    flate2::Compression::fast(),
                ))
            } else {
                Box::new(out)
            };
            for z in 0..dims[2] {
                let s = slice(z, &mut rng);
                let bytes: Vec<u8> = to16(&s).iter().flat_map(|v| v.to_le_bytes()).collect();
                sink.write_all(&bytes)?;
            }
            sink.flush()?;
        }
        SynthFormat::Nifti { gzip } => {
            let file = std::io::BufWriter::new(std::fs::File::create(path)?);
            let mut sink: Box<dyn Write> = if gzip {
                Box::new(flate2::write::GzEncoder::new(
                    file,
                    flate2::Compression::fast(),
                ))
            } else {
                Box::new(file)
            };
            sink.write_all(&nifti_header(dims, voxel, spec.unit))?;
            for z in 0..dims[2] {
                let s = slice(z, &mut rng);
                let bytes: Vec<u8> = to16(&s).iter().flat_map(|v| v.to_le_bytes()).collect();
                sink.write_all(&bytes)?;
            }
            sink.flush()?;
        }
    }
    Ok(voxel)
}

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
