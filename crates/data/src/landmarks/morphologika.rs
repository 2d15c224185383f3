//! Morphologika landmark files (read by MorphoJ and geomorph's
//! `read.morphologika`): bracketed sections
//!
//! ```text
//! [individuals]  n
//! [landmarks]    k
//! [dimensions]   3
//! [names]        n names, one a line
//! [rawpoints]    n blocks of k lines `x y z`, each block optionally
//!                preceded by a `'name` line
//! ```
//!
//! Other sections (`[labels]`, `[wireframe]`, …) are skipped. Lines
//! starting with `'` are comments.

use super::tps::{one_line, NamedLandmarks};
use super::{content_lines, coordinate_error, parse_xyz, xyz_line, LandmarkError, Landmarks};
use std::path::Path;

/// Whether `text` looks like a morphologika file (its first non-blank line
/// is a bracketed section).
pub(crate) fn is_morphologika(text: &str) -> bool {
    content_lines(text)
        .next()
        .is_some_and(|(_, l)| l.starts_with('['))
}

/// Parse a morphologika file; `path` only names the source in errors.
pub fn parse_morphologika(text: &str, path: &Path) -> Result<Vec<NamedLandmarks>, LandmarkError> {
    let err = |line: usize, message: String| LandmarkError::Syntax {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut section = String::new();
    let mut section_line = 0;
    let (mut individuals, mut landmarks, mut dimensions) = (None, None, None);
    let mut names: Vec<String> = Vec::new();
    let mut points: Vec<([f64; 3], usize)> = Vec::new();
    let count = |v: &str, line: usize, what: &str| -> Result<usize, LandmarkError> {
        v.parse::<usize>()
            .map_err(|_| err(line, format!("[{what}] `{v}` is not a count")))
    };
    for (line, t) in content_lines(text) {
        if t.starts_with('\'') && section != "names" {
            continue;
        }
        if let Some(rest) = t.strip_prefix('[') {
            let Some((name, after)) = rest.split_once(']') else {
                return Err(err(line, format!("unclosed section `{t}`")));
            };
            section = name.trim().to_ascii_lowercase();
            section_line = line;
            let after = after.trim();
            if !after.is_empty() {
                // `[individuals] 3` on one line.
                match section.as_str() {
                    "individuals" => individuals = Some(count(after, line, "individuals")?),
                    "landmarks" => landmarks = Some(count(after, line, "landmarks")?),
                    "dimensions" => dimensions = Some(count(after, line, "dimensions")?),
                    _ => {}
                }
            }
            continue;
        }
        match section.as_str() {
            "individuals" => individuals = Some(count(t, line, "individuals")?),
            "landmarks" => landmarks = Some(count(t, line, "landmarks")?),
            "dimensions" => dimensions = Some(count(t, line, "dimensions")?),
            "names" => names.push(t.trim_start_matches('\'').to_string()),
            "rawpoints" => {
                let p = parse_xyz(t).map_err(|e| coordinate_error(path, line, e))?;
                points.push((p, line));
            }
            "" => return Err(err(line, "content before any [section]".into())),
            _ => {}
        }
    }
    let (Some(n), Some(k)) = (individuals, landmarks) else {
        return Err(err(
            section_line.max(1),
            "no [individuals] or [landmarks] count".into(),
        ));
    };
    if let Some(d) = dimensions.filter(|&d| d != 3) {
        return Err(err(
            section_line.max(1),
            format!("{d} dimensions; morphoid reads 3D"),
        ));
    }
    let Some(total) = n.checked_mul(k) else {
        return Err(err(
            section_line.max(1),
            format!("{n} individuals × {k} landmarks: more points than any file holds"),
        ));
    };
    if points.len() != total {
        let line = points.last().map_or(section_line.max(1), |p| p.1);
        return Err(err(
            line,
            format!(
                "{} points under [rawpoints]; {n} individuals × {k} landmarks need {total}",
                points.len(),
            ),
        ));
    }
    if !names.is_empty() && names.len() != n {
        return Err(err(
            section_line.max(1),
            format!("{} names for {n} individuals", names.len()),
        ));
    }
    if n == 0 || k == 0 {
        return Err(LandmarkError::Empty(path.to_path_buf()));
    }
    Ok(points
        .chunks(k)
        .enumerate()
        .map(|(i, block)| NamedLandmarks {
            name: names
                .get(i)
                .cloned()
                .unwrap_or_else(|| format!("{}", i + 1)),
            landmarks: Landmarks::from_points(block.iter().map(|p| p.0).collect()),
        })
        .collect())
}

/// The morphologika text of a collection (every specimen with the same
/// number of landmarks as the first).
pub fn format_morphologika(specimens: &[NamedLandmarks]) -> String {
    let k = specimens.first().map_or(0, |s| s.landmarks.len());
    let mut s = format!(
        "[individuals]\n{}\n[landmarks]\n{k}\n[dimensions]\n3\n[names]\n",
        specimens.len()
    );
    for sp in specimens {
        s.push_str(&one_line(&sp.name));
        s.push('\n');
    }
    s.push_str("[rawpoints]\n");
    for sp in specimens {
        s.push_str(&format!("'{}\n", one_line(&sp.name)));
        for p in &sp.landmarks.points {
            s.push_str(&xyz_line(p));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        let c = vec![
            NamedLandmarks {
                name: "x1".into(),
                landmarks: Landmarks::from_points(vec![[0.1, 2.0, -3.5], [1e-9, 0.0, 1.0 / 3.0]]),
            },
            NamedLandmarks {
                name: "y two".into(),
                landmarks: Landmarks::from_points(vec![[4.0, 5.0, 6.0], [7.0, 8.0, 9.0]]),
            },
        ];
        let text = format_morphologika(&c);
        assert!(is_morphologika(&text));
        assert_eq!(parse_morphologika(&text, Path::new("m.txt")).unwrap(), c);
    }

    #[test]
    fn wrong_counts_name_the_line() {
        let text =
            "[individuals]\n2\n[landmarks]\n2\n[dimensions]\n3\n[rawpoints]\n1 2 3\n4 5 6\n7 8 9\n";
        let e = parse_morphologika(text, Path::new("m.txt"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("m.txt:10:") && e.contains("need 4"), "{e}");
        let e = parse_morphologika(
            "[individuals]\n1\n[landmarks]\n1\n[rawpoints]\n1 2\n",
            Path::new("m.txt"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("m.txt:6:"), "{e}");
    }
}
