//! Crown extraction on whole teeth as scanners export them
//! (`support::exports`: isosurfaces of voxelized teeth built below the real
//! crowns, smooth or sharp necks, one to three roots, a pulp cavity, the
//! voxel staircase), written as files and prepared as a user's file is;
//! the crown is compared with the real crop it was built on, and the
//! whole teeth are identified against the other crowns.

use crate::support::clean::{crop_fit, print_identified_fits, CropFit};
use crate::support::exports::{export_seed, exported_tooth, form_for, Junction, Placement};
use morphoid_core::mesh::{bbox_diagonal, Mesh};
use std::time::Instant;

/// A kind of export: roots, junction and resolution.
#[derive(Debug, Clone, Copy)]
struct Kind {
    name: &'static str,
    roots: Option<usize>,
    junction: Option<Junction>,
    voxels: usize,
}

/// Smooth-necked single-rooted teeth.
const SMOOTH_ONE_ROOT: Kind = Kind {
    name: "smooth single-rooted",
    roots: Some(1),
    junction: Some(Junction::Smooth),
    voxels: 220,
};

/// Two-rooted isosurfaces at about 300 voxels across the tooth.
const TWO_ROOTS_300: Kind = Kind {
    name: "two-rooted isosurface, 300 voxels",
    roots: Some(2),
    junction: None,
    voxels: 300,
};

/// Every form mixed: 1–3 roots, every junction, 140–300 voxels.
const MIXED: Kind = Kind {
    name: "mixed",
    roots: None,
    junction: None,
    voxels: 0,
};

/// Lowest and highest point of the crop line of `crop` along `axis`, as a
/// fraction of `whole`'s length along it (0 at the root end): where the
/// cut should lie, in the terms of `CrownReport::cut_height_min`/`max`.
fn crop_line_heights(whole: &Mesh, crop: &Mesh, axis: [f64; 3]) -> (f64, f64) {
    let h = |p: [f64; 3]| morphoid_core::mesh::dot(p, axis);
    let lo = whole
        .vertices
        .iter()
        .map(|&p| h(p))
        .fold(f64::MAX, f64::min);
    let hi = whole
        .vertices
        .iter()
        .map(|&p| h(p))
        .fold(f64::MIN, f64::max);
    let rim = morphoid_core::mesh::longest_boundary_loop(crop).unwrap_or_default();
    let t: Vec<f64> = rim
        .iter()
        .map(|&v| (h(crop.vertices[v as usize]) - lo) / (hi - lo))
        .collect();
    (
        t.iter().copied().fold(f64::MAX, f64::min),
        t.iter().copied().fold(f64::MIN, f64::max),
    )
}

/// What one run found.
struct Run {
    prepared: Vec<morphoid_data::pipeline::PreparedSurface>,
    /// The crop each of `prepared` was built on, moved as it was.
    crops: Vec<Mesh>,
    refused: Vec<String>,
    off_target: Vec<String>,
    total: usize,
}

/// Every `step`-th real tooth (or those in `MORPHOID_EXPORT_NAMES`) built
/// as `kind`, moved at random, written as binary PLY, prepared through
/// `pipeline::prepare_file`.
fn run_kind(kind: Kind, step: usize, through_binary: bool) -> Option<Run> {
    let dir = crate::support::data::teeth_dir()?;
    let names = crate::support::cp::tooth_names(&dir);
    let tmp = tempfile::tempdir().unwrap();
    let out_dir = std::env::var_os("MORPHOID_EXPORT_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| tmp.path().to_path_buf());
    std::fs::create_dir_all(&out_dir).unwrap();
    let only: Option<Vec<String>> = std::env::var("MORPHOID_EXPORT_NAMES")
        .ok()
        .map(|v| v.split(',').map(|s| s.trim().to_string()).collect());
    let picked: Vec<(usize, &String)> = match &only {
        Some(only) => names
            .iter()
            .enumerate()
            .filter(|(_, n)| only.contains(n))
            .collect(),
        None => names.iter().enumerate().step_by(step).collect(),
    };
    let settings = morphoid_data::pipeline::Settings::default();
    let mut run = Run {
        prepared: Vec::new(),
        crops: Vec::new(),
        refused: Vec::new(),
        off_target: Vec::new(),
        total: picked.len(),
    };
    use rayon::prelude::*;
    let outcomes: Vec<_> = picked
        .par_iter()
        .map(|&(i, name)| {
            let original = crate::support::cp::load_tooth(&dir, name);
            let seed = export_seed(i);
            let form = form_for(seed, kind.roots, kind.junction, kind.voxels);
            let tooth = exported_tooth(&original, &form).expect("a whole tooth is built");
            let placement = Placement::for_seed(seed, bbox_diagonal(&original));
            let moved = |x: &Mesh| placement.apply(x);
            let path = out_dir.join(format!("{name}.ply"));
            // MORPHOID_EXPORT_IDEAL_CUT=1: the export cut at the true crop
            // line instead, so that only the surface's resolution differs
            // from the crop (what a perfect margin finder would reach).
            let surface = if std::env::var_os("MORPHOID_EXPORT_IDEAL_CUT").is_some() {
                tooth.cut_at_crop_line()
            } else {
                tooth.mesh.clone()
            };
            morphoid_data::mesh_io::write_ply(&path, &moved(&surface)).unwrap();
            if std::env::var_os("MORPHOID_EXPORT_DIR").is_some() {
                // Kept beside the export, for `clean_exports_from_dir`.
                let crop = out_dir.join(format!("{name}.crop.ply"));
                morphoid_data::mesh_io::write_ply(&crop, &moved(&original)).unwrap();
            }
            let started = Instant::now();
            let line = |seconds: f64| {
                format!(
                    "{name}: {} roots, {:?}, {} voxels, blur {:.1}, pulp {}, {} faces, {seconds:.1} s",
                    form.roots,
                    form.junction,
                    form.voxels,
                    form.blur,
                    form.pulp,
                    tooth.mesh.faces.len()
                )
            };
            if through_binary {
                // The CLI's own process, as a user runs it: the test
                // process does not hold the cleaning's memory.
                let crown_path = out_dir.join(format!("{name}.crown.ply"));
                let out = std::process::Command::new(env!("CARGO_BIN_EXE_morphoid"))
                    .arg("inspect")
                    .arg(&path)
                    .arg("--write-clean")
                    .arg(&crown_path)
                    .output()
                    .expect("the morphoid binary runs");
                let seconds = started.elapsed().as_secs_f64();
                if !out.status.success() {
                    println!("{}: REFUSED {}", line(seconds), String::from_utf8_lossy(&out.stderr).trim());
                    return Err(name.clone());
                }
                let crown = morphoid_data::mesh_io::load(&crown_path).expect("the crown written").mesh;
                let f = crop_fit(&crown, &moved(&original));
                println!("{}: mean {:.4} area {:.3}", line(seconds), f.mean, f.area_ratio);
                return Ok((name.clone(), f, None, moved(&original)));
            }
            let out = morphoid_data::pipeline::prepare_file(&path, &settings);
            let seconds = started.elapsed().as_secs_f64();
            match out {
                Ok(out) => {
                    if std::env::var_os("MORPHOID_EXPORT_DIR").is_some() {
                        // The crown cut, for experiments on the cut's place.
                        let cleaned = out_dir.join(format!("{name}.cleaned.ply"));
                        morphoid_data::mesh_io::write_ply(&cleaned, &out.cleaned).unwrap();
                    }
                    let f = crop_fit(&out.cleaned, &moved(&original));
                    let crown = out.cleaning.crown.clone();
                    let truth = crown
                        .as_ref()
                        .map(|c| crop_line_heights(&moved(&tooth.mesh), &moved(&original), c.occlusal));
                    println!(
                        "{}: mean {:.4} area {:.3} cut {:?} crop line {:?}",
                        line(seconds),
                        f.mean,
                        f.area_ratio,
                        crown.map(|c| (c.method, c.cut_height_min, c.cut_height_max)),
                        truth
                    );
                    Ok((name.clone(), f, Some(out), moved(&original)))
                }
                Err(e) => {
                    println!("{}: REFUSED {e}", line(seconds));
                    Err(name.clone())
                }
            }
        })
        .collect();
    for o in outcomes {
        match o {
            Ok((name, f, prepared, crop)) => {
                if !f.on_target() {
                    run.off_target.push(name);
                }
                if let Some(prepared) = prepared {
                    run.prepared.push(prepared);
                    run.crops.push(crop);
                }
            }
            Err(name) => run.refused.push(name),
        }
    }
    println!(
        "{}: {} teeth, {} refused {:?}, {} off target {:?}",
        kind.name,
        run.total,
        run.refused.len(),
        run.refused,
        run.off_target.len(),
        run.off_target
    );
    Some(run)
}

/// The held-out identification of a run's teeth against the other crowns;
/// the crowns they were identified by (cut again along the nearest
/// references' lines) measured against their crops too.
fn identify(run: &mut Run) -> Vec<morphoid_research::eval::RankScore> {
    let dir = crate::support::data::teeth_dir().unwrap();
    let names = crate::support::cp::tooth_names(&dir);
    let params = morphoid_core::cp::CpParams::default();
    let originals = crate::support::cp::prepare_teeth(&dir, &names, &params);
    let scores = crate::support::cp::heldout_scores_classified(&dir, &mut run.prepared, &originals);
    let fits: Vec<(String, CropFit)> = run
        .prepared
        .iter()
        .zip(&run.crops)
        .map(|(s, crop)| (s.prepared.name().to_string(), crop_fit(&s.cleaned, crop)))
        .collect();
    print_identified_fits(&fits, run.total);
    for s in &scores {
        println!(
            "held out, {}: {}/{} ({} refused, not counted)",
            s.rank,
            s.correct,
            s.total,
            run.refused.len()
        );
    }
    scores
}

#[test]
#[ignore = "real data, ~2 min and ~1 GB in the test process (which cli_inspect's peak-memory check inherits): run by name"]
fn clean_exports_whole_teeth_of_every_form_are_cut_on_target() {
    let Some(run) = run_kind(MIXED, 12, true) else {
        return;
    };
    // What the extraction reaches today on these 10 (8 on target, two cut
    // a little low: areas about 1.15); the aim is 95 % on target.
    assert!(run.refused.is_empty(), "refused: {:?}", run.refused);
    assert!(
        run.off_target.len() <= 2,
        "off target: {:?}",
        run.off_target
    );
}

#[test]
#[ignore = "full data: 116 smooth-necked single-rooted teeth, identified held out"]
fn clean_exports_smooth_single_rooted_all() {
    if let Some(mut run) = run_kind(SMOOTH_ONE_ROOT, 1, false) {
        identify(&mut run);
    }
}

#[test]
#[ignore = "full data: 116 two-rooted isosurfaces at 300 voxels, identified held out"]
fn clean_exports_two_rooted_300_all() {
    if let Some(mut run) = run_kind(TWO_ROOTS_300, 1, false) {
        identify(&mut run);
    }
}

#[test]
#[ignore = "real data: every 4th tooth of every form, cut and measured"]
fn clean_exports_mixed_subset() {
    if let Some(mut run) = run_kind(MIXED, 4, false) {
        identify(&mut run);
    }
}

/// Re-measures the exports a run kept in `MORPHOID_EXPORT_DIR` (each
/// `NAME.ply` beside its moved crop `NAME.crop.ply`) without building them
/// again: the quick loop for working on the extraction.
#[test]
#[ignore = "needs MORPHOID_EXPORT_FROM: a folder a run kept"]
fn clean_exports_from_dir() {
    let Some(dir) = std::env::var_os("MORPHOID_EXPORT_FROM").map(std::path::PathBuf::from) else {
        return;
    };
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter_map(|f| f.strip_suffix(".crop.ply").map(str::to_string))
        .collect();
    names.sort();
    let settings = morphoid_data::pipeline::Settings::default();
    use rayon::prelude::*;
    let results: Vec<(
        String,
        Option<CropFit>,
        Option<morphoid_data::pipeline::PreparedSurface>,
    )> = names
        .par_iter()
        .map(|name| {
            let crop = morphoid_data::mesh_io::load(&dir.join(format!("{name}.crop.ply")))
                .unwrap()
                .mesh;
            let started = Instant::now();
            // MORPHOID_EXPORT_CLEANED=1: the crowns the run cut (kept as
            // NAME.cleaned.ply) instead of cutting them again: the quick
            // loop for working on what follows the cut.
            let prepared = if std::env::var_os("MORPHOID_EXPORT_CLEANED").is_some() {
                // No cleaned crown: the run refused the export.
                morphoid_data::mesh_io::load(&dir.join(format!("{name}.cleaned.ply")))
                    .map_err(anyhow::Error::from)
                    .and_then(|cut| {
                        let mut s =
                            morphoid_data::pipeline::prepare_mesh(&cut.mesh, name, &settings)?;
                        s.cleaning.crown = Some(Default::default());
                        Ok(s)
                    })
            } else {
                morphoid_data::pipeline::prepare_file(&dir.join(format!("{name}.ply")), &settings)
                    .map_err(anyhow::Error::from)
            };
            match prepared {
                Ok(out) => {
                    let f = crop_fit(&out.cleaned, &crop);
                    let c = out.cleaning.crown.clone();
                    println!(
                        "{name}: mean {:.4} area {:.3} {:.1} s {:?}",
                        f.mean,
                        f.area_ratio,
                        started.elapsed().as_secs_f64(),
                        c.map(|c| (c.method, c.cut_height_min, c.cut_height_max, c.neck_bulge))
                    );
                    (name.clone(), Some(f), Some(out))
                }
                Err(e) => {
                    println!("{name}: REFUSED {e}");
                    (name.clone(), None, None)
                }
            }
        })
        .collect();
    let refused = results.iter().filter(|(_, f, _)| f.is_none()).count();
    let on = results
        .iter()
        .filter(|(_, f, _)| f.as_ref().is_some_and(CropFit::on_target))
        .count();
    println!(
        "{} exports: {on} on target, {refused} refused",
        results.len()
    );
    // MORPHOID_EXPORT_IDENTIFY=1: identified held out too, as `classify`
    // does (the crowns cut again along the nearest references' lines).
    if std::env::var_os("MORPHOID_EXPORT_IDENTIFY").is_some() {
        let teeth = crate::support::data::teeth_dir().unwrap();
        let all = crate::support::cp::tooth_names(&teeth);
        let params = morphoid_core::cp::CpParams::default();
        let originals = crate::support::cp::prepare_teeth(&teeth, &all, &params);
        let mut surfaces: Vec<_> = results.into_iter().filter_map(|(_, _, s)| s).collect();
        crate::support::cp::heldout_scores_classified(&teeth, &mut surfaces, &originals);
        let fits: Vec<(String, CropFit)> = surfaces
            .iter()
            .map(|s| {
                let name = s.prepared.name().to_string();
                let crop = morphoid_data::mesh_io::load(&dir.join(format!("{name}.crop.ply")))
                    .unwrap()
                    .mesh;
                let f = crop_fit(&s.cleaned, &crop);
                (name, f)
            })
            .collect();
        print_identified_fits(&fits, names.len());
    }
}
