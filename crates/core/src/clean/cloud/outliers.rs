//! Outlier removal from k-nearest-neighbour statistics.
//!
//! Two kinds of stray points are caught: isolated points (far from every
//! other, e.g. dust anywhere in the scanner's volume), whose mean distance
//! to their neighbours is several times that of their neighbours and of
//! the cloud as a whole; and points floating just off the surface, far
//! from the plane fitted to their neighbours compared with how well that
//! plane fits the neighbours themselves.

use super::normals::{local_plane, plane_distance};
use crate::stats::upper_median;

/// A point whose mean neighbour distance is this many times the median of
/// its neighbours' is isolated.
const LOCAL_ISOLATION: f64 = 3.0;
/// ... or this many times the median over the whole cloud.
const GLOBAL_ISOLATION: f64 = 5.0;
/// A point farther from its neighbours' plane than this many times their
/// root-mean-square distance from it, ...
const OFF_PLANE_RESIDUALS: f64 = 4.0;
/// ... and than this fraction of the neighbours' spacing, is off the surface.
const OFF_PLANE_SPACING: f64 = 0.75;

/// Which points are isolated: `spacing[i]` is point `i`'s mean distance to
/// its neighbours `neighbours[i]`.
pub(super) fn isolated_points(spacing: &[f64], neighbours: &[Vec<usize>]) -> Vec<bool> {
    let global = upper_median(spacing).unwrap_or(0.0);
    spacing
        .iter()
        .zip(neighbours)
        .map(|(&d, list)| {
            let around: Vec<f64> = list.iter().map(|&j| spacing[j]).collect();
            let local = upper_median(&around).unwrap_or(0.0);
            d > GLOBAL_ISOLATION * global || (!around.is_empty() && d > LOCAL_ISOLATION * local)
        })
        .collect()
}

/// Which points lie off the surface that their neighbours sample: farther
/// from the neighbours' least-squares plane (the point itself left out)
/// than both [`OFF_PLANE_RESIDUALS`] times the plane's residual and
/// [`OFF_PLANE_SPACING`] times the neighbours' spacing.
pub(super) fn off_surface_points(
    points: &[[f64; 3]],
    spacing: &[f64],
    neighbours: &[Vec<usize>],
) -> Vec<bool> {
    use rayon::prelude::*;
    neighbours
        .par_iter()
        .enumerate()
        .map(|(i, list)| {
            let around: Vec<[f64; 3]> = list.iter().map(|&j| points[j]).collect();
            let Some(plane) = local_plane(&around) else {
                return false;
            };
            // The neighbours' spacing: an outlier's own is inflated.
            let local =
                upper_median(&list.iter().map(|&j| spacing[j]).collect::<Vec<_>>()).unwrap_or(0.0);
            let limit = (OFF_PLANE_RESIDUALS * plane.residual).max(OFF_PLANE_SPACING * local);
            plane_distance(&plane, points[i]).abs() > limit
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dust_and_a_floating_point_are_caught() {
        // A jittered grid in the plane z = 0, a far point and one just above.
        let mut pts: Vec<[f64; 3]> = (0..400)
            .map(|k| {
                let (x, y) = ((k % 20) as f64, (k / 20) as f64);
                [
                    x + 0.1 * (k as f64).sin(),
                    y + 0.1 * (k as f64 * 1.7).cos(),
                    0.0,
                ]
            })
            .collect();
        pts.push([10.0, 10.0, 30.0]);
        pts.push([7.5, 7.5, 1.5]);
        let nb = super::super::neighbours::Neighbours::new(&pts);
        let lists: Vec<Vec<usize>> = (0..pts.len())
            .map(|i| nb.of_point(i, 12).into_iter().map(|f| f.0).collect())
            .collect();
        let spacing = super::super::neighbours::mean_neighbour_distances(&nb, 12);
        let isolated = isolated_points(&spacing, &lists);
        assert!(isolated[400]);
        assert_eq!(isolated.iter().filter(|&&b| b).count(), 1);
        let off = off_surface_points(&pts, &spacing, &lists);
        assert!(off[401]);
        assert!(!off[..400].iter().any(|&b| b));
    }
}
