//! Point clouds reconstructed into surfaces: a synthetic crown with
//! overhanging walls, and clouds of the real teeth identified against the
//! original crowns (held out: each cloud against the other 115 teeth).

use morphoid_core::clean::point_to_surface_distances;
use morphoid_core::clean::{clean, CleanError, CleanOptions};
use morphoid_core::mesh::{bbox_diagonal, surface_area, Mesh};
use morphoid_data::mesh_io;
use morphoid_synth::mesh::{self as synth, ScannerCloud, CROWN_GENERA};
use std::path::Path;

/// Mean distance between two surfaces, both ways, over their vertices.
fn mean_distance_both_ways(a: &Mesh, b: &Mesh) -> f64 {
    let ab = point_to_surface_distances(&a.vertices, b);
    let ba = point_to_surface_distances(&b.vertices, a);
    0.5 * (ab.iter().sum::<f64>() / ab.len() as f64 + ba.iter().sum::<f64>() / ba.len() as f64)
}

#[test]
fn overhanging_crown_cloud_is_reconstructed_on_its_surface() {
    let opts = CleanOptions::default();
    for (g, genus) in CROWN_GENERA.iter().enumerate().take(3) {
        let truth = synth::overhanging_crown(genus, 7 + g as u64, 20_000);
        let diag = bbox_diagonal(&truth);
        for (kind, spec) in [
            (
                "clean",
                ScannerCloud {
                    noise: 0.0,
                    outliers: 0.0,
                    ..ScannerCloud::default()
                },
            ),
            ("noisy", ScannerCloud::default()),
        ] {
            let cloud = synth::scanner_cloud(
                &truth,
                &ScannerCloud {
                    seed: g as u64,
                    ..spec
                },
            );
            let c = clean(&cloud, &opts).unwrap_or_else(|e| panic!("{}: {e}", genus.name));
            let report = c.report.cloud.as_ref().expect("cloud report");
            assert_eq!(report.points_in, cloud.vertices.len());
            if kind == "noisy" {
                // 200 outliers; the ones in the box far from the surface
                // must go, a few near it may stay.
                assert!(report.outliers_removed >= 150, "{report:?}");
            }
            let mean = mean_distance_both_ways(&c.mesh, &truth) / diag;
            let area = c.report.area / surface_area(&truth);
            println!(
                "{} {kind}: mean distance {:.4} % of the diagonal, area ratio {area:.3}, {report:?}",
                genus.name,
                100.0 * mean
            );
            assert!(mean < 0.004, "{} {kind}: mean distance {mean}", genus.name);
            assert!(
                (area - 1.0).abs() < 0.05,
                "{} {kind}: area ratio {area}",
                genus.name
            );
        }
    }
}

#[test]
fn degenerate_clouds_give_clear_errors() {
    let opts = CleanOptions::default();
    let line = Mesh::new(
        (0..100).map(|i| [i as f64, 1.0, 2.0 * i as f64]).collect(),
        vec![],
    );
    let e = clean(&line, &opts).unwrap_err();
    assert!(matches!(e, CleanError::Cloud(_)));
    assert!(e.to_string().contains("line"), "{e}");
    let flat = synth::scanner_cloud(
        &synth::unit_disk(500),
        &ScannerCloud {
            points: 2000,
            noise: 0.0,
            outliers: 0.0,
            seed: 1,
        },
    );
    let e = clean(&flat, &opts).unwrap_err();
    assert!(e.to_string().contains("plane"), "{e}");
    // Uniform noise in a box samples no surface.
    let dust = synth::scanner_cloud(
        &synth::crown(&CROWN_GENERA[0], 1, 2000),
        &ScannerCloud {
            points: 0,
            noise: 0.0,
            outliers: 1.0,
            seed: 1,
        },
    );
    assert!(clean(&dust, &opts).is_err() || dust.vertices.is_empty());
}

/// The two kinds of cloud the targets name, made from one tooth: the
/// vertices of a remeshed copy (subdivided once, cleaned to about 4,500
/// vertices), and a scanner cloud (10,000 points, noise 0.2 % of the
/// diagonal, 2 % outliers).
fn tooth_clouds(tooth: &Mesh, seed: u64) -> [Mesh; 2] {
    let opts = CleanOptions {
        target_vertices: 4500,
        ..CleanOptions::default()
    };
    let remeshed = clean(&synth::subdivide_midpoint(tooth, 1), &opts)
        .expect("remesh")
        .mesh;
    [
        synth::to_point_cloud(&remeshed),
        synth::scanner_cloud(
            tooth,
            &ScannerCloud {
                seed,
                ..ScannerCloud::default()
            },
        ),
    ]
}

/// Held-out identification of the clouds of the teeth `chosen` (indices
/// into the labels' order) against all 116 original crowns; the scores of
/// both kinds of cloud, each `[order, family, genus]`.
fn heldout_cloud_scores(dir: &Path, every: usize) -> [Vec<morphoid_research::eval::RankScore>; 2] {
    use crate::support::cp::{heldout_scores, prepare_teeth, tooth_names};
    use rayon::prelude::*;
    let names = tooth_names(dir);
    let params = morphoid_core::cp::CpParams::default();
    let originals = prepare_teeth(dir, &names, &params);
    let chosen: Vec<&String> = names.iter().step_by(every).collect();
    let tmp = tempfile::tempdir().expect("tmp");
    let settings = morphoid_data::pipeline::Settings::default();
    let kinds = ["remeshed-vertices", "scanner"];
    for kind in kinds {
        std::fs::create_dir(tmp.path().join(kind)).expect("dir");
    }
    let prepared: Vec<[morphoid_core::cp::Prepared; 2]> = chosen
        .par_iter()
        .enumerate()
        .map(|(i, name)| {
            let path = dir.join("meshes").join(format!("{name}.ply"));
            let tooth = mesh_io::load(&path).expect("tooth").mesh;
            let clouds = tooth_clouds(&tooth, 1000 + i as u64);
            let mut out = Vec::new();
            for (kind, cloud) in kinds.iter().zip(&clouds) {
                let file = tmp.path().join(kind).join(format!("{name}.ply"));
                mesh_io::save(&file, cloud).expect("save");
                let p = morphoid_data::pipeline::prepare_file(&file, &settings)
                    .unwrap_or_else(|e| panic!("{kind} {name}: {e}"));
                let r = p.cleaning.cloud.clone().expect("cloud report");
                println!("{kind} {name}: {r:?}");
                out.push(p.prepared);
            }
            let second = out.pop().expect("two");
            let first = out.pop().expect("two");
            [first, second]
        })
        .collect();
    let compare = params.compare.clone();
    kinds.map(|kind| {
        let k = kinds.iter().position(|&x| x == kind).unwrap_or(0);
        println!("{kind} clouds of {} teeth:", prepared.len());
        let variants: Vec<morphoid_core::cp::Prepared> =
            prepared.iter().map(|p| p[k].clone()).collect();
        heldout_scores(dir, &variants, &originals, &compare)
    })
}

fn genus(scores: &[morphoid_research::eval::RankScore]) -> (usize, usize) {
    let g = scores.iter().find(|s| s.rank == "genus").expect("genus");
    (g.correct, g.total)
}

/// Every tenth tooth (12 teeth): the same path as the full measurement
/// below in about a tenth of its time. Run with `cargo test --release
/// --test it clouds_of_every_tenth -- --ignored --nocapture`.
#[test]
#[ignore]
fn clouds_of_every_tenth_tooth_are_identified() {
    let Some(dir) = crate::support::data::teeth_dir() else {
        return;
    };
    for scores in heldout_cloud_scores(&dir, 10) {
        let (correct, total) = genus(&scores);
        // The crowns themselves: 96 of 101 (95 %); allow one more miss.
        assert!(correct + 2 >= total, "genus {correct}/{total}");
    }
}

/// All 116 teeth as clouds of both kinds: genus within 3 of the crowns'
/// 96/101. Run with `cargo test --release --test it
/// clouds_of_all_teeth -- --ignored --nocapture`.
#[test]
#[ignore]
fn clouds_of_all_teeth_are_identified_to_genus_as_the_crowns_are() {
    let Some(dir) = crate::support::data::teeth_dir() else {
        return;
    };
    for scores in heldout_cloud_scores(&dir, 1) {
        let (correct, total) = genus(&scores);
        assert!(correct >= 93, "genus {correct}/{total}");
    }
}

/// Clouds of every 29th tooth (4 teeth) cleaned through the users' path
/// lie on the tooth and cover it: a cheap check for CI.
#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn real_tooth_clouds_become_the_tooth_surface() {
    let Some(dir) = crate::support::data::teeth_dir() else {
        return;
    };
    let names = crate::support::cp::tooth_names(&dir);
    let tmp = tempfile::tempdir().expect("tmp");
    let settings = morphoid_data::pipeline::Settings::default();
    for (i, name) in names.iter().enumerate().step_by(29) {
        let tooth = mesh_io::load(&dir.join("meshes").join(format!("{name}.ply")))
            .expect("tooth")
            .mesh;
        let diag = bbox_diagonal(&tooth);
        for (k, cloud) in tooth_clouds(&tooth, 1000 + i as u64).iter().enumerate() {
            let file = tmp.path().join(format!("{k}_{name}.ply"));
            mesh_io::save(&file, cloud).expect("save");
            let p = morphoid_data::pipeline::prepare_file(&file, &settings)
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            let mean = mean_distance_both_ways(&p.cleaned, &tooth) / diag;
            let area = p.cleaning.area / surface_area(&tooth);
            println!(
                "{name} cloud {k}: mean distance {:.3} % of the diagonal, area ratio {area:.3}",
                100.0 * mean
            );
            assert!(mean < 0.005, "{name} cloud {k}: mean distance {mean}");
            assert!(
                (area - 1.0).abs() < 0.1,
                "{name} cloud {k}: area ratio {area}"
            );
        }
    }
}
