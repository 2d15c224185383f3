//! `morphoid propagate`: carry landmarks of a reference onto another
//! surface through cP correspondences, directly, through listed
//! intermediate specimens, or along the minimum spanning tree of a
//! library's cP distances (the paper's Figures 2 and 3).

use super::common::ConfigFile;
use anyhow::Result;
use morphoid_data::landmarks::{self, Landmarks, Specimens};
use morphoid_data::library;
use morphoid_data::pipeline::{self, PreparedSurface, Settings};
use morphoid_data::table::DistanceMatrix;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `morphoid propagate`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
    /// The reference surface the landmarks belong to.
    #[arg(long)]
    from: PathBuf,
    /// The surface to carry the landmarks to.
    #[arg(long)]
    to: PathBuf,
    /// The reference's landmarks, in its file's coordinates (.csv, .fcsv,
    /// .mrk.json or .pp).
    #[arg(long)]
    landmarks: PathBuf,
    /// The number of landmarks the file must hold (an error otherwise).
    #[arg(long, value_name = "N")]
    count: Option<usize>,
    /// Output file, format by extension (.csv, .fcsv, .mrk.json, .pp);
    /// default: CSV on stdout.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Intermediate surfaces, in order: the landmarks go step by step
    /// from REF through each of them to MESH.
    #[arg(long, value_delimiter = ',', conflicts_with = "via_mst")]
    via: Vec<PathBuf>,
    /// A folder of surfaces: the path goes along the minimum spanning tree
    /// of their cP distances (REF and MESH included).
    #[arg(long, value_name = "LIBRARY_DIR")]
    via_mst: Option<PathBuf>,
    /// With --via-mst: a cP distance matrix CSV of the library (from
    /// `morphoid matrix`), so that only missing pairs are computed.
    #[arg(long, requires = "via_mst")]
    matrix: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

/// Run `morphoid propagate`.
pub(super) fn run(args: Args, config: ConfigFile) -> Result<ExitCode> {
    let settings = config.load()?.settings();
    super::configure_threads(args.threads)?;
    let input = landmarks::read(&args.landmarks, args.count)?;
    let (surfaces, route) = match &args.via_mst {
        None => {
            let mut files: Vec<&Path> = vec![&args.from];
            files.extend(args.via.iter().map(PathBuf::as_path));
            files.push(&args.to);
            let route = (0..files.len()).collect();
            (pipeline::prepare_files(&files, &settings)?, route)
        }
        Some(dir) => mst_route(&args, dir, &settings)?,
    };
    let carried = landmarks::carry_along(&input, &surfaces, &route, &settings.cp.compare)?;
    for (step, m) in route.windows(2).zip(&carried.maps) {
        eprintln!(
            "{} → {}: directed cP distance {:.6}{}",
            surfaces[step[0]].prepared.name(),
            surfaces[step[1]].prepared.name(),
            m.distance,
            if m.reflected { " (mirror image)" } else { "" }
        );
    }
    let source = &surfaces[route[0]].cleaned;
    if let Some((far, worst)) = landmarks::far_landmarks(source, &carried.result.source_offsets) {
        eprintln!(
            "warning: {far} landmark(s) of {} lie more than 2 % of the bounding-box diagonal from the reference surface (worst {worst:.3} %); are they in the same coordinates?",
            args.landmarks.display(),
        );
    }
    write_output(args.out.as_deref(), &carried.result.landmarks)?;
    Ok(ExitCode::SUCCESS)
}

/// The surfaces of the library (plus REF and MESH when they are not in it)
/// and the path from REF to MESH in the minimum spanning tree of their cP
/// distances.
fn mst_route(
    args: &Args,
    dir: &Path,
    settings: &Settings,
) -> Result<(Vec<PreparedSurface>, Vec<usize>)> {
    let members = library::members(dir)?;
    let (names, files) = members
        .into_iter()
        .map(|m| (m.name().to_string(), m.path().to_path_buf()))
        .unzip();
    let Specimens {
        names,
        files,
        from,
        to,
    } = landmarks::with_ends(names, files, &args.from, &args.to);
    let known = match &args.matrix {
        Some(m) => Some(DistanceMatrix::read_csv(m)?),
        None => None,
    };
    eprintln!("preparing {} surfaces for the spanning tree", files.len());
    let paths: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    let surfaces = pipeline::prepare_files(&paths, settings)?;
    let (d, computed) =
        landmarks::complete_distances(&names, &surfaces, known.as_ref(), &settings.cp.compare);
    eprintln!(
        "{computed} cP distances computed, {} taken from the matrix",
        names.len() * names.len().saturating_sub(1) / 2 - computed
    );
    let route = landmarks::spanning_tree_route(&d, &names, from, to)?;
    let shown: Vec<&str> = route.iter().map(|&i| names[i].as_str()).collect();
    eprintln!("path in the spanning tree: {}", shown.join(" → "));
    Ok((surfaces, route))
}

fn write_output(out: Option<&Path>, result: &Landmarks) -> Result<()> {
    match out {
        Some(path) => {
            landmarks::write(path, result)?;
            eprintln!("wrote {} landmarks to {}", result.len(), path.display());
        }
        None => print!("{}", landmarks::format(result, landmarks::Format::Csv)),
    }
    Ok(())
}
