//! The cWn distance on the real teeth: the matrix and its leave-one-out
//! nearest-neighbour accuracy per rank.
//!
//! The whole 116-tooth matrix takes a few minutes on two cores, so it is
//! ignored by default: `cargo test --release --test it cwn_teeth --
//! --ignored --nocapture`. The suite runs the same on every third tooth.
//! `CWN_PARAMS` (CwnParams JSON) overrides the parameters;
//! `CWN_MATRIX_OUT` writes the matrix CSV.

use morphoid_core::cp::CpParams;
use morphoid_core::cwn::{self, CwnParams};
use rayon::prelude::*;

/// Every third tooth (39): the matrix is well defined and nearest
/// neighbours are far better than chance.
#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn leave_one_out_on_a_third_of_the_real_teeth() {
    leave_one_out_on_teeth(3, |order, genus, total| {
        assert!(order >= 30, "order {order}/39");
        assert!(genus * 100 >= 40 * total, "genus {genus}/{total}");
    });
}

/// All 116 teeth (README figures).
#[test]
#[ignore]
fn leave_one_out_on_real_teeth() {
    // The paper found cWn below cP; a sane floor well above chance.
    leave_one_out_on_teeth(1, |order, genus, total| {
        assert!(order >= 90, "order {order}");
        assert!(genus * 100 >= 50 * total, "genus {genus}/{total}");
    });
}

/// The cWn matrix of every `step`-th tooth and its leave-one-out scores,
/// checked by `floors(order correct, genus correct, genus total)`.
fn leave_one_out_on_teeth(step: usize, floors: impl Fn(usize, usize, usize)) {
    let Some(dir) = crate::support::cp::data_dir() else {
        return;
    };
    let params: CwnParams = crate::support::cp::params_from_env("CWN_PARAMS");
    let names: Vec<String> = crate::support::cp::tooth_names(&dir)
        .into_iter()
        .step_by(step)
        .collect();
    let t0 = std::time::Instant::now();
    let landscapes: Vec<cwn::Landscape> =
        crate::support::cp::prepare_teeth(&dir, &names, &CpParams::default())
            .par_iter()
            .map(|p| cwn::prepare(p, &params).expect("landscape"))
            .collect();
    println!("prepared {} in {:.1?}", landscapes.len(), t0.elapsed());
    let t0 = std::time::Instant::now();
    let m = morphoid_research::surfaces::cwn_matrix(&landscapes, &params, |_| {}).expect("matrix");
    let n = landscapes.len();
    let pairs = n * (n - 1) / 2;
    let elapsed = t0.elapsed();
    println!(
        "matrix of {pairs} pairs in {elapsed:.1?} ({:.1} ms per pair on {} threads)",
        elapsed.as_secs_f64() * 1e3 / pairs as f64,
        rayon::current_num_threads()
    );
    if let Ok(out) = std::env::var("CWN_MATRIX_OUT") {
        m.write_csv(std::path::Path::new(&out))
            .expect("write matrix");
    }
    for i in 0..n {
        assert_eq!(m.values()[i][i], 0.0);
        for j in 0..n {
            assert!(m.values()[i][j].is_finite() && m.values()[i][j] >= 0.0);
        }
    }
    let scores = crate::support::cp::leave_one_out_scores(&dir, &m);
    floors(scores[0].correct, scores[2].correct, scores[2].total);
}
