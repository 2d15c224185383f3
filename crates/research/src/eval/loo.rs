//! Leave-one-out nearest-neighbour classification.

use morphoid_data::table::DistanceMatrix;
use morphoid_data::table::Labels;
use serde::Serialize;

/// Score at one rank.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct RankScore {
    /// The rank.
    pub rank: String,
    /// Specimens whose nearest labelled neighbour has their own value.
    pub correct: usize,
    /// Specimens known at this rank that were classified.
    pub total: usize,
}

impl RankScore {
    /// The share of correct classifications in percent (0 when none).
    pub fn percent(&self) -> f64 {
        if self.total == 0 {
            0.0
        } else {
            100.0 * self.correct as f64 / self.total as f64
        }
    }
}

/// For each rank: classify every specimen known at that rank by its nearest
/// other specimen known at that rank (ties: first in matrix order), and
/// count the correct ones. Specimens absent from the labels are unknown.
pub fn leave_one_out(matrix: &DistanceMatrix, labels: &Labels, ranks: &[String]) -> Vec<RankScore> {
    ranks
        .iter()
        .map(|rank| {
            let known: Vec<Option<&str>> =
                matrix.names().iter().map(|n| labels.get(n, rank)).collect();
            let mut correct = 0;
            let mut total = 0;
            for (i, vi) in known.iter().enumerate() {
                let Some(vi) = vi else { continue };
                let mut best: Option<(f64, usize)> = None;
                for (j, vj) in known.iter().enumerate() {
                    if j == i || vj.is_none() {
                        continue;
                    }
                    let d = matrix.get(i, j);
                    if !d.is_finite() {
                        continue;
                    }
                    if best.is_none_or(|(bd, _)| d < bd) {
                        best = Some((d, j));
                    }
                }
                if let Some((_, j)) = best {
                    total += 1;
                    if known[j] == Some(*vi) {
                        correct += 1;
                    }
                }
            }
            RankScore {
                rank: rank.clone(),
                correct,
                total,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn counts_nearest_neighbours_and_skips_unknowns() {
        let names: Vec<String> = ["a", "b", "c", "d"].iter().map(|s| s.to_string()).collect();
        // a–b close, c–d close; d's genus unknown.
        let v = vec![
            vec![0.0, 1.0, 5.0, 6.0],
            vec![1.0, 0.0, 5.5, 6.5],
            vec![5.0, 5.5, 0.0, 0.5],
            vec![6.0, 6.5, 0.5, 0.0],
        ];
        let m = DistanceMatrix::new(names, v).unwrap();
        let l = Labels::parse(
            "name,order,genus\na,X,G\nb,X,G\nc,X,H\nd,Y,NA\n",
            None,
            Path::new("l"),
        )
        .unwrap();
        let r = leave_one_out(&m, &l, l.ranks());
        // order: a→b ok, b→a ok, c→d (Y≠X) wrong, d→c wrong.
        assert_eq!(
            r[0],
            RankScore {
                rank: "order".into(),
                correct: 2,
                total: 4
            }
        );
        // genus: d skipped as specimen and reference; c→a (H≠G) wrong.
        assert_eq!(
            r[1],
            RankScore {
                rank: "genus".into(),
                correct: 2,
                total: 3
            }
        );
    }
}
