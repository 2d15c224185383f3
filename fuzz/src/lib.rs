//! The entry points of the fuzz targets, one function per target: each
//! takes arbitrary bytes to one of morphoid's readers (or to cleaning or
//! the volume pipeline), returns whether the input was accepted, and
//! panics only where the library broke a promise (a panic inside it, or a
//! result that breaks the invariants its documentation gives).
//!
//! The stable integration test `tests/it/fuzz_replay.rs` includes this
//! file by path and replays the kept inputs through the same functions,
//! so it uses nothing but `morphoid` and `std`.

use morphoid_core::mesh::Grid;
use morphoid_core::mesh::Mesh;
use morphoid_core::volume::VolumeOptions;
use morphoid_data::mesh_io::{encode, load_bytes, Encoding, Format};
use morphoid_data::volume::VolumeFormat;
use std::path::Path;

/// A target's entry point: whether the input was accepted.
pub type Target = fn(&[u8]) -> bool;

/// Every target by name, as `cargo fuzz` and the replay test call them.
pub const TARGETS: &[(&str, Target)] = &[
    ("ply", ply),
    ("obj", obj),
    ("stl", stl),
    ("off", off),
    ("tiff", tiff),
    ("png", png),
    ("bmp", bmp),
    ("dicom", dicom),
    ("nrrd", nrrd),
    ("nifti", nifti),
    ("tps", tps),
    ("morphologika", morphologika),
    ("fcsv", fcsv),
    ("mrk_json", mrk_json),
    ("pp", pp),
    ("config", config),
    ("labels", labels),
    ("matrix", matrix),
    ("shard", shard),
    ("clean", clean),
    ("volume_pipeline", volume_pipeline),
];

/// A mesh reader on `data`; what it accepts must be a valid mesh that the
/// lossless writer of `rewrite` (if any) writes and the reader reads back.
fn mesh(data: &[u8], format: Format, rewrite: Option<Encoding>) -> bool {
    let name = Path::new("fuzz").with_extension(format.extension());
    let Ok(loaded) = load_bytes(data, format, &name) else {
        return false;
    };
    let m = &loaded.mesh;
    assert!(!m.vertices.is_empty(), "accepted a mesh without vertices");
    assert_eq!(m.first_non_finite_vertex(), None, "non-finite vertex");
    assert_eq!(m.first_face_out_of_range(), None, "face index out of range");
    if let Some(encoding) = rewrite {
        let bytes = encode(m, encoding).expect("a loaded mesh is writable");
        let again = load_bytes(&bytes, format, &name).expect("a written mesh reads back");
        assert_eq!(again.mesh.vertices.len(), m.vertices.len());
        assert_eq!(again.mesh.faces.len(), m.faces.len());
    }
    true
}

/// PLY (ASCII and binary), rewritten as binary PLY.
pub fn ply(data: &[u8]) -> bool {
    mesh(data, Format::Ply, Some(Encoding::PlyBinaryLe))
}

/// Wavefront OBJ, rewritten as OBJ.
pub fn obj(data: &[u8]) -> bool {
    mesh(data, Format::Obj, Some(Encoding::Obj))
}

/// STL (ASCII and binary). Not rewritten: binary STL stores `f32`, so
/// a coordinate read from ASCII need not survive it.
pub fn stl(data: &[u8]) -> bool {
    mesh(data, Format::Stl, None)
}

/// OFF, rewritten as OFF.
pub fn off(data: &[u8]) -> bool {
    mesh(data, Format::Off, Some(Encoding::Off))
}

/// One slice file: what is accepted has one finite value per pixel.
fn slice(data: &[u8], format: VolumeFormat, name: &str) -> bool {
    match morphoid_data::volume::decode_slice_bytes(data, format, Path::new(name)) {
        Ok(([w, h], values)) => {
            assert_eq!(values.len(), w * h, "{w}×{h} slice");
            assert!(values.iter().all(|v| v.is_finite()), "non-finite value");
            true
        }
        Err(_) => false,
    }
}

/// A TIFF slice.
pub fn tiff(data: &[u8]) -> bool {
    slice(data, VolumeFormat::Tiff, "fuzz_0001.tif")
}

/// A PNG slice.
pub fn png(data: &[u8]) -> bool {
    slice(data, VolumeFormat::Png, "fuzz_0001.png")
}

/// A BMP slice.
pub fn bmp(data: &[u8]) -> bool {
    slice(data, VolumeFormat::Bmp, "fuzz_0001.bmp")
}

/// One DICOM file of a series.
pub fn dicom(data: &[u8]) -> bool {
    slice(data, VolumeFormat::Dicom, "fuzz_0001.dcm")
}

/// Working resolution of the volume targets: small, so that each run is
/// quick; the reduction is the same code at any size.
const FUZZ_WORKING_VOXELS: usize = 24;

/// A single-file volume read into the working grid: what is accepted
/// has the grid's shape, finite values and a finite positive voxel size.
fn volume_file(data: &[u8], name: &str) -> bool {
    let opts = VolumeOptions {
        working_voxels: FUZZ_WORKING_VOXELS,
        ..VolumeOptions::default()
    };
    match morphoid_data::volume::working_grid_from_bytes(data, Path::new(name), &opts) {
        Ok((grid, info)) => {
            let n: usize = grid.dims.iter().product();
            assert_eq!(grid.values.len(), n, "grid of {:?}", grid.dims);
            assert!(grid.dims.iter().all(|&d| d <= FUZZ_WORKING_VOXELS));
            assert!(
                grid.values.iter().all(|v| v.is_finite()),
                "non-finite value"
            );
            assert!(
                info.voxel_size.iter().all(|s| s.is_finite() && *s > 0.0),
                "voxel size {:?}",
                info.voxel_size
            );
            true
        }
        Err(_) => false,
    }
}

/// NRRD (raw or gzip).
pub fn nrrd(data: &[u8]) -> bool {
    volume_file(data, "fuzz.nrrd")
}

/// NIfTI-1, gzipped when the bytes start with the gzip magic (as a
/// `.nii.gz` file would).
pub fn nifti(data: &[u8]) -> bool {
    let gz = data.starts_with(&[0x1f, 0x8b]);
    volume_file(data, if gz { "fuzz.nii.gz" } else { "fuzz.nii" })
}

/// A landmark file in `format`: what is accepted holds finite points.
fn landmarks(data: &[u8], format: morphoid_data::landmarks::Format, name: &str) -> bool {
    let Ok(text) = std::str::from_utf8(data) else {
        return false;
    };
    match morphoid_data::landmarks::parse(text, format, Path::new(name)) {
        Ok(lm) => {
            assert!(!lm.is_empty());
            assert_eq!(lm.labels().len(), lm.len());
            assert!(
                lm.points().iter().flatten().all(|c| c.is_finite()),
                "non-finite landmark"
            );
            true
        }
        Err(_) => false,
    }
}

/// TPS (one specimen, as a specimen's landmark file).
pub fn tps(data: &[u8]) -> bool {
    if let Ok(text) = std::str::from_utf8(data) {
        // The collection reader too (`morphoid align`'s TPS input).
        let _ = morphoid_data::landmarks::parse_tps(text, Path::new("fuzz.tps"));
    }
    landmarks(data, morphoid_data::landmarks::Format::Tps, "fuzz.tps")
}

/// Morphologika.
pub fn morphologika(data: &[u8]) -> bool {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = morphoid_data::landmarks::parse_morphologika(text, Path::new("fuzz.txt"));
    }
    landmarks(
        data,
        morphoid_data::landmarks::Format::Morphologika,
        "fuzz.txt",
    )
}

/// 3D Slicer markups CSV.
pub fn fcsv(data: &[u8]) -> bool {
    landmarks(data, morphoid_data::landmarks::Format::Fcsv, "fuzz.fcsv")
}

/// 3D Slicer markups JSON.
pub fn mrk_json(data: &[u8]) -> bool {
    landmarks(
        data,
        morphoid_data::landmarks::Format::MarkupsJson,
        "fuzz.mrk.json",
    )
}

/// MeshLab picked points.
pub fn pp(data: &[u8]) -> bool {
    landmarks(
        data,
        morphoid_data::landmarks::Format::PickedPoints,
        "fuzz.pp",
    )
}

/// The TOML configuration.
pub fn config(data: &[u8]) -> bool {
    let Ok(text) = std::str::from_utf8(data) else {
        return false;
    };
    match morphoid_service::config::Config::parse(text, Path::new("fuzz.toml")) {
        Ok(c) => {
            let _ = c.settings();
            let _ = c.ranks();
            true
        }
        Err(_) => false,
    }
}

/// `labels.csv`, all rank columns and then only `genus`.
pub fn labels(data: &[u8]) -> bool {
    let Ok(text) = std::str::from_utf8(data) else {
        return false;
    };
    let path = Path::new("labels.csv");
    let genus = ["genus".to_string()];
    let _ = morphoid_data::table::Labels::parse(text, Some(&genus), path);
    match morphoid_data::table::Labels::parse(text, None, path) {
        Ok(l) => {
            for name in l.names() {
                for rank in l.ranks() {
                    let _ = l.get(name, rank);
                }
            }
            true
        }
        Err(_) => false,
    }
}

/// A distance matrix CSV: what is accepted is square.
pub fn matrix(data: &[u8]) -> bool {
    let Ok(text) = std::str::from_utf8(data) else {
        return false;
    };
    match morphoid_data::table::DistanceMatrix::parse_csv(text, Path::new("fuzz.csv")) {
        Ok(m) => {
            assert_eq!(m.names().len(), m.len());
            assert!(m.values().iter().all(|row| row.len() == m.len()));
            true
        }
        Err(_) => false,
    }
}

/// Up to four shard files, separated by NUL bytes, each parsed; those
/// that parse are merged.
pub fn shard(data: &[u8]) -> bool {
    let Ok(text) = std::str::from_utf8(data) else {
        return false;
    };
    let shards: Vec<_> = text
        .split('\0')
        .take(4)
        .enumerate()
        .filter_map(|(k, part)| {
            let path = std::path::PathBuf::from(format!("shard{k}.csv"));
            let parsed = morphoid_research::eval::ShardFile::parse(part, &path).ok()?;
            Some((path, parsed))
        })
        .collect();
    if shards.is_empty() {
        return false;
    }
    match morphoid_research::eval::merge_shards(&shards) {
        Ok(m) => {
            assert!(m.values().iter().all(|row| row.len() == m.len()));
            true
        }
        Err(_) => false,
    }
}

/// A little-endian `i16` at `k` of `data`, 0 past its end.
fn i16_at(data: &[u8], k: usize) -> i16 {
    i16::from_le_bytes([
        data.get(k).copied().unwrap_or(0),
        data.get(k + 1).copied().unwrap_or(0),
    ])
}

/// Cleaning of a small soup read from the bytes: byte 0 holds options
/// (bits 0–1 the working resolution, 2 crown extraction off, 3 a point
/// cloud, 4–6 the coordinate scale), byte 1 the vertex count; then the
/// vertices (three `i16` each), then faces (three bytes each, indices
/// modulo a little more than the vertex count, so some are out of range).
/// What cleaning accepts must be a valid mesh.
pub fn clean(data: &[u8]) -> bool {
    use morphoid_core::clean::{CleanOptions, CrownMode};
    let [flags, count, rest @ ..] = data else {
        return false;
    };
    let scale = [1e-9, 1e-3, 0.01, 1.0, 10.0, 1e3, 1e6, 1e12][usize::from((flags >> 4) & 7)];
    let nv = usize::from(*count);
    let vertices: Vec<[f64; 3]> = (0..nv)
        .map(|v| [0, 1, 2].map(|c| f64::from(i16_at(rest, 6 * v + 2 * c)) * scale))
        .collect();
    let faces: Vec<[u32; 3]> = if flags & 8 != 0 {
        Vec::new()
    } else {
        rest.get(6 * nv..)
            .unwrap_or_default()
            .chunks_exact(3)
            .take(1024)
            .map(|f| [0, 1, 2].map(|c| u32::from(f[c]) % (nv as u32 + 2)))
            .collect()
    };
    let opts = CleanOptions {
        target_vertices: [100, 200, 500, 1000][usize::from(flags & 3)],
        crown: if flags & 4 != 0 {
            CrownMode::Off
        } else {
            CrownMode::Auto
        },
        ..CleanOptions::default()
    };
    match morphoid_core::clean::clean(&Mesh::new(vertices, faces), &opts) {
        Ok(cleaned) => {
            let m = &cleaned.mesh;
            assert!(!m.faces.is_empty(), "a cleaned surface has faces");
            assert_eq!(m.first_non_finite_vertex(), None, "non-finite vertex");
            assert_eq!(m.first_face_out_of_range(), None, "face index out of range");
            true
        }
        Err(_) => false,
    }
}

/// The volume pipeline after reading, on a grid of at most 24³ samples
/// from the bytes: bytes 0–2 the dimensions (1 to 24 each), byte 3 the
/// spacing (bits 0–2) and the enamel cut (bit 3), then one byte per
/// sample (0 past the end), as the grey values of an 8-bit scan.
pub fn volume_pipeline(data: &[u8]) -> bool {
    let [x, y, z, flags, rest @ ..] = data else {
        return false;
    };
    let dims = [*x, *y, *z].map(|d| 1 + usize::from(d) % 24);
    let spacing = [1e-3, 0.01, 0.05, 0.1, 1.0, 10.0, 1e3, 1e6][usize::from(flags & 7)];
    let mut grid = Grid::filled(dims, [0.0; 3], [spacing; 3], 0.0);
    for (v, &b) in grid.values.iter_mut().zip(rest) {
        *v = f32::from(b);
    }
    let opts = VolumeOptions {
        working_voxels: FUZZ_WORKING_VOXELS,
        enamel: flags & 8 != 0,
    };
    match morphoid_data::volume::surface_from_grid(&grid, &opts, Path::new("fuzz")) {
        Ok(meshes) => {
            for m in meshes {
                assert_eq!(m.first_non_finite_vertex(), None, "non-finite vertex");
                assert_eq!(m.first_face_out_of_range(), None, "face index out of range");
            }
            true
        }
        Err(_) => false,
    }
}
