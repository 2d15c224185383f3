//! 3D Slicer markups: the fiducial CSV (`.fcsv`) and the markups JSON
//! (`.mrk.json`). Points are converted to LPS on reading (see the module
//! documentation of [`super`]); the writers declare LPS.

use super::{coordinate_error, csv_error, parse_coordinate, LandmarkError, Landmarks};
use crate::table::csv_text::{rows, CsvString, Row};
use serde_json::{json, Value};
use std::path::Path;

/// The column list Slicer writes (version 4.6 and later).
const FCSV_COLUMNS: &str = "id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID";

/// The markups JSON schema this writer follows.
const MARKUPS_SCHEMA: &str = "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/Resources/Schema/markups-schema-v1.0.3.json#";

/// Slicer's two patient coordinate systems.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Space {
    /// Left, posterior, superior (the in-memory convention).
    Lps,
    /// Right, anterior, superior.
    Ras,
}

impl Space {
    /// The name as Slicer writes it: `LPS`/`RAS`, or the older `1`/`0`.
    fn parse(s: &str) -> Option<Space> {
        match s.trim().to_ascii_uppercase().as_str() {
            "LPS" | "1" => Some(Space::Lps),
            "RAS" | "0" => Some(Space::Ras),
            _ => None,
        }
    }

    /// The point in LPS: RAS and LPS differ by the sign of x and y.
    fn to_lps(self, p: [f64; 3]) -> [f64; 3] {
        match self {
            Space::Lps => p,
            Space::Ras => [-p[0], -p[1], p[2]],
        }
    }
}

pub(super) fn parse_fcsv(text: &str, path: &Path) -> Result<Landmarks, LandmarkError> {
    let err = |line: usize, message: String| LandmarkError::Syntax {
        path: path.to_path_buf(),
        line,
        message,
    };
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    // The `# key = value` header lines, by line number; the data records
    // come from the CSV reader, which skips them (and lets a quoted label
    // span lines).
    let mut header = text.lines().enumerate().filter_map(|(i, raw)| {
        let (key, value) = raw.trim().strip_prefix('#')?.split_once('=')?;
        Some((i + 1, key.trim().to_ascii_lowercase(), value.to_string()))
    });
    let mut next_header = header.next();
    // Files written before Slicer 4.11 have no coordinate system line and
    // are in RAS.
    let mut space = Space::Ras;
    let mut columns: Vec<String> = FCSV_COLUMNS.split(',').map(str::to_string).collect();
    let mut seen_header = false;
    let mut lm = Landmarks::default();
    let mut data = rows(text, true);
    loop {
        let row = data.next().transpose().map_err(|e| csv_error(path, e))?;
        // Header lines above this record (all that remain after the last).
        let until = row.as_ref().map_or(usize::MAX, |r| r.line);
        while let Some((line, key, value)) = next_header.take_if(|(l, _, _)| *l < until) {
            match key.as_str() {
                "markups fiducial file version" => seen_header = true,
                "coordinatesystem" => {
                    space = Space::parse(&value).ok_or_else(|| {
                        err(
                            line,
                            format!("unknown coordinate system `{}`", value.trim()),
                        )
                    })?;
                }
                "columns" => {
                    columns = value.split(',').map(|c| c.trim().to_string()).collect();
                    seen_header = true;
                }
                _ => {}
            }
            next_header = header.next();
        }
        let Some(Row { line, fields }) = row else {
            break;
        };
        if !seen_header {
            return Err(err(
                line,
                "not a Slicer markups file (no `# Markups fiducial file version` or `# columns` header)"
                    .into(),
            ));
        }
        let col = |name: &str| columns.iter().position(|c| c == name);
        let (Some(x), Some(y), Some(z)) = (col("x"), col("y"), col("z")) else {
            return Err(err(line, "the columns header lacks x, y or z".into()));
        };
        if fields.len() != columns.len() {
            return Err(err(
                line,
                format!(
                    "{} columns; the header names {}",
                    fields.len(),
                    columns.len()
                ),
            ));
        }
        let mut p = [0.0; 3];
        for (k, c) in [x, y, z].into_iter().enumerate() {
            let f = fields.get(c).map(String::as_str).unwrap_or("");
            p[k] = parse_coordinate(f).map_err(|e| coordinate_error(path, line, e))?;
        }
        let label = col("label").and_then(|c| fields.get(c)).cloned();
        lm.push(space.to_lps(p), label);
    }
    Ok(lm)
}

pub(super) fn format_fcsv(lm: &Landmarks) -> String {
    let mut w = CsvString::new();
    for (i, p) in lm.points.iter().enumerate() {
        let [x, y, z] = p.map(|c| c.to_string());
        let id = (i + 1).to_string();
        let label = lm.label(i).unwrap_or("");
        w.record([
            id.as_str(),
            &x,
            &y,
            &z,
            "0",
            "0",
            "0",
            "1",
            "1",
            "1",
            "0",
            label,
            "",
            "",
        ]);
    }
    format!(
        "# Markups fiducial file version = 4.11\n# CoordinateSystem = LPS\n# columns = {FCSV_COLUMNS}\n{}",
        w.finish()
    )
}

pub(super) fn parse_markups_json(text: &str, path: &Path) -> Result<Landmarks, LandmarkError> {
    let root: Value = serde_json::from_str(text).map_err(|e| LandmarkError::Syntax {
        path: path.to_path_buf(),
        line: e.line(),
        message: format!("invalid JSON: {e}"),
    })?;
    let err = |element: String, message: &str| LandmarkError::Element {
        path: path.to_path_buf(),
        element,
        message: message.to_string(),
    };
    let markups = root
        .get("markups")
        .and_then(Value::as_array)
        .ok_or_else(|| {
            err(
                "root".into(),
                "no `markups` array (not a Slicer markups file)",
            )
        })?;
    let mut lm = Landmarks::default();
    let mut fiducials = 0;
    for (m, markup) in markups.iter().enumerate() {
        let here = format!("markups[{m}]");
        // Point lists are "Fiducial" in every Slicer version so far; curves,
        // lines, angles and planes are not landmarks.
        if markup.get("type").and_then(Value::as_str) != Some("Fiducial") {
            continue;
        }
        fiducials += 1;
        let space = match markup.get("coordinateSystem") {
            None => Space::Lps,
            Some(v) => v
                .as_str()
                .and_then(Space::parse)
                .ok_or_else(|| err(here.clone(), "coordinateSystem is neither LPS nor RAS"))?,
        };
        let points = match markup.get("controlPoints") {
            None => continue,
            Some(v) => v
                .as_array()
                .ok_or_else(|| err(here.clone(), "controlPoints is not an array"))?,
        };
        for (c, point) in points.iter().enumerate() {
            let here = format!("{here}.controlPoints[{c}]");
            // A point the user skipped while placing a template has no
            // meaningful position.
            if point.get("positionStatus").and_then(Value::as_str) == Some("missing") {
                return Err(err(here, "the point is marked missing (positionStatus)"));
            }
            let position = point
                .get("position")
                .and_then(Value::as_array)
                .ok_or_else(|| err(here.clone(), "no position (a missing point?)"))?;
            if position.len() != 3 {
                return Err(err(here, "position does not have 3 coordinates"));
            }
            let mut p = [0.0; 3];
            for (k, v) in position.iter().enumerate() {
                p[k] = v
                    .as_f64()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| err(here.clone(), "a coordinate is not a finite number"))?;
            }
            let label = point
                .get("label")
                .and_then(Value::as_str)
                .map(str::to_string);
            lm.push(space.to_lps(p), label);
        }
    }
    if fiducials == 0 {
        return Err(err("markups".into(), "no markup of type Fiducial"));
    }
    Ok(lm)
}

pub(super) fn format_markups_json(lm: &Landmarks) -> String {
    let points: Vec<Value> = lm
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            json!({
                "id": (i + 1).to_string(),
                "label": lm.label(i).unwrap_or(""),
                "description": "",
                "associatedNodeID": "",
                "position": p,
                "orientation": [-1.0, -0.0, -0.0, -0.0, -1.0, -0.0, 0.0, 0.0, 1.0],
                "selected": true,
                "locked": false,
                "visibility": true,
                "positionStatus": "defined"
            })
        })
        .collect();
    let doc = json!({
        "@schema": MARKUPS_SCHEMA,
        "markups": [{
            "type": "Fiducial",
            "coordinateSystem": "LPS",
            "coordinateUnits": "mm",
            "locked": false,
            "labelFormat": "%N-%d",
            "lastUsedControlPointNumber": lm.len(),
            "controlPoints": points,
            "measurements": []
        }]
    });
    let mut s = serde_json::to_string_pretty(&doc).unwrap_or_default();
    s.push('\n');
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fcsv_in_ras_is_converted_to_lps() {
        let text = "# Markups fiducial file version = 4.10\n# CoordinateSystem = 0\n# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\nvtkMRMLMarkupsFiducialNode_0,1.5,-2,3,0,0,0,1,1,1,0,F-1,,vtkMRMLModelNode4\n";
        let lm = parse_fcsv(text, Path::new("r.fcsv")).unwrap();
        assert_eq!(lm.points, vec![[-1.5, 2.0, 3.0]]);
        assert_eq!(lm.label(0), Some("F-1"));
        let lps = text.replace("= 0", "= LPS");
        let lm = parse_fcsv(&lps, Path::new("r.fcsv")).unwrap();
        assert_eq!(lm.points, vec![[1.5, -2.0, 3.0]]);
    }

    #[test]
    fn fcsv_labels_with_commas_quotes_and_line_breaks_round_trip() {
        let mut lm = Landmarks::default();
        lm.push([1.0, 2.5, -3.0], Some("a, \"b\"\nc".into()));
        lm.push([0.1, 0.2, 0.3], None);
        let text = format_fcsv(&lm);
        assert!(
            text.ends_with("\n2,0.1,0.2,0.3,0,0,0,1,1,1,0,,,\n"),
            "{text}"
        );
        assert_eq!(parse_fcsv(&text, Path::new("l.fcsv")).unwrap(), lm);
        let e = parse_fcsv(&format!("{text}3,1,2\n"), Path::new("l.fcsv")).unwrap_err();
        assert!(e.to_string().contains("l.fcsv:7"), "{e}");
    }

    #[test]
    fn fcsv_errors_name_the_line() {
        let head = format!("# Markups fiducial file version = 4.11\n# CoordinateSystem = LPS\n# columns = {FCSV_COLUMNS}\n");
        let e = parse_fcsv(&format!("{head}1,1,2,3,0,0\n"), Path::new("w.fcsv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("w.fcsv:4") && e.contains("6 columns"), "{e}");
        let e = parse_fcsv(
            &format!("{head}1,1,2,3,0,0,0,1,1,1,0,a,,\n2,1,nan,3,0,0,0,1,1,1,0,b,,\n"),
            Path::new("w.fcsv"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("w.fcsv:5") && e.contains("not finite"), "{e}");
        let e = parse_fcsv("# CoordinateSystem = XYZ\n", Path::new("w.fcsv")).unwrap_err();
        assert!(e.to_string().contains("w.fcsv:1"), "{e}");
    }

    #[test]
    fn markups_json_in_ras_and_errors() {
        let text = r#"{"@schema": "x", "markups": [
            {"type": "Curve", "controlPoints": [{"position": [9, 9, 9]}]},
            {"type": "Fiducial", "coordinateSystem": "RAS",
             "controlPoints": [{"id": "1", "label": "a", "position": [1, 2, 3]}]}]}"#;
        let lm = parse_markups_json(text, Path::new("m.mrk.json")).unwrap();
        assert_eq!(lm.points, vec![[-1.0, -2.0, 3.0]]);
        assert_eq!(lm.label(0), Some("a"));
        let bad = text.replace("[1, 2, 3]", "[1, 2]");
        let e = parse_markups_json(&bad, Path::new("m.mrk.json"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("m.mrk.json") && e.contains("markups[1].controlPoints[0]"),
            "{e}"
        );
        let missing = text.replace("\"label\": \"a\",", "\"positionStatus\": \"missing\",");
        let e = parse_markups_json(&missing, Path::new("m.mrk.json"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing"), "{e}");
        let e = parse_markups_json("{\n\"markups\": [,]}", Path::new("m.mrk.json"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("m.mrk.json:2"), "{e}");
    }
}
