//! Principal axes of a weighted point set: the one home of the
//! centroid-and-covariance computation that point clouds (local planes)
//! and whole teeth (the tooth's long axis) both need.

use super::cross;

/// The principal axes of a point set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrincipalAxes {
    /// Weighted mean of the points.
    pub centroid: [f64; 3],
    /// Axis of largest spread, second, and their cross product (the
    /// normal, least spread).
    pub axes: [[f64; 3]; 3],
    /// Weighted variances along the axes, in the same order.
    pub spreads: [f64; 3],
}

/// Principal axes of `points`, all of weight one (`None` for fewer than
/// three points).
pub fn principal_axes(points: &[[f64; 3]]) -> Option<PrincipalAxes> {
    weighted_principal_axes(points.iter().map(|&p| (p, 1.0)))
}

/// Principal axes of points given with their weights (`None` for fewer
/// than three points or no positive total weight).
pub(crate) fn weighted_principal_axes<I>(points: I) -> Option<PrincipalAxes>
where
    I: Iterator<Item = ([f64; 3], f64)> + Clone,
{
    let (count, total) = points
        .clone()
        .fold((0usize, 0.0), |(n, t), (_, w)| (n + 1, t + w));
    if count < 3 || total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let mut c = [0.0; 3];
    for (p, w) in points.clone() {
        for d in 0..3 {
            c[d] += p[d] * w / total;
        }
    }
    let mut cov = nalgebra::Matrix3::<f64>::zeros();
    for (p, w) in points {
        let q = nalgebra::Vector3::new(p[0] - c[0], p[1] - c[1], p[2] - c[2]);
        // `(qqᵀ·w)/total`: for unit weights exactly the mean of qqᵀ.
        cov += q * q.transpose() * w / total;
    }
    let eig = nalgebra::SymmetricEigen::new(cov);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let axis = |k: usize| {
        let col = eig.eigenvectors.column(order[k]);
        [col[0], col[1], col[2]]
    };
    let (u, v) = (axis(0), axis(1));
    Some(PrincipalAxes {
        centroid: c,
        axes: [u, v, cross(u, v)],
        spreads: order.map(|k| eig.eigenvalues[k].max(0.0)),
    })
}
