//! `morphoid distance`: the cP distance and correspondence of two surfaces,
//! their cWn distance (`--method cwn`), or their cW distance and the
//! correspondence of its map (`--method cw`).

use super::common::{write_output, ConfigFile};
use super::method::{CwArgs, CwnArgs, Method};
use anyhow::{bail, Context, Result};
use morphoid_core::cp;
use morphoid_core::cw;
use morphoid_core::cwn;
use morphoid_data::landmarks;
use morphoid_data::pipeline::{self, PreparedSurface, Settings, StageTimings};
use morphoid_research::surfaces::SurfaceDistance;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `morphoid distance`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
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
    /// Which distance: cp (continuous Procrustes), cwn (conformal
    /// Wasserstein neighbourhood dissimilarity) or cw (conformal
    /// Wasserstein; `--map` writes the correspondence of its map).
    #[arg(long, value_enum, default_value_t = Method::Cp)]
    method: Method,
    #[command(flatten)]
    cwn: CwnArgs,
    #[command(flatten)]
    cw: CwArgs,
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
    method: &'static str,
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

/// The cWn result as JSON.
#[derive(Debug, Serialize)]
struct CwnOutput {
    a: String,
    b: String,
    method: &'static str,
    distance: f64,
    radius: f64,
    reflections: bool,
    /// Share of the transported mass matched to mirror-image neighbourhoods.
    reflected_share: f64,
    pivots: usize,
    area_a: f64,
    area_b: f64,
    timings_ms: CwnTimings,
}

#[derive(Debug, Serialize)]
struct CwnTimings {
    a: StageTimings,
    b: StageTimings,
    landscapes: f64,
    cost: f64,
    transport: f64,
    compare: f64,
}

/// Run `morphoid distance`.
pub(super) fn run(args: Args, config: ConfigFile) -> Result<ExitCode> {
    let settings = config.load()?.settings();
    super::configure_threads(args.threads)?;
    match args.method {
        Method::Cp => run_cp(args, &settings),
        Method::Cwn => run_cwn(args, &settings),
        Method::Cw => run_cw(args, &settings),
        Method::Landmarks => bail!(
            "--method landmarks compares the landmark files of a library: use `morphoid matrix --method landmarks`"
        ),
    }
}

/// Load, clean and prepare both surfaces (in parallel).
fn prepare_both(args: &Args, settings: &Settings) -> Result<(PreparedSurface, PreparedSurface)> {
    let mut both = pipeline::prepare_files(&[&args.a, &args.b], settings)?.into_iter();
    match (both.next(), both.next()) {
        (Some(a), Some(b)) => Ok((a, b)),
        _ => bail!("preparing two surfaces gave fewer than two"),
    }
}

/// Write the correspondence of `map` from `a` to `b` (`--map`).
fn write_correspondence(
    out: &Path,
    a: &PreparedSurface,
    b: &PreparedSurface,
    map: &cp::Directed,
) -> Result<()> {
    let text = landmarks::correspondence_csv(a, b, map)
        .context("the correspondence does not fit the surfaces")?;
    write_output(out, text).context("writing the correspondence")
}

/// The cWn distance: landscapes of both surfaces, then one transport.
fn run_cwn(args: Args, settings: &Settings) -> Result<ExitCode> {
    if args.map.is_some() {
        bail!("--map writes the cP correspondence; it is not available with --method cwn");
    }
    let params = args.cwn.params();
    SurfaceDistance::Cwn(params.clone()).validate()?;
    let (a, b) = prepare_both(&args, settings)?;
    let t = Instant::now();
    let (la, lb) = rayon::join(
        || morphoid_research::surfaces::landscape(&a.prepared, &params),
        || morphoid_research::surfaces::landscape(&b.prepared, &params),
    );
    let (la, lb) = (la?, lb?);
    let landscapes_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let r = {
        let _s =
            tracing::info_span!("cwn", a = %a.prepared.name(), b = %b.prepared.name()).entered();
        cwn::distance(&la, &lb, &params)?
    };
    let compare_ms = t.elapsed().as_secs_f64() * 1e3;
    let out = CwnOutput {
        a: args.a.display().to_string(),
        b: args.b.display().to_string(),
        method: Method::Cwn.name(),
        distance: r.distance,
        radius: params.radius,
        reflections: params.reflections,
        reflected_share: r.reflected_share,
        pivots: r.pivots,
        area_a: a.cleaning.area,
        area_b: b.cleaning.area,
        timings_ms: CwnTimings {
            a: a.timings,
            b: b.timings,
            landscapes: landscapes_ms,
            cost: r.cost_ms,
            transport: r.transport_ms,
            compare: compare_ms,
        },
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "cWn distance {:.6} (R = {}, {:.0} % of the mass matched to mirror images); compared in {:.1} ms",
            out.distance,
            out.radius,
            100.0 * out.reflected_share,
            compare_ms
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// The cW result as JSON.
#[derive(Debug, Serialize)]
struct CwOutput {
    a: String,
    b: String,
    method: &'static str,
    distance: f64,
    reflections: bool,
    /// Whether the best map reverses orientation (mirror images).
    reflected: bool,
    /// The best map from A's disk to B's.
    mobius: cp::Mobius,
    /// Candidate maps screened and exact transport problems solved.
    screened: usize,
    exact_solves: usize,
    area_a: f64,
    area_b: f64,
    timings_ms: CwTimings,
}

#[derive(Debug, Serialize)]
struct CwTimings {
    a: StageTimings,
    b: StageTimings,
    screen: f64,
    exact: f64,
    compare: f64,
}

/// The cW distance and, with `--map`, the correspondence of its map.
fn run_cw(args: Args, settings: &Settings) -> Result<ExitCode> {
    let params = args.cw.params();
    SurfaceDistance::Cw(params.clone()).validate()?;
    let (a, b) = prepare_both(&args, settings)?;
    let t = Instant::now();
    let r = {
        let _s =
            tracing::info_span!("cw", a = %a.prepared.name(), b = %b.prepared.name()).entered();
        cw::distance(&a.prepared, &b.prepared, &params)?
    };
    let compare_ms = t.elapsed().as_secs_f64() * 1e3;
    if let Some(out) = &args.map {
        let directed = cw::correspondence(&a.prepared, &b.prepared, &r)
            .context("the cW map has no correspondence (a surface without triangles)")?;
        write_correspondence(out, &a, &b, &directed)?;
    }
    let out = CwOutput {
        a: args.a.display().to_string(),
        b: args.b.display().to_string(),
        method: Method::Cw.name(),
        distance: r.distance,
        reflections: params.reflections,
        reflected: r.reflected,
        mobius: r.mobius,
        screened: r.screened,
        exact_solves: r.exact_solves,
        area_a: a.cleaning.area,
        area_b: b.cleaning.area,
        timings_ms: CwTimings {
            a: a.timings,
            b: b.timings,
            screen: r.screen_ms,
            exact: r.exact_ms,
            compare: compare_ms,
        },
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "cW distance {:.6}{} ({} maps screened, {} exact transports); compared in {:.1} ms",
            out.distance,
            if out.reflected { ", mirror images" } else { "" },
            out.screened,
            out.exact_solves,
            compare_ms
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// The cP distance and, with `--map`, the correspondence.
fn run_cp(args: Args, settings: &Settings) -> Result<ExitCode> {
    let (a, b) = prepare_both(&args, settings)?;
    let t = Instant::now();
    let c = {
        let _s = tracing::info_span!("compare", a = %a.prepared.name(), b = %b.prepared.name())
            .entered();
        cp::compare(&a.prepared, &b.prepared, &settings.cp.compare)
    };
    let compare_ms = t.elapsed().as_secs_f64() * 1e3;
    if let Some(out) = &args.map {
        write_correspondence(out, &a, &b, &c.forward)?;
    }
    let out = Output {
        a: args.a.display().to_string(),
        b: args.b.display().to_string(),
        method: Method::Cp.name(),
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
