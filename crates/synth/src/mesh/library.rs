//! A labelled reference library of synthetic crowns, in the library
//! folder layout: `labels.csv` (`name,order,family,genus`) and one binary
//! PLY per specimen.

use super::transform::{scale, RigidMotion};
use super::{crown, CrownGenus, CROWN_GENERA};
use morphoid_core::mesh::Mesh;
use morphoid_data::mesh_io::{save, SaveError};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What a synthetic library contains.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LibrarySpec {
    /// Specimens of each built-in configuration.
    pub per_genus: usize,
    /// Approximate vertex count of each crown.
    pub target_vertices: usize,
    /// Master seed; each specimen derives its own from it.
    pub seed: u64,
    /// Give every specimen a random rotation and position and a scale in
    /// `[0.5, 2]`, as scans come in arbitrary poses and units.
    pub random_pose: bool,
}

impl Default for LibrarySpec {
    fn default() -> Self {
        LibrarySpec {
            per_genus: 4,
            target_vertices: 3000,
            seed: 1,
            random_pose: false,
        }
    }
}

/// One specimen of a synthetic library.
#[derive(Debug, Clone)]
pub struct Specimen {
    /// Name (the mesh file stem), e.g. `tric03`.
    pub name: String,
    /// Its configuration (genus, family, order).
    pub genus: &'static CrownGenus,
    /// The seed its crown was generated from.
    pub seed: u64,
    /// The mesh file written.
    pub path: PathBuf,
}

/// The seed of specimen `index` of configuration `genus` (a fixed mixing of
/// the master seed, so that specimens are independent but reproducible).
fn specimen_seed(master: u64, genus: usize, index: usize) -> u64 {
    let mut z = master.wrapping_add(
        0x9E37_79B9_7F4A_7C15u64.wrapping_mul(1 + ((genus as u64) << 20) + index as u64),
    );
    // splitmix64 finalizer
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The mesh of one specimen as the library writes it.
pub fn specimen_mesh(genus: &CrownGenus, seed: u64, spec: &LibrarySpec) -> Mesh {
    let m = crown(genus, seed, spec.target_vertices);
    if spec.random_pose {
        // Scale in [0.5, 2], log-uniform, from the seed's high bits.
        let u = (seed >> 11) as f64 / (1u64 << 53) as f64;
        let posed = RigidMotion::random(seed ^ 0x5EED, 10.0).apply(&m);
        scale(&posed, 2f64.powf(2.0 * u - 1.0))
    } else {
        m
    }
}

/// Write `spec.per_genus` crowns of every built-in configuration into
/// `dir` as `<name>.ply`, and `labels.csv` with the columns
/// `name,order,family,genus`. Returns the specimens in file order.
pub fn write_synthetic_library(dir: &Path, spec: &LibrarySpec) -> Result<Vec<Specimen>, SaveError> {
    std::fs::create_dir_all(dir).map_err(|source| SaveError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut specimens = Vec::new();
    let mut labels = String::from("name,order,family,genus\n");
    for (gi, genus) in CROWN_GENERA.iter().enumerate() {
        let prefix: String = genus.name.to_ascii_lowercase().chars().take(4).collect();
        for i in 0..spec.per_genus {
            let name = format!("{prefix}{:02}", i + 1);
            let seed = specimen_seed(spec.seed, gi, i);
            let path = dir.join(format!("{name}.ply"));
            save(&path, &specimen_mesh(genus, seed, spec))?;
            let _ = writeln!(
                labels,
                "{name},{},{},{}",
                genus.order, genus.family, genus.name
            );
            specimens.push(Specimen {
                name,
                genus,
                seed,
                path,
            });
        }
    }
    let labels_path = dir.join("labels.csv");
    std::fs::write(&labels_path, labels).map_err(|source| SaveError::Io {
        path: labels_path,
        source,
    })?;
    Ok(specimens)
}
