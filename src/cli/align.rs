//! `morphoid align`: a whole collection in correspondence — the template's
//! vertices carried to every specimen through cP maps (along the minimum
//! spanning tree, or directly), pseudolandmarks, GPA, PCA and the files
//! morphometricians' tools read.

use super::common::{progress_bar, ConfigFile};
use anyhow::{bail, Context, Result};
use morphoid_data::library::{self, Preparation};
use morphoid_data::table::DistanceMatrix;
use morphoid_research::collection::{self, AlignParams, Consistency, OutputContext, SyncParams};
use morphoid_research::eval;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// How the correspondences are made consistent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(super) enum ConsistentArg {
    /// Compose the cP maps along the minimum spanning tree of the distances.
    Mst,
    /// One cP map from the template to each specimen.
    None,
    /// Along the minimum spanning tree, then synchronized: each
    /// specimen's image of the template agrees with those of its nearest
    /// neighbours carried by the cP maps between them.
    Sync,
}

/// Arguments of `morphoid align`.
#[derive(Debug, clap::Args)]
pub(super) struct Args {
    /// Folder of surfaces (a library folder; `meshes/` is used when the
    /// folder itself holds none). `labels.csv` in it, when present, colours
    /// the morphospace.
    #[arg(long)]
    library: PathBuf,
    /// Output folder (created if needed).
    #[arg(long)]
    out: PathBuf,
    /// Pseudolandmarks spread over the template.
    #[arg(long, value_name = "N", default_value_t = 1024)]
    pseudolandmarks: usize,
    /// The template specimen's name, or `auto`: the medoid of the cP
    /// distances.
    #[arg(long, value_name = "NAME|auto", default_value = "auto")]
    template: String,
    /// How correspondences reach the specimens: `mst` composes the maps
    /// along the minimum spanning tree of the cP distances (consistent
    /// over the collection, each map between similar specimens), `none`
    /// maps the template to each specimen directly, `sync` refines the
    /// `mst` images until each agrees with its 4 nearest neighbours' images
    /// carried by the direct cP maps (4 more maps per specimen).
    #[arg(long, value_enum, default_value_t = ConsistentArg::Mst)]
    consistent: ConsistentArg,
    /// A cP distance matrix CSV of the library (from `morphoid matrix`):
    /// only the pairs missing from it are computed.
    #[arg(long, value_name = "FILE")]
    matrix: Option<PathBuf>,
    /// Cache folder of prepared surfaces (default: the `[library] cache`
    /// of the configuration, else the default cache folder).
    #[arg(long, value_name = "DIR")]
    cache: Option<PathBuf>,
    /// The rank column of labels.csv that colours the morphospace
    /// (default: the first rank column).
    #[arg(long)]
    rank: Option<String>,
    /// Worker threads (default: all cores). The output does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
}

/// Run `morphoid align`.
pub(super) fn run(args: Args, file: ConfigFile) -> Result<ExitCode> {
    let config = file.load()?;
    let settings = config.settings();
    super::configure_threads(args.threads)?;
    if args.pseudolandmarks < 3 {
        bail!("--pseudolandmarks must be at least 3");
    }
    let started = Instant::now();
    let members = library::members(&args.library)?;
    if args.template != "auto" && !members.iter().any(|m| m.name() == args.template) {
        bail!(
            "template `{}` is not among the specimens of {}",
            args.template,
            args.library.display()
        );
    }
    let cache = config.cache_for(&args.library, args.cache.as_deref())?;
    let preparation = Preparation::new(Some(&cache), &settings);
    let bar = progress_bar(members.len() as u64, "preparing");
    let (prepared, failures) =
        collection::prepare_collection(&members, &preparation, |_| bar.inc(1));
    bar.finish_and_clear();
    let left_out: Vec<(String, String)> = failures
        .iter()
        .map(|f| (f.name().to_string(), f.error().to_string()))
        .collect();
    for (name, why) in &left_out {
        eprintln!("warning: `{name}` left out: {why}");
    }
    eprintln!(
        "{} specimens prepared ({} from the cache){}",
        prepared.len(),
        preparation.reused(),
        if left_out.is_empty() {
            String::new()
        } else {
            format!(", {} left out", left_out.len())
        }
    );
    let known = match &args.matrix {
        Some(m) => Some(DistanceMatrix::read_csv(m)?),
        None => None,
    };
    let n = prepared.len();
    let bar = progress_bar((n * n.saturating_sub(1) / 2) as u64, "distances");
    let (distances, computed) =
        collection::collection_distances(&prepared, known.as_ref(), &settings.cp.compare, |_| {
            bar.inc(1)
        });
    bar.finish_and_clear();
    eprintln!(
        "{computed} cP distances computed, {} taken from the matrix",
        n * n.saturating_sub(1) / 2 - computed
    );
    let params = AlignParams {
        pseudolandmarks: args.pseudolandmarks,
        template: (args.template != "auto").then(|| args.template.clone()),
        consistency: match args.consistent {
            ConsistentArg::Mst => Consistency::SpanningTree,
            ConsistentArg::None => Consistency::Direct,
            ConsistentArg::Sync => Consistency::Synchronized(SyncParams::default()),
        },
        ..AlignParams::default()
    };
    let bar = progress_bar(params.consistency.maps(n) as u64, "cP maps");
    let alignment =
        collection::align(&prepared, &distances, &params, &settings.cp.compare, |_| {
            bar.inc(1)
        })?;
    bar.finish_and_clear();
    eprintln!(
        "template {}; {} pseudolandmarks on {} specimens; GPA in {} iterations",
        alignment.names[alignment.template],
        alignment.gpa.mean.len(),
        n,
        alignment.gpa.iterations
    );
    let groups = eval::folder_groups(&args.library, &alignment.names, args.rank.as_deref())?;
    let context = OutputContext {
        distances: Some(&distances),
        groups: groups.as_ref().map(|(r, g)| (r.as_str(), g.clone())),
        left_out: &left_out,
    };
    let written = collection::write_outputs(&args.out, &alignment, &prepared, &context)
        .with_context(|| format!("writing the outputs into {}", args.out.display()))?;
    eprintln!(
        "wrote {} files into {} in {:.1} s",
        written.files.len(),
        args.out.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}
