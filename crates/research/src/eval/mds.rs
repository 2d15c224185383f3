//! Classical (Torgerson) multidimensional scaling of a distance matrix.

use morphoid_data::table::DistanceMatrix;
use nalgebra::DMatrix;

/// Coordinates whose Euclidean distances approximate a matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct Mds {
    /// `coordinates[i][k]`: specimen `i` on axis `k`.
    pub coordinates: Vec<Vec<f64>>,
    /// The eigenvalue of each axis, largest first (positive only).
    pub eigenvalues: Vec<f64>,
}

/// Classical MDS of `m` into at most `dimensions` axes: the doubly centred
/// matrix of squared distances `B = −½ J D² J`, its largest positive
/// eigenvalues `λ` and eigenvectors `u`, coordinates `u √λ`. Each axis's
/// sign makes its largest-magnitude coordinate positive. Non-finite
/// distances count as 0.
pub fn classical_mds(m: &DistanceMatrix, dimensions: usize) -> Mds {
    let n = m.names().len();
    if n == 0 {
        return Mds {
            coordinates: Vec::new(),
            eigenvalues: Vec::new(),
        };
    }
    let d2 = DMatrix::from_fn(n, n, |i, j| {
        let v = 0.5 * (m.get(i, j) + m.get(j, i));
        if v.is_finite() {
            v * v
        } else {
            0.0
        }
    });
    let row_mean: Vec<f64> = (0..n).map(|i| d2.row(i).sum() / n as f64).collect();
    let all_mean = row_mean.iter().sum::<f64>() / n as f64;
    let b = DMatrix::from_fn(n, n, |i, j| {
        -0.5 * (d2[(i, j)] - row_mean[i] - row_mean[j] + all_mean)
    });
    let eig = b.symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &c| eig.eigenvalues[c].total_cmp(&eig.eigenvalues[a]));
    let top = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
    let mut coordinates = vec![Vec::new(); n];
    let mut eigenvalues = Vec::new();
    for &k in order.iter().take(dimensions) {
        let lambda = eig.eigenvalues[k];
        if lambda.partial_cmp(&(1e-12 * top)) != Some(std::cmp::Ordering::Greater) {
            break;
        }
        let u = eig.eigenvectors.column(k);
        let mut largest = 0;
        for i in 0..n {
            if u[i].abs() > u[largest].abs() {
                largest = i;
            }
        }
        let sign = if u[largest] < 0.0 { -1.0 } else { 1.0 };
        for (i, c) in coordinates.iter_mut().enumerate() {
            c.push(sign * u[i] * lambda.sqrt());
        }
        eigenvalues.push(lambda);
    }
    Mds {
        coordinates,
        eigenvalues,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planar_points_are_recovered_up_to_motion() {
        let pts = [[0.0, 0.0], [3.0, 0.0], [0.0, 4.0], [1.0, 1.0], [2.0, 5.0]];
        let dist =
            |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
        let m = DistanceMatrix::new(
            (0..5).map(|i| i.to_string()).collect(),
            pts.iter()
                .map(|&a| pts.iter().map(|&b| dist(a, b)).collect())
                .collect(),
        )
        .unwrap();
        let mds = classical_mds(&m, 5);
        assert_eq!(mds.eigenvalues.len(), 2);
        for i in 0..5 {
            for j in 0..5 {
                let c = &mds.coordinates;
                let d = ((c[i][0] - c[j][0]).powi(2) + (c[i][1] - c[j][1]).powi(2)).sqrt();
                assert!((d - m.values()[i][j]).abs() < 1e-9);
            }
        }
    }
}
