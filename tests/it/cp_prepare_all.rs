//! Every real tooth can be prepared (needs the data set, see
//! `support::data`).

use morphoid_core::cp::CpParams;

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn every_real_tooth_is_prepared() {
    let Some(dir) = crate::support::cp::data_dir() else {
        return;
    };
    let params = CpParams::default();
    let names = crate::support::cp::tooth_names(&dir);
    // Panics naming the file of a tooth that cannot be prepared.
    let prepared = crate::support::cp::prepare_teeth(&dir, &names, &params);
    assert_eq!(prepared.len(), 116);
    for (name, p) in names.iter().zip(&prepared) {
        assert_eq!(p.name(), name);
        p.validate()
            .unwrap_or_else(|e| panic!("{name}: inconsistent: {e}"));
        assert!(!p.features().is_empty() && p.samples().len() == params.prepare.samples);
        let total: f64 = p.sample_weights().iter().sum();
        assert!((total - 1.0).abs() < 1e-9, "{name}: weights sum to {total}");
        assert!(
            p.uv().iter().all(|z| z[0].hypot(z[1]) <= 1.0 + 1e-12),
            "{name}"
        );
    }
}
