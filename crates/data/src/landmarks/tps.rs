//! TPS landmark files (F. J. Rohlf's format, read by geomorph's
//! `readland.tps` and MorphoJ): one or more specimens, each
//!
//! ```text
//! LM3=<count>
//! x y z          (count lines)
//! [SCALE=<factor>] [IMAGE=…] [COMMENT=…] …
//! ID=<name>
//! ```
//!
//! Coordinates are multiplied by the specimen's `SCALE=` when it has one.
//! A landmark at `-99`, `-999` or `-9999` in every coordinate, or a
//! negative sentinel in any, is the TPS convention for a missing landmark:
//! morphoid needs every landmark, so it is an error naming the line, as are
//! a specimen without `ID=`, a count that does not match its lines and 2D
//! (`LM=`) data. Written files hold `LM3=`, the coordinates and `ID=`.

use super::{
    content_lines, coordinate_error, parse_coordinate, parse_xyz, xyz_line, LandmarkError,
    Landmarks,
};
use std::path::Path;

/// The landmarks of one specimen of a collection file.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedLandmarks {
    /// The specimen's name (TPS `ID=`, morphologika `[names]`).
    pub name: String,
    /// Its landmarks (unlabelled).
    pub landmarks: Landmarks,
}

/// Whether `v` is one of the sentinels TPS files use for a missing
/// landmark.
fn is_missing_sentinel(v: f64) -> bool {
    [-99.0, -999.0, -9999.0, -99999.0].contains(&v)
}

/// One specimen being read.
struct Pending {
    /// Line of its `LM3=`.
    line: usize,
    count: usize,
    points: Vec<[f64; 3]>,
    scale: Option<f64>,
    id: Option<String>,
}

/// The error naming `path` and `line`.
fn syntax(path: &Path, line: usize, message: String) -> LandmarkError {
    LandmarkError::Syntax {
        path: path.to_path_buf(),
        line,
        message,
    }
}

/// Parse a TPS file; `path` only names the source in errors.
pub fn parse_tps(text: &str, path: &Path) -> Result<Vec<NamedLandmarks>, LandmarkError> {
    let mut out = Vec::new();
    let mut current: Option<Pending> = None;
    for (line, t) in content_lines(text) {
        if let Some((key, value)) = t.split_once('=') {
            let key = key.trim().to_ascii_uppercase();
            take_field(path, line, &key, value.trim(), &mut current, &mut out)?;
            continue;
        }
        let Some(p) = current.as_mut() else {
            return Err(syntax(path, line, "coordinates before any LM3=".into()));
        };
        p.take_coordinates(path, line, t)?;
    }
    if let Some(p) = current.take() {
        out.push(p.finish(path)?);
    }
    if out.is_empty() {
        return Err(LandmarkError::Empty(path.to_path_buf()));
    }
    Ok(out)
}

/// Take the field `key=value` (key upper-cased) at `line`: `LM3=` ends
/// the specimen being read (into `out`) and starts the next; the others
/// belong to the specimen being read.
fn take_field(
    path: &Path,
    line: usize,
    key: &str,
    value: &str,
    current: &mut Option<Pending>,
    out: &mut Vec<NamedLandmarks>,
) -> Result<(), LandmarkError> {
    let err = |message: String| syntax(path, line, message);
    match key {
        "LM3" => {
            if let Some(p) = current.take() {
                out.push(p.finish(path)?);
            }
            let count = value
                .parse::<usize>()
                .map_err(|_| err(format!("LM3=`{value}` is not a count")))?;
            *current = Some(Pending {
                line,
                count,
                points: Vec::with_capacity(count.min(1 << 16)),
                scale: None,
                id: None,
            });
        }
        "LM" => return Err(err("2D landmarks (LM=); morphoid reads 3D (LM3=)".into())),
        "ID" | "SCALE" | "IMAGE" | "COMMENT" | "VARIABLES" | "CURVES" | "POINTS" => {
            let Some(p) = current.as_mut() else {
                return Err(err(format!("{key}= before any LM3=")));
            };
            if key == "ID" {
                if value.is_empty() {
                    return Err(err("empty ID=".into()));
                }
                p.id = Some(value.to_string());
            } else if key == "SCALE" {
                let s = parse_coordinate(value).map_err(|source| LandmarkError::Scale {
                    path: path.to_path_buf(),
                    line,
                    source,
                })?;
                if s <= 0.0 {
                    return Err(err(format!("SCALE={value} is not positive")));
                }
                p.scale = Some(s);
            } else if key == "CURVES" && value != "0" {
                return Err(err("curves (CURVES=) are not supported".into()));
            }
        }
        _ => return Err(err(format!("unknown TPS field `{key}=`"))),
    }
    Ok(())
}

impl Pending {
    /// Take the coordinate line `t` (at `line`) as the specimen's next
    /// landmark: an error for a missing landmark or one past its count.
    fn take_coordinates(&mut self, path: &Path, line: usize, t: &str) -> Result<(), LandmarkError> {
        let q = parse_xyz(t).map_err(|e| coordinate_error(path, line, e))?;
        if q.iter().any(|&v| is_missing_sentinel(v)) {
            return Err(syntax(
                path,
                line,
                format!(
                    "landmark {} is missing (a {} coordinate, the TPS missing-landmark convention); every landmark is needed",
                    self.points.len() + 1,
                    q.iter().copied().find(|&v| is_missing_sentinel(v)).unwrap_or(-999.0)
                ),
            ));
        }
        if self.points.len() == self.count {
            return Err(syntax(
                path,
                line,
                format!(
                    "more than LM3={} coordinate lines (no ID= between specimens?)",
                    self.count
                ),
            ));
        }
        self.points.push(q);
        Ok(())
    }

    /// The specimen read, its coordinates scaled by its `SCALE=`; an error
    /// when it has fewer landmarks than its `LM3=` or no `ID=`.
    fn finish(self, path: &Path) -> Result<NamedLandmarks, LandmarkError> {
        if self.points.len() != self.count {
            return Err(syntax(
                path,
                self.line,
                format!(
                    "LM3={} but {} coordinate lines follow",
                    self.count,
                    self.points.len()
                ),
            ));
        }
        let Some(name) = self.id else {
            return Err(syntax(
                path,
                self.line,
                "specimen without ID= (every specimen needs one)".into(),
            ));
        };
        let s = self.scale.unwrap_or(1.0);
        let points = self.points.iter().map(|q| q.map(|v| v * s)).collect();
        Ok(NamedLandmarks {
            name,
            landmarks: Landmarks::from_points(points),
        })
    }
}

/// The TPS text of a collection; names are written as they are (one
/// line each; line breaks become spaces).
pub fn format_tps(specimens: &[NamedLandmarks]) -> String {
    let mut s = String::new();
    for sp in specimens {
        s.push_str(&format!("LM3={}\n", sp.landmarks.len()));
        for p in &sp.landmarks.points {
            s.push_str(&xyz_line(p));
        }
        s.push_str(&format!("ID={}\n", one_line(&sp.name)));
    }
    s
}

/// `name` on one line.
pub(super) fn one_line(name: &str) -> String {
    name.replace(['\n', '\r'], " ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn collection() -> Vec<NamedLandmarks> {
        vec![
            NamedLandmarks {
                name: "a b".into(),
                landmarks: Landmarks::from_points(vec![
                    [0.1, -2.5e-7, 1234.5678901234567],
                    [1.0, 2.0, 3.0],
                ]),
            },
            NamedLandmarks {
                name: "c".into(),
                landmarks: Landmarks::from_points(vec![[-0.0, 1.0 / 3.0, 7.0], [4.0, 5.0, 6.0]]),
            },
        ]
    }

    #[test]
    fn round_trip_and_scale() {
        let c = collection();
        let text = format_tps(&c);
        assert!(text.starts_with("LM3=2\n"), "{text}");
        assert_eq!(parse_tps(&text, Path::new("x.tps")).unwrap(), c);
        let scaled = "LM3=1\n1 2 3\nSCALE=0.5\nIMAGE=x.tif\nID=s\n";
        let got = parse_tps(scaled, Path::new("x.tps")).unwrap();
        assert_eq!(got[0].landmarks.points, vec![[0.5, 1.0, 1.5]]);
    }

    #[test]
    fn malformed_files_name_file_and_line() {
        let p = Path::new("col.tps");
        for (text, line, needle) in [
            ("LM3=2\n1 2 3\n-999 -999 -999\nID=a\n", 3, "missing"),
            ("LM3=2\n1 2 3\n4 5 -99\nID=a\n", 3, "missing"),
            ("LM3=2\n1 2 3\n4 5 6\n", 1, "ID="),
            (
                "LM3=2\n1 2 3\nID=a\nLM3=1\n1 2 3\nID=b\n",
                1,
                "1 coordinate lines",
            ),
            ("LM3=1\n1 2 3\n4 5 6\nID=a\n", 3, "more than LM3=1"),
            ("LM=2\n1 2\n3 4\nID=a\n", 1, "2D"),
            ("LM3=1\n1 2\nID=a\n", 2, "2 values"),
            ("LM3=1\n1 x 3\nID=a\n", 2, "not a number"),
            ("LM3=1\n1 2 3\nSCALE=-1\nID=a\n", 3, "not positive"),
        ] {
            let e = parse_tps(text, p).unwrap_err().to_string();
            assert!(e.starts_with(&format!("col.tps:{line}:")), "{text:?}: {e}");
            assert!(e.contains(needle), "{text:?}: {e}");
        }
        assert!(matches!(parse_tps("\n", p), Err(LandmarkError::Empty(_))));
    }
}
