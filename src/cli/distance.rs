//! `morphoid distance`: the cP distance and correspondence of two surfaces.

use anyhow::{Context, Result};
use morphoid::cp::{self, Directed};
use morphoid::pipeline::{self, PreparedSurface, Settings, StageTimings};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `morphoid distance`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// First surface.
    a: PathBuf,
    /// Second surface.
    b: PathBuf,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Write the correspondence A → B as CSV: for each vertex of the cleaned
    /// A, the triangle of the cleaned B, barycentric coordinates, and the
    /// image point (in B's file units).
    #[arg(long, value_name = "OUT.csv")]
    map: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

#[derive(Debug, Serialize)]
struct DirectedJson {
    distance: f64,
    reflected: bool,
}

#[derive(Debug, Serialize)]
struct Output {
    a: String,
    b: String,
    distance: f64,
    forward: DirectedJson,
    backward: DirectedJson,
    reflected: bool,
    /// Surface areas in file units (size is reported; distances are at area 1).
    area_a: f64,
    area_b: f64,
    timings_ms: Timings,
}

#[derive(Debug, Serialize)]
struct Timings {
    a: StageTimings,
    b: StageTimings,
    compare: f64,
}

/// Run `morphoid distance`.
pub fn run(args: Args) -> Result<ExitCode> {
    super::configure_threads(args.threads)?;
    let settings = Settings::default();
    let (a, b) = rayon::join(
        || pipeline::prepare_file(&args.a, &settings),
        || pipeline::prepare_file(&args.b, &settings),
    );
    let (a, b) = (a?, b?);
    let t = Instant::now();
    let c = {
        let _s =
            tracing::info_span!("compare", a = %a.prepared.name, b = %b.prepared.name).entered();
        cp::compare(&a.prepared, &b.prepared, &settings.cp)
    };
    let compare_ms = t.elapsed().as_secs_f64() * 1e3;
    if let Some(out) = &args.map {
        write_map(out, &a, &b, &c.forward)
            .with_context(|| format!("writing the correspondence to {}", out.display()))?;
    }
    let out = Output {
        a: args.a.display().to_string(),
        b: args.b.display().to_string(),
        distance: c.distance,
        forward: DirectedJson {
            distance: c.forward.distance,
            reflected: c.forward.reflected,
        },
        backward: DirectedJson {
            distance: c.backward.distance,
            reflected: c.backward.reflected,
        },
        reflected: c.reflected,
        area_a: a.cleaning.area,
        area_b: b.cleaning.area,
        timings_ms: Timings {
            a: a.timings,
            b: b.timings,
            compare: compare_ms,
        },
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "cP distance {:.6}{} (A→B {:.6}, B→A {:.6}); compared in {:.1} ms",
            out.distance,
            if out.reflected { ", mirror images" } else { "" },
            out.forward.distance,
            out.backward.distance,
            compare_ms
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// The correspondence as CSV, one row per vertex of the cleaned A.
fn write_map(
    path: &Path,
    a: &PreparedSurface,
    b: &PreparedSurface,
    forward: &Directed,
) -> Result<()> {
    let mut text = String::from("vertex,x,y,z,face,b0,b1,b2,tx,ty,tz\n");
    for (v, (x, &(face, bary))) in a
        .cleaned
        .vertices
        .iter()
        .zip(&forward.correspondence)
        .enumerate()
    {
        let tri = b
            .prepared
            .faces
            .get(face as usize)
            .context("the correspondence names a triangle that does not exist")?;
        let mut image = [0.0; 3];
        for (k, &corner) in tri.iter().enumerate() {
            let p = b.cleaned.vertices[corner as usize];
            for d in 0..3 {
                image[d] += bary[k] * p[d];
            }
        }
        writeln!(
            text,
            "{v},{},{},{},{face},{},{},{},{},{},{}",
            x[0], x[1], x[2], bary[0], bary[1], bary[2], image[0], image[1], image[2]
        )?;
    }
    std::fs::write(path, text)?;
    Ok(())
}
