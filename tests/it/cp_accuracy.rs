//! Leave-one-out accuracy of the cP distance on the 116 real teeth, through
//! the path `morphoid matrix` takes: each file loaded, cleaned and prepared
//! by `pipeline::prepare_file`, all pairs by `eval::distance_matrix`.
//!
//! Slow (all 6,670 pairs, a few minutes on two cores): run with
//! `cargo test --release --test it cp_accuracy -- --ignored --nocapture`.
//! Writes the matrix to `$CP_MATRIX_OUT` when set; `$CP_PARAMS` (JSON)
//! overrides the `[cp]` settings.

use crate::support::cp::{data_dir, params_from_env, prepare_teeth, tooth_names};
use morphoid_core::cp::CpParams;
use morphoid_data::table::distance_matrix;

#[test]
#[ignore]
fn leave_one_out_on_real_teeth() {
    let Some(dir) = data_dir() else {
        return;
    };
    let params: CpParams = params_from_env("CP_PARAMS");
    let names = tooth_names(&dir);
    let t0 = std::time::Instant::now();
    let prepared = prepare_teeth(&dir, &names, &params);
    println!("prepared {} in {:.1?}", prepared.len(), t0.elapsed());
    let t0 = std::time::Instant::now();
    let m = distance_matrix(&prepared, &params.compare, |_| {});
    println!("matrix in {:.1?}", t0.elapsed());
    if let Ok(out) = std::env::var("CP_MATRIX_OUT") {
        m.write_csv(std::path::Path::new(&out))
            .expect("write matrix");
    }
    let scores = crate::support::cp::leave_one_out_scores(&dir, &m);
    // The authors' implementation reaches 114/116, 99/106, 89/101; ours is
    // 114/116, 101/106, 96/101 (README). Any loss fails.
    let need = [114, 101, 96];
    for (s, n) in scores.iter().zip(need) {
        assert!(
            s.correct >= n,
            "LOO {}: {}/{} < {n}",
            s.rank,
            s.correct,
            s.total
        );
    }
}
