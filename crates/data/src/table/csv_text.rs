//! The crate's CSV dialect, through the `csv` crate: commas, `\n` line
//! ends, a field quoted only when it holds a comma, a double quote or a
//! line break (so ordinary files read as they always did, and any name
//! round-trips), and a reader that also takes `\r\n`, line breaks inside
//! quoted fields and a leading byte-order mark.

use std::path::{Path, PathBuf};

/// Why a table file (a distance matrix, labels) could not be read or
/// written; the message names the file, and the line for bad content.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file could not be replaced.
    #[error(transparent)]
    Write(#[from] crate::atomic_write::AtomicWriteError),
    /// A record the CSV reader cannot read.
    #[error("{path}:{line}: {source}")]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line number of the record.
        line: usize,
        /// The reader's error.
        source: RowError,
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

/// Records written into a string.
pub struct CsvString(csv::Writer<Vec<u8>>);

impl Default for CsvString {
    fn default() -> Self {
        Self::new()
    }
}

impl CsvString {
    /// An empty text.
    pub fn new() -> Self {
        CsvString(
            csv::WriterBuilder::new()
                .flexible(true)
                .terminator(csv::Terminator::Any(b'\n'))
                .quote_style(csv::QuoteStyle::Necessary)
                .from_writer(Vec::new()),
        )
    }

    /// Append one record.
    pub fn record<I, T>(&mut self, fields: I)
    where
        I: IntoIterator<Item = T>,
        T: AsRef<[u8]>,
    {
        // The writer is flexible and writes into memory, so nothing can
        // fail here: its only errors are unequal lengths and I/O.
        let _ = self.0.write_record(fields);
    }

    /// The text written so far.
    pub fn finish(self) -> String {
        let bytes = match self.0.into_inner() {
            Ok(bytes) => bytes,
            Err(e) => e.into_inner().get_ref().clone(),
        };
        // Every field came in as text, so the bytes are UTF-8.
        String::from_utf8(bytes).unwrap_or_else(|e| String::from_utf8_lossy(e.as_bytes()).into())
    }
}

/// One record read: its fields and the 1-based line it starts on.
pub struct Row {
    /// The line of the file the record starts on.
    pub line: usize,
    /// The fields, unquoted.
    pub fields: Vec<String>,
}

/// A record the CSV reader cannot read ([`rows`]). Its message is the
/// reader's: the caller, which knows the file, names the file and line.
#[derive(Debug, thiserror::Error)]
#[error("{source}")]
pub struct RowError {
    /// The 1-based line the record starts on.
    pub line: usize,
    /// The reader's error.
    pub source: csv::Error,
}

/// The records of `text` in order, each with its line; blank lines (also
/// ones of spaces only) are skipped. With `comments`, so are lines whose
/// first non-blank character is `#`.
pub fn rows(text: &str, comments: bool) -> impl Iterator<Item = Result<Row, RowError>> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    // Comment lines are emptied rather than left to the reader's comment
    // option: that one does not count them as lines, and a quote in a
    // comment could open a field.
    let bytes: Vec<u8> = if comments {
        text.split_inclusive('\n')
            .flat_map(|l| {
                let kept = if l.trim_start().starts_with('#') {
                    if l.ends_with('\n') {
                        "\n"
                    } else {
                        ""
                    }
                } else {
                    l
                };
                kept.bytes()
            })
            .collect()
    } else {
        text.as_bytes().to_vec()
    };
    // A record's position is where the reader stood before it skipped
    // the blank lines in front of the record, so step over those to find
    // the record's first line.
    let ends: Vec<usize> = bytes
        .iter()
        .enumerate()
        .filter(|&(_, &b)| b == b'\n' || b == b'\r')
        .map(|(i, _)| i)
        .collect();
    let newlines: Vec<usize> = bytes
        .iter()
        .enumerate()
        .filter(|&(_, &b)| b == b'\n')
        .map(|(i, _)| i)
        .collect();
    let line_of = move |p: Option<&csv::Position>| {
        let Some(p) = p else { return 0 };
        let mut at = usize::try_from(p.byte()).unwrap_or(usize::MAX);
        let mut k = ends.partition_point(|&e| e < at);
        while ends.get(k) == Some(&at) {
            at += 1;
            k += 1;
        }
        newlines.partition_point(|&n| n < at) + 1
    };
    csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(std::io::Cursor::new(bytes))
        .into_records()
        .filter_map(move |r| match r {
            Ok(record) => {
                let line = line_of(record.position());
                let fields: Vec<String> = record.iter().map(str::to_string).collect();
                let blank = fields.iter().all(|f| f.trim().is_empty());
                (!blank).then_some(Ok(Row { line, fields }))
            }
            Err(source) => Some(Err(RowError {
                line: line_of(source.position()),
                source,
            })),
        })
}

/// A field without the spaces and tabs around it (line breaks inside a
/// quoted field are content and stay).
pub fn trimmed(field: &str) -> &str {
    field.trim_matches([' ', '\t'])
}

/// The records of a table file's `text` (as [`rows`], without comments)
/// split into its header and the rest, with errors that name `path` and
/// the line. A text with no record is an "empty file".
pub(crate) fn header_and_rows<'a>(
    text: &'a str,
    path: &'a Path,
) -> Result<(Row, impl Iterator<Item = Result<Row, TableError>> + 'a), TableError> {
    let mut rows = rows(text, false).map(move |r| {
        r.map_err(|source| TableError::Csv {
            path: path.to_path_buf(),
            line: source.line,
            source,
        })
    });
    let header = rows
        .next()
        .unwrap_or_else(|| Err(format_error(path, 1, "empty file".into())))?;
    Ok((header, rows))
}

/// The content error of line `line` of `path`.
pub(crate) fn format_error(path: &Path, line: usize, message: String) -> TableError {
    TableError::Format {
        path: path.to_path_buf(),
        line,
        message,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_table_without_records_is_an_empty_file_and_lines_are_kept() {
        let path = Path::new("t.csv");
        for text in ["", "\n  \n"] {
            let Err(TableError::Format { line, message, .. }) = header_and_rows(text, path) else {
                panic!("{text:?} has no header");
            };
            assert_eq!((line, message.as_str()), (1, "empty file"));
        }
        let (header, rows) = header_and_rows("\nname,a\n\nx,1\n", path).unwrap();
        assert_eq!(
            (header.line, header.fields),
            (2, vec!["name".into(), "a".into()])
        );
        let rows: Vec<Row> = rows.collect::<Result<_, _>>().unwrap();
        assert_eq!((rows[0].line, rows[0].fields.len()), (4, 2));
        let e = format_error(path, 7, "bad".into());
        assert_eq!(e.to_string(), "t.csv:7: bad");
    }

    fn all(text: &str) -> Vec<(usize, Vec<String>)> {
        rows(text, false)
            .map(|r| r.map(|r| (r.line, r.fields)).unwrap())
            .collect()
    }

    #[test]
    fn writes_quotes_only_where_needed_and_reads_back() {
        let mut w = CsvString::new();
        w.record(["name", "a,b", "c\"d", "e\nf", "plain", ""]);
        w.record(["x"]);
        let text = w.finish();
        assert_eq!(text, "name,\"a,b\",\"c\"\"d\",\"e\nf\",plain,\nx\n");
        let back = all(&text);
        assert_eq!(back[0].1, ["name", "a,b", "c\"d", "e\nf", "plain", ""]);
        // The second record starts on line 3: the quoted line break counts.
        assert_eq!((back[1].0, back[1].1.clone()), (3, vec!["x".to_string()]));
    }

    #[test]
    fn reads_crlf_bom_blank_lines_and_comments() {
        let text = "\u{feff}a,b\r\n\r\n   \n# note, \"x\n\"c, d\",e\n";
        let got = all(text);
        assert_eq!(got[0], (1, vec!["a".to_string(), "b".to_string()]));
        assert_eq!(got[1].0, 4);
        assert_eq!(got[2], (5, vec!["c, d".to_string(), "e".to_string()]));
        let without: Vec<usize> = rows(text, true)
            .map(|r| r.map(|r| r.line).unwrap())
            .collect();
        assert_eq!(without, [1, 5]);
        assert_eq!(trimmed(" a\n\t"), "a\n");
    }
}
