//! Stanford PLY reader: ASCII, binary little- and big-endian.
//!
//! Vertex properties may come in any order and with any scalar type; `x`,
//! `y`, `z` are read, everything else is skipped. Faces are the list
//! property `vertex_indices` (or `vertex_index`) of the `face` element,
//! fan-triangulated. Other elements are skipped.

use super::text::{shorten, Tokens};
use super::{check_count, push_fan, Location, ParseError, ParseResult, PlyHeaderProblem};
use morphoid_core::mesh::Mesh;

/// Longest header accepted (bytes).
const MAX_HEADER_BYTES: usize = 1 << 20;
/// Largest polygon accepted (corners).
const MAX_POLYGON: u64 = 1 << 16;

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum PropertyKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
struct Property {
    name: String,
    kind: PropertyKind,
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Storage {
    Ascii,
    BinaryLe,
    BinaryBe,
}

struct Header {
    storage: Storage,
    elements: Vec<Element>,
    /// Byte offset of the body.
    body: usize,
    /// Number of header lines (the body starts on the next line).
    lines: usize,
}

/// What the reader does with each property of an element.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    Skip,
    Coordinate(usize),
    FaceIndices,
}

/// Parse a PLY file.
pub(crate) fn read_ply(bytes: &[u8]) -> ParseResult<Mesh> {
    let header = parse_header(bytes)?;
    let vertex_count = header
        .elements
        .iter()
        .find(|e| e.name == "vertex")
        .map(|e| e.count)
        .ok_or(ParseError::PlyNoVertexElement)?;
    if header.elements.iter().any(|e| e.name == "tristrips") {
        // Skipping them would silently turn the surface into a point cloud.
        return Err(ParseError::PlyTriangleStrips);
    }
    let body = bytes.get(header.body..).unwrap_or(&[]);
    let mut reader = match header.storage {
        Storage::Ascii => Body::Ascii(Tokens::new(body, header.lines + 1, false)),
        Storage::BinaryLe => Body::Binary {
            data: body,
            pos: 0,
            base: header.body,
            last: 0,
            big_endian: false,
        },
        Storage::BinaryBe => Body::Binary {
            data: body,
            pos: 0,
            base: header.body,
            last: 0,
            big_endian: true,
        },
    };
    let mut mesh = Mesh::default();
    let mut have_vertices = false;
    for element in &header.elements {
        let roles = roles_of(element)?;
        let min_row = reader.min_row_bytes(element, &roles);
        let count = check_count(
            &format!("'{}' elements", element.name),
            element.count,
            min_row,
            reader.remaining(),
        )?;
        match element.name.as_str() {
            "vertex" if !have_vertices => {
                have_vertices = true;
                mesh.vertices = read_vertices(&mut reader, element, &roles, count)?;
            }
            "face" if roles.contains(&Role::FaceIndices) => {
                if !mesh.faces.is_empty() {
                    return Err(ParseError::PlyFaceElements);
                }
                mesh.faces = read_faces(&mut reader, element, &roles, count, vertex_count)?;
            }
            _ => skip_rows(&mut reader, element, count)?,
        }
    }
    Ok(mesh)
}

/// Decide the role of every property of an element, checking that the
/// vertex element has `x y z` scalars and the face element an index list.
fn roles_of(element: &Element) -> ParseResult<Vec<Role>> {
    let mut roles = vec![Role::Skip; element.properties.len()];
    match element.name.as_str() {
        "vertex" => {
            for (axis, name) in ["x", "y", "z"].iter().enumerate() {
                let i = element
                    .properties
                    .iter()
                    .position(|p| p.name == *name)
                    .ok_or(ParseError::PlyNoCoordinate { axis: name })?;
                if !matches!(element.properties[i].kind, PropertyKind::Scalar(_)) {
                    return Err(ParseError::PlyCoordinateList { axis: name });
                }
                roles[i] = Role::Coordinate(axis);
            }
        }
        "face" => {
            let found = element
                .properties
                .iter()
                .position(|p| p.name == "vertex_indices" || p.name == "vertex_index");
            let Some(i) = found else {
                if element.count == 0 {
                    return Ok(roles);
                }
                // Skipping the faces would silently give a point cloud.
                return Err(ParseError::PlyNoFaceIndices);
            };
            match element.properties[i].kind {
                PropertyKind::List { count, item } if count.is_integer() && item.is_integer() => {
                    roles[i] = Role::FaceIndices
                }
                _ => {
                    return Err(ParseError::PlyFaceIndicesType {
                        property: element.properties[i].name.clone(),
                    })
                }
            }
        }
        _ => {}
    }
    Ok(roles)
}

fn read_vertices(
    reader: &mut Body,
    element: &Element,
    roles: &[Role],
    count: usize,
) -> ParseResult<Vec<[f64; 3]>> {
    let mut vertices = Vec::with_capacity(count);
    for vi in 0..count {
        let mut p = [0.0; 3];
        for (prop, role) in element.properties.iter().zip(roles) {
            match (prop.kind, role) {
                (PropertyKind::Scalar(t), Role::Coordinate(axis)) => {
                    let v = reader.scalar(t, "vertex coordinate")?;
                    if !v.is_finite() {
                        return Err(ParseError::PlyNonFiniteVertex {
                            vertex: vi,
                            value: v,
                            at: reader.location(),
                        });
                    }
                    p[*axis] = v;
                }
                (PropertyKind::Scalar(t), _) => reader.skip_scalar(t, &prop.name)?,
                (PropertyKind::List { count, item }, _) => {
                    reader.skip_list(count, item, &prop.name)?
                }
            }
        }
        vertices.push(p);
    }
    Ok(vertices)
}

fn read_faces(
    reader: &mut Body,
    element: &Element,
    roles: &[Role],
    count: usize,
    vertex_count: u64,
) -> ParseResult<Vec<[u32; 3]>> {
    let mut faces = Vec::with_capacity(count);
    let mut poly: Vec<u32> = Vec::new();
    for fi in 0..count {
        for (prop, role) in element.properties.iter().zip(roles) {
            match (prop.kind, role) {
                (PropertyKind::List { count, item }, Role::FaceIndices) => {
                    let n = reader.list_count(count, &prop.name)?;
                    if !(3..=MAX_POLYGON).contains(&n) {
                        return Err(ParseError::PlyPolygonSize {
                            face: fi,
                            corners: n,
                            max: MAX_POLYGON,
                            at: reader.location(),
                        });
                    }
                    poly.clear();
                    for _ in 0..n {
                        let v = reader.scalar(item, "vertex index")?;
                        if !(v >= 0.0 && v < vertex_count as f64) {
                            return Err(ParseError::PlyFaceOutOfRange {
                                face: fi,
                                vertex: v,
                                vertices: vertex_count,
                                at: reader.location(),
                            });
                        }
                        poly.push(v as u32);
                    }
                    push_fan(&mut faces, &poly);
                }
                (PropertyKind::Scalar(t), _) => reader.skip_scalar(t, &prop.name)?,
                (PropertyKind::List { count, item }, _) => {
                    reader.skip_list(count, item, &prop.name)?
                }
            }
        }
    }
    Ok(faces)
}

fn skip_rows(reader: &mut Body, element: &Element, count: usize) -> ParseResult<()> {
    // Fixed-size binary rows are skipped in one step.
    let fixed: Option<usize> = element
        .properties
        .iter()
        .map(|p| match p.kind {
            PropertyKind::Scalar(t) => Some(t.size()),
            PropertyKind::List { .. } => None,
        })
        .sum();
    if let (Body::Binary { data, pos, .. }, Some(row)) = (&mut *reader, fixed) {
        let n = row.saturating_mul(count);
        if data.len().saturating_sub(*pos) < n {
            return Err(ParseError::TruncatedElement {
                element: element.name.clone(),
            });
        }
        *pos += n;
        return Ok(());
    }
    for _ in 0..count {
        for prop in &element.properties {
            match prop.kind {
                PropertyKind::Scalar(t) => reader.skip_scalar(t, &prop.name)?,
                PropertyKind::List { count, item } => reader.skip_list(count, item, &prop.name)?,
            }
        }
    }
    Ok(())
}

/// The body of a PLY file, as a cursor.
enum Body<'a> {
    Ascii(Tokens<'a>),
    Binary {
        data: &'a [u8],
        pos: usize,
        /// Offset of `data` in the file, for messages.
        base: usize,
        /// Offset in `data` of the scalar read last, for messages.
        last: usize,
        big_endian: bool,
    },
}

impl Body<'_> {
    fn remaining(&self) -> usize {
        match self {
            Body::Ascii(t) => t.remaining(),
            Body::Binary { data, pos, .. } => data.len().saturating_sub(*pos),
        }
    }

    /// Where the value read last is, for messages.
    fn location(&self) -> Location {
        match self {
            Body::Ascii(t) => Location::Line(t.line()),
            Body::Binary { base, last, .. } => Location::ByteOffset(base + last),
        }
    }

    /// The fewest bytes one row of `element` can take, so that claimed
    /// counts can be checked against the file size.
    fn min_row_bytes(&self, element: &Element, roles: &[Role]) -> u64 {
        let ascii = matches!(self, Body::Ascii(_));
        let mut bytes = 0u64;
        for (p, role) in element.properties.iter().zip(roles) {
            // (tokens, binary bytes) of the smallest possible value.
            let (tokens, binary) = match (p.kind, role) {
                (PropertyKind::Scalar(t), _) => (1, t.size()),
                // A face has at least three corners.
                (PropertyKind::List { count, item }, Role::FaceIndices) => {
                    (4, count.size() + 3 * item.size())
                }
                (PropertyKind::List { count, .. }, _) => (1, count.size()),
            };
            // An ASCII token takes at least one character and a separator.
            bytes += if ascii { 2 * tokens } else { binary as u64 };
        }
        if ascii {
            // The very last token needs no separator.
            bytes = bytes.saturating_sub(1).max(1);
        }
        bytes
    }

    /// Read one scalar of type `t` as `f64` (exact for every PLY integer).
    fn scalar(&mut self, t: Scalar, what: &str) -> ParseResult<f64> {
        match self {
            Body::Ascii(tokens) => {
                let tok = tokens.expect(what)?;
                let v = if t.is_integer() {
                    tok.parse::<i64>().ok().map(|i| i as f64)
                } else {
                    tok.parse::<f64>().ok()
                };
                v.ok_or_else(|| ParseError::Expected {
                    line: tokens.line(),
                    expected: what.to_string(),
                    found: shorten(tok),
                })
            }
            Body::Binary {
                data,
                pos,
                base,
                last,
                big_endian,
            } => {
                let size = t.size();
                let b = data
                    .get(*pos..*pos + size)
                    .ok_or_else(|| ParseError::TruncatedAt {
                        offset: *base + *pos,
                        reading: what.to_string(),
                    })?;
                *last = *pos;
                *pos += size;
                Ok(decode(t, b, *big_endian))
            }
        }
    }

    fn skip_scalar(&mut self, t: Scalar, name: &str) -> ParseResult<()> {
        self.scalar(t, &format!("property '{name}'")).map(|_| ())
    }

    /// Read a list length, which must be a non-negative integer.
    fn list_count(&mut self, t: Scalar, name: &str) -> ParseResult<u64> {
        let n = self.scalar(t, &format!("length of list '{name}'"))?;
        if n >= 0.0 && n.fract() == 0.0 {
            Ok(n as u64)
        } else {
            Err(ParseError::PlyListLength {
                length: n,
                list: name.to_string(),
                at: self.location(),
            })
        }
    }

    fn skip_list(&mut self, count: Scalar, item: Scalar, name: &str) -> ParseResult<()> {
        let n = self.list_count(count, name)?;
        if let Body::Binary { data, pos, .. } = self {
            let bytes = n.saturating_mul(item.size() as u64);
            if (data.len().saturating_sub(*pos) as u64) < bytes {
                return Err(ParseError::TruncatedList {
                    list: name.to_string(),
                });
            }
            *pos += bytes as usize;
            return Ok(());
        }
        for _ in 0..n {
            self.skip_scalar(item, name)?;
        }
        Ok(())
    }
}

/// Decode a binary scalar (`b` has exactly `t.size()` bytes).
fn decode(t: Scalar, b: &[u8], big_endian: bool) -> f64 {
    macro_rules! num {
        ($ty:ty, $n:expr) => {{
            let mut a = [0u8; $n];
            a.copy_from_slice(b);
            if big_endian {
                <$ty>::from_be_bytes(a) as f64
            } else {
                <$ty>::from_le_bytes(a) as f64
            }
        }};
    }
    match t {
        Scalar::I8 => num!(i8, 1),
        Scalar::U8 => num!(u8, 1),
        Scalar::I16 => num!(i16, 2),
        Scalar::U16 => num!(u16, 2),
        Scalar::I32 => num!(i32, 4),
        Scalar::U32 => num!(u32, 4),
        Scalar::F32 => num!(f32, 4),
        Scalar::F64 => num!(f64, 8),
    }
}

fn parse_header(bytes: &[u8]) -> ParseResult<Header> {
    if !bytes.starts_with(b"ply") {
        return Err(ParseError::NotPly);
    }
    let mut storage = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut pos = 0usize;
    let mut line_no = 0usize;
    loop {
        if pos >= bytes.len().min(MAX_HEADER_BYTES) {
            return Err(if bytes.len() > MAX_HEADER_BYTES {
                ParseError::PlyHeaderTooLong {
                    limit: MAX_HEADER_BYTES,
                }
            } else {
                ParseError::PlyHeaderTruncated
            });
        }
        let rest = &bytes[pos..];
        let len = rest.iter().position(|&b| b == b'\n');
        let raw = &rest[..len.unwrap_or(rest.len())];
        pos += raw.len() + 1;
        line_no += 1;
        let line =
            std::str::from_utf8(raw).map_err(|_| ParseError::PlyHeaderNotText { line: line_no })?;
        let mut words = line.split_ascii_whitespace();
        let keyword = words.next().unwrap_or("");
        let words: Vec<&str> = words.collect();
        let bad = |problem| ParseError::PlyHeaderLine {
            line: line_no,
            problem,
            text: shorten(line),
        };
        match keyword {
            "ply" if line_no == 1 => {}
            "" | "comment" | "obj_info" => {}
            "format" => {
                storage = Some(match words.as_slice() {
                    ["ascii", _] => Storage::Ascii,
                    ["binary_little_endian", _] => Storage::BinaryLe,
                    ["binary_big_endian", _] => Storage::BinaryBe,
                    _ => return Err(bad(PlyHeaderProblem::UnknownFormat)),
                });
            }
            "element" => {
                let [name, count] = words.as_slice() else {
                    return Err(bad(PlyHeaderProblem::MalformedElement));
                };
                let count = count
                    .parse::<u64>()
                    .map_err(|_| bad(PlyHeaderProblem::ElementCount))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            "property" => {
                let element = elements
                    .last_mut()
                    .ok_or_else(|| bad(PlyHeaderProblem::PropertyFirst))?;
                let (kind, name) = match words.as_slice() {
                    ["list", c, i, name] => match (Scalar::parse(c), Scalar::parse(i)) {
                        (Some(count), Some(item)) if count.is_integer() => {
                            (PropertyKind::List { count, item }, name)
                        }
                        _ => return Err(bad(PlyHeaderProblem::UnknownListTypes)),
                    },
                    [t, name] => (
                        PropertyKind::Scalar(
                            Scalar::parse(t).ok_or_else(|| bad(PlyHeaderProblem::UnknownType))?,
                        ),
                        name,
                    ),
                    _ => return Err(bad(PlyHeaderProblem::MalformedProperty)),
                };
                element.properties.push(Property {
                    name: name.to_string(),
                    kind,
                });
            }
            "end_header" => {
                // A '\r\n' line end leaves '\r' in `line`, already trimmed
                // by the whitespace split; the body starts after '\n'.
                let storage = storage.ok_or(ParseError::PlyNoFormat)?;
                return Ok(Header {
                    storage,
                    elements,
                    body: pos.min(bytes.len()),
                    lines: line_no,
                });
            }
            _ => return Err(bad(PlyHeaderProblem::UnknownKeyword)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ascii_with_extra_properties_and_quads() {
        let text = "ply\nformat ascii 1.0\ncomment hi\nelement vertex 4\n\
                    property uchar red\nproperty float z\nproperty double x\nproperty int y\n\
                    element face 1\nproperty list uchar uint vertex_index\nproperty float q\n\
                    end_header\n\
                    255 0.5 0 0\n1 0 1 0\n2 0 1 1\n3 0 0 1\n4 0 1 2 3 9.5\n";
        let m = read_ply(text.as_bytes()).unwrap();
        assert_eq!(m.vertices.len(), 4);
        assert_eq!(m.vertices[0], [0.0, 0.0, 0.5]);
        assert_eq!(m.vertices[2], [1.0, 1.0, 0.0]);
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn huge_claimed_count_fails_before_allocating() {
        let text = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n\
                    property float x\nproperty float y\nproperty float z\nend_header\n";
        let err = read_ply(text.as_bytes()).unwrap_err();
        assert_eq!(
            err.to_string(),
            "header claims 4000000000 'vertex' elements, which cannot fit in the remaining 0 \
             bytes"
        );
    }

    #[test]
    fn index_out_of_range_is_reported() {
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                    property float y\nproperty float z\nelement face 1\n\
                    property list uchar int vertex_indices\nend_header\n\
                    0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n";
        let err = read_ply(text.as_bytes()).unwrap_err();
        assert_eq!(
            err,
            ParseError::PlyFaceOutOfRange {
                face: 0,
                vertex: 3.0,
                vertices: 3,
                at: Location::Line(13),
            }
        );
        assert_eq!(
            err.to_string(),
            "face 0 refers to vertex 3, but there are only 3 vertices (line 13)"
        );
    }

    #[test]
    fn faces_without_an_index_list_are_an_error() {
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                    property float y\nproperty float z\nelement face 1\n\
                    property list uchar int corners\nend_header\n\
                    0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        let err = read_ply(text.as_bytes()).unwrap_err();
        assert_eq!(err, ParseError::PlyNoFaceIndices);
        assert_eq!(
            err.to_string(),
            "PLY face element has no 'vertex_indices' list"
        );
        let strips = text.replace("element face 1", "element tristrips 1");
        assert!(read_ply(strips.as_bytes()).is_err());
    }

    #[test]
    fn negative_list_length_is_an_error() {
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                    property float y\nproperty float z\nelement face 1\n\
                    property list char int vertex_indices\nend_header\n\
                    0 0 0\n1 0 0\n0 1 0\n-3 0 1 2\n";
        assert!(read_ply(text.as_bytes()).is_err());
    }
}
