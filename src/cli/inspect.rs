//! `morphoid inspect`: load, clean, report.

use super::common::ConfigFile;
use anyhow::{Context, Result};
use morphoid::clean::{self, CleanOptions, CleanReport, CrownReport};
use morphoid::mesh::io::{self, Format};
use morphoid::volume::{self, VolumeOptions, VolumeReport};
use serde::Serialize;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `morphoid inspect`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The surface file (OBJ, PLY, STL or OFF), or a volume: a folder of
    /// TIFF/PNG/BMP slices or a DICOM series, `.nrrd`, `.nii`, `.nii.gz`.
    mesh: PathBuf,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Write the cleaned surface here (format from the extension).
    #[arg(long, value_name = "OUT")]
    write_clean: Option<PathBuf>,
    /// Working resolution: about this many vertices after cleaning
    /// (default: `[clean] target_vertices` of the configuration).
    #[arg(long)]
    target_vertices: Option<usize>,
}

#[derive(Debug, Serialize)]
struct Counts {
    #[serde(skip_serializing_if = "Option::is_none")]
    format: Option<Format>,
    vertices: usize,
    faces: usize,
}

#[derive(Debug, Serialize)]
struct Report {
    status: &'static str,
    file: String,
    input: Counts,
    output: OutputCounts,
    welded_vertices: usize,
    removed_faces: usize,
    dropped_components: usize,
    filled_holes: usize,
    area: f64,
    bbox_diagonal: f64,
    repairs: Repairs,
    /// Point clouds: points in, outliers removed, triangles made.
    #[serde(skip_serializing_if = "Option::is_none")]
    cloud: Option<morphoid::clean::CloudReport>,
    /// The crown cut from a closed whole tooth (absent for a crop).
    #[serde(skip_serializing_if = "Option::is_none")]
    crown: Option<CrownReport>,
    timings_ms: Timings,
    /// Slice folder or volume file: what segmentation did.
    #[serde(skip_serializing_if = "Option::is_none")]
    volume: Option<VolumeReport>,
}

/// The rarer repairs, grouped so that the top level stays readable.
#[derive(Debug, Serialize)]
struct Repairs {
    nonmanifold_edges: usize,
    nonmanifold_vertices: usize,
    flipped_faces: usize,
    reversed_orientation: bool,
    triangulated_point_cloud: bool,
    edge_flips: usize,
}

impl Report {
    fn new(file: String, format: Option<Format>, r: &CleanReport, timings_ms: Timings) -> Self {
        Report {
            status: "ok",
            file,
            input: Counts {
                format,
                vertices: r.input_vertices,
                faces: r.input_faces,
            },
            output: OutputCounts {
                vertices: r.output_vertices,
                faces: r.output_faces,
                boundary_loops: r.boundary_loops,
                euler_characteristic: r.euler_characteristic,
            },
            welded_vertices: r.welded_vertices,
            removed_faces: r.removed_faces,
            dropped_components: r.dropped_components,
            filled_holes: r.filled_holes,
            area: r.area,
            bbox_diagonal: r.bbox_diagonal,
            repairs: Repairs {
                nonmanifold_edges: r.repaired_nonmanifold_edges,
                nonmanifold_vertices: r.repaired_nonmanifold_vertices,
                flipped_faces: r.flipped_faces,
                reversed_orientation: r.reversed_orientation,
                triangulated_point_cloud: r.triangulated_point_cloud,
                edge_flips: r.edge_flips,
            },
            cloud: r.cloud.clone(),
            crown: r.crown.clone(),
            timings_ms,
            volume: None,
        }
    }
}

#[derive(Debug, Serialize)]
struct OutputCounts {
    vertices: usize,
    faces: usize,
    boundary_loops: usize,
    euler_characteristic: i64,
}

#[derive(Debug, Serialize)]
struct Timings {
    load: f64,
    clean: f64,
}

/// Run `morphoid inspect`.
pub fn run(args: Args, config: ConfigFile) -> Result<ExitCode> {
    let _span = tracing::info_span!("inspect", scan = %args.mesh.display()).entered();
    let config = config.load()?;
    let mut opts = config.clean;
    if let Some(n) = args.target_vertices {
        opts.target_vertices = n;
    }
    match inspect(&args, &opts, &config.volume) {
        Ok(report) => {
            if args.json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                print_human(&report);
            }
            Ok(ExitCode::SUCCESS)
        }
        Err(e) => {
            let message = super::one_line(&e);
            if args.json {
                let out = serde_json::json!({
                    "status": "error",
                    "file": args.mesh.display().to_string(),
                    "error": message,
                });
                println!("{}", serde_json::to_string_pretty(&out)?);
            }
            eprintln!("morphoid: error: {message}");
            Ok(ExitCode::FAILURE)
        }
    }
}

fn inspect(args: &Args, opts: &CleanOptions, volume_opts: &VolumeOptions) -> Result<Report> {
    let t0 = Instant::now();
    let (mesh, format, volume_report) = if volume::is_volume_path(&args.mesh) {
        let s = volume::surface_from_path(&args.mesh, volume_opts)?;
        (s.mesh, None, Some(s.report))
    } else {
        let loaded = io::load(&args.mesh)?;
        (loaded.mesh, Some(loaded.format), None)
    };
    let t_load = t0.elapsed();
    let cleaned = clean::clean(&mesh, opts).with_context(|| format!("{}", args.mesh.display()))?;
    let t_clean = t0.elapsed() - t_load;
    if let Some(out) = &args.write_clean {
        io::save(out, &cleaned.mesh)
            .with_context(|| format!("writing the cleaned surface of {}", args.mesh.display()))?;
    }
    let mut report = Report::new(
        args.mesh.display().to_string(),
        format,
        &cleaned.report,
        Timings {
            load: t_load.as_secs_f64() * 1e3,
            clean: t_clean.as_secs_f64() * 1e3,
        },
    );
    report.volume = volume_report;
    Ok(report)
}

fn print_human(r: &Report) {
    println!("{}: ok", r.file);
    // A volume's surface is the isosurface of its specimen: named by the
    // volume's format, since the mesh has none.
    let format = match (&r.input.format, &r.volume) {
        (Some(f), _) => format!("{f:?}").to_lowercase(),
        (None, Some(v)) => format!("isosurface of a {:?} volume", v.input.format).to_lowercase(),
        (None, None) => "unknown format".to_string(),
    };
    println!(
        "  input   {:>8} vertices {:>8} faces ({format})",
        r.input.vertices, r.input.faces,
    );
    println!(
        "  output  {:>8} vertices {:>8} faces, {} boundary loop(s), Euler characteristic {}",
        r.output.vertices, r.output.faces, r.output.boundary_loops, r.output.euler_characteristic
    );
    println!(
        "  welded {} vertices, removed {} faces, dropped {} components, filled {} holes",
        r.welded_vertices, r.removed_faces, r.dropped_components, r.filled_holes
    );
    println!(
        "  area {:.6}, bounding-box diagonal {:.6}",
        r.area, r.bbox_diagonal
    );
    if let Some(c) = &r.crown {
        println!(
            "  crown cut from a closed whole tooth ({}{}): kept area {:.6}, removed {:.6} ({} faces), crease {:.1}°, cut at {:.2}–{:.2} of the tooth's length (mean {:.2}), filled {} holes, removed {} handles",
            c.method,
            if c.revoxelized {
                ", after a voxel grid closed its handles"
            } else {
                ""
            },
            c.kept_area,
            c.removed_area,
            c.removed_faces,
            c.crease_degrees,
            c.cut_height_min,
            c.cut_height_max,
            c.cut_height_mean,
            c.filled_holes,
            c.removed_handles
        );
    }
    println!(
        "  load {:.1} ms, clean {:.1} ms",
        r.timings_ms.load, r.timings_ms.clean
    );
}
