//! Minimum spanning tree of a distance matrix and paths in it, to
//! propagate landmarks through a chain of similar specimens.

/// The edges `(i, j)`, `i < j`, of a minimum spanning tree (a forest when
/// some distances are not finite) of the complete graph whose edge weights
/// are `d[i][j]` (Prim's algorithm, O(n²), deterministic: ties go to the
/// lower index). Missing or non-finite entries count as no edge.
pub fn minimum_spanning_tree(d: &[Vec<f64>]) -> Vec<(usize, usize)> {
    let n = d.len();
    let weight = |i: usize, j: usize| {
        let a = d.get(i).and_then(|r| r.get(j)).copied();
        let b = d.get(j).and_then(|r| r.get(i)).copied();
        // Symmetrize: the smaller finite value of the two directions.
        match (a.filter(|x| x.is_finite()), b.filter(|x| x.is_finite())) {
            (Some(x), Some(y)) => Some(x.min(y)),
            (x, y) => x.or(y),
        }
    };
    let mut in_tree = vec![false; n];
    let mut best: Vec<Option<(f64, usize)>> = vec![None; n];
    let mut edges = Vec::with_capacity(n.saturating_sub(1));
    for root in 0..n {
        if in_tree[root] {
            continue;
        }
        // Grow one component of the forest from `root`.
        let mut next = Some(root);
        while let Some(u) = next {
            in_tree[u] = true;
            if let Some((_, parent)) = best[u] {
                edges.push((parent.min(u), parent.max(u)));
            }
            next = None;
            let mut next_w = f64::INFINITY;
            for v in 0..n {
                if in_tree[v] {
                    continue;
                }
                if let Some(w) = weight(u, v) {
                    if best[v].is_none_or(|(bw, _)| w < bw) {
                        best[v] = Some((w, u));
                    }
                }
                if let Some((w, _)) = best[v] {
                    if w < next_w {
                        next_w = w;
                        next = Some(v);
                    }
                }
            }
        }
    }
    edges
}

/// The path from `from` to `to` in the tree (or forest) with `edges` over
/// `n` nodes, both ends included; `None` when they are not connected.
pub(crate) fn tree_path(
    n: usize,
    edges: &[(usize, usize)],
    from: usize,
    to: usize,
) -> Option<Vec<usize>> {
    if from >= n || to >= n {
        return None;
    }
    let mut adjacency = vec![Vec::new(); n];
    for &(a, b) in edges {
        if a < n && b < n {
            adjacency[a].push(b);
            adjacency[b].push(a);
        }
    }
    // Breadth-first search from `from`, then follow the parents back.
    let mut parent = vec![usize::MAX; n];
    parent[from] = from;
    let mut queue = std::collections::VecDeque::from([from]);
    while let Some(u) = queue.pop_front() {
        if u == to {
            break;
        }
        for &v in &adjacency[u] {
            if parent[v] == usize::MAX {
                parent[v] = u;
                queue.push_back(v);
            }
        }
    }
    if parent[to] == usize::MAX {
        return None;
    }
    let mut path = vec![to];
    let mut u = to;
    while u != from {
        u = parent[u];
        path.push(u);
    }
    path.reverse();
    Some(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Total weight of the lightest spanning tree by brute force over all
    /// edge subsets of size n − 1 that connect the graph (small n only).
    fn brute_force_weight(d: &[Vec<f64>]) -> f64 {
        let n = d.len();
        let all: Vec<(usize, usize)> = (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .collect();
        let mut best = f64::INFINITY;
        for mask in 0u32..(1 << all.len()) {
            if mask.count_ones() as usize != n - 1 {
                continue;
            }
            let chosen: Vec<_> = (0..all.len())
                .filter(|k| mask & (1 << k) != 0)
                .map(|k| all[k])
                .collect();
            if (1..n).all(|t| tree_path(n, &chosen, 0, t).is_some()) {
                best = best.min(chosen.iter().map(|&(i, j)| d[i][j]).sum());
            }
        }
        best
    }

    #[test]
    fn prim_matches_brute_force() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..20 {
            let n = 5;
            let upper: Vec<f64> = (0..n * n).map(|_| rng.gen()).collect();
            let d: Vec<Vec<f64>> = (0..n)
                .map(|i| {
                    (0..n)
                        .map(|j| match i.cmp(&j) {
                            std::cmp::Ordering::Less => upper[i * n + j],
                            std::cmp::Ordering::Greater => upper[j * n + i],
                            std::cmp::Ordering::Equal => 0.0,
                        })
                        .collect()
                })
                .collect();
            let t = minimum_spanning_tree(&d);
            assert_eq!(t.len(), n - 1);
            let w: f64 = t.iter().map(|&(i, j)| d[i][j]).sum();
            assert!((w - brute_force_weight(&d)).abs() < 1e-12);
        }
    }

    #[test]
    fn chain_path_and_forest() {
        // Points on a line: the tree is the chain 0-1-2-3.
        let x: [f64; 4] = [0.0, 1.0, 2.5, 4.0];
        let d: Vec<Vec<f64>> = x
            .iter()
            .map(|a| x.iter().map(|b| (a - b).abs()).collect())
            .collect();
        let t = minimum_spanning_tree(&d);
        assert_eq!(tree_path(4, &t, 0, 3), Some(vec![0, 1, 2, 3]));
        assert_eq!(tree_path(4, &t, 2, 2), Some(vec![2]));
        // Node 3 unreachable: infinite distances split the forest.
        let mut d2 = d.clone();
        for (i, row) in d2.iter_mut().enumerate() {
            row[3] = if i == 3 { 0.0 } else { f64::INFINITY };
        }
        d2[3] = vec![f64::NAN, f64::NAN, f64::NAN, 0.0];
        let t2 = minimum_spanning_tree(&d2);
        assert_eq!(t2.len(), 2);
        assert_eq!(tree_path(4, &t2, 0, 3), None);
        assert_eq!(tree_path(4, &t2, 0, 9), None);
    }
}
