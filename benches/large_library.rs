//! How identification grows with the reference library (issue #33): the
//! preparation of libraries of 116, 1,000, 5,000 and 10,000 references,
//! and the identification of the same five scans against each.
//!
//! Every library is made in a temporary folder (never in the repository)
//! from one reproducible sequence, so that a larger library holds every
//! smaller one: the real teeth but five held out (their files copied),
//! then in turn a perturbed copy of a real tooth (a new random rigid
//! motion and 0.1 % noise on every vertex coordinate, written with the
//! project's mesh writer) and a synthetic crown of one of
//! [`SYNTHETIC_GENERA`] synthetic genera (variants of `morphoid_synth`'s
//! configurations), all labelled in `labels.csv` with the real one's
//! columns. The scans are the five held-out teeth after a new rigid
//! motion: not in any library.
//!
//! Each library is prepared with `morphoid library build` into a cache of
//! its own (`[library] calibrate = false`, unless `MORPHOID_BENCH_CALIBRATE=1`:
//! then the build time includes the calibration), then each scan is identified with one `morphoid
//! classify` process into a database of the library's own. Every command
//! runs under GNU time (`/usr/bin/time`, Debian package `time`), which
//! reports the wall time, CPU time (user + system) and peak RSS of
//! morphoid alone: a child forked from this process would carry this
//! process's own peak into its `ru_maxrss` across `exec`, one forked from
//! `time` does not. Nothing is asserted about the figures.
//!
//! Prints one row per library size and scan, then a summary per size.
//!
//! ```sh
//! MORPHOID_BENCH_SIZES=116,1000 cargo bench --bench large_library
//! ```
//!
//! Environment:
//! - `MORPHOID_BENCH_SIZES`: the library sizes, comma-separated (default
//!   `116,1000`; 5,000 and 10,000 take long to prepare);
//! - `MORPHOID_BENCH_SEED`: the seed of everything made (default 33);
//! - `MORPHOID_BENCH_CSV`: also write the rows as CSV to this file;
//! - `MORPHOID_BENCH_CALIBRATE=1`: calibrate each library in its build, so
//!   that answers carry their confidence;
//! - `MORPHOID_TEETH`: the real teeth (`labels.csv` and `meshes/`), else
//!   `../shared/data/pnas-teeth` beside the repository;
//! - `TMPDIR`: where the temporary folder is made (removed at the end);
//! - `MORPHOID_BENCH_WORK`: a folder to work in instead, kept at the end,
//!   so that a second run finds the libraries' caches prepared and measures
//!   the identifications only;
//! - `MORPHOID_BENCH_COPIES=N`: instead of the sizes above, one library of
//!   every real tooth N times, each copy with its own rigid motion and
//!   0.1 % noise (N = 9 gives the 1,044 references of issue #33). Nothing
//!   is held out: the five scans are real teeth after a new rigid motion,
//!   with their own copies in the library, as when a collection's
//!   specimens are scanned again.

use anyhow::{bail, ensure, Context, Result};
use morphoid_core::mesh::bbox_diagonal;
use morphoid_data::atomic_write::write_atomic;
use morphoid_data::library::Library;
use morphoid_data::mesh_io;
use morphoid_data::table::csv_text::{self, CsvString};
use morphoid_synth::mesh::{
    rigid_motion, specimen_mesh, CrownGenus, Cusp, LibrarySpec, Mesh, CROWN_GENERA,
};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::time::Instant;
use support::measured::{run_measured, Cost, GNU_TIME};

#[allow(dead_code)]
#[path = "../tests/it/support/mod.rs"]
mod support;

/// Library sizes measured when `MORPHOID_BENCH_SIZES` is not set.
const DEFAULT_SIZES: &str = "116,1000";
/// Seed when `MORPHOID_BENCH_SEED` is not set.
const DEFAULT_SEED: u64 = 33;
/// Real teeth held out of every library and identified against it.
const SCANS: usize = 5;
/// Noise of a perturbed copy: each vertex coordinate moved by up to this
/// fraction of the bounding-box diagonal (uniform).
const VERTEX_NOISE: f64 = 0.001;
/// Synthetic genera the synthetic crowns are spread over.
const SYNTHETIC_GENERA: usize = 60;
/// Vertices of a synthetic crown (about the real teeth's count).
const SYNTHETIC_VERTICES: usize = 5000;
/// The perturbed copies' seed stream (see [`mixed_seed`]).
const PERTURBED_STREAM: u64 = 1;
/// The synthetic crowns' seed stream.
const SYNTHETIC_STREAM: u64 = 2;
/// The synthetic genera's seed stream.
const GENUS_STREAM: u64 = 3;
/// The scans' seed stream.
const SCAN_STREAM: u64 = 4;

fn main() -> Result<()> {
    // `cargo bench` passes `--bench`; the knobs are in the environment.
    let sizes = bench_sizes()?;
    let seed = bench_seed()?;
    let csv_out = std::env::var_os("MORPHOID_BENCH_CSV").map(PathBuf::from);
    let bin = Path::new(env!("CARGO_BIN_EXE_morphoid"));
    ensure!(
        Path::new(GNU_TIME).is_file(),
        "{GNU_TIME} not found: it measures each morphoid process (Debian package `time`)"
    );
    let teeth = read_real_teeth(&teeth_folder()?)?;
    let work = WorkFolder::new()?;
    let work = work.path();

    let held_out = choose_held_out(&teeth, seed, SCANS)?;
    let scans = write_scans(&teeth, &held_out, seed, &work.join("scans"))?;
    let copies = bench_copies()?;
    let sizes = match copies {
        Some(n) => vec![n * teeth.teeth.len()],
        None => sizes,
    };
    println!(
        "library sizes {sizes:?}, seed {seed}, {} real teeth, work folder {}",
        teeth.teeth.len(),
        work.display()
    );
    let largest = sizes.iter().copied().max().unwrap_or(0);
    let genera = synthetic_genera(seed, SYNTHETIC_GENERA);
    let plan = match copies {
        Some(n) => plan_copies(&teeth, seed, n),
        None => plan_references(&teeth, &held_out, &genera, seed, largest),
    };
    let pool = work.join("pool");
    let t = Instant::now();
    write_reference_files(&teeth, &genera, &plan, &pool)?;
    println!(
        "{} reference files made in {:.1} s (scans: {})",
        plan.len(),
        t.elapsed().as_secs_f64(),
        scans
            .iter()
            .map(|s| s.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    );

    let mut rows = Vec::new();
    for &size in &sizes {
        let library = LibraryRun {
            bin,
            work,
            header: &teeth.header,
            references: &plan[..size],
            pool: &pool,
        };
        rows.extend(measure_library(&library, &scans)?);
    }
    print_rows(&rows);
    print_summary(&rows);
    if let Some(path) = csv_out {
        write_atomic(&path, rows_csv(&rows).as_bytes())
            .with_context(|| format!("writing MORPHOID_BENCH_CSV={}", path.display()))?;
        println!("rows written to {}", path.display());
    }
    Ok(())
}

/// Where the libraries, caches and databases are made: a temporary folder
/// (removed when dropped), or `MORPHOID_BENCH_WORK` (kept).
enum WorkFolder {
    Temporary(tempfile::TempDir),
    Kept(PathBuf),
}

impl WorkFolder {
    fn new() -> Result<Self> {
        match std::env::var_os("MORPHOID_BENCH_WORK") {
            Some(dir) => {
                let dir = PathBuf::from(dir);
                std::fs::create_dir_all(&dir)
                    .with_context(|| format!("creating MORPHOID_BENCH_WORK={}", dir.display()))?;
                Ok(WorkFolder::Kept(dir))
            }
            None => Ok(WorkFolder::Temporary(
                tempfile::Builder::new()
                    .prefix("morphoid-large-library-")
                    .tempdir()
                    .context("making the temporary folder (TMPDIR)")?,
            )),
        }
    }

    fn path(&self) -> &Path {
        match self {
            WorkFolder::Temporary(t) => t.path(),
            WorkFolder::Kept(p) => p,
        }
    }
}

/// What one library's measurement needs.
struct LibraryRun<'a> {
    /// The `morphoid` binary.
    bin: &'a Path,
    /// The temporary folder.
    work: &'a Path,
    /// The columns of `labels.csv`.
    header: &'a [String],
    /// The library's references.
    references: &'a [Reference],
    /// The folder holding every reference's file.
    pool: &'a Path,
}

/// Make the library of `run.references`, prepare it into a cache of its
/// own with `morphoid library build`, then identify each scan against it
/// with `morphoid classify`: one row per scan.
fn measure_library(run: &LibraryRun, scans: &[Scan]) -> Result<Vec<Row>> {
    let size = run.references.len();
    let lib = run.work.join(format!("library-{size}"));
    link_library(run.header, run.references, run.pool, &lib)?;
    let config = run.work.join(format!("morphoid-{size}.toml"));
    let cache = run.work.join(format!("cache-{size}"));
    let db = run.work.join(format!("ids-{size}.sqlite"));
    // A kept work folder's database knows the scans already: identifying
    // them again would only look them up.
    for stale in [
        db.clone(),
        db.with_extension("sqlite-wal"),
        db.with_extension("sqlite-shm"),
    ] {
        if stale.exists() {
            std::fs::remove_file(&stale)
                .with_context(|| format!("removing {}", stale.display()))?;
        }
    }
    write_config(&config, &lib, &cache, &db)?;
    let build = prepare_library(run.bin, &config, run.work)?;
    let cache_bytes = folder_bytes(&cache)?;
    println!(
        "{size} references: library build {:.1} s wall, {:.1} s CPU, {:.0} MB peak RSS; cache {:.1} MB; {}",
        build.cost.wall,
        build.cost.cpu,
        build.cost.peak_rss_mb,
        cache_bytes as f64 / 1e6,
        build.summary
    );
    let mut rows = Vec::new();
    for scan in scans {
        let id = identify_scan(run.bin, &config, &scan.path, run.work)?;
        println!(
            "  {}: {:.2} s wall, {:.2} s CPU, {:.0} MB peak RSS, comparing {:.2} s; genus {} (truth {})",
            scan.name,
            id.cost.wall,
            id.cost.cpu,
            id.cost.peak_rss_mb,
            id.compare_seconds,
            id.genus,
            scan.genus
        );
        rows.push(Row {
            composition: Composition::of(run.references),
            build: build.clone(),
            cache_bytes,
            scan: scan.name.clone(),
            expected_genus: scan.genus.clone(),
            identification: id,
        });
    }
    Ok(rows)
}

/// The sizes of `MORPHOID_BENCH_SIZES` (default [`DEFAULT_SIZES`]),
/// ascending, each once.
fn bench_sizes() -> Result<Vec<usize>> {
    let text = std::env::var("MORPHOID_BENCH_SIZES").unwrap_or_else(|_| DEFAULT_SIZES.into());
    let sizes: BTreeSet<usize> = text
        .split(',')
        .map(|s| {
            let n: usize = s.trim().parse().with_context(|| {
                format!("MORPHOID_BENCH_SIZES={text}: `{s}` is not a count of references")
            })?;
            ensure!(
                n > 0,
                "MORPHOID_BENCH_SIZES={text}: a library needs a reference"
            );
            Ok(n)
        })
        .collect::<Result<_>>()?;
    Ok(sizes.into_iter().collect())
}

/// `MORPHOID_BENCH_COPIES`, if set: how many perturbed copies of each real
/// tooth make the one library measured.
fn bench_copies() -> Result<Option<usize>> {
    match std::env::var("MORPHOID_BENCH_COPIES") {
        Err(_) => Ok(None),
        Ok(s) => match s.trim().parse::<usize>() {
            Ok(n) if n > 0 => Ok(Some(n)),
            _ => bail!("MORPHOID_BENCH_COPIES={s}: not a positive count of copies"),
        },
    }
}

/// `MORPHOID_BENCH_SEED`, default [`DEFAULT_SEED`].
fn bench_seed() -> Result<u64> {
    match std::env::var("MORPHOID_BENCH_SEED") {
        Ok(s) => s
            .trim()
            .parse()
            .with_context(|| format!("MORPHOID_BENCH_SEED={s}: not an unsigned integer")),
        Err(_) => Ok(DEFAULT_SEED),
    }
}

/// The real teeth's folder (`MORPHOID_TEETH`, else beside the repository),
/// or an error saying where it was looked for.
fn teeth_folder() -> Result<PathBuf> {
    let dir = support::data::teeth_location();
    ensure!(
        dir.join("labels.csv").is_file() && dir.join("meshes").is_dir(),
        "the real teeth are not at {} (labels.csv and meshes/): put the 116 PNAS teeth there, \
         or name their folder in MORPHOID_TEETH",
        dir.display()
    );
    Ok(dir)
}

/// The real teeth: the columns of their `labels.csv` and each tooth.
struct RealTeeth {
    /// The header of `labels.csv` (`name` first).
    header: Vec<String>,
    /// The teeth, by name.
    teeth: Vec<RealTooth>,
}

/// One real tooth.
struct RealTooth {
    /// Its name (the file stem).
    name: String,
    /// Its surface file.
    path: PathBuf,
    /// Its row of `labels.csv`, every column.
    row: Vec<String>,
    /// Its genus, when known.
    genus: Option<String>,
}

/// The real teeth of `dir`, opened as a library (so labels and files are
/// checked to match), with their full rows of `labels.csv`.
fn read_real_teeth(dir: &Path) -> Result<RealTeeth> {
    let library = Library::open(dir, None)
        .with_context(|| format!("opening the real teeth at {}", dir.display()))?;
    let labels_path = dir.join("labels.csv");
    let text = std::fs::read_to_string(&labels_path)
        .with_context(|| format!("reading {}", labels_path.display()))?;
    let mut records = csv_text::rows(&text, false);
    let header = match records.next() {
        Some(Ok(row)) => row.fields,
        Some(Err(e)) => bail!("{}:{}: {e}", labels_path.display(), e.line),
        None => bail!("{}: empty", labels_path.display()),
    };
    ensure!(
        header.first().is_some_and(|c| c == "name"),
        "{}: the first column is not `name`",
        labels_path.display()
    );
    let genus_column = header.iter().position(|c| c == "genus");
    let mut rows = BTreeMap::new();
    for record in records {
        let row =
            record.map_err(|e| anyhow::anyhow!("{}:{}: {e}", labels_path.display(), e.line))?;
        rows.insert(row.fields[0].clone(), row.fields);
    }
    let teeth = library
        .members()
        .iter()
        .map(|m| {
            let row = rows
                .get(m.name())
                .cloned()
                .with_context(|| format!("{}: no row for {}", labels_path.display(), m.name()))?;
            let genus = genus_column
                .and_then(|k| row.get(k))
                .filter(|g| !g.is_empty() && *g != "NA")
                .cloned();
            Ok(RealTooth {
                name: m.name().to_string(),
                path: m.path().to_path_buf(),
                row,
                genus,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(RealTeeth { header, teeth })
}

/// `count` teeth to hold out, chosen by `seed`: each of a different
/// genus that keeps at least two other teeth in the library.
fn choose_held_out(teeth: &RealTeeth, seed: u64, count: usize) -> Result<Vec<usize>> {
    let mut per_genus: BTreeMap<&str, usize> = BTreeMap::new();
    for g in teeth.teeth.iter().filter_map(|t| t.genus.as_deref()) {
        *per_genus.entry(g).or_default() += 1;
    }
    let mut order: Vec<usize> = (0..teeth.teeth.len()).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let mut genera = BTreeSet::new();
    let mut chosen = Vec::new();
    for i in order {
        let Some(genus) = teeth.teeth[i].genus.as_deref() else {
            continue;
        };
        if per_genus[genus] >= 3 && genera.insert(genus) {
            chosen.push(i);
            if chosen.len() == count {
                chosen.sort_unstable();
                return Ok(chosen);
            }
        }
    }
    bail!("fewer than {count} genera with three teeth among the real teeth")
}

/// One scan to identify.
struct Scan {
    /// The held-out tooth it was made from.
    name: String,
    /// That tooth's genus.
    genus: String,
    /// The scan file.
    path: PathBuf,
}

/// The held-out teeth, each after a random rigid motion, written into
/// `dir` as `<name>-moved.ply`.
fn write_scans(teeth: &RealTeeth, held_out: &[usize], seed: u64, dir: &Path) -> Result<Vec<Scan>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    held_out
        .iter()
        .map(|&i| {
            let tooth = &teeth.teeth[i];
            let mesh = load_mesh(&tooth.path)?;
            let moved = rigid_motion(&mesh, mixed_seed(seed, SCAN_STREAM, i as u64));
            let path = dir.join(format!("{}-moved.ply", tooth.name));
            mesh_io::save(&path, &moved)
                .with_context(|| format!("writing the scan {}", path.display()))?;
            Ok(Scan {
                name: tooth.name.clone(),
                genus: tooth.genus.clone().unwrap_or_default(),
                path,
            })
        })
        .collect()
}

/// A surface read with the project's reader.
fn load_mesh(path: &Path) -> Result<Mesh> {
    Ok(mesh_io::load(path)
        .with_context(|| format!("reading {}", path.display()))?
        .mesh)
}

/// A seed of its own for item `index` of `stream`, from the master seed
/// (splitmix64's mixing).
fn mixed_seed(master: u64, stream: u64, index: u64) -> u64 {
    let mut z = master
        .wrapping_add(stream.wrapping_mul(0xD1B5_4A32_D192_ED03))
        .wrapping_add(index.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// `count` synthetic genera, each a variant of one of `morphoid_synth`'s
/// configurations in turn (cusps moved by up to 0.12 of the radius, their
/// heights ±25 %, widths ±20 %, the footprint's aspect ±10 % and the dome
/// ±30 %), named after it with a number (`Tricuspis01`, `Quadricuspis01`,
/// …) and filed under its family and order.
fn synthetic_genera(seed: u64, count: usize) -> Vec<CrownGenus> {
    (0..count)
        .map(|k| {
            let base = CROWN_GENERA[k % CROWN_GENERA.len()];
            let mut rng = ChaCha8Rng::seed_from_u64(mixed_seed(seed, GENUS_STREAM, k as u64));
            let mut within = |x: f64, spread: f64| x + spread * rng.gen_range(-1.0..=1.0);
            let cusps: Vec<Cusp> = base
                .cusps
                .iter()
                .map(|c| Cusp {
                    x: within(c.x, 0.12),
                    y: within(c.y, 0.12),
                    height: c.height * within(1.0, 0.25),
                    width: c.width * within(1.0, 0.2),
                    elongation: c.elongation,
                    angle: within(c.angle, 0.3),
                })
                .collect();
            let name = format!("{}{:02}", base.name, k / CROWN_GENERA.len() + 1);
            // A genus names its cusps and itself for the program's life:
            // a few dozen small allocations, leaked on purpose.
            CrownGenus {
                name: Box::leak(name.into_boxed_str()),
                family: base.family,
                order: base.order,
                cusps: Box::leak(cusps.into_boxed_slice()),
                aspect: base.aspect * within(1.0, 0.1),
                dome: base.dome * within(1.0, 0.3),
            }
        })
        .collect()
}

/// Where a reference's surface comes from.
#[derive(Debug, Clone, Copy)]
enum Source {
    /// The real tooth of this index, its file copied.
    Real(usize),
    /// The real tooth of this index moved and jittered with this seed.
    Perturbed { of: usize, seed: u64 },
    /// An individual of this synthetic genus, of this seed.
    Synthetic { genus: usize, seed: u64 },
}

/// One reference of the sequence every library is a prefix of.
#[derive(Debug, Clone)]
struct Reference {
    /// Its surface file's name in the pool and the library (the stem is
    /// its name).
    file: String,
    /// Its row of `labels.csv`, in the real one's columns.
    row: Vec<String>,
    /// Its surface.
    source: Source,
}

/// The first `count` references of the sequence: the real teeth not held
/// out, in name order, then in turn a perturbed copy of each of them and
/// a synthetic crown of each synthetic genus.
fn plan_references(
    teeth: &RealTeeth,
    held_out: &[usize],
    genera: &[CrownGenus],
    seed: u64,
    count: usize,
) -> Vec<Reference> {
    let kept: Vec<usize> = (0..teeth.teeth.len())
        .filter(|i| !held_out.contains(i))
        .collect();
    let mut plan: Vec<Reference> = kept
        .iter()
        .take(count)
        .map(|&i| {
            let tooth = &teeth.teeth[i];
            let extension = tooth
                .path
                .extension()
                .map_or_else(|| "ply".into(), |e| e.to_string_lossy().into_owned());
            Reference {
                file: format!("{}.{extension}", tooth.name),
                row: tooth.row.clone(),
                source: Source::Real(i),
            }
        })
        .collect();
    let (mut perturbed, mut synthetic) = (0usize, 0usize);
    while plan.len() < count {
        let reference = if perturbed <= synthetic {
            let of = kept[perturbed % kept.len()];
            let name = format!("{}-p{perturbed:05}", teeth.teeth[of].name);
            let mut row = teeth.teeth[of].row.clone();
            row[0] = name.clone();
            let seed = mixed_seed(seed, PERTURBED_STREAM, perturbed as u64);
            perturbed += 1;
            Reference {
                file: format!("{name}.ply"),
                row,
                source: Source::Perturbed { of, seed },
            }
        } else {
            let genus = synthetic % genera.len();
            let name = format!(
                "{}-s{synthetic:05}",
                genera[genus].name.to_ascii_lowercase()
            );
            let row = synthetic_labels_row(&teeth.header, &name, &genera[genus]);
            let seed = mixed_seed(seed, SYNTHETIC_STREAM, synthetic as u64);
            synthetic += 1;
            Reference {
                file: format!("{name}.ply"),
                row,
                source: Source::Synthetic { genus, seed },
            }
        };
        plan.push(reference);
    }
    plan
}

/// The library of `MORPHOID_BENCH_COPIES`: `copies` perturbed copies of
/// every real tooth, copy by copy, named `<tooth>-c<k>`.
fn plan_copies(teeth: &RealTeeth, seed: u64, copies: usize) -> Vec<Reference> {
    let n = teeth.teeth.len();
    (0..copies * n)
        .map(|k| {
            let (of, copy) = (k % n, k / n);
            let name = format!("{}-c{copy}", teeth.teeth[of].name);
            let mut row = teeth.teeth[of].row.clone();
            row[0] = name.clone();
            Reference {
                file: format!("{name}.ply"),
                row,
                source: Source::Perturbed {
                    of,
                    seed: mixed_seed(seed, PERTURBED_STREAM, k as u64),
                },
            }
        })
        .collect()
}

/// A synthetic crown's row of `labels.csv` in the columns of `header`:
/// its name, order, family and genus, `NA` in every other column.
fn synthetic_labels_row(header: &[String], name: &str, genus: &CrownGenus) -> Vec<String> {
    header
        .iter()
        .map(|column| match column.as_str() {
            "name" => name,
            "order" => genus.order,
            "family" => genus.family,
            "genus" => genus.name,
            _ => "NA",
        })
        .map(str::to_string)
        .collect()
}

/// How many references of each kind a library holds.
#[derive(Debug, Clone, Copy, Default)]
struct Composition {
    /// Real teeth, their files copied.
    real: usize,
    /// Perturbed copies of real teeth.
    perturbed: usize,
    /// Synthetic crowns.
    synthetic: usize,
}

impl Composition {
    /// The kinds of `references`.
    fn of(references: &[Reference]) -> Self {
        let mut c = Composition::default();
        for r in references {
            match r.source {
                Source::Real(_) => c.real += 1,
                Source::Perturbed { .. } => c.perturbed += 1,
                Source::Synthetic { .. } => c.synthetic += 1,
            }
        }
        c
    }

    /// All references.
    fn total(&self) -> usize {
        self.real + self.perturbed + self.synthetic
    }
}

/// Write every planned reference's surface into `pool` (in parallel):
/// real teeth copied, perturbed copies and synthetic crowns written with
/// the project's mesh writer as binary PLY.
fn write_reference_files(
    teeth: &RealTeeth,
    genera: &[CrownGenus],
    plan: &[Reference],
    pool: &Path,
) -> Result<()> {
    std::fs::create_dir_all(pool).with_context(|| format!("creating {}", pool.display()))?;
    plan.par_iter().try_for_each(|r| -> Result<()> {
        let path = pool.join(&r.file);
        match r.source {
            Source::Real(i) => {
                let from = &teeth.teeth[i].path;
                std::fs::copy(from, &path)
                    .with_context(|| format!("copying {} to {}", from.display(), path.display()))?;
            }
            Source::Perturbed { of, seed } => {
                let mesh = load_mesh(&teeth.teeth[of].path)?;
                let moved = rigid_motion(&jittered(&mesh, VERTEX_NOISE, seed), seed);
                mesh_io::save(&path, &moved)
                    .with_context(|| format!("writing {}", path.display()))?;
            }
            Source::Synthetic { genus, seed } => {
                let spec = LibrarySpec {
                    per_genus: 1,
                    target_vertices: SYNTHETIC_VERTICES,
                    seed,
                    random_pose: true,
                };
                mesh_io::save(&path, &specimen_mesh(&genera[genus], seed, &spec))
                    .with_context(|| format!("writing {}", path.display()))?;
            }
        }
        Ok(())
    })
}

/// `mesh` with every vertex coordinate moved by a uniform amount of at
/// most `fraction` of its bounding-box diagonal.
fn jittered(mesh: &Mesh, fraction: f64, seed: u64) -> Mesh {
    let reach = fraction * bbox_diagonal(mesh);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let vertices = mesh
        .vertices
        .iter()
        .map(|p| p.map(|x| x + reach * rng.gen_range(-1.0..=1.0)))
        .collect();
    Mesh::new(vertices, mesh.faces.clone())
}

/// A library folder `lib` of `references`: their files hard-linked from
/// `pool` into `meshes/` (copied where a link cannot be made) and
/// `labels.csv` with the real teeth's columns.
fn link_library(
    header: &[String],
    references: &[Reference],
    pool: &Path,
    lib: &Path,
) -> Result<()> {
    let meshes = lib.join("meshes");
    std::fs::create_dir_all(&meshes).with_context(|| format!("creating {}", meshes.display()))?;
    for r in references {
        let (from, to) = (pool.join(&r.file), meshes.join(&r.file));
        // A kept work folder has the link already: copying onto it would
        // truncate the pool's file through the link.
        if to.exists() {
            std::fs::remove_file(&to).with_context(|| format!("removing {}", to.display()))?;
        }
        if std::fs::hard_link(&from, &to).is_err() {
            std::fs::copy(&from, &to)
                .with_context(|| format!("copying {} to {}", from.display(), to.display()))?;
        }
    }
    let mut labels = CsvString::new();
    labels.record(header);
    for r in references {
        labels.record(&r.row);
    }
    let path = lib.join("labels.csv");
    write_atomic(&path, labels.finish().as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// The configuration of one library's runs: the library, its own cache
/// and database, the calibration off unless `MORPHOID_BENCH_CALIBRATE=1`.
fn write_config(path: &Path, lib: &Path, cache: &Path, db: &Path) -> Result<()> {
    let text_of = |p: &Path| -> Result<toml::Value> {
        let s = p
            .to_str()
            .with_context(|| format!("{}: not UTF-8, cannot go in a configuration", p.display()))?;
        Ok(toml::Value::String(s.to_string()))
    };
    let mut library = toml::Table::new();
    library.insert("dir".into(), text_of(lib)?);
    library.insert("cache".into(), text_of(cache)?);
    let calibrate = std::env::var("MORPHOID_BENCH_CALIBRATE").is_ok_and(|v| v == "1");
    library.insert("calibrate".into(), toml::Value::Boolean(calibrate));
    let mut database = toml::Table::new();
    database.insert("path".into(), text_of(db)?);
    let mut config = toml::Table::new();
    config.insert("library".into(), toml::Value::Table(library));
    config.insert("database".into(), toml::Value::Table(database));
    let text = toml::to_string(&config).context("writing the configuration as TOML")?;
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

/// One `morphoid library build`: its cost, how many references it
/// prepared and how many failed, and its summary line.
#[derive(Debug, Clone)]
struct Preparation {
    /// The process's cost.
    cost: Cost,
    /// References prepared.
    prepared: usize,
    /// References that could not be prepared.
    failed: usize,
    /// Its summary line, without the folder in front.
    summary: String,
}

/// Prepare the library of `config` into its cache with `morphoid library
/// build`.
fn prepare_library(bin: &Path, config: &Path, work: &Path) -> Result<Preparation> {
    let args = [
        OsStr::new("--config"),
        config.as_os_str(),
        OsStr::new("library"),
        OsStr::new("build"),
    ];
    let (cost, stdout) = run_measured(bin, &args, &work.join("time.txt"))?;
    let summary = stdout
        .lines()
        .find(|l| l.contains(" references ("))
        .with_context(|| {
            format!("no summary line in `morphoid library build`'s output:\n{stdout}")
        })?
        .to_string();
    let count = |word: &str| {
        count_before(&summary, word).with_context(|| format!("no `N {word}` in: {summary}"))
    };
    Ok(Preparation {
        cost,
        prepared: count("prepared")?,
        failed: count("failed")?,
        summary: summary
            .split_once(": ")
            .map_or(summary.as_str(), |(_, rest)| rest)
            .to_string(),
    })
}

/// The number written just before `word` in `line` (`(116 prepared,` →
/// 116 for `prepared`).
fn count_before(line: &str, word: &str) -> Option<usize> {
    let words: Vec<&str> = line.split_whitespace().collect();
    words.windows(2).find_map(|w| {
        (w[1].trim_end_matches([',', ';']) == word)
            .then(|| w[0].trim_start_matches('(').parse().ok())
            .flatten()
    })
}

/// One scan identified by `morphoid classify`.
#[derive(Debug, Clone)]
struct Identification {
    /// The process's cost.
    cost: Cost,
    /// The genus answered.
    genus: String,
    /// The comparison with every reference, in seconds (its
    /// `timings_ms.compare`).
    compare_seconds: f64,
}

/// Identify `scan` with one `morphoid classify --json` process.
fn identify_scan(bin: &Path, config: &Path, scan: &Path, work: &Path) -> Result<Identification> {
    let args = [
        OsStr::new("--config"),
        config.as_os_str(),
        OsStr::new("classify"),
        OsStr::new("--json"),
        scan.as_os_str(),
    ];
    let (cost, stdout) = run_measured(bin, &args, &work.join("time.txt"))?;
    let line = stdout
        .lines()
        .find(|l| l.starts_with('{'))
        .with_context(|| {
            format!(
                "no JSON line from `morphoid classify` of {}",
                scan.display()
            )
        })?;
    let record: serde_json::Value = serde_json::from_str(line)
        .with_context(|| format!("`morphoid classify`'s JSON for {}", scan.display()))?;
    ensure!(
        record["status"] == "ok",
        "{} was not identified: {line}",
        scan.display()
    );
    Ok(Identification {
        cost,
        genus: record["ranks"]["genus"]["taxon"]
            .as_str()
            .unwrap_or("-")
            .to_string(),
        compare_seconds: record["timings_ms"]["compare"].as_f64().unwrap_or(f64::NAN) / 1e3,
    })
}

/// The bytes of every file under `dir` (their lengths).
fn folder_bytes(dir: &Path) -> Result<u64> {
    let mut total = 0;
    for entry in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let entry = entry.with_context(|| format!("reading {}", dir.display()))?;
        let meta = entry
            .metadata()
            .with_context(|| format!("{}", entry.path().display()))?;
        total += if meta.is_dir() {
            folder_bytes(&entry.path())?
        } else {
            meta.len()
        };
    }
    Ok(total)
}

/// One scan against one library: the table's row.
struct Row {
    /// The library's kinds of references.
    composition: Composition,
    /// Its preparation.
    build: Preparation,
    /// Its cache's size on disk.
    cache_bytes: u64,
    /// The held-out tooth the scan was made from.
    scan: String,
    /// Its genus.
    expected_genus: String,
    /// The scan's identification.
    identification: Identification,
}

/// The table's columns, as in the CSV.
const COLUMNS: [&str; 18] = [
    "references",
    "real",
    "perturbed",
    "synthetic",
    "prepared",
    "failed",
    "build_wall_s",
    "build_cpu_s",
    "build_peak_rss_mb",
    "cache_mb",
    "scan",
    "genus",
    "answered_genus",
    "classify_wall_s",
    "classify_cpu_s",
    "classify_peak_rss_mb",
    "compare_s",
    "rss_mb_per_reference",
];

/// A row's fields in [`COLUMNS`]' order.
fn row_fields(r: &Row) -> Vec<String> {
    let c = &r.composition;
    let id = &r.identification;
    vec![
        c.total().to_string(),
        c.real.to_string(),
        c.perturbed.to_string(),
        c.synthetic.to_string(),
        r.build.prepared.to_string(),
        r.build.failed.to_string(),
        format!("{:.2}", r.build.cost.wall),
        format!("{:.2}", r.build.cost.cpu),
        format!("{:.1}", r.build.cost.peak_rss_mb),
        format!("{:.2}", r.cache_bytes as f64 / 1e6),
        r.scan.clone(),
        r.expected_genus.clone(),
        id.genus.clone(),
        format!("{:.2}", id.cost.wall),
        format!("{:.2}", id.cost.cpu),
        format!("{:.1}", id.cost.peak_rss_mb),
        format!("{:.2}", id.compare_seconds),
        format!("{:.3}", id.cost.peak_rss_mb / c.total() as f64),
    ]
}

/// The rows as CSV (the project's dialect), with a header.
fn rows_csv(rows: &[Row]) -> String {
    let mut csv = CsvString::new();
    csv.record(COLUMNS);
    for r in rows {
        csv.record(row_fields(r));
    }
    csv.finish()
}

/// The rows as an aligned table.
fn print_rows(rows: &[Row]) {
    let mut cells: Vec<Vec<String>> = vec![COLUMNS.iter().map(|c| c.to_string()).collect()];
    cells.extend(rows.iter().map(row_fields));
    let widths: Vec<usize> = (0..COLUMNS.len())
        .map(|k| cells.iter().map(|row| row[k].len()).max().unwrap_or(0))
        .collect();
    println!();
    for row in &cells {
        let line: Vec<String> = row
            .iter()
            .zip(&widths)
            .map(|(cell, &w)| format!("{cell:>w$}"))
            .collect();
        println!("{}", line.join("  "));
    }
}

/// One line per library size: preparation, cache, and the median
/// (minimum–maximum) over its scans of the wall and CPU time and the peak
/// RSS of an identification.
fn print_summary(rows: &[Row]) {
    println!();
    println!(
        "references | library build wall / CPU | cache | classify wall per scan | CPU per scan | peak RSS | compare | genus right"
    );
    let mut sizes: Vec<usize> = rows.iter().map(|r| r.composition.total()).collect();
    sizes.dedup();
    for size in sizes {
        let of_size: Vec<&Row> = rows
            .iter()
            .filter(|r| r.composition.total() == size)
            .collect();
        let first = of_size[0];
        let spread = |f: fn(&Identification) -> f64, digits: usize| {
            let mut v: Vec<f64> = of_size.iter().map(|r| f(&r.identification)).collect();
            v.sort_by(f64::total_cmp);
            format!(
                "{:.digits$} ({:.digits$}–{:.digits$})",
                v[v.len() / 2],
                v[0],
                v[v.len() - 1]
            )
        };
        let right = of_size
            .iter()
            .filter(|r| r.identification.genus == r.expected_genus)
            .count();
        println!(
            "{size} | {:.1} s / {:.1} s | {:.1} MB ({:.3} MB a reference) | {} s | {} s | {} MB | {} s | {right}/{}",
            first.build.cost.wall,
            first.build.cost.cpu,
            first.cache_bytes as f64 / 1e6,
            first.cache_bytes as f64 / 1e6 / size as f64,
            spread(|i| i.cost.wall, 2),
            spread(|i| i.cost.cpu, 2),
            spread(|i| i.cost.peak_rss_mb, 0),
            spread(|i| i.compare_seconds, 2),
            of_size.len()
        );
    }
}
