//! Which labels a research command reads, and at which rank it groups the
//! specimens: the one home of the rules `evaluate` and `align` follow.
//! A labels file is read once; a rank that is not a column is an error
//! naming the file and its ranks.

use morphoid_data::table::{Labels, TableError};
use std::path::{Path, PathBuf};

/// The taxon of each specimen at one rank (in the specimens' order;
/// `None` where unknown), with the rank's name.
pub type Groups = (String, Vec<Option<String>>);

/// Why the labels cannot serve a command.
#[derive(Debug, thiserror::Error)]
pub enum LabelsError {
    /// The file cannot be read or parsed.
    #[error(transparent)]
    Table(#[from] TableError),
    /// The rank asked for is not a column of the file.
    #[error("{path}: no rank column `{rank}` (ranks: {ranks})")]
    NoRank {
        /// The labels file.
        path: PathBuf,
        /// The rank asked for.
        rank: String,
        /// The file's ranks, comma-separated.
        ranks: String,
    },
    /// Specimens of the matrix have no row in the labels file.
    #[error("{path}: no label row for {count} specimen(s) of the matrix: {names}")]
    Unlabelled {
        /// The labels file.
        path: PathBuf,
        /// How many.
        count: usize,
        /// Their names, comma-separated.
        names: String,
    },
    /// A rank was asked for, but the folder has no labels file.
    #[error("--rank {rank}: {path} does not exist")]
    NoLabelsFile {
        /// The rank asked for.
        rank: String,
        /// The labels file looked for.
        path: PathBuf,
    },
}

/// What `evaluate` reads from its labels file: the labels at the ranks to
/// evaluate, and the specimens' groups at the grouping rank.
#[derive(Debug, Clone)]
pub struct EvaluationLabels {
    /// The labels at the ranks evaluated by leave-one-out.
    pub labels: Labels,
    /// The specimens' taxa at the grouping rank, when one was asked for.
    pub groups: Option<Groups>,
}

/// The labels of `path` for the specimens `names` of a matrix: at `ranks`
/// (default: every rank column) for leave-one-out, and grouped at
/// `group_rank` (any rank column of the file). Every specimen must have a
/// row. The file is read once.
pub fn evaluation_labels(
    path: &Path,
    names: &[String],
    ranks: Option<&[String]>,
    group_rank: Option<&str>,
) -> Result<EvaluationLabels, LabelsError> {
    let text = std::fs::read_to_string(path).map_err(|source| TableError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let all = Labels::parse(&text, None, path)?;
    let missing = all.unlabelled(names);
    if !missing.is_empty() {
        return Err(LabelsError::Unlabelled {
            path: path.to_path_buf(),
            count: missing.len(),
            names: missing.join(", "),
        });
    }
    let groups = group_rank
        .map(|rank| groups_at(&all, path, names, rank))
        .transpose()?;
    let labels = match ranks {
        Some(ranks) => Labels::parse(&text, Some(ranks), path)?,
        None => all,
    };
    Ok(EvaluationLabels { labels, groups })
}

/// The groups of the specimens `names` of a folder, from its
/// `labels.csv`: at `rank`, or at the file's first rank column. No labels
/// file: no groups, unless a rank was asked for (an error).
pub fn folder_groups(
    folder: &Path,
    names: &[String],
    rank: Option<&str>,
) -> Result<Option<Groups>, LabelsError> {
    let path = folder.join("labels.csv");
    if !path.is_file() {
        return match rank {
            Some(rank) => Err(LabelsError::NoLabelsFile {
                rank: rank.to_string(),
                path,
            }),
            None => Ok(None),
        };
    }
    let labels = Labels::read(&path, None)?;
    match rank {
        Some(rank) => groups_at(&labels, &path, names, rank).map(Some),
        None => Ok(labels
            .ranks()
            .first()
            .and_then(|rank| groups_at(&labels, &path, names, rank).ok())),
    }
}

/// The taxa of `names` at `rank` of `labels` (read from `path`).
fn groups_at(
    labels: &Labels,
    path: &Path,
    names: &[String],
    rank: &str,
) -> Result<Groups, LabelsError> {
    labels
        .column(names, rank)
        .map(|column| (rank.to_string(), column))
        .ok_or_else(|| LabelsError::NoRank {
            path: path.to_path_buf(),
            rank: rank.to_string(),
            ranks: labels.ranks().join(", "),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn the_file_gives_the_ranks_and_the_groups_or_names_what_is_missing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("labels.csv");
        std::fs::write(&path, "name,family,genus\na,F,G1\nb,F,G2\nc,H,NA\n").unwrap();
        let genus = [String::from("genus")];
        let e =
            evaluation_labels(&path, &names(&["a", "c"]), Some(&genus), Some("family")).unwrap();
        assert_eq!(e.labels.ranks(), &genus[..]);
        let (rank, groups) = e.groups.unwrap();
        assert_eq!(rank, "family");
        assert_eq!(groups, vec![Some("F".into()), Some("H".into())]);
        let err = evaluation_labels(&path, &names(&["a"]), None, Some("tribe")).unwrap_err();
        assert!(
            err.to_string()
                .ends_with("no rank column `tribe` (ranks: family, genus)"),
            "{err}"
        );
        let err = evaluation_labels(&path, &names(&["a", "x"]), None, None).unwrap_err();
        assert!(
            err.to_string().contains("1 specimen(s) of the matrix: x"),
            "{err}"
        );
        // A folder: the first rank by default; a rank it lacks is an error.
        let (rank, _) = folder_groups(dir.path(), &names(&["b"]), None)
            .unwrap()
            .unwrap();
        assert_eq!(rank, "family");
        assert!(folder_groups(dir.path(), &names(&["b"]), Some("tribe")).is_err());
        let empty = tempfile::tempdir().unwrap();
        assert!(folder_groups(empty.path(), &names(&["b"]), None)
            .unwrap()
            .is_none());
        let err = folder_groups(empty.path(), &names(&["b"]), Some("genus")).unwrap_err();
        assert!(err.to_string().starts_with("--rank genus: "), "{err}");
    }
}
