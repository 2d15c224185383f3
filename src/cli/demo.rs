//! `morphoid demo`: the whole loop on synthetic data in a temporary
//! folder — a reference library, an export folder with new scans as a
//! scanner writes them (cropped crowns in four formats, a closed whole
//! tooth, a folder of TIFF slices, and one broken file), identification
//! through the same path the daemon takes, results in a real SQLite
//! database. Needs no data and no configuration.

use super::classify::summary;
use super::common::{progress_bar, ConfigFile};
use anyhow::{Context, Result};
use morphoid_data::library::{Cache, Library};
use morphoid_data::mesh_io;
use morphoid_service::classify::{self, Classifier};
use morphoid_service::store::Store;
use morphoid_synth::mesh::{
    self as synth, LibrarySpec, RigidMotion, WholeToothParams, CROWN_GENERA,
};
use morphoid_synth::volume::{
    batch_in_foam, phantom, write_volume, PhantomParams, StackSpec, SynthFormat,
};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `morphoid demo`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
    /// Keep the temporary folder (library, scans, database) and print its path.
    #[arg(long)]
    keep: bool,
}

/// Run `morphoid demo`.
pub(super) fn run(args: Args, config: ConfigFile) -> Result<ExitCode> {
    // The library, scans and database are the demo's own; the cleaning and
    // engine settings come from the configuration.
    let settings = config.load()?.settings();
    let started = Instant::now();
    let tmp = tempfile::Builder::new()
        .prefix("morphoid-demo-")
        .tempdir()
        .context("creating a temporary folder")?;
    let root = tmp.path();
    let lib_dir = root.join("library");
    let export = root.join("export");
    std::fs::create_dir_all(&export)?;

    write_demo_library(&lib_dir)?;
    let scans = write_demo_scans(&export)?;
    let DemoScans {
        expected,
        batch,
        batch_expected,
        broken,
    } = scans;

    // The daemon's path: prepared library, jobs in SQLite, one transaction per scan.
    let library = Library::open(&lib_dir, None)?;
    let cache = Cache::open(&root.join("cache"))?;
    let bar = progress_bar(library.members().len() as u64, "library");
    let (classifier, built) = Classifier::build(&library, &cache, &settings, |_| bar.inc(1))?;
    bar.finish_and_clear();
    let mut store = Store::open(&root.join("morphoid.sqlite"))?;
    classifier.register(&mut store, &built)?;
    let mut files: Vec<_> = expected.iter().map(|(p, _)| p.clone()).collect();
    files.push(batch.clone());
    files.push(broken.clone());

    println!();
    let mut correct = 0;
    for f in &files {
        let record = classify::identify_file(&mut store, &classifier, f)?;
        let truth = expected.iter().find(|(p, _)| p == f).map(|(_, g)| *g);
        let called = record
            .ranks
            .iter()
            .find(|r| r.rank == "genus")
            .map(|r| r.taxon.as_str());
        if truth.is_some() && truth == called {
            correct += 1;
        }
        let name = f
            .file_name()
            .map(|n| n.to_string_lossy())
            .unwrap_or_default();
        let line = summary(&record).replace(&record.path, &name);
        if *f == batch {
            for (s, t) in record.specimens.iter().zip(&batch_expected) {
                let called = s.ranks.iter().find(|r| r.rank == "genus");
                if called.is_some_and(|r| r.taxon == *t) {
                    correct += 1;
                }
            }
            println!(
                "{line}\n    (generated as {}, left to right)",
                batch_expected.join(", ")
            );
            continue;
        }
        match truth {
            Some(t) => println!("{line}\n    (generated as {t})"),
            None => println!("{line}\n    (cut short on purpose: recorded as an error)"),
        }
    }
    let total = expected.len() + batch_expected.len();
    println!(
        "\n{correct} of {total} specimens identified to the right genus in {:.1} s; database {}",
        started.elapsed().as_secs_f64(),
        if args.keep {
            root.join("morphoid.sqlite").display().to_string()
        } else {
            "removed with the temporary folder (use --keep to look at it)".into()
        }
    );
    if args.keep {
        let kept = tmp.keep();
        println!("kept {}", Path::new(&kept).display());
    }
    Ok(if correct == total {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// The demo's library: 4 synthetic crowns of each of 5 "genera", in
/// random poses, with their labels, in `lib_dir`.
fn write_demo_library(lib_dir: &Path) -> Result<()> {
    // A library of 4 synthetic crowns of each of 5 "genera", in random poses.
    let spec = LibrarySpec {
        per_genus: 4,
        target_vertices: 3000,
        seed: 1,
        random_pose: true,
    };
    synth::write_synthetic_library(lib_dir, &spec)?;
    println!(
        "library: {} synthetic crowns of {} genera in {}",
        spec.per_genus * CROWN_GENERA.len(),
        CROWN_GENERA.len(),
        lib_dir.display()
    );
    Ok(())
}

/// The demo's scans, as a scanner's exports would come.
struct DemoScans {
    /// Each single-specimen scan and the genus it was generated as.
    expected: Vec<(PathBuf, &'static str)>,
    /// The slice stack of three teeth in foam.
    batch: PathBuf,
    /// Its teeth's genera, in the documented order (left to right).
    batch_expected: Vec<&'static str>,
    /// A file cut short on purpose.
    broken: PathBuf,
}

/// Write the demo's scans into `export`: each genus once in a new pose,
/// unit and format; a closed whole tooth; a slice stack; a two-rooted
/// isosurface; three teeth in foam in one stack; a file cut short.
fn write_demo_scans(export: &Path) -> Result<DemoScans> {
    // New individuals as scanner exports: each genus once, in a new pose and
    // unit, in a different format; plus one file cut short.
    let formats = ["ply", "stl", "obj", "off", "ply"];
    let mut expected = Vec::new();
    for (i, (genus, ext)) in CROWN_GENERA.iter().zip(formats).enumerate() {
        let crown = synth::crown(genus, 1000 + i as u64, 4000);
        let posed = synth::scale(
            &RigidMotion::random(77 + i as u64, 50.0).apply(&crown),
            1000.0,
        );
        let path = export.join(format!("scan{:02}.{ext}", i + 1));
        mesh_io::save(&path, &posed)?;
        expected.push((path, genus.name));
    }
    // Whole teeth (crown, cervical neck, roots) below new crowns.
    let whole_tooth = |genus: &synth::CrownGenus, seed: u64| {
        let crown = synth::crown(genus, seed, 4000);
        synth::whole_tooth(&crown, &WholeToothParams::default(), seed)
            .with_context(|| format!("building a whole {} tooth", genus.name))
    };
    // A closed whole tooth, as an isosurface export of a segmented tooth
    // is: its crown is cut at the margin.
    let genus = &CROWN_GENERA[1];
    let whole = whole_tooth(genus, 1010)?;
    let path = export.join("scan06_whole_tooth.stl");
    mesh_io::save(&path, &RigidMotion::random(1010, 20.0).apply(&whole.mesh))?;
    expected.push((path, genus.name));
    // A reconstructed slice stack of another whole tooth: 16-bit TIFF
    // slices with a brighter enamel cap, blur and noise.
    let genus = &CROWN_GENERA[3];
    let grid = phantom(&whole_tooth(genus, 1020)?, &PhantomParams::default());
    let path = export.join("scan07_slices");
    write_volume(&grid, &path, SynthFormat::Tiff16, &StackSpec::default())
        .with_context(|| format!("writing {}", path.display()))?;
    expected.push((path, genus.name));

    // A two-rooted whole tooth exported as a marching-cubes isosurface of
    // its scan (the voxel staircase and all).
    let genus = &CROWN_GENERA[4];
    let two_rooted = {
        let crown = synth::crown(genus, 1030, 4000);
        let params = WholeToothParams {
            root_count: [2, 2],
            ..WholeToothParams::default()
        };
        synth::whole_tooth(&crown, &params, 1030)
            .with_context(|| format!("building a whole {} tooth", genus.name))?
    };
    let grid = phantom(
        &two_rooted,
        &PhantomParams {
            voxels_across: 200,
            ..PhantomParams::default()
        },
    );
    let path = export.join("scan09_two_rooted_isosurface.stl");
    mesh_io::save(&path, &morphoid_core::mesh::isosurface(&grid, 0.3))?;
    expected.push((path, genus.name));
    // Three teeth scanned together, their roots in foam.
    let batch_genera = [&CROWN_GENERA[0], &CROWN_GENERA[2], &CROWN_GENERA[1]];
    let mut phantoms = Vec::new();
    for (k, g) in batch_genera.iter().enumerate() {
        let params = PhantomParams {
            voxels_across: 130,
            ..PhantomParams::default()
        };
        phantoms.push(phantom(
            &whole_tooth(g, 1040 + k as u64)?.upright(),
            &params,
        ));
    }
    let grid = batch_in_foam(&phantoms, 6, 0.25, 0.06, 0.35, 1050);
    let batch = export.join("scan10_batch_of_three");
    write_volume(&grid, &batch, SynthFormat::Tiff16, &StackSpec::default())
        .with_context(|| format!("writing {}", batch.display()))?;
    let batch_expected: Vec<&str> = batch_genera.iter().map(|g| g.name).collect();

    let broken = export.join("scan08.ply");
    let good = std::fs::read(&expected[0].0)?;
    std::fs::write(&broken, &good[..good.len() / 3])?;
    println!(
        "export: {} scans (a closed whole tooth, a folder of slices, a two-rooted isosurface, \
         three teeth in foam in one stack, one file cut short) in {}",
        expected.len() + 2,
        export.display()
    );
    Ok(DemoScans {
        expected,
        batch,
        batch_expected,
        broken,
    })
}
