//! `morphoid synth`: write a synthetic crown-like surface, so that a new user
//! can try every command without data of their own.

use super::common::ConfigFile;
use anyhow::{Context, Result};
use morphoid_data::mesh_io;
use morphoid_synth::mesh::{self as synth, CROWN_GENERA};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `morphoid synth`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
    /// Output file; the format follows the extension (.ply, .obj, .stl, .off).
    #[arg(long)]
    out: PathBuf,
    /// Crown configuration (a synthetic "genus").
    #[arg(long, default_value = "Tricuspis")]
    genus: String,
    /// Seed of the individual variation.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Approximate number of vertices.
    #[arg(long, default_value_t = 5000)]
    vertices: usize,
}

/// Run `morphoid synth`.
pub(super) fn run(args: Args, config: ConfigFile) -> Result<ExitCode> {
    // Nothing here depends on the configuration; a broken one is still
    // reported, as by every command.
    config.load()?;
    let genus = synth::crown_genus(&args.genus).with_context(|| {
        let names: Vec<&str> = CROWN_GENERA.iter().map(|g| g.name).collect();
        format!(
            "unknown crown configuration '{}' (known: {})",
            args.genus,
            names.join(", ")
        )
    })?;
    let mesh = synth::crown(genus, args.seed, args.vertices);
    mesh_io::save(&args.out, &mesh)?;
    println!(
        "{}: {} crown, seed {}, {} vertices, {} faces",
        args.out.display(),
        genus.name,
        args.seed,
        mesh.vertex_count(),
        mesh.face_count()
    );
    Ok(ExitCode::SUCCESS)
}
