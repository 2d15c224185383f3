//! What the mesh readers report about a malformed file, before the file
//! name is attached ([`super::LoadError::Invalid`] carries it as its
//! source). Every message is one line: the text a variant quotes from the
//! file (a token, a header line) is cut and has its control characters
//! replaced ([`super::text::shorten`]), and the names it holds (elements,
//! properties) are single words of a header line.

use std::fmt;

/// Why a mesh file's content cannot be read: what is wrong and, where the
/// reader knows it, the line or byte offset.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParseError {
    /// The file holds no bytes.
    #[error("file is empty")]
    Empty,
    /// The file was read, but it holds no vertex.
    #[error("file contains no vertices")]
    NoVertices,
    /// A vertex read has a coordinate that is infinite or NaN.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFiniteVertex {
        /// The vertex (0-based).
        vertex: usize,
    },
    /// A face read refers to a vertex past the last one.
    #[error("face {face} refers to vertex {vertex}, but there are only {vertices} vertices")]
    FaceOutOfRange {
        /// The triangle (0-based).
        face: usize,
        /// The vertex it refers to (0-based).
        vertex: u32,
        /// How many vertices there are.
        vertices: usize,
    },
    /// A count in the header is more than the rest of the file can hold.
    #[error("header claims {count} {what}, which cannot fit in the remaining {remaining} bytes")]
    CountTooLarge {
        /// What is counted (`vertices`, `faces`, `'face' elements`).
        what: String,
        /// The count claimed.
        count: u64,
        /// The bytes left in the file after the header.
        remaining: usize,
    },
    /// The file ends where more was expected.
    #[error("unexpected end of file after line {line} (expected {expected})")]
    UnexpectedEnd {
        /// The last line (1-based).
        line: usize,
        /// What was expected next.
        expected: String,
    },
    /// A token is not what was expected there.
    #[error("line {line}: expected {expected}, found '{found}'")]
    Expected {
        /// The token's line (1-based).
        line: usize,
        /// What was expected (`a vertex coordinate`, `'normal'`, …).
        expected: String,
        /// The token found (shortened).
        found: String,
    },
    /// A token is not the non-negative integer expected there.
    #[error("line {line}: expected {expected} (a non-negative integer), found '{found}'")]
    ExpectedInteger {
        /// The token's line (1-based).
        line: usize,
        /// What was expected (`the vertex count`, …).
        expected: String,
        /// The token found (shortened).
        found: String,
    },
    /// A line is not UTF-8 text.
    #[error("line {line}: not text (invalid UTF-8 at byte {byte} of the line)")]
    NotText {
        /// The line (1-based).
        line: usize,
        /// The offset of the first invalid byte in the line.
        byte: usize,
    },
    /// More vertices than a face index can address.
    #[error("line {line}: too many vertices")]
    TooManyVertices {
        /// The line of the vertex that is one too many (1-based).
        line: usize,
    },
    /// An OBJ face corner that does not start with an integer index.
    #[error("line {line}: malformed face corner '{corner}'")]
    MalformedCorner {
        /// The line (1-based).
        line: usize,
        /// The corner (shortened).
        corner: String,
    },
    /// An OBJ face index of 0 (OBJ indices start at 1).
    #[error("line {line}: face index 0 (OBJ counts from 1)")]
    ZeroIndex {
        /// The line (1-based).
        line: usize,
    },
    /// A negative (relative) OBJ face index that reaches before the first
    /// vertex.
    #[error("line {line}: relative face index {index} reaches before the first vertex")]
    BeforeFirstVertex {
        /// The line (1-based).
        line: usize,
        /// The index as written.
        index: i64,
    },
    /// An OBJ face index too large for any mesh.
    #[error("line {line}: face index {index} is out of range")]
    IndexOutOfRange {
        /// The line (1-based).
        line: usize,
        /// The index as written.
        index: i64,
    },
    /// An OBJ face with fewer than three corners.
    #[error(
        "line {line}: face has {corners} corner(s), at least 3 are needed (is the file \
         truncated?)"
    )]
    FewCorners {
        /// The line (1-based).
        line: usize,
        /// The corners it has.
        corners: usize,
    },
    /// An OBJ face refers to a vertex that the file never defines.
    #[error("line {line}: face refers to vertex {vertex}, but there are only {vertices} vertices")]
    ForwardReference {
        /// The line of the face (1-based).
        line: usize,
        /// The vertex it refers to (1-based, as OBJ counts).
        vertex: u64,
        /// How many vertices the file defines.
        vertices: usize,
    },
    /// An OBJ vertex with fewer than three coordinates.
    #[error(
        "line {line}: vertex has {coordinates} coordinate(s), 3 are needed (is the file \
         truncated?)"
    )]
    FewCoordinates {
        /// The line (1-based).
        line: usize,
        /// The coordinates it has.
        coordinates: usize,
    },
    /// An OBJ vertex coordinate that is not a finite number.
    #[error("line {line}: vertex coordinate '{found}' is not a finite number")]
    BadCoordinate {
        /// The line (1-based).
        line: usize,
        /// The coordinate as written (shortened).
        found: String,
    },
    /// An OBJ homogeneous weight `w` that is zero or not a number.
    #[error("line {line}: homogeneous weight '{found}' is not a non-zero number")]
    BadWeight {
        /// The line (1-based).
        line: usize,
        /// The weight as written (shortened).
        found: String,
    },
    /// A binary OFF file.
    #[error("binary OFF is not supported")]
    BinaryOff,
    /// An OFF file of another dimension than 3 (`4OFF`, `nOFF`).
    #[error("line 1: '{keyword}' is not a 3-D OFF file")]
    NotThreeDimensionalOff {
        /// The keyword (shortened).
        keyword: String,
    },
    /// A file read as OFF that starts with neither `OFF` nor a count.
    #[error("not an OFF file (it starts with '{start}', not 'OFF')")]
    NotOff {
        /// Its first word (shortened).
        start: String,
    },
    /// An OFF face with fewer than three or too many corners.
    #[error("line {line}: face {face} has {corners} corners (3 to {max} allowed)")]
    OffPolygonSize {
        /// The line (1-based).
        line: usize,
        /// The face (0-based).
        face: usize,
        /// The corners it claims.
        corners: u64,
        /// The most corners a face may have.
        max: u64,
    },
    /// An OFF face refers to a vertex past the last one.
    #[error(
        "line {line}: face {face} refers to vertex {vertex}, but there are only {vertices} \
         vertices"
    )]
    OffFaceOutOfRange {
        /// The line (1-based).
        line: usize,
        /// The face (0-based).
        face: usize,
        /// The vertex it refers to (0-based).
        vertex: u64,
        /// How many vertices there are.
        vertices: usize,
    },
    /// A file read as PLY that does not start with `ply`.
    #[error("not a PLY file (it does not start with 'ply')")]
    NotPly,
    /// A PLY header longer than the readers take.
    #[error("PLY header has no 'end_header' in its first {limit} bytes")]
    PlyHeaderTooLong {
        /// The longest header taken (bytes).
        limit: usize,
    },
    /// A PLY file that ends inside its header.
    #[error("PLY header is truncated (no 'end_header')")]
    PlyHeaderTruncated,
    /// A PLY header line that is not UTF-8 text.
    #[error("PLY header line {line} is not text")]
    PlyHeaderNotText {
        /// The line (1-based).
        line: usize,
    },
    /// A PLY header line that cannot be read.
    #[error("PLY header line {line}: {problem}: '{text}'")]
    PlyHeaderLine {
        /// The line (1-based).
        line: usize,
        /// What is wrong with it.
        problem: PlyHeaderProblem,
        /// The line (shortened).
        text: String,
    },
    /// A PLY header without a `format` line.
    #[error("PLY header has no 'format' line")]
    PlyNoFormat,
    /// A PLY header without a `vertex` element.
    #[error("PLY header has no 'vertex' element")]
    PlyNoVertexElement,
    /// A PLY file of triangle strips, which the reader does not take.
    #[error("PLY triangle strips ('tristrips') are not supported")]
    PlyTriangleStrips,
    /// A PLY file with two face elements.
    #[error("PLY file has more than one 'face' element")]
    PlyFaceElements,
    /// A PLY vertex element without one of `x`, `y`, `z`.
    #[error("PLY vertex element has no property '{axis}'")]
    PlyNoCoordinate {
        /// The missing coordinate (`x`, `y` or `z`).
        axis: &'static str,
    },
    /// A PLY vertex coordinate declared as a list.
    #[error("PLY vertex property '{axis}' is a list")]
    PlyCoordinateList {
        /// The coordinate (`x`, `y` or `z`).
        axis: &'static str,
    },
    /// A PLY face element, not empty, without a `vertex_indices` list.
    #[error("PLY face element has no 'vertex_indices' list")]
    PlyNoFaceIndices,
    /// A PLY face index property that is not a list of integers.
    #[error("PLY face property '{property}' is not a list of integers")]
    PlyFaceIndicesType {
        /// The property's name.
        property: String,
    },
    /// A PLY vertex coordinate that is infinite or NaN.
    #[error("vertex {vertex} has a non-finite coordinate ({value}) ({at})")]
    PlyNonFiniteVertex {
        /// The vertex (0-based).
        vertex: usize,
        /// The coordinate read.
        value: f64,
        /// Where it was read.
        at: Location,
    },
    /// A PLY face with fewer than three or too many corners.
    #[error("face {face} has {corners} corners (3 to {max} allowed) ({at})")]
    PlyPolygonSize {
        /// The face (0-based).
        face: usize,
        /// The corners it claims.
        corners: u64,
        /// The most corners a face may have.
        max: u64,
        /// Where its corner count was read.
        at: Location,
    },
    /// A PLY face refers to a vertex that does not exist.
    #[error(
        "face {face} refers to vertex {vertex}, but there are only {vertices} vertices ({at})"
    )]
    PlyFaceOutOfRange {
        /// The face (0-based).
        face: usize,
        /// The index read (a negative one too).
        vertex: f64,
        /// How many vertices the header declares.
        vertices: u64,
        /// Where the index was read.
        at: Location,
    },
    /// A PLY list with a negative length.
    #[error("negative length {length} of list '{list}' ({at})")]
    PlyListLength {
        /// The length read.
        length: f64,
        /// The list property's name.
        list: String,
        /// Where the length was read.
        at: Location,
    },
    /// A binary PLY file that ends inside a scalar.
    #[error("file is truncated at byte offset {offset} (reading {reading})")]
    TruncatedAt {
        /// Where the scalar starts in the file.
        offset: usize,
        /// What was being read.
        reading: String,
    },
    /// A binary PLY file that ends inside the rows of an element.
    #[error("file is truncated inside element '{element}'")]
    TruncatedElement {
        /// The element's name.
        element: String,
    },
    /// A binary PLY file that ends inside a list.
    #[error("file is truncated inside list '{list}'")]
    TruncatedList {
        /// The list property's name.
        list: String,
    },
    /// A file read as STL that starts with `solid` but holds binary data,
    /// and whose size fits no binary STL.
    #[error("not an STL file: binary data after 'solid', and {size}")]
    StlBinaryAfterSolid {
        /// How its size fails to match a binary STL.
        size: StlSize,
    },
    /// A file read as STL that does not start with `solid`, and whose size
    /// fits no binary STL.
    #[error("not an STL file: {size}, and the file does not start with 'solid'")]
    NotStl {
        /// How its size fails to match a binary STL.
        size: StlSize,
    },
    /// A file read as STL that is too short for binary STL and does not
    /// start with `solid`.
    #[error(
        "not an STL file: {size} bytes is too short for binary STL, and the file does not \
         start with 'solid'"
    )]
    StlTooShort {
        /// The file's size (bytes).
        size: usize,
    },
    /// A binary STL triangle with a coordinate that is infinite or NaN.
    #[error("triangle {triangle} has a non-finite coordinate (byte offset {offset})")]
    StlNonFinite {
        /// The triangle (0-based).
        triangle: usize,
        /// Where the coordinate is in the file.
        offset: usize,
    },
    /// An ASCII STL file without `endsolid` at its end.
    #[error("ASCII STL ends without 'endsolid' (is the file truncated?)")]
    StlNoEndsolid,
    /// An ASCII STL file with something other than a new solid after
    /// `endsolid`.
    #[error("line {line}: unexpected '{found}' after 'endsolid'")]
    StlAfterEndsolid {
        /// The line (1-based).
        line: usize,
        /// The word found (shortened).
        found: String,
    },
    /// An ASCII STL facet with fewer than three vertices.
    #[error("line {line}: facet has {vertices} vertices, at least 3 are needed")]
    StlFewVertices {
        /// The line of its `endloop` (1-based).
        line: usize,
        /// The vertices it has.
        vertices: usize,
    },
}

/// What is wrong with a PLY header line ([`ParseError::PlyHeaderLine`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum PlyHeaderProblem {
    /// A `format` line naming no known storage.
    #[error("unknown format")]
    UnknownFormat,
    /// An `element` line without a name and a count.
    #[error("malformed element")]
    MalformedElement,
    /// An `element` count that is not a non-negative integer.
    #[error("element count is not a non-negative integer")]
    ElementCount,
    /// A `property` line before any `element` line.
    #[error("property before any element")]
    PropertyFirst,
    /// A list property with unknown types (or a non-integer count type).
    #[error("unknown list types")]
    UnknownListTypes,
    /// A scalar property of an unknown type.
    #[error("unknown type")]
    UnknownType,
    /// A `property` line of another shape than `property TYPE NAME` or
    /// `property list COUNT ITEM NAME`.
    #[error("malformed property")]
    MalformedProperty,
    /// A line starting with an unknown keyword.
    #[error("unknown keyword")]
    UnknownKeyword,
}

/// Where in a PLY body a value was read: shown as `line N` (ASCII) or
/// `byte offset N` (binary).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    /// A line of an ASCII body (1-based, counted from the file's start).
    Line(usize),
    /// A byte offset in the file, for a binary body.
    ByteOffset(usize),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(n) => write!(f, "line {n}"),
            Location::ByteOffset(n) => write!(f, "byte offset {n}"),
        }
    }
}

/// A file's size that is not the size of a binary STL of the triangle
/// count in its header: shown as `B bytes do not match a binary STL of N
/// triangles (S bytes)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StlSize {
    /// The file's size (bytes).
    pub bytes: usize,
    /// The triangle count at byte 80.
    pub triangles: u32,
}

impl fmt::Display for StlSize {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = u64::from(self.triangles);
        write!(
            f,
            "{} bytes do not match a binary STL of {n} triangles ({} bytes)",
            self.bytes,
            84 + 50 * n
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_are_the_readers_lines() {
        assert_eq!(
            ParseError::PlyHeaderLine {
                line: 2,
                problem: PlyHeaderProblem::UnknownFormat,
                text: "format weird 1.0".into(),
            }
            .to_string(),
            "PLY header line 2: unknown format: 'format weird 1.0'"
        );
        assert_eq!(
            ParseError::PlyFaceOutOfRange {
                face: 0,
                vertex: -1.0,
                vertices: 3,
                at: Location::Line(13),
            }
            .to_string(),
            "face 0 refers to vertex -1, but there are only 3 vertices (line 13)"
        );
        assert_eq!(
            ParseError::PlyNonFiniteVertex {
                vertex: 0,
                value: f64::INFINITY,
                at: Location::ByteOffset(115),
            }
            .to_string(),
            "vertex 0 has a non-finite coordinate (inf) (byte offset 115)"
        );
        assert_eq!(
            ParseError::NotStl {
                size: StlSize {
                    bytes: 91,
                    triangles: 5,
                },
            }
            .to_string(),
            "not an STL file: 91 bytes do not match a binary STL of 5 triangles (334 bytes), \
             and the file does not start with 'solid'"
        );
        assert_eq!(
            ParseError::FewCorners {
                line: 2,
                corners: 2
            }
            .to_string(),
            "line 2: face has 2 corner(s), at least 3 are needed (is the file truncated?)"
        );
    }
}
