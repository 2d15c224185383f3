//! A surface's area as a measure of its disk, at a few weighted points.

use super::search::DiskMeasure;
use crate::cp::Prepared;

/// Points of the flattening this close to the unit circle are on the
/// surface's rim.
const RIM: f64 = 1e-6;

/// The area measure of `p` carried to its disk, at one point per sample:
/// every vertex goes to the sample nearest it in space (its cell), each
/// cell's mass is its vertex areas' sum, and its point is the disk
/// position of the cell's vertex nearest the cell's area centroid, off
/// the rim where the cell has such a vertex.
///
/// Why not the samples themselves: farthest-point samples sit on the rim,
/// which the flattening puts on the unit circle, infinitely far from
/// everything in the hyperbolic metric; a cell's mass lies inside it. The
/// points depend on the surface only, so another flattening of it (by a
/// disk automorphism) moves them with it, as cW needs.
pub(super) fn area_measure(p: &Prepared) -> DiskMeasure {
    let (x, uv, areas) = (p.vertices(), p.uv(), p.vertex_areas());
    let centres: Vec<[f64; 3]> = p.samples().iter().map(|&v| x[v as usize]).collect();
    let k = centres.len();
    let owner: Vec<usize> = x
        .iter()
        .map(|y| {
            centres
                .iter()
                .map(|c| (c[0] - y[0]).powi(2) + (c[1] - y[1]).powi(2) + (c[2] - y[2]).powi(2))
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
                .map_or(0, |(i, _)| i)
        })
        .collect();
    let mut mass = vec![0.0; k];
    let mut centroid = vec![[0.0; 3]; k];
    for ((&o, y), &w) in owner.iter().zip(x).zip(areas) {
        mass[o] += w;
        for d in 0..3 {
            centroid[o][d] += w * y[d];
        }
    }
    for (c, &m) in centroid.iter_mut().zip(&mass) {
        if m > 0.0 {
            *c = c.map(|v| v / m);
        }
    }
    // The representative of each cell: (off the rim?, squared distance to
    // the centroid, vertex), smallest wins — inner vertices first.
    let mut best: Vec<Option<(bool, f64, usize)>> = vec![None; k];
    for (v, (&o, y)) in owner.iter().zip(x).enumerate() {
        let c = centroid[o];
        let on_rim = uv[v][0].hypot(uv[v][1]) >= 1.0 - RIM;
        let key = (
            on_rim,
            (c[0] - y[0]).powi(2) + (c[1] - y[1]).powi(2) + (c[2] - y[2]).powi(2),
            v,
        );
        let better = match best[o] {
            None => true,
            Some(b) => (key.0, key.1).partial_cmp(&(b.0, b.1)) == Some(std::cmp::Ordering::Less),
        };
        if better {
            best[o] = Some(key);
        }
    }
    let (mut points, mut masses) = (Vec::with_capacity(k), Vec::with_capacity(k));
    for (b, &m) in best.iter().zip(&mass) {
        if let Some((_, _, v)) = b {
            if m > 0.0 {
                points.push(uv[*v]);
                masses.push(m);
            }
        }
    }
    DiskMeasure { points, masses }
}
