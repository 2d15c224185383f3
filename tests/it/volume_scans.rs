//! Slice folders as scans, the way users hand them over: `morphoid
//! classify FOLDER` and a folder written slice by slice into the daemon's
//! export folder; and single-file volumes (NRRD, NIfTI) through
//! `pipeline::prepare_file`.

use crate::support::daemon::*;
use morphoid::mesh::synth::{self, whole_tooth, WholeToothParams, CROWN_GENERA};
use morphoid::store::ScanStatus;
use morphoid::volume::synth::{phantom, write_volume, PhantomParams, StackSpec, SynthFormat};
use morphoid::volume::Grid;
use std::path::Path;
use std::process::Command;
use std::time::Duration;

/// A small voxelized whole tooth of genus `g` (about 64 samples across),
/// with an enamel cap. At this size the cap is too thin to show as a
/// material of its own, so these scans take the closed-surface route,
/// which needs crown extraction on ([`AUTO_CROWN`]); what is tested here
/// is how folders and volume files are taken, not where the crown is cut.
fn small_phantom(g: usize, seed: u64) -> Grid {
    let crown = synth::crown(&CROWN_GENERA[g], seed, 1500);
    let tooth = whole_tooth(&crown, &WholeToothParams::default(), seed).unwrap();
    let params = PhantomParams {
        voxels_across: 64,
        margin: 4,
        ..Default::default()
    };
    phantom(&tooth, &params)
}

/// The phantom written to `path` in `format`.
fn write(grid: &Grid, path: &Path, format: SynthFormat) {
    write_volume(grid, path, format, &StackSpec::default()).unwrap();
}

/// The `[clean]` line that turns crown extraction on (off by default).
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
    let slices = morphoid::volume::slice_paths(&stack).unwrap();
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
    let copied = morphoid::volume::slice_paths(&copy).unwrap();
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
    let slices = morphoid::volume::slice_paths(&staged).unwrap();
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
    let mut settings = morphoid::pipeline::Settings::default();
    settings.clean.crown = morphoid::clean::CrownMode::Auto;
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
        let p = morphoid::pipeline::prepare_file(&path, &settings).unwrap();
        let v = p.volume.as_ref().expect("a volume report");
        for (got, written) in v.input.voxel_size.iter().zip(voxel) {
            assert!((got / written - 1.0).abs() < 1e-4, "{name}: {v:?}");
        }
        assert!(v.isosurface_faces > 1000, "{name}: {v:?}");
        assert!(!p.cleaned.faces.is_empty());
        // The voxel size comes from the file: the crown is in its units.
        let extent = morphoid::mesh::bbox_diagonal(&p.cleaned);
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
