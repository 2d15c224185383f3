//! k-nearest-neighbour queries over a point set (a `kiddo` k-d tree).

use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use std::num::NonZero;

/// A k-d tree over a fixed set of points, answering nearest-neighbour
/// queries with indices into that set.
pub(super) struct Neighbours<'a> {
    points: &'a [[f64; 3]],
    tree: ImmutableKdTree<f64, u32, 3, 32>,
}

impl<'a> Neighbours<'a> {
    /// Build the tree over `points`.
    pub(super) fn new(points: &'a [[f64; 3]]) -> Self {
        Neighbours {
            points,
            tree: ImmutableKdTree::new_from_slice(points),
        }
    }

    /// The points the tree holds.
    pub(super) fn points(&self) -> &'a [[f64; 3]] {
        self.points
    }

    /// The `k` points nearest to `q` as `(index, distance)`, nearest
    /// first (fewer when the set is smaller).
    pub(super) fn nearest(&self, q: [f64; 3], k: usize) -> Vec<(usize, f64)> {
        let Some(k) = NonZero::new(k.min(self.points.len())) else {
            return Vec::new();
        };
        self.tree
            .nearest_n::<SquaredEuclidean>(&q, k)
            .into_iter()
            .map(|n| (n.item as usize, n.distance.sqrt()))
            .collect()
    }

    /// The `k` nearest other points of point `i` (itself left out, also
    /// when another point shares its position), nearest first.
    pub(super) fn of_point(&self, i: usize, k: usize) -> Vec<(usize, f64)> {
        let mut found = self.nearest(self.points[i], k + 1);
        if let Some(at) = found.iter().position(|&(j, _)| j == i) {
            found.remove(at);
        }
        found.truncate(k);
        found
    }
}

/// The mean distance from each point to its `k` nearest other points: the
/// local sample spacing.
pub(super) fn mean_neighbour_distances(neighbours: &Neighbours, k: usize) -> Vec<f64> {
    use rayon::prelude::*;
    (0..neighbours.points().len())
        .into_par_iter()
        .map(|i| {
            let found = neighbours.of_point(i, k);
            if found.is_empty() {
                return 0.0;
            }
            found.iter().map(|&(_, d)| d).sum::<f64>() / found.len() as f64
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_other_points_leave_the_point_out() {
        let pts: Vec<[f64; 3]> = (0..10).map(|i| [i as f64, 0.0, 0.0]).collect();
        let nb = Neighbours::new(&pts);
        let found = nb.of_point(4, 2);
        let mut idx: Vec<usize> = found.iter().map(|f| f.0).collect();
        idx.sort();
        assert_eq!(idx, vec![3, 5]);
        assert!(found.iter().all(|f| (f.1 - 1.0).abs() < 1e-12));
        let spacing = mean_neighbour_distances(&nb, 2);
        assert!((spacing[0] - 1.5).abs() < 1e-12 && (spacing[5] - 1.0).abs() < 1e-12);
    }
}
