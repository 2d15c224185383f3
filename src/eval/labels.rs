//! Taxonomic labels of a library (`labels.csv`).

use super::split_csv_line;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Why a labels file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum LabelsError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The content is malformed.
    #[error("{path}:{line}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
}

/// Labels: for each specimen name, a value (or unknown) at each rank.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Labels {
    /// Rank names, in file order.
    pub ranks: Vec<String>,
    /// Specimen names, in file order.
    pub names: Vec<String>,
    /// `values[i][r]`: value of specimen `i` at rank `r`; `None` = unknown.
    pub values: Vec<Vec<Option<String>>>,
    index: HashMap<String, usize>,
}

impl Labels {
    /// Parse labels CSV text: a `name` column plus rank columns. `ranks`
    /// selects the rank columns (default: every column but `name`). `NA`
    /// or an empty field means unknown. `path` is only used in errors.
    pub fn parse(text: &str, ranks: Option<&[String]>, path: &Path) -> Result<Self, LabelsError> {
        let err = |line: usize, message: String| LabelsError::Format {
            path: path.to_path_buf(),
            line,
            message,
        };
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty());
        let (_, head) = lines.next().ok_or_else(|| err(1, "empty file".into()))?;
        let header = split_csv_line(head).map_err(|m| err(1, m.into()))?;
        let header: Vec<String> = header.iter().map(|h| h.trim().to_string()).collect();
        let name_col = header
            .iter()
            .position(|h| h == "name")
            .ok_or_else(|| err(1, "no `name` column".into()))?;
        let rank_names: Vec<String> = match ranks {
            Some(r) => r.to_vec(),
            None => header.iter().filter(|h| *h != "name").cloned().collect(),
        };
        let mut cols = Vec::with_capacity(rank_names.len());
        for r in &rank_names {
            cols.push(
                header
                    .iter()
                    .position(|h| h == r)
                    .ok_or_else(|| err(1, format!("no column `{r}`")))?,
            );
        }
        let mut out = Labels {
            ranks: rank_names,
            ..Default::default()
        };
        for (i, line) in lines {
            let f = split_csv_line(line).map_err(|m| err(i + 1, m.into()))?;
            if f.len() != header.len() {
                return Err(err(
                    i + 1,
                    format!("{} fields, the header has {}", f.len(), header.len()),
                ));
            }
            let name = f[name_col].trim().to_string();
            if name.is_empty() {
                return Err(err(i + 1, "empty name".into()));
            }
            if out.index.contains_key(&name) {
                return Err(err(i + 1, format!("duplicate name `{name}`")));
            }
            let vals = cols
                .iter()
                .map(|&c| {
                    let v = f[c].trim();
                    (!v.is_empty() && v != "NA").then(|| v.to_string())
                })
                .collect();
            out.index.insert(name.clone(), out.names.len());
            out.names.push(name);
            out.values.push(vals);
        }
        Ok(out)
    }

    /// Read and parse a labels file.
    pub fn read(path: &Path, ranks: Option<&[String]>) -> Result<Self, LabelsError> {
        let text = std::fs::read_to_string(path).map_err(|source| LabelsError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, ranks, path)
    }

    /// Value of specimen `name` at rank `rank` (`None`: unknown or absent).
    pub fn get(&self, name: &str, rank: &str) -> Option<&str> {
        let i = *self.index.get(name)?;
        let r = self.ranks.iter().position(|x| x == rank)?;
        self.values.get(i)?.get(r)?.as_deref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_unknowns_quotes_and_rank_selection() {
        let text = "name,order,genus,note\nA,P,G1,\"x, y\"\nB,P,NA,z\nC,Q,,w\n";
        let l = Labels::parse(text, None, Path::new("l.csv")).unwrap();
        assert_eq!(l.ranks, vec!["order", "genus", "note"]);
        assert_eq!(l.get("A", "note"), Some("x, y"));
        assert_eq!(l.get("B", "genus"), None);
        assert_eq!(l.get("C", "genus"), None);
        assert_eq!(l.get("C", "order"), Some("Q"));
        let only = vec!["genus".to_string()];
        let l = Labels::parse(text, Some(&only), Path::new("l.csv")).unwrap();
        assert_eq!(l.ranks, vec!["genus"]);
        assert_eq!(l.get("A", "order"), None);
    }

    #[test]
    fn errors_name_file_and_line() {
        let e = Labels::parse("name,a\nX,1\nY,2,3\n", None, Path::new("lab.csv")).unwrap_err();
        assert!(e.to_string().starts_with("lab.csv:3:"), "{e}");
        let e = Labels::parse("id,a\n", None, Path::new("lab.csv")).unwrap_err();
        assert!(e.to_string().contains("name"));
        let only = vec!["genus".to_string()];
        assert!(Labels::parse("name,a\n", Some(&only), Path::new("l")).is_err());
    }
}
