//! The average-linkage (UPGMA) tree of a distance matrix, as Newick text
//! and as a dendrogram picture (SVG).

use morphoid_data::present::escape;
use morphoid_data::table::DistanceMatrix;

/// A binary tree from hierarchical clustering: leaves are specimens,
/// every inner node a merge at a height (half the average distance
/// between its two clusters, so the tree is ultrametric).
#[derive(Debug, Clone, PartialEq)]
pub enum Dendrogram {
    /// A specimen (its index).
    Leaf(usize),
    /// Two clusters merged at `height`.
    Merge {
        /// Half the average distance between the two clusters.
        height: f64,
        /// The two clusters (the one with the lower least index first).
        children: Box<[Dendrogram; 2]>,
    },
}

impl Dendrogram {
    /// The height of the node (0 for a leaf).
    pub fn height(&self) -> f64 {
        match self {
            Dendrogram::Leaf(_) => 0.0,
            Dendrogram::Merge { height, .. } => *height,
        }
    }

    /// The leaves in drawing order.
    pub fn leaves(&self) -> Vec<usize> {
        let mut out = Vec::new();
        let mut stack = vec![self];
        while let Some(t) = stack.pop() {
            match t {
                Dendrogram::Leaf(i) => out.push(*i),
                Dendrogram::Merge { children, .. } => {
                    stack.push(&children[1]);
                    stack.push(&children[0]);
                }
            }
        }
        out
    }

    fn min_leaf(&self) -> usize {
        self.leaves().into_iter().min().unwrap_or(usize::MAX)
    }
}

/// One merge of average-linkage clustering. A cluster is known by the
/// lowest index among its specimens; after the merge it lives on as
/// `keep`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Merge {
    /// The surviving cluster (the lower index).
    pub(super) keep: usize,
    /// The cluster merged into it.
    pub(super) gone: usize,
    /// The average distance between the two clusters.
    pub(super) distance: f64,
}

/// The `n - 1` merges of the average-linkage (UPGMA) clustering of `m`
/// (symmetrized; non-finite distances count as the largest finite one).
/// Found by the nearest-neighbour chain algorithm, O(n²) time: merges come
/// in chain order, not by distance, but average linkage is reducible, so
/// the clusters are those of merging the closest pair first. Ties are
/// broken by index, so the result is deterministic.
pub(super) fn average_linkage_merges(m: &DistanceMatrix) -> Vec<Merge> {
    let n = m.len();
    let big = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .map(|(i, j)| m.get(i, j))
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let mut d: Vec<f64> = (0..n * n)
        .map(|k| {
            let (i, j) = (k / n, k % n);
            let v = 0.5 * (m.get(i, j) + m.get(j, i));
            if v.is_finite() {
                v
            } else {
                big
            }
        })
        .collect();
    let mut size = vec![1usize; n];
    let mut active = vec![true; n];
    let mut merges = Vec::with_capacity(n.saturating_sub(1));
    let mut chain: Vec<usize> = Vec::new();
    while merges.len() + 1 < n {
        if chain.is_empty() {
            if let Some(first) = active.iter().position(|&a| a) {
                chain.push(first);
            }
        }
        // Grow the chain until its last two clusters are each other's
        // nearest neighbours.
        let (a, b) = loop {
            let Some(&a) = chain.last() else { break (0, 0) };
            let prev = chain.len().checked_sub(2).map(|k| chain[k]);
            let mut best = prev;
            let mut best_d = prev.map_or(f64::INFINITY, |p| d[a * n + p]);
            for c in (0..n).filter(|&c| active[c] && c != a) {
                if best.is_none() || d[a * n + c] < best_d {
                    best = Some(c);
                    best_d = d[a * n + c];
                }
            }
            match best {
                Some(c) if Some(c) == prev => break (a, c),
                Some(c) => chain.push(c),
                None => break (a, a),
            }
        };
        if a == b {
            break;
        }
        chain.truncate(chain.len() - 2);
        let (keep, gone) = (a.min(b), a.max(b));
        merges.push(Merge {
            keep,
            gone,
            distance: d[keep * n + gone],
        });
        let (sk, sg) = (size[keep] as f64, size[gone] as f64);
        for c in (0..n).filter(|&c| active[c] && c != keep && c != gone) {
            let v = (sk * d[keep * n + c] + sg * d[gone * n + c]) / (sk + sg);
            d[keep * n + c] = v;
            d[c * n + keep] = v;
        }
        size[keep] += size[gone];
        active[gone] = false;
    }
    merges
}

/// The average-linkage tree of `m` (see [`average_linkage_merges`] for
/// how distances are read and ties broken), each merge at half the
/// average distance between its clusters. `None` for an empty matrix.
pub fn average_linkage_tree(m: &DistanceMatrix) -> Option<Dendrogram> {
    let mut clusters: Vec<Option<Dendrogram>> =
        (0..m.len()).map(|i| Some(Dendrogram::Leaf(i))).collect();
    for Merge {
        keep,
        gone,
        distance,
    } in average_linkage_merges(m)
    {
        let ta = clusters[keep].take()?;
        let tb = clusters[gone].take()?;
        let children = if ta.min_leaf() <= tb.min_leaf() {
            [ta, tb]
        } else {
            [tb, ta]
        };
        clusters[keep] = Some(Dendrogram::Merge {
            height: distance / 2.0,
            children: Box::new(children),
        });
    }
    clusters.into_iter().flatten().next()
}

/// A Newick label: bare when it has no special character, else quoted
/// with `'` (doubled inside).
fn newick_label(name: &str) -> String {
    if !name.is_empty() && !name.chars().any(|c| "()[]':;, \t\n\r".contains(c)) {
        name.to_string()
    } else {
        format!("'{}'", name.replace('\'', "''"))
    }
}

/// The tree as Newick text with branch lengths (the height differences),
/// leaves named by `names`; ends with `;` and a line break.
pub fn newick(tree: &Dendrogram, names: &[String]) -> String {
    fn node(t: &Dendrogram, parent: f64, names: &[String], out: &mut String) {
        match t {
            Dendrogram::Leaf(i) => {
                out.push_str(&newick_label(names.get(*i).map_or("", String::as_str)));
            }
            Dendrogram::Merge { children, .. } => {
                out.push('(');
                node(&children[0], t.height(), names, out);
                out.push(',');
                node(&children[1], t.height(), names, out);
                out.push(')');
            }
        }
        out.push_str(&format!(":{:?}", (parent - t.height()).max(0.0)));
    }
    let mut out = String::new();
    match tree {
        Dendrogram::Leaf(_) => node(tree, 0.0, names, &mut out),
        Dendrogram::Merge { children, .. } => {
            out.push('(');
            node(&children[0], tree.height(), names, &mut out);
            out.push(',');
            node(&children[1], tree.height(), names, &mut out);
            out.push(')');
        }
    }
    out.push_str(";\n");
    out
}

/// The tree drawn as an SVG dendrogram: leaves top to bottom with their
/// names (and group, when given) on the right, heights growing to the left.
pub fn dendrogram_svg(
    tree: &Dendrogram,
    names: &[String],
    groups: Option<&[Option<String>]>,
) -> String {
    let leaves = tree.leaves();
    let row = 14.0;
    let (left, top, width) = (20.0, 20.0, 520.0);
    let height = row * leaves.len() as f64;
    let max_h = tree.height().max(f64::MIN_POSITIVE);
    let mut pos = vec![0.0; names.len().max(leaves.iter().max().map_or(0, |m| m + 1))];
    for (k, &i) in leaves.iter().enumerate() {
        pos[i] = top + row * (k as f64 + 0.5);
    }
    let x = |h: f64| left + width * (1.0 - h / max_h);
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" font-family=\"sans-serif\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n",
        left + width + 260.0,
        height + 2.0 * top
    );
    // Returns the vertical position of the node.
    fn draw(t: &Dendrogram, pos: &[f64], x: &dyn Fn(f64) -> f64, s: &mut String) -> f64 {
        match t {
            Dendrogram::Leaf(i) => pos[*i],
            Dendrogram::Merge { children, height } => {
                let ys = [draw(&children[0], pos, x, s), draw(&children[1], pos, x, s)];
                for (c, y) in children.iter().zip(ys) {
                    s.push_str(&format!(
                        "<line x1=\"{:.2}\" y1=\"{y:.2}\" x2=\"{:.2}\" y2=\"{y:.2}\" stroke=\"black\"/>\n",
                        x(c.height()),
                        x(*height)
                    ));
                }
                s.push_str(&format!(
                    "<line x1=\"{0:.2}\" y1=\"{1:.2}\" x2=\"{0:.2}\" y2=\"{2:.2}\" stroke=\"black\"/>\n",
                    x(*height),
                    ys[0],
                    ys[1]
                ));
                0.5 * (ys[0] + ys[1])
            }
        }
    }
    draw(tree, &pos, &x, &mut s);
    for &i in &leaves {
        let mut label = names.get(i).cloned().unwrap_or_default();
        if let Some(g) = groups.and_then(|g| g.get(i)).and_then(|g| g.as_deref()) {
            label = format!("{label} ({g})");
        }
        s.push_str(&format!(
            "<text x=\"{}\" y=\"{:.2}\" dominant-baseline=\"middle\">{}</text>\n",
            left + width + 6.0,
            pos[i],
            escape(&label)
        ));
    }
    s.push_str("</svg>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line() -> DistanceMatrix {
        let x: [f64; 4] = [0.0, 1.0, 5.0, 5.5];
        DistanceMatrix::new(
            vec!["a".into(), "b c".into(), "d'e".into(), "f".into()],
            x.iter()
                .map(|p| x.iter().map(|q| (p - q).abs()).collect())
                .collect(),
        )
        .unwrap()
    }

    #[test]
    fn upgma_by_hand() {
        // a–b at 1, d–f at 0.5, then the two pairs at the mean of
        // 5, 5.5, 4, 4.5 = 4.75.
        let m = line();
        let t = average_linkage_tree(&m).unwrap();
        assert_eq!(t.leaves(), vec![0, 1, 2, 3]);
        assert!((t.height() - 4.75 / 2.0).abs() < 1e-12);
        let text = newick(&t, m.names());
        assert_eq!(
            text,
            "((a:0.5,'b c':0.5):1.875,('d''e':0.25,f:0.25):2.125);\n"
        );
        let svg = dendrogram_svg(&t, m.names(), None);
        assert_eq!(svg.matches("<text").count(), 4);
        assert!(average_linkage_tree(&DistanceMatrix::new(vec![], vec![]).unwrap()).is_none());
    }
}
