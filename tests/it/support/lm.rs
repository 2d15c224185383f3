//! What the landmark tests share: landmark files for a synthetic library
//! (chosen vertices of each reference, in every supported format) and
//! rigidly moved, remeshed, rescaled copies of a reference with the true
//! positions of its landmarks.

use morphoid_core::mesh::{bbox_diagonal, norm, sub, Mesh};
use morphoid_data::landmarks::{self, Landmarks};
use morphoid_data::mesh_io;
use morphoid_synth::mesh::{self as synth, RigidMotion};
use std::path::Path;

/// The vertices that serve as landmarks: the same indices on every crown
/// of one resolution sit at about the same place of its disk, so they are
/// (roughly) homologous across specimens.
pub(crate) const LANDMARK_VERTICES: [usize; 10] =
    [0, 100, 250, 400, 550, 700, 850, 1000, 1150, 1300];

/// Scale of the moved copies (file units change, e.g. mm to µm).
pub(crate) const SCALE: f64 = 1000.0;

/// The landmark file extensions, cycled over the references.
pub(crate) const EXTENSIONS: [&str; 4] = ["csv", "fcsv", "mrk.json", "pp"];

/// The landmarks of the reference surface file `mesh_path`: its vertices
/// at [`LANDMARK_VERTICES`], labelled `L1`…
pub(crate) fn landmarks_of(mesh_path: &Path) -> Landmarks {
    let mesh = mesh_io::load(mesh_path).expect("reference loads").mesh;
    let mut lm = Landmarks::default();
    for (k, &v) in LANDMARK_VERTICES.iter().enumerate() {
        lm.push(mesh.vertices[v], Some(format!("L{}", k + 1)));
    }
    lm
}

/// Write `landmarks/<name>.<ext>` for each of `names` of the library
/// folder `lib`, the format cycling through [`EXTENSIONS`].
pub(crate) fn write_library_landmarks(lib: &Path, names: &[String]) {
    let dir = lib.join("landmarks");
    std::fs::create_dir_all(&dir).unwrap();
    for (i, name) in names.iter().enumerate() {
        let lm = landmarks_of(&lib.join(format!("{name}.ply")));
        let ext = EXTENSIONS[i % EXTENSIONS.len()];
        landmarks::write(&dir.join(format!("{name}.{ext}")), &lm).unwrap();
    }
}

/// A copy of `mesh`: subdivided once (so its vertices are new once
/// cleaning resamples it), scaled by [`SCALE`], rigidly moved.
pub(crate) fn moved_copy(mesh: &Mesh, seed: u64) -> (Mesh, RigidMotion) {
    let reach = 3.0 * SCALE * bbox_diagonal(mesh);
    let motion = RigidMotion::random(seed, reach);
    let fine = synth::scale(&synth::subdivide_midpoint(mesh, 1), SCALE);
    (motion.apply(&fine), motion)
}

/// Where a landmark `p` of the original lies on the moved copy.
pub(crate) fn true_position(p: [f64; 3], motion: &RigidMotion) -> [f64; 3] {
    motion.apply_point(p.map(|x| x * SCALE))
}

/// Distances between `got` and `truth` relative to the bounding-box
/// diagonal of `target`: (mean, max).
pub(crate) fn relative_errors(got: &[[f64; 3]], truth: &[[f64; 3]], target: &Mesh) -> (f64, f64) {
    assert_eq!(got.len(), truth.len());
    let diag = bbox_diagonal(target);
    let e: Vec<f64> = got
        .iter()
        .zip(truth)
        .map(|(a, b)| norm(sub(*a, *b)) / diag)
        .collect();
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    (mean, e.iter().copied().fold(0.0, f64::max))
}

/// The points of a JSON `"landmarks"` list and their labels.
pub(crate) fn json_landmarks(v: &serde_json::Value) -> (Vec<[f64; 3]>, Vec<String>) {
    let list = v["landmarks"].as_array().expect("a landmarks list");
    let points = list
        .iter()
        .map(|p| {
            [
                p["x"].as_f64().unwrap(),
                p["y"].as_f64().unwrap(),
                p["z"].as_f64().unwrap(),
            ]
        })
        .collect();
    let labels = list
        .iter()
        .map(|p| p["label"].as_str().unwrap_or("").to_string())
        .collect();
    (points, labels)
}
