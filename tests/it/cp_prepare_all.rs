//! Every real tooth can be prepared (skipped when the data is absent).

use morphoid::cp::{self, CpParams};

#[test]
fn every_real_tooth_is_prepared() {
    let Some(dir) = crate::support::cp::data_dir() else {
        return;
    };
    let params = CpParams::default();
    let mut failures = Vec::new();
    for name in crate::support::cp::tooth_names(&dir) {
        match cp::prepare(&crate::support::cp::load_tooth(&dir, &name), &params) {
            Ok(p) => {
                p.validate().expect("consistent");
                assert!(!p.features.is_empty() && p.samples.len() == params.samples);
                let total: f64 = p.sample_weights.iter().sum();
                assert!((total - 1.0).abs() < 1e-9, "{name}: weights sum to {total}");
                assert!(p.uv.iter().all(|z| z[0].hypot(z[1]) <= 1.0 + 1e-12));
            }
            Err(e) => failures.push(format!("{name}: {e}")),
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
