//! STL reader, binary and ASCII. ASCII STL loads as a triangle soup (three
//! vertices per triangle; welding is left to cleaning); binary STL, the
//! form big exports take, shares bit-identical corners while it is read.
//!
//! A file is binary exactly when its size is `84 + 50·n` for the triangle
//! count `n` stored at byte 80: binary files often start with "solid" too,
//! so the leading word alone decides nothing. An ASCII file cannot pass for
//! binary: its bytes 80–83 are text, which read as a count of at least
//! 0x09090909 triangles, far more than the size limit allows.

use super::text::{shorten, Tokens};
use super::{push_fan, ParseError, ParseResult, StlSize};
use morphoid_core::mesh::Mesh;
use rustc_hash::FxHashMap as HashMap;

/// Parse an STL file.
pub(crate) fn read_stl(bytes: &[u8]) -> ParseResult<Mesh> {
    if let Some(n) = binary_triangle_count(bytes) {
        return read_binary(bytes, n);
    }
    let start = bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(bytes.len());
    let begins_solid = bytes
        .get(start..start + 5)
        .is_some_and(|w| w.eq_ignore_ascii_case(b"solid"));
    let size_mismatch = bytes.get(80..84).map(|c| StlSize {
        bytes: bytes.len(),
        triangles: u32::from_le_bytes([c[0], c[1], c[2], c[3]]),
    });
    if begins_solid {
        return read_ascii(bytes).map_err(|e| {
            // A binary file whose header happens to start with "solid".
            let binary = bytes.iter().take(4096).any(|&b| b == 0 || b >= 0x80);
            match (binary, size_mismatch) {
                (true, Some(size)) => ParseError::StlBinaryAfterSolid { size },
                _ => e,
            }
        });
    }
    Err(match size_mismatch {
        Some(size) => ParseError::NotStl { size },
        None => ParseError::StlTooShort { size: bytes.len() },
    })
}

/// The triangle count when the size matches a binary STL exactly.
fn binary_triangle_count(bytes: &[u8]) -> Option<usize> {
    let c = bytes.get(80..84)?;
    let n = u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as u64;
    (84 + 50 * n == bytes.len() as u64).then_some(n as usize)
}

fn read_binary(bytes: &[u8], n: usize) -> ParseResult<Mesh> {
    // The size check above bounds n by the file size.
    let mut soup = SharedCorners::with_triangles(n);
    for (t, record) in bytes[84..].chunks_exact(RECORD).enumerate() {
        soup.push(t, record)?;
    }
    Ok(soup.into_mesh())
}

/// Bytes of one binary STL triangle record.
const RECORD: usize = 50;

/// The triangle count of a binary STL whose first 84 bytes are `header`,
/// when `size` (the file's bytes) is exactly `84 + 50·n`; `None` when the
/// file is not binary STL (the caller reads it as ASCII).
pub(crate) fn binary_count(header: &[u8; 84], size: u64) -> Option<usize> {
    let n = u32::from_le_bytes([header[80], header[81], header[82], header[83]]) as u64;
    (84 + RECORD as u64 * n == size).then_some(n as usize)
}

/// Read the `n` triangle records that follow a binary STL's header from
/// `reader`, one at a time, without holding the file in memory (a µCT
/// export can be hundreds of megabytes). `Err` carries the I/O error or
/// what is wrong with a bad record; the caller attaches the file name.
pub(crate) fn read_binary_records<R: std::io::Read>(
    reader: &mut R,
    n: usize,
) -> Result<Mesh, BinaryFileError> {
    let mut soup = SharedCorners::with_triangles(n);
    let mut record = [0u8; RECORD];
    for t in 0..n {
        reader
            .read_exact(&mut record)
            .map_err(BinaryFileError::Io)?;
        soup.push(t, &record).map_err(BinaryFileError::Invalid)?;
    }
    Ok(soup.into_mesh())
}

/// Bytes a reader of binary STL buffers: many records per read.
pub(crate) const READ_BUFFER: usize = RECORD * 4096;

/// Why [`read_binary_records`] failed.
#[derive(Debug)]
pub(crate) enum BinaryFileError {
    /// Reading failed (or the file shrank while it was read).
    Io(std::io::Error),
    /// A record is unusable.
    Invalid(ParseError),
}

/// A binary STL's triangles as they are read: corners with bit-identical
/// coordinates become one vertex. A µCT export holds millions of
/// triangles, and a soup of three f64 vertices per triangle would take six
/// times the memory of the shared vertices, only for cleaning to weld them
/// again; merging identical positions is what welding does first anyway,
/// whatever its tolerance.
struct SharedCorners {
    index: HashMap<[u32; 3], u32>,
    vertices: Vec<[f64; 3]>,
    faces: Vec<[u32; 3]>,
}

impl SharedCorners {
    fn with_triangles(n: usize) -> Self {
        // A closed surface has about half as many vertices as triangles.
        let mut index = HashMap::default();
        index.reserve(n / 2 + 8);
        SharedCorners {
            index,
            vertices: Vec::with_capacity(n / 2 + 8),
            faces: Vec::with_capacity(n),
        }
    }

    /// Add triangle `t` from its 50-byte record.
    fn push(&mut self, t: usize, record: &[u8]) -> ParseResult<()> {
        let mut face = [0u32; 3];
        for (k, corner) in face.iter_mut().enumerate() {
            let mut p = [0.0f32; 3];
            for (c, value) in p.iter_mut().enumerate() {
                let o = 12 + 12 * k + 4 * c;
                let v =
                    f32::from_le_bytes([record[o], record[o + 1], record[o + 2], record[o + 3]]);
                if !v.is_finite() {
                    return Err(ParseError::StlNonFinite {
                        triangle: t,
                        offset: 84 + RECORD * t + o,
                    });
                }
                // -0.0 and 0.0 are the same position.
                *value = if v == 0.0 { 0.0 } else { v };
            }
            let vertices = &mut self.vertices;
            *corner = *self.index.entry(p.map(f32::to_bits)).or_insert_with(|| {
                vertices.push(p.map(f64::from));
                (vertices.len() - 1) as u32
            });
        }
        self.faces.push(face);
        Ok(())
    }

    fn into_mesh(self) -> Mesh {
        Mesh::new(self.vertices, self.faces)
    }
}

/// Compare a keyword case-insensitively, with a message naming the line.
fn keyword(t: &mut Tokens, want: &str) -> ParseResult<()> {
    let got = t.expect(&format!("'{want}'"))?;
    if got.eq_ignore_ascii_case(want) {
        Ok(())
    } else {
        Err(ParseError::Expected {
            line: t.line(),
            expected: format!("'{want}'"),
            found: shorten(got),
        })
    }
}

fn read_ascii(bytes: &[u8]) -> ParseResult<Mesh> {
    let mut t = Tokens::new(bytes, 1, false);
    keyword(&mut t, "solid")?;
    t.skip_line();
    let mut mesh = Mesh::default();
    let mut poly: Vec<u32> = Vec::new();
    loop {
        let Some(word) = t.next_token() else {
            return Err(ParseError::StlNoEndsolid);
        };
        if word.eq_ignore_ascii_case("endsolid") {
            t.skip_line();
            // Several solids may follow each other.
            match t.next_token() {
                None => return Ok(mesh),
                Some(w) if w.eq_ignore_ascii_case("solid") => {
                    t.skip_line();
                    continue;
                }
                Some(w) => {
                    return Err(ParseError::StlAfterEndsolid {
                        line: t.line(),
                        found: shorten(w),
                    })
                }
            }
        }
        if !word.eq_ignore_ascii_case("facet") {
            return Err(ParseError::Expected {
                line: t.line(),
                expected: "'facet' or 'endsolid'".into(),
                found: shorten(word),
            });
        }
        keyword(&mut t, "normal")?;
        for _ in 0..3 {
            // The stored normal is not used, and may be anything numeric.
            let w = t.expect("a normal component")?;
            if w.parse::<f64>().is_err() {
                return Err(ParseError::Expected {
                    line: t.line(),
                    expected: "a normal component".into(),
                    found: shorten(w),
                });
            }
        }
        keyword(&mut t, "outer")?;
        keyword(&mut t, "loop")?;
        poly.clear();
        loop {
            let w = t.expect("'vertex' or 'endloop'")?;
            if w.eq_ignore_ascii_case("endloop") {
                break;
            }
            if !w.eq_ignore_ascii_case("vertex") {
                return Err(ParseError::Expected {
                    line: t.line(),
                    expected: "'vertex' or 'endloop'".into(),
                    found: shorten(w),
                });
            }
            let mut p = [0.0; 3];
            for c in &mut p {
                *c = t.expect_f64("a vertex coordinate")?;
            }
            if mesh.vertices.len() >= u32::MAX as usize {
                return Err(ParseError::TooManyVertices { line: t.line() });
            }
            poly.push(mesh.vertices.len() as u32);
            mesh.vertices.push(p);
        }
        if poly.len() < 3 {
            return Err(ParseError::StlFewVertices {
                line: t.line(),
                vertices: poly.len(),
            });
        }
        push_fan(&mut mesh.faces, &poly);
        keyword(&mut t, "endfacet")?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASCII: &str = "solid test\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n\
                         vertex 1 0 0\n vertex 0 1 0\n endloop\n endfacet\nendsolid test\n";

    #[test]
    fn ascii_triangle() {
        let m = read_stl(ASCII.as_bytes()).unwrap();
        assert_eq!(m.vertices.len(), 3);
        assert_eq!(m.faces, vec![[0, 1, 2]]);
        assert_eq!(m.vertices[1], [1.0, 0.0, 0.0]);
    }

    #[test]
    fn truncated_ascii_is_an_error() {
        let cut = &ASCII[..ASCII.len() - 30];
        assert!(read_stl(cut.as_bytes()).is_err());
        assert_eq!(read_stl(b"solid x\n"), Err(ParseError::StlNoEndsolid));
        assert_eq!(
            ParseError::StlNoEndsolid.to_string(),
            "ASCII STL ends without 'endsolid' (is the file truncated?)"
        );
    }

    #[test]
    fn binary_with_solid_header() {
        let mut b = b"solid pretending to be ascii".to_vec();
        b.resize(80, b' ');
        b.extend_from_slice(&1u32.to_le_bytes());
        for v in [[0f32, 0., 1.], [0., 0., 0.], [2., 0., 0.], [0., 3., 0.]] {
            for c in v {
                b.extend_from_slice(&c.to_le_bytes());
            }
        }
        b.extend_from_slice(&[0, 0]);
        let m = read_stl(&b).unwrap();
        assert_eq!(m.vertices, vec![[0., 0., 0.], [2., 0., 0.], [0., 3., 0.]]);
    }
}
