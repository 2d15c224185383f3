//! MeshLab picked points (`.pp`): an XML document with one
//! `<point x= y= z= name= active=/>` element per landmark. Inactive points
//! (`active="0"`) are read like the others, so that counts match the file.

use super::{coordinate_error, parse_coordinate, LandmarkError, Landmarks};
use crate::present::escape;
use quick_xml::events::Event;
use quick_xml::{Reader, XmlVersion};
use std::fmt::Write as _;
use std::path::Path;

/// 1-based line of byte `offset` in `text`.
fn line_of(text: &str, offset: u64) -> usize {
    let end = (offset as usize).min(text.len());
    text.as_bytes()[..end]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

pub(super) fn parse_picked_points(text: &str, path: &Path) -> Result<Landmarks, LandmarkError> {
    let err = |offset: u64, message: String| LandmarkError::Syntax {
        path: path.to_path_buf(),
        line: line_of(text, offset),
        message,
    };
    let mut reader = Reader::from_str(text);
    let mut lm = Landmarks::default();
    let mut root = false;
    loop {
        let start = reader.buffer_position();
        let event = reader
            .read_event()
            .map_err(|e| err(reader.error_position(), format!("invalid XML: {e}")))?;
        match event {
            Event::Eof => break,
            Event::Start(e) | Event::Empty(e) => {
                let name = e.name();
                if name.as_ref() == b"PickedPoints" {
                    root = true;
                    continue;
                }
                if name.as_ref() != b"point" {
                    continue;
                }
                if !root {
                    return Err(err(start, "<point> outside <PickedPoints>".into()));
                }
                let mut xyz: [Option<f64>; 3] = [None; 3];
                let mut label = None;
                for attr in e.attributes() {
                    let attr = attr.map_err(|e| err(start, format!("invalid attribute: {e}")))?;
                    let value = attr
                        .normalized_value(XmlVersion::Implicit1_0)
                        .map_err(|e| err(start, format!("invalid attribute value: {e}")))?;
                    let slot = match attr.key.as_ref() {
                        b"x" => 0,
                        b"y" => 1,
                        b"z" => 2,
                        b"name" => {
                            label = Some(value.into_owned());
                            continue;
                        }
                        _ => continue,
                    };
                    xyz[slot] = Some(
                        parse_coordinate(&value)
                            .map_err(|e| coordinate_error(path, line_of(text, start), e))?,
                    );
                }
                let [Some(x), Some(y), Some(z)] = xyz else {
                    return Err(err(start, "<point> lacks an x, y or z attribute".into()));
                };
                lm.push([x, y, z], label);
            }
            _ => {}
        }
    }
    if !root {
        return Err(err(
            0,
            "no <PickedPoints> element (not a MeshLab .pp file)".into(),
        ));
    }
    Ok(lm)
}

pub(super) fn format_picked_points(lm: &Landmarks) -> String {
    let mut s = String::from("<!DOCTYPE PickedPoints>\n<PickedPoints>\n");
    for (i, p) in lm.points.iter().enumerate() {
        let _ = writeln!(
            s,
            " <point x=\"{}\" y=\"{}\" z=\"{}\" active=\"1\" name=\"{}\"/>",
            p[0],
            p[1],
            p[2],
            escape(lm.label(i).unwrap_or(""))
        );
    }
    s.push_str("</PickedPoints>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_meshlab_output() {
        let text = "<!DOCTYPE PickedPoints>\n<PickedPoints>\n <DocumentData>\n  <DataFileName name=\"t.ply\"/>\n </DocumentData>\n <point x=\"1.5\" y=\"2\" z=\"-3\" active=\"1\" name=\"1\"/>\n <point name=\"hypo&amp;conid\" active=\"0\" z=\"0\" y=\"0\" x=\"0\"/>\n</PickedPoints>\n";
        let lm = parse_picked_points(text, Path::new("p.pp")).unwrap();
        assert_eq!(lm.points, vec![[1.5, 2.0, -3.0], [0.0, 0.0, 0.0]]);
        assert_eq!(lm.label(1), Some("hypo&conid"));
        assert_eq!(lm.label(0), Some("1"));
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse_picked_points(
            "<PickedPoints>\n<point x=\"1\" y=\"2\" z=\"3\"/>\n<point x=\"1\" y=\"oops\" z=\"3\"/>\n</PickedPoints>",
            Path::new("p.pp"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("p.pp:3") && e.contains("oops"), "{e}");
        let e = parse_picked_points(
            "<PickedPoints>\n<point x=\"1\" z=\"3\"/>\n</PickedPoints>",
            Path::new("p.pp"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("p.pp:2") && e.contains("lacks"), "{e}");
        assert!(parse_picked_points("just text", Path::new("p.pp")).is_err());
    }
}
