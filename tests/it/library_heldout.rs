//! Held-out identification on the real teeth: ten teeth with a known genus
//! leave the library, come back as new scans (rigid motion, millimetres to
//! micrometres, remeshed) and must be identified to the right genus.

use morphoid_core::clean::{clean, CleanOptions, CleanReport};
use morphoid_data::library::CachedReference;
use morphoid_data::mesh_io;
use morphoid_data::pipeline::Settings;
use morphoid_data::table::Labels;
use morphoid_service::classify::Classifier;
use morphoid_synth::mesh::{self as synth, RigidMotion};

#[test]
#[cfg_attr(
    morphoid_skip_data,
    ignore = "needs the real teeth (MORPHOID_SKIP_DATA=1 and none found)"
)]
fn held_out_teeth_are_identified_to_genus() {
    let Some(data) = crate::support::data::teeth_dir() else {
        return;
    };
    let ranks: Vec<String> = ["order", "family", "genus"].map(String::from).to_vec();
    let labels = Labels::read(&data.join("labels.csv"), Some(&ranks)).unwrap();
    // Every tenth tooth with a known genus, in name order: ten teeth.
    let mut with_genus: Vec<&String> = labels
        .names()
        .iter()
        .filter(|n| labels.get(n, "genus").is_some())
        .collect();
    with_genus.sort();
    let held_out: Vec<String> = with_genus
        .iter()
        .step_by(10)
        .take(10)
        .map(|s| s.to_string())
        .collect();
    assert_eq!(held_out.len(), 10);

    let settings = Settings::default();
    // Prepared as `morphoid library build` does (`pipeline::prepare_file`),
    // shared with the other tests of this process that need the same teeth.
    let names: Vec<String> = labels
        .names()
        .iter()
        .filter(|n| !held_out.contains(n))
        .cloned()
        .collect();
    let references: Vec<CachedReference> =
        crate::support::cp::prepare_teeth(&data, &names, &settings.cp)
            .into_iter()
            .zip(&names)
            .map(|(p, n)| CachedReference::new(n.clone(), String::new(), p, CleanReport::default()))
            .collect();
    assert_eq!(references.len(), 106);
    let classifier = Classifier::new(references, labels.clone(), settings.clone());

    let tmp = tempfile::tempdir().unwrap();
    let mut correct = 0;
    for (i, name) in held_out.iter().enumerate() {
        let tooth = mesh_io::load(&data.join("meshes").join(format!("{name}.ply")))
            .unwrap()
            .mesh;
        // Remesh: refine, then let cleaning decimate back to the working
        // resolution, so no vertex of the scan is a vertex of the original.
        let opts = CleanOptions {
            target_vertices: 4500,
            ..CleanOptions::default()
        };
        let remeshed = clean(&synth::subdivide_midpoint(&tooth, 1), &opts)
            .unwrap()
            .mesh;
        let moved = RigidMotion::random(100 + i as u64, 5.0).apply(&remeshed);
        let scan = synth::scale(&moved, 1000.0);
        let path = tmp.path().join(format!("{name}_scan.stl"));
        mesh_io::save(&path, &scan).unwrap();
        let outcome = classifier.classify_file(&path).unwrap();
        let genus = outcome.ranks.iter().find(|r| r.rank == "genus").unwrap();
        let truth = labels.get(name, "genus").unwrap();
        let ok = genus.taxon == truth;
        correct += ok as usize;
        eprintln!(
            "{name}: true {truth}, called {} via {} at {:.4} {}",
            genus.taxon,
            genus.reference,
            genus.distance,
            if ok { "" } else { "(wrong)" }
        );
    }
    eprintln!("held-out genus: {correct}/10");
    assert!(
        correct >= 8,
        "only {correct}/10 held-out teeth got the right genus"
    );
}
