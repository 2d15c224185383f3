//! The discrete Procrustes distance matrix of a library's landmark files
//! (the paper's ODLP matrix, to set against the cP matrix).

use super::{load_library, procrustes_distance, ProcrustesError};
use crate::table::{pairwise_matrix, DistanceMatrix};
use std::path::{Path, PathBuf};

/// Why the landmark matrix of a folder cannot be computed.
#[derive(Debug, thiserror::Error)]
pub enum LandmarkMatrixError {
    /// A specimen's landmark file cannot be used.
    #[error("landmarks of `{name}`: {source}")]
    Unusable {
        /// The specimen.
        name: String,
        /// Why (names the file).
        source: super::LandmarkProblem,
    },
    /// Specimens without a landmark file.
    #[error(
        "{}: no landmark file (landmarks/<name>.csv, .fcsv, .mrk.json or .pp) for {}",
        dir.display(),
        names.join(", ")
    )]
    Missing {
        /// The folder.
        dir: PathBuf,
        /// The specimens.
        names: Vec<String>,
    },
    /// Two landmark sets cannot be compared.
    #[error("landmarks of `{a}` and `{b}`: {source}")]
    Compare {
        /// The first specimen.
        a: String,
        /// The second specimen.
        b: String,
        /// Why.
        #[source]
        source: ProcrustesError,
    },
}

/// The landmark Procrustes matrix of the specimens `names` of the folder
/// `dir` (each must have a usable landmark file, all with the same count;
/// see [`load_library`]), in the order of `names`, and the number of
/// landmarks per specimen.
pub fn procrustes_matrix(
    dir: &Path,
    names: &[String],
    allow_reflection: bool,
) -> Result<(DistanceMatrix, usize), LandmarkMatrixError> {
    let mut loaded = load_library(dir, names);
    if !loaded.problems.is_empty() {
        let (name, source) = loaded.problems.swap_remove(0);
        return Err(LandmarkMatrixError::Unusable { name, source });
    }
    let mut sets = Vec::with_capacity(names.len());
    let mut missing = Vec::new();
    for name in names {
        match loaded.by_name.get(name) {
            Some(lm) => sets.push(lm.points.as_slice()),
            None => missing.push(name.clone()),
        }
    }
    if !missing.is_empty() {
        return Err(LandmarkMatrixError::Missing {
            dir: dir.to_path_buf(),
            names: missing,
        });
    }
    let matrix = pairwise_matrix(
        names.to_vec(),
        |i, j| {
            procrustes_distance(sets[i], sets[j], allow_reflection).map_err(|source| {
                LandmarkMatrixError::Compare {
                    a: names[i].clone(),
                    b: names[j].clone(),
                    source,
                }
            })
        },
        |_| {},
    )?;
    Ok((matrix, loaded.count.unwrap_or(0)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::landmarks::{write, Landmarks};

    #[test]
    fn matrix_of_a_folder_and_its_errors() {
        let dir = tempfile::tempdir().unwrap();
        let lm = dir.path().join("landmarks");
        std::fs::create_dir(&lm).unwrap();
        let square = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        // The same square, turned and scaled: distance 0 to the first.
        let turned = square.map(|p| [-2.0 * p[1], 2.0 * p[0], 5.0]);
        let kite = [
            [0.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        for (name, points) in [("a", square), ("b,1", turned), ("c", kite)] {
            write(
                &lm.join(format!("{name}.csv")),
                &Landmarks::from_points(points.to_vec()),
            )
            .unwrap();
        }
        let names: Vec<String> = ["a", "b,1", "c"].map(String::from).to_vec();
        let (m, count) = procrustes_matrix(dir.path(), &names, false).unwrap();
        assert_eq!(count, 4);
        assert_eq!(m.names(), names);
        assert!(m.get(0, 1) < 1e-12, "{}", m.get(0, 1));
        assert!(m.get(0, 2) > 0.1 && m.get(0, 2) == m.get(2, 0));

        let more = [names.clone(), vec!["d".to_string()]].concat();
        let e = procrustes_matrix(dir.path(), &more, false).unwrap_err();
        assert!(
            matches!(&e, LandmarkMatrixError::Missing { names, .. } if names == &["d"]),
            "{e}"
        );
        std::fs::write(lm.join("c.csv"), "1,2,3\n").unwrap();
        let e = procrustes_matrix(dir.path(), &names, false).unwrap_err();
        assert!(e.to_string().contains("landmarks of `c`"), "{e}");
    }
}
