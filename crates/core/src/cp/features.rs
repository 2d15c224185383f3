//! Feature points: local maxima of the smoothed hyperbolic conformal
//! density (on a tooth, the cusps).

/// `iterations` steps of area-weighted averaging over the closed one-ring.
pub(super) fn smooth_vertex_function(
    adjacency: &[Vec<u32>],
    areas: &[f64],
    values: &[f64],
    iterations: usize,
) -> Vec<f64> {
    let mut cur = values.to_vec();
    for _ in 0..iterations {
        let next: Vec<f64> = (0..cur.len())
            .map(|i| {
                let mut s = areas[i] * cur[i];
                let mut w = areas[i];
                for &j in &adjacency[i] {
                    s += areas[j as usize] * cur[j as usize];
                    w += areas[j as usize];
                }
                if w > 0.0 {
                    s / w
                } else {
                    cur[i]
                }
            })
            .collect();
        cur = next;
    }
    cur
}

/// Local maxima of `values` over `rings`-ring neighbourhoods, among the
/// vertices where `eligible` holds, strongest first (ties: smaller index),
/// at most `max_count`, no two closer than `min_separation` by `distance`.
pub(super) fn local_maxima(
    adjacency: &[Vec<u32>],
    values: &[f64],
    eligible: &[bool],
    max_count: usize,
    min_separation: f64,
    distance: impl Fn(u32, u32) -> f64,
) -> Vec<u32> {
    let mut cands: Vec<u32> = (0..values.len() as u32)
        .filter(|&i| {
            let v = values[i as usize];
            eligible[i as usize]
                && adjacency[i as usize].iter().all(|&j| {
                    let w = values[j as usize];
                    v > w || (v == w && i < j)
                })
        })
        .collect();
    cands.sort_by(|&a, &b| {
        values[b as usize]
            .total_cmp(&values[a as usize])
            .then(a.cmp(&b))
    });
    let mut out: Vec<u32> = Vec::new();
    for c in cands {
        if out.len() >= max_count {
            break;
        }
        if out.iter().all(|&o| distance(o, c) >= min_separation) {
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maxima_are_found_strongest_first_and_separated() {
        // A path graph 0-1-2-3-4-5-6 with peaks at 1 and 5.
        let adj: Vec<Vec<u32>> = (0..7u32)
            .map(|i| {
                let mut v = Vec::new();
                if i > 0 {
                    v.push(i - 1);
                }
                if i < 6 {
                    v.push(i + 1);
                }
                v
            })
            .collect();
        let vals = [0.0, 2.0, 1.0, 0.5, 1.0, 3.0, 0.0];
        let elig = [true; 7];
        let m = local_maxima(&adj, &vals, &elig, 5, 0.0, |a, b| {
            (a as f64 - b as f64).abs()
        });
        assert_eq!(m, vec![5, 1]);
        let m = local_maxima(&adj, &vals, &elig, 5, 5.0, |a, b| {
            (a as f64 - b as f64).abs()
        });
        assert_eq!(m, vec![5]);
        let m = local_maxima(&adj, &vals, &elig, 1, 0.0, |a, b| {
            (a as f64 - b as f64).abs()
        });
        assert_eq!(m, vec![5]);
    }
}
