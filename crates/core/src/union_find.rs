//! Disjoint sets (union–find), for grouping vertices, faces, corners and
//! runs of voxels.

/// Disjoint-set forest with path halving and union by index (the smaller
/// index becomes the root, which keeps labels deterministic).
#[derive(Debug, Clone)]
pub(crate) struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    /// `n` singleton sets.
    pub(crate) fn new(n: usize) -> Self {
        Self {
            parent: (0..n as u32).collect(),
        }
    }

    /// A new singleton set; its element.
    pub(crate) fn add(&mut self) -> u32 {
        let x = self.parent.len() as u32;
        self.parent.push(x);
        x
    }

    /// Representative of `x`'s set.
    pub(crate) fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let gp = self.parent[self.parent[x as usize] as usize];
            self.parent[x as usize] = gp;
            x = gp;
        }
        x
    }

    /// Each element's set, numbered 0, 1, … in the order of the sets'
    /// smallest elements (a set's root is its smallest element), and the
    /// number of sets.
    pub(crate) fn numbered_sets(mut self) -> (Vec<u32>, usize) {
        for x in 0..self.parent.len() as u32 {
            self.parent[x as usize] = self.find(x);
        }
        // Roots come before the rest of their sets: each is numbered
        // before its members read the number.
        let mut count = 0;
        for x in 0..self.parent.len() {
            let root = self.parent[x] as usize;
            self.parent[x] = if root == x {
                count += 1;
                count - 1
            } else {
                self.parent[root]
            };
        }
        (self.parent, count as usize)
    }

    /// Merge the sets of `a` and `b`.
    pub(crate) fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = (ra.min(rb), ra.max(rb));
            self.parent[hi as usize] = lo;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_are_numbered_in_the_order_of_their_smallest_elements() {
        // Sets {0, 4}, {1, 2, 5}, {3}, {6}, joined in no particular order
        // and grown by `add`.
        let mut sets = UnionFind::new(4);
        assert_eq!((sets.add(), sets.add(), sets.add()), (4, 5, 6));
        sets.union(5, 2);
        sets.union(4, 0);
        sets.union(1, 5);
        let (numbers, count) = sets.numbered_sets();
        assert_eq!(count, 4);
        assert_eq!(numbers, vec![0, 1, 1, 2, 0, 1, 3]);
    }
}
