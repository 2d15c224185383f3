//! Leave-one-out accuracy of the cP distance on the 116 PNAS teeth.
//!
//! Slow (all 6,670 pairs): run with
//! `cargo test --release --test cp_accuracy -- --ignored --nocapture`.
//! Writes the matrix to `$CP_MATRIX_OUT` when set.

mod cp_support;

use morphoid::cp::{self, CpParams};
use morphoid::eval::{distance_matrix, leave_one_out, DistanceMatrix, Labels};
use rayon::prelude::*;

#[test]
#[ignore]
fn leave_one_out_on_real_teeth() {
    let Some(dir) = cp_support::data_dir() else {
        return;
    };
    let params: CpParams = cp_support::params_from_env("CP_PARAMS");
    let names = cp_support::tooth_names(&dir);
    let t0 = std::time::Instant::now();
    let prepared = cp_support::prepare_teeth(&dir, &names, &params.prepare);
    println!("prepared {} in {:.1?}", prepared.len(), t0.elapsed());
    let t0 = std::time::Instant::now();
    let n = prepared.len();
    let pairs: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .collect();
    let directed: Vec<(f64, f64, f64, f64)> = pairs
        .par_iter()
        .map(|&(i, j)| {
            let c = cp::compare(&prepared[i], &prepared[j], &params.compare);
            (
                c.forward.distance,
                c.backward.distance,
                c.forward.search_distance,
                c.backward.search_distance,
            )
        })
        .collect();
    println!("matrix in {:.1?}", t0.elapsed());
    let mut fwd = DistanceMatrix {
        names: prepared.iter().map(|p| p.name().to_string()).collect(),
        values: vec![vec![0.0; n]; n],
    };
    let mut searched = fwd.clone();
    for (&(i, j), &(f, b, fm, bm)) in pairs.iter().zip(&directed) {
        fwd.values[i][j] = f;
        fwd.values[j][i] = b;
        searched.values[i][j] = fm;
        searched.values[j][i] = bm;
    }
    if let Ok(out) = std::env::var("CP_DIRECTED_OUT") {
        fwd.write_csv(std::path::Path::new(&out))
            .expect("write matrix");
        let out = format!("{out}.search.csv");
        searched
            .write_csv(std::path::Path::new(&out))
            .expect("write matrix");
    }
    let mut m = fwd.clone();
    for i in 0..n {
        for j in 0..n {
            m.values[i][j] = fwd.values[i][j].min(fwd.values[j][i]);
        }
    }
    // The library's matrix function gives the same values.
    let few = &prepared[..4];
    let lib = distance_matrix(few, &params.compare, |_| {});
    for i in 0..4 {
        for j in 0..4 {
            assert_eq!(lib.values[i][j], m.values[i][j]);
        }
    }
    if let Ok(out) = std::env::var("CP_MATRIX_OUT") {
        m.write_csv(std::path::Path::new(&out))
            .expect("write matrix");
    }
    let ranks: Vec<String> = ["order", "family", "genus"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let labels = Labels::read(&dir.join("labels.csv"), Some(&ranks)).expect("labels");
    let scores = leave_one_out(&m, &labels, &ranks);
    for s in &scores {
        println!("LOO {}: {}/{}", s.rank, s.correct, s.total);
    }
    // The authors' implementation reaches 114/116, 99/106, 89/101; with
    // the final descent we measured 114/116, 101/106, 96/101. Guard the
    // targets: the authors' order and family, genus 93 or better.
    let need = [114, 99, 93];
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
