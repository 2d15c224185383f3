//! A whole collection in correspondence: the template's vertices carried
//! to every specimen through cP maps (consistent over the collection when
//! they go along the minimum spanning tree), pseudolandmarks spread over
//! the template and read off every specimen, generalized Procrustes
//! analysis of them and the principal components of the result.
//!
//! `fps` (pseudolandmarks), `gpa`, `pca` and `maps` are numerical;
//! [`align`] puts them together over prepared surfaces and a distance
//! matrix; `files` writes what morphometricians' tools read.

mod files;
mod fps;
mod gpa;
mod maps;
mod pca;
mod sync;

pub use files::{write_outputs, OutputContext, Written};
pub use fps::pseudolandmarks;
pub(crate) use fps::MeshPoint;
pub(crate) use gpa::{generalized_procrustes, Gpa, GpaError};
pub(crate) use maps::{carry_template, carrying_steps, CarryError, TemplateImages};
pub use maps::{medoid, template_on, transfer_through_template, Consistency};
pub(crate) use pca::{principal_components, Pca};
pub(crate) use sync::synchronize_template;
pub use sync::SyncParams;

use morphoid_core::cp::{CompareParams, Handedness, Prepared};
use morphoid_core::mesh::Mesh;
use morphoid_data::landmarks::{procrustes_distance, PropagateError, Surface};
use morphoid_data::library::{Failure, Member, Preparation};
use morphoid_data::table::{pairwise_matrix, DistanceMatrix};
use rayon::prelude::*;

/// Settings of [`align`].
#[derive(Debug, Clone, PartialEq)]
pub struct AlignParams {
    /// Pseudolandmarks spread over the template.
    pub pseudolandmarks: usize,
    /// The template specimen by name; `None`: the medoid of the distances.
    pub template: Option<String>,
    /// How the template reaches the specimens.
    pub consistency: Consistency,
    /// Seed of the area-uniform sample the pseudolandmarks are chosen from.
    pub seed: u64,
}

impl Default for AlignParams {
    fn default() -> Self {
        AlignParams {
            pseudolandmarks: 1024,
            template: None,
            consistency: Consistency::SpanningTree,
            seed: 1,
        }
    }
}

/// Why a collection cannot be aligned.
#[derive(Debug, thiserror::Error)]
pub enum AlignError {
    /// Fewer than two specimens.
    #[error("{0} specimen(s): aligning needs at least two")]
    TooFew(usize),
    /// No pseudolandmark asked for.
    #[error("--pseudolandmarks must be at least 3")]
    NoPseudolandmarks,
    /// The named template is not in the collection.
    #[error("template `{0}` is not among the specimens")]
    UnknownTemplate(String),
    /// The distance matrix does not cover the specimens.
    #[error("the distance matrix has {found} rows for {expected} specimens")]
    MatrixSize {
        /// Specimens.
        expected: usize,
        /// Matrix rows.
        found: usize,
    },
    /// A specimen's surface cannot be rebuilt from its prepared form.
    #[error("surface of `{name}`: {source}")]
    Surface {
        /// The specimen.
        name: String,
        /// Why.
        #[source]
        source: PropagateError,
    },
    /// The minimum spanning tree does not reach some specimens.
    #[error("no finite distance links {} to the template", .0.join(", "))]
    Unreached(Vec<String>),
    /// Carrying the template failed.
    #[error(transparent)]
    Carry(#[from] CarryError),
    /// GPA failed.
    #[error("generalized Procrustes analysis: {0}")]
    Gpa(#[from] GpaError),
}

/// A collection in correspondence.
#[derive(Debug, Clone)]
pub struct Alignment {
    /// Specimen names, in input order.
    pub names: Vec<String>,
    /// Index of the template.
    pub template: usize,
    /// The steps `(from, to)` the template went along.
    pub steps: Vec<(usize, usize)>,
    /// The template's triangles (its vertex images on each specimen use them).
    pub template_faces: Vec<[u32; 3]>,
    /// The template's vertices on each specimen (file units).
    pub template_images: Vec<Vec<[f64; 3]>>,
    /// The carried images and per-step distances.
    pub carried: TemplateImages,
    /// The mean move of a template vertex's image (file units) in each
    /// round of the synchronization (empty without one).
    pub sync_moves: Vec<f64>,
    /// Pseudolandmarks on the template.
    pub template_points: Vec<MeshPoint>,
    /// The pseudolandmarks on each specimen (file units, on its surface).
    pub pseudolandmarks: Vec<Vec<[f64; 3]>>,
    /// GPA of the pseudolandmarks.
    pub gpa: Gpa,
    /// Principal components of the Procrustes coordinates.
    pub pca: Pca,
}

/// The surfaces of `members` that could be prepared (from the cache or
/// now), in their order, and the ones that could not, with why; in
/// parallel, `progress` called once per member.
pub fn prepare_collection(
    members: &[Member],
    preparation: &Preparation,
    progress: impl Fn(&str) + Sync,
) -> (Vec<Prepared>, Vec<Failure>) {
    let results: Vec<_> = members
        .par_iter()
        .map(|m| {
            let r = preparation.prepare(m);
            progress(m.name());
            r
        })
        .collect();
    let (mut ok, mut failed) = (Vec::new(), Vec::new());
    for (m, r) in members.iter().zip(results) {
        match r {
            Ok(p) => ok.push(p),
            Err(error) => failed.push(Failure::new(m.name().to_string(), error)),
        }
    }
    (ok, failed)
}

/// The cP distance matrix of `prepared` (in its order): pairs found in
/// `known` (by name, finite) are taken from it, the others computed in
/// parallel; also returns how many were computed. `progress` receives the
/// number of pairs done.
pub fn collection_distances(
    prepared: &[Prepared],
    known: Option<&DistanceMatrix>,
    params: &CompareParams,
    progress: impl Fn(usize) + Sync,
) -> (DistanceMatrix, usize) {
    let names: Vec<String> = prepared.iter().map(|p| p.name().to_string()).collect();
    let index: Option<std::collections::HashMap<&str, usize>> = known.map(|m| {
        m.names()
            .iter()
            .enumerate()
            .map(|(i, n)| (n.as_str(), i))
            .collect()
    });
    let lookup = |i: usize, j: usize| -> Option<f64> {
        let (m, idx) = (known?, index.as_ref()?);
        let (a, b) = (*idx.get(names[i].as_str())?, *idx.get(names[j].as_str())?);
        Some(m.get(a, b)).filter(|d| d.is_finite())
    };
    let computed = AtomicCount::default();
    let matrix = pairwise_matrix(
        names.clone(),
        |i, j| {
            Ok::<f64, std::convert::Infallible>(match lookup(i, j) {
                Some(d) => d,
                None => {
                    computed.add();
                    morphoid_core::cp::compare(&prepared[i], &prepared[j], params).distance
                }
            })
        },
        progress,
    )
    .unwrap_or_else(|never| match never {});
    (matrix, computed.get())
}

#[derive(Default)]
struct AtomicCount(std::sync::atomic::AtomicUsize);

impl AtomicCount {
    fn add(&self) {
        self.0.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }
    fn get(&self) -> usize {
        self.0.load(std::sync::atomic::Ordering::Relaxed)
    }
}

/// Put `prepared` (with `distances` over them, in the same order) in
/// correspondence: the template (named, or the medoid), the template's
/// vertices carried to every specimen (see [`Consistency`]; `progress`
/// receives the number of cP maps done), pseudolandmarks spread over the
/// template and read off each specimen through its template image and
/// projected onto its surface, GPA and PCA of them. Deterministic for any
/// number of threads.
pub fn align(
    prepared: &[Prepared],
    distances: &DistanceMatrix,
    params: &AlignParams,
    compare: &CompareParams,
    progress: impl Fn(usize) + Sync,
) -> Result<Alignment, AlignError> {
    check_align_inputs(prepared.len(), distances, params)?;
    let names: Vec<String> = prepared.iter().map(|p| p.name().to_string()).collect();
    let template = template_index(&names, distances, params)?;
    let surfaces = rebuilt_surfaces(prepared)?;
    let steps = carrying_steps(distances.values(), template, params.consistency);
    check_reached(&names, template, &steps)?;
    let carried = {
        let _span = tracing::info_span!("carry", template = %names[template]).entered();
        carry_template(prepared, &surfaces, template, &steps, compare, &progress)?
    };
    let (carried, sync_moves) = match params.consistency {
        Consistency::Synchronized(sync) => {
            let _span = tracing::info_span!("synchronize", template = %names[template]).entered();
            synchronize_template(
                prepared,
                &surfaces,
                carried,
                distances.values(),
                template,
                sync,
                compare,
                |k| progress(steps.len() + k),
            )?
        }
        Consistency::SpanningTree | Consistency::Direct => (carried, Vec::new()),
    };
    let template_images = template_images(&carried);
    let template_mesh = surfaces[template].mesh();
    let template_faces = template_mesh.faces.clone();
    let template_points = fps::pseudolandmarks(template_mesh, params.pseudolandmarks, params.seed);
    let pseudolandmarks = pseudolandmarks_on(
        &template_points,
        &template_images,
        &template_faces,
        &surfaces,
    );
    let handedness = carried.handedness();
    let gpa = generalized_procrustes(&pseudolandmarks, &handedness, template)?;
    let pca = principal_components(&gpa.aligned);
    Ok(Alignment {
        names,
        template,
        steps,
        template_faces,
        template_images,
        carried,
        sync_moves,
        template_points,
        pseudolandmarks,
        gpa,
        pca,
    })
}

/// An error unless [`align`] can work on `n` specimens with `distances`
/// and `params`: at least two specimens, three pseudolandmarks, and an
/// `n`×`n` matrix.
fn check_align_inputs(
    n: usize,
    distances: &DistanceMatrix,
    params: &AlignParams,
) -> Result<(), AlignError> {
    if n < 2 {
        return Err(AlignError::TooFew(n));
    }
    if params.pseudolandmarks < 3 {
        return Err(AlignError::NoPseudolandmarks);
    }
    if distances.values().len() != n || distances.values().iter().any(|r| r.len() != n) {
        return Err(AlignError::MatrixSize {
            expected: n,
            found: distances.values().len(),
        });
    }
    Ok(())
}

/// The index in `names` of the template: the one `params` names, or the
/// medoid of `distances` (the first specimen when it has none).
fn template_index(
    names: &[String],
    distances: &DistanceMatrix,
    params: &AlignParams,
) -> Result<usize, AlignError> {
    Ok(match &params.template {
        Some(t) => names
            .iter()
            .position(|n| n == t)
            .ok_or_else(|| AlignError::UnknownTemplate(t.clone()))?,
        None => medoid(distances.values()).unwrap_or(0),
    })
}

/// Each specimen's surface rebuilt from its prepared form (in parallel).
fn rebuilt_surfaces(prepared: &[Prepared]) -> Result<Vec<Surface>, AlignError> {
    prepared
        .par_iter()
        .map(|p| {
            Surface::from_normalized(p).map_err(|source| AlignError::Surface {
                name: p.name().to_string(),
                source,
            })
        })
        .collect()
}

/// An error naming the specimens that neither are the template nor are
/// reached by one of `steps`.
fn check_reached(
    names: &[String],
    template: usize,
    steps: &[(usize, usize)],
) -> Result<(), AlignError> {
    let n = names.len();
    let mut reached = vec![false; n];
    reached[template] = true;
    for &(_, b) in steps {
        reached[b] = true;
    }
    let unreached: Vec<String> = (0..n)
        .filter(|&i| !reached[i])
        .map(|i| names[i].clone())
        .collect();
    if !unreached.is_empty() {
        return Err(AlignError::Unreached(unreached));
    }
    Ok(())
}

/// The template's vertex images on each specimen, from `carried`.
fn template_images(carried: &TemplateImages) -> Vec<Vec<[f64; 3]>> {
    // Every specimen is reached (checked before carrying), so every image
    // is there.
    carried
        .images
        .iter()
        .map(|im| im.clone().unwrap_or_default())
        .collect()
}

/// The pseudolandmarks on each specimen: each of `template_points` placed
/// through the specimen's template vertex images (over `template_faces`)
/// and projected onto its surface; NaN where a point cannot be placed.
fn pseudolandmarks_on(
    template_points: &[MeshPoint],
    template_images: &[Vec<[f64; 3]>],
    template_faces: &[[u32; 3]],
    surfaces: &[Surface],
) -> Vec<Vec<[f64; 3]>> {
    template_images
        .par_iter()
        .zip(surfaces)
        .map(|(images, surface)| {
            template_points
                .iter()
                .map(|p| {
                    p.position(images, template_faces)
                        .map_or([f64::NAN; 3], |q| surface.closest(q))
                })
                .collect()
        })
        .collect()
}

impl Alignment {
    /// The mean centroid size of the pseudolandmark configurations: the
    /// collection frame is the Procrustes frame scaled by it, so that
    /// aligned meshes keep about their file units.
    pub fn mean_centroid_size(&self) -> f64 {
        let s = &self.gpa.superimpositions;
        s.iter().map(|x| x.size).sum::<f64>() / s.len().max(1) as f64
    }

    /// `mesh` (specimen `i`'s surface, file units) moved into the
    /// collection frame: its GPA superimposition, scaled by
    /// [`Alignment::mean_centroid_size`]; faces reversed when the
    /// superimposition reflects.
    pub fn aligned_mesh(&self, i: usize, mesh: &Mesh) -> Mesh {
        let Some(sup) = self.gpa.superimpositions.get(i) else {
            return mesh.clone();
        };
        let scale = self.mean_centroid_size();
        let vertices = mesh
            .vertices
            .iter()
            .map(|&v| sup.apply(v).map(|x| x * scale))
            .collect();
        let faces = if sup.reflects() {
            morphoid_core::mesh::reversed_winding(&mesh.faces)
        } else {
            mesh.faces.clone()
        };
        Mesh::new(vertices, faces)
    }

    /// The mean shape as a mesh: the template's triangles with each vertex
    /// at the mean of its superimposed images over the collection (in the
    /// collection frame).
    pub fn mean_mesh(&self) -> Mesh {
        let n = self.template_images.len().max(1) as f64;
        let scale = self.mean_centroid_size();
        let k = self.template_images.first().map_or(0, Vec::len);
        let mut mean = vec![[0.0; 3]; k];
        for (images, sup) in self.template_images.iter().zip(&self.gpa.superimpositions) {
            for (m, &v) in mean.iter_mut().zip(images) {
                let q = sup.apply(v);
                for d in 0..3 {
                    m[d] += scale * q[d] / n;
                }
            }
        }
        // The template's own orientation: reflected specimens are already
        // mirrored back by their superimposition.
        Mesh::new(mean, self.template_faces.clone())
    }

    /// The Procrustes distances between the specimens' pseudolandmark
    /// configurations (each against each, mirror images allowed where the
    /// handedness of the two differs), for leave-one-out classification.
    pub fn procrustes_distances(&self) -> DistanceMatrix {
        let hands = self.carried.handedness();
        pairwise_matrix(
            self.names.clone(),
            |i, j| {
                let mirror = hands[i] != hands[j];
                Ok::<f64, std::convert::Infallible>(
                    procrustes_distance(&self.pseudolandmarks[i], &self.pseudolandmarks[j], mirror)
                        .unwrap_or(f64::NAN),
                )
            },
            |_| {},
        )
        .unwrap_or_else(|never| match never {})
    }

    /// The handedness each configuration was fitted with.
    pub fn handedness(&self) -> Vec<Handedness> {
        self.carried.handedness()
    }
}
