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

    /// How many elements the sets hold.
    pub(crate) fn len(&self) -> usize {
        self.parent.len()
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

    /// Merge the sets of `a` and `b`.
    pub(crate) fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = (ra.min(rb), ra.max(rb));
            self.parent[hi as usize] = lo;
        }
    }
}
