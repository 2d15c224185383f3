//! Flattening of all 116 teeth after the cleaning pipeline (which also
//! repairs J12 and S09); needs the data set, see `support::data`.

use morphoid_core::clean::{clean, CleanOptions};
use morphoid_core::conformal::{
    flatten_to_disk, flipped_triangles, normalize, quasi_conformal_ratios,
};

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn all_cleaned_teeth_flatten_without_flips() {
    let Some(paths) = crate::support::data::tooth_paths() else {
        return;
    };
    assert_eq!(paths.len(), 116);
    let mut ratios = Vec::new();
    for path in &paths {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        let raw = morphoid_data::mesh_io::load(path).unwrap().mesh;
        let cleaned = clean(&raw, &CleanOptions::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"))
            .mesh;
        let mesh = normalize(&cleaned).unwrap().mesh;
        let map = flatten_to_disk(&mesh).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(flipped_triangles(&mesh.faces, &map.uv), 0, "{name}");
        for z in &map.uv {
            assert!(z[0].hypot(z[1]) <= 1.0 + 1e-9, "{name}");
        }
        ratios.extend(quasi_conformal_ratios(&mesh, &map.uv));
    }
    ratios.sort_by(f64::total_cmp);
    let pct = |q: f64| ratios[((ratios.len() - 1) as f64 * q).round() as usize];
    println!(
        "116 cleaned teeth, {} triangles: quasi-conformal ratio median {:.4}, 95th percentile {:.4}, 99th {:.4}, max {:.1}",
        ratios.len(),
        pct(0.5),
        pct(0.95),
        pct(0.99),
        pct(1.0)
    );
    assert!(pct(0.5) < 1.06);
    assert!(pct(0.95) < 1.2);
}
