//! Crown extraction: a closed whole tooth (crown, cervical neck, roots), as
//! an isosurface export of a segmented µCT tooth is, becomes the disk-type
//! crown a reference library holds, cut at the cervical margin the way a
//! morphologist crops it.
//!
//! Anatomy used, from the geometry alone (no pose, no scale):
//! - a whole tooth is elongated along its crown–root axis: the candidate
//!   axes are the surface's area-weighted principal axes, both ways; of
//!   the two ends, the crown is the more folded one (cusps, crests and
//!   fissures against a smooth neck and roots);
//! - the enamel ends at the cervical margin with an edge: the crown's
//!   enamel bulges over the neck and the surface turns inward below it, a
//!   ridge of convex edges running once around the tooth (not in a plane:
//!   its height varies around the tooth);
//! - so the margin is the closed line around the axis that collects the
//!   most convex turn of edges running around the axis
//!   ([`margin::trace_margin`], dynamic programming over angle sectors in
//!   a band of heights), and the crown is grown from the top of the tooth
//!   up to the crease edges along that line ([`cut::crown_faces`]): the
//!   cut follows the mesh's own enamel edge around the tooth;
//! - a surface is accepted as a tooth only when the cut is a real crease
//!   (mean turn at least [`MIN_CREASE_DEGREES`]), leaves a crown that is
//!   runs along crease edges for most of its length
//!   ([`MIN_CREASE_COVERAGE`]), leaves a crown that is not flat and a root
//!   part that tapers, and the crown is a disk: a sphere, an ellipsoid or
//!   a box is refused.
//!
//! Handles or tunnels below the margin go with the roots and are
//! reported; handles in the crown are an error.

// Negated comparisons are meant: a NaN must fail every check.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod cut;
mod geometry;
mod margin;

use crate::mesh::{bbox_diagonal, boundary_loops, euler_characteristic, norm, sub, Mesh};
use geometry::{area_weighted_axes, signed_volume6, Cylinder, SurfaceGeometry};
use margin::{Band, CreaseSample};

/// Whether a closed surface is cut to its crown.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CrownMode {
    /// Closed whole teeth are cut at the cervical margin.
    Auto,
    /// Closed surfaces are refused (the default while the extraction is
    /// below its accuracy target on whole teeth built from real crowns:
    /// a refused scan is better than a confident wrong answer).
    #[default]
    Off,
}

/// The smallest mean turn (degrees) of the surface along the cut for it to
/// count as the cervical margin.
pub const MIN_CREASE_DEGREES: f64 = 15.0;

/// The smallest share of the cut's length that must run along crease
/// edges (turn ≥ 10°): the enamel edge runs all around the tooth.
pub const MIN_CREASE_COVERAGE: f64 = 0.5;

/// Number of angle sectors of the margin search.
const SECTORS: usize = 96;

/// What the crown extraction did.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CrownReport {
    /// How the cut was found.
    pub method: String,
    /// Unit occlusal direction found (roots towards crown), in the input's
    /// coordinates.
    pub occlusal: [f64; 3],
    /// Holes of the nearly closed input filled before the cut.
    pub filled_holes: usize,
    /// Handles (genus) of the closed surface, all below the cut: removed
    /// with the roots.
    pub removed_handles: i64,
    /// Faces removed with the neck and roots.
    pub removed_faces: usize,
    /// Area removed with the neck and roots.
    pub removed_area: f64,
    /// Area of the crown kept.
    pub kept_area: f64,
    /// Mean turn of the surface across the cut (degrees).
    pub crease_degrees: f64,
    /// How much more folded the crown is than the part removed (mean
    /// |turn| per area, crown over rest).
    pub folding_ratio: f64,
    /// Share of the cut's length that runs along crease edges (turn ≥ 10°).
    pub crease_coverage: f64,
    /// Lowest point of the cut along the occlusal axis, as a fraction of
    /// the tooth's length from the apex (0) to the top of the crown (1).
    pub cut_height_min: f64,
    /// Mean height of the cut, same scale.
    pub cut_height_mean: f64,
    /// Highest point of the cut, same scale.
    pub cut_height_max: f64,
    /// Height range of the cut as a fraction of the crown's height above
    /// its lowest point (hand crops of real teeth: about 0.27).
    pub cut_variation: f64,
}

/// Why no crown could be cut from a closed surface.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CrownError {
    /// Nothing on the surface looks like a tooth crown above a neck.
    #[error("no recognisable tooth crown on this closed surface ({0}); crown extraction needs a whole tooth (crown, cervical neck, roots): crop the crown at the cervical margin by hand, or check that the file is a tooth")]
    NoCrown(String),
    /// The crown part has handles or several boundaries.
    #[error("the crown cut from this closed surface is not a disk ({loops} boundary loop(s), Euler characteristic {euler}: handles or tunnels through the crown); repair the surface or crop the crown by hand")]
    NotDisk {
        /// Boundary loops of the crown part.
        loops: usize,
        /// Its Euler characteristic.
        euler: i64,
    },
}

/// A crown cut from a closed surface.
#[derive(Debug, Clone)]
pub struct ExtractedCrown {
    /// The crown: one disk-type component, normals outward.
    pub mesh: Mesh,
    /// What was cut.
    pub report: CrownReport,
}

/// One axis tried and the crown it gives.
struct Candidate {
    inside: Vec<bool>,
    score: f64,
    report: CrownReport,
}

/// Median edge length.
fn median_edge(mesh: &Mesh, geo: &SurfaceGeometry) -> f64 {
    let mut lens: Vec<f64> = geo
        .edges
        .edges()
        .iter()
        .map(|&(a, b)| norm(sub(mesh.vertices[a as usize], mesh.vertices[b as usize])))
        .collect();
    if lens.is_empty() {
        return 0.0;
    }
    let mid = lens.len() / 2;
    *lens.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Mean absolute turn per area (summed over edges: |turn| × length, over
/// the faces' area) of the faces with `inside[f] == side`: how folded that
/// part of the surface is. A crown (cusps, crests, fissures) is more folded
/// than the smooth neck and roots.
fn folding(mesh: &Mesh, geo: &SurfaceGeometry, inside: &[bool], side: bool) -> f64 {
    let mut turn = 0.0;
    for e in 0..geo.edges.len() {
        if let &[f, g] = geo.edges.faces_of(e) {
            if inside[f as usize] == side && inside[g as usize] == side {
                let (a, b) = geo.edges.edge(e);
                let len = norm(sub(mesh.vertices[a as usize], mesh.vertices[b as usize]));
                turn += geo.turn[e].abs() * len;
            }
        }
    }
    let area: f64 = geo
        .areas
        .iter()
        .zip(inside)
        .filter(|(_, &k)| k == side)
        .map(|(a, _)| a)
        .sum();
    turn / area.max(f64::MIN_POSITIVE)
}

/// Mean distance of `points` from their centroid, across the axis.
fn cross_radius(cyl: &Cylinder, points: &[[f64; 3]]) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let n = points.len() as f64;
    let c = [0, 1, 2].map(|d| points.iter().map(|p| p[d]).sum::<f64>() / n);
    let a = cyl.axis();
    points
        .iter()
        .map(|p| {
            let d = sub(*p, c);
            let along = crate::mesh::dot(d, a);
            norm([
                d[0] - along * a[0],
                d[1] - along * a[1],
                d[2] - along * a[2],
            ])
        })
        .sum::<f64>()
        / n
}

/// The crown along one candidate axis, or why there is none.
fn cut_along(
    mesh: &Mesh,
    geo: &SurfaceGeometry,
    centre: [f64; 3],
    axis: [f64; 3],
) -> Result<Candidate, (f64, String)> {
    cut_along_line(mesh, geo, centre, axis)
}

/// [`cut_along`]'s work; a refusal carries the margin line's score (0
/// before there is one), so the most promising candidate's reason is the
/// one reported.
fn cut_along_line(
    mesh: &Mesh,
    geo: &SurfaceGeometry,
    centre: [f64; 3],
    axis: [f64; 3],
) -> Result<Candidate, (f64, String)> {
    let early = |r: &str| (0.0, r.to_string());
    let cyl = Cylinder::new(centre, axis);
    let heights: Vec<f64> = mesh.vertices.iter().map(|&p| cyl.height(p)).collect();
    let zmin = heights.iter().copied().fold(f64::MAX, f64::min);
    let zmax = heights.iter().copied().fold(f64::MIN, f64::max);
    let length = zmax - zmin;
    let edge = median_edge(mesh, geo);
    if !(length > 0.0 && edge > 0.0) {
        return Err(early("the surface has no extent"));
    }
    let (low, high) = (zmin + 0.15 * length, zmax - 0.05 * length);
    let bins = ((high - low) / (0.5 * edge)).ceil().clamp(30.0, 300.0) as usize;
    let bin = (high - low) / bins as f64;
    let in_band: Vec<f64> = mesh
        .vertices
        .iter()
        .zip(&heights)
        .filter(|(_, &z)| z >= low && z <= high)
        .map(|(&p, _)| cyl.polar(p).1)
        .collect();
    let radius = in_band.iter().sum::<f64>() / in_band.len().max(1) as f64;
    // Allow a climb of 1.2 times the arc of one sector (50°).
    let max_step = ((1.2 * std::f64::consts::TAU * radius / SECTORS as f64) / bin)
        .ceil()
        .clamp(1.0, (bins / 4) as f64) as usize;
    let mut samples = Vec::new();
    let mut edge_info = Vec::new();
    for (e, &(a, b)) in geo.edges.edges().iter().enumerate() {
        let t = geo.turn[e];
        if t <= 0.0 {
            continue;
        }
        let (pa, pb) = (mesh.vertices[a as usize], mesh.vertices[b as usize]);
        let d = sub(pb, pa);
        let len = norm(d);
        let mid = [0, 1, 2].map(|k| 0.5 * (pa[k] + pb[k]));
        let around = crate::mesh::dot(d, cyl.around(mid)).abs() / len.max(f64::MIN_POSITIVE);
        let (angle, _) = cyl.polar(mid);
        let height = cyl.height(mid);
        samples.push(CreaseSample {
            angle,
            height,
            weight: t * len * around,
        });
        edge_info.push((t, angle, height, around));
    }
    let band = Band {
        low,
        high,
        sectors: SECTORS,
        bins,
        max_step,
    };
    let line =
        margin::trace_margin(&samples, &band).ok_or_else(|| early("no convex edges at all"))?;
    // The crease edges on the line set the turn that stops the growth.
    let mut on_line: Vec<f64> = edge_info
        .iter()
        .filter(|(_, angle, height, around)| {
            *around >= 0.5 && (height - line.height_at(*angle)).abs() <= 1.5 * bin
        })
        .map(|e| e.0)
        .collect();
    on_line.sort_by(f64::total_cmp);
    let p75 = on_line
        .get(on_line.len() * 3 / 4)
        .copied()
        .ok_or_else(|| early("no crease along the margin line"))?;
    // Low enough that the uppermost of two neighbouring creases (the
    // enamel edge above the foot of the step) stops the growth.
    let min_turn = (0.3 * p75).max(10f64.to_radians());
    let tolerance = (3.0 * bin).max(1.5 * edge);
    let seed = (0..mesh.faces.len())
        .max_by(|&f, &g| {
            cyl.height(geo.centroids[f])
                .total_cmp(&cyl.height(geo.centroids[g]))
        })
        .ok_or_else(|| early("no faces"))?;
    let rule = cut::CutRule {
        margin: &line,
        cylinder: &cyl,
        tolerance,
        min_turn,
    };
    let inside = cut::crown_faces(mesh, geo, &rule, seed);
    let report = judge(mesh, geo, &cyl, &inside, (zmin, zmax)).map_err(|r| (line.score, r))?;
    Ok(Candidate {
        inside,
        score: line.score,
        report,
    })
}

/// Check that the cut found a crown (see the module documentation) and
/// measure it.
fn judge(
    mesh: &Mesh,
    geo: &SurfaceGeometry,
    cyl: &Cylinder,
    inside: &[bool],
    (zmin, zmax): (f64, f64),
) -> Result<CrownReport, String> {
    let total: f64 = geo.areas.iter().sum();
    let kept: f64 = geo
        .areas
        .iter()
        .zip(inside)
        .filter(|(_, &k)| k)
        .map(|(a, _)| a)
        .sum();
    let fraction = kept / total;
    if (2.0 * fraction - 1.0).abs() < 0.05 {
        return Err(
            "the best margin line cuts the surface into two halves of equal area: a symmetric solid, not a tooth"
                .into(),
        );
    }
    if !(0.08..=0.92).contains(&fraction) {
        return Err(format!(
            "the best margin line leaves {:.0} % of the surface as crown",
            100.0 * fraction
        ));
    }
    // The cut: edges between a crown face and a removed one.
    let (mut turn_len, mut len_sum, mut crease_len) = (0.0, 0.0, 0.0);
    let mut cut_vertices = vec![false; mesh.vertices.len()];
    for e in 0..geo.edges.len() {
        if let &[f, g] = geo.edges.faces_of(e) {
            if inside[f as usize] != inside[g as usize] {
                let (a, b) = geo.edges.edge(e);
                let len = norm(sub(mesh.vertices[a as usize], mesh.vertices[b as usize]));
                turn_len += geo.turn[e] * len;
                len_sum += len;
                if geo.turn[e] >= 10f64.to_radians() {
                    crease_len += len;
                }
                cut_vertices[a as usize] = true;
                cut_vertices[b as usize] = true;
            }
        }
    }
    let crease = (turn_len / len_sum.max(f64::MIN_POSITIVE)).to_degrees();
    if !(crease >= MIN_CREASE_DEGREES) {
        return Err(format!(
            "no cervical crease: the surface turns by {crease:.1}° on average along the best margin line, at least {MIN_CREASE_DEGREES}° is needed"
        ));
    }
    let coverage = crease_len / len_sum.max(f64::MIN_POSITIVE);
    if !(coverage >= MIN_CREASE_COVERAGE) {
        return Err(format!(
            "the best margin line runs along a crease for {:.0} % of its length only, not around the tooth",
            100.0 * coverage
        ));
    }
    let cut_points: Vec<[f64; 3]> = (0..mesh.vertices.len())
        .filter(|&v| cut_vertices[v])
        .map(|v| mesh.vertices[v])
        .collect();
    let cut_heights: Vec<f64> = cut_points.iter().map(|&p| cyl.height(p)).collect();
    let cut_low = cut_heights.iter().copied().fold(f64::MAX, f64::min);
    let cut_high = cut_heights.iter().copied().fold(f64::MIN, f64::max);
    let cut_mean = cut_heights.iter().sum::<f64>() / cut_heights.len().max(1) as f64;
    let cut_radius = cross_radius(cyl, &cut_points);
    let mut crown_top = f64::MIN;
    let mut root_points = Vec::new();
    let mut root_low = f64::MAX;
    for (f, face) in mesh.faces.iter().enumerate() {
        for &v in face {
            let z = cyl.height(mesh.vertices[v as usize]);
            if inside[f] {
                crown_top = crown_top.max(z);
            } else {
                root_low = root_low.min(z);
            }
        }
    }
    if crown_top - cut_mean < 0.2 * cut_radius {
        return Err("the part above the best margin line is flat, not a crown".into());
    }
    let slab = root_low + 0.15 * (cut_mean - root_low);
    for (f, face) in mesh.faces.iter().enumerate() {
        if !inside[f] {
            for &v in face {
                let p = mesh.vertices[v as usize];
                if cyl.height(p) <= slab {
                    root_points.push(p);
                }
            }
        }
    }
    let apex_radius = cross_radius(cyl, &root_points);
    if !(apex_radius < 0.75 * cut_radius) {
        return Err("the part below the best margin line does not taper to a root apex".into());
    }
    let folding_ratio =
        folding(mesh, geo, inside, true) / folding(mesh, geo, inside, false).max(f64::MIN_POSITIVE);
    let scale = |z: f64| (z - zmin) / (zmax - zmin);
    Ok(CrownReport {
        method: "cervical crease".into(),
        occlusal: cyl.axis(),
        filled_holes: 0,
        removed_handles: 0,
        removed_faces: inside.iter().filter(|&&k| !k).count(),
        removed_area: total - kept,
        kept_area: kept,
        crease_degrees: crease,
        folding_ratio,
        crease_coverage: coverage,
        cut_height_min: scale(cut_low),
        cut_height_mean: scale(cut_mean),
        cut_height_max: scale(cut_high),
        cut_variation: (cut_high - cut_low) / (crown_top - cut_low).max(f64::MIN_POSITIVE),
    })
}

/// Cut the crown from a closed, consistently oriented, manifold surface
/// (see the module documentation). The crown's faces keep their vertices'
/// positions; normals point outward.
pub fn extract_crown(mesh: &Mesh) -> Result<ExtractedCrown, CrownError> {
    let _span = tracing::debug_span!("crown").entered();
    let oriented = if signed_volume6(mesh) < 0.0 {
        Mesh::new(
            mesh.vertices.clone(),
            mesh.faces.iter().map(|f| [f[0], f[2], f[1]]).collect(),
        )
    } else {
        mesh.clone()
    };
    let geo = SurfaceGeometry::new(&oriented);
    let (centre, axes) = area_weighted_axes(&geo)
        .filter(|_| bbox_diagonal(mesh) > 0.0)
        .ok_or_else(|| CrownError::NoCrown("the surface has no area".into()))?;
    let mut best: Option<Candidate> = None;
    let mut reasons = Vec::new();
    for axis in axes {
        // Both ends are tried: the same margin line is found either way,
        // and the crown is the side that is more folded than the rest.
        let mut pair = Vec::new();
        for sign in [1.0, -1.0] {
            match cut_along(&oriented, &geo, centre, axis.map(|x| sign * x)) {
                Ok(c) => pair.push(c),
                Err(reason) => reasons.push(reason),
            }
        }
        let chosen = pair
            .into_iter()
            .max_by(|a, b| a.report.folding_ratio.total_cmp(&b.report.folding_ratio));
        if let Some(c) = chosen {
            if best.as_ref().is_none_or(|b| c.score > b.score) {
                best = Some(c);
            }
        }
    }
    let Some(best) = best else {
        let reason = reasons
            .into_iter()
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .map(|r| r.1)
            .unwrap_or_default();
        return Err(CrownError::NoCrown(reason));
    };
    let faces: Vec<[u32; 3]> = oriented
        .faces
        .iter()
        .zip(&best.inside)
        .filter_map(|(f, &k)| k.then_some(*f))
        .collect();
    let crown =
        super::faces::remove_unreferenced_vertices(&Mesh::new(oriented.vertices.clone(), faces));
    let loops = boundary_loops(&crown).len();
    let euler = euler_characteristic(&crown);
    if loops != 1 || euler != 1 {
        return Err(CrownError::NotDisk { loops, euler });
    }
    let mut report = best.report;
    report.removed_handles = (2 - euler_characteristic(mesh)) / 2;
    tracing::debug!(
        kept_area = report.kept_area,
        removed_area = report.removed_area,
        crease = report.crease_degrees,
        "crown cut"
    );
    Ok(ExtractedCrown {
        mesh: crown,
        report,
    })
}
