//! Helpers shared by the cp tests: the real teeth loaded, cleaned and
//! prepared through the same path as `morphoid matrix`.

use morphoid_core::mesh::Mesh;
use std::path::{Path, PathBuf};

/// The real teeth folder (`labels.csv`, `meshes/`); see
/// [`super::data::teeth_dir`] for when it is missing.
pub(crate) fn data_dir() -> Option<PathBuf> {
    super::data::teeth_dir()
}

/// Load a tooth by name through the path users run: the file reader and
/// the cleaning stage with default settings.
pub(crate) fn load_tooth(dir: &Path, name: &str) -> Mesh {
    let path = dir.join("meshes").join(format!("{name}.ply"));
    let loaded = morphoid_data::mesh_io::load(&path).expect("tooth loads");
    morphoid_core::clean::clean(&loaded.mesh, &morphoid_core::clean::CleanOptions::default())
        .expect("tooth cleans")
        .mesh
}

/// Names in labels.csv order, read as `morphoid evaluate` reads them.
pub(crate) fn tooth_names(dir: &Path) -> Vec<String> {
    morphoid_data::table::Labels::read(&dir.join("labels.csv"), None)
        .expect("labels")
        .names()
        .to_vec()
}

/// Parameters from the JSON in the environment variable `var`, else the
/// defaults; printed, so a run's output says what it measured.
pub(crate) fn params_from_env<T>(var: &str) -> T
where
    T: serde::de::DeserializeOwned + serde::Serialize + Default,
{
    let params: T = match std::env::var(var) {
        Ok(json) => serde_json::from_str(&json)
            .unwrap_or_else(|e| panic!("{var} is not parameter JSON: {e}")),
        Err(_) => T::default(),
    };
    println!(
        "params: {}",
        serde_json::to_string(&params).unwrap_or_default()
    );
    params
}

/// Every tooth of `names` loaded, cleaned and prepared with `params` (in
/// parallel) by `pipeline::prepare_file`, as `morphoid matrix` does; each
/// carries its name.
///
/// Prepared surfaces are kept for the life of the test process, keyed by
/// file and preparation parameters: several tests need the same teeth, and
/// preparing all 116 costs about a minute of CPU each time.
pub(crate) fn prepare_teeth(
    dir: &Path,
    names: &[String],
    params: &morphoid_core::cp::CpParams,
) -> Vec<morphoid_core::cp::Prepared> {
    use rayon::prelude::*;
    let settings = morphoid_data::pipeline::Settings {
        cp: params.clone(),
        ..Default::default()
    };
    let key_params = serde_json::to_string(&params.prepare).expect("parameters serialize");
    names
        .par_iter()
        .map(|n| {
            let path = dir.join("meshes").join(format!("{n}.ply"));
            let slot = prepared_slot(&path, &key_params);
            slot.get_or_init(|| {
                morphoid_data::pipeline::prepare_file(&path, &settings)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
                    .prepared
            })
            .clone()
        })
        .collect()
}

/// The process-wide slot of one prepared tooth: filled once, by whichever
/// test gets there first, while the others wait for it.
fn prepared_slot(
    path: &Path,
    params: &str,
) -> std::sync::Arc<std::sync::OnceLock<morphoid_core::cp::Prepared>> {
    use std::collections::HashMap;
    use std::sync::{Arc, Mutex, OnceLock};
    type Slots = Mutex<HashMap<(PathBuf, String), Arc<OnceLock<morphoid_core::cp::Prepared>>>>;
    static SLOTS: OnceLock<Slots> = OnceLock::new();
    let mut slots = SLOTS
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    slots
        .entry((path.to_path_buf(), params.to_string()))
        .or_default()
        .clone()
}

/// The pair the benchmarks compare: the real teeth H10 and H16 (loaded and
/// cleaned as users' files are) when the data is present, else two
/// synthetic crowns of about 5,000 vertices; with a description of which.
#[allow(dead_code)] // used by the benches, which include this module
pub(crate) fn benchmark_pair() -> (Mesh, Mesh, &'static str) {
    match super::data::teeth_dir_if_present() {
        Some(dir) => (
            load_tooth(&dir, "H10"),
            load_tooth(&dir, "H16"),
            "real teeth H10, H16",
        ),
        None => {
            use morphoid_synth::mesh::{crown, CROWN_GENERA};
            (
                crown(&CROWN_GENERA[0], 1, 5000),
                crown(&CROWN_GENERA[1], 2, 5000),
                "synthetic crowns (data not found)",
            )
        }
    }
}

/// Leave-one-out nearest-neighbour scores of `matrix` at order, family and
/// genus, against the real teeth's `labels.csv`; printed.
pub(crate) fn leave_one_out_scores(
    dir: &Path,
    matrix: &morphoid_data::table::DistanceMatrix,
) -> Vec<morphoid_research::eval::RankScore> {
    let ranks: Vec<String> = ["order", "family", "genus"].map(String::from).to_vec();
    let labels =
        morphoid_data::table::Labels::read(&dir.join("labels.csv"), Some(&ranks)).expect("labels");
    let scores = morphoid_research::eval::leave_one_out(matrix, &labels, &ranks);
    for s in &scores {
        println!("LOO {}: {}/{}", s.rank, s.correct, s.total);
    }
    scores
}

/// Held-out identification as `morphoid classify` makes it, crowns found
/// on whole teeth cut again along their nearest references' crop lines:
/// each surface of `surfaces` (prepared by the pipeline, named after its
/// tooth) is identified by a classifier of every surface of `originals`
/// but its own tooth. Scores at order, family and genus (a tooth counts at
/// a rank when it is labelled there); printed, misses at genus listed.
#[allow(dead_code)] // used by some of the test modules only
pub(crate) fn heldout_scores_classified(
    dir: &Path,
    surfaces: &mut [morphoid_data::pipeline::PreparedSurface],
    originals: &[morphoid_core::cp::Prepared],
) -> Vec<morphoid_research::eval::RankScore> {
    use morphoid_data::library::CachedReference;
    use rayon::prelude::*;
    let ranks: Vec<String> = ["order", "family", "genus"].map(String::from).to_vec();
    let labels =
        morphoid_data::table::Labels::read(&dir.join("labels.csv"), Some(&ranks)).expect("labels");
    let mut settings = morphoid_data::pipeline::Settings::default();
    // MORPHOID_RECUT_AMONG=N: identified with `[cp] recut_among = N`.
    if let Some(n) = std::env::var("MORPHOID_RECUT_AMONG")
        .ok()
        .and_then(|v| v.parse().ok())
    {
        settings.cp.recut.recut_among = n;
    }
    let outcomes: Vec<morphoid_service::identify::ScanOutcome> = surfaces
        .par_iter_mut()
        .map(|surface| {
            let references: Vec<CachedReference> = originals
                .iter()
                .filter(|o| o.name() != surface.prepared.name())
                .map(|o| {
                    CachedReference::new(
                        o.name().to_string(),
                        String::new(),
                        o.clone(),
                        morphoid_core::clean::CleanReport::default(),
                    )
                })
                .collect();
            morphoid_service::classify::Classifier::new(
                references,
                labels.clone(),
                settings.clone(),
            )
            .classify_prepared(surface)
        })
        .collect();
    ranks
        .iter()
        .map(|rank| {
            let (mut correct, mut total) = (0, 0);
            for (surface, outcome) in surfaces.iter().zip(&outcomes) {
                let name = surface.prepared.name();
                let (Some(truth), Some(call)) = (
                    labels.get(name, rank),
                    outcome.ranks.iter().find(|r| &r.rank == rank),
                ) else {
                    continue;
                };
                total += 1;
                if call.taxon == truth {
                    correct += 1;
                } else if rank == "genus" {
                    // Where the nearest of its own genus stood.
                    let mut rows: Vec<_> = outcome.distances.iter().collect();
                    rows.sort_by(|a, b| a.distance.total_cmp(&b.distance));
                    let own = rows
                        .iter()
                        .position(|r| labels.get(&r.reference, rank) == Some(truth));
                    let own = own.map(|k| (k + 1, &rows[k].reference, rows[k].distance));
                    println!(
                        "  miss {name}: {truth} called {} via {} at {:.4}; nearest of its own (rank, name, distance): {own:?}",
                        call.taxon, call.reference, call.distance
                    );
                }
            }
            rank_score(rank, correct, total)
        })
        .collect()
}

/// Held-out identification of altered copies of the real teeth (closed
/// whole teeth, slice stacks, point clouds, ...): each surface of
/// `variants`, named after its tooth, is compared with every surface of
/// `originals` but its own tooth, and called by its nearest one. Scores at
/// order, family and genus (a tooth counts at a rank when its label and
/// its nearest neighbour's label at that rank are both known, as in
/// `eval::leave_one_out`); printed, misses at genus listed.
#[allow(dead_code)] // used by some of the test modules only
pub(crate) fn heldout_scores(
    dir: &Path,
    variants: &[morphoid_core::cp::Prepared],
    originals: &[morphoid_core::cp::Prepared],
    params: &morphoid_core::cp::CompareParams,
) -> Vec<morphoid_research::eval::RankScore> {
    use rayon::prelude::*;
    let ranks: Vec<String> = ["order", "family", "genus"].map(String::from).to_vec();
    let labels =
        morphoid_data::table::Labels::read(&dir.join("labels.csv"), Some(&ranks)).expect("labels");
    let pairs: Vec<(usize, usize)> = (0..variants.len())
        .flat_map(|i| (0..originals.len()).map(move |j| (i, j)))
        .filter(|&(i, j)| variants[i].name() != originals[j].name())
        .collect();
    let distances: Vec<f64> = pairs
        .par_iter()
        .map(|&(i, j)| morphoid_core::cp::compare(&variants[i], &originals[j], params).distance)
        .collect();
    ranks
        .iter()
        .map(|rank| {
            let mut best: Vec<Option<(f64, usize)>> = vec![None; variants.len()];
            for (&(i, j), &d) in pairs.iter().zip(&distances) {
                if labels.get(originals[j].name(), rank).is_none() || !d.is_finite() {
                    continue;
                }
                if best[i].is_none_or(|(bd, _)| d < bd) {
                    best[i] = Some((d, j));
                }
            }
            let (mut correct, mut total) = (0, 0);
            for (i, b) in best.iter().enumerate() {
                let (Some(truth), Some((d, j))) = (labels.get(variants[i].name(), rank), b) else {
                    continue;
                };
                total += 1;
                let called = labels.get(originals[*j].name(), rank);
                if called == Some(truth) {
                    correct += 1;
                } else if rank == "genus" {
                    println!(
                        "  miss {}: {truth} called {} via {} at {d:.4}",
                        variants[i].name(),
                        called.unwrap_or("?"),
                        originals[*j].name()
                    );
                }
            }
            rank_score(rank, correct, total)
        })
        .collect()
}

/// The held-out score at `rank`, printed.
fn rank_score(rank: &str, correct: usize, total: usize) -> morphoid_research::eval::RankScore {
    println!("held-out {rank}: {correct}/{total}");
    morphoid_research::eval::RankScore {
        rank: rank.to_string(),
        correct,
        total,
    }
}
