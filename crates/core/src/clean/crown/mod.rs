//! Crown extraction: a closed whole tooth (crown, cervical neck, roots), as
//! an isosurface export of a segmented µCT tooth is, becomes the disk-type
//! crown a reference library holds, cut at the cervical margin the way a
//! morphologist crops it.
//!
//! Anatomy used, from the geometry alone (no pose, no scale):
//! - the enamel ends at the cervical margin with an edge: the crown's
//!   enamel bulges over the neck and the surface turns inward below it, a
//!   convex crease running once around the tooth (not in a plane: its
//!   height varies around the tooth);
//! - so the margin is the cheapest closed edge path winding once around
//!   the tooth's axis, where an edge costs its length times a weight that
//!   is small on convex creases, plus its climb along the axis
//!   ([`cycle::cheapest_winding_cycle`]); it is searched about each of the
//!   surface's area-weighted principal axes, then again about the normal of
//!   the loop found (the principal axes are only near the tooth's axis);
//! - the loop cuts the surface in two ([`cut::faces_bounded_by`]); the
//!   crown is the side that lies farther from the axis next to the cut
//!   (the crown bulges over the neck, [`near_cut_radius`]);
//! - of the axes, the loop most on crease and least climbing wins
//!   ([`Candidate::merit`]); it is accepted as a tooth's margin only when
//!   the cut is a real crease (mean turn at least [`MIN_CREASE_DEGREES`],
//!   along crease edges for most of its length, [`MIN_CREASE_COVERAGE`]),
//!   leaves a crown that is not flat and a root part that tapers, and the
//!   crown is a disk: a sphere, an ellipsoid or a box is refused.
//! - The roots hang below the margin: of the margins found, one whose
//!   part cut off reaches far less from the cut than another's
//!   ([`root_reach`]) ranks after it, and when the best leaves a root with
//!   the crown, the search is made again nearer the axis and its margin
//!   taken where its roots clearly reach farther
//!   ([`roots_clearly_longer`]). A loop round one root, or a line slanting
//!   across the neck, leaves a root or the side of one with the crown. It
//!   is a preference, never a refusal: a tooth whose roots are short
//!   beside its crown (still growing, broken off) has its margin all the
//!   same.
//!
//! Handles or tunnels below the margin go with the roots and are
//! reported; handles in the crown are an error.

// Negated comparisons are meant: a NaN must fail every check.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod cut;
mod cycle;
mod geometry;
mod neck;

use crate::mesh::{
    bbox_diagonal, boundary_loops, euler_characteristic, norm, perpendicular_frame, sub, Mesh,
};
use geometry::{
    area_weighted_axes, directed_hausdorff, signed_volume6, taubin_smoothed, Cylinder,
    SurfaceGeometry,
};
use neck::{neck_heights, NeckHeights};
use rayon::prelude::*;

/// Whether a closed surface is cut to its crown.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CrownMode {
    /// Closed whole teeth are cut at the cervical margin (the default: a
    /// scanner's isosurface export is closed). A cut that cannot be the
    /// margin is refused, not used ([`MIN_CUT_HEIGHT`]).
    #[default]
    Auto,
    /// Closed surfaces are refused.
    Off,
}

/// The smallest mean turn (degrees) of the surface along the cut for it to
/// count as the cervical margin.
const MIN_CREASE_DEGREES: f64 = 15.0;

/// The lowest the chosen cut may dip, as a fraction of the tooth's length
/// from the apex: below the whole of its cervical margin a tooth has
/// roots longer than this. A cut that dips lower ran round a wrong axis
/// or round the roots, so the scan is refused rather than identified from
/// a wrong crown. (On whole teeth built from the 116 PNAS crowns the
/// margin's lowest point lies at 0.48 or higher; a loop round the roots'
/// closure near the apex dips to 0.07–0.17.)
const MIN_CUT_HEIGHT: f64 = 0.3;

/// The smallest share of the cut's length that must run along crease
/// edges (turn ≥ 10°): the enamel edge runs all around the tooth.
const MIN_CREASE_COVERAGE: f64 = 0.5;

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
    /// How much wider the crown's outline is at its height of contour than
    /// at the margin (median over polar sectors round the axis; 0 when the
    /// cut followed a crease alone, no neck being seen on the outline).
    #[serde(default)]
    pub neck_bulge: f64,
    /// How clearly the cut is a cervical margin: the share of it on
    /// crease less 0.1 × its rise and fall (what ranks the loops found
    /// about the different axes; 0 to 1).
    pub margin_merit: f64,
    /// Whether the whole tooth had handles (the tunnels of a thresholded
    /// export) and was cut after being taken through a voxel grid that
    /// closes them.
    #[serde(default)]
    pub revoxelized: bool,
    /// How far the part removed reaches from the cut, over how far the
    /// crown does ([`root_reach`]; 0 in reports written before it was
    /// measured).
    #[serde(default)]
    pub root_reach: f64,
}

/// Why no crown could be cut from a closed surface.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CrownError {
    /// Nothing on the surface looks like a tooth crown above a neck; why,
    /// for the margin line that came closest.
    #[error("no recognisable tooth crown on this closed surface ({0}); crown extraction needs a whole tooth (crown, cervical neck, roots): crop the crown at the cervical margin by hand, or check that the file is a tooth")]
    NoCrown(CrownRefusal),
    /// The crown part has handles or several boundaries.
    #[error("the crown cut from this closed surface is not a disk ({loops} boundary loop(s), Euler characteristic {euler}: handles or tunnels through the crown); repair the surface or crop the crown by hand")]
    NotDisk {
        /// Boundary loops of the crown part.
        loops: usize,
        /// Its Euler characteristic.
        euler: i64,
    },
}

/// Why a margin line (or the whole surface) gives no crown: one variant per
/// test of the module documentation, with what the test measured. The
/// texts are part of the messages users read.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum CrownRefusal {
    /// The surface has no area (or no extent) to find axes in.
    #[error("the surface has no area")]
    NoArea,
    /// No closed edge path winds round the axis.
    #[error("no closed line runs round the surface")]
    NoMarginLine,
    /// The surface has no faces to seed a side of the cut from.
    #[error("no faces")]
    NoFaces,
    /// Both sides of the cut alike in area and in width next to it.
    #[error("the best margin line cuts the surface into two halves alike in area and width: a symmetric solid, not a tooth")]
    SymmetricSolid,
    /// A neck-guided cut whose crown side does not bulge over the neck.
    #[error("the part above the neck seen on the outline does not bulge over it: the roots' end")]
    RootsEnd,
    /// Neither side of the line was judged (nothing was measured).
    #[error("no crown on either side of the line")]
    NeitherSide,
    /// The crown side holds too little or too much of the surface.
    #[error("the best margin line leaves {:.0} % of the surface as crown", 100.0 * .share)]
    CrownShare {
        /// The crown side's share of the surface area (0 to 1).
        share: f64,
    },
    /// The surface turns too little along the cut for a cervical crease.
    #[error("no cervical crease: the surface turns by {degrees:.1}° on average along the best margin line, at least {MIN_CREASE_DEGREES}° is needed")]
    NoCrease {
        /// The mean turn along the cut, in degrees.
        degrees: f64,
    },
    /// Too little of the cut runs along crease edges.
    #[error("the best margin line runs along a crease for {:.0} % of its length only, not around the tooth", 100.0 * .coverage)]
    ShortCrease {
        /// The share of the cut's length on crease edges (0 to 1).
        coverage: f64,
    },
    /// The crown side does not rise above the cut.
    #[error("the part above the best margin line is flat, not a crown")]
    Flat,
    /// The other side does not narrow towards an apex.
    #[error("the part below the best margin line does not taper to a root apex")]
    NoTaper,
    /// The cut dips below [`MIN_CUT_HEIGHT`].
    #[error("the best margin line found dips to {:.0} % of the tooth's length above the apex, where no cervical margin lies: the tooth's axis was not found", 100.0 * .height)]
    TooLow {
        /// The cut's lowest point, as a share of the tooth's length from
        /// the apex.
        height: f64,
    },
}

/// A margin line that gave no crown: how clearly it was a margin (its
/// loop's score, which picks the refusal users are told) and why.
#[derive(Debug, Clone, Copy)]
struct Rejection {
    score: f64,
    reason: CrownRefusal,
}

/// A crown cut from a closed surface.
#[derive(Debug, Clone)]
pub(super) struct ExtractedCrown {
    /// The crown: one disk-type component, normals outward.
    pub mesh: Mesh,
    /// What was cut.
    pub report: CrownReport,
    /// The crowns of other margins found (about other axes, or from the
    /// neck rather than a crease), of lower merit, that keep a different
    /// part of the surface: disk-type, best merit first, at most
    /// [`MAX_ALTERNATIVE_CUTS`]. The geometry ranks the loops; the
    /// references can tell which crown is one (the classifier compares
    /// them).
    pub alternatives: Vec<Mesh>,
}

/// Other cuts kept beside the best (see [`ExtractedCrown::alternatives`]).
/// On the two-rooted exports of the 116 teeth at 300 voxels, 61 of 116
/// have more than one distinct candidate, rarely more than three.
const MAX_ALTERNATIVE_CUTS: usize = 2;

/// Two cuts are one when the faces kept by one and not the other are
/// fewer than this share of the smaller crown's faces.
const DISTINCT_CUT: f64 = 0.1;

/// One axis tried and the crown it gives.
struct Candidate {
    inside: Vec<bool>,
    report: CrownReport,
}

impl Candidate {
    /// What ranks the loops found about the different axes (see
    /// [`margin_merit`]), as the report carries it.
    fn merit(&self) -> f64 {
        self.report.margin_merit
    }
}

/// The merit of a loop whose share on crease is `score` and whose cut
/// rises and falls by `cut_variation` of the crown's height: the share
/// less [`CREST_PENALTY`] per unit of rise and fall. A cervical margin
/// runs round the tooth at much the same height; a loop round another
/// axis that follows the occlusal crests climbs over the crown, and on a
/// crenulated crown it can be as much on crease as the margin.
fn margin_merit(score: f64, cut_variation: f64) -> f64 {
    score - CREST_PENALTY * cut_variation
}

/// Penalty on a cut's rise and fall in [`margin_merit`]: on whole teeth
/// built from the 116 PNAS crowns, the margin's loop lost to a crest loop
/// by less than 0.01 in score where the crest loop rose and fell by 0.3
/// more (of the crown's height), and won by 0.03 where it rose and fell
/// by 0.08 more than the crest loop.
const CREST_PENALTY: f64 = 0.1;

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

/// Weight of an edge's length in the margin search: small along a convex
/// crease (the enamel edge turns the surface inward by 35° or more), 1 on
/// smooth or concave surface.
fn crease_weight(turn: f64) -> f64 {
    (-turn.max(0.0) / CREASE_SCALE.to_radians()).exp().max(0.01)
}

/// Cost of the margin's climb along the axis per unit of height, on top
/// of its length: a loop that dives down a root ridge to the apex and back
/// pays for the way down and up, while the margin's own rise and fall
/// round the tooth (about a quarter of the crown's height) costs little.
const CLIMB_COST: f64 = 0.3;

/// Turn (degrees) over which an edge's weight falls by e.
const CREASE_SCALE: f64 = 12.0;

/// Share of the tooth's length at each end that the margin search leaves
/// out: the margin lies 0.5–0.8 of the length above the apex, and a
/// short loop round the roots' narrow closure near the apex (7–19 % of
/// the length) must not compete with it.
const END_EXCLUDED: f64 = 0.15;

/// How far from the axis the margin search keeps, as a share of the
/// widest radius at each height ([`margin_vertices`]).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Clearance {
    /// Half the widest radius: no small loop round the axis where it
    /// pierces the occlusal surface or the apex competes with the margin.
    Half,
    /// A quarter, for a surface on which no search found a crown within
    /// half: a crown whose outline is over twice as long as it is wide
    /// about the axis (a long molar, or one the principal axis runs
    /// through slanted) has its near side closer than half the far side's
    /// radius. (Of ten synthetic whole teeth stretched to 2.2–2.9 times
    /// their width, half finds 4 crowns, a quarter 8 and cuts 2 wrong, a
    /// tenth no more.)
    Quarter,
}

impl Clearance {
    /// The share of the widest radius at a vertex's height it keeps from
    /// the axis.
    fn share(self) -> f64 {
        match self {
            Clearance::Half => 0.5,
            Clearance::Quarter => 0.25,
        }
    }

    /// The share of the widest radius of all it keeps from the axis
    /// (three fifths of [`Clearance::share`]).
    fn share_of_widest(self) -> f64 {
        0.6 * self.share()
    }
}

/// Vertices the margin may pass through along `cyl`: not at the very ends
/// of the tooth, and away from the axis (`clearance` of the widest radius
/// at their height).
fn margin_vertices(
    mesh: &Mesh,
    cyl: &Cylinder,
    neck: Option<&NeckHeights>,
    clearance: Clearance,
) -> Vec<bool> {
    const BINS: usize = 50;
    let polar: Vec<(f64, f64)> = mesh
        .vertices
        .iter()
        .map(|&p| (cyl.height(p), cyl.polar(p).1))
        .collect();
    let zmin = polar.iter().map(|p| p.0).fold(f64::MAX, f64::min);
    let zmax = polar.iter().map(|p| p.0).fold(f64::MIN, f64::max);
    let length = (zmax - zmin).max(f64::MIN_POSITIVE);
    let bin_of = |z: f64| (((z - zmin) / length * BINS as f64) as usize).min(BINS - 1);
    let mut widest = vec![0.0f64; BINS];
    for &(z, r) in &polar {
        let b = bin_of(z);
        widest[b] = widest[b].max(r);
    }
    let widest_all = widest.iter().copied().fold(0.0, f64::max);
    polar
        .iter()
        .zip(&mesh.vertices)
        .map(|(&(z, r), &p)| {
            let t = (z - zmin) / length;
            (END_EXCLUDED..=1.0 - END_EXCLUDED).contains(&t)
                && r >= clearance.share() * widest[bin_of(z)]
                && r >= clearance.share_of_widest() * widest_all
                && neck.is_none_or(|n| (t - n.at(cyl.polar(p).0)).abs() <= NECK_WINDOW)
        })
        .collect()
}

/// The least a crown's outline must be wider at its height of contour
/// than at the neck for the neck to guide the margin: a box or a cylinder
/// round a slanted axis bends too, but does not narrow under a bulge.
const MIN_NECK_BULGE: f64 = 1.04;

/// How far (share of the tooth's length) the margin may stray from the
/// neck's height seen on the outline ([`neck::neck_heights`]).
const NECK_WINDOW: f64 = 0.15;

/// The distance from the neck's height (share of the length) at which an
/// edge costs twice its length: the loop follows a crease near the neck
/// where there is one, and the neck itself where there is none.
const NECK_BAND: f64 = 0.04;

/// The cost of an edge's straying from the neck's height, per unit of
/// its length: `1 + ((t − neck) / NECK_BAND)²`.
fn neck_weight(deviation: f64) -> f64 {
    1.0 + (deviation / NECK_BAND).powi(2)
}

/// Largest difference from 1 of the ratio of the two sides' distances
/// from the axis next to the cut for a cut into halves of equal area to
/// count as the symmetry cut of a solid (a cube cut round its body
/// diagonal), not a tooth's margin (whose crown bulges over the neck).
const SYMMETRIC_BULGE: f64 = 0.005;

/// A margin loop found about one axis.
struct MarginLoop {
    /// The loop's vertices in order.
    vertices: Vec<u32>,
    /// 1 − its mean edge weight: the larger, the more of it runs along
    /// crease.
    score: f64,
    /// Centroid of the loop's vertices.
    centre: [f64; 3],
    /// Unit normal of the loop's vector area, on the side of the axis it
    /// was found about.
    normal: [f64; 3],
}

/// The cheapest loop round the axis `axis` through `centre` (see
/// [`cycle`]), `clearance` away from it.
fn margin_loop(
    mesh: &Mesh,
    geo: &SurfaceGeometry,
    centre: [f64; 3],
    axis: [f64; 3],
    neck: Option<&NeckHeights>,
    clearance: Clearance,
) -> Option<MarginLoop> {
    let cyl = Cylinder::new(centre, axis);
    let angles: Vec<f64> = mesh.vertices.iter().map(|&p| cyl.polar(p).0).collect();
    let allowed = margin_vertices(mesh, &cyl, neck, clearance);
    let heights: Vec<f64> = mesh.vertices.iter().map(|&p| cyl.height(p)).collect();
    let zmin = heights.iter().copied().fold(f64::MAX, f64::min);
    let zmax = heights.iter().copied().fold(f64::MIN, f64::max);
    let length = (zmax - zmin).max(f64::MIN_POSITIVE);
    let mut cheapest = vec![f64::INFINITY; mesh.vertices.len()];
    let edges: Vec<(u32, u32, f64)> = geo
        .edges
        .edges()
        .iter()
        .enumerate()
        .map(|(e, &(a, b))| {
            let mut w = crease_weight(geo.turn[e]);
            if let Some(n) = neck {
                let mid = [0, 1, 2]
                    .map(|d| 0.5 * (mesh.vertices[a as usize][d] + mesh.vertices[b as usize][d]));
                let t = (cyl.height(mid) - zmin) / length;
                w *= neck_weight(t - n.at(cyl.polar(mid).0));
            }
            cheapest[a as usize] = cheapest[a as usize].min(w);
            cheapest[b as usize] = cheapest[b as usize].min(w);
            let (pa, pb) = (mesh.vertices[a as usize], mesh.vertices[b as usize]);
            let len = norm(sub(pa, pb));
            (
                a,
                b,
                len * w + CLIMB_COST * (cyl.height(pa) - cyl.height(pb)).abs(),
            )
        })
        .collect();
    let search = |allowed: &[bool]| {
        let graph = cycle::WindingGraph::new(&angles, &edges, allowed);
        let mut sources = graph.seam_vertices();
        sources.sort_by(|&a, &b| cheapest[a as usize].total_cmp(&cheapest[b as usize]));
        cycle::cheapest_winding_cycle(&graph, &sources)
    };
    let found = match search(&allowed) {
        Some(found) => found,
        // The neck's window leaves a gap somewhere round the tooth (a
        // sector whose outline bends at the furcation, not at the neck):
        // the loop may leave the window there, still drawn to the neck by
        // the edges' weights.
        None if neck.is_some() => search(&margin_vertices(mesh, &cyl, None, clearance))?,
        None => return None,
    };
    let points: Vec<[f64; 3]> = found
        .vertices
        .iter()
        .map(|&v| mesh.vertices[v as usize])
        .collect();
    let k = points.len();
    let length: f64 = (0..k)
        .map(|i| norm(sub(points[i], points[(i + 1) % k])))
        .sum();
    let c = [0, 1, 2].map(|d| points.iter().map(|p| p[d]).sum::<f64>() / k.max(1) as f64);
    let mut area = [0.0; 3];
    for i in 0..k {
        let n = crate::mesh::cross(sub(points[i], c), sub(points[(i + 1) % k], c));
        area = [area[0] + n[0], area[1] + n[1], area[2] + n[2]];
    }
    let sign = if crate::mesh::dot(area, axis) < 0.0 {
        -1.0
    } else {
        1.0
    };
    let an = norm(area);
    let normal = if an > 0.0 {
        area.map(|x| sign * x / an)
    } else {
        axis
    };
    Some(MarginLoop {
        vertices: found.vertices,
        score: 1.0 - found.cost / length.max(f64::MIN_POSITIVE),
        centre: c,
        normal,
    })
}

/// The crown that `found` cuts off, the crown's side being the one that
/// bulges over the other (see [`near_cut_radius`]).
fn crown_of_loop(
    mesh: &Mesh,
    geo: &SurfaceGeometry,
    found: &MarginLoop,
    neck_guided: bool,
) -> Result<Candidate, Rejection> {
    let k = found.vertices.len();
    let cut: std::collections::HashSet<(u32, u32)> = (0..k)
        .map(|i| {
            let (a, b) = (found.vertices[i], found.vertices[(i + 1) % k]);
            (a.min(b), a.max(b))
        })
        .collect();
    let score = found.score;
    let mut reasons = Vec::new();
    let mut sides = Vec::new();
    // A loop found on the neck's outline has its crown towards the axis'
    // positive end; a crease loop's side is told by the bulge.
    let signs: &[f64] = if neck_guided { &[1.0] } else { &[1.0, -1.0] };
    for &sign in signs {
        let cyl = Cylinder::new(found.centre, found.normal.map(|x| sign * x));
        let heights: Vec<f64> = mesh.vertices.iter().map(|&p| cyl.height(p)).collect();
        let zmin = heights.iter().copied().fold(f64::MAX, f64::min);
        let zmax = heights.iter().copied().fold(f64::MIN, f64::max);
        let Some(seed) = (0..mesh.faces.len()).max_by(|&f, &g| {
            cyl.height(geo.centroids[f])
                .total_cmp(&cyl.height(geo.centroids[g]))
        }) else {
            return Err(Rejection {
                score: 0.0,
                reason: CrownRefusal::NoFaces,
            });
        };
        let inside = cut::faces_bounded_by(mesh, geo, &cut, seed);
        let bulge = near_cut_radius(mesh, geo, &cyl, &inside, true)
            / near_cut_radius(mesh, geo, &cyl, &inside, false).max(f64::MIN_POSITIVE);
        let kept: f64 = geo
            .areas
            .iter()
            .zip(&inside)
            .filter(|(_, &k)| k)
            .map(|(a, _)| a)
            .sum::<f64>()
            / geo.areas.iter().sum::<f64>().max(f64::MIN_POSITIVE);
        if (2.0 * kept - 1.0).abs() < 0.05 && (bulge - 1.0).abs() < SYMMETRIC_BULGE {
            reasons.push(Rejection {
                score,
                reason: CrownRefusal::SymmetricSolid,
            });
            continue;
        }
        if neck_guided && !(bulge > 1.0) {
            reasons.push(Rejection {
                score,
                reason: CrownRefusal::RootsEnd,
            });
            continue;
        }
        match judge(mesh, geo, &cyl, &inside, (zmin, zmax), !neck_guided) {
            Ok(mut report) => {
                report.margin_merit = margin_merit(score, report.cut_variation);
                sides.push((bulge, Candidate { inside, report }));
            }
            Err(reason) => reasons.push(Rejection { score, reason }),
        }
    }
    sides
        .into_iter()
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|s| s.1)
        .ok_or_else(|| {
            reasons.into_iter().next().unwrap_or(Rejection {
                score,
                reason: CrownRefusal::NeitherSide,
            })
        })
}

/// Rings of faces next to the cut over which [`near_cut_radius`]
/// averages.
const BULGE_RINGS: usize = 4;

/// Mean distance from the axis of the faces within [`BULGE_RINGS`] rings
/// of the cut on the `side` of it: the crown's enamel bulges over the
/// neck, so right at the cervical margin the crown's side lies farther
/// out than the neck's.
fn near_cut_radius(
    mesh: &Mesh,
    geo: &SurfaceGeometry,
    cyl: &Cylinder,
    inside: &[bool],
    side: bool,
) -> f64 {
    let adjacency = crate::mesh::triangle_adjacency(&mesh.faces);
    let mut seen = vec![false; mesh.faces.len()];
    let mut frontier: Vec<usize> = (0..mesh.faces.len())
        .filter(|&f| {
            inside[f] == side
                && adjacency[f]
                    .iter()
                    .any(|&g| g != crate::mesh::NO_TRIANGLE && inside[g as usize] != side)
        })
        .collect();
    for &f in &frontier {
        seen[f] = true;
    }
    let (mut sum, mut area) = (0.0, 0.0);
    for _ in 0..BULGE_RINGS {
        let mut next = Vec::new();
        for &f in &frontier {
            sum += geo.areas[f] * cyl.polar(geo.centroids[f]).1;
            area += geo.areas[f];
            for &g in &adjacency[f] {
                if g != crate::mesh::NO_TRIANGLE && inside[g as usize] == side && !seen[g as usize]
                {
                    seen[g as usize] = true;
                    next.push(g as usize);
                }
            }
        }
        frontier = next;
    }
    sum / area.max(f64::MIN_POSITIVE)
}

/// Check that the cut found a crown (see the module documentation) and
/// measure it.
fn judge(
    mesh: &Mesh,
    geo: &SurfaceGeometry,
    cyl: &Cylinder,
    inside: &[bool],
    (zmin, zmax): (f64, f64),
    crease_required: bool,
) -> Result<CrownReport, CrownRefusal> {
    let total: f64 = geo.areas.iter().sum();
    let kept: f64 = geo
        .areas
        .iter()
        .zip(inside)
        .filter(|(_, &k)| k)
        .map(|(a, _)| a)
        .sum();
    let fraction = kept / total;
    if !(0.08..=0.92).contains(&fraction) {
        return Err(CrownRefusal::CrownShare { share: fraction });
    }
    let cut = cut_crease(mesh, geo, inside);
    let crease = cut.degrees;
    if crease_required && !(crease >= MIN_CREASE_DEGREES) {
        return Err(CrownRefusal::NoCrease { degrees: crease });
    }
    let coverage = cut.coverage;
    if crease_required && !(coverage >= MIN_CREASE_COVERAGE) {
        return Err(CrownRefusal::ShortCrease { coverage });
    }
    let cut_points: Vec<[f64; 3]> = (0..mesh.vertices.len())
        .filter(|&v| cut.vertices[v])
        .map(|v| mesh.vertices[v])
        .collect();
    let CutHeights {
        low: cut_low,
        mean: cut_mean,
        high: cut_high,
    } = cut_heights(cyl, &cut_points);
    let cut_radius = cross_radius(cyl, &cut_points);
    let (crown_top, root_low) = crown_top_and_root_low(mesh, cyl, inside);
    if crown_top - cut_mean < 0.2 * cut_radius {
        return Err(CrownRefusal::Flat);
    }
    let slab = root_low + 0.15 * (cut_mean - root_low);
    let root_points = root_points_below(mesh, cyl, inside, slab);
    let apex_radius = cross_radius(cyl, &root_points);
    if !(apex_radius < 0.75 * cut_radius) {
        return Err(CrownRefusal::NoTaper);
    }
    let reach = root_reach(mesh, inside, &cut_points);
    let folding_ratio =
        folding(mesh, geo, inside, true) / folding(mesh, geo, inside, false).max(f64::MIN_POSITIVE);
    let scale = |z: f64| (z - zmin) / (zmax - zmin);
    Ok(CrownReport {
        method: if crease_required {
            "cervical crease"
        } else {
            "neck outline"
        }
        .into(),
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
        // Set by the caller, which knows the loop's share on crease.
        margin_merit: 0.0,
        // Set by the caller, which knows the neck it followed.
        neck_bulge: 0.0,
        revoxelized: false,
        root_reach: reach,
    })
}

/// The [`root_reach`] below which a margin is taken to leave a root with
/// the crown: a tooth's roots are longer than its crown is tall, so below
/// the margin the surface reaches farther from it than above. (On the
/// two-rooted 300-voxel exports of the 116 PNAS teeth, the first choices
/// that were loops round one root or slants across the neck measured
/// 0.68–1.03, every other first choice 1.39 or more; but the project's
/// synthetic teeth with short roots beside long crowns have their true
/// margins at 0.8–1.2, so this only asks for a second look.)
const MIN_ROOT_REACH: f64 = 1.2;

/// How many times farther the roots below one margin must reach than
/// below another for the first to be preferred ([`roots_clearly_longer`]).
/// (On the real exports above, where a wrong first choice and a right one
/// were both found, the right one reached 1.65–2.0 times as far; on the
/// synthetic teeth, where a wrong cut reached farther than the true one,
/// at most 1.25 times.)
const CLEARLY_LONGER: f64 = 1.5;

/// How far the part of the surface off the crown (`inside` false) reaches
/// from the cut through `cut_points`, over how far the crown reaches: the
/// ratio of their directed Hausdorff distances to the cut.
fn root_reach(mesh: &Mesh, inside: &[bool], cut_points: &[[f64; 3]]) -> f64 {
    const CROWN: u8 = 1;
    const REST: u8 = 2;
    let mut sides = vec![0u8; mesh.vertices.len()];
    for (face, &k) in mesh.faces.iter().zip(inside) {
        for &v in face {
            sides[v as usize] |= if k { CROWN } else { REST };
        }
    }
    let side = |which: u8| -> Vec<[f64; 3]> {
        sides
            .iter()
            .zip(&mesh.vertices)
            .filter(|(&s, _)| s == which)
            .map(|(_, &p)| p)
            .collect()
    };
    let crown = directed_hausdorff(&side(CROWN), cut_points);
    directed_hausdorff(&side(REST), cut_points) / crown.max(f64::MIN_POSITIVE)
}

/// How the surface turns along a cut, and where the cut runs.
struct CutCrease {
    /// Length-weighted mean turn of the surface across the cut's edges
    /// (degrees).
    degrees: f64,
    /// Share of the cut's length on crease edges (turn ≥ 10°).
    coverage: f64,
    /// Whether each vertex is an end of a cut edge.
    vertices: Vec<bool>,
}

/// The cut: edges between a crown face and a removed one, with the
/// surface's turn along it.
fn cut_crease(mesh: &Mesh, geo: &SurfaceGeometry, inside: &[bool]) -> CutCrease {
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
    CutCrease {
        degrees: (turn_len / len_sum.max(f64::MIN_POSITIVE)).to_degrees(),
        coverage: crease_len / len_sum.max(f64::MIN_POSITIVE),
        vertices: cut_vertices,
    }
}

/// Heights along the axis of the cut's vertices.
struct CutHeights {
    /// The lowest.
    low: f64,
    /// The mean.
    mean: f64,
    /// The highest.
    high: f64,
}

/// Lowest, mean and highest height along the axis of `cut_points`.
fn cut_heights(cyl: &Cylinder, cut_points: &[[f64; 3]]) -> CutHeights {
    let heights: Vec<f64> = cut_points.iter().map(|&p| cyl.height(p)).collect();
    let low = heights.iter().copied().fold(f64::MAX, f64::min);
    let high = heights.iter().copied().fold(f64::MIN, f64::max);
    let mean = heights.iter().sum::<f64>() / heights.len().max(1) as f64;
    CutHeights { low, mean, high }
}

/// The greatest height along the axis of a crown face's corner and the
/// least of a removed face's corner.
fn crown_top_and_root_low(mesh: &Mesh, cyl: &Cylinder, inside: &[bool]) -> (f64, f64) {
    let mut crown_top = f64::MIN;
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
    (crown_top, root_low)
}

/// The corners of removed faces at height `slab` or lower, once per face
/// they are a corner of, in face order.
fn root_points_below(mesh: &Mesh, cyl: &Cylinder, inside: &[bool], slab: f64) -> Vec<[f64; 3]> {
    let mut root_points = Vec::new();
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
    root_points
}

/// How much lower (share of the tooth's length) than the neck seen on the
/// outline a crease loop may cut.
const BELOW_NECK: f64 = 0.05;

/// The candidates by merit, highest first, except that where a neck was
/// seen on the outline, a crease loop cutting well below it is no margin:
/// below the neck hang the roots, whose furcation and ridges have creases
/// too. Of equal merits the last found comes first.
fn ranked_candidates(candidates: Vec<Candidate>) -> Vec<Candidate> {
    let neck = candidates
        .iter()
        .filter(|c| c.report.neck_bulge > 0.0)
        .max_by(|a, b| a.merit().total_cmp(&b.merit()))
        .map(|c| c.report.cut_height_mean);
    let mut ranked: Vec<Candidate> = candidates
        .into_iter()
        .filter(|c| {
            c.report.neck_bulge > 0.0
                || neck.is_none_or(|n| c.report.cut_height_mean >= n - BELOW_NECK)
        })
        .collect();
    ranked.reverse();
    ranked.sort_by(|a, b| b.merit().total_cmp(&a.merit()));
    ranked
}

/// Whether the crown of `report` may leave a root with it: its
/// [`root_reach`] is under [`MIN_ROOT_REACH`].
pub(super) fn roots_short(report: &CrownReport) -> bool {
    report.root_reach < MIN_ROOT_REACH
}

/// Whether the part cut off below the margin of `a` clearly reaches
/// farther than below that of `b`: at least [`MIN_ROOT_REACH`] and
/// [`CLEARLY_LONGER`] times `b`'s.
pub(super) fn roots_clearly_longer(a: &CrownReport, b: &CrownReport) -> bool {
    a.root_reach >= MIN_ROOT_REACH && a.root_reach >= CLEARLY_LONGER * b.root_reach
}

/// `ranked` with the candidates that may leave a root with the crown
/// while another's roots clearly reach farther moved to the end, each
/// part in its order.
fn roots_hanging_below_first(ranked: Vec<Candidate>) -> Vec<Candidate> {
    let most = ranked
        .iter()
        .map(|c| c.report.root_reach)
        .fold(0.0, f64::max);
    let limit = (most / CLEARLY_LONGER).min(MIN_ROOT_REACH);
    let (mut kept, short): (Vec<Candidate>, Vec<Candidate>) = ranked
        .into_iter()
        .partition(|c| c.report.root_reach >= limit);
    kept.extend(short);
    kept
}

/// Whether the crowns `a` and `b` (faces kept) are the same cut (see
/// [`DISTINCT_CUT`]).
fn same_cut(a: &[bool], b: &[bool]) -> bool {
    let differ = a.iter().zip(b).filter(|(x, y)| x != y).count();
    let smaller = a
        .iter()
        .filter(|&&k| k)
        .count()
        .min(b.iter().filter(|&&k| k).count());
    (differ as f64) < DISTINCT_CUT * smaller as f64
}

/// The faces of `oriented` marked in `inside`, as a mesh of their own:
/// the crown, with the disk's Euler characteristic and boundary count.
fn crown_faces(oriented: &Mesh, inside: &[bool]) -> (Mesh, usize, i64) {
    let faces: Vec<[u32; 3]> = oriented
        .faces
        .iter()
        .zip(inside)
        .filter_map(|(f, &k)| k.then_some(*f))
        .collect();
    // A closed shell inside the tooth (a pulp cavity, a void an isosurface
    // closed) that falls on the crown's side of the cut is not crown.
    // Measured: the two-rooted export of i23 was refused, its crown a disk
    // and a closed shell (one boundary loop, Euler characteristic 3).
    let crown = super::components::without_closed_components(
        super::faces::remove_unreferenced_vertices(&Mesh::new(oriented.vertices.clone(), faces)),
    );
    let loops = boundary_loops(&crown).len();
    let euler = euler_characteristic(&crown);
    (crown, loops, euler)
}

/// The crowns of `others` (ranked, after `best`) that are disks and cut
/// differently from `best` and from each other, at most
/// [`MAX_ALTERNATIVE_CUTS`].
fn alternative_crowns(oriented: &Mesh, best: &Candidate, others: &[Candidate]) -> Vec<Mesh> {
    let mut kept: Vec<&[bool]> = vec![&best.inside];
    let mut crowns = Vec::new();
    for c in others {
        if crowns.len() == MAX_ALTERNATIVE_CUTS {
            break;
        }
        if kept.iter().any(|k| same_cut(k, &c.inside)) {
            continue;
        }
        let (crown, loops, euler) = crown_faces(oriented, &c.inside);
        if loops == 1 && euler == 1 {
            kept.push(&c.inside);
            crowns.push(crown);
        }
    }
    crowns
}

/// Rounds of smoothing before the margin search: enough to flatten
/// features below about 0.4 % of the diagonal (a voxel's staircase at
/// 300 voxels across), none on a coarse surface whose edges are longer.
fn smoothing_iterations(mesh: &Mesh) -> usize {
    let edges: f64 = mesh
        .faces
        .iter()
        .take(5000)
        .map(|f| {
            norm(sub(
                mesh.vertices[f[0] as usize],
                mesh.vertices[f[1] as usize],
            ))
        })
        .sum();
    let count = mesh.faces.len().clamp(1, 5000) as f64;
    let edge = edges / count;
    if !(edge > 0.0) {
        return 0;
    }
    let ratio = 0.004 * bbox_diagonal(mesh) / edge;
    (ratio * ratio).round().clamp(0.0, 30.0) as usize
}

/// `mesh` smoothed just enough that the voxel staircase of an isosurface
/// export goes (see [`smoothing_iterations`]); its connectivity kept.
pub(super) fn staircase_smoothed(mesh: &Mesh) -> Mesh {
    Mesh::new(
        taubin_smoothed(mesh, smoothing_iterations(mesh)),
        mesh.faces.clone(),
    )
}

/// How far from the longest principal axis the axes searched when every
/// margin found may leave a root with the crown are tilted.
const TILT_DEGREES: f64 = 25.0;

/// `ranked`, led by the candidates `found` by a further search (ranked
/// alike) when the best of those leaves the roots clearly further below
/// it ([`roots_clearly_longer`]) than `ranked`'s best; `how` says where
/// they were searched, for the log.
fn first_if_roots_clearly_longer(
    found: Vec<Candidate>,
    ranked: Vec<Candidate>,
    how: &str,
) -> Vec<Candidate> {
    let found = roots_hanging_below_first(ranked_candidates(found));
    if found
        .first()
        .zip(ranked.first())
        .is_some_and(|(f, b)| roots_clearly_longer(&f.report, &b.report))
    {
        tracing::debug!(
            searched = how,
            "a margin found further leaves the roots below it"
        );
        found.into_iter().chain(ranked).collect()
    } else {
        ranked
    }
}

/// Six unit axes, each `degrees` from the unit vector `axis`, evenly round
/// it.
fn tilted_axes(axis: [f64; 3], degrees: f64) -> Vec<[f64; 3]> {
    let [u, v] = perpendicular_frame(axis);
    let (sin, cos) = degrees.to_radians().sin_cos();
    (0..6)
        .map(|k| {
            let (s, c) = (k as f64 * std::f64::consts::FRAC_PI_3).sin_cos();
            [0, 1, 2].map(|d| cos * axis[d] + sin * (c * u[d] + s * v[d]))
        })
        .collect()
}

/// The margin searches about each of `axes` through `centre`: one guided
/// by the neck seen on the outline from each end of the axis that shows
/// one (the crown may be at either; the loop still follows a crease near
/// the neck), then one that follows creases alone, accepted only on a real
/// crease (an enamel edge).
fn margin_searches(
    smoothed: &Mesh,
    centre: [f64; 3],
    axes: impl IntoIterator<Item = [f64; 3]>,
) -> Vec<([f64; 3], Option<NeckHeights>)> {
    let mut searches = Vec::new();
    for axis in axes {
        for sign in [1.0, -1.0] {
            let a = axis.map(|x| sign * x);
            let neck = neck_heights(&smoothed.vertices, &Cylinder::new(centre, a))
                .inspect(|n| tracing::debug!(bulge = n.bulge, "neck seen"))
                .filter(|n| n.bulge >= MIN_NECK_BULGE);
            if let Some(n) = neck {
                searches.push((a, Some(n)));
            }
        }
        searches.push((axis, None));
    }
    searches
}

/// The crown candidate of one margin search about `axis` (guided by
/// `neck`, or by creases alone): the cheapest loop, searched again about
/// the normal of the loop found (the principal axis is only near the
/// tooth's axis; the better of the two is kept), and the crown it cuts;
/// or why there is none.
fn margin_candidate(
    smoothed: &Mesh,
    geo: &SurfaceGeometry,
    centre: [f64; 3],
    axis: [f64; 3],
    neck: Option<&NeckHeights>,
    clearance: Clearance,
) -> Result<Candidate, Rejection> {
    let Some(first) = margin_loop(smoothed, geo, centre, axis, neck, clearance) else {
        tracing::debug!(neck = neck.is_some(), "no winding loop");
        return Err(Rejection {
            score: 0.0,
            reason: CrownRefusal::NoMarginLine,
        });
    };
    let neck_again = neck.and_then(|_| {
        neck_heights(
            &smoothed.vertices,
            &Cylinder::new(first.centre, first.normal),
        )
        .filter(|n| n.bulge >= MIN_NECK_BULGE)
    });
    let again = if neck.is_some() && neck_again.is_none() {
        None
    } else {
        margin_loop(
            smoothed,
            geo,
            first.centre,
            first.normal,
            neck_again.as_ref(),
            clearance,
        )
    };
    let found = match again {
        Some(again) if again.score > first.score => again,
        _ => first,
    };
    // A line that dips where no margin lies ran round a wrong axis or the
    // roots: it cannot be the margin, whatever its merit.
    let candidate = crown_of_loop(smoothed, geo, &found, neck.is_some()).and_then(|c| {
        if c.report.cut_height_min < MIN_CUT_HEIGHT {
            Err(Rejection {
                score: found.score,
                reason: CrownRefusal::TooLow {
                    height: c.report.cut_height_min,
                },
            })
        } else {
            Ok(c)
        }
    });
    match candidate {
        Ok(mut c) => {
            tracing::debug!(
                neck = neck.is_some(),
                merit = c.merit(),
                cut_low = c.report.cut_height_min,
                cut_high = c.report.cut_height_max,
                "margin candidate"
            );
            c.report.neck_bulge = neck.map_or(0.0, |n| n.bulge);
            Ok(c)
        }
        Err(r) => {
            tracing::debug!(neck = neck.is_some(), reason = %r.reason, "margin refused");
            Err(r)
        }
    }
}

/// Cut the crown from a closed, consistently oriented, manifold surface
/// (see the module documentation). The crown's faces keep their vertices'
/// positions; normals point outward.
pub(super) fn extract_crown(mesh: &Mesh) -> Result<ExtractedCrown, CrownError> {
    let _span = tracing::debug_span!("crown").entered();
    let oriented = if signed_volume6(mesh) < 0.0 {
        Mesh::new(
            mesh.vertices.clone(),
            mesh.faces.iter().map(|f| [f[0], f[2], f[1]]).collect(),
        )
    } else {
        mesh.clone()
    };
    // The margin is looked for on a smoothed copy (the voxel staircase of
    // an isosurface and scanner noise would be creases everywhere); the
    // crown is cut from the surface as it is, along the same edges.
    let smoothed = Mesh::new(
        taubin_smoothed(&oriented, smoothing_iterations(&oriented)),
        oriented.faces.clone(),
    );
    let geo = SurfaceGeometry::new(&smoothed);
    let (centre, axes) = area_weighted_axes(&geo)
        .filter(|_| bbox_diagonal(mesh) > 0.0)
        .ok_or(CrownError::NoCrown(CrownRefusal::NoArea))?;
    // The searches are independent: they run in parallel, and their
    // outcomes are taken in the order of the searches, as one after
    // another would give them.
    let span = tracing::Span::current();
    let searches = margin_searches(&smoothed, centre, axes);
    let search = |searches: &[([f64; 3], Option<NeckHeights>)],
                  clearance: Clearance|
     -> (Vec<Candidate>, Vec<Rejection>) {
        let outcomes: Vec<Result<Candidate, Rejection>> = searches
            .par_iter()
            .map(|(axis, neck)| {
                let _in_crown = span.enter();
                margin_candidate(&smoothed, &geo, centre, *axis, neck.as_ref(), clearance)
            })
            .collect();
        let mut candidates: Vec<Candidate> = Vec::new();
        let mut reasons = Vec::new();
        for outcome in outcomes {
            match outcome {
                Ok(c) => candidates.push(c),
                Err(r) => reasons.push(r),
            }
        }
        (candidates, reasons)
    };
    let (mut candidates, mut reasons) = search(&searches, Clearance::Half);
    // Only a surface on which no search found a crown is searched again,
    // nearer the axis: one with any keeps the choice among them as it was,
    // and one refused again is told why the first searches refused it.
    let searched_near = candidates.is_empty();
    if searched_near {
        tracing::debug!("no crown about any axis: searched again nearer the axis");
        let (wide, _) = search(&searches, Clearance::Quarter);
        if !wide.is_empty() {
            candidates = wide;
            reasons.clear();
        }
    }
    let mut ranked = roots_hanging_below_first(ranked_candidates(candidates));
    // A best margin that may leave a root with the crown was maybe found
    // about an axis the half clearance held too far out (measured: on the
    // two-rooted export of h08, half found only a slant reaching 0.94,
    // a quarter the margin reaching 1.86). Candidates found nearer the
    // axis already would only be found again.
    if !searched_near && ranked.first().is_some_and(|b| roots_short(&b.report)) {
        let (near, _) = search(&searches, Clearance::Quarter);
        ranked = first_if_roots_clearly_longer(near, ranked, "nearer the axis");
    }
    // Still short: every axis searched may run through a root. On a
    // two-rooted tooth about as wide as it is long the principal axes are
    // nearly equal in spread, and the longest may lie well off the
    // tooth's (measured: j18, spreads 0.0035, 0.0045 and 0.0056, its axis
    // 25° from the longest; its margin was found about the axes tilted
    // that far from it, and about no principal axis).
    if ranked.first().is_some_and(|b| roots_short(&b.report)) {
        let tilted = margin_searches(&smoothed, centre, tilted_axes(axes[0], TILT_DEGREES));
        let (found, _) = search(&tilted, Clearance::Half);
        ranked =
            first_if_roots_clearly_longer(found, ranked, "about an axis tilted off the longest");
    }
    let mut ranked = ranked.into_iter();
    let Some(best) = ranked.next() else {
        // Every axis searched leaves a candidate or a rejection, so the
        // fallback only guards an empty set of axes.
        let reason = reasons
            .into_iter()
            .max_by(|a, b| a.score.total_cmp(&b.score))
            .map_or(CrownRefusal::NoMarginLine, |r| r.reason);
        return Err(CrownError::NoCrown(reason));
    };
    let (crown, loops, euler) = crown_faces(&oriented, &best.inside);
    if loops != 1 || euler != 1 {
        return Err(CrownError::NotDisk { loops, euler });
    }
    let others: Vec<Candidate> = ranked.collect();
    let alternatives = alternative_crowns(&oriented, &best, &others);
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
        alternatives,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn candidate(merit: f64, neck: f64, mean: f64, inside: &[bool]) -> Candidate {
        Candidate {
            inside: inside.to_vec(),
            report: CrownReport {
                margin_merit: merit,
                neck_bulge: neck,
                cut_height_mean: mean,
                ..CrownReport::default()
            },
        }
    }

    #[test]
    fn candidates_rank_by_merit_and_a_crease_far_below_the_neck_goes() {
        let ranked = ranked_candidates(vec![
            candidate(0.5, 1.1, 0.6, &[true]),
            candidate(0.8, 1.2, 0.5, &[false]),
            // A crease loop 0.1 below the best neck's cut: the roots'.
            candidate(0.9, 0.0, 0.4, &[true, true]),
            candidate(0.8, 0.0, 0.48, &[true, false]),
        ]);
        let merits: Vec<(f64, usize)> =
            ranked.iter().map(|c| (c.merit(), c.inside.len())).collect();
        // Of equal merits the last found comes first, as the single best
        // was chosen before there were alternatives.
        assert_eq!(merits, [(0.8, 2), (0.8, 1), (0.5, 1)]);
    }

    #[test]
    fn tilted_axes_are_unit_vectors_at_the_angle_evenly_round_the_axis() {
        let axis = [0.6, 0.0, 0.8];
        let tilted = tilted_axes(axis, 25.0);
        assert_eq!(tilted.len(), 6);
        for (k, t) in tilted.iter().enumerate() {
            assert!((norm(*t) - 1.0).abs() < 1e-12);
            let angle = crate::mesh::dot(*t, axis).acos().to_degrees();
            assert!((angle - 25.0).abs() < 1e-9, "{angle}");
            // Each two neighbours round the axis lie as far apart.
            let next = tilted[(k + 1) % 6];
            let apart = crate::mesh::dot(*t, next).acos().to_degrees();
            let first_two = crate::mesh::dot(tilted[0], tilted[1]).acos().to_degrees();
            assert!((apart - first_two).abs() < 1e-9);
        }
        // Opposite tilts lie 50° apart, through the axis.
        let across = crate::mesh::dot(tilted[0], tilted[3]).acos().to_degrees();
        assert!((across - 50.0).abs() < 1e-9, "{across}");
    }

    #[test]
    fn margins_that_leave_a_root_with_the_crown_rank_after_those_that_do_not() {
        let with_reach = |merit: f64, reach: f64| {
            let mut c = candidate(merit, 0.0, 0.6, &[true]);
            c.report.root_reach = reach;
            c
        };
        let reaches = |ranked: Vec<Candidate>| -> Vec<f64> {
            ranked.iter().map(|c| c.report.root_reach).collect()
        };
        // 0.86 is under 1.61 / 1.5: it goes after the others.
        let ranked = roots_hanging_below_first(vec![
            with_reach(0.8, 0.86),
            with_reach(0.7, 1.61),
            with_reach(0.6, 1.1),
        ]);
        assert_eq!(reaches(ranked), [1.61, 1.1, 0.86]);
        // Short roots beside a long crown: 1.17 is not under 1.46 / 1.5.
        let ranked = roots_hanging_below_first(vec![with_reach(0.9, 1.17), with_reach(0.1, 1.46)]);
        assert_eq!(reaches(ranked), [1.17, 1.46]);
        // Nothing at or over MIN_ROOT_REACH ever moves.
        let ranked = roots_hanging_below_first(vec![with_reach(0.9, 1.25), with_reach(0.1, 3.0)]);
        assert_eq!(reaches(ranked), [1.25, 3.0]);
        let short = with_reach(0.9, 1.17).report;
        assert!(roots_short(&short));
        assert!(!roots_clearly_longer(&with_reach(0.1, 1.46).report, &short));
        assert!(roots_clearly_longer(&with_reach(0.1, 1.8).report, &short));
        // However short the other's, a reach under the least is no better.
        assert!(!roots_clearly_longer(
            &with_reach(0.1, 1.1).report,
            &with_reach(0.1, 0.5).report
        ));
    }

    #[test]
    fn a_closed_shell_on_the_crowns_side_is_not_crown() {
        use crate::testing::synth as g;
        // A grid (the crown, a disk) and, beside it, a closed sphere (a
        // shell inside the tooth), both on the crown's side of the cut.
        let disk = g::square_grid(12);
        let shell = g::closed_sphere(400);
        let offset = disk.vertices.len() as u32;
        let mut vertices = disk.vertices.clone();
        vertices.extend(shell.vertices.iter().map(|p| [p[0] + 5.0, p[1], p[2]]));
        let mut faces = disk.faces.clone();
        faces.extend(shell.faces.iter().map(|f| f.map(|v| v + offset)));
        let both = Mesh::new(vertices, faces);
        let (crown, loops, euler) = crown_faces(&both, &vec![true; both.faces.len()]);
        assert_eq!((loops, euler), (1, 1));
        assert_eq!(crown.faces.len(), disk.faces.len());
        assert_eq!(crown.vertices.len(), disk.vertices.len());
        // A crown with no shell is kept whole.
        let (alone, ..) = crown_faces(&disk, &vec![true; disk.faces.len()]);
        assert_eq!(alone.faces, disk.faces);
    }

    #[test]
    fn cuts_that_differ_by_under_a_tenth_of_the_smaller_crown_are_one() {
        let a: Vec<bool> = (0..100).map(|i| i < 50).collect();
        let mut b = a.clone();
        for k in b.iter_mut().skip(50).take(4) {
            *k = true;
        }
        assert!(same_cut(&a, &b));
        for k in b.iter_mut().skip(54).take(2) {
            *k = true;
        }
        assert!(!same_cut(&a, &b), "6 of 50 differ");
        let c: Vec<bool> = (0..100).map(|i| i >= 50).collect();
        assert!(!same_cut(&a, &c));
    }

    #[test]
    fn a_caps_rest_reaches_farther_from_the_cut_than_the_cap() {
        use crate::testing::synth as g;
        // The unit sphere cut at z = 0.6: the rest reaches from the ring
        // (radius 0.8) to the far pole, √(0.8² + 1.6²) ≈ 1.79; the cap
        // to its own pole, √(0.8² + 0.4²) ≈ 0.89.
        let sphere = g::closed_sphere(2000);
        let height = |f: &[u32; 3]| {
            f.iter()
                .map(|&v| sphere.vertices[v as usize][2])
                .sum::<f64>()
                / 3.0
        };
        let cap: Vec<bool> = sphere.faces.iter().map(|f| height(f) > 0.6).collect();
        let mut on_cut = vec![(false, false); sphere.vertices.len()];
        for (f, &k) in sphere.faces.iter().zip(&cap) {
            for &v in f {
                if k {
                    on_cut[v as usize].0 = true;
                } else {
                    on_cut[v as usize].1 = true;
                }
            }
        }
        let cut: Vec<[f64; 3]> = on_cut
            .iter()
            .zip(&sphere.vertices)
            .filter(|(&(a, b), _)| a && b)
            .map(|(_, &p)| p)
            .collect();
        let reach = root_reach(&sphere, &cap, &cut);
        assert!((1.8..2.2).contains(&reach), "{reach}");
        // Kept the other way round, the "crown" is the longer part.
        let rest: Vec<bool> = cap.iter().map(|&k| !k).collect();
        let reach = root_reach(&sphere, &rest, &cut);
        assert!((0.45..0.56).contains(&reach), "{reach}");
        assert!(reach < MIN_ROOT_REACH);
    }

    #[test]
    fn refusals_print_what_they_measured() {
        let said = |r: CrownRefusal| CrownError::NoCrown(r).to_string();
        assert_eq!(
            CrownRefusal::NoCrease { degrees: 7.26 }.to_string(),
            "no cervical crease: the surface turns by 7.3° on average along the best margin line, at least 15° is needed"
        );
        assert_eq!(
            CrownRefusal::ShortCrease { coverage: 0.314 }.to_string(),
            "the best margin line runs along a crease for 31 % of its length only, not around the tooth"
        );
        assert_eq!(
            CrownRefusal::CrownShare { share: 0.956 }.to_string(),
            "the best margin line leaves 96 % of the surface as crown"
        );
        assert!(said(CrownRefusal::TooLow { height: 0.12 }).starts_with(
            "no recognisable tooth crown on this closed surface (the best margin line found dips to 12 % of the tooth's length above the apex,"
        ));
    }
}
