//! Wavefront OBJ reader (geometry only).
//!
//! A small line-based parser rather than `tobj`: it keeps the vertex order
//! and unreferenced vertices of the file (so an OBJ with only `v` lines is a
//! point cloud), reads coordinates in double precision, shares vertices
//! across groups, and reports errors with their line number.
//!
//! `v x y z [w | r g b]` and `f a b c …` (with `a`, `a/t`, `a/t/n` or `a//n`
//! corners, 1-based or negative relative indices) are read; every other
//! statement (`vt`, `vn`, `l`, `p`, `o`, `g`, `s`, `usemtl`, `mtllib`, …)
//! is skipped. A `v` line with fewer than three numbers or an `f` line with
//! fewer than three corners is an error, which also catches most files cut
//! off in the middle of a line.

use super::text::{parse_f64, shorten};
use super::{push_fan, ParseError, ParseResult};
use morphoid_core::mesh::Mesh;

/// Parse an OBJ file.
pub(crate) fn read_obj(bytes: &[u8]) -> ParseResult<Mesh> {
    let mut mesh = Mesh::default();
    let mut poly: Vec<u32> = Vec::new();
    // The largest forward reference and its line, checked at the end.
    let mut forward: Option<(u64, usize)> = None;
    for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line_no = i + 1;
        let line = std::str::from_utf8(raw).map_err(|e| ParseError::NotText {
            line: line_no,
            byte: e.valid_up_to(),
        })?;
        let line = line.split('#').next().unwrap_or("");
        let mut words = line.split_ascii_whitespace();
        match words.next() {
            Some("v") => {
                let values: Vec<&str> = words.collect();
                mesh.vertices.push(vertex(&values, line_no)?);
                if mesh.vertices.len() > u32::MAX as usize {
                    return Err(ParseError::TooManyVertices { line: line_no });
                }
            }
            Some("f") => {
                poly.clear();
                let n = mesh.vertices.len() as i64;
                for corner in words {
                    let index = corner.split('/').next().unwrap_or("");
                    let k: i64 = index.parse().map_err(|_| ParseError::MalformedCorner {
                        line: line_no,
                        corner: shorten(corner),
                    })?;
                    let zero_based = match k {
                        k if k > 0 => k - 1,
                        k if k < 0 => n + k,
                        _ => return Err(ParseError::ZeroIndex { line: line_no }),
                    };
                    if zero_based < 0 {
                        return Err(ParseError::BeforeFirstVertex {
                            line: line_no,
                            index: k,
                        });
                    }
                    if zero_based >= u32::MAX as i64 {
                        return Err(ParseError::IndexOutOfRange {
                            line: line_no,
                            index: k,
                        });
                    }
                    if zero_based >= n && forward.is_none_or(|(m, _)| zero_based as u64 > m) {
                        forward = Some((zero_based as u64, line_no));
                    }
                    poly.push(zero_based as u32);
                }
                if poly.len() < 3 {
                    return Err(ParseError::FewCorners {
                        line: line_no,
                        corners: poly.len(),
                    });
                }
                push_fan(&mut mesh.faces, &poly);
            }
            _ => {}
        }
    }
    if let Some((index, line)) = forward {
        if index >= mesh.vertices.len() as u64 {
            return Err(ParseError::ForwardReference {
                line,
                vertex: index + 1,
                vertices: mesh.vertices.len(),
            });
        }
    }
    Ok(mesh)
}

/// The position of a `v` statement: `x y z`, optionally followed by a
/// homogeneous `w` or a colour `r g b`.
fn vertex(values: &[&str], line_no: usize) -> ParseResult<[f64; 3]> {
    let mut p = [0.0; 3];
    if values.len() < 3 {
        return Err(ParseError::FewCoordinates {
            line: line_no,
            coordinates: values.len(),
        });
    }
    for (k, t) in values.iter().take(3).enumerate() {
        p[k] = parse_f64(t).ok_or_else(|| ParseError::BadCoordinate {
            line: line_no,
            found: shorten(t),
        })?;
    }
    if values.len() == 4 {
        let w =
            parse_f64(values[3])
                .filter(|w| *w != 0.0)
                .ok_or_else(|| ParseError::BadWeight {
                    line: line_no,
                    found: shorten(values[3]),
                })?;
        for c in &mut p {
            *c /= w;
        }
    }
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quads_negative_indices_and_slashes() {
        let text = "# square\nv 0 0 0\nv 1 0 0\nv 1 1 0 1\nv 0 1 0 0.5 0.5 0.5\n\
                    vt 0 0\nvn 0 0 1\ng part\nf 1/1/1 2//1 -2 -1/1\n";
        let m = read_obj(text.as_bytes()).unwrap();
        assert_eq!(m.vertices.len(), 4);
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn truncated_lines_are_errors() {
        let e = read_obj(b"v 0 0 0\nv 1 0 0\nv 1.0 2.").unwrap_err();
        assert_eq!(
            e,
            ParseError::FewCoordinates {
                line: 3,
                coordinates: 2
            }
        );
        assert_eq!(
            e.to_string(),
            "line 3: vertex has 2 coordinate(s), 3 are needed (is the file truncated?)"
        );
        let e = read_obj(b"v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2").unwrap_err();
        assert_eq!(
            e,
            ParseError::FewCorners {
                line: 4,
                corners: 2
            }
        );
    }

    #[test]
    fn vertices_only_is_a_point_cloud() {
        let m = read_obj(b"v 0 0 0\nv 1 0 0\r\nv 1 1 0\n").unwrap();
        assert_eq!(m.vertices.len(), 3);
        assert!(m.faces.is_empty());
    }

    #[test]
    fn index_past_the_end_names_its_line() {
        let e = read_obj(b"v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 9\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "line 4: face refers to vertex 9, but there are only 3 vertices"
        );
    }
}
