//! Reading and writing OBJ, PLY, STL and OFF.
//!
//! Every reader works on the whole file in memory, checks each count and
//! index against the file size and the limits below *before* it allocates,
//! rejects non-finite coordinates and out-of-range indices, and reports any
//! problem as one line that names the file and, where meaningful, the line
//! number or byte offset. No input makes a reader panic.
//!
//! Polygons are fan-triangulated. A file with vertices and no faces loads as
//! a point cloud (a [`Mesh`] with empty `faces`). STL has no shared
//! vertices: ASCII STL loads as a triangle soup, which cleaning welds;
//! binary STL shares bit-identical corners as it is read.

mod error;
mod obj;
mod off;
mod ply;
mod stl;
mod text;
mod write;

pub use error::{Location, ParseError, PlyHeaderProblem, StlSize};
pub use write::{encode, save, save_as, write_ply};
pub use write::{write_stl, write_stl_ascii, EncodeError, Encoding, SaveError};

use crate::hash::{Content, HashingReader, SharedHash};
use morphoid_core::mesh::Mesh;
use std::path::{Path, PathBuf};

/// Largest file the readers accept (bytes); bigger files are refused before
/// they are read.
const MAX_FILE_BYTES: u64 = 2 << 30;

/// A surface file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// Wavefront OBJ.
    Obj,
    /// Stanford PLY (ASCII or binary).
    Ply,
    /// STL (ASCII or binary).
    Stl,
    /// Object File Format.
    Off,
}

impl Format {
    /// The format named by a path's extension (case-insensitive), if any.
    pub fn from_path(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(Format::Obj),
            "ply" => Some(Format::Ply),
            "stl" => Some(Format::Stl),
            "off" => Some(Format::Off),
            _ => None,
        }
    }

    /// The usual lower-case file extension.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Obj => "obj",
            Format::Ply => "ply",
            Format::Stl => "stl",
            Format::Off => "off",
        }
    }
}

/// A mesh as read from a file, with the format it came in.
#[derive(Debug, Clone)]
pub struct LoadedMesh {
    /// The vertices and faces as stored (faces empty for a point cloud).
    pub mesh: Mesh,
    /// The detected format.
    pub format: Format,
}

/// Why a file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The file content is malformed or unusable.
    #[error("{}: {source}", shown(.path))]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong (and where, line or byte offset).
        source: ParseError,
    },
    /// The file is larger than the readers take; it was not read.
    #[error("{}: file is {size} bytes, more than the limit of {limit}", shown(.path))]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size (bytes).
        size: u64,
        /// The largest file taken (bytes).
        limit: u64,
    },
    /// The file could not be opened or read.
    #[error("{}: cannot read: {source}", shown(.path))]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The extension names no supported format.
    #[error(
        "{}: unsupported file type (expected .obj, .ply, .stl or .off)",
        shown(.path)
    )]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
}

impl LoadError {
    /// The file the error concerns.
    pub fn path(&self) -> &Path {
        match self {
            LoadError::Invalid { path, .. }
            | LoadError::TooLarge { path, .. }
            | LoadError::Io { path, .. }
            | LoadError::UnknownFormat { path } => path,
        }
    }
}

/// A path as shown in a one-line message (control characters escaped).
pub(crate) fn shown(path: &Path) -> String {
    path.display().to_string().escape_debug().to_string()
}

/// A parse failure inside one reader, before the file name is attached.
pub(crate) type ParseResult<T> = Result<T, ParseError>;

/// Read a mesh, choosing the reader from the file extension
/// (case-insensitive: `.obj`, `.ply`, `.stl`, `.off`).
pub fn load(path: &Path) -> Result<LoadedMesh, LoadError> {
    load_from(path, None)
}

/// [`load`], and the content of exactly the bytes that were parsed
/// ([`crate::hash::content_hash_file`] of the file as it was read): the
/// file is read once, so the mesh and the hash are of the same content
/// even while another program rewrites it. A file that changed while it
/// was being read is an I/O error (`InvalidData`).
pub fn load_hashed(path: &Path) -> Result<(LoadedMesh, Content), LoadError> {
    let hash = SharedHash::new();
    let mesh = load_from(path, Some(&hash))?;
    Ok((mesh, hash.content()))
}

/// [`load`], hashing every byte read into `hash` when given.
fn load_from(path: &Path, hash: Option<&SharedHash>) -> Result<LoadedMesh, LoadError> {
    use std::io::Read as _;
    let format = Format::from_path(path).ok_or_else(|| LoadError::UnknownFormat {
        path: path.to_path_buf(),
    })?;
    let io_err = |source| LoadError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io_err)?;
    let size = file.metadata().map_err(io_err)?.len();
    if size > MAX_FILE_BYTES {
        return Err(LoadError::TooLarge {
            path: path.to_path_buf(),
            size,
            limit: MAX_FILE_BYTES,
        });
    }
    let hashing = HashingReader::maybe(file, hash.cloned());
    let mut reader = std::io::BufReader::with_capacity(stl::READ_BUFFER, hashing);
    let mut head = [0u8; 84];
    let mut bytes = Vec::new();
    if format == Format::Stl && size >= 84 {
        reader.read_exact(&mut head).map_err(io_err)?;
        if let Some(n) = stl::binary_count(&head, size) {
            // Big exports are binary STL: read record by record.
            let mesh = stl::read_binary_records(&mut reader, n).map_err(|e| match e {
                stl::BinaryFileError::Io(source) => io_err(source),
                stl::BinaryFileError::Invalid(source) => LoadError::Invalid {
                    path: path.to_path_buf(),
                    source,
                },
            })?;
            // Anything after the records is read (and hashed) too: a file
            // that grew meanwhile is not the content that was parsed.
            let rest = std::io::copy(&mut reader, &mut std::io::sink()).map_err(io_err)?;
            if rest > 0 {
                return Err(io_err(changed_while_read()));
            }
            let mesh = validate(mesh).map_err(|source| LoadError::Invalid {
                path: path.to_path_buf(),
                source,
            })?;
            return Ok(LoadedMesh { mesh, format });
        }
        bytes.extend_from_slice(&head);
    }
    bytes.reserve(usize::try_from(size).unwrap_or(0));
    reader.read_to_end(&mut bytes).map_err(io_err)?;
    load_bytes(&bytes, format, path)
}

/// The error of a file whose size changed while it was read.
fn changed_while_read() -> std::io::Error {
    std::io::Error::new(
        std::io::ErrorKind::InvalidData,
        "the file changed while it was being read",
    )
}

/// Parse a mesh held in memory. `name` only labels error messages.
pub fn load_bytes(bytes: &[u8], format: Format, name: &Path) -> Result<LoadedMesh, LoadError> {
    // Text-only formats may start with a UTF-8 byte-order mark.
    let text = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes);
    let parsed = if bytes.is_empty() {
        Err(ParseError::Empty)
    } else {
        match format {
            Format::Obj => obj::read_obj(text),
            Format::Ply => ply::read_ply(bytes),
            Format::Stl => stl::read_stl(bytes),
            Format::Off => off::read_off(text),
        }
    };
    // The messages are one line each (see `error`).
    let mesh = parsed
        .and_then(validate)
        .map_err(|source| LoadError::Invalid {
            path: name.to_path_buf(),
            source,
        })?;
    Ok(LoadedMesh { mesh, format })
}

/// Final checks shared by all readers: something was read, every coordinate
/// is finite and every face index is in range.
fn validate(mesh: Mesh) -> ParseResult<Mesh> {
    if mesh.vertices.is_empty() {
        return Err(ParseError::NoVertices);
    }
    if let Some(vertex) = mesh.first_non_finite_vertex() {
        return Err(ParseError::NonFiniteVertex { vertex });
    }
    if let Some((face, vertex)) = mesh.first_face_out_of_range() {
        return Err(ParseError::FaceOutOfRange {
            face,
            vertex,
            vertices: mesh.vertices.len(),
        });
    }
    Ok(mesh)
}

/// Refuse a count whose rows cannot fit in the remaining bytes, so that a
/// header claiming billions of elements fails before any allocation.
pub(crate) fn check_count(
    what: &str,
    count: u64,
    min_row_bytes: u64,
    remaining: usize,
) -> ParseResult<usize> {
    let needed = count.checked_mul(min_row_bytes.max(1));
    match needed {
        Some(b) if b <= remaining as u64 && count <= u32::MAX as u64 => Ok(count as usize),
        _ => Err(ParseError::CountTooLarge {
            what: what.to_string(),
            count,
            remaining,
        }),
    }
}

/// Fan-triangulate one polygon given by its (already checked) corner indices.
pub(crate) fn push_fan(faces: &mut Vec<[u32; 3]>, poly: &[u32]) {
    if let Some((&first, rest)) = poly.split_first() {
        for w in rest.windows(2) {
            faces.push([first, w[0], w[1]]);
        }
    }
}
