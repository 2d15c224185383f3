//! `morphoid inspect`: load, clean, report.

use super::common::ConfigFile;
use anyhow::{Context, Result};
use morphoid_core::clean::{self, CleanOptions, CleanReport, CrownReport};
use morphoid_core::volume::VolumeOptions;
use morphoid_data::mesh_io::{self, Format};
use morphoid_data::pipeline::{self, Position, Settings, SplitReport};
use morphoid_data::volume::VolumeReport;
use serde::Serialize;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `morphoid inspect`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
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
    cloud: Option<morphoid_core::clean::CloudReport>,
    /// The crown cut from a closed whole tooth (absent for a crop).
    #[serde(skip_serializing_if = "Option::is_none")]
    crown: Option<CrownReport>,
    timings_ms: Timings,
    /// Slice folder or volume file: what segmentation did.
    #[serde(skip_serializing_if = "Option::is_none")]
    volume: Option<VolumeReport>,
    /// A surface file of several specimens: what the split dropped.
    #[serde(skip_serializing_if = "Option::is_none")]
    split: Option<SplitReport>,
    /// A scan of several specimens: each one (the fields above describe
    /// the first that could be cleaned).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    specimens: Vec<InspectedSpecimen>,
}

/// One specimen of a scan of several.
#[derive(Debug, Serialize)]
struct InspectedSpecimen {
    /// `<scan>#n`.
    name: String,
    position: Position,
    status: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    area: Option<f64>,
    /// Whether a crown was cut from a whole tooth.
    crown_cut: bool,
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
            split: None,
            specimens: Vec::new(),
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
pub(super) fn run(args: Args, config: ConfigFile) -> Result<ExitCode> {
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
    let settings = Settings {
        clean: opts.clone(),
        volume: volume_opts.clone(),
        ..Settings::default()
    };
    let loaded = pipeline::load_scan(&args.mesh, &settings)?;
    let t_load = t0.elapsed();
    let several = loaded.specimens.len() > 1;
    let mut first: Option<(clean::Cleaned, f64)> = None;
    let mut specimens = Vec::new();
    for (i, s) in loaded.specimens.iter().enumerate() {
        let t = Instant::now();
        let name = if several {
            format!("{}#{}", args.mesh.display(), i + 1)
        } else {
            args.mesh.display().to_string()
        };
        match clean::clean(&s.mesh, opts) {
            Ok(cleaned) => {
                let ms = t.elapsed().as_secs_f64() * 1e3;
                if several {
                    specimens.push(InspectedSpecimen {
                        name,
                        position: s.position.clone(),
                        status: "ok",
                        error: None,
                        area: Some(cleaned.report.area),
                        crown_cut: cleaned.report.crown.is_some(),
                    });
                }
                if first.is_none() {
                    first = Some((cleaned, ms));
                }
            }
            Err(e) if several => specimens.push(InspectedSpecimen {
                name,
                position: s.position.clone(),
                status: "error",
                error: Some(e.to_string()),
                area: None,
                crown_cut: false,
            }),
            Err(e) => return Err(e).with_context(|| format!("{}", args.mesh.display())),
        }
    }
    let Some((cleaned, clean_ms)) = first else {
        anyhow::bail!(
            "{}: none of its {} specimens could be cleaned",
            args.mesh.display(),
            specimens.len()
        );
    };
    if let Some(out) = &args.write_clean {
        mesh_io::save(out, &cleaned.mesh)
            .with_context(|| format!("writing the cleaned surface of {}", args.mesh.display()))?;
    }
    let mut report = Report::new(
        args.mesh.display().to_string(),
        loaded.format,
        &cleaned.report,
        Timings {
            load: t_load.as_secs_f64() * 1e3,
            clean: clean_ms,
        },
    );
    report.volume = loaded.volume;
    report.split = loaded.split;
    report.specimens = specimens;
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
    if !r.specimens.is_empty() {
        println!(
            "  {} specimens (in order along the scan's longest axis; the lines above are the first):",
            r.specimens.len()
        );
        for s in &r.specimens {
            let [lo, hi] = s.position.bounds;
            let at = format!(
                "({:.2}, {:.2}, {:.2})–({:.2}, {:.2}, {:.2})",
                lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
            );
            match &s.error {
                None => println!(
                    "    {}: ok, area {:.6}{}, at {at}",
                    s.name,
                    s.area.unwrap_or(0.0),
                    if s.crown_cut { ", crown cut" } else { "" }
                ),
                Some(e) => println!("    {}: error: {e}, at {at}", s.name),
            }
        }
    }
    if let Some(v) = &r.volume {
        for w in &v.segmentation.warnings {
            println!("  warning: {w}");
        }
    }
    if let Some(s) = &r.split {
        if s.debris + s.nested > 0 {
            println!(
                "  dropped {} debris or fragment component(s) and {} surface(s) nested inside a specimen",
                s.debris, s.nested
            );
        }
    }
    println!(
        "  load {:.1} ms, clean {:.1} ms",
        r.timings_ms.load, r.timings_ms.clean
    );
}
