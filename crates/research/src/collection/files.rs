//! The files of an aligned collection, each in the form its users' tools
//! read: TPS and morphologika (geomorph, MorphoJ), CSV, one Slicer
//! `.fcsv` per specimen, aligned meshes and the mean shape as PLY
//! (MeshLab, Slicer), Procrustes coordinates and PCA as CSV, the
//! morphospace plot as SVG and PNG, and a JSON summary.

use super::Alignment;
use crate::eval::{scatter_raster, scatter_svg, Scatter};
use morphoid_core::cp::Prepared;
use morphoid_data::atomic_write::{write_atomic, AtomicWriteError};
use morphoid_data::landmarks::{
    self, LandmarkError, Landmarks, NamedLandmarks, PropagateError, Surface,
};
use morphoid_data::mesh_io::{write_ply, SaveError};
use morphoid_data::table::csv_text::CsvString;
use morphoid_data::table::{DistanceMatrix, TableError};
use std::path::{Path, PathBuf};

/// Why an output file could not be written; names the file.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// A folder cannot be created.
    #[error("{path}: cannot create the folder: {source}")]
    Folder {
        /// The folder.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A text or image file.
    #[error(transparent)]
    Write(#[from] AtomicWriteError),
    /// A landmark file.
    #[error(transparent)]
    Landmarks(#[from] LandmarkError),
    /// A mesh.
    #[error(transparent)]
    Mesh(#[from] SaveError),
    /// A matrix.
    #[error(transparent)]
    Matrix(#[from] TableError),
    /// The PNG encoder.
    #[error("{path}: {source}")]
    Png {
        /// The file.
        path: PathBuf,
        /// Why.
        source: png::EncodingError,
    },
    /// A specimen's surface cannot be rebuilt.
    #[error("surface of `{name}`: {source}")]
    Surface {
        /// The specimen.
        name: String,
        /// Why.
        source: PropagateError,
    },
}

/// What [`write_outputs`] wrote.
#[derive(Debug, Clone, Default)]
pub struct Written {
    /// Every file, in the order written.
    pub files: Vec<PathBuf>,
}

/// What the outputs are labelled with besides the alignment.
#[derive(Debug, Clone, Default)]
pub struct OutputContext<'a> {
    /// The cP distances the template and the tree came from.
    pub distances: Option<&'a DistanceMatrix>,
    /// The rank the morphospace is coloured by, and each specimen's taxon
    /// at it (in alignment order).
    pub groups: Option<(&'a str, Vec<Option<String>>)>,
    /// Specimens left out (name, why).
    pub left_out: &'a [(String, String)],
}

fn mkdir(path: &Path) -> Result<(), OutputError> {
    std::fs::create_dir_all(path).map_err(|source| OutputError::Folder {
        path: path.to_path_buf(),
        source,
    })
}

/// A file name for a specimen: path separators and other awkward
/// characters become `_`.
fn file_stem(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_alphanumeric() || "-_.+".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Write every output of `alignment` (over `prepared`, in the same order)
/// into the folder `out` (created if needed).
pub fn write_outputs(
    out: &Path,
    alignment: &Alignment,
    prepared: &[Prepared],
    context: &OutputContext,
) -> Result<Written, OutputError> {
    mkdir(out)?;
    let mut written = Written::default();
    let sets = landmark_sets(alignment);
    let tps = landmarks::format_tps(&sets);
    write_text(out, "pseudolandmarks.tps", tps, &mut written)?;
    let morphologika = landmarks::format_morphologika(&sets);
    let name = "pseudolandmarks_morphologika.txt";
    write_text(out, name, morphologika, &mut written)?;
    let csv = pseudolandmarks_csv(alignment);
    write_text(out, "pseudolandmarks.csv", csv, &mut written)?;
    write_fcsv_files(out, alignment, &mut written)?;
    write_aligned_meshes(out, alignment, prepared, &mut written)?;
    let path = out.join("mean_shape.ply");
    write_ply(&path, &alignment.mean_mesh())?;
    written.files.push(path);

    let csv = procrustes_coordinates_csv(alignment);
    write_text(out, "procrustes_coordinates.csv", csv, &mut written)?;
    let csv = pca_scores_csv(alignment, context);
    write_text(out, "pca_scores.csv", csv, &mut written)?;
    let percent = alignment.pca.percent_explained();
    let csv = pca_variance_csv(alignment, &percent);
    write_text(out, "pca_variance.csv", csv, &mut written)?;

    let plot = morphospace(alignment, context, &percent);
    write_text(out, "morphospace.svg", scatter_svg(&plot), &mut written)?;
    write_morphospace_png(out, &plot, &mut written)?;

    write_distance_matrices(out, alignment, context, &mut written)?;
    let csv = correspondence_steps_csv(alignment);
    write_text(out, "correspondence_steps.csv", csv, &mut written)?;
    let summary = format!("{:#}\n", summary(alignment, context));
    write_text(out, "summary.json", summary, &mut written)?;
    Ok(written)
}

/// Write `body` to the file `name` in `out`, and note it in `written`.
fn write_text(
    out: &Path,
    name: &str,
    body: String,
    written: &mut Written,
) -> Result<(), OutputError> {
    let path = out.join(name);
    write_atomic(&path, body.as_bytes())?;
    written.files.push(path);
    Ok(())
}

/// Each specimen's pseudolandmarks under its name, in alignment order.
fn landmark_sets(alignment: &Alignment) -> Vec<NamedLandmarks> {
    alignment
        .names
        .iter()
        .zip(&alignment.pseudolandmarks)
        .map(|(n, p)| NamedLandmarks {
            name: n.clone(),
            landmarks: Landmarks::from_points(p.clone()),
        })
        .collect()
}

/// The pseudolandmarks as CSV: one row per specimen and landmark
/// (1-based), with its coordinates.
fn pseudolandmarks_csv(alignment: &Alignment) -> String {
    let mut csv = CsvString::new();
    csv.record(["specimen", "landmark", "x", "y", "z"]);
    for (n, pts) in alignment.names.iter().zip(&alignment.pseudolandmarks) {
        for (k, p) in pts.iter().enumerate() {
            csv.record([
                n.clone(),
                (k + 1).to_string(),
                format!("{:?}", p[0]),
                format!("{:?}", p[1]),
                format!("{:?}", p[2]),
            ]);
        }
    }
    csv.finish()
}

/// Write one Slicer `.fcsv` per specimen (landmarks `PL1`, `PL2`, …)
/// into `out/fcsv`.
fn write_fcsv_files(
    out: &Path,
    alignment: &Alignment,
    written: &mut Written,
) -> Result<(), OutputError> {
    let fcsv = out.join("fcsv");
    mkdir(&fcsv)?;
    for (n, pts) in alignment.names.iter().zip(&alignment.pseudolandmarks) {
        let path = fcsv.join(format!("{}.fcsv", file_stem(n)));
        let mut lm = Landmarks::default();
        for (k, p) in pts.iter().enumerate() {
            lm.push(*p, Some(format!("PL{}", k + 1)));
        }
        landmarks::write(&path, &lm)?;
        written.files.push(path);
    }
    Ok(())
}

/// Write each specimen's surface, moved into the collection frame, as PLY
/// into `out/aligned`.
fn write_aligned_meshes(
    out: &Path,
    alignment: &Alignment,
    prepared: &[Prepared],
    written: &mut Written,
) -> Result<(), OutputError> {
    let aligned = out.join("aligned");
    mkdir(&aligned)?;
    for (i, p) in prepared.iter().enumerate() {
        let surface = Surface::from_normalized(p).map_err(|source| OutputError::Surface {
            name: p.name().to_string(),
            source,
        })?;
        let path = aligned.join(format!("{}.ply", file_stem(p.name())));
        write_ply(&path, &alignment.aligned_mesh(i, surface.mesh()))?;
        written.files.push(path);
    }
    Ok(())
}

/// The Procrustes coordinates as CSV: one row per specimen, columns
/// `x1, y1, z1, x2, …`.
fn procrustes_coordinates_csv(alignment: &Alignment) -> String {
    let k = alignment.gpa.mean.len();
    let mut csv = CsvString::new();
    let mut header = vec!["specimen".to_string()];
    for j in 1..=k {
        header.extend(["x", "y", "z"].map(|a| format!("{a}{j}")));
    }
    csv.record(&header);
    for (n, conf) in alignment.names.iter().zip(&alignment.gpa.aligned) {
        let mut row = vec![n.clone()];
        row.extend(conf.iter().flat_map(|p| p.map(|v| format!("{v:?}"))));
        csv.record(&row);
    }
    csv.finish()
}

/// The taxon specimen `i` is coloured by, if the context has groups and
/// one for it.
fn group_of(context: &OutputContext, i: usize) -> Option<String> {
    context
        .groups
        .as_ref()
        .and_then(|(_, g)| g.get(i).cloned().flatten())
}

/// The PCA scores as CSV: one row per specimen (with its group, when the
/// context has a rank), columns `PC1, PC2, …`.
fn pca_scores_csv(alignment: &Alignment, context: &OutputContext) -> String {
    let pcs = alignment.pca.variances.len();
    let mut csv = CsvString::new();
    let mut header = vec!["specimen".to_string()];
    if let Some((rank, _)) = &context.groups {
        header.push(rank.to_string());
    }
    header.extend((1..=pcs).map(|c| format!("PC{c}")));
    csv.record(&header);
    let scores = alignment.names.iter().zip(&alignment.pca.scores);
    for (i, (n, s)) in scores.enumerate() {
        let mut row = vec![n.clone()];
        if context.groups.is_some() {
            row.push(group_of(context, i).unwrap_or_default());
        }
        row.extend(s.iter().map(|v| format!("{v:?}")));
        csv.record(&row);
    }
    csv.finish()
}

/// Each component's variance, percent of the total (`percent`) and the
/// cumulative percent, as CSV.
fn pca_variance_csv(alignment: &Alignment, percent: &[f64]) -> String {
    let mut csv = CsvString::new();
    csv.record(["component", "variance", "percent", "cumulative_percent"]);
    let mut cumulative = 0.0;
    for (c, (v, p)) in alignment.pca.variances.iter().zip(percent).enumerate() {
        cumulative += p;
        csv.record([
            format!("PC{}", c + 1),
            format!("{v:?}"),
            format!("{p:?}"),
            format!("{cumulative:?}"),
        ]);
    }
    csv.finish()
}

/// The morphospace plot: every specimen at its first two PCA scores
/// (0 where it has none), axes labelled with their `percent` explained,
/// coloured by the context's groups.
fn morphospace(alignment: &Alignment, context: &OutputContext, percent: &[f64]) -> Scatter {
    let names = &alignment.names;
    let pc = |i: usize, c: usize| alignment.pca.scores[i].get(c).copied().unwrap_or(0.0);
    let axis = |c: usize| match percent.get(c) {
        Some(p) => format!("PC{} ({p:.1} %)", c + 1),
        None => format!("PC{}", c + 1),
    };
    Scatter {
        title: match &context.groups {
            Some((rank, _)) => format!("Morphospace of {} specimens, by {rank}", names.len()),
            None => format!("Morphospace of {} specimens", names.len()),
        },
        x_label: axis(0),
        y_label: axis(1),
        points: (0..names.len()).map(|i| [pc(i, 0), pc(i, 1)]).collect(),
        names: names.clone(),
        groups: (0..names.len()).map(|i| group_of(context, i)).collect(),
    }
}

/// Write the morphospace plot as a PNG to `out/morphospace.png`.
fn write_morphospace_png(
    out: &Path,
    plot: &Scatter,
    written: &mut Written,
) -> Result<(), OutputError> {
    let png_path = out.join("morphospace.png");
    let png = scatter_raster(plot, 900, 640)
        .to_png()
        .map_err(|source| OutputError::Png {
            path: png_path.clone(),
            source,
        })?;
    write_atomic(&png_path, &png)?;
    written.files.push(png_path);
    Ok(())
}

/// Write the Procrustes distance matrix and, when the context has them,
/// the cP distances.
fn write_distance_matrices(
    out: &Path,
    alignment: &Alignment,
    context: &OutputContext,
    written: &mut Written,
) -> Result<(), OutputError> {
    let path = out.join("procrustes_distances.csv");
    alignment.procrustes_distances().write_csv(&path)?;
    written.files.push(path);
    if let Some(d) = context.distances {
        let path = out.join("cp_distances.csv");
        d.write_csv(&path)?;
        written.files.push(path);
    }
    Ok(())
}

/// The steps the template went along, each with its directed cP
/// distance, as CSV.
fn correspondence_steps_csv(alignment: &Alignment) -> String {
    let names = &alignment.names;
    let mut csv = CsvString::new();
    csv.record(["from", "to", "directed_cp_distance"]);
    for (&(a, b), d) in alignment
        .steps
        .iter()
        .zip(&alignment.carried.step_distances)
    {
        csv.record([names[a].clone(), names[b].clone(), format!("{d:?}")]);
    }
    csv.finish()
}

/// The JSON summary: specimens, template, mirror images, GPA and
/// synchronization figures, and who was left out and why.
fn summary(alignment: &Alignment, context: &OutputContext) -> serde_json::Value {
    let names = &alignment.names;
    serde_json::json!({
        "specimens": names,
        "template": names[alignment.template],
        "pseudolandmarks": alignment.gpa.mean.len(),
        "mirror_images": names.iter().zip(&alignment.carried.reflected).filter(|(_, r)| **r).map(|(n, _)| n).collect::<Vec<_>>(),
        "gpa_iterations": alignment.gpa.iterations,
        "synchronization_moves": alignment.sync_moves,
        "mean_centroid_size": alignment.mean_centroid_size(),
        "left_out": context.left_out.iter().map(|(n, why)| serde_json::json!({"name": n, "reason": why})).collect::<Vec<_>>(),
    })
}
