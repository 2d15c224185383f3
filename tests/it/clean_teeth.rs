//! Cleaning the real teeth (needs the data set, see `support::data`).

use crate::support::clean::*;
use morphoid_core::clean::{clean, CleanOptions};
use morphoid_core::mesh::{bbox_diagonal, boundary_loops, edge_face_map, euler_characteristic};

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn all_teeth_clean_to_disks_on_their_surface() {
    let Some(teeth) = all_teeth() else {
        return;
    };
    assert_eq!(teeth.len(), 116);
    let opts = CleanOptions::default();
    let mut rel = Vec::new();
    let mut reversed = 0;
    let mut worst_in: f64 = 0.0;
    let mut worst_out: f64 = 0.0;
    let mut obtuse = (0.0, 0.0);
    for (name, mesh) in &teeth {
        let c = clean(mesh, &opts).unwrap_or_else(|e| panic!("{name}: {e}"));
        let m = &c.mesh;
        assert_eq!(boundary_loops(m).len(), 1, "{name}");
        assert_eq!(euler_characteristic(m), 1, "{name}");
        assert_eq!(c.report.boundary_loops, 1);
        assert_eq!(c.report.euler_characteristic, 1);
        let nv = m.vertices.len() as f64;
        assert!((nv - 5000.0).abs() <= 500.0, "{name}: {nv} vertices");
        assert!(edge_face_map(m).values().all(|f| f.len() <= 2), "{name}");
        let (mean, _) = mean_max_distance(&m.vertices, mesh);
        let r = mean / bbox_diagonal(mesh);
        assert!(r < 0.005, "{name}: mean distance {r} of the diagonal");
        rel.push(r);
        let (qi, qo) = (max_angles(mesh), max_angles(m));
        worst_in = worst_in.max(qi.0);
        worst_out = worst_out.max(qo.0);
        if qo.0 > 170.0 {
            println!("{name}: largest angle {:.1}° (input {:.1}°)", qo.0, qi.0);
        }
        obtuse.0 += qi.1 / teeth.len() as f64;
        obtuse.1 += qo.1 / teeth.len() as f64;
        // Resampling improves the triangles.
        assert!(qo.1 < qi.1, "{name}: obtuse fraction {} -> {}", qi.1, qo.1);
        if c.report.reversed_orientation {
            reversed += 1;
        }
        if name == "J12" || name == "S09" {
            assert!(
                c.report.repaired_nonmanifold_edges + c.report.repaired_nonmanifold_vertices >= 1,
                "{name}: {:?}",
                c.report
            );
        }
    }
    println!(
        "mean distance / diagonal over {} teeth: median {:.2e}, max {:.2e}; reversed {}",
        rel.len(),
        median(&rel),
        rel.iter().copied().fold(0.0, f64::max),
        reversed
    );
    println!(
        "largest angle in / out: {worst_in:.1}° / {worst_out:.1}°; obtuse triangles in / out: {:.1} % / {:.1} %",
        100.0 * obtuse.0,
        100.0 * obtuse.1
    );
    assert!(worst_out < 170.0);
}

/// Largest triangle angle (degrees) and fraction of obtuse triangles.
fn max_angles(m: &morphoid_core::mesh::Mesh) -> (f64, f64) {
    use morphoid_core::mesh::{dot, norm, sub};
    let mut worst: f64 = 0.0;
    let mut obtuse = 0;
    for f in &m.faces {
        let p = f.map(|v| m.vertices[v as usize]);
        let mut mx: f64 = 0.0;
        for k in 0..3 {
            let (u, v) = (sub(p[(k + 1) % 3], p[k]), sub(p[(k + 2) % 3], p[k]));
            let c = (dot(u, v) / (norm(u) * norm(v))).clamp(-1.0, 1.0);
            mx = mx.max(c.acos().to_degrees());
        }
        worst = worst.max(mx);
        if mx > 90.0 {
            obtuse += 1;
        }
    }
    (worst, obtuse as f64 / m.faces.len() as f64)
}

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn every_third_tooth_as_a_point_cloud_cleans_to_a_disk_covering_the_tooth() {
    use rayon::prelude::*;
    let Some(teeth) = all_teeth() else {
        return;
    };
    // Every third tooth (39): the reconstruction of a cloud costs about
    // two seconds, and `clean_cloud` measures it on other teeth.
    let opts = CleanOptions::default();
    let mut coverage: Vec<(f64, String)> = teeth
        .par_iter()
        .step_by(3)
        .map(|(name, mesh)| {
            let cloud = morphoid_synth::mesh::to_point_cloud(mesh);
            let c = clean(&cloud, &opts).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(boundary_loops(&c.mesh).len(), 1, "{name}");
            assert_eq!(euler_characteristic(&c.mesh), 1, "{name}");
            let nv = c.mesh.vertices.len() as f64;
            assert!((nv - 5000.0).abs() <= 500.0, "{name}: {nv} vertices");
            let (mean, _) = mean_max_distance(&c.mesh.vertices, mesh);
            assert!(mean < 0.005 * bbox_diagonal(mesh), "{name}");
            (
                c.report.area / morphoid_core::mesh::surface_area(mesh),
                name.clone(),
            )
        })
        .collect();
    assert_eq!(coverage.len(), teeth.len().div_ceil(3));
    coverage.sort_by(|a, b| a.0.total_cmp(&b.0));
    println!(
        "point-cloud area / tooth area: min {:.3} ({}), median {:.3}, max {:.3}",
        coverage[0].0,
        coverage[0].1,
        coverage[coverage.len() / 2].0,
        coverage[coverage.len() - 1].0
    );
    assert!(coverage[0].0 > 0.8, "{:?}", &coverage[..5]);
    assert!(coverage[coverage.len() / 2].0 > 0.95);
}
