//! OFF reader (ASCII): `[C|N|ST…]OFF`, counts, vertices, polygons.
//!
//! Anything after the three coordinates of a vertex line (colours, normals,
//! texture coordinates) and after the indices of a face line (colours) is
//! skipped. `#` starts a comment. The keyword line may be absent.

use super::text::{shorten, Tokens};
use super::{check_count, push_fan, ParseError, ParseResult};
use morphoid_core::mesh::Mesh;

/// Largest polygon accepted (corners).
const MAX_POLYGON: u64 = 1 << 16;

/// Parse an OFF file.
pub(crate) fn read_off(bytes: &[u8]) -> ParseResult<Mesh> {
    let first_line = bytes.split(|&b| b == b'\n').next().unwrap_or(&[]);
    if first_line.windows(6).any(|w| w == b"BINARY") {
        return Err(ParseError::BinaryOff);
    }
    let mut t = Tokens::new(bytes, 1, true);
    let keyword = t.expect("'OFF'")?;
    let counts_follow_keyword = keyword.ends_with("OFF");
    if counts_follow_keyword {
        if keyword.starts_with('4') || keyword.starts_with('n') {
            return Err(ParseError::NotThreeDimensionalOff {
                keyword: shorten(keyword),
            });
        }
    } else if keyword.parse::<u64>().is_err() {
        return Err(ParseError::NotOff {
            start: shorten(keyword),
        });
    }
    let nv = if counts_follow_keyword {
        t.expect_u64("the vertex count")?
    } else {
        // No keyword: the first token is already the vertex count.
        keyword.parse::<u64>().unwrap_or(0)
    };
    let nf = t.expect_u64("the face count")?;
    // The edge count is ignored (and often wrong).
    t.skip_line();
    // "x y z\n" takes at least 6 bytes, "3 a b c\n" at least 8.
    let nv = check_count("vertices", nv, 6, t.remaining())?;
    let nf_usize = check_count("faces", nf, 8, t.remaining().saturating_sub(6 * nv))?;
    let mut vertices = Vec::with_capacity(nv);
    for _ in 0..nv {
        let mut p = [0.0; 3];
        for c in &mut p {
            *c = t.expect_f64("a vertex coordinate")?;
        }
        vertices.push(p);
        t.skip_line();
    }
    let mut faces = Vec::with_capacity(nf_usize);
    let mut poly = Vec::new();
    for fi in 0..nf_usize {
        let n = t.expect_u64("a face's corner count")?;
        if !(3..=MAX_POLYGON).contains(&n) {
            return Err(ParseError::OffPolygonSize {
                line: t.line(),
                face: fi,
                corners: n,
                max: MAX_POLYGON,
            });
        }
        poly.clear();
        for _ in 0..n {
            let v = t.expect_u64("a vertex index")?;
            if v >= nv as u64 {
                return Err(ParseError::OffFaceOutOfRange {
                    line: t.line(),
                    face: fi,
                    vertex: v,
                    vertices: nv,
                });
            }
            poly.push(v as u32);
        }
        push_fan(&mut faces, &poly);
        t.skip_line();
    }
    Ok(Mesh::new(vertices, faces))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colors_comments_and_polygons() {
        let text = "COFF\n# a square\n4 1 4\n0 0 0 255 0 0 255\n1 0 0 255 0 0 255\n\
                    1 1 0 1 2 3 4 # corner\n0 1 0 9 9 9 9\n4 0 1 2 3 200 10 10\n";
        let m = read_off(text.as_bytes()).unwrap();
        assert_eq!(m.vertices.len(), 4);
        assert_eq!(m.vertices[2], [1.0, 1.0, 0.0]);
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn counts_on_the_keyword_line_and_no_keyword() {
        let a = read_off(b"OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").unwrap();
        let b = read_off(b"3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").unwrap();
        assert_eq!(a, b);
        assert_eq!(a.faces.len(), 1);
    }

    #[test]
    fn bad_files() {
        assert!(read_off(b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n").is_err());
        assert!(read_off(b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1\n").is_err());
        let e = read_off(b"OFF\n4000000000 1 0\n0 0 0\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "header claims 4000000000 vertices, which cannot fit in the remaining 6 bytes"
        );
        assert!(read_off(b"PLY\n").is_err());
    }
}
