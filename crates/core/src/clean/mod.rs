//! Cleaning: from a raw scan to a clean disk-type triangle mesh.
//!
//! [`clean`] runs the steps below in order; each is a pure function over
//! [`Mesh`] in its own submodule and can be used alone:
//!
//! 1. point clouds are reconstructed into a surface
//!    ([`cloud::reconstruct_surface`]: outliers removed, oriented normals,
//!    an implicit surface trimmed to the points);
//! 2. duplicate vertices are welded ([`weld::weld_vertices`]);
//! 3. degenerate and duplicate faces go ([`faces`]). A surface far above
//!    the working resolution (a µCT export of millions of faces) is first
//!    decimated once to eight times it
//!    ([`resample::decimate_to_face_count`]; before welding when it shares
//!    its vertices, else after), so that what follows costs the same
//!    whatever the export's resolution;
//! 4. the largest connected component by area is kept ([`components`]);
//! 5. non-manifold edges and vertices are repaired ([`manifold`]);
//! 6. face orientation is made consistent ([`orient`]);
//! 7. a closed surface (or a nearly closed one: every hole small, see
//!    [`NEARLY_CLOSED`]) is taken for a whole tooth and cut to its crown at
//!    the cervical margin ([`crown`], unless `crown = "off"`); the crowns
//!    of other margins found go on beside it ([`Cleaned::alternatives`]);
//! 8. all boundary loops but the longest (by geometric length) are filled
//!    ([`holes`]); the surface must then be a disk (one loop, Euler
//!    characteristic 1);
//! 9. the orientation is chosen so that normals point outward
//!    ([`orient::normals_point_outward`]: the vector area points from the
//!    boundary loop towards the body of the surface, e.g. out of a tooth
//!    crown);
//! 10. the mesh is resampled to the working resolution with well-shaped
//!     triangles ([`resample`]).

// Coordinate loops `for d in 0..3` read more clearly than zipped iterators.
#![allow(clippy::needless_range_loop)]

mod closest;
mod cloud;
mod components;
mod crown;
mod faces;
mod holes;
mod manifold;
mod orient;
mod resample;
mod specimens;
mod voxelize;
mod weld;

pub use closest::{point_to_surface_distances, TriangleGrid};
pub use cloud::CloudReport;
pub(crate) use components::largest_component_by_area;

use crate::mesh::{
    bbox_diagonal, boundary_loops, euler_characteristic, genus, longest_boundary_loop,
    surface_area, widest_boundary_loop_extent, Mesh,
};
pub use crown::{CrownError, CrownMode, CrownReport};
use rayon::prelude::*;
pub use specimens::surface_specimens;

/// A surface whose every boundary loop spans less than this share of its
/// bounding-box diagonal ([`widest_boundary_loop_extent`]) is a closed surface
/// with holes, not a cropped crown: a crop's rim runs all around the
/// crown (0.72–0.94 of the diagonal on the 116 real crowns). The extent,
/// not the length: a root cut off by the scan's field of view leaves a
/// rim as long as the crown is round, though it spans a small part of
/// the tooth.
pub const NEARLY_CLOSED: f64 = 0.4;

/// Surfaces of more than five times `2 × EARLY_DECIMATION_FACTOR ×
/// target_vertices` faces are first decimated to `2 ×
/// EARLY_DECIMATION_FACTOR × target_vertices` faces: eight times the
/// working resolution keeps the shape well beyond what the working mesh
/// can show.
const EARLY_DECIMATION_FACTOR: usize = 8;

/// Parameters of the cleaning pipeline.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CleanOptions {
    /// Working resolution: the cleaned mesh has about this many vertices
    /// (within ±10 %).
    pub target_vertices: usize,
    /// Weld tolerance as a fraction of the bounding-box diagonal.
    pub weld_tolerance: f64,
    /// Fewer (distinct) points or faces than this is an error.
    pub min_elements: usize,
    /// Rounds of edge flips + tangential relaxation after resampling.
    pub relax_iterations: usize,
    /// Closed surfaces (whole teeth): `auto` cuts the crown at the
    /// cervical margin, `off` refuses them.
    pub crown: CrownMode,
}

impl Default for CleanOptions {
    fn default() -> Self {
        Self {
            target_vertices: 5000,
            weld_tolerance: 1e-6,
            min_elements: 20,
            relax_iterations: 3,
            crown: CrownMode::default(),
        }
    }
}

/// What cleaning changed.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CleanReport {
    /// Vertices of the input.
    pub input_vertices: usize,
    /// Faces of the input.
    pub input_faces: usize,
    /// Vertices of the output.
    pub output_vertices: usize,
    /// Faces of the output.
    pub output_faces: usize,
    /// Boundary loops of the output (1 for a disk).
    pub boundary_loops: usize,
    /// Euler characteristic of the output (1 for a disk).
    pub euler_characteristic: i64,
    /// Vertices merged into others by welding.
    pub welded_vertices: usize,
    /// Degenerate or duplicate faces removed.
    pub removed_faces: usize,
    /// Connected components dropped (debris).
    pub dropped_components: usize,
    /// Holes filled.
    pub filled_holes: usize,
    /// Non-manifold edges repaired (extra faces dropped).
    pub repaired_nonmanifold_edges: usize,
    /// Non-manifold vertices split.
    pub repaired_nonmanifold_vertices: usize,
    /// Faces reversed to make the orientation consistent.
    pub flipped_faces: usize,
    /// Whether the whole surface was reversed so its normals point outward.
    pub reversed_orientation: bool,
    /// Faces of a surface far above the working resolution before its
    /// first decimation (0 when there was none).
    pub predecimated_faces: usize,
    /// The input was a point cloud and was triangulated.
    pub triangulated_point_cloud: bool,
    /// Edge flips made while improving triangle shapes.
    pub edge_flips: usize,
    /// Surface area of the output.
    pub area: f64,
    /// Bounding-box diagonal of the output.
    pub bbox_diagonal: f64,
    /// What the point-cloud reconstruction did (point clouds only).
    pub cloud: Option<cloud::CloudReport>,
    /// The crown cut from a closed whole tooth, if the input was one.
    pub crown: Option<CrownReport>,
}

/// A cleaned mesh and the report of what was done.
#[derive(Debug, Clone)]
pub struct Cleaned {
    /// The clean, disk-type mesh.
    pub mesh: Mesh,
    /// What was changed.
    pub report: CleanReport,
    /// For a crown cut from a whole tooth: the crowns of other margins the
    /// search found, cleaned alike (disk-type, at the working resolution),
    /// best merit first. Which crown is the tooth's is for a library to
    /// tell; the geometry's choice is `mesh`.
    pub alternatives: Vec<Mesh>,
}

/// A disk-type surface and, for a crown cut from a whole tooth, the disks
/// of the other cuts found ([`Cleaned::alternatives`]).
type Disks = (Mesh, Vec<Mesh>);

/// Why a surface cannot be made disk-type.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CleanError {
    /// The surface is closed (no boundary).
    #[error("the surface is closed (no boundary loop) and crown extraction is off; crop the crown to a disk-type surface, or set [clean] crown = \"auto\" to cut a whole tooth at its cervical margin")]
    Closed,
    /// A closed surface whose crown could not be cut.
    #[error(transparent)]
    Crown(#[from] CrownError),
    /// The surface has handles (genus > 0).
    #[error("the surface has {0} handle(s) (Euler characteristic {1} with one boundary loop); a disk-type surface is needed")]
    Handles(i64, i64),
    /// The surface is not orientable.
    #[error("the surface is not orientable (Möbius-type); a disk-type surface is needed")]
    NonOrientable,
    /// Too few points to form a surface.
    #[error("too few points ({0}) to form a surface")]
    TooFewPoints(usize),
    /// Too few faces to form a surface.
    #[error("too few faces ({0}) to form a surface")]
    TooFewFaces(usize),
    /// A point cloud with no surface to reconstruct.
    #[error("the point cloud cannot be made into a surface: {0}")]
    Cloud(#[from] cloud::CloudError),
    /// A coordinate is NaN or infinite.
    #[error("vertex {0} has a non-finite coordinate")]
    NonFinite(usize),
    /// A face refers to a vertex that does not exist.
    #[error("face {face} refers to vertex {vertex}, but the mesh has {count} vertices")]
    BadIndex {
        /// The face.
        face: usize,
        /// The missing vertex index.
        vertex: u32,
        /// Number of vertices.
        count: usize,
    },
    /// The topology is neither a disk nor a surface with handles (should
    /// not happen after the repairs).
    #[error("the surface is not disk-type (Euler characteristic {0} with one boundary loop)")]
    NotDisk(i64),
    /// Resampling did not keep the disk topology (should not happen).
    #[error("resampling changed the topology ({0} boundary loops, Euler characteristic {1})")]
    Resampling(usize, i64),
}

/// Check indices and coordinates.
fn validate(mesh: &Mesh) -> Result<(), CleanError> {
    if let Some(i) = mesh
        .vertices
        .iter()
        .position(|p| p.iter().any(|x| !x.is_finite()))
    {
        return Err(CleanError::NonFinite(i));
    }
    let count = mesh.vertices.len();
    for (face, f) in mesh.faces.iter().enumerate() {
        if let Some(&vertex) = f.iter().find(|&&v| v as usize >= count) {
            return Err(CleanError::BadIndex {
                face,
                vertex,
                count,
            });
        }
    }
    Ok(())
}

/// Steps 4–8: largest component, manifold repair, consistent orientation,
/// hole filling, disk test and outward orientation, with counts added to
/// `report`.
fn make_disk(m: &Mesh, report: &mut CleanReport, crown: CrownMode) -> Result<Disks, CleanError> {
    make_disk_of(m, report, crown, false)
}

/// [`make_disk`], told whether `m` was re-voxelized already.
fn make_disk_of(
    m: &Mesh,
    report: &mut CleanReport,
    crown: CrownMode,
    revoxelized: bool,
) -> Result<Disks, CleanError> {
    let min = 3;
    let (m3, d1) = components::largest_component_by_area(m);
    let (m4, ne) = manifold::repair_nonmanifold_edges(&m3);
    let (m5, nv) = manifold::split_nonmanifold_vertices(&m4);
    let (m6, d2) = components::largest_component_by_area(&m5);
    report.dropped_components += d1 + d2;
    report.repaired_nonmanifold_edges += ne;
    report.repaired_nonmanifold_vertices += nv;
    let m7 = faces::remove_unreferenced_vertices(&m6);
    if m7.faces.len() < min {
        return Err(CleanError::TooFewFaces(m7.faces.len()));
    }
    let (m8, flipped) = match orient::orient_faces_consistently(&m7) {
        Ok(oriented) => oriented,
        // Only a surface this cleaning decimated is cut open where it is
        // twisted: the decimation folded it, the scan was orientable.
        Err(_) if report.predecimated_faces > 0 => {
            let (opened, _) = orient::drop_orientation_conflicts(&m7);
            let (kept, _) = components::largest_component_by_area(&opened);
            orient::orient_faces_consistently(&faces::remove_unreferenced_vertices(&kept))
                .map_err(|_| CleanError::NonOrientable)?
        }
        Err(_) => return Err(CleanError::NonOrientable),
    };
    report.flipped_faces += flipped;
    if let Some(coarser) = decimated_for_crown_search(&m8, crown) {
        // The repairs run again on the coarser surface, which the margin
        // search then takes.
        report.predecimated_faces = report.predecimated_faces.max(m8.faces.len());
        return make_disk_of(&coarser, report, crown, revoxelized);
    }
    let (m8, alternatives) = if !is_whole(&m8, crown) {
        (m8, Vec::new())
    } else if crown == CrownMode::Off {
        return Err(CleanError::Closed);
    } else {
        let (closed, filled) = holes::fill_all_holes(&m8);
        // A tooth is a ball: handles are the tunnels a thresholded export
        // leaves where voxels touch along an edge. A margin loop through
        // one does not cut the surface in two, and a crown that keeps one
        // is no disk (so it went on every such export measured, after a
        // whole margin search). The same solid without them is searched
        // first; the surface as it is only when that fails, or when the
        // solid's margin may leave a root with the crown.
        if !revoxelized && euler_characteristic(&closed) < 2 {
            let before = report.clone();
            if let Some(disk) = revoxelized_disk(&closed, report, crown) {
                if !report.crown.as_ref().is_some_and(crown::roots_short) {
                    return Ok(disk);
                }
                // The solid's best margin leaves a root with the crown:
                // the surface as it is (its handles go with the roots)
                // may be cut where the roots hang below. It is taken only
                // when that is clearly so.
                let mut as_is = before;
                let better = cut_whole_tooth(&closed, filled, &mut as_is)
                    .ok()
                    .filter(|_| match (&as_is.crown, &report.crown) {
                        (Some(a), Some(r)) => crown::roots_clearly_longer(a, r),
                        _ => false,
                    })
                    .and_then(|(m8, alternatives)| {
                        outward_disks(&m8, &alternatives, &mut as_is).ok()
                    });
                if let Some(disks) = better {
                    tracing::debug!("the surface as it is leaves the roots below its margin");
                    *report = as_is;
                    return Ok(disks);
                }
                return Ok(disk);
            }
        }
        cut_whole_tooth(&closed, filled, report)?
    };
    outward_disks(&m8, &alternatives, report)
}

/// [`outward_disk`] of `m8`, and of each of the other crowns
/// `alternatives` that can be made one.
fn outward_disks(
    m8: &Mesh,
    alternatives: &[Mesh],
    report: &mut CleanReport,
) -> Result<Disks, CleanError> {
    // The other crowns are made disks beside the chosen one: on a whole
    // tooth this step is single-threaded, and a second core is free.
    let (disk, alternatives) = rayon::join(
        || outward_disk(m8, report),
        || {
            alternatives
                .par_iter()
                .filter_map(|a| outward_disk(a, &mut CleanReport::default()).ok())
                .collect()
        },
    );
    Ok((disk?, alternatives))
}

/// Steps 8–9: `m8`'s holes but its outer boundary filled, checked to be a
/// disk and turned so that its normals point outward.
fn outward_disk(m8: &Mesh, report: &mut CleanReport) -> Result<Mesh, CleanError> {
    let (m9, filled) = holes::fill_holes_except_longest(m8);
    report.filled_holes += filled;
    let chi = euler_characteristic(&m9);
    if chi != 1 {
        let handles = genus(chi, 1);
        return Err(if handles > 0 {
            CleanError::Handles(handles, chi)
        } else {
            CleanError::NotDisk(chi)
        });
    }
    let outer = longest_boundary_loop(&m9).unwrap_or_default();
    if orient::normals_point_outward(&m9, &outer) {
        Ok(m9)
    } else {
        report.reversed_orientation = !report.reversed_orientation;
        Ok(orient::reverse_faces(&m9))
    }
}

/// The disk of the whole tooth `closed` taken through a voxel grid
/// ([`voxelize::revoxelized`]), which closes its handles, with `report`
/// updated; `None` (and `report` as it was) when that fails.
fn revoxelized_disk(closed: &Mesh, report: &mut CleanReport, crown: CrownMode) -> Option<Disks> {
    let solid = voxelize::revoxelized(closed, REVOXEL_SAMPLES)?;
    tracing::debug!(
        faces = solid.faces.len(),
        "whole tooth with handles re-voxelized"
    );
    let mut attempt = report.clone();
    match make_disk_of(&solid, &mut attempt, crown, true) {
        Ok(disk) => {
            if let Some(c) = attempt.crown.as_mut() {
                c.revoxelized = true;
            }
            *report = attempt;
            Some(disk)
        }
        Err(e) => {
            tracing::debug!("re-voxelized: {e}");
            None
        }
    }
}

/// A µCT-resolution export has millions of faces, hundreds of times the
/// working resolution. The repairs are linear but not cheap, and the
/// resampling's reference surface would hold the whole: one decimation to
/// a few times the working resolution first bounds time and memory, and
/// the working mesh is decimated from it as from any other surface.
/// `None` when `m` is not far above the working resolution (or was
/// decimated already).
fn decimate_if_dense(m: &Mesh, opts: &CleanOptions, report: &mut CleanReport) -> Option<Mesh> {
    let early_faces = 2 * EARLY_DECIMATION_FACTOR * opts.target_vertices;
    if report.predecimated_faces > 0 || m.faces.len() <= 5 * early_faces {
        return None;
    }
    report.predecimated_faces = m.faces.len();
    let _span = tracing::debug_span!("decimate dense", faces = m.faces.len()).entered();
    // Pinched vertices (two sheets of an isosurface through one vertex)
    // are split and debris dropped first: collapsing edges round a pinch
    // can fold the surface into a non-orientable one.
    let kept = {
        let _s = tracing::debug_span!("repair").entered();
        let (repaired, _) = manifold::repair_nonmanifold_edges(m);
        let (split, _) = manifold::split_nonmanifold_vertices(&repaired);
        drop(repaired);
        let (kept, dropped) = components::largest_component_by_area(&split);
        drop(split);
        report.dropped_components += dropped;
        faces::remove_unreferenced_vertices(&kept)
    };
    // A whole tooth this dense is an isosurface export: its voxel
    // staircase is smoothed away before the decimation, which would keep
    // the stairs' corners as sharp features.
    let kept = if is_whole(&kept, opts.crown) {
        let _s = tracing::debug_span!("smooth staircase").entered();
        crown::staircase_smoothed(&kept)
    } else {
        kept
    };
    let _s = tracing::debug_span!("decimate").entered();
    decimated_orientable(&kept, early_faces)
}

/// Faces of a whole tooth on which its margin is searched: the crown
/// keeps about two fifths of them, several times the working resolution,
/// and the search's time does not grow with the export's resolution.
const CROWN_SEARCH_FACES: usize = 60_000;

/// A whole tooth far denser than [`CROWN_SEARCH_FACES`], decimated to it;
/// `None` for anything else.
fn decimated_for_crown_search(m: &Mesh, crown: CrownMode) -> Option<Mesh> {
    if crown != CrownMode::Auto
        || m.faces.len() <= 3 * CROWN_SEARCH_FACES / 2
        || !is_whole(m, crown)
    {
        return None;
    }
    decimated_orientable(m, CROWN_SEARCH_FACES)
}

/// `m` decimated to about `target` faces, or to twice as many when that
/// folded a thin part of it (two walls of a narrow tunnel between roots
/// collapsed into a non-orientable strip). When both did, the first is
/// taken all the same: [`make_disk`] cuts a decimated surface open where
/// it is twisted, and the surface as it is would leave the margin search
/// a million faces (measured: over 15 min on a 1.6 M-face two-rooted
/// isosurface). `None` when `m` has no more than `target` faces.
fn decimated_orientable(m: &Mesh, target: usize) -> Option<Mesh> {
    let orientable = |d: &Mesh| {
        let (e, _) = manifold::repair_nonmanifold_edges(d);
        orient::orient_faces_consistently(&e).is_ok()
    };
    let mut first = None;
    for t in [target, 2 * target]
        .into_iter()
        .filter(|&t| t < m.faces.len())
    {
        let d = resample::decimate_to_face_count(m, t);
        if orientable(&d) {
            return Some(d);
        }
        first.get_or_insert(d);
    }
    first
}

/// Samples along the longest side of the grid through which a whole
/// tooth with handles is taken ([`voxelize::revoxelized`]): the crown
/// keeps about 100 across, more than the working resolution's 70.
const REVOXEL_SAMPLES: usize = 224;

/// Whether `m` is a closed or nearly closed surface (a whole tooth, not a
/// cropped crown).
fn is_whole(m: &Mesh, crown: CrownMode) -> bool {
    match widest_boundary_loop_extent(m) {
        None => true,
        Some(extent) => crown == CrownMode::Auto && extent < NEARLY_CLOSED * bbox_diagonal(m),
    }
}

/// Step 7: a whole tooth, its holes filled (`filled` of them), cut to
/// its crown; the crown report goes into `report`.
fn cut_whole_tooth(
    closed: &Mesh,
    filled: usize,
    report: &mut CleanReport,
) -> Result<Disks, CleanError> {
    let cut = crown::extract_crown(closed)?;
    let mut crown_report = cut.report;
    crown_report.filled_holes = filled;
    report.crown = Some(crown_report);
    Ok((cut.mesh, cut.alternatives))
}

/// Run the whole cleaning pipeline (see the module documentation).
pub fn clean(mesh: &Mesh, opts: &CleanOptions) -> Result<Cleaned, CleanError> {
    validate(mesh)?;
    let mut report = CleanReport {
        input_vertices: mesh.vertices.len(),
        input_faces: mesh.faces.len(),
        ..CleanReport::default()
    };
    let min = opts.min_elements.max(3);
    let tol = opts.weld_tolerance * bbox_diagonal(mesh);
    // A surface that shares its vertices is decimated before anything
    // else when it is far too dense: welding and the face checks then run
    // on the decimated surface.
    let decimated = if mesh.vertices.len() < mesh.faces.len() {
        decimate_if_dense(mesh, opts, &mut report)
    } else {
        None
    };
    let (mut m, welded) = weld::weld_vertices(decimated.as_ref().unwrap_or(mesh), tol);
    drop(decimated);
    report.welded_vertices = welded;

    if m.faces.is_empty() {
        if m.vertices.len() < min {
            return Err(CleanError::TooFewPoints(m.vertices.len()));
        }
        let (surface, cloud_report) = cloud::reconstruct_surface(&m.vertices, min)?;
        m = surface;
        report.triangulated_point_cloud = true;
        report.cloud = Some(cloud_report);
    }

    let diag = bbox_diagonal(&m);
    let (m1, r1) = faces::remove_degenerate_faces(&m, 1e-14 * diag * diag);
    drop(m);
    let (mut m2, r2) = faces::remove_duplicate_faces(&m1);
    drop(m1);
    report.removed_faces = r1 + r2;
    if m2.faces.len() < min {
        return Err(CleanError::TooFewFaces(m2.faces.len()));
    }
    // A triangle soup can only be decimated once welded.
    if let Some(d) = decimate_if_dense(&m2, opts, &mut report) {
        m2 = d;
    }

    let (m3, alternatives) = make_disk(&m2, &mut report, opts.crown)?;
    // Resampled beside the chosen crown, as in `make_disk`.
    let (out, alternatives) = rayon::join(
        || working_resolution(&m3, opts, &mut report),
        || {
            alternatives
                .par_iter()
                .filter_map(|a| working_resolution(a, opts, &mut CleanReport::default()).ok())
                .collect()
        },
    );
    let out = out?;
    drop(m3);
    Ok(Cleaned {
        mesh: out,
        report,
        alternatives,
    })
}

/// Step 10: the disk `m3` resampled to the working resolution and its
/// triangles improved, with the output's figures in `report`.
fn working_resolution(
    m3: &Mesh,
    opts: &CleanOptions,
    report: &mut CleanReport,
) -> Result<Mesh, CleanError> {
    // Decimation may merge vertices that share a position (copies made by
    // the vertex split) and create non-manifold spots: repair again.
    let resampled = resample::resample_to_vertex_count(m3, opts.target_vertices);
    let m4 = if resampled.vertices.len() == m3.vertices.len() {
        resampled
    } else {
        make_disk(&resampled, &mut CleanReport::default(), CrownMode::Off)?.0
    };
    let reference = resample::SurfaceReference::new(m3).ok_or(CleanError::TooFewFaces(0))?;
    let (out, flips) = resample::improve_triangles(&m4, &reference, opts.relax_iterations);
    report.edge_flips = flips;
    // A relaxed sliver can end up flat (three points on a line), which the
    // flattening refuses: its shortest edge is collapsed.
    let d = bbox_diagonal(&out);
    let (out, slivers) = faces::remove_degenerate_faces(&out, 1e-12 * d * d);
    let out = if slivers > 0 {
        faces::remove_unreferenced_vertices(&out)
    } else {
        out
    };
    let loops = boundary_loops(&out).len();
    let chi = euler_characteristic(&out);
    if loops != 1 || chi != 1 {
        return Err(CleanError::Resampling(loops, chi));
    }
    report.output_vertices = out.vertices.len();
    report.output_faces = out.faces.len();
    report.boundary_loops = loops;
    report.euler_characteristic = chi;
    report.area = surface_area(&out);
    report.bbox_diagonal = bbox_diagonal(&out);
    Ok(out)
}
