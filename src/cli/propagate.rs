//! `morphoid propagate`: carry landmarks of a reference onto another
//! surface through cP correspondences, directly, through listed
//! intermediate specimens, or along the minimum spanning tree of a
//! library's cP distances (the paper's Figures 2 and 3).

use anyhow::{bail, Context, Result};
use morphoid::cp::{self, Directed};
use morphoid::eval::DistanceMatrix;
use morphoid::landmarks::{self, Landmarks, Surface};
use morphoid::library;
use morphoid::mesh::bbox_diagonal;
use morphoid::pipeline::{self, PreparedSurface, Settings};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `morphoid propagate`.
#[derive(Debug, clap::Args)]
pub struct Args {
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
pub fn run(args: Args) -> Result<ExitCode> {
    super::configure_threads(args.threads)?;
    let settings = Settings::default();
    let input = landmarks::read(&args.landmarks, args.count)?;
    let (surfaces, path) = match &args.via_mst {
        None => {
            let mut files = vec![args.from.clone()];
            files.extend(args.via.iter().cloned());
            files.push(args.to.clone());
            let n = files.len();
            (prepare_all(&files, &settings)?, (0..n).collect())
        }
        Some(dir) => mst_route(&args, dir, &settings)?,
    };
    let steps: Vec<(usize, usize)> = path.windows(2).map(|w| (w[0], w[1])).collect();
    let maps: Vec<Directed> = steps
        .par_iter()
        .map(|&(a, b)| {
            cp::compare_directed(
                &surfaces[a].prepared,
                &surfaces[b].prepared,
                &settings.cp.compare,
            )
        })
        .collect();
    for (&(a, b), m) in steps.iter().zip(&maps) {
        eprintln!(
            "{} → {}: directed cP distance {:.6}{}",
            surfaces[a].prepared.name(),
            surfaces[b].prepared.name(),
            m.distance,
            if m.reflected { " (mirror image)" } else { "" }
        );
    }
    let indexed: Vec<Surface> = path
        .iter()
        .map(|&i| {
            Surface::from_prepared(&surfaces[i])
                .with_context(|| format!("surface {}", surfaces[i].prepared.name()))
        })
        .collect::<Result<_>>()?;
    let along: Vec<&Surface> = indexed.iter().collect();
    let map_refs: Vec<&[(u32, [f64; 3])]> =
        maps.iter().map(|m| m.correspondence.as_slice()).collect();
    let result = landmarks::propagate_along(&input, &along, &map_refs)
        .context("propagating the landmarks")?;
    warn_far_landmarks(&args.landmarks, &surfaces[path[0]], &result.source_offsets);
    write_output(args.out.as_deref(), &result.landmarks)?;
    Ok(ExitCode::SUCCESS)
}

/// Load, clean and prepare surfaces in parallel.
fn prepare_all(files: &[PathBuf], settings: &Settings) -> Result<Vec<PreparedSurface>> {
    Ok(files
        .par_iter()
        .map(|f| pipeline::prepare_file(f, settings))
        .collect::<Result<Vec<_>, _>>()?)
}

/// The surfaces of the library (plus REF and MESH when they are not in it)
/// and the path from REF to MESH in the minimum spanning tree of their cP
/// distances.
fn mst_route(
    args: &Args,
    dir: &Path,
    settings: &Settings,
) -> Result<(Vec<PreparedSurface>, Vec<usize>)> {
    let mut files = library::surface_files(dir)?;
    if files.is_empty() {
        bail!(
            "{}: no surface files (.obj, .ply, .stl, .off)",
            dir.display()
        );
    }
    let mut names: Vec<String> = files.iter().map(|f| stem(f)).collect();
    let index_of = |file: &Path, names: &mut Vec<String>, files: &mut Vec<PathBuf>| {
        let name = stem(file);
        match names.iter().position(|n| *n == name) {
            // The library's specimen of that name: use the given file, on
            // which the landmarks were placed.
            Some(i) => {
                files[i] = file.to_path_buf();
                i
            }
            None => {
                names.push(name);
                files.push(file.to_path_buf());
                files.len() - 1
            }
        }
    };
    let from = index_of(&args.from, &mut names, &mut files);
    let to = index_of(&args.to, &mut names, &mut files);
    let known = match &args.matrix {
        Some(m) => Some(DistanceMatrix::read_csv(m)?),
        None => None,
    };
    let n = files.len();
    eprintln!("preparing {n} surfaces for the spanning tree");
    let surfaces = prepare_all(&files, settings)?;
    let lookup = |i: usize, j: usize| -> Option<f64> {
        let m = known.as_ref()?;
        let a = m.names.iter().position(|x| *x == names[i])?;
        let b = m.names.iter().position(|x| *x == names[j])?;
        Some(m.get(a, b)).filter(|d| d.is_finite())
    };
    let pairs: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .collect();
    let missing = pairs
        .iter()
        .filter(|&&(i, j)| lookup(i, j).is_none())
        .count();
    if missing > 0 {
        eprintln!("computing {missing} cP distances");
    }
    let values: Vec<f64> = pairs
        .par_iter()
        .map(|&(i, j)| {
            lookup(i, j).unwrap_or_else(|| {
                cp::compare(
                    &surfaces[i].prepared,
                    &surfaces[j].prepared,
                    &settings.cp.compare,
                )
                .distance
            })
        })
        .collect();
    let mut d = vec![vec![0.0; n]; n];
    for (&(i, j), &v) in pairs.iter().zip(&values) {
        d[i][j] = v;
        d[j][i] = v;
    }
    let tree = landmarks::minimum_spanning_tree(&d);
    let path = landmarks::tree_path(n, &tree, from, to)
        .context("the spanning tree does not connect REF and MESH")?;
    let route: Vec<&str> = path.iter().map(|&i| names[i].as_str()).collect();
    eprintln!("path in the spanning tree: {}", route.join(" → "));
    Ok((surfaces, path))
}

fn stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Landmarks far from the reference surface usually mean another
/// coordinate system (e.g. RAS against a surface in LPS): say so.
fn warn_far_landmarks(file: &Path, source: &PreparedSurface, offsets: &[f64]) {
    let diagonal = bbox_diagonal(&source.cleaned);
    let far = offsets.iter().filter(|&&d| d > 0.02 * diagonal).count();
    if far > 0 {
        let worst = offsets.iter().copied().fold(0.0, f64::max);
        eprintln!(
            "warning: {far} landmark(s) of {} lie more than 2 % of the bounding-box diagonal from the reference surface (worst {:.3} %); are they in the same coordinates?",
            file.display(),
            100.0 * worst / diagonal
        );
    }
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
