//! Distance matrices: computation over prepared surfaces and CSV files.

use super::csv_text::{format_error, header_and_rows, trimmed, CsvString, Row, TableError};
use morphoid_core::cp::{compare, CompareParams, Prepared};
use rayon::prelude::*;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A square matrix of distances between named specimens.
#[derive(Debug, Clone, PartialEq)]
pub struct DistanceMatrix {
    /// Specimen names (row and column order).
    names: Vec<String>,
    /// `values[i][j]`: distance between specimens `i` and `j`; one row of
    /// `names.len()` values per name.
    values: Vec<Vec<f64>>,
}

/// A matrix whose rows do not match its names.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("a distance matrix of {names} names has {rows} rows; row {row} has {len} values")]
pub struct MatrixShapeError {
    /// Number of names.
    pub names: usize,
    /// Number of rows.
    pub rows: usize,
    /// The first row of the wrong length (or `rows` when the row count is wrong).
    pub row: usize,
    /// Its length (0 when the row count is wrong).
    pub len: usize,
}

impl DistanceMatrix {
    /// The matrix of `values[i][j]` between `names[i]` and `names[j]`;
    /// fails unless there is one row of `names.len()` values per name.
    pub fn new(names: Vec<String>, values: Vec<Vec<f64>>) -> Result<Self, MatrixShapeError> {
        let n = names.len();
        let bad = |row: usize, len: usize| MatrixShapeError {
            names: n,
            rows: values.len(),
            row,
            len,
        };
        if values.len() != n {
            return Err(bad(values.len(), 0));
        }
        if let Some((row, r)) = values.iter().enumerate().find(|(_, r)| r.len() != n) {
            return Err(bad(row, r.len()));
        }
        Ok(Self { names, values })
    }

    /// A matrix built in this crate with one row of `names.len()` values
    /// per name by construction (checked in debug builds).
    pub fn square(names: Vec<String>, values: Vec<Vec<f64>>) -> Self {
        debug_assert!(
            values.len() == names.len() && values.iter().all(|r| r.len() == names.len()),
            "a distance matrix must be square"
        );
        Self { names, values }
    }

    /// The names and the rows, taken apart.
    pub fn into_parts(self) -> (Vec<String>, Vec<Vec<f64>>) {
        (self.names, self.values)
    }

    /// Specimen names (row and column order).
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The rows: `values()[i][j]` is the distance between specimens `i` and `j`.
    pub fn values(&self) -> &[Vec<f64>] {
        &self.values
    }

    /// Number of specimens.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether the matrix has no specimen.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Distance between specimens `i` and `j` (NaN when out of range).
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.values
            .get(i)
            .and_then(|r| r.get(j))
            .copied()
            .unwrap_or(f64::NAN)
    }

    /// The CSV text: header `name,<name1>,…`, then one row per specimen;
    /// each value in the shortest form that reads back exactly.
    pub fn to_csv(&self) -> String {
        let mut w = CsvString::new();
        w.record(std::iter::once("name").chain(self.names.iter().map(String::as_str)));
        for (n, row) in self.names.iter().zip(&self.values) {
            w.record(std::iter::once(n.clone()).chain(row.iter().map(|v| format!("{v:?}"))));
        }
        w.finish()
    }

    /// Parse CSV text (`path` is only used in errors). Rows must follow the
    /// header's order of names.
    pub fn parse_csv(text: &str, path: &Path) -> Result<Self, TableError> {
        let err = |line: usize, message: String| format_error(path, line, message);
        let (header, rows) = header_and_rows(text, path)?;
        if header.fields.first().map(|h| trimmed(h)) != Some("name") {
            return Err(err(header.line, "the header must start with `name`".into()));
        }
        let names: Vec<String> = header.fields[1..]
            .iter()
            .map(|h| trimmed(h).to_string())
            .collect();
        let mut values = Vec::with_capacity(names.len());
        for r in rows {
            let Row { line, fields: f } = r?;
            let row = values.len();
            if row >= names.len() {
                return Err(err(line, "more rows than columns".into()));
            }
            if f.len() != names.len() + 1 {
                return Err(err(
                    line,
                    format!("{} fields, expected {}", f.len(), names.len() + 1),
                ));
            }
            if trimmed(&f[0]) != names[row] {
                return Err(err(
                    line,
                    format!(
                        "row `{}` where `{}` was expected",
                        trimmed(&f[0]),
                        names[row]
                    ),
                ));
            }
            let mut r = Vec::with_capacity(names.len());
            for (k, v) in f[1..].iter().enumerate() {
                let x: f64 = v.trim().parse().map_err(|_| {
                    err(
                        line,
                        format!("column {}: `{}` is not a number", k + 2, v.trim()),
                    )
                })?;
                if !x.is_finite() {
                    return Err(err(line, format!("column {}: not finite", k + 2)));
                }
                r.push(x);
            }
            values.push(r);
        }
        if values.len() != names.len() {
            return Err(err(
                text.lines().count(),
                format!("{} rows for {} columns", values.len(), names.len()),
            ));
        }
        Ok(Self { names, values })
    }

    /// Read a matrix CSV file.
    pub fn read_csv(path: &Path) -> Result<Self, TableError> {
        let text = std::fs::read_to_string(path).map_err(|source| TableError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse_csv(&text, path)
    }

    /// Write a matrix CSV file.
    pub fn write_csv(&self, path: &Path) -> Result<(), TableError> {
        Ok(crate::atomic_write::write_atomic(
            path,
            self.to_csv().as_bytes(),
        )?)
    }
}

/// The symmetric matrix of cP distances between all pairs of prepared
/// surfaces (zero diagonal), computed in parallel; `progress` receives the
/// number of pairs done so far. The values do not depend on the number of
/// threads.
pub fn distance_matrix(
    prepared: &[Prepared],
    params: &CompareParams,
    progress: impl Fn(usize) + Sync,
) -> DistanceMatrix {
    let names = prepared.iter().map(|p| p.name().to_string()).collect();
    pairwise_matrix(
        names,
        |i, j| Ok(compare(&prepared[i], &prepared[j], params).distance),
        progress,
    )
    .unwrap_or_else(|never: std::convert::Infallible| match never {})
}

/// The symmetric matrix (zero diagonal) of `distance(i, j)` over all pairs
/// `i < j` of the `names`, pairs in parallel; `progress` receives the number
/// of pairs done so far. The first error stops it. The values do not depend
/// on the number of threads.
pub fn pairwise_matrix<E: Send>(
    names: Vec<String>,
    distance: impl Fn(usize, usize) -> Result<f64, E> + Sync,
    progress: impl Fn(usize) + Sync,
) -> Result<DistanceMatrix, E> {
    let n = names.len();
    let pairs: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .collect();
    let done = AtomicUsize::new(0);
    let d: Vec<f64> = pairs
        .par_iter()
        .map(|&(i, j)| {
            let v = distance(i, j)?;
            progress(done.fetch_add(1, Ordering::Relaxed) + 1);
            Ok(v)
        })
        .collect::<Result<_, E>>()?;
    let mut values = vec![vec![0.0; n]; n];
    for (&(i, j), &v) in pairs.iter().zip(&d) {
        values[i][j] = v;
        values[j][i] = v;
    }
    Ok(DistanceMatrix { names, values })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> DistanceMatrix {
        DistanceMatrix {
            names: vec![
                "a".into(),
                "b,c".into(),
                "q\"uote".into(),
                "new\nline".into(),
            ],
            values: vec![
                vec![0.0, 0.1234567890123, 1.0, 2.5],
                vec![0.1234567890123, 0.0, 1e-300, 0.1 + 0.2],
                vec![1.0, 1e-300, 0.0, 3.0],
                vec![2.5, 0.1 + 0.2, 3.0, 0.0],
            ],
        }
    }

    #[test]
    fn csv_round_trip_is_exact() {
        let m = sample();
        let text = m.to_csv();
        assert!(text.starts_with("name,a,\"b,c\",\"q\"\"uote\",\"new\nline\"\n"));
        assert!(text.contains("\na,0.0,0.1234567890123,1.0,2.5\n"), "{text}");
        assert_eq!(
            DistanceMatrix::parse_csv(&text, Path::new("m.csv")).unwrap(),
            m
        );
    }

    #[test]
    fn malformed_csv_names_file_and_line() {
        let p = Path::new("m.csv");
        let e = DistanceMatrix::parse_csv("name,a,b\na,0,1\nb,1,x\n", p).unwrap_err();
        assert!(e.to_string().starts_with("m.csv:3:"), "{e}");
        let e = DistanceMatrix::parse_csv("name,a,b\na,0,1\n", p).unwrap_err();
        assert!(e.to_string().contains("1 rows"), "{e}");
        let e = DistanceMatrix::parse_csv("name,a,b\nb,0,1\na,1,0\n", p).unwrap_err();
        assert!(e.to_string().starts_with("m.csv:2:"), "{e}");
        assert!(DistanceMatrix::parse_csv("id,a\n", p).is_err());
    }
}
