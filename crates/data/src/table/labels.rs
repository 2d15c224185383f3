//! Taxonomic labels of a library (`labels.csv`).

use super::csv_text::{format_error, header_and_rows, trimmed, CsvString, Row, TableError};
use std::collections::HashMap;
use std::path::Path;

/// Labels: for each specimen name, a value (or unknown) at each rank.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Labels {
    /// Rank names, in the order asked for (default: file order).
    ranks: Vec<String>,
    /// Specimen names, in file order.
    names: Vec<String>,
    /// `values[i][r]`: value of specimen `i` at rank `r`; `None` = unknown.
    values: Vec<Vec<Option<String>>>,
    /// Row of each name.
    index: HashMap<String, usize>,
}

impl Labels {
    /// Parse labels CSV text: a `name` column plus rank columns. `ranks`
    /// selects the rank columns (default: every column but `name`). `NA`
    /// or an empty field means unknown. `path` is only used in errors.
    pub fn parse(text: &str, ranks: Option<&[String]>, path: &Path) -> Result<Self, TableError> {
        let err = |line: usize, message: String| format_error(path, line, message);
        let (header, rows) = header_and_rows(text, path)?;
        let header_line = header.line;
        let header: Vec<String> = header
            .fields
            .iter()
            .map(|h| trimmed(h).to_string())
            .collect();
        let name_col = header
            .iter()
            .position(|h| h == "name")
            .ok_or_else(|| err(header_line, "no `name` column".into()))?;
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
                    .ok_or_else(|| err(header_line, format!("no column `{r}`")))?,
            );
        }
        let mut out = Labels {
            ranks: rank_names,
            ..Default::default()
        };
        for r in rows {
            let Row { line, fields: f } = r?;
            if f.len() != header.len() {
                return Err(err(
                    line,
                    format!("{} fields, the header has {}", f.len(), header.len()),
                ));
            }
            let name = trimmed(&f[name_col]).to_string();
            if name.is_empty() {
                return Err(err(line, "empty name".into()));
            }
            if out.index.contains_key(&name) {
                return Err(err(line, format!("duplicate name `{name}`")));
            }
            let vals = cols
                .iter()
                .map(|&c| {
                    let v = trimmed(&f[c]);
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
    pub fn read(path: &Path, ranks: Option<&[String]>) -> Result<Self, TableError> {
        let text = std::fs::read_to_string(path).map_err(|source| TableError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, ranks, path)
    }

    /// The CSV text: `name` and the ranks, then one row per specimen,
    /// `NA` for unknown values.
    pub fn to_csv(&self) -> String {
        let mut w = CsvString::new();
        w.record(std::iter::once("name").chain(self.ranks.iter().map(String::as_str)));
        for (name, values) in self.names.iter().zip(&self.values) {
            w.record(
                std::iter::once(name.as_str())
                    .chain(values.iter().map(|v| v.as_deref().unwrap_or("NA"))),
            );
        }
        w.finish()
    }

    /// The rank columns, in the order asked for (default: file order).
    pub fn ranks(&self) -> &[String] {
        &self.ranks
    }

    /// The specimen names, in file order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Whether `name` has a row.
    pub fn contains(&self, name: &str) -> bool {
        self.index.contains_key(name)
    }

    /// The names among `names` that have no row.
    pub fn unlabelled<'a>(&self, names: &'a [String]) -> Vec<&'a str> {
        names
            .iter()
            .filter(|n| !self.index.contains_key(*n))
            .map(String::as_str)
            .collect()
    }

    /// The values of `names` at `rank` (`None` for unknown or absent
    /// specimens); `None` when `rank` is not one of the ranks.
    pub fn column(&self, names: &[String], rank: &str) -> Option<Vec<Option<String>>> {
        self.ranks.iter().any(|r| r == rank).then(|| {
            names
                .iter()
                .map(|n| self.get(n, rank).map(str::to_string))
                .collect()
        })
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
        let names = ["C", "X", "A"].map(String::from);
        assert_eq!(l.unlabelled(&names), ["X"]);
        assert_eq!(
            l.column(&names, "genus"),
            Some(vec![None, None, Some("G1".to_string())])
        );
        assert_eq!(l.column(&names, "family"), None);
        let only = vec!["genus".to_string()];
        let l = Labels::parse(text, Some(&only), Path::new("l.csv")).unwrap();
        assert_eq!(l.ranks, vec!["genus"]);
        assert_eq!(l.get("A", "order"), None);
    }

    #[test]
    fn any_name_round_trips() {
        let text =
            "name,order,genus\n\"a,b\",P,G\n\"q\"\"x\",P,NA\n\"new\nline\",Q,G2\nplain,Q,G2\n";
        let l = Labels::parse(text, None, Path::new("l.csv")).unwrap();
        assert_eq!(l.names, ["a,b", "q\"x", "new\nline", "plain"]);
        assert_eq!(l.get("new\nline", "genus"), Some("G2"));
        assert_eq!(l.to_csv(), text);
        assert_eq!(
            Labels::parse(&l.to_csv(), None, Path::new("l.csv")).unwrap(),
            l
        );
        let e = Labels::parse("name,a\n\"x\ny\",1\nz\n", None, Path::new("l.csv")).unwrap_err();
        assert!(e.to_string().starts_with("l.csv:4:"), "{e}");
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
