//! The malformed or unusable inputs the daemon must survive, as files.

use super::transform::closed_sphere;
use super::{crown, CROWN_GENERA};
use morphoid_core::mesh::Mesh;
use morphoid_data::mesh_io::{encode, Encoding};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};

/// Write the eight bad inputs into `dir` and return each path with a short
/// description. The first six and the last fail to load; the closed sphere
/// and the three points load but cannot be made a disk-type surface.
///
/// 1. `empty.ply`: an empty file;
/// 2. `truncated.obj`: an OBJ cut off in the middle of a vertex line;
/// 3. `random.stl`: random bytes named `.stl`;
/// 4. `nan.ply`: a binary PLY with NaN coordinates;
/// 5. `bad_index.off`: a face index past the vertex count;
/// 6. `closed_sphere.ply`: a closed surface (no boundary);
/// 7. `three_points.ply`: a point cloud of three points;
/// 8. `four_billion.ply`: a PLY header claiming four billion vertices.
pub fn write_bad_inputs(dir: &Path) -> std::io::Result<Vec<(PathBuf, &'static str)>> {
    std::fs::create_dir_all(dir)?;
    let mut out = Vec::new();
    let mut put = |name: &str, bytes: &[u8], what: &'static str| -> std::io::Result<()> {
        let path = dir.join(name);
        std::fs::write(&path, bytes)?;
        out.push((path, what));
        Ok(())
    };
    let to_io = |e: morphoid_data::mesh_io::EncodeError| std::io::Error::other(e);
    let small = crown(&CROWN_GENERA[0], 7, 300);

    put("empty.ply", b"", "an empty file")?;
    put(
        "truncated.obj",
        &truncated_obj(&small).map_err(to_io)?,
        "an OBJ file cut off in the middle of a vertex line",
    )?;
    put(
        "random.stl",
        &random_bytes(4096, 11),
        "random bytes named .stl",
    )?;
    put(
        "nan.ply",
        &ply_with_nan(&small).map_err(to_io)?,
        "a binary PLY with NaN coordinates",
    )?;
    put(
        "bad_index.off",
        b"OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 4\n",
        "a face index past the vertex count",
    )?;
    put(
        "closed_sphere.ply",
        &encode(&closed_sphere(642), Encoding::PlyBinaryLe).map_err(to_io)?,
        "a closed surface (a sphere, no boundary)",
    )?;
    let three = Mesh::new(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![],
    );
    put(
        "three_points.ply",
        &encode(&three, Encoding::PlyAscii).map_err(to_io)?,
        "a point cloud of three points",
    )?;
    put(
        "four_billion.ply",
        b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n\
          property float x\nproperty float y\nproperty float z\n\
          element face 1\nproperty list uchar int vertex_indices\nend_header\n\
          \0\0\0\0\0\0\0\0\0\0\0\0",
        "a PLY header claiming four billion vertices",
    )?;
    Ok(out)
}

/// The OBJ text of `mesh`, cut in the middle of a vertex line, right
/// after the first digits of its second coordinate (`v 0.123 0.`).
fn truncated_obj(mesh: &Mesh) -> Result<Vec<u8>, morphoid_data::mesh_io::EncodeError> {
    let text = encode(mesh, Encoding::Obj)?;
    let target = mesh.vertices.len() / 2;
    let mut cut = text.len();
    let mut seen = 0usize;
    let mut pos = 0usize;
    for line in text.split(|&b| b == b'\n') {
        if line.starts_with(b"v ") {
            if seen == target {
                // After "v x " and two more characters of y.
                let second = line
                    .iter()
                    .enumerate()
                    .filter(|(_, &b)| b == b' ')
                    .nth(1)
                    .map_or(line.len(), |(i, _)| i);
                cut = (pos + second + 3).min(pos + line.len());
                break;
            }
            seen += 1;
        }
        pos += line.len() + 1;
    }
    Ok(text[..cut].to_vec())
}

/// Seeded random bytes that are neither a binary STL (wrong size) nor an
/// ASCII one (no leading "solid").
fn random_bytes(len: usize, seed: u64) -> Vec<u8> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut b: Vec<u8> = (0..len).map(|_| rng.gen()).collect();
    // Make sure the triangle count cannot match the size by chance.
    if let Some(c) = b.get_mut(80..84) {
        c.copy_from_slice(&u32::MAX.to_le_bytes());
    }
    if let Some(first) = b.first_mut() {
        *first = 0xff;
    }
    b
}

/// Binary PLY of `mesh` with the coordinates of one vertex set to NaN.
fn ply_with_nan(mesh: &Mesh) -> Result<Vec<u8>, morphoid_data::mesh_io::EncodeError> {
    let mut bytes = encode(mesh, Encoding::PlyBinaryLe)?;
    let header_end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .map_or(0, |p| p + 11);
    let vertex = mesh.vertices.len() / 3;
    for k in 0..3 {
        let o = header_end + 24 * vertex + 8 * k;
        if let Some(slot) = bytes.get_mut(o..o + 8) {
            slot.copy_from_slice(&f64::NAN.to_le_bytes());
        }
    }
    Ok(bytes)
}
