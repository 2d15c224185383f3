//! Entropic optimal transport (Sinkhorn's matrix scaling): the cheap,
//! approximate transport cost that ranks the candidate maps before the
//! exact solver sees the best few.

/// The transport cost `Σ πᵢⱼ cᵢⱼ` of the entropic plan
/// `π = diag(x) exp(−c/ε) diag(y)` whose marginals are `rows` and
/// `columns` (each of total 1), after `iterations` scaling sweeps, with
/// `ε = epsilon · mean(c)`. An upper-bound-like estimate of the exact
/// cost that keeps the ranking of maps; `f64::MAX` if the scaling breaks
/// down (no finite plan).
pub(super) fn entropic_transport_cost(
    rows: &[f64],
    columns: &[f64],
    cost: &[f64],
    epsilon: f64,
    iterations: usize,
) -> f64 {
    let (n, m) = (rows.len(), columns.len());
    if n == 0 || m == 0 || cost.len() != n * m {
        return f64::MAX;
    }
    let mean = cost.iter().sum::<f64>() / cost.len() as f64;
    let eps = (epsilon * mean).max(1e-12);
    // Each row's kernel is taken relative to the row's smallest cost, so
    // that no row underflows; the row scaling absorbs the factor.
    let mut kernel = Vec::with_capacity(n * m);
    for row in cost.chunks_exact(m) {
        let low = row.iter().copied().fold(f64::INFINITY, f64::min);
        kernel.extend(row.iter().map(|&c| (-(c - low) / eps).exp()));
    }
    let mut x = vec![1.0; n];
    let mut y = vec![1.0; m];
    let mut ky = vec![0.0; n];
    let mut kx = vec![0.0; m];
    for _ in 0..iterations.max(1) {
        for (i, row) in kernel.chunks_exact(m).enumerate() {
            let s: f64 = row.iter().zip(&y).map(|(k, y)| k * y).sum();
            ky[i] = s;
            x[i] = if s > 0.0 { rows[i] / s } else { 0.0 };
        }
        kx.fill(0.0);
        for (row, &xi) in kernel.chunks_exact(m).zip(&x) {
            for (acc, k) in kx.iter_mut().zip(row) {
                *acc += k * xi;
            }
        }
        for (yj, (&s, &b)) in y.iter_mut().zip(kx.iter().zip(columns)) {
            *yj = if s > 0.0 { b / s } else { 0.0 };
        }
    }
    let mut total = 0.0;
    for ((krow, crow), &xi) in kernel.chunks_exact(m).zip(cost.chunks_exact(m)).zip(&x) {
        total += xi
            * krow
                .iter()
                .zip(crow)
                .zip(&y)
                .map(|((k, c), yj)| k * c * yj)
                .sum::<f64>();
    }
    if total.is_finite() {
        total
    } else {
        f64::MAX
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cwn::optimal_transport;

    #[test]
    fn identical_points_cost_little_and_the_estimate_is_near_the_exact_cost() {
        let pts: Vec<f64> = (0..12).map(|k| k as f64 / 11.0).collect();
        let masses = vec![1.0 / 12.0; 12];
        let cost_of = |shift: f64| -> Vec<f64> {
            pts.iter()
                .flat_map(|&a| pts.iter().map(move |&b| (a + shift - b).abs()))
                .collect()
        };
        let same = entropic_transport_cost(&masses, &masses, &cost_of(0.0), 0.01, 200);
        assert!(same < 0.01, "{same}");
        let c = cost_of(0.3);
        let exact = optimal_transport(&masses, &masses, &c).unwrap().cost;
        let approx = entropic_transport_cost(&masses, &masses, &c, 0.01, 200);
        assert!((approx - exact).abs() < 0.05 * exact, "{approx} vs {exact}");
    }
}
