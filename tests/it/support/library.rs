//! The real teeth as the product holds them, for the measurements that
//! need the whole library: opened with the ranks order, family and genus,
//! prepared and calibrated by `Classifier::build`, and the distances among
//! the references. The cache is `MORPHOID_CALIBRATION_CACHE` when set, so
//! repeated runs prepare and compare once; else a temporary folder.

use morphoid_data::library::{Cache, Library};
use morphoid_data::pipeline::Settings;
use morphoid_service::classify::Classifier;
use morphoid_service::identify::ReferenceDistances;
use std::path::PathBuf;

/// What [`real_library`] builds.
pub(crate) struct RealLibrary {
    /// The real-data folder.
    pub dir: PathBuf,
    /// The library (ranks order, family, genus).
    pub library: Library,
    /// The classifier built from it with the default settings.
    pub classifier: Classifier,
    /// The distances among the classifier's references.
    pub table: ReferenceDistances,
    /// The settings everything was built with.
    pub settings: Settings,
    /// Holds the temporary cache folder, when there is one.
    _tmp: tempfile::TempDir,
}

/// The real teeth built as [`RealLibrary`] says, or `None` without the
/// data when the developer opted out of it (see `data::teeth_dir`).
/// Every reference must prepare.
pub(crate) fn real_library() -> Option<RealLibrary> {
    let dir = super::data::teeth_dir()?;
    let ranks: Vec<String> = ["order", "family", "genus"].map(String::from).to_vec();
    let library = Library::open(&dir, Some(&ranks)).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let root = std::env::var_os("MORPHOID_CALIBRATION_CACHE")
        .map(PathBuf::from)
        .unwrap_or_else(|| tmp.path().to_path_buf());
    let cache = Cache::for_folder(Some(&root), &dir).unwrap();
    let settings = Settings::default();
    let (classifier, built) = Classifier::build(&library, &cache, &settings, |_| {}).unwrap();
    assert!(built.failures().is_empty());
    let table = morphoid_service::identify::reference_distances(
        classifier.references(),
        &settings,
        Some(&cache),
        |_, _| {},
    );
    Some(RealLibrary {
        dir,
        library,
        classifier,
        table,
        settings,
        _tmp: tmp,
    })
}

/// Two identifications of each held-out tooth compared rank by rank: how
/// often they agree, and how often each is right where the truth is known.
pub(crate) struct AnswerTally {
    ranks: Vec<String>,
    same: Vec<usize>,
    right: [Vec<usize>; 2],
}

impl AnswerTally {
    /// An empty tally over `labels`' ranks.
    pub(crate) fn new(labels: &morphoid_data::table::Labels) -> Self {
        let ranks = labels.ranks().to_vec();
        let zero = vec![0; ranks.len()];
        AnswerTally {
            same: zero.clone(),
            right: [zero.clone(), zero],
            ranks,
        }
    }

    /// Count the two answers `a` and `b` of the tooth `name`.
    pub(crate) fn add(
        &mut self,
        labels: &morphoid_data::table::Labels,
        name: &str,
        a: &morphoid_service::identify::Identification,
        b: &morphoid_service::identify::Identification,
    ) {
        for (k, rank) in self.ranks.iter().enumerate() {
            let truth = labels.get(name, rank);
            let answer = |id: &morphoid_service::identify::Identification| {
                id.ranks
                    .iter()
                    .find(|r| &r.rank == rank)
                    .map(|r| r.taxon.clone())
            };
            let (x, y) = (answer(a), answer(b));
            self.same[k] += usize::from(x == y);
            if truth.is_some() {
                self.right[0][k] += usize::from(x.as_deref() == truth);
                self.right[1][k] += usize::from(y.as_deref() == truth);
            }
        }
    }

    /// Per rank: answers the same, right with the first, with the second.
    pub(crate) fn per_rank(&self) -> impl Iterator<Item = (&str, usize, usize, usize)> + '_ {
        self.ranks
            .iter()
            .enumerate()
            .map(|(k, r)| (r.as_str(), self.same[k], self.right[0][k], self.right[1][k]))
    }
}
