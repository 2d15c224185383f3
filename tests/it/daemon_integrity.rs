//! Every row true to the bytes it names (issue 30): under `morphoid run`,
//! a file that changes while it is queued is identified once, as its final
//! content, and no row records a content other than the one identified.
//! Each test checks both: the rows of a path that ended `ok` or `error`
//! carry the hash of the file's final content, exactly once; every other
//! row of it is `superseded`, pointing at a later row.

use crate::support::daemon::*;
use morphoid_data::hash::content_hash_file;
use morphoid_data::mesh_io;
use morphoid_service::store::{ScanRecord, ScanStatus};
use morphoid_synth::mesh::{self as synth, RigidMotion, CROWN_GENERA};
use morphoid_synth::volume::{phantom, write_volume, PhantomParams, StackSpec, SynthFormat};
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The rows of `path` once its final content has finished: exactly one
/// finished row (`ok`, or `error` when `ok_only` is false) carrying the
/// final content's hash, every other row superseded by a later one.
fn assert_final_content_once(env: &Env, d: &Daemon, path: &Path, ok_only: bool) -> ScanRecord {
    let (hash, size) = content_hash_file(path).unwrap();
    let shown = path.display().to_string();
    let done = |r: &[ScanRecord]| {
        r.iter().any(|x| {
            x.path == shown
                && x.content_hash == hash
                && matches!(x.status, ScanStatus::Ok | ScanStatus::Error)
        })
    };
    assert!(
        wait_until(Duration::from_secs(120), || done(&rows(&env.db))),
        "final content not finished: {:#?}\n{}",
        rows(&env.db)
            .iter()
            .map(|r| (&r.path, r.status, &r.content_hash[..8]))
            .collect::<Vec<_>>(),
        d.log_text()
    );
    // Anything still in flight would show as another row now.
    std::thread::sleep(Duration::from_secs(3));
    let mine: Vec<ScanRecord> = rows(&env.db)
        .into_iter()
        .filter(|r| r.path == shown)
        .collect();
    let finished: Vec<&ScanRecord> = mine
        .iter()
        .filter(|r| matches!(r.status, ScanStatus::Ok | ScanStatus::Error))
        .collect();
    assert_eq!(finished.len(), 1, "{mine:#?}\n{}", d.log_text());
    let last = finished[0];
    assert_eq!((&last.content_hash, last.size), (&hash, size), "{mine:#?}");
    if ok_only {
        assert_eq!(last.status, ScanStatus::Ok, "{last:?}");
    }
    for r in &mine {
        if r.id != last.id {
            assert_eq!(r.status, ScanStatus::Superseded, "{r:?}\n{}", d.log_text());
            assert!(r.superseded_by.is_some_and(|n| n > r.id), "{r:?}");
        }
    }
    println!(
        "{}: {} row(s), {} superseded, final content {} once",
        path.display(),
        mine.len(),
        mine.len() - 1,
        last.status
    );
    last.clone()
}

/// A scan of genus `g` as OFF bytes (ASCII: its counts tell when the
/// file is complete).
fn off_scan(g: usize, seed: u64) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let crown = synth::crown(&CROWN_GENERA[g % CROWN_GENERA.len()], seed, 1500);
    let posed = RigidMotion::random(seed, 20.0).apply(&crown);
    let path = dir.path().join("s.off");
    mesh_io::save(&path, &posed).unwrap();
    std::fs::read(&path).unwrap()
}

/// Keep the worker busy for a while: large scans dropped in first (their
/// jobs take seconds, so the next file waits in the queue).
fn busy(env: &Env, d: &Daemon) {
    // Eight: on a quick machine four were identified in 0.8 s, before the
    // next scan's row could be seen pending.
    for k in 0..8 {
        let large = large_scan(env, k, 90 + k as u64, 100_000);
        std::fs::rename(&large, env.export.join(format!("large{k}.ply"))).unwrap();
    }
    assert!(
        wait_until(Duration::from_secs(60), || rows(&env.db)
            .iter()
            .any(|r| r.status == ScanStatus::Running)),
        "{}",
        d.log_text()
    );
}

/// Stop the daemon (SIGSTOP) once the row of `path` with `hash` (any
/// content when `None`) is pending, and check it still is: its job has
/// not read the file. The caller changes the file, then continues it
/// (SIGCONT).
fn stop_while_pending(env: &Env, d: &Daemon, path: &Path, hash: Option<&str>) {
    let shown = path.display().to_string();
    let pending = || {
        rows(&env.db).iter().any(|r| {
            r.path == shown
                && hash.is_none_or(|h| r.content_hash == h)
                && r.status == ScanStatus::Pending
        })
    };
    assert!(
        wait_until(Duration::from_secs(30), pending),
        "{}",
        d.log_text()
    );
    d.signal(libc::SIGSTOP);
    assert!(
        pending(),
        "claimed before the daemon stopped: {:#?}",
        rows(&env.db)
    );
}

/// A whole tooth of genus `g` as a small volume in `format`, written to
/// `staged` under the test's root: its slice files in order.
fn staged_volume(env: &Env, g: usize, seed: u64, format: SynthFormat) -> Vec<PathBuf> {
    let staged = env.root.join("staged");
    let crown = synth::crown(&CROWN_GENERA[g], seed, 1500);
    let tooth = synth::whole_tooth(&crown, &synth::WholeToothParams::default(), seed).unwrap();
    let params = PhantomParams {
        voxels_across: 48,
        margin: 4,
        enamel_thickness: 0.06,
        ..Default::default()
    };
    let grid = phantom(&tooth, &params);
    write_volume(&grid, &staged, format, &StackSpec::default()).unwrap();
    morphoid_data::volume::slice_paths(&staged).unwrap()
}

/// The total size of `files` in bytes.
fn bytes_of(files: &[PathBuf]) -> u64 {
    files
        .iter()
        .map(|p| std::fs::metadata(p).unwrap().len())
        .sum()
}

#[test]
fn a_slow_writer_is_identified_once_as_its_final_content() {
    let env = env(0.5, "", "");
    let d = Daemon::start(&env);
    let bytes = off_scan(2, 301);
    let path = env.export.join("slow.off");
    let mut f = std::fs::File::create(&path).unwrap();
    // Five parts, each pause four times the settle time.
    for part in bytes.chunks(bytes.len().div_ceil(5)) {
        f.write_all(part).unwrap();
        f.flush().unwrap();
        std::thread::sleep(Duration::from_secs(2));
    }
    drop(f);
    let last = assert_final_content_once(&env, &d, &path, true);
    assert_eq!(genus_of(&last), Some(genus(2)));
    let log = d.log_text();
    assert!(log.contains("not complete yet"), "{log}");
    assert!(!log.contains("unexpected end of file"), "{log}");
}

#[test]
fn a_file_replaced_while_queued_is_identified_as_its_new_content() {
    let env = env(0.5, "", "");
    let d = Daemon::start(&env);
    busy(&env, &d);
    let path = env.export.join("replaced.ply");
    put(&env, &path, &scan_bytes(1, 302));
    let first = content_hash_file(&path).unwrap().0;
    assert!(
        wait_until(Duration::from_secs(30), || {
            rows(&env.db)
                .iter()
                .any(|r| r.content_hash == first && r.status == ScanStatus::Pending)
        }),
        "{}",
        d.log_text()
    );
    // Replaced while its job waits behind the large scan.
    put(&env, &path, &scan_bytes(3, 303));
    let last = assert_final_content_once(&env, &d, &path, true);
    assert_eq!(genus_of(&last), Some(genus(3)));
    let r = rows(&env.db);
    let old = r.iter().find(|x| x.content_hash == first).unwrap();
    assert_eq!(old.status, ScanStatus::Superseded, "{old:?}");
    assert_eq!(old.superseded_by, Some(last.id));
    assert!(r.iter().all(|x| x.status != ScanStatus::Error), "{r:#?}");
}

#[test]
fn a_slice_folder_that_grows_while_queued_is_identified_once_whole() {
    let env = env(0.5, "", "");
    let d = Daemon::start(&env);
    let slices = staged_volume(&env, 1, 77, SynthFormat::Tiff8);
    let half = slices.len() / 2;
    busy(&env, &d);
    // Half the slices, queued as they are; the rest while it waits.
    let folder = env.export.join("stack");
    let building = env.root.join("building");
    std::fs::create_dir(&building).unwrap();
    for s in &slices[..half] {
        std::fs::copy(s, building.join(s.file_name().unwrap())).unwrap();
    }
    std::fs::rename(&building, &folder).unwrap();
    let shown = folder.display().to_string();
    stop_while_pending(&env, &d, &folder, None);
    for s in &slices[half..] {
        let staged_slice = env.root.join("slice.part");
        std::fs::copy(s, &staged_slice).unwrap();
        std::fs::rename(&staged_slice, folder.join(s.file_name().unwrap())).unwrap();
    }
    d.signal(libc::SIGCONT);
    let last = assert_final_content_once(&env, &d, &folder, false);
    assert_eq!(last.size, bytes_of(&slices), "every slice was in the scan");
    assert!(
        rows(&env.db)
            .iter()
            .any(|r| r.path == shown && r.status == ScanStatus::Superseded),
        "the half folder was queued and superseded: {:#?}",
        rows(&env.db)
    );
}

#[test]
fn a_dicom_series_with_a_slice_missing_waits_for_it() {
    // Settle time 0.5 s, the default wait for incomplete files (600 s):
    // the series is held by its positions, not by the clock.
    let env = env(0.5, "", "");
    let d = Daemon::start(&env);
    let slices = staged_volume(
        &env,
        2,
        78,
        SynthFormat::Dicom {
            bits: 16,
            signed: false,
            implicit: false,
        },
    );
    let missing = &slices[slices.len() / 3];
    let folder = env.export.join("series");
    let building = env.root.join("building");
    std::fs::create_dir(&building).unwrap();
    for s in slices.iter().filter(|s| *s != missing) {
        std::fs::copy(s, building.join(s.file_name().unwrap())).unwrap();
    }
    std::fs::rename(&building, &folder).unwrap();
    // Held: the positions jump where the slice is missing.
    let shown = folder.display().to_string();
    assert!(
        wait_until(Duration::from_secs(30), || d.log_text().contains(&format!(
            "{shown}: not complete yet (DICOM slice positions jump"
        ))),
        "{}",
        d.log_text()
    );
    std::thread::sleep(Duration::from_secs(3));
    assert!(
        rows(&env.db).iter().all(|r| r.path != shown),
        "queued with a slice missing: {:#?}",
        rows(&env.db)
    );
    let part = env.root.join("slice.part");
    std::fs::copy(missing, &part).unwrap();
    std::fs::rename(&part, folder.join(missing.file_name().unwrap())).unwrap();
    let last = assert_final_content_once(&env, &d, &folder, true);
    assert!(
        rows(&env.db).iter().filter(|r| r.path == shown).count() == 1,
        "one row, of the whole series: {:#?}",
        rows(&env.db)
    );
    assert!(d.log_text().contains(&format!("{shown}: complete now")));
    assert_eq!(last.size, bytes_of(&slices), "every slice was in the scan");
}
