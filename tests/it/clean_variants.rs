//! Defective variants of a real tooth, generated here, clean back to a disk
//! on the tooth's surface (needs the data set, see `support::data`).

use crate::support::clean::*;
use morphoid_core::clean::{clean, CleanOptions, Cleaned};
use morphoid_core::mesh::{
    bbox_diagonal, boundary_loops, euler_characteristic, surface_area, Mesh,
};
use morphoid_synth::mesh as synth;

fn tooth() -> Option<Mesh> {
    let dir = teeth_dir()?;
    Some(read_tooth(&dir.join("B03.ply")))
}

/// Disk-type, within the vertex target, on `surface` (mean distance below
/// 0.5 % of its diagonal). Returns the relative mean distance.
fn check(label: &str, c: &Cleaned, surface: &Mesh) -> f64 {
    let m = &c.mesh;
    assert_eq!(boundary_loops(m).len(), 1, "{label}");
    assert_eq!(euler_characteristic(m), 1, "{label}");
    let nv = m.vertices.len() as f64;
    assert!((nv - 5000.0).abs() <= 500.0, "{label}: {nv} vertices");
    let (mean, max) = mean_max_distance(&m.vertices, surface);
    let d = bbox_diagonal(surface);
    println!(
        "{label}: {nv} vertices, mean {:.2e}, max {:.2e} of the diagonal; {:?}",
        mean / d,
        max / d,
        c.report
    );
    assert!(mean < 0.005 * d, "{label}: mean distance {}", mean / d);
    mean / d
}

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn stl_soup_with_debris_cleans_back() {
    let Some(t) = tooth() else {
        return;
    };
    let soup = synth::triangle_soup(&synth::add_debris(&t, 3, 11));
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("soup.stl");
    morphoid_data::mesh_io::write_stl(&path, &soup).expect("write stl");
    let loaded = morphoid_data::mesh_io::load(&path).expect("load stl").mesh;
    // Binary STL shares identical corners as it is read.
    assert!(loaded.vertices.len() < loaded.faces.len());
    let c = clean(&loaded, &CleanOptions::default()).expect("clean soup");
    assert_eq!(c.report.dropped_components, 3);
    check("binary stl soup + 3 debris", &c, &t);
    // ASCII STL stays a soup, which cleaning welds.
    let path = dir.path().join("soup_ascii.stl");
    morphoid_data::mesh_io::write_stl_ascii(&path, &soup).expect("write ascii stl");
    let loaded = morphoid_data::mesh_io::load(&path)
        .expect("load ascii stl")
        .mesh;
    assert_eq!(loaded.vertices.len(), 3 * loaded.faces.len());
    let c = clean(&loaded, &CleanOptions::default()).expect("clean ascii soup");
    assert_eq!(c.report.dropped_components, 3);
    assert!(c.report.welded_vertices > 2 * t.vertices.len());
    check("ascii stl soup + 3 debris", &c, &t);
}

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn mirrored_flipped_cloud_and_dense_variants_clean_back() {
    let Some(t) = tooth() else {
        return;
    };
    let opts = CleanOptions::default();
    let base = clean(&t, &opts).expect("clean tooth");
    check("original", &base, &t);

    let mirrored = synth::mirror(&t);
    let c = clean(&mirrored, &opts).expect("mirror");
    check("mirrored", &c, &mirrored);
    // Mirroring commutes with cleaning's choice of the outward side.
    assert_eq!(
        c.report.reversed_orientation,
        base.report.reversed_orientation
    );

    let flipped = synth::flip_faces(&t, 0.4, 2);
    let c = clean(&flipped, &opts).expect("flipped");
    assert!(c.report.flipped_faces > 0);
    check("flipped faces", &c, &t);
    assert_eq!(c.mesh, base.mesh, "re-oriented faces give the same result");

    let c = clean(&synth::to_point_cloud(&t), &opts).expect("cloud");
    assert!(c.report.triangulated_point_cloud);
    check("point cloud", &c, &t);
    // The triangulation covers the tooth, not just part of it.
    let covered = c.report.area / surface_area(&t);
    assert!(covered > 0.95, "point cloud covers {covered} of the area");

    let dense = synth::subdivide_midpoint(&t, 2);
    assert!(dense.vertices.len() > 75_000);
    let c = clean(&dense, &opts).expect("dense");
    check("16x denser", &c, &t);
}
