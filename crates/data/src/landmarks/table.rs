//! Plain CSV landmark files: `x,y,z` per line, optional header, optional
//! label column. Without a header, a fourth column is the label; with a
//! header, the columns are found by name (`x`, `y`, `z`, and `label` or
//! `name`). Blank lines and lines starting with `#` are skipped; a line
//! without commas is split at whitespace (`x y z`). Files are written with
//! commas.

use super::{coordinate_error, csv_error, parse_coordinate, LandmarkError, Landmarks};
use crate::table::csv_text::{rows, CsvString, Row};
use std::path::Path;

/// Column positions of the coordinates and the label.
struct Layout {
    xyz: [usize; 3],
    label: Option<usize>,
    columns: usize,
}

fn header_layout(fields: &[String]) -> Option<Layout> {
    let find = |names: &[&str]| {
        fields
            .iter()
            .position(|f| names.iter().any(|n| f.trim().eq_ignore_ascii_case(n)))
    };
    let xyz = [find(&["x"])?, find(&["y"])?, find(&["z"])?];
    Some(Layout {
        xyz,
        label: find(&["label", "name"]),
        columns: fields.len(),
    })
}

pub(super) fn parse_csv(text: &str, path: &Path) -> Result<Landmarks, LandmarkError> {
    let err = |line: usize, message: String| LandmarkError::Syntax {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut layout: Option<Layout> = None;
    let mut lm = Landmarks::default();
    for row in rows(text, true) {
        let Row { line, fields } = row.map_err(|e| csv_error(path, e))?;
        if fields
            .first()
            .is_some_and(|f| f.trim_start().starts_with('#'))
        {
            // An indented comment.
            continue;
        }
        // A line without a comma is split at whitespace (`x y z`, as many
        // morphometrics programs write landmarks).
        let fields = match fields.as_slice() {
            [one] => one.split_whitespace().map(str::to_string).collect(),
            _ => fields,
        };
        let lay = match &layout {
            Some(l) => l,
            None => {
                let numeric =
                    fields.len() >= 3 && fields[..3].iter().all(|f| parse_coordinate(f).is_ok());
                let new = if numeric {
                    match fields.len() {
                        3 => Layout {
                            xyz: [0, 1, 2],
                            label: None,
                            columns: 3,
                        },
                        4 => Layout {
                            xyz: [0, 1, 2],
                            label: Some(3),
                            columns: 4,
                        },
                        n => {
                            return Err(err(
                                line,
                                format!("{n} columns; expected x,y,z or x,y,z,label"),
                            ))
                        }
                    }
                } else if let Some(h) = header_layout(&fields) {
                    layout = Some(h);
                    continue;
                } else if fields.len() < 3 {
                    return Err(err(
                        line,
                        format!("{} column(s); expected x,y,z or x,y,z,label", fields.len()),
                    ));
                } else {
                    // Neither numbers nor a header: report the first bad field.
                    let bad = fields[..3].iter().find_map(|f| parse_coordinate(f).err());
                    return Err(match bad {
                        Some(e) => coordinate_error(path, line, e),
                        None => err(line, String::new()),
                    });
                };
                layout.insert(new)
            }
        };
        if fields.len() != lay.columns {
            return Err(err(
                line,
                format!(
                    "{} columns; expected {} like the first line",
                    fields.len(),
                    lay.columns
                ),
            ));
        }
        let mut p = [0.0; 3];
        for (k, &c) in lay.xyz.iter().enumerate() {
            let f = fields.get(c).map(String::as_str).unwrap_or("");
            p[k] = parse_coordinate(f).map_err(|e| coordinate_error(path, line, e))?;
        }
        let label = lay
            .label
            .and_then(|c| fields.get(c))
            .map(|s| s.trim().to_string());
        lm.push(p, label);
    }
    Ok(lm)
}

pub(super) fn format_csv(lm: &Landmarks) -> String {
    let labels = lm.has_labels();
    let mut w = CsvString::new();
    if labels {
        w.record(["x", "y", "z", "label"]);
    } else {
        w.record(["x", "y", "z"]);
    }
    for (i, p) in lm.points.iter().enumerate() {
        let xyz = p.map(|c| c.to_string());
        if labels {
            w.record(
                xyz.iter()
                    .map(String::as_str)
                    .chain([lm.label(i).unwrap_or("")]),
            );
        } else {
            w.record(&xyz);
        }
    }
    w.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Landmarks, LandmarkError> {
        parse_csv(text, Path::new("t.csv"))
    }

    #[test]
    fn reads_plain_headed_and_labelled() {
        let a = parse("1,2,3\n4,5,6\n").unwrap();
        assert_eq!(a.points, vec![[1., 2., 3.], [4., 5., 6.]]);
        assert!(!a.has_labels());
        let b = parse("# comment\nlabel,X,Y,Z\ntip,1,2,3\n\n,4,5,6\r\n").unwrap();
        assert_eq!(b.points, vec![[1., 2., 3.], [4., 5., 6.]]);
        assert_eq!(b.labels, vec![Some("tip".into()), None]);
        let w = parse("x y z\n1 2\t3\n  4 5 6 \n").unwrap();
        assert_eq!(w.points, vec![[1., 2., 3.], [4., 5., 6.]]);
        let c = parse("1,2,3,a\n4,5,6,\"b, c\"\n7,8,9,\"two\nlines\"\n  # indented\n").unwrap();
        assert_eq!(c.label(1), Some("b, c"));
        assert_eq!(c.label(2), Some("two\nlines"));
        assert_eq!(parse(&format_csv(&c)).unwrap(), c);
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse("1,2,3\n4,5\n").unwrap_err().to_string();
        assert!(e.contains("t.csv:2") && e.contains("2 columns"), "{e}");
        let e = parse("x,y,z\n1,2,3\n1,NaN,3\n").unwrap_err().to_string();
        assert!(e.contains("t.csv:3") && e.contains("not finite"), "{e}");
        let e = parse("1,2,3\n1,two,3\n").unwrap_err().to_string();
        assert!(
            e.contains("t.csv:2") && e.contains("`two` is not a number"),
            "{e}"
        );
        let e = parse("a,b,c\n").unwrap_err().to_string();
        assert!(e.contains("t.csv:1"), "{e}");
        let e = parse("1,2,3,4,5\n").unwrap_err().to_string();
        assert!(e.contains("5 columns"), "{e}");
    }
}
