//! Farthest-point sampling, whatever the distance: along a surface's edges
//! (the comparison's samples) or straight through space (a collection's
//! pseudolandmarks).

/// Up to `count` of `len` points in farthest-point order: first `seeds`
/// (out of range or repeated ones passed over; point 0 when none is
/// usable), then again and again the point farthest from its nearest pick
/// (the lowest index on ties), until `count` are picked or every point
/// left lies at distance 0 from a pick. Infinite and NaN distances (points
/// no pick reaches) are never taken.
///
/// `relax(i, p, nearest)` is told that point `p` is the `i`-th pick and
/// lowers `nearest[q]` to the distance from `q` to `p` wherever that is
/// smaller, `nearest[p]` to 0 included; `nearest` starts infinite. The
/// distance is the caller's, and so is anything it gathers on the way
/// (which pick is nearest to each point, say).
pub fn farthest_point_order(
    len: usize,
    seeds: &[usize],
    count: usize,
    mut relax: impl FnMut(usize, usize, &mut [f64]),
) -> Vec<usize> {
    let count = count.min(len);
    let mut nearest = vec![f64::INFINITY; len];
    let mut chosen: Vec<usize> = Vec::new();
    let mut pick = |p: usize, chosen: &mut Vec<usize>, nearest: &mut [f64]| {
        chosen.push(p);
        relax(chosen.len() - 1, p, nearest);
    };
    for &s in seeds {
        if chosen.len() >= count {
            break;
        }
        if s < len && !chosen.contains(&s) {
            pick(s, &mut chosen, &mut nearest);
        }
    }
    if chosen.is_empty() && count > 0 {
        pick(0, &mut chosen, &mut nearest);
    }
    while chosen.len() < count {
        let mut best: Option<(f64, usize)> = None;
        for (i, &d) in nearest.iter().enumerate() {
            if d.is_finite() && best.is_none_or(|(bd, _)| d > bd) {
                best = Some((d, i));
            }
        }
        match best {
            // A farthest point at distance 0 is a pick again: no new point
            // is left.
            Some((d, i)) if d > 0.0 => pick(i, &mut chosen, &mut nearest),
            _ => break,
        }
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance along a line of points at `xs`.
    fn on_line(xs: &[f64]) -> impl FnMut(usize, usize, &mut [f64]) + '_ {
        |_, p, nearest| {
            for (q, x) in xs.iter().enumerate() {
                nearest[q] = nearest[q].min((x - xs[p]).abs());
            }
        }
    }

    #[test]
    fn picks_bisect_a_line_from_the_seed() {
        let xs: Vec<f64> = (0..=8).map(f64::from).collect();
        assert_eq!(
            farthest_point_order(9, &[4], 5, on_line(&xs)),
            vec![4, 0, 8, 2, 6]
        );
        assert_eq!(farthest_point_order(9, &[4], 50, on_line(&xs)).len(), 9);
        // No usable seed: point 0 first.
        assert_eq!(
            farthest_point_order(9, &[9, 40], 2, on_line(&xs)),
            vec![0, 8]
        );
        assert!(farthest_point_order(0, &[0], 3, on_line(&[])).is_empty());
        assert!(farthest_point_order(9, &[4], 0, on_line(&xs)).is_empty());
    }

    #[test]
    fn coincident_points_are_not_picked_twice() {
        let xs = [0.0, 0.0, 1.0, 1.0];
        assert_eq!(farthest_point_order(4, &[0], 4, on_line(&xs)), vec![0, 2]);
    }
}
