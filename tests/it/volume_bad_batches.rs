//! What a batch scan can hold besides teeth, each a clear answer and never
//! a lost scan: two teeth touching at a contact (cut apart), two fused
//! over a wide junction (one result, with a warning), thirty crumbs of debris around a tooth (one specimen, the
//! crumbs reported), a closed surface that is a sphere (a clear error).

use morphoid_core::mesh::Grid;
use morphoid_core::volume::DropReason;
use morphoid_data::mesh_io;
use morphoid_data::pipeline::{load_scan, prepare_file, Settings};
use morphoid_synth::mesh::{self as synth, whole_tooth, WholeToothParams, CROWN_GENERA};
use morphoid_synth::volume::{phantom, write_volume, PhantomParams, StackSpec, SynthFormat};

/// The phantom of a whole synthetic tooth of genus `g`, crown up.
fn tooth_grid(g: usize, seed: u64, across: usize) -> Grid {
    let crown = synth::crown(&CROWN_GENERA[g], seed, 3000);
    let tooth = whole_tooth(&crown, &WholeToothParams::default(), seed)
        .unwrap()
        .upright();
    phantom(
        &tooth,
        &PhantomParams {
            voxels_across: across,
            ..PhantomParams::default()
        },
    )
}

/// `b` laid into `a` at x offset `dx` (the brighter value wins), on a grid
/// wide enough for both.
fn overlay(a: &Grid, b: &Grid, dx: usize) -> Grid {
    let dims = [
        a.dims[0].max(dx + b.dims[0]),
        a.dims[1].max(b.dims[1]),
        a.dims[2].max(b.dims[2]),
    ];
    let mut out = Grid::filled(dims, [0.0; 3], a.spacing, a.values[0]);
    for (g, x0) in [(a, 0), (b, dx)] {
        for z in 0..g.dims[2] {
            for y in 0..g.dims[1] {
                for x in 0..g.dims[0] {
                    let i = out.index(x0 + x, y, z);
                    out.values[i] = out.values[i].max(g.values[g.index(x, y, z)]);
                }
            }
        }
    }
    out
}

/// Two synthetic teeth pushed `overlap` of a tooth's width into each
/// other, read back: the specimens and the segmentation's warnings.
fn pushed_together(overlap: f64) -> (usize, Vec<String>) {
    let a = tooth_grid(1, 71, 90);
    let b = tooth_grid(3, 72, 90);
    let dx = (a.dims[0] as f64 * (1.0 - overlap)) as usize;
    let both = overlay(&a, &b, dx);
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("pair");
    write_volume(&both, &path, SynthFormat::Tiff16, &StackSpec::default()).unwrap();
    let loaded = load_scan(&path, &Settings::default()).unwrap();
    let warnings = loaded
        .volume
        .as_ref()
        .unwrap()
        .segmentation
        .warnings
        .clone();
    (loaded.specimens.len(), warnings)
}

#[test]
fn two_teeth_touching_at_a_contact_are_cut_apart() {
    let (n, warnings) = pushed_together(0.25);
    assert_eq!(n, 2, "{warnings:?}");
    assert!(
        warnings.iter().any(|w| w.contains("cut at a neck")),
        "{warnings:?}"
    );
}

#[test]
fn two_teeth_fused_over_a_wide_junction_give_one_result_and_a_warning() {
    // Pushed deeper still (0.35 and more of a tooth) the pair erodes as one
    // object at every radius up to the fused radius: one result, and no
    // warning (a documented limit).
    let (n, warnings) = pushed_together(0.3);
    assert_eq!(n, 1, "{warnings:?}");
    assert!(
        warnings.iter().any(|w| w.contains("fused")),
        "no warning: {warnings:?}"
    );
}

#[test]
fn thirty_crumbs_of_debris_around_a_tooth_are_reported_not_identified() {
    let mut g = tooth_grid(2, 73, 100);
    let n = g.dims;
    // Thirty small bright crumbs, 3 to 6 samples across, in the air.
    let mut placed = 0;
    let mut k = 0u64;
    while placed < 30 && k < 10_000 {
        k += 1;
        let r = 1 + (k % 3) as usize;
        let c = [
            (k * 7919 % (n[0] as u64 - 8)) as usize + 4,
            (k * 104_729 % (n[1] as u64 - 8)) as usize + 4,
            (k * 1_299_709 % (n[2] as u64 - 8)) as usize + 4,
        ];
        let clear = (0..=2 * (r + 2)).all(|d| {
            let p = [0, 1, 2].map(|a| (c[a] + d).saturating_sub(r + 2).min(n[a] - 1));
            g.values[g.index(p[0], p[1], p[2])] < 0.2
        });
        if !clear {
            continue;
        }
        for z in c[2] - r..=c[2] + r {
            for y in c[1] - r..=c[1] + r {
                for x in c[0] - r..=c[0] + r {
                    let i = g.index(x, y, z);
                    g.values[i] = 0.6;
                }
            }
        }
        placed += 1;
    }
    assert_eq!(placed, 30);
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("crumbs");
    write_volume(&g, &path, SynthFormat::Tiff16, &StackSpec::default()).unwrap();
    let loaded = load_scan(&path, &Settings::default()).unwrap();
    assert_eq!(loaded.specimens.len(), 1, "crumbs taken for specimens");
    let seg = &loaded.volume.as_ref().unwrap().segmentation;
    let reported = seg
        .objects
        .iter()
        .filter(|o| matches!(o.reason, Some(DropReason::TooSmall | DropReason::Fragment)))
        .count()
        + seg.small_objects;
    // Crumbs that happen to touch count as one.
    assert!(reported >= 25, "{reported} crumbs reported: {seg:?}");
    let p = prepare_file(&path, &Settings::default()).expect("the tooth is prepared");
    assert!(p.cleaning.crown.is_some());
}

#[test]
fn a_closed_sphere_is_refused_with_a_clear_message() {
    // An icosphere (2,562 vertices, radius 5): closed, smooth, no tooth.
    let m = synth::scale(&synth::closed_sphere(2562), 5.0);
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("ball.ply");
    mesh_io::save(&path, &m).unwrap();
    let e = prepare_file(&path, &Settings::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("ball.ply") && e.contains("no recognisable tooth crown"),
        "{e}"
    );
}
