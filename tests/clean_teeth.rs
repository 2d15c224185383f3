//! Cleaning the real teeth (skipped when the data set is absent).

mod clean_support;

use clean_support::*;
use morphoid::clean::{clean, CleanOptions};
use morphoid::mesh::{bbox_diagonal, boundary_loops, edge_face_map, euler_characteristic};

#[test]
fn all_teeth_clean_to_disks_on_their_surface() {
    let Some(teeth) = all_teeth() else {
        println!("skipped: data not found");
        return;
    };
    assert_eq!(teeth.len(), 116);
    let opts = CleanOptions::default();
    let mut rel = Vec::new();
    let mut reversed = 0;
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
}
