//! Principal component analysis of Procrustes coordinates.

use nalgebra::DMatrix;

/// Principal components of a set of configurations.
#[derive(Debug, Clone, PartialEq)]
pub struct Pca {
    /// `scores[i][k]`: the score of specimen `i` on component `k`.
    pub scores: Vec<Vec<f64>>,
    /// Variance along each component (sample variance, `n − 1`),
    /// largest first.
    pub variances: Vec<f64>,
}

impl Pca {
    /// The share of the total variance of each component, in percent.
    pub fn percent_explained(&self) -> Vec<f64> {
        let total: f64 = self.variances.iter().sum();
        self.variances
            .iter()
            .map(|v| if total > 0.0 { 100.0 * v / total } else { 0.0 })
            .collect()
    }
}

/// The principal components of `configurations` (each flattened to
/// `x1, y1, z1, x2, …`), through the eigen-decomposition of the `n × n`
/// Gram matrix of the centred data (n specimens is far fewer than 3k
/// coordinates). Components with no variance are left out; at most
/// `n − 1` remain. Each component's sign makes its largest coefficient
/// (loading) positive, so the output does not depend on the eigensolver.
pub(crate) fn principal_components(configurations: &[Vec<[f64; 3]>]) -> Pca {
    let n = configurations.len();
    let p = configurations.first().map_or(0, |c| 3 * c.len());
    if n < 2 || p == 0 || configurations.iter().any(|c| 3 * c.len() != p) {
        return Pca {
            scores: vec![Vec::new(); n],
            variances: Vec::new(),
        };
    }
    let x = DMatrix::from_fn(n, p, |i, j| configurations[i][j / 3][j % 3]);
    let mean = x.row_mean();
    let xc = DMatrix::from_fn(n, p, |i, j| x[(i, j)] - mean[j]);
    let gram = &xc * xc.transpose();
    let eig = gram.symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let top = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
    let mut scores = vec![Vec::new(); n];
    let mut variances = Vec::new();
    for &k in order.iter().take(n - 1) {
        let lambda = eig.eigenvalues[k];
        if lambda.partial_cmp(&(1e-12 * top)) != Some(std::cmp::Ordering::Greater) {
            break;
        }
        let u = eig.eigenvectors.column(k);
        // Loadings: the unit direction in coordinate space.
        let loading = xc.transpose() * u / lambda.sqrt();
        let mut largest = 0;
        for j in 0..p {
            if loading[j].abs() > loading[largest].abs() {
                largest = j;
            }
        }
        let sign = if loading[largest] < 0.0 { -1.0 } else { 1.0 };
        for (i, s) in scores.iter_mut().enumerate() {
            s.push(sign * u[i] * lambda.sqrt());
        }
        variances.push(lambda / (n - 1) as f64);
    }
    Pca { scores, variances }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_along_a_direction_have_one_component() {
        // Landmark 0 moves along x by t; everything else is fixed.
        let configs: Vec<Vec<[f64; 3]>> = [-2.0, -1.0, 0.0, 1.0, 2.0]
            .iter()
            .map(|&t| vec![[t, 0.0, 0.0], [0.0, 1.0, 0.0]])
            .collect();
        let pca = principal_components(&configs);
        assert_eq!(pca.variances.len(), 1);
        assert!((pca.variances[0] - 2.5).abs() < 1e-12);
        assert!((pca.percent_explained()[0] - 100.0).abs() < 1e-12);
        let s: Vec<f64> = pca.scores.iter().map(|r| r[0]).collect();
        for (got, want) in s.iter().zip([-2.0, -1.0, 0.0, 1.0, 2.0]) {
            assert!((got - want).abs() < 1e-12, "{s:?}");
        }
    }

    #[test]
    fn two_components_are_ordered_and_uncorrelated() {
        let configs: Vec<Vec<[f64; 3]>> = (0..8)
            .map(|i| {
                let a = (i as f64 * 0.7).sin() * 3.0;
                let b = (i as f64 * 1.3).cos();
                vec![[a, 0.0, 0.0], [0.0, b, 0.0], [1.0, 1.0, 1.0]]
            })
            .collect();
        let pca = principal_components(&configs);
        assert!(pca.variances[0] >= pca.variances[1]);
        let dot: f64 = pca.scores.iter().map(|r| r[0] * r[1]).sum();
        assert!(dot.abs() < 1e-9);
        let total: f64 = pca.percent_explained().iter().sum();
        assert!((total - 100.0).abs() < 1e-9);
    }
}
