//! Writers for PLY (binary and ASCII), STL (binary and ASCII), OBJ and OFF.
//!
//! Files are replaced atomically ([`crate::atomic_write`]), so a watcher
//! never sees a half-written mesh.

use super::{shown, Format};
use crate::atomic_write::{write_atomic, AtomicWriteError};
use morphoid_core::mesh::{norm, triangle_normal2, Mesh};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// How a mesh is encoded in a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// PLY, binary little-endian, `double` coordinates (lossless).
    PlyBinaryLe,
    /// PLY, binary big-endian, `double` coordinates (lossless).
    PlyBinaryBe,
    /// PLY, ASCII (shortest exact decimal for each coordinate).
    PlyAscii,
    /// STL, binary (float32 coordinates), a triangle soup.
    StlBinary,
    /// STL, ASCII, a triangle soup.
    StlAscii,
    /// Wavefront OBJ.
    Obj,
    /// Object File Format.
    Off,
}

impl Encoding {
    /// The default encoding of a format (binary where there is a choice).
    fn default_for(format: Format) -> Encoding {
        match format {
            Format::Ply => Encoding::PlyBinaryLe,
            Format::Stl => Encoding::StlBinary,
            Format::Obj => Encoding::Obj,
            Format::Off => Encoding::Off,
        }
    }

    /// The format this encoding belongs to.
    pub fn format(self) -> Format {
        match self {
            Encoding::PlyBinaryLe | Encoding::PlyBinaryBe | Encoding::PlyAscii => Format::Ply,
            Encoding::StlBinary | Encoding::StlAscii => Format::Stl,
            Encoding::Obj => Format::Obj,
            Encoding::Off => Format::Off,
        }
    }
}

/// Why a mesh could not be written.
#[derive(Debug, thiserror::Error)]
pub enum SaveError {
    /// The mesh itself cannot be written (bad index, non-finite coordinate,
    /// or no faces for a format that needs them).
    #[error("{}: cannot write: {source}", shown(.path))]
    InvalidMesh {
        /// The target file.
        path: PathBuf,
        /// What is wrong with the mesh.
        source: EncodeError,
    },
    /// The file could not be written.
    #[error("{}: cannot write: {source}", shown(.path))]
    Io {
        /// The target file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The file could not be replaced atomically.
    #[error(transparent)]
    Write(#[from] AtomicWriteError),
    /// The extension names no supported format.
    #[error(
        "{}: unsupported file type (expected .obj, .ply, .stl or .off)",
        shown(.path)
    )]
    UnknownFormat {
        /// The target file.
        path: PathBuf,
    },
}

/// Write a mesh in the format named by the extension, with that format's
/// default encoding (binary PLY and STL).
pub fn save(path: &Path, mesh: &Mesh) -> Result<(), SaveError> {
    let format = Format::from_path(path).ok_or_else(|| SaveError::UnknownFormat {
        path: path.to_path_buf(),
    })?;
    save_as(path, mesh, Encoding::default_for(format))
}

/// Write a mesh with an explicit encoding (the extension is not checked).
pub fn save_as(path: &Path, mesh: &Mesh, encoding: Encoding) -> Result<(), SaveError> {
    let bytes = encode(mesh, encoding).map_err(|source| SaveError::InvalidMesh {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(write_atomic(path, &bytes)?)
}

/// Write binary little-endian PLY (a vertex-only PLY for a point cloud).
pub fn write_ply(path: &Path, mesh: &Mesh) -> Result<(), SaveError> {
    save_as(path, mesh, Encoding::PlyBinaryLe)
}

/// Write binary STL.
pub fn write_stl(path: &Path, mesh: &Mesh) -> Result<(), SaveError> {
    save_as(path, mesh, Encoding::StlBinary)
}

/// Write ASCII STL.
pub fn write_stl_ascii(path: &Path, mesh: &Mesh) -> Result<(), SaveError> {
    save_as(path, mesh, Encoding::StlAscii)
}

/// Why a mesh cannot be encoded: a face index out of range, a non-finite
/// coordinate, too many vertices or faces, or a point cloud for STL.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    /// A vertex has a NaN or infinite coordinate.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFiniteVertex {
        /// The vertex's index.
        vertex: usize,
    },
    /// More vertices than the formats' indices can address.
    #[error("{count} vertices are too many to write")]
    TooManyVertices {
        /// The number of vertices.
        count: usize,
    },
    /// A face refers to a vertex that does not exist.
    #[error("face {face} refers to a vertex past {vertices}")]
    FaceOutOfRange {
        /// The face's index.
        face: usize,
        /// The number of vertices.
        vertices: usize,
    },
    /// STL holds triangles only, and the mesh has none.
    #[error("STL cannot hold a point cloud (the mesh has no faces)")]
    StlPointCloud,
    /// More faces than binary STL can count.
    #[error("too many faces for STL")]
    StlTooManyFaces {
        /// The number of faces.
        count: usize,
    },
}

/// Encode a mesh in memory.
pub fn encode(mesh: &Mesh, encoding: Encoding) -> Result<Vec<u8>, EncodeError> {
    check_writable(mesh)?;
    Ok(match encoding {
        Encoding::PlyBinaryLe => ply_binary(mesh, false),
        Encoding::PlyBinaryBe => ply_binary(mesh, true),
        Encoding::PlyAscii => ply_ascii(mesh),
        Encoding::StlBinary => stl_binary(mesh)?,
        Encoding::StlAscii => stl_ascii(mesh)?,
        Encoding::Obj => obj(mesh),
        Encoding::Off => off(mesh),
    })
}

/// Error unless every format can write `mesh`: finite coordinates, a
/// vertex count the indices can address, faces within the vertices.
fn check_writable(mesh: &Mesh) -> Result<(), EncodeError> {
    if let Some(vertex) = mesh.first_non_finite_vertex() {
        return Err(EncodeError::NonFiniteVertex { vertex });
    }
    let n = mesh.vertices.len();
    if n > i32::MAX as usize {
        // PLY stores indices as int, OBJ/OFF readers as u32.
        return Err(EncodeError::TooManyVertices { count: n });
    }
    if let Some((face, _)) = mesh.first_face_out_of_range() {
        return Err(EncodeError::FaceOutOfRange { face, vertices: n });
    }
    Ok(())
}

fn ply_header(mesh: &Mesh, format: &str, scalar: &str) -> String {
    let mut h = format!(
        "ply\nformat {format} 1.0\ncomment written by morphoid\nelement vertex {}\n\
         property {scalar} x\nproperty {scalar} y\nproperty {scalar} z\n",
        mesh.vertices.len()
    );
    if !mesh.faces.is_empty() {
        let _ = write!(
            h,
            "element face {}\nproperty list uchar int vertex_indices\n",
            mesh.faces.len()
        );
    }
    h.push_str("end_header\n");
    h
}

fn ply_binary(mesh: &Mesh, big_endian: bool) -> Vec<u8> {
    let format = if big_endian {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut out = ply_header(mesh, format, "double").into_bytes();
    out.reserve(mesh.vertices.len() * 24 + mesh.faces.len() * 13);
    for v in &mesh.vertices {
        for c in v {
            out.extend_from_slice(&if big_endian {
                c.to_be_bytes()
            } else {
                c.to_le_bytes()
            });
        }
    }
    for f in &mesh.faces {
        out.push(3);
        for &i in f {
            // Indices are below the vertex count, which PLY stores as int.
            let i = i as i32;
            out.extend_from_slice(&if big_endian {
                i.to_be_bytes()
            } else {
                i.to_le_bytes()
            });
        }
    }
    out
}

fn ply_ascii(mesh: &Mesh) -> Vec<u8> {
    let mut s = ply_header(mesh, "ascii", "double");
    for v in &mesh.vertices {
        let _ = writeln!(s, "{} {} {}", v[0], v[1], v[2]);
    }
    for f in &mesh.faces {
        let _ = writeln!(s, "3 {} {} {}", f[0], f[1], f[2]);
    }
    s.into_bytes()
}

/// Unit normal of a face, or zero for a degenerate one.
fn face_normal(mesh: &Mesh, f: &[u32; 3]) -> [f32; 3] {
    let p = |k: usize| mesh.vertices[f[k] as usize];
    let n = triangle_normal2(p(0), p(1), p(2));
    let len = norm(n);
    if len > 0.0 && len.is_finite() {
        [
            (n[0] / len) as f32,
            (n[1] / len) as f32,
            (n[2] / len) as f32,
        ]
    } else {
        [0.0; 3]
    }
}

/// Error unless `mesh` has faces (STL holds triangles only).
fn require_faces(mesh: &Mesh) -> Result<(), EncodeError> {
    if mesh.faces.is_empty() {
        Err(EncodeError::StlPointCloud)
    } else {
        Ok(())
    }
}

fn stl_binary(mesh: &Mesh) -> Result<Vec<u8>, EncodeError> {
    require_faces(mesh)?;
    let count = u32::try_from(mesh.faces.len()).map_err(|_| EncodeError::StlTooManyFaces {
        count: mesh.faces.len(),
    })?;
    let mut out = Vec::with_capacity(84 + 50 * mesh.faces.len());
    let mut header = [b' '; 80];
    let label = b"binary STL written by morphoid";
    header[..label.len()].copy_from_slice(label);
    out.extend_from_slice(&header);
    out.extend_from_slice(&count.to_le_bytes());
    for f in &mesh.faces {
        for c in face_normal(mesh, f) {
            out.extend_from_slice(&c.to_le_bytes());
        }
        for &i in f {
            for c in mesh.vertices[i as usize] {
                out.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
        out.extend_from_slice(&[0, 0]);
    }
    Ok(out)
}

fn stl_ascii(mesh: &Mesh) -> Result<Vec<u8>, EncodeError> {
    require_faces(mesh)?;
    let mut s = String::from("solid morphoid\n");
    for f in &mesh.faces {
        let n = face_normal(mesh, f);
        let _ = writeln!(s, "  facet normal {:e} {:e} {:e}", n[0], n[1], n[2]);
        s.push_str("    outer loop\n");
        for &i in f {
            let v = mesh.vertices[i as usize];
            let _ = writeln!(s, "      vertex {:e} {:e} {:e}", v[0], v[1], v[2]);
        }
        s.push_str("    endloop\n  endfacet\n");
    }
    s.push_str("endsolid morphoid\n");
    Ok(s.into_bytes())
}

fn obj(mesh: &Mesh) -> Vec<u8> {
    let mut s = String::from("# written by morphoid\n");
    for v in &mesh.vertices {
        let _ = writeln!(s, "v {} {} {}", v[0], v[1], v[2]);
    }
    for f in &mesh.faces {
        let _ = writeln!(s, "f {} {} {}", f[0] + 1, f[1] + 1, f[2] + 1);
    }
    s.into_bytes()
}

fn off(mesh: &Mesh) -> Vec<u8> {
    let mut s = format!(
        "OFF\n# written by morphoid\n{} {} 0\n",
        mesh.vertices.len(),
        mesh.faces.len()
    );
    for v in &mesh.vertices {
        let _ = writeln!(s, "{} {} {}", v[0], v[1], v[2]);
    }
    for f in &mesh.faces {
        let _ = writeln!(s, "3 {} {} {}", f[0], f[1], f[2]);
    }
    s.into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encode_errors_read_as_before() {
        let cases = [
            (
                EncodeError::NonFiniteVertex { vertex: 3 },
                "vertex 3 has a non-finite coordinate",
            ),
            (
                EncodeError::TooManyVertices { count: 5 },
                "5 vertices are too many to write",
            ),
            (
                EncodeError::FaceOutOfRange {
                    face: 2,
                    vertices: 4,
                },
                "face 2 refers to a vertex past 4",
            ),
            (
                EncodeError::StlPointCloud,
                "STL cannot hold a point cloud (the mesh has no faces)",
            ),
            (
                EncodeError::StlTooManyFaces { count: 9 },
                "too many faces for STL",
            ),
        ];
        for (e, text) in cases {
            assert_eq!(e.to_string(), text);
        }
    }

    #[test]
    fn unwritable_meshes_are_refused_with_the_reason_as_source() {
        let cloud = Mesh {
            vertices: vec![[0.0; 3]],
            faces: vec![],
        };
        assert_eq!(
            encode(&cloud, Encoding::StlAscii).unwrap_err(),
            EncodeError::StlPointCloud
        );
        let nan = Mesh {
            vertices: vec![[0.0, f64::NAN, 0.0]],
            faces: vec![],
        };
        assert_eq!(
            encode(&nan, Encoding::Obj).unwrap_err(),
            EncodeError::NonFiniteVertex { vertex: 0 }
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.stl");
        let e = save(&path, &cloud).unwrap_err();
        assert!(
            matches!(
                &e,
                SaveError::InvalidMesh {
                    source: EncodeError::StlPointCloud,
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(
            e.to_string()
                .ends_with(": cannot write: STL cannot hold a point cloud (the mesh has no faces)"),
            "{e}"
        );
    }
}
