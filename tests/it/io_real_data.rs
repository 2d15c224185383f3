//! All 116 molars of the reference data set load with plausible sizes.

use morphoid_core::mesh::{boundary_loops, euler_characteristic};
use morphoid_data::mesh_io::{load, Format};

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn all_real_teeth_load() {
    let Some(data) = crate::support::data::teeth_dir() else {
        return;
    };
    let dir = data.join("meshes");
    let Some(paths) = crate::support::data::tooth_paths() else {
        return;
    };
    assert_eq!(paths.len(), 116);
    // Every labelled specimen has its mesh.
    let labels = std::fs::read_to_string(data.join("labels.csv")).unwrap();
    for row in labels.lines().skip(1) {
        let name = row.split(',').next().unwrap();
        assert!(dir.join(format!("{name}.ply")).exists(), "{name}");
    }
    let start = std::time::Instant::now();
    let mut loading = std::time::Duration::ZERO;
    let (mut vmin, mut vmax, mut fmin, mut fmax) = (usize::MAX, 0, usize::MAX, 0);
    for path in &paths {
        let t = std::time::Instant::now();
        let loaded = load(path).unwrap_or_else(|e| panic!("{e}"));
        loading += t.elapsed();
        assert_eq!(loaded.format, Format::Ply);
        let m = &loaded.mesh;
        let (v, f) = (m.vertex_count(), m.face_count());
        assert!(
            (4_500..=5_700).contains(&v),
            "{}: {v} vertices",
            path.display()
        );
        // A disk with V vertices, b of them on the boundary, has 2V - b - 2
        // triangles; the crowns have ~10,000 triangles.
        assert!(
            (9_000..=11_000).contains(&f),
            "{}: {f} faces",
            path.display()
        );
        (vmin, vmax) = (vmin.min(v), vmax.max(v));
        (fmin, fmax) = (fmin.min(f), fmax.max(f));
        let name = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        let loops = boundary_loops(m);
        if name != "J12" && name != "S09" {
            assert_eq!(euler_characteristic(m), 1, "{name}");
            assert_eq!(loops.len(), 1, "{name}");
            let b = loops[0].len();
            assert_eq!(f, 2 * v - b - 2, "{name}");
        }
    }
    println!(
        "116 meshes: {vmin}..{vmax} vertices, {fmin}..{fmax} faces, read in {:.3} s, checked in {:.2} s",
        loading.as_secs_f64(),
        start.elapsed().as_secs_f64()
    );
}
