//! Seed inputs of the fuzz targets (`fuzz/`), made from the synthetic
//! data with the project's own writers, so that no binary file is kept in
//! git: `examples/fuzz_seeds.rs` writes them for a campaign, and
//! `fuzz_replay` runs a handful through the targets' entry points.

use morphoid_core::mesh::Grid;
use morphoid_core::mesh::Mesh;
use morphoid_data::landmarks::{
    format_morphologika, format_tps, Format, Landmarks, NamedLandmarks,
};
use morphoid_data::mesh_io::{encode, Encoding};
use morphoid_data::table::DistanceMatrix;
use morphoid_research::eval::{PairDistance, Shard, ShardFile};
use morphoid_synth::mesh::{
    closed_sphere, crown, punch_hole, square_grid, to_point_cloud, whole_tooth, WholeToothParams,
    CROWN_GENERA,
};
use morphoid_synth::volume::{phantom, write_volume, PhantomParams, StackSpec, SynthFormat};

/// One seed: the target it is for, a file name, its bytes.
pub(crate) type Seed = (&'static str, String, Vec<u8>);

/// Largest seed (bytes): libFuzzer mutates small inputs best.
pub(crate) const MAX_SEED_BYTES: usize = 64 << 10;

/// Every seed of every target, each at most [`MAX_SEED_BYTES`].
pub(crate) fn seeds() -> std::io::Result<Vec<Seed>> {
    let mut out = Vec::new();
    mesh_seeds(&mut out)?;
    volume_seeds(&mut out)?;
    landmark_seeds(&mut out);
    table_seeds(&mut out)?;
    clean_seeds(&mut out);
    pipeline_seeds(&mut out);
    out.retain(|(_, _, bytes)| bytes.len() <= MAX_SEED_BYTES);
    Ok(out)
}

fn encoded(mesh: &Mesh, encoding: Encoding) -> std::io::Result<Vec<u8>> {
    encode(mesh, encoding).map_err(std::io::Error::other)
}

/// Small crowns in every encoding, a point cloud, and the bad inputs the
/// daemon must survive.
fn mesh_seeds(out: &mut Vec<Seed>) -> std::io::Result<()> {
    let small = crown(&CROWN_GENERA[0], 7, 150);
    let tiny = crown(&CROWN_GENERA[2], 3, 40);
    let cloud = to_point_cloud(&small);
    let encodings = [
        ("ply", Encoding::PlyBinaryLe, "le"),
        ("ply", Encoding::PlyBinaryBe, "be"),
        ("ply", Encoding::PlyAscii, "ascii"),
        ("stl", Encoding::StlBinary, "binary"),
        ("stl", Encoding::StlAscii, "ascii"),
        ("obj", Encoding::Obj, "text"),
        ("off", Encoding::Off, "text"),
    ];
    for (target, encoding, kind) in encodings {
        for (what, mesh) in [("crown", &small), ("tiny", &tiny)] {
            let bytes = encoded(mesh, encoding)?;
            out.push((target, format!("{what}_{kind}.{target}"), bytes));
        }
        if target != "stl" {
            let bytes = encoded(&cloud, encoding)?;
            out.push((target, format!("cloud_{kind}.{target}"), bytes));
        }
    }
    let dir = tempfile::tempdir()?;
    for (path, _) in morphoid_synth::mesh::write_bad_inputs(dir.path())? {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        let target = match ext {
            "ply" => "ply",
            "obj" => "obj",
            "stl" => "stl",
            "off" => "off",
            _ => continue,
        };
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        out.push((target, format!("bad_{name}"), std::fs::read(&path)?));
    }
    Ok(())
}

/// A small voxelized whole tooth with an enamel cap, as a grid.
fn small_phantom(voxels_across: usize) -> Grid {
    let c = crown(&CROWN_GENERA[1], 5, 400);
    let tooth = whole_tooth(&c, &WholeToothParams::default(), 5).expect("a whole tooth");
    let params = PhantomParams {
        voxels_across,
        margin: 2,
        enamel_thickness: 0.08,
        ..Default::default()
    };
    phantom(&tooth, &params)
}

/// The phantom written by the volume writers: one slice of each slice
/// format (the middle one: it crosses the tooth), and whole NRRD and
/// NIfTI files.
fn volume_seeds(out: &mut Vec<Seed>) -> std::io::Result<()> {
    let grid = small_phantom(20);
    let spec = StackSpec {
        dims: Some([20, 20, 8]),
        ..StackSpec::default()
    };
    let formats: [(&str, SynthFormat, &str); 12] = [
        ("tiff", SynthFormat::Tiff8, "8"),
        ("tiff", SynthFormat::Tiff16, "16"),
        ("png", SynthFormat::Png8, "8"),
        ("png", SynthFormat::Png16, "16"),
        ("bmp", SynthFormat::Bmp, "8"),
        (
            "dicom",
            SynthFormat::Dicom {
                bits: 16,
                signed: false,
                implicit: false,
            },
            "u16_explicit",
        ),
        (
            "dicom",
            SynthFormat::Dicom {
                bits: 16,
                signed: true,
                implicit: true,
            },
            "i16_implicit",
        ),
        (
            "dicom",
            SynthFormat::Dicom {
                bits: 8,
                signed: false,
                implicit: true,
            },
            "u8_implicit",
        ),
        ("nrrd", SynthFormat::Nrrd { gzip: false }, "raw"),
        ("nrrd", SynthFormat::Nrrd { gzip: true }, "gzip"),
        ("nifti", SynthFormat::Nifti { gzip: false }, "raw"),
        ("nifti", SynthFormat::Nifti { gzip: true }, "gzip"),
    ];
    for (target, format, kind) in formats {
        let dir = tempfile::tempdir()?;
        let path = match target {
            "nrrd" => dir.path().join("v.nrrd"),
            "nifti" if kind == "gzip" => dir.path().join("v.nii.gz"),
            "nifti" => dir.path().join("v.nii"),
            _ => dir.path().join("slices"),
        };
        write_volume(&grid, &path, format, &spec)?;
        if path.is_dir() {
            let files = morphoid_data::volume::slice_paths(&path)?;
            let mid = &files[files.len() / 2];
            let ext = mid.extension().and_then(|e| e.to_str()).unwrap_or("");
            out.push((target, format!("slice_{kind}.{ext}"), std::fs::read(mid)?));
        } else {
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            out.push((target, format!("{kind}_{name}"), std::fs::read(&path)?));
        }
    }
    Ok(())
}

/// Landmarks taken from a crown's vertices, labelled and not, in every
/// landmark format; TPS and morphologika also as a collection.
fn landmark_seeds(out: &mut Vec<Seed>) {
    let c = crown(&CROWN_GENERA[3], 2, 200);
    let points: Vec<[f64; 3]> = c.vertices.iter().step_by(17).copied().collect();
    let labels = (0..points.len()).map(|k| Some(format!("LM{k}"))).collect();
    let labelled = Landmarks::with_labels(points.clone(), labels).expect("one label each");
    let plain = Landmarks::from_points(points);
    let formats = [
        ("tps", Format::Tps, "tps"),
        ("morphologika", Format::Morphologika, "txt"),
        ("fcsv", Format::Fcsv, "fcsv"),
        ("mrk_json", Format::MarkupsJson, "mrk.json"),
        ("pp", Format::PickedPoints, "pp"),
    ];
    for (target, format, ext) in formats {
        for (what, lm) in [("labelled", &labelled), ("plain", &plain)] {
            let text = morphoid_data::landmarks::format(lm, format);
            out.push((target, format!("{what}.{ext}"), text.into_bytes()));
        }
    }
    let collection: Vec<NamedLandmarks> = (0..3)
        .map(|k| NamedLandmarks {
            name: format!("specimen_{k}"),
            landmarks: Landmarks::from_points(
                plain
                    .points()
                    .iter()
                    .map(|p| p.map(|c| c + k as f64))
                    .collect(),
            ),
        })
        .collect();
    out.push((
        "tps",
        "collection.tps".into(),
        format_tps(&collection).into_bytes(),
    ));
    out.push((
        "morphologika",
        "collection.txt".into(),
        format_morphologika(&collection).into_bytes(),
    ));
}

/// The configuration files shipped, the default configuration, a
/// synthetic library's `labels.csv`, a distance matrix and a complete set
/// of two shards (NUL between files, as the shard target splits them).
fn table_seeds(out: &mut Vec<Seed>) -> std::io::Result<()> {
    let shipped = [
        (
            "morphoid.toml",
            include_str!("../../../config/morphoid.toml"),
        ),
        (
            "packaged.toml",
            include_str!("../../../packaging/morphoid.toml"),
        ),
    ];
    for (name, text) in shipped {
        out.push(("config", name.into(), text.as_bytes().to_vec()));
    }
    let default = toml::to_string(&morphoid_service::config::Config::default())
        .map_err(std::io::Error::other)?;
    out.push(("config", "default.toml".into(), default.into_bytes()));

    let dir = tempfile::tempdir()?;
    let spec = morphoid_synth::mesh::LibrarySpec {
        per_genus: 2,
        target_vertices: 60,
        ..Default::default()
    };
    morphoid_synth::mesh::write_synthetic_library(dir.path(), &spec)
        .map_err(std::io::Error::other)?;
    let labels = std::fs::read(dir.path().join("labels.csv"))?;
    out.push(("labels", "labels.csv".into(), labels));

    let names: Vec<String> = (0..5).map(|k| format!("S{k}")).collect();
    let value = |i: usize, j: usize| 0.01 * (i as f64 - j as f64).abs() + 0.001 * (i + j) as f64;
    let values: Vec<Vec<f64>> = (0..5)
        .map(|i| {
            (0..5)
                .map(|j| if i == j { 0.0 } else { value(i, j) })
                .collect()
        })
        .collect();
    let m = DistanceMatrix::new(names.clone(), values).map_err(std::io::Error::other)?;
    out.push(("matrix", "matrix.csv".into(), m.to_csv().into_bytes()));

    let pairs: Vec<(usize, usize)> = (0..5)
        .flat_map(|a| (a + 1..5).map(move |b| (a, b)))
        .collect();
    let mut shards = Vec::new();
    for (index, part) in pairs.chunks(5).enumerate() {
        let file = ShardFile {
            shard: Shard {
                index: index + 1,
                count: 2,
            },
            names: names.clone(),
            content: (0..5).map(|k| Some(format!("{k:064x}"))).collect(),
            pairs: part
                .iter()
                .map(|&(a, b)| PairDistance {
                    a,
                    b,
                    distance: value(a, b),
                    forward: value(a, b),
                    backward: value(a, b) * 1.1,
                })
                .collect(),
        };
        let path = dir.path().join(format!("shard{index}.csv"));
        file.write(&path).map_err(std::io::Error::other)?;
        shards.push(std::fs::read(&path)?);
    }
    out.push(("shard", "one_shard.csv".into(), shards[0].clone()));
    out.push(("shard", "both_shards.csv".into(), shards.join(&0u8)));
    Ok(())
}

/// `mesh` in the clean target's soup format (see `fuzz/src/lib.rs`):
/// coordinates in thousandths (scale code 1), at most 255 vertices.
fn soup(mesh: &Mesh, flags: u8) -> Vec<u8> {
    let n = mesh.vertices.len().min(255);
    let mut bytes = vec![flags | (1 << 4), n as u8];
    for p in &mesh.vertices[..n] {
        for c in p {
            bytes.extend_from_slice(&((c * 1e3).round() as i16).to_le_bytes());
        }
    }
    let modulus = n as u32 + 2;
    for f in mesh.faces.iter().filter(|f| f.iter().all(|&v| v < modulus)) {
        bytes.extend(f.iter().map(|&v| v as u8));
    }
    bytes
}

/// Small disks, a disk with a hole, a closed sphere and a point cloud as
/// vertex and face soups.
fn clean_seeds(out: &mut Vec<Seed>) {
    let c = crown(&CROWN_GENERA[4], 1, 120);
    let grid = square_grid(8);
    let holed = punch_hole(&grid, [4.0, 4.0, 0.0], 1.5);
    // A grid of unit squares is 8 units across: shrink it into i16 range.
    let shrink = |m: &Mesh| {
        Mesh::new(
            m.vertices.iter().map(|p| p.map(|c| c / 4.0)).collect(),
            m.faces.clone(),
        )
    };
    let meshes = [
        ("crown", c.clone(), 0),
        ("grid", shrink(&grid), 1),
        ("holed", shrink(&holed), 0),
        ("sphere", closed_sphere(162), 2),
        ("sphere_crown_off", closed_sphere(162), 4),
        ("cloud", to_point_cloud(&c), 8),
    ];
    for (name, mesh, flags) in meshes {
        out.push(("clean", format!("{name}.soup"), soup(&mesh, flags)));
    }
}

/// The phantom resampled to at most 24³ samples as the volume pipeline
/// target's grid (8-bit grey values), with and without the enamel cut.
fn pipeline_seeds(out: &mut Vec<Seed>) {
    // 20 across and a margin of 2 is 24 samples: the largest grid the
    // target makes.
    let grid = small_phantom(20);
    let dims = grid.dims.map(|d| d.min(24));
    let top = grid
        .values
        .iter()
        .copied()
        .fold(f32::MIN, f32::max)
        .max(1e-6);
    for (name, flags) in [("phantom", 4u8), ("phantom_enamel", 4 | 8)] {
        let mut bytes = vec![
            (dims[0] - 1) as u8,
            (dims[1] - 1) as u8,
            (dims[2] - 1) as u8,
            flags,
        ];
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let v = grid.values[grid.index(x, y, z)] / top * 255.0;
                    bytes.push(v.clamp(0.0, 255.0) as u8);
                }
            }
        }
        out.push(("volume_pipeline", format!("{name}.grid"), bytes));
    }
}
