//! A crown cut again along a reference's crop line.
//!
//! A crown cut from a whole tooth at a margin found on the geometry alone
//! ends where the outline narrows; on a smooth neck the hand crop of a
//! library crown often rises above that on some sides. Once the cP
//! comparison has aligned the scan with a reference, the reference's own
//! crop line, carried over by the comparison's rigid motion, says where a
//! crown of that kind ends: the scan's faces below it are neck. Several
//! references' lines vote face by face ([`cut_along_rims`]).

use super::comparison::Comparison;
use super::prepared::Prepared;
use crate::mesh::{cross, dot, longest_boundary_loop, norm, perpendicular_frame, sub, unit, Mesh};
use std::f64::consts::PI;

/// Polar bins of a crop line: fine enough for the line's rise and fall
/// between cusps, coarse enough that each bin holds a rim vertex or two
/// of a 5,000-vertex crown.
const BINS: usize = 360;

/// A crown's crop line as a height over the polar angle about the line's
/// own axis (the normal of its vector area, towards the crown).
#[derive(Debug, Clone)]
pub struct RimProfile {
    centre: [f64; 3],
    /// Rows: two in-plane directions and the axis.
    rows: [[f64; 3]; 3],
    /// The line's height in each polar bin.
    heights: Vec<f64>,
}

impl RimProfile {
    /// The crop line of `crown` (its longest boundary loop); `None` for a
    /// surface without a boundary or with a degenerate one.
    pub fn of(crown: &Prepared) -> Option<RimProfile> {
        let mesh = Mesh::new(crown.vertices().to_vec(), crown.faces().to_vec());
        let rim = longest_boundary_loop(&mesh)?;
        let points: Vec<[f64; 3]> = rim.iter().map(|&v| mesh.vertices[v as usize]).collect();
        let centre = mean(&points)?;
        let mut area = [0.0; 3];
        for (i, &p) in points.iter().enumerate() {
            let x = cross(sub(p, centre), sub(points[(i + 1) % points.len()], centre));
            area = [area[0] + x[0], area[1] + x[1], area[2] + x[2]];
        }
        let size = norm(area);
        if !(size > 0.0 && size.is_finite()) {
            return None;
        }
        let mut axis = unit(area);
        // Towards the crown: its vertices' mean lies above the line.
        if dot(sub(mean(&mesh.vertices)?, centre), axis) < 0.0 {
            axis = axis.map(|a| -a);
        }
        let [x, y] = perpendicular_frame(axis);
        let rows = [x, y, axis];
        let mut profile = RimProfile {
            centre,
            rows,
            heights: Vec::new(),
        };
        let mut samples: Vec<(f64, f64)> = points
            .iter()
            .map(|&p| {
                let l = profile.local(p);
                (l[1].atan2(l[0]), l[2])
            })
            .collect();
        samples.sort_by(|a, b| a.0.total_cmp(&b.0));
        profile.heights = (0..BINS)
            .map(|b| interpolate_periodic(&samples, bin_angle(b)))
            .collect();
        Some(profile)
    }

    /// `p` in the line's frame: two in-plane coordinates and the height.
    fn local(&self, p: [f64; 3]) -> [f64; 3] {
        let d = sub(p, self.centre);
        self.rows.map(|r| dot(r, d))
    }

    /// Whether the point `p` (the profile's frame is the crown's) lies
    /// above the crop line at its polar angle.
    fn above(&self, p: [f64; 3]) -> bool {
        let l = self.local(p);
        l[2] > self.heights[bin_of(l[1].atan2(l[0]))]
    }
}

/// The rigid motion `x ↦ R x + t` (R orthogonal, a reflection for a
/// mirror-image match) that takes a scan's normalized vertices onto a
/// reference's, as a comparison of the two found it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Alignment {
    rotation: [[f64; 3]; 3],
    translation: [f64; 3],
}

impl Alignment {
    /// The motion of the better direction of `c` (a comparison of the
    /// scan with the reference): the backward one is inverted.
    pub fn of(c: &Comparison) -> Alignment {
        if c.forward.distance <= c.backward.distance {
            return Alignment {
                rotation: c.forward.rotation,
                translation: c.forward.translation,
            };
        }
        let r = c.backward.rotation;
        let rotation = [0, 1, 2].map(|i| [r[0][i], r[1][i], r[2][i]]);
        let translation = rotation.map(|row| -dot(row, c.backward.translation));
        Alignment {
            rotation,
            translation,
        }
    }

    /// The motion for the surface that `part` was prepared from, when
    /// this one takes `part`'s normalized vertices onto the reference: it
    /// normalizes as `part` did first, so it is a similarity.
    pub fn of_unnormalized(&self, part: &Prepared) -> Alignment {
        let (c, s) = (part.centroid(), part.scale());
        let rotation = self.rotation.map(|row| row.map(|x| x / s));
        let translation = [0, 1, 2].map(|i| self.translation[i] - dot(rotation[i], c));
        Alignment {
            rotation,
            translation,
        }
    }

    fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let r = self.rotation.map(|row| dot(row, p));
        [
            r[0] + self.translation[0],
            r[1] + self.translation[1],
            r[2] + self.translation[2],
        ]
    }
}

/// The faces of `scan` that lie above `rim` (by their centroids) once
/// the scan is moved onto the reference whose line `rim` is by
/// `alignment`; the vertices are the scan's normalized vertices, unused
/// ones kept.
pub fn cut_along_rim(scan: &Prepared, alignment: &Alignment, rim: &RimProfile) -> Mesh {
    cut_along_rims(scan, &[(*alignment, rim.clone())])
}

/// The faces of `scan` that lie above the crop lines of at least half of
/// `rims` (each with the motion that takes the scan onto its reference;
/// by the faces' centroids): the cut on which several references agree.
/// The vertices are the scan's normalized vertices, unused ones kept;
/// no lines keep every face.
pub fn cut_along_rims(scan: &Prepared, rims: &[(Alignment, RimProfile)]) -> Mesh {
    let mut votes = vec![0usize; scan.faces().len()];
    for (alignment, rim) in rims {
        let moved: Vec<[f64; 3]> = scan
            .vertices()
            .iter()
            .map(|&p| alignment.apply(p))
            .collect();
        for (f, v) in scan.faces().iter().zip(votes.iter_mut()) {
            let c = f.iter().fold([0.0; 3], |a, &i| {
                let p = moved[i as usize];
                [a[0] + p[0] / 3.0, a[1] + p[1] / 3.0, a[2] + p[2] / 3.0]
            });
            if rim.above(c) {
                *v += 1;
            }
        }
    }
    let need = rims.len().div_ceil(2);
    let faces = scan
        .faces()
        .iter()
        .zip(&votes)
        .filter(|(_, &v)| v >= need)
        .map(|(f, _)| *f)
        .collect();
    Mesh::new(scan.vertices().to_vec(), faces)
}

fn mean(points: &[[f64; 3]]) -> Option<[f64; 3]> {
    if points.is_empty() {
        return None;
    }
    let n = points.len() as f64;
    Some([0, 1, 2].map(|d| points.iter().map(|p| p[d]).sum::<f64>() / n))
}

fn bin_angle(b: usize) -> f64 {
    -PI + (b as f64 + 0.5) / BINS as f64 * 2.0 * PI
}

fn bin_of(theta: f64) -> usize {
    (((theta + PI) / (2.0 * PI) * BINS as f64) as usize).min(BINS - 1)
}

/// The value at angle `theta` of samples `(angle, value)` sorted by angle,
/// linear between the neighbours on either side, round the circle.
fn interpolate_periodic(samples: &[(f64, f64)], theta: f64) -> f64 {
    let k = samples.len();
    let i = samples.partition_point(|s| s.0 < theta);
    let (lo, hi) = (samples[(i + k - 1) % k], samples[i % k]);
    let span = (hi.0 - lo.0).rem_euclid(2.0 * PI);
    let off = (theta - lo.0).rem_euclid(2.0 * PI);
    let t = if span > 0.0 {
        (off / span).clamp(0.0, 1.0)
    } else {
        0.0
    };
    lo.1 + t * (hi.1 - lo.1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cp::{compare, prepare, CompareParams, PrepareParams};
    use crate::testing::synth::{self, CROWN_GENERA};

    /// Lines vote face by face: a face is kept when it lies above at
    /// least half of them.
    #[test]
    fn the_cut_along_several_lines_keeps_what_half_of_them_keep() {
        let crown = synth::crown(&CROWN_GENERA[1], 5, 1200);
        let scan = prepare(&crown, &PrepareParams::default()).expect("prepares");
        let rim = RimProfile::of(&scan).expect("a crop line");
        let identity = Alignment {
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation: [0.0; 3],
        };
        // Moved far down the line's axis: every face lies below it.
        let sunk = Alignment {
            translation: rim.rows[2].map(|a| -100.0 * a),
            ..identity
        };
        let own = cut_along_rim(&scan, &identity, &rim);
        assert!(own.faces.len() > scan.faces().len() / 2);
        assert!(cut_along_rim(&scan, &sunk, &rim).faces.is_empty());
        let line = |a: Alignment| (a, rim.clone());
        let two_of_three = cut_along_rims(&scan, &[line(identity), line(sunk), line(identity)]);
        assert_eq!(two_of_three.faces, own.faces);
        let half = cut_along_rims(&scan, &[line(sunk), line(identity)]);
        assert_eq!(half.faces, own.faces);
        let one_of_three = cut_along_rims(&scan, &[line(sunk), line(identity), line(sunk)]);
        assert!(one_of_three.faces.is_empty());
    }

    /// A moved copy of a crown is taken back onto it, vertex for vertex,
    /// from either direction of the comparison.
    #[test]
    fn the_alignment_takes_the_scan_onto_the_reference_from_either_direction() {
        let crown = synth::crown(&CROWN_GENERA[0], 5, 1500);
        let reference = prepare(&crown, &PrepareParams::default()).expect("prepares");
        let moved = synth::scale(&synth::rigid_motion(&crown, 3), 0.5);
        let scan = prepare(&moved, &PrepareParams::default()).expect("prepares");
        let params = CompareParams::default();
        let c = compare(&scan, &reference, &params);
        let back = compare(&reference, &scan, &params);
        let swapped = Comparison {
            distance: back.distance,
            forward: back.backward.clone(),
            backward: back.forward.clone(),
            reflected: back.reflected,
        };
        for (label, c) in [("forward", c), ("swapped", swapped)] {
            let a = Alignment::of(&c);
            let worst = scan
                .vertices()
                .iter()
                .zip(reference.vertices())
                .map(|(&p, &q)| norm(sub(a.apply(p), q)))
                .fold(0.0, f64::max);
            assert!(worst < 1e-3, "{label}: {worst}");
        }
    }

    /// The crown with a band of neck below its rim (the rim's vertices
    /// and a copy of them lowered along the crown's height direction),
    /// moved: cut again along the crown's own line, the neck goes and
    /// the crown stays.
    #[test]
    fn a_crown_with_a_neck_cut_along_its_own_line_loses_the_neck() {
        let crown = synth::crown(&CROWN_GENERA[2], 11, 1500);
        let reference = prepare(&crown, &PrepareParams::default()).expect("prepares");
        let rim = RimProfile::of(&reference).expect("a crop line");
        let loop_ = longest_boundary_loop(&crown).expect("a boundary");
        // The crown's height direction: from its rim's centre to its mean.
        let centre = mean(
            &loop_
                .iter()
                .map(|&v| crown.vertices[v as usize])
                .collect::<Vec<_>>(),
        )
        .expect("points");
        let up = unit(sub(mean(&crown.vertices).expect("points"), centre));
        let mut necked = crown.clone();
        let drop = 0.06 * crate::mesh::bbox_diagonal(&crown);
        let first = necked.vertices.len() as u32;
        for &v in &loop_ {
            let p = crown.vertices[v as usize];
            necked.vertices.push([
                p[0] - drop * up[0],
                p[1] - drop * up[1],
                p[2] - drop * up[2],
            ]);
        }
        let n = loop_.len();
        // The new faces run each rim edge the other way from the crown's
        // face on it, so the orientation stays consistent.
        let forward = crown
            .faces
            .iter()
            .any(|&f| crate::mesh::has_directed_edge(f, loop_[0], loop_[1 % n]));
        for i in 0..n {
            let (a, b) = (loop_[i], loop_[(i + 1) % n]);
            let (a2, b2) = (first + i as u32, first + ((i + 1) % n) as u32);
            if forward {
                necked.faces.push([b, a, a2]);
                necked.faces.push([b, a2, b2]);
            } else {
                necked.faces.push([a, b, b2]);
                necked.faces.push([a, b2, a2]);
            }
        }
        let moved = synth::scale(&synth::rigid_motion(&necked, 7), 3.0);
        let scan = prepare(&moved, &PrepareParams::default()).expect("prepares");
        let c = compare(&scan, &reference, &CompareParams::default());
        // The neck's faces are those with a lowered vertex.
        let neck_kept = |cut: &Mesh| {
            cut.faces
                .iter()
                .filter(|f| f.iter().any(|&v| v >= first))
                .count()
        };
        // The first cut is aligned with the neck on, which pulls the scan
        // up: part of the neck stays. Aligned again without it (the
        // surface the first cut left, cleaned and prepared as a scan is),
        // the second cut takes it all.
        let first_cut = cut_along_rim(&scan, &Alignment::of(&c), &rim);
        assert!(
            neck_kept(&first_cut) < 2 * n,
            "the first cut takes some neck"
        );
        let cleaned = crate::clean::clean(&first_cut, &Default::default()).expect("cleans");
        let part = prepare(&cleaned.mesh, &PrepareParams::default()).expect("prepares");
        let again = compare(&part, &reference, &CompareParams::default());
        assert!(again.distance < c.distance);
        let cut = cut_along_rim(&scan, &Alignment::of(&again).of_unnormalized(&part), &rim);
        let kept_neck = neck_kept(&cut);
        assert!(
            kept_neck <= n / 10,
            "{kept_neck} of {} neck faces kept",
            2 * n
        );
        let crown_faces = crown.faces.len();
        assert!(
            cut.faces.len() >= crown_faces * 95 / 100,
            "{} of {crown_faces} crown faces kept",
            cut.faces.len()
        );
    }
}
