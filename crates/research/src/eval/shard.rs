//! Sharded distance matrices for cluster job arrays. The pairs `(i, j)`,
//! `i < j`, of a library's specimen list are taken in row-major order and
//! cut into `N` contiguous, nearly equal parts; shard `K` (1-based)
//! computes part `K` and prepares only the specimens its pairs involve. A
//! shard file is self-describing CSV:
//!
//! ```text
//! # morphoid matrix shard 2/3
//! # content: 9f2c…,,51ab…,07de…
//! # names: a,b,c,d
//! a,b,distance,forward,backward
//! a,d,0.0312,0.0312,0.0340
//! …
//! ```
//!
//! `# content:` holds, for each name, the content hash of the surface the
//! shard compared (empty for specimens its pairs do not involve), so that
//! shards of a library whose files changed between tasks are never mixed.
//! [`merge_shards`] checks that the files belong together (same name list,
//! same content for every specimen, same `N`, every `K` once, every pair
//! once), that every value is a distance, and assembles the matrix the
//! unsharded computation writes.

use morphoid_core::cp::{compare, CompareParams, Prepared};
use morphoid_data::atomic_write::{write_atomic, AtomicWriteError};
pub use morphoid_data::shard::Shard;
use morphoid_data::table::csv_text::{rows, trimmed, CsvString, Row, RowError};
use morphoid_data::table::DistanceMatrix;
use rayon::prelude::*;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Number of unordered pairs of `n` specimens.
pub fn pair_count(n: usize) -> usize {
    n * n.saturating_sub(1) / 2
}

/// The pairs `(i, j)`, `i < j`, of `shard`, in row-major order.
pub fn shard_pairs(n: usize, shard: Shard) -> Vec<(usize, usize)> {
    let range = shard.range(pair_count(n));
    if range.is_empty() {
        return Vec::new();
    }
    // Row i starts at position i·n − i(i+1)/2; find the row of `start`.
    let row_start = |i: usize| i * n - i * (i + 1) / 2;
    let mut i = 0;
    while i + 1 < n && row_start(i + 1) <= range.start {
        i += 1;
    }
    let mut j = i + 1 + (range.start - row_start(i));
    let mut out = Vec::with_capacity(range.len());
    while out.len() < range.len() && i + 1 < n {
        out.push((i, j));
        j += 1;
        if j == n {
            i += 1;
            j = i + 1;
        }
    }
    out
}

/// The specimens (sorted, unique) that a list of pairs involves.
pub fn pair_specimens(pairs: &[(usize, usize)]) -> Vec<usize> {
    let mut s: Vec<usize> = pairs.iter().flat_map(|&(i, j)| [i, j]).collect();
    s.sort_unstable();
    s.dedup();
    s
}

/// The cP distances of one pair, both directions kept.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairDistance {
    /// Index of the first specimen in the name list.
    pub a: usize,
    /// Index of the second specimen (`a < b`).
    pub b: usize,
    /// `min(forward, backward)`: the matrix entry.
    pub distance: f64,
    /// `d(a, b)`.
    pub forward: f64,
    /// `d(b, a)`.
    pub backward: f64,
}

/// The content of one shard file.
#[derive(Debug, Clone, PartialEq)]
pub struct ShardFile {
    /// Which shard this is.
    pub shard: Shard,
    /// The full specimen list of the library, in matrix order.
    pub names: Vec<String>,
    /// Per name, the content hash of the surface file this shard compared
    /// (`None` for specimens its pairs do not involve).
    pub content: Vec<Option<String>>,
    /// The distances of the shard's pairs.
    pub pairs: Vec<PairDistance>,
}

/// Why a shard could not be computed, read or merged; messages name the
/// file.
#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A shard file is malformed.
    #[error("{}:{line}: {message}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A record of a shard file that the CSV reader cannot read.
    #[error("{}:{line}: {source}", path.display())]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line of the record.
        line: usize,
        /// The reader's error.
        source: RowError,
    },
    /// The first two lines of a shard file do not name the shard and the
    /// content hashes.
    #[error("{}:{line}: {source}", path.display())]
    Header {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong with the line.
        source: ShardHeaderError,
    },
    /// A shard file could not be written (it names the file and the step).
    #[error(transparent)]
    Write(#[from] AtomicWriteError),
    /// Shards that do not belong together, or an incomplete set.
    #[error("{0}")]
    Mismatch(String),
    /// No shard files were given.
    #[error("no shard files to merge")]
    NoShards,
}

/// Why a shard file's first line (`# morphoid matrix shard K/N`) or
/// second line (`# content: …`) cannot be read.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub enum ShardHeaderError {
    /// The first line is not a shard file's.
    #[error("not a morphoid matrix shard")]
    NotAShard,
    /// The first line's shard is not `K/N` with `1 ≤ K ≤ N`.
    #[error(transparent)]
    Shard(#[from] morphoid_data::shard::ShardSyntax),
    /// The second line is not `# content: …`.
    #[error("expected `# content: …` (a shard of an older morphoid: compute it again)")]
    NoContentLine,
}

impl ShardFile {
    /// The file text: three comment lines (`# morphoid matrix shard K/N`,
    /// `# content: …`, `# names: …`), the header
    /// `a,b,distance,forward,backward`, one line per pair.
    fn to_text(&self) -> String {
        let content: Vec<&str> = (0..self.names.len())
            .map(|k| self.content.get(k).and_then(Option::as_deref).unwrap_or(""))
            .collect();
        let mut w = CsvString::new();
        w.record(&self.names);
        w.record(["a", "b", "distance", "forward", "backward"]);
        let name = |k: usize| self.names.get(k).map_or("", String::as_str);
        for p in &self.pairs {
            // `{:?}` is the shortest text that reads back exactly.
            w.record([
                name(p.a),
                name(p.b),
                &format!("{:?}", p.distance),
                &format!("{:?}", p.forward),
                &format!("{:?}", p.backward),
            ]);
        }
        // Hashes are hex: one plain line, before the names (a quoted name
        // may span lines).
        format!(
            "# morphoid matrix shard {}\n# content: {}\n# names: {}",
            self.shard,
            content.join(","),
            w.finish()
        )
    }

    /// Parse shard text (`path` only names the file in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self, ShardError> {
        let err = |line: usize, message: String| format_error(path, line, message);
        let (first, rest) = text.split_once('\n').unwrap_or((text, ""));
        if first.is_empty() && rest.is_empty() {
            return Err(err(1, "empty file".into()));
        }
        let header = |line: usize| {
            move |source| ShardError::Header {
                path: path.to_path_buf(),
                line,
                source,
            }
        };
        let shard = parse_shard_line(first).map_err(header(1))?;
        let (second, rest) = rest.split_once('\n').unwrap_or((rest, ""));
        let content = parse_content_line(second).map_err(header(2))?;
        // The name list is a CSV record after the prefix (a quoted name
        // may hold a line break); the lines of `rest` start at line 3.
        let rest = rest
            .strip_prefix("# names:")
            .ok_or_else(|| err(3, "expected `# names: …`".into()))?;
        let rest = rest.strip_prefix(' ').unwrap_or(rest);
        // An empty name list leaves no record on the names line.
        let names_empty = rest.starts_with(['\n', '\r']);
        let mut rows = rows(rest, false).map(|r| {
            r.map_err(|source| ShardError::Csv {
                path: path.to_path_buf(),
                line: file_line(source.line),
                source,
            })
        });
        let names: Vec<String> = if names_empty {
            Vec::new()
        } else {
            match rows.next() {
                Some(r) => r?.fields.into_iter().filter(|n| !n.is_empty()).collect(),
                None => Vec::new(),
            }
        };
        let index = name_index(&names).ok_or_else(|| err(3, "a name occurs twice".into()))?;
        // An empty content line splits into one empty field.
        let content = if names.is_empty() {
            Vec::new()
        } else {
            content
        };
        if content.len() != names.len() {
            return Err(err(
                2,
                format!("{} content hashes for {} names", content.len(), names.len()),
            ));
        }
        check_pair_header(rows.next().transpose()?)
            .map_err(|line| err(line, "expected `a,b,distance,forward,backward`".into()))?;
        let pairs = rows
            .map(|r| pair_of_row(r?, &index, path))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(ShardFile {
            shard,
            names,
            content,
            pairs,
        })
    }

    /// Read a shard file.
    pub fn read(path: &Path) -> Result<Self, ShardError> {
        let text = std::fs::read_to_string(path).map_err(|source| ShardError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Write a shard file, whole or not at all: a task killed while
    /// writing leaves no truncated shard to merge.
    pub fn write(&self, path: &Path) -> Result<(), ShardError> {
        Ok(write_atomic(path, self.to_text().as_bytes())?)
    }
}

/// Compute shard `shard` of the matrix of `names`: `prepare(k)` (the
/// prepared surface of specimen `k` and the content hash of its file) is
/// called in parallel only for the specimens the shard's pairs involve,
/// then the pairs are compared in parallel exactly as
/// [`super::distance_matrix`] compares them; `progress` receives the
/// number of pairs done.
pub fn compute_shard<E: Send>(
    names: &[String],
    shard: Shard,
    prepare: impl Fn(usize) -> Result<(Prepared, String), E> + Sync,
    params: &CompareParams,
    progress: impl Fn(usize) + Sync,
) -> Result<ShardFile, E> {
    let pairs = shard_pairs(names.len(), shard);
    let needed = pair_specimens(&pairs);
    let (prepared, hashes): (Vec<Prepared>, Vec<String>) = needed
        .par_iter()
        .map(|&k| prepare(k))
        .collect::<Result<Vec<_>, E>>()?
        .into_iter()
        .unzip();
    let mut content = vec![None; names.len()];
    for (&k, hash) in needed.iter().zip(hashes) {
        if let Some(slot) = content.get_mut(k) {
            *slot = Some(hash);
        }
    }
    let slot: HashMap<usize, usize> = needed.iter().enumerate().map(|(s, &k)| (k, s)).collect();
    let done = AtomicUsize::new(0);
    let distances: Vec<PairDistance> = pairs
        .par_iter()
        .filter_map(|&(a, b)| {
            let (sa, sb) = (slot.get(&a)?, slot.get(&b)?);
            let c = compare(prepared.get(*sa)?, prepared.get(*sb)?, params);
            progress(done.fetch_add(1, Ordering::Relaxed) + 1);
            Some(PairDistance {
                a,
                b,
                distance: c.distance,
                forward: c.forward.distance,
                backward: c.backward.distance,
            })
        })
        .collect();
    Ok(ShardFile {
        shard,
        names: names.to_vec(),
        content,
        pairs: distances,
    })
}

/// Merge shard files (each with the path it came from) into the full
/// symmetric matrix with zero diagonal. Errors name the files: a different
/// name list or shard count, specimens whose content differs between
/// shards, a shard given twice or missing, a pair outside its shard's
/// range, missing or given twice, a value that is not a distance.
pub fn merge_shards(shards: &[(PathBuf, ShardFile)]) -> Result<DistanceMatrix, ShardError> {
    let (first_path, first) = shards.first().ok_or(ShardError::NoShards)?;
    let by_index = shards_by_index(shards, first_path, first)?;
    check_same_content(shards)?;
    check_none_missing(&by_index, shards)?;
    let n = first.names.len();
    let mut values = vec![vec![0.0; n]; n];
    let mut seen = vec![false; pair_count(n)];
    for (path, s) in shards {
        enter_pairs(path, s, &first.names, &mut values, &mut seen)?;
        check_shard_complete(path, s, &first.names, &seen)?;
    }
    Ok(DistanceMatrix::square(first.names.clone(), values))
}

/// Each shard index's file (`None` for shards not given), once every
/// shard has been checked against the first (`first_path`, `first`): the
/// same name list and shard count, and no index given twice.
fn shards_by_index<'a>(
    shards: &'a [(PathBuf, ShardFile)],
    first_path: &Path,
    first: &ShardFile,
) -> Result<Vec<Option<&'a Path>>, ShardError> {
    let count = first.shard.count;
    let mut by_index: Vec<Option<&Path>> = vec![None; count];
    for (path, s) in shards {
        if s.names != first.names {
            return Err(ShardError::Mismatch(format!(
                "{}: its name list differs from that of {} (shards of different libraries?)",
                path.display(),
                first_path.display()
            )));
        }
        if s.shard.count != count {
            return Err(ShardError::Mismatch(format!(
                "{}: shard {} but {} is shard {}",
                path.display(),
                s.shard,
                first_path.display(),
                first.shard
            )));
        }
        let slot = by_index
            .get_mut(s.shard.index.wrapping_sub(1))
            .ok_or_else(|| ShardError::Mismatch(format!("{}: bad shard", path.display())))?;
        if let Some(other) = slot {
            return Err(ShardError::Mismatch(format!(
                "shard {} given twice: {} and {}",
                s.shard,
                other.display(),
                path.display()
            )));
        }
        *slot = Some(path);
    }
    Ok(by_index)
}

/// An error naming the shards of `by_index` (one slot per shard of the
/// set) that none of `shards` is, if any.
fn check_none_missing(
    by_index: &[Option<&Path>],
    shards: &[(PathBuf, ShardFile)],
) -> Result<(), ShardError> {
    let count = by_index.len();
    let missing: Vec<String> = by_index
        .iter()
        .enumerate()
        .filter(|(_, p)| p.is_none())
        .map(|(k, _)| format!("{}/{count}", k + 1))
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    Err(ShardError::Mismatch(format!(
        "missing shard(s) {} of the {count} (given: {})",
        missing.join(", "),
        shards
            .iter()
            .map(|(p, _)| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    )))
}

/// The position of the pair `(a, b)`, `a < b`, among the pairs of `n`
/// specimens in row-major order (row `a` starts at `a·n − a(a+1)/2`).
fn pair_position(n: usize, a: usize, b: usize) -> usize {
    a * n - a * (a + 1) / 2 + (b - a - 1)
}

/// Enter the pairs of shard `s` (from `path`) into `values` (both
/// triangles) and mark them in `seen` (by [`pair_position`]); an error for
/// a pair that is not one of the specimens `names`, lies outside the
/// shard's range, is not a distance, or was seen before.
fn enter_pairs(
    path: &Path,
    s: &ShardFile,
    names: &[String],
    values: &mut [Vec<f64>],
    seen: &mut [bool],
) -> Result<(), ShardError> {
    let n = names.len();
    let range = s.shard.range(pair_count(n));
    let mismatch = |problem: String| ShardError::Mismatch(format!("{}: {problem}", path.display()));
    for p in &s.pairs {
        if p.a >= p.b || p.b >= n {
            return Err(mismatch(format!(
                "pair ({}, {}) is not a pair of the {n} specimens",
                p.a, p.b
            )));
        }
        let (a, b) = (&names[p.a], &names[p.b]);
        let pos = pair_position(n, p.a, p.b);
        if !range.contains(&pos) {
            return Err(mismatch(format!(
                "pair {a},{b} does not belong to shard {}",
                s.shard
            )));
        }
        if let Some(problem) = not_a_distance(p) {
            return Err(mismatch(format!("pair {a},{b}: {problem}")));
        }
        if std::mem::replace(&mut seen[pos], true) {
            return Err(mismatch(format!("pair {a},{b} occurs twice")));
        }
        values[p.a][p.b] = p.distance;
        values[p.b][p.a] = p.distance;
    }
    Ok(())
}

/// An error naming shard `s` (from `path`) when `seen` lacks any pair of
/// its range, with the first such pair of `names`.
fn check_shard_complete(
    path: &Path,
    s: &ShardFile,
    names: &[String],
    seen: &[bool],
) -> Result<(), ShardError> {
    let n = names.len();
    let range = s.shard.range(pair_count(n));
    let present = seen[range.clone()].iter().filter(|&&x| x).count();
    if present == range.len() {
        return Ok(());
    }
    let absent = shard_pairs(n, s.shard)
        .into_iter()
        .find(|&(a, b)| !seen[pair_position(n, a, b)]);
    Err(ShardError::Mismatch(format!(
        "{}: shard {} lacks {} of its {} pairs (e.g. {})",
        path.display(),
        s.shard,
        range.len() - present,
        range.len(),
        absent.map_or(String::new(), |(a, b)| format!("{},{}", names[a], names[b]))
    )))
}

/// What is wrong with the values of a pair, if anything: each must be
/// finite and non-negative, and the matrix entry the smaller direction.
fn not_a_distance(p: &PairDistance) -> Option<String> {
    let values = [
        ("distance", p.distance),
        ("forward", p.forward),
        ("backward", p.backward),
    ];
    if let Some((what, x)) = values.iter().find(|(_, x)| !x.is_finite() || *x < 0.0) {
        return Some(format!("{what} {x:?} is not a distance (finite, ≥ 0)"));
    }
    // Written with `{:?}`, the values read back exactly: compare exactly.
    let min = p.forward.min(p.backward);
    (p.distance != min).then(|| {
        format!(
            "distance {:?} is not min(forward {:?}, backward {:?})",
            p.distance, p.forward, p.backward
        )
    })
}

/// Every specimen compared by more than one shard must have had the same
/// content hash in each; otherwise name the specimens and the shards.
fn check_same_content(shards: &[(PathBuf, ShardFile)]) -> Result<(), ShardError> {
    let Some((_, first)) = shards.first() else {
        return Ok(());
    };
    let mut differing = Vec::new();
    for (k, name) in first.names.iter().enumerate() {
        let seen: Vec<(&Path, &str)> = shards
            .iter()
            .filter_map(|(path, s)| Some((path.as_path(), s.content.get(k)?.as_deref()?)))
            .collect();
        let Some(&(path0, hash0)) = seen.first() else {
            continue;
        };
        if let Some(&(path1, hash1)) = seen.iter().find(|(_, h)| *h != hash0) {
            differing.push(format!(
                "{name} ({} in {}, {} in {})",
                short(hash0),
                path0.display(),
                short(hash1),
                path1.display()
            ));
        }
    }
    if differing.is_empty() {
        return Ok(());
    }
    Err(ShardError::Mismatch(format!(
        "shards computed from different files: {} specimen(s) changed between tasks: {}          (compute the shards holding the old content again)",
        differing.len(),
        differing.join("; ")
    )))
}

/// The error for line `line` (1-based) of the shard file `path`.
fn format_error(path: &Path, line: usize, message: String) -> ShardError {
    ShardError::Format {
        path: path.to_path_buf(),
        line,
        message,
    }
}

/// The line of the file that line `line` of the name list and the pairs
/// (which start on the file's third line) is.
fn file_line(line: usize) -> usize {
    line + 2
}

/// The shard named by the first line, `# morphoid matrix shard K/N`.
fn parse_shard_line(first: &str) -> Result<Shard, ShardHeaderError> {
    Ok(first
        .trim_end_matches('\r')
        .strip_prefix("# morphoid matrix shard ")
        .ok_or(ShardHeaderError::NotAShard)?
        .trim()
        .parse()?)
}

/// The content hashes of the second line, `# content: h1,,h3,…` (`None`
/// where empty).
fn parse_content_line(second: &str) -> Result<Vec<Option<String>>, ShardHeaderError> {
    Ok(second
        .trim_end_matches('\r')
        .strip_prefix("# content:")
        .ok_or(ShardHeaderError::NoContentLine)?
        .trim()
        .split(',')
        .map(|h| Some(h.trim().to_string()).filter(|h| !h.is_empty()))
        .collect())
}

/// Each name's position in `names`; `None` when a name occurs twice.
fn name_index(names: &[String]) -> Option<HashMap<&str, usize>> {
    let index: HashMap<&str, usize> = names
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i))
        .collect();
    (index.len() == names.len()).then_some(index)
}

/// Whether the row after the names, `header` (`None` at the end of the
/// file), is `a,b,distance,forward,backward`; else the line to blame.
fn check_pair_header(header: Option<Row>) -> Result<(), usize> {
    match header {
        Some(h)
            if h.fields
                .iter()
                .map(|f| trimmed(f))
                .eq(["a", "b", "distance", "forward", "backward"]) =>
        {
            Ok(())
        }
        h => Err(h.map_or(4, |h| file_line(h.line))),
    }
}

/// The pair of a row `a,b,distance,forward,backward` of the shard file
/// `path`, its specimens looked up in `index`: an error unless both are
/// names of the list, in list order, and the three values finite numbers.
fn pair_of_row(
    row: Row,
    index: &HashMap<&str, usize>,
    path: &Path,
) -> Result<PairDistance, ShardError> {
    let Row { line, fields: f } = row;
    let line = file_line(line);
    let err = |message: String| format_error(path, line, message);
    if f.len() != 5 {
        return Err(err(format!("{} fields, expected 5", f.len())));
    }
    let specimen = |s: &str| {
        index
            .get(trimmed(s))
            .copied()
            .ok_or_else(|| err(format!("`{}` is not in the name list", trimmed(s))))
    };
    let (a, b) = (specimen(&f[0])?, specimen(&f[1])?);
    if a >= b {
        return Err(err(format!(
            "pair `{}`,`{}` is not in list order",
            f[0], f[1]
        )));
    }
    let mut v = [0.0; 3];
    for (k, x) in v.iter_mut().enumerate() {
        let s = f[2 + k].trim();
        *x = s
            .parse()
            .ok()
            .filter(|x: &f64| x.is_finite())
            .ok_or_else(|| err(format!("`{s}` is not a finite number")))?;
    }
    Ok(PairDistance {
        a,
        b,
        distance: v[0],
        forward: v[1],
        backward: v[2],
    })
}

/// The first 12 hex digits of a hash, for messages.
fn short(hash: &str) -> &str {
    hash.get(..12).unwrap_or(hash)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_pairs_in_order() {
        for n in [0, 1, 2, 3, 7, 12] {
            for count in [1, 2, 3, 5, 30] {
                let all: Vec<(usize, usize)> = (1..=count)
                    .flat_map(|index| shard_pairs(n, Shard { index, count }))
                    .collect();
                let expected: Vec<(usize, usize)> = (0..n)
                    .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
                    .collect();
                assert_eq!(all, expected, "n {n}, {count} shards");
                let sizes: Vec<usize> = (1..=count)
                    .map(|index| Shard { index, count }.range(pair_count(n)).len())
                    .collect();
                let (lo, hi) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
                assert!(hi - lo <= 1, "{sizes:?}");
            }
        }
        assert_eq!(pair_specimens(&[(0, 3), (1, 3), (0, 2)]), vec![0, 1, 2, 3]);
    }

    #[test]
    fn parses_shard_specs() {
        assert_eq!("2/8".parse(), Ok(Shard { index: 2, count: 8 }));
        for bad in ["0/3", "4/3", "3", "a/b", "1/0"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }

    fn fake_shards(names: &[&str], count: usize) -> Vec<(PathBuf, ShardFile)> {
        let names: Vec<String> = names.iter().map(|s| s.to_string()).collect();
        (1..=count)
            .map(|index| {
                let shard = Shard { index, count };
                let pairs = shard_pairs(names.len(), shard)
                    .into_iter()
                    .map(|(a, b)| {
                        let f = (a * 10 + b) as f64 + 0.125;
                        PairDistance {
                            a,
                            b,
                            distance: f,
                            forward: f,
                            backward: f + 1.0,
                        }
                    })
                    .collect();
                let content = (1..=names.len())
                    .map(|k| Some(format!("{k:016x}")))
                    .collect();
                (
                    PathBuf::from(format!("shard{index}.csv")),
                    ShardFile {
                        shard,
                        names: names.clone(),
                        content,
                        pairs,
                    },
                )
            })
            .collect()
    }

    #[test]
    fn text_round_trip() {
        let mut s = fake_shards(&["a", "b,c", "d", "q\"x", "new\nline", "e"], 2)
            .remove(1)
            .1;
        s.pairs[0].forward = 0.1 + 0.2;
        s.content[0] = None;
        let text = s.to_text();
        assert!(text.starts_with(
            "# morphoid matrix shard 2/2\n# content: ,0000000000000002,0000000000000003,\
             0000000000000004,0000000000000005,0000000000000006\n# names: a,\"b,c\",d,\"q\"\"x\",\"new\nline\",e\na,b,distance,forward,backward\n"
        ));
        assert_eq!(ShardFile::parse(&text, Path::new("s.csv")).unwrap(), s);
        let e = ShardFile::parse(&text.replace(",e\n", ",x\n"), Path::new("s.csv")).unwrap_err();
        assert!(e.to_string().starts_with("s.csv:"), "{e}");
    }

    #[test]
    fn header_lines_are_checked_with_typed_errors() {
        let path = Path::new("s.csv");
        let cases = [
            (
                "x\n",
                1,
                ShardHeaderError::NotAShard,
                "s.csv:1: not a morphoid matrix shard",
            ),
            (
                "# morphoid matrix shard 3/2\n",
                1,
                ShardHeaderError::Shard("3/2".parse::<Shard>().unwrap_err()),
                "s.csv:1: `3/2`: a shard is K/N with 1 ≤ K ≤ N, e.g. 2/8",
            ),
            (
                "# morphoid matrix shard 1/2\n# names: a\n",
                2,
                ShardHeaderError::NoContentLine,
                "s.csv:2: expected `# content: …` (a shard of an older morphoid: compute it \
                 again)",
            ),
        ];
        for (text, at, why, message) in cases {
            let e = ShardFile::parse(text, path).unwrap_err();
            assert_eq!(e.to_string(), message);
            assert!(
                matches!(&e, ShardError::Header { line, source, .. } if *line == at && *source == why),
                "{e:?}"
            );
        }
    }

    #[test]
    fn merge_checks_the_set() {
        let names = ["a", "b", "c", "d", "e"];
        let shards = fake_shards(&names, 3);
        let m = merge_shards(&shards).unwrap();
        assert_eq!(m.values()[1][3], 13.125);
        assert_eq!(m.values()[3][1], 13.125);
        assert_eq!(m.values()[2][2], 0.0);

        let e = merge_shards(&shards[..2]).unwrap_err().to_string();
        assert!(e.contains("missing shard(s) 3/3"), "{e}");
        let mut dup = shards.clone();
        dup[2] = (PathBuf::from("again.csv"), shards[1].1.clone());
        let e = merge_shards(&dup).unwrap_err().to_string();
        assert!(
            e.contains("2/3 given twice") && e.contains("shard2.csv") && e.contains("again.csv"),
            "{e}"
        );
        let mut other = shards.clone();
        other[1].1.names[4] = "z".into();
        let e = merge_shards(&other).unwrap_err().to_string();
        assert!(e.contains("shard2.csv") && e.contains("name list"), "{e}");
        let mut short = shards.clone();
        short[0].1.pairs.pop();
        let e = merge_shards(&short).unwrap_err().to_string();
        assert!(e.contains("shard1.csv") && e.contains("lacks 1"), "{e}");
        let mut twice = shards.clone();
        let p = twice[0].1.pairs[0];
        twice[0].1.pairs.push(p);
        let e = merge_shards(&twice).unwrap_err().to_string();
        assert!(e.contains("shard1.csv") && e.contains("twice"), "{e}");
        let mut stray = shards.clone();
        let p = stray[2].1.pairs[0];
        stray[0].1.pairs.push(p);
        let e = merge_shards(&stray).unwrap_err().to_string();
        assert!(e.contains("does not belong"), "{e}");
        assert!(matches!(merge_shards(&[]), Err(ShardError::NoShards)));
    }

    #[test]
    fn merge_refuses_shards_of_changed_files_naming_the_specimens() {
        let shards = fake_shards(&["a", "b", "c", "d", "e"], 3);
        let mut stale = shards.clone();
        stale[2].1.content[3] = Some("ffffffffffffffff".into());
        // A specimen one shard does not involve carries no hash there.
        stale[0].1.content[4] = None;
        let e = merge_shards(&stale).unwrap_err().to_string();
        assert!(
            e.contains("1 specimen(s) changed")
                && e.contains("d (000000000000 in shard1.csv, ffffffffffff in shard3.csv)"),
            "{e}"
        );
        let mut one_missing = shards.clone();
        one_missing[1].1.content[0] = None;
        merge_shards(&one_missing).unwrap();
    }

    #[test]
    fn merge_refuses_values_that_are_not_distances() {
        let shards = fake_shards(&["a", "b", "c", "d"], 2);
        let bad = |edit: &dyn Fn(&mut PairDistance)| {
            let mut s = shards.clone();
            edit(&mut s[1].1.pairs[0]);
            merge_shards(&s).unwrap_err().to_string()
        };
        let e = bad(&|p| p.distance = p.backward);
        assert!(
            e.starts_with("shard2.csv: pair b,c:") && e.contains("is not min(forward"),
            "{e}"
        );
        let e = bad(&|p| {
            p.forward = -1.0;
            p.distance = -1.0
        });
        assert!(e.contains("distance -1.0 is not a distance"), "{e}");
        let e = bad(&|p| p.backward = f64::NAN);
        assert!(e.contains("backward NaN is not a distance"), "{e}");
        // Equal directions, and a zero distance, are distances.
        let mut ok = shards.clone();
        let p = &mut ok[0].1.pairs[0];
        (p.distance, p.forward, p.backward) = (0.0, 0.0, 0.0);
        merge_shards(&ok).unwrap();
    }
}
