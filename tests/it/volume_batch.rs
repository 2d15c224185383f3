//! Batch scans: several real teeth scanned together, each in its own foam
//! and tube, the mounts standing side by side (`morphoid_synth::volume::mounting`, built
//! independently of the segmentation). Each tooth must come out as its own
//! specimen, numbered along the stack's longest axis, with its position,
//! its crown on the real crown, and its own identification.

use super::support::clean::{crop_fit, print_identified_fits, CropFit};
use super::support::{cp as cps, data};
use morphoid_core::clean::point_to_surface_distances;
use morphoid_core::mesh::Mesh;
use morphoid_data::pipeline::{load_scan, prepare_specimens, PreparedSurface, Settings};
use morphoid_synth::volume::mounting::*;
use rayon::prelude::*;
use std::path::Path;

/// One specimen of a batch: prepared (or why not), its mean distance to
/// the true crown its box holds (in voxels), and that crown.
type Specimen = (Result<PreparedSurface, String>, Option<f64>, Option<Mesh>);

/// One batch of teeth as read back: each specimen prepared (or why not),
/// with its mean distance to the true crown (voxels) and the crown its box
/// holds.
struct Batch {
    names: Vec<String>,
    specimens: Vec<Specimen>,
    warnings: Vec<String>,
}

fn mean(d: Vec<f64>) -> f64 {
    d.iter().sum::<f64>() / d.len().max(1) as f64
}

/// The teeth `names` of `dir` scanned together (mount varied by `seed`,
/// `across` voxels across each crown, mounts `gap` voxels apart), written
/// under `out`, read back through the normal volume path.
fn batch(dir: &Path, names: &[String], seed: u64, across: usize, gap: i64, out: &Path) -> Batch {
    let crowns: Vec<_> = names.iter().map(|n| cps::load_tooth(dir, n)).collect();
    let teeth: Vec<(&morphoid_core::mesh::Mesh, Mount)> = crowns
        .iter()
        .zip(batch_mounts(seed, across, names.len()))
        .collect();
    let path = out.join(format!("batch-{seed}"));
    let truth = write_batch(&teeth, gap, &path).unwrap();
    let settings = Settings::default();
    let loaded = load_scan(&path, &settings).expect("the batch stack is read");
    let warnings = loaded
        .volume
        .as_ref()
        .map(|v| v.segmentation.warnings.clone())
        .unwrap_or_default();
    let specimens = prepare_specimens(loaded, &path, &settings)
        .into_iter()
        .map(|(position, prepared)| {
            let prepared = prepared.map_err(|e| e.to_string());
            // The true crown this specimen's box holds (by its centre).
            let holder = truth.iter().position(|t| {
                let c = centre(&t.crown.vertices);
                let [lo, hi] = position.bounds;
                (0..3).all(|a| c[a] >= lo[a] && c[a] <= hi[a])
            });
            let distance = match (&prepared, holder) {
                (Ok(p), Some(k)) => Some(mean(point_to_surface_distances(
                    &p.cleaned.vertices,
                    &truth[k].crown,
                ))),
                _ => None,
            };
            (prepared, distance, holder.map(|k| truth[k].crown.clone()))
        })
        .collect();
    keep_or_remove(&path);
    Batch {
        names: names.to_vec(),
        specimens,
        warnings,
    }
}

/// The stack at `path` removed, or with MORPHOID_KEEP_BATCH=folder moved
/// there, to look at.
fn keep_or_remove(path: &Path) {
    match std::env::var_os("MORPHOID_KEEP_BATCH") {
        Some(keep) => {
            let keep = Path::new(&keep);
            let _ = std::fs::create_dir_all(keep);
            let _ = std::fs::rename(path, keep.join(path.file_name().unwrap_or_default()));
        }
        None => {
            let _ = std::fs::remove_dir_all(path);
        }
    }
}

fn centre(points: &[[f64; 3]]) -> [f64; 3] {
    let n = points.len().max(1) as f64;
    [0, 1, 2].map(|a| points.iter().map(|p| p[a]).sum::<f64>() / n)
}

fn print_batch(b: &Batch) {
    println!("{}: {} specimens", b.names.join(" + "), b.specimens.len());
    for (i, (p, d, truth)) in b.specimens.iter().enumerate() {
        let holds = truth.is_some();
        match p {
            Ok(_) => println!(
                "  #{}: crown {:.2} voxels from the true crown, box holds a crown {holds}",
                i + 1,
                d.unwrap_or(f64::NAN)
            ),
            Err(e) => println!("  #{}: REFUSED {e}", i + 1),
        }
    }
    for w in &b.warnings {
        println!("  warning: {w}");
    }
}

/// Three real teeth in one stack, each in its own foam and tube: three
/// specimens, in order along x (the stack's longest axis), each box
/// holding its own tooth and each crown within two voxels of the truth.
#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn three_teeth_scanned_together_are_three_specimens_in_order() {
    let Some(dir) = data::teeth_dir() else {
        return;
    };
    let all = cps::tooth_names(&dir);
    let names: Vec<String> = [3, 40, 77].iter().map(|&k| all[k].clone()).collect();
    let tmp = tempfile::tempdir().unwrap();
    let b = batch(&dir, &names, 7, 90, 4, tmp.path());
    print_batch(&b);
    assert_eq!(b.specimens.len(), 3, "{:?}", b.warnings);
    let mut xs = Vec::new();
    for (p, d, truth) in &b.specimens {
        assert!(truth.is_some(), "a specimen's box holds no tooth");
        let p = p.as_ref().expect("each specimen is prepared");
        assert!(d.is_some_and(|d| d < 2.0), "crown {d:?} voxels off");
        xs.push(centre(&p.cleaned.vertices)[0]);
    }
    assert!(xs[0] < xs[1] && xs[1] < xs[2], "{xs:?}");
}

/// Two teeth whose mounts are pushed into each other (tubes and foam
/// merged): still two specimens, each on its own tooth.
#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn two_teeth_in_merged_mounts_are_two_specimens() {
    let Some(dir) = data::teeth_dir() else {
        return;
    };
    let all = cps::tooth_names(&dir);
    let names: Vec<String> = [12, 95].iter().map(|&k| all[k].clone()).collect();
    let tmp = tempfile::tempdir().unwrap();
    let b = batch(&dir, &names, 11, 80, -12, tmp.path());
    print_batch(&b);
    assert_eq!(b.specimens.len(), 2, "{:?}", b.warnings);
    assert!(b
        .specimens
        .iter()
        .all(|(p, _, truth)| p.is_ok() && truth.is_some()));
}

/// Three real teeth in one stack whose mounts stop short of its ends:
/// tubes cut to different lengths, foam blocks of different heights, so
/// that neither foam nor tube reaches both ends of the stack, and foam
/// fine-grained enough that the working grid's block averaging smooths
/// its texture away. Each tooth is still its own specimen: three, in order
/// along x, each box holding its own crown and no other and lying within
/// its tooth's box (no foam or tube kept with it). Segmentation only (no
/// cleaning): a few seconds.
#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn teeth_in_mounts_short_of_the_stack_ends_are_each_their_own_specimen() {
    let Some(dir) = data::teeth_dir() else {
        return;
    };
    let all = cps::tooth_names(&dir);
    let crowns: Vec<_> = [5, 44, 83]
        .iter()
        .map(|&k| cps::load_tooth(&dir, &all[k]))
        .collect();
    let mut mounts = batch_mounts(29, 80, crowns.len());
    for (m, (length, fill)) in mounts.iter_mut().zip([(0.6, 0.5), (0.8, 0.9), (0.7, 0.4)]) {
        if let Some(t) = &mut m.tube {
            t.length = length;
        }
        if let Some(f) = &mut m.foam {
            f.fill = fill;
            f.grain = 1.5;
        }
    }
    let teeth: Vec<(&morphoid_core::mesh::Mesh, Mount)> = crowns.iter().zip(mounts).collect();
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("short-mounts");
    let truth = write_batch(&teeth, 3, &path).unwrap();
    let loaded = load_scan(&path, &Settings::default()).expect("the batch stack is read");
    keep_or_remove(&path);
    let report = loaded.volume.as_ref().map(|v| &v.segmentation);
    assert_eq!(loaded.specimens.len(), 3, "{report:#?}");
    for (k, s) in loaded.specimens.iter().enumerate() {
        let [lo, hi] = s.position.bounds;
        let held: Vec<usize> = truth
            .iter()
            .enumerate()
            .filter(|(_, t)| {
                let c = centre(&t.crown.vertices);
                (0..3).all(|a| c[a] >= lo[a] && c[a] <= hi[a])
            })
            .map(|(j, _)| j)
            .collect();
        assert_eq!(
            held,
            [k],
            "specimen #{} holds crowns {held:?}: {report:#?}",
            k + 1
        );
        // A few voxels for the blur at the tooth's edge; foam or a tube
        // kept with it would reach tens of voxels further.
        let [t_lo, t_hi] = truth[k].tooth_box;
        assert!(
            (0..3).all(|a| lo[a] >= t_lo[a] - 5.0 && hi[a] <= t_hi[a] + 5.0),
            "specimen #{} spans {:?}, the tooth {:?}: {report:#?}",
            k + 1,
            [lo, hi],
            [t_lo, t_hi]
        );
    }
}

/// All 116 teeth, three per stack (38 batches and one of two), each
/// specimen identified against the other 115 original crowns: run by
/// name, figures printed. `MORPHOID_BATCH_STEP=k` takes every k-th batch,
/// `MORPHOID_BATCH_ONLY=i,j` the batches numbered i and j.
#[test]
#[ignore = "real data, tens of minutes: run by name"]
fn all_teeth_in_batches_of_three_are_identified() {
    let Some(dir) = data::teeth_dir() else {
        return;
    };
    let all = cps::tooth_names(&dir);
    let step = std::env::var("MORPHOID_BATCH_STEP")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1);
    // Neighbours in the list share a genus: batches mix the list's thirds.
    let third = all.len().div_ceil(3);
    let groups: Vec<Vec<String>> = (0..third)
        .step_by(step)
        .map(|i| {
            [i, i + third, i + 2 * third]
                .iter()
                .filter_map(|&k| all.get(k).cloned())
                .collect()
        })
        .collect();
    // MORPHOID_BATCH_ONLY=3,9 takes those batches only (numbered from 0).
    let only: Option<Vec<usize>> = std::env::var("MORPHOID_BATCH_ONLY")
        .ok()
        .map(|v| v.split(',').filter_map(|k| k.trim().parse().ok()).collect());
    let tmp = tempfile::tempdir().unwrap();
    let batches: Vec<Batch> = groups
        .par_iter()
        .enumerate()
        .filter(|(i, _)| only.as_ref().is_none_or(|o| o.contains(i)))
        .map(|(i, names)| {
            let across = 100 + (i * 23) % 60;
            batch(&dir, names, 500 + i as u64, across, 3, tmp.path())
        })
        .collect();
    batches.iter().for_each(print_batch);
    let teeth: usize = batches.iter().map(|b| b.names.len()).sum();
    let found: usize = batches
        .iter()
        .filter(|b| b.specimens.len() == b.names.len())
        .map(|b| b.names.len())
        .sum();
    let on_target = batches
        .iter()
        .flat_map(|b| &b.specimens)
        .filter(|(_, d, _)| d.is_some_and(|d| d < 2.0))
        .count();
    // Each specimen named after the tooth its box holds, in x order: the
    // batch's teeth stand in the order they were given.
    let mut prepared: Vec<morphoid_data::pipeline::PreparedSurface> = Vec::new();
    let mut truths: Vec<Option<Mesh>> = Vec::new();
    for b in batches
        .iter()
        .filter(|b| b.specimens.len() == b.names.len())
    {
        for (name, (p, _, truth)) in b.names.iter().zip(&b.specimens) {
            if let Ok(p) = p {
                let mut q = p.clone();
                q.prepared.set_name(name);
                prepared.push(q);
                truths.push(truth.clone());
            }
        }
    }
    let params = morphoid_core::cp::CpParams::default();
    let originals = cps::prepare_teeth(&dir, &all, &params);
    let s = cps::heldout_scores_classified(&dir, &mut prepared, &originals);
    let fits: Vec<(String, CropFit)> = prepared
        .iter()
        .zip(&truths)
        .filter_map(|(p, t)| {
            Some((
                p.prepared.name().to_string(),
                crop_fit(&p.cleaned, t.as_ref()?),
            ))
        })
        .collect();
    print_identified_fits(&fits, teeth);
    let genus = s
        .iter()
        .find(|r| r.rank == "genus")
        .map(|r| (r.correct, r.total))
        .unwrap_or_default();
    println!(
        "teeth {teeth}; in batches split right {found}; crowns within 2 voxels {on_target}; \
         prepared {}; genus right {}/{}",
        prepared.len(),
        genus.0,
        genus.1
    );
    assert!(found * 10 >= teeth * 9, "split right {found}/{teeth}");
}
