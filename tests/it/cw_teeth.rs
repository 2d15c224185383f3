//! The cW distance on the real teeth: metric properties on a few teeth
//! (symmetry, the triangle inequality, a mirror image), the agreement of
//! cW's maps with cP's, and (ignored, long) the 116-tooth matrix.
//!
//! `cargo test --release --test it cw_teeth -- --nocapture`; the whole
//! matrix: `cargo test --release --test it cw_teeth -- --ignored --nocapture`.

use morphoid_core::cp::{self, CpParams, Prepared};
use morphoid_core::cw::{self, CwParams};
use morphoid_synth::mesh as synth;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rayon::prelude::*;

/// Five teeth drawn at random (seeded) from the 116, prepared as
/// `morphoid matrix` prepares them.
fn random_teeth(seed: u64) -> Option<(std::path::PathBuf, Vec<Prepared>)> {
    let dir = crate::support::cp::data_dir()?;
    let mut names = crate::support::cp::tooth_names(&dir);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    names.shuffle(&mut rng);
    names.truncate(5);
    let teeth = crate::support::cp::prepare_teeth(&dir, &names, &CpParams::default());
    Some((dir, teeth))
}

/// Both directions of every pair: they agree, and every triple satisfies
/// the triangle inequality, within the tolerance of the search (which
/// returns an upper bound of the minimum over maps).
#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn cw_is_symmetric_and_satisfies_the_triangle_inequality_on_real_teeth() {
    let Some((_, teeth)) = random_teeth(17) else {
        return;
    };
    let params = CwParams::default();
    let n = teeth.len();
    let pairs: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .filter(|(i, j)| i != j)
        .collect();
    let values: Vec<f64> = pairs
        .par_iter()
        .map(|&(i, j)| {
            cw::distance(&teeth[i], &teeth[j], &params)
                .unwrap()
                .distance
        })
        .collect();
    let mut d = vec![vec![0.0; n]; n];
    for (&(i, j), &v) in pairs.iter().zip(&values) {
        d[i][j] = v;
    }
    let mut worst_asymmetry: f64 = 0.0;
    let mut worst_triangle: f64 = 0.0;
    for i in 0..n {
        for j in 0..n {
            if i == j {
                continue;
            }
            assert!(d[i][j] > 0.0, "{} {}", teeth[i].name(), teeth[j].name());
            worst_asymmetry = worst_asymmetry.max((d[i][j] - d[j][i]).abs() / d[i][j].min(d[j][i]));
            for k in 0..n {
                if k != i && k != j {
                    worst_triangle = worst_triangle.max(d[i][k] / (d[i][j] + d[j][k]));
                }
            }
        }
    }
    println!(
        "cW on 5 teeth: largest relative asymmetry {worst_asymmetry:.4}, largest d(a,c)/(d(a,b)+d(b,c)) {worst_triangle:.4}"
    );
    assert!(worst_asymmetry < 0.05, "{worst_asymmetry}");
    assert!(worst_triangle <= 1.02, "{worst_triangle}");
}

/// A real tooth and its mirror image: near zero through a reflection,
/// far without reflections.
#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn a_real_mirror_image_is_at_cw_zero_only_with_reflections() {
    let Some(dir) = crate::support::cp::data_dir() else {
        return;
    };
    let prepare =
        |m: &morphoid_core::mesh::Mesh| cp::prepare(m, &CpParams::default().prepare).unwrap();
    let tooth = crate::support::cp::load_tooth(&dir, "H10");
    let (a, mirrored) = (prepare(&tooth), prepare(&synth::mirror(&tooth)));
    let other = prepare(&crate::support::cp::load_tooth(&dir, "H16"));
    let params = CwParams::default();
    let apart = cw::distance(&a, &other, &params).unwrap().distance;
    let with = cw::distance(&a, &mirrored, &params).unwrap();
    let without = cw::distance(
        &a,
        &mirrored,
        &CwParams {
            reflections: false,
            ..params
        },
    )
    .unwrap();
    println!(
        "H10 vs its mirror image: {:.5} with reflections, {:.5} without; H10 vs H16 {apart:.5}",
        with.distance, without.distance
    );
    assert!(with.reflected);
    assert!(with.distance < 0.05 * apart, "{} vs {apart}", with.distance);
    assert!(
        without.distance > 5.0 * with.distance,
        "{}",
        without.distance
    );
}

/// The image of a vertex of `s` under a correspondence, in `t`'s
/// normalized coordinates.
fn image(t: &Prepared, corr: &cp::Correspondence, v: usize) -> [f64; 3] {
    let (f, b) = corr[v];
    let face = t.faces()[f as usize];
    let mut y = [0.0; 3];
    for k in 0..3 {
        for (d, yd) in y.iter_mut().enumerate() {
            *yd += b[k] * t.vertices()[face[k] as usize][d];
        }
    }
    y
}

/// Landmarks (here the first 20 samples of each source tooth, spread by
/// farthest-point sampling) carried by cW's map and by cP's map: their
/// mean distance as a share of the target's bounding-box diagonal.
#[test]
#[ignore]
fn cw_maps_carry_landmarks_near_where_cp_maps_do() {
    let Some((_, teeth)) = random_teeth(5) else {
        return;
    };
    let pairs = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 0)];
    let shares: Vec<f64> = pairs
        .par_iter()
        .map(|&(i, j)| {
            let (s, t) = (&teeth[i], &teeth[j]);
            let by_cw = cw::distance(s, t, &CwParams::default()).unwrap();
            let cw_map = cw::correspondence(s, t, &by_cw).unwrap();
            let cp_map = cp::compare_directed(s, t, &CpParams::default().compare);
            let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
            for x in t.vertices() {
                for d in 0..3 {
                    lo[d] = lo[d].min(x[d]);
                    hi[d] = hi[d].max(x[d]);
                }
            }
            let diagonal = (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt();
            let marks: Vec<usize> = s.samples().iter().take(20).map(|&v| v as usize).collect();
            let mean = marks
                .iter()
                .map(|&v| {
                    let (a, b) = (
                        image(t, &cw_map.correspondence, v),
                        image(t, &cp_map.correspondence, v),
                    );
                    (0..3).map(|d| (a[d] - b[d]).powi(2)).sum::<f64>().sqrt()
                })
                .sum::<f64>()
                / marks.len() as f64;
            let share = mean / diagonal;
            println!(
                "{} → {}: {:.1} % of the diagonal",
                s.name(),
                t.name(),
                100.0 * share
            );
            share
        })
        .collect();
    let mean = shares.iter().sum::<f64>() / shares.len() as f64;
    println!(
        "cW vs cP maps: landmarks {:.1} % of the diagonal apart on average",
        100.0 * mean
    );
    assert!(mean < 0.15, "{mean}");
}

/// The whole 116-tooth cW matrix: leave-one-out accuracy (README) and the
/// Mantel correlation with cP (`CP_MATRIX` names a cP matrix CSV of the
/// same teeth, e.g. from `morphoid matrix`; without it only the accuracy).
#[test]
#[ignore]
fn cw_leave_one_out_on_real_teeth() {
    let Some(dir) = crate::support::cp::data_dir() else {
        return;
    };
    let names = crate::support::cp::tooth_names(&dir);
    let teeth = crate::support::cp::prepare_teeth(&dir, &names, &CpParams::default());
    let matrix =
        morphoid_research::surfaces::cw_matrix(&teeth, &CwParams::default(), |_| {}).unwrap();
    let scores = crate::support::cp::leave_one_out_scores(&dir, &matrix);
    if let Ok(path) = std::env::var("CP_MATRIX") {
        let cp_matrix =
            morphoid_data::table::DistanceMatrix::read_csv(std::path::Path::new(&path)).unwrap();
        let m = morphoid_research::eval::mantel_test(&matrix, &cp_matrix, 999, 1).unwrap();
        println!("Mantel cW vs cP: {m:?}");
    }
    // cWn reaches 107/116 at order; cW should be in that range.
    assert!(scores[0].correct >= 95, "order {}", scores[0].correct);
}
