//! Slice folders as scans, the way users hand them over: `morphoid
//! classify FOLDER` and a folder written slice by slice into the daemon's
//! export folder; and single-file volumes (NRRD, NIfTI) through
//! `pipeline::prepare_file`.

use crate::support::daemon::*;
use morphoid_core::mesh::Grid;
use morphoid_service::store::ScanStatus;
use morphoid_synth::mesh::{self as synth, whole_tooth, WholeToothParams, CROWN_GENERA};
use morphoid_synth::volume::{phantom, write_volume, PhantomParams, StackSpec, SynthFormat};
use std::path::Path;
use std::process::Command;
use std::time::Duration;

/// A small voxelized whole tooth of genus `g` (about 64 samples across),
/// with an enamel cap 0.06 of the diagonal (about six samples) thick, so
/// that the enamel shows as a material and the crown is cut over it, as in
/// a real µCT scan of a tooth at full resolution. (The default cap, 0.025,
/// is two samples here, too thin to show: the crown is then cut from the
/// closed surface by its geometry alone, which on a surface this coarse is
/// not stable: such cuts came out on different sides, or were refused.)
/// What is tested here is how folders and volume files are taken, not
/// where the crown is cut.
fn small_phantom(g: usize, seed: u64) -> Grid {
    let crown = synth::crown(&CROWN_GENERA[g], seed, 1500);
    let tooth = whole_tooth(&crown, &WholeToothParams::default(), seed).unwrap();
    let params = PhantomParams {
        voxels_across: 64,
        margin: 4,
        enamel_thickness: 0.06,
        ..Default::default()
    };
    phantom(&tooth, &params)
}

/// The phantom written to `path` in `format`.
fn write(grid: &Grid, path: &Path, format: SynthFormat) {
    write_volume(grid, path, format, &StackSpec::default()).unwrap();
}

/// The `[clean]` line that turns crown extraction on (the default; said
/// here so that these tests do not depend on it).
const AUTO_CROWN: &str = "crown = \"auto\"";

fn classify_json(env: &Env, scan: &Path) -> serde_json::Value {
    let out = Command::new(BIN)
        .arg("classify")
        .arg("--json")
        .arg("--config")
        .arg(&env.config)
        .arg(scan)
        .output()
        .unwrap();
    let stdout = String::from_utf8(out.stdout).unwrap();
    let v: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    // Only an `ok` result exits 0 (a duplicate exits 1, as for files).
    assert_eq!(out.status.success(), v["status"] == "ok", "{v}");
    v
}

#[test]
fn classify_takes_a_slice_folder_and_knows_it_again_by_content() {
    let env = env(2.0, "", AUTO_CROWN);
    let stack = env.root.join("stacks").join("tooth_a");
    write(&small_phantom(2, 41), &stack, SynthFormat::Tiff8);
    let first = classify_json(&env, &stack);
    assert_eq!(first["status"], "ok", "{first}");
    assert_eq!(first["scan"], stack.display().to_string());
    assert!(first["ranks"]["genus"]["taxon"].is_string(), "{first}");
    let rows1 = rows(&env.db);
    assert_eq!(rows1.len(), 1, "{rows1:?}");
    let slices = morphoid_data::volume::slice_paths(&stack).unwrap();
    let bytes: u64 = slices
        .iter()
        .map(|p| std::fs::metadata(p).unwrap().len())
        .sum();
    assert_eq!(rows1[0].size, bytes, "the size of a folder is its slices'");

    // The same folder again: known content, not a second scan.
    let again = classify_json(&env, &stack);
    assert_eq!(again["id"], first["id"]);
    assert_eq!(again["ranks"], first["ranks"]);
    assert_eq!(rows(&env.db).len(), 1);

    // The same slices under another folder name: recognised as the same
    // content (a duplicate row carrying the earlier result).
    let copy = env.root.join("stacks").join("tooth_a_copy");
    std::fs::create_dir_all(&copy).unwrap();
    for f in &slices {
        std::fs::copy(f, copy.join(f.file_name().unwrap())).unwrap();
    }
    let dup = classify_json(&env, &copy);
    assert_eq!(dup["status"], "duplicate", "{dup}");
    assert_eq!(dup["duplicate_of"]["id"], first["id"]);
    assert_eq!(dup["ranks"], first["ranks"]);

    // One slice replaced by its neighbour: new content, a new scan.
    let copied = morphoid_data::volume::slice_paths(&copy).unwrap();
    let mid = copied.len() / 2;
    std::fs::copy(&copied[mid + 1], &copied[mid]).unwrap();
    let changed = classify_json(&env, &copy);
    assert_eq!(changed["status"], "ok", "{changed}");
    let r = rows(&env.db);
    assert_eq!(r.len(), 3, "{r:?}");
    assert_ne!(r[2].content_hash, r[0].content_hash);
    assert_eq!(r[1].content_hash, r[0].content_hash);
}

#[test]
fn daemon_takes_a_slice_folder_once_after_its_last_slice() {
    // Settle time well above the pauses between slices (0.5 s), so a busy
    // machine waking the writer late does not end the stack early.
    let env = env(4.0, "", AUTO_CROWN);
    let d = Daemon::start(&env);
    let staged = env.root.join("staged");
    write(&small_phantom(1, 77), &staged, SynthFormat::Tiff16);
    let slices = morphoid_data::volume::slice_paths(&staged).unwrap();
    assert!(slices.len() > 20, "{}", slices.len());
    let target = env.export.join("stack_b");
    std::fs::create_dir(&target).unwrap();
    for (i, s) in slices.iter().enumerate() {
        std::fs::copy(s, target.join(s.file_name().unwrap())).unwrap();
        if i % 8 == 7 {
            std::thread::sleep(Duration::from_millis(500));
            assert!(rows(&env.db).is_empty(), "taken before its last slice");
        }
    }
    // The scanner's log beside the slices is not a scan.
    std::fs::write(target.join("scan.log"), b"done").unwrap();
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 1),
        "not processed: {:?}\n{}",
        rows(&env.db),
        d.log_text()
    );
    // Longer than the settle time again: nothing more is taken.
    std::thread::sleep(Duration::from_secs(6));
    let r = rows(&env.db);
    assert_eq!(r.len(), 1, "{r:?}\n{}", d.log_text());
    assert_eq!(r[0].path, target.display().to_string());
    assert_eq!(r[0].status, ScanStatus::Ok, "{:?}", r[0]);
    assert!(genus_of(&r[0]).is_some());
    let bytes: u64 = slices
        .iter()
        .map(|p| std::fs::metadata(p).unwrap().len())
        .sum();
    assert_eq!(r[0].size, bytes, "every slice was in the scan");
}

#[test]
fn nrrd_and_nifti_files_are_prepared_as_the_same_crown() {
    let tmp = tempfile::tempdir().unwrap();
    let grid = small_phantom(3, 19);
    let mut settings = morphoid_data::pipeline::Settings::default();
    settings.clean.crown = morphoid_core::clean::CrownMode::Auto;
    let mut areas = Vec::new();
    for (name, format) in [
        ("t.nrrd", SynthFormat::Nrrd { gzip: true }),
        ("t.nii", SynthFormat::Nifti { gzip: false }),
        ("t.nii.gz", SynthFormat::Nifti { gzip: true }),
    ] {
        let path = tmp.path().join(name);
        let spec = StackSpec {
            noise: 0.0,
            ..Default::default()
        };
        let voxel = write_volume(&grid, &path, format, &spec).unwrap();
        let p = morphoid_data::pipeline::prepare_file(&path, &settings).unwrap();
        let v = p.volume.as_ref().expect("a volume report");
        for (got, written) in v.input.voxel_size.iter().zip(voxel) {
            assert!((got / written - 1.0).abs() < 1e-4, "{name}: {v:?}");
        }
        assert!(v.isosurface_faces > 1000, "{name}: {v:?}");
        assert!(!p.cleaned.faces.is_empty());
        // The voxel size comes from the file: the crown is in its units.
        let extent = morphoid_core::mesh::bbox_diagonal(&p.cleaned);
        let grid_extent = (0..3)
            .map(|a| (grid.dims[a] as f64 * voxel[a]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            extent > 0.1 * grid_extent && extent < grid_extent,
            "{name}: {extent} vs {grid_extent}"
        );
        areas.push(v.isosurface_area);
    }
    for a in &areas[1..] {
        assert!((a / areas[0] - 1.0).abs() < 0.01, "{areas:?}");
    }
}

/// `morphoid inspect PATH`: must fail; its error message (stderr).
fn inspect_error(env: &Env, path: &Path) -> String {
    let out = Command::new(BIN)
        .arg("inspect")
        .arg("--config")
        .arg(&env.config)
        .arg(path)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !out.status.success(),
        "{} was taken: {stderr}",
        path.display()
    );
    stderr
}

/// `morphoid inspect --json PATH`, which must succeed.
fn inspect_json(env: &Env, path: &Path) -> serde_json::Value {
    let out = Command::new(BIN)
        .args(["inspect", "--json", "--config"])
        .arg(&env.config)
        .arg(path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// A DICOM series as a scanner writes it: 16-bit signed, explicit VR.
const DICOM: SynthFormat = SynthFormat::Dicom {
    bits: 16,
    signed: true,
    implicit: false,
};

/// Rename the files of a DICOM folder to names unrelated to slice order
/// (as exports named by instance UID are), so that only the positions in
/// the files can order them.
fn scramble_names(dir: &Path) {
    let files = morphoid_data::volume::slice_paths(dir).unwrap();
    let n = files.len();
    for (k, f) in files.iter().enumerate() {
        let name = format!("1.3.6.1.4.{}", (k * 37 + 11) % (n * 41) + 1000);
        std::fs::rename(f, dir.join(name)).unwrap();
    }
}

#[test]
fn a_dicom_series_gives_the_crown_and_genus_of_the_tiff_stack() {
    let env = env(2.0, "", AUTO_CROWN);
    let grid = small_phantom(2, 41);
    let spec = StackSpec::default();
    let tiff = env.root.join("tiff");
    let dicom = env.root.join("dicom");
    write_volume(&grid, &tiff, SynthFormat::Tiff16, &spec).unwrap();
    let voxel = write_volume(&grid, &dicom, DICOM, &spec).unwrap();
    scramble_names(&dicom);
    assert!(morphoid_data::volume::slice_paths(&dicom)
        .unwrap()
        .iter()
        .all(|p| !p.to_string_lossy().ends_with(".dcm")));

    let mut settings = morphoid_data::pipeline::Settings::default();
    settings.clean.crown = morphoid_core::clean::CrownMode::Auto;
    let t = morphoid_data::pipeline::prepare_file(&tiff, &settings).unwrap();
    let d = morphoid_data::pipeline::prepare_file(&dicom, &settings).unwrap();
    let (tv, dv) = (t.volume.unwrap(), d.volume.unwrap());
    assert_eq!(dv.input.format, morphoid_data::volume::VolumeFormat::Dicom);
    assert_eq!(dv.input.dims, tv.input.dims);
    assert_eq!(dv.input.unit, "mm");
    for (got, written) in dv.input.voxel_size.iter().zip(voxel) {
        assert!((got / written - 1.0).abs() < 1e-4, "{dv:?}");
    }
    // The TIFF stack is in voxels, the series in mm: same shape, scaled.
    let h2 = voxel[0] * voxel[1];
    let iso = dv.isosurface_area / h2 / tv.isosurface_area;
    assert!((iso - 1.0).abs() < 0.01, "isosurface area ratio {iso}");
    let crown = morphoid_core::mesh::surface_area(&d.cleaned)
        / h2
        / morphoid_core::mesh::surface_area(&t.cleaned);
    assert!((crown - 1.0).abs() < 0.03, "crown area ratio {crown}");

    // The same identification (a phantom this small is not always put in
    // its own genus by a 12-crown library: what matters is that both
    // readers give one answer).
    let ct = classify_json(&env, &tiff);
    let cd = classify_json(&env, &dicom);
    assert_eq!(cd["status"], "ok", "{cd}");
    for rank in ["order", "family", "genus"] {
        let (a, b) = (&cd["ranks"][rank], &ct["ranks"][rank]);
        assert_eq!(a["taxon"], b["taxon"], "{cd}\n{ct}");
        assert_eq!(a["reference"], b["reference"]);
        // 12 stored bits against 16: the distances differ a little (the
        // crown's edge follows the enamel level, which the rounding of
        // the noisy grey values moves by a fraction of a sample; measured
        // 6 % apart at a distance of 0.025, far from every reference).
        let (x, y) = (
            a["distance"].as_f64().unwrap(),
            b["distance"].as_f64().unwrap(),
        );
        assert!((x / y - 1.0).abs() < 0.1, "{x} vs {y}");
    }
    // Known again by content, whatever the folder is called.
    let renamed = env.root.join("renamed");
    std::fs::rename(&dicom, &renamed).unwrap();
    let again = classify_json(&env, &renamed);
    assert_eq!(again["status"], "duplicate", "{again}");
    assert_eq!(again["duplicate_of"]["id"], cd["id"]);
}

#[test]
fn bad_dicom_series_are_named_errors() {
    let env = env(2.0, "", AUTO_CROWN);
    let grid = small_phantom(4, 5);
    let spec = StackSpec::default();
    let fresh = |name: &str| {
        let dir = env.root.join(name);
        write_volume(&grid, &dir, DICOM, &spec).unwrap();
        let files = morphoid_data::volume::slice_paths(&dir).unwrap();
        (dir, files)
    };
    let file_name = |p: &Path| p.file_name().unwrap().to_string_lossy().into_owned();

    // Two series in one folder: both named, with their counts.
    let (mixed, files) = fresh("mixed");
    let other = StackSpec {
        seed: 9,
        dims: Some([grid.dims[0], grid.dims[1], 5]),
        ..spec.clone()
    };
    write_volume(&grid, &mixed, DICOM, &other).unwrap();
    let e = inspect_error(&env, &mixed);
    assert!(
        e.contains(&mixed.display().to_string())
            && e.contains("2 DICOM series")
            && e.contains(&format!("({} files", files.len()))
            && e.contains("(5 files"),
        "{e}"
    );

    // A compressed transfer syntax, written by the DICOM library itself.
    let (compressed, files) = fresh("compressed");
    let victim = &files[files.len() / 2];
    let obj = dicom_object::open_file(victim).unwrap().into_inner();
    let jpeg_ls = "1.2.840.10008.1.2.4.80";
    obj.with_meta(dicom_object::FileMetaTableBuilder::new().transfer_syntax(jpeg_ls))
        .unwrap()
        .write_to_file(victim)
        .unwrap();
    let e = inspect_error(&env, &compressed);
    assert!(
        e.contains(&file_name(victim))
            && e.contains("JPEG-LS")
            && e.contains(jpeg_ls)
            && e.contains("export the series uncompressed"),
        "{e}"
    );

    // A file cut short.
    let (truncated, files) = fresh("truncated");
    let victim = &files[3];
    let bytes = std::fs::read(victim).unwrap();
    std::fs::write(victim, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let e = inspect_error(&env, &truncated);
    assert!(
        e.contains(&file_name(victim)) && e.contains("truncated"),
        "{e}"
    );

    // A slice missing: the positions jump.
    let (gap, files) = fresh("gap");
    let k = files.len() / 2;
    std::fs::remove_file(&files[k]).unwrap();
    let e = inspect_error(&env, &gap);
    assert!(
        e.contains(&gap.display().to_string())
            && e.contains(&format!(
                "missing between {} and {}",
                file_name(&files[k - 1]),
                file_name(&files[k + 1])
            ))
            && e.contains("2.0 times the median spacing"),
        "{e}"
    );
}

#[test]
fn bad_slice_folders_are_named_errors() {
    let env = env(2.0, "", AUTO_CROWN);
    let grid = small_phantom(0, 8);
    let stack = |name: &str, dims: Option<[usize; 3]>| {
        let dir = env.root.join(name);
        let spec = StackSpec {
            dims,
            ..Default::default()
        };
        write_volume(&grid, &dir, SynthFormat::Tiff16, &spec).unwrap();
        let files = morphoid_data::volume::slice_paths(&dir).unwrap();
        (dir, files)
    };
    let shown = |p: &Path| p.display().to_string();

    // One slice of another size.
    let (unequal, files) = stack("unequal", None);
    let [w, h, n] = grid.dims;
    let (_, wider) = stack("wider", Some([w + 3, h, n]));
    std::fs::copy(&wider[n / 2], &files[n / 2]).unwrap();
    let e = inspect_error(&env, &unequal);
    assert!(
        e.contains(&shown(&files[n / 2])) && e.contains("unequal size"),
        "{e}"
    );

    // A slice missing from the numbering.
    let (missing, files) = stack("missing", None);
    std::fs::remove_file(&files[n / 2]).unwrap();
    let e = inspect_error(&env, &missing);
    assert!(
        e.contains(&shown(&missing)) && e.contains("slices missing or duplicated"),
        "{e}"
    );

    // One slice only.
    let (single, files) = stack("single", None);
    for f in &files[1..] {
        std::fs::remove_file(f).unwrap();
    }
    let e = inspect_error(&env, &single);
    assert!(
        e.contains(&shown(&single)) && e.contains("only 1 slice"),
        "{e}"
    );

    // A slice cut short.
    let (truncated, files) = stack("truncated", None);
    let bytes = std::fs::read(&files[4]).unwrap();
    std::fs::write(&files[4], &bytes[..bytes.len() / 2]).unwrap();
    let e = inspect_error(&env, &truncated);
    assert!(
        e.contains(&shown(&files[4])) && e.contains("cannot decode the TIFF slice"),
        "{e}"
    );

    // Nothing but background, with the scanner's noise.
    let empty = Grid::filled(grid.dims, grid.origin, grid.spacing, 0.1);
    let background = env.root.join("background");
    write_volume(
        &empty,
        &background,
        SynthFormat::Tiff16,
        &StackSpec::default(),
    )
    .unwrap();
    let e = inspect_error(&env, &background);
    assert!(
        e.contains(&shown(&background)) && e.contains("no specimen"),
        "{e}"
    );
}

/// The phantom with room beside it for a second, smaller specimen: a
/// dentine-grey ball `radius` samples across, clear of the tooth.
fn with_second_specimen(grid: &Grid, radius: usize) -> Grid {
    let extra = 2 * radius + 6;
    let mut dims = grid.dims;
    dims[0] += extra;
    let mut out = Grid::filled(dims, grid.origin, grid.spacing, grid.values[0]);
    for z in 0..grid.dims[2] {
        for y in 0..grid.dims[1] {
            for x in 0..grid.dims[0] {
                let i = out.index(x, y, z);
                out.values[i] = grid.values[grid.index(x, y, z)];
            }
        }
    }
    let c = [grid.dims[0] + extra / 2, grid.dims[1] / 2, grid.dims[2] / 2];
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in grid.dims[0]..dims[0] {
                let d2 = [x, y, z]
                    .iter()
                    .zip(c)
                    .map(|(&a, b)| (a as f64 - b as f64).powi(2))
                    .sum::<f64>();
                if d2 <= (radius * radius) as f64 {
                    let i = out.index(x, y, z);
                    out.values[i] = 0.5;
                }
            }
        }
    }
    out
}

/// The crown is cut in both volumes (asserted): what is tested is that
/// the second specimen is dropped, reported and changes nothing.
#[test]
fn of_two_specimens_the_largest_is_identified_and_the_other_reported() {
    // Without the re-cut along the nearest references: this coarse tooth
    // is far from every reference ("no close match"), where the re-cut
    // distances of its five nearest lie within a few per cent of each
    // other and the answer is a near tie. What is tested here is the
    // segmentation: the second specimen changes nothing.
    let env = env(2.0, "", &format!("{AUTO_CROWN}\n[cp]\nrecut_nearest = 0"));
    let alone = small_phantom(3, 12);
    let grid = with_second_specimen(&alone, 6);
    let dir = env.root.join("two");
    write(&grid, &dir, SynthFormat::Tiff16);
    let one = env.root.join("one");
    write(&alone, &one, SynthFormat::Tiff16);
    let v = inspect_json(&env, &dir);
    // The crown is cut in both (at the margin of the closed surface).
    assert!(v["crown"].is_object(), "{v}");
    assert!(inspect_json(&env, &one)["crown"].is_object());
    let seg = &v["volume"]["segmentation"];
    assert_eq!(seg["dropped_components"], 1, "{v}");
    // The ball: about 4/3 π 6³ ≈ 900 voxels.
    let dropped = seg["dropped_voxels"].as_u64().unwrap();
    assert!((500..1400).contains(&dropped), "{seg}");
    assert!(seg["kept_voxels"].as_u64().unwrap() > 20 * dropped, "{seg}");
    // Identified as the tooth alone is.
    let c = classify_json(&env, &dir);
    assert_eq!(c["status"], "ok", "{c}");
    let a = classify_json(&env, &one);
    assert_eq!(
        c["ranks"]["genus"]["taxon"], a["ranks"]["genus"]["taxon"],
        "{c}\n{a}"
    );
    assert_eq!(c["nearest"][0]["reference"], a["nearest"][0]["reference"]);
}

#[test]
fn daemon_records_a_bad_volume_folder_and_goes_on() {
    // A series with a gap waits for its missing slices, here 3 s, and is
    // then recorded as an error.
    let env = env(2.0, "incomplete_seconds = 3", AUTO_CROWN);
    let d = Daemon::start(&env);
    let staging = env.root.join("staging");
    std::fs::create_dir_all(&staging).unwrap();
    // A series with a slice missing, moved in whole.
    let bad = staging.join("series_bad");
    write(&small_phantom(1, 3), &bad, DICOM);
    let files = morphoid_data::volume::slice_paths(&bad).unwrap();
    std::fs::remove_file(&files[files.len() / 2]).unwrap();
    std::fs::rename(&bad, env.export.join("series_bad")).unwrap();
    assert!(
        wait_until(Duration::from_secs(120), || finished(&env.db) >= 1),
        "not processed: {:?}\n{}",
        rows(&env.db),
        d.log_text()
    );
    let good = staging.join("series_good");
    write(&small_phantom(4, 21), &good, DICOM);
    std::fs::rename(&good, env.export.join("series_good")).unwrap();
    assert!(
        wait_until(Duration::from_secs(180), || finished(&env.db) >= 2),
        "not processed: {:?}\n{}",
        rows(&env.db),
        d.log_text()
    );
    let r = rows(&env.db);
    assert_eq!(r.len(), 2, "{r:?}");
    assert_eq!(
        r[0].path,
        env.export.join("series_bad").display().to_string()
    );
    assert_eq!(r[0].status, ScanStatus::Error, "{:?}", r[0]);
    let error = r[0].error.as_deref().unwrap_or_default();
    assert!(
        error.contains("incomplete after waiting 3 s: DICOM slice positions jump"),
        "{error}"
    );
    assert_eq!(r[1].status, ScanStatus::Ok, "{:?}", r[1]);
    assert!(genus_of(&r[1]).is_some(), "{:?}", r[1]);
}
