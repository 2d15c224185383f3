//! Deterministic edge–face incidence built from a sorted list (no hash-map
//! iteration, so every step that walks edges is reproducible bit for bit).

/// Undirected edges `(a, b)` with `a < b`, each with the faces that contain
/// it, in increasing face order.
#[derive(Debug, Clone, Default)]
pub struct EdgeFaces {
    /// The distinct undirected edges, sorted.
    pub edges: Vec<(u32, u32)>,
    /// `faces[offsets[e]..offsets[e + 1]]` are the faces of edge `e`.
    pub offsets: Vec<usize>,
    /// Face indices grouped by edge.
    pub faces: Vec<u32>,
}

impl EdgeFaces {
    /// Build the incidence of `faces` (repeated-index faces contribute their
    /// degenerate edges too; callers remove them first).
    pub fn new(faces: &[[u32; 3]]) -> Self {
        let mut list: Vec<(u32, u32, u32)> = Vec::with_capacity(faces.len() * 3);
        for (fi, f) in faces.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                list.push((a.min(b), a.max(b), fi as u32));
            }
        }
        list.sort_unstable();
        let mut out = EdgeFaces {
            edges: Vec::new(),
            offsets: vec![0],
            faces: Vec::with_capacity(list.len()),
        };
        for (i, &(a, b, f)) in list.iter().enumerate() {
            if i > 0 && (list[i - 1].0, list[i - 1].1) != (a, b) {
                out.offsets.push(out.faces.len());
            }
            if i == 0 || (list[i - 1].0, list[i - 1].1) != (a, b) {
                out.edges.push((a, b));
            }
            out.faces.push(f);
        }
        if !list.is_empty() {
            out.offsets.push(out.faces.len());
        }
        out
    }

    /// Number of distinct edges.
    pub fn len(&self) -> usize {
        self.edges.len()
    }

    /// True when there are no edges.
    pub fn is_empty(&self) -> bool {
        self.edges.is_empty()
    }

    /// Faces incident to edge number `e`.
    pub fn faces_of(&self, e: usize) -> &[u32] {
        &self.faces[self.offsets[e]..self.offsets[e + 1]]
    }

    /// Index of the edge `a`–`b`, if present.
    pub fn find(&self, a: u32, b: u32) -> Option<usize> {
        self.edges.binary_search(&(a.min(b), a.max(b))).ok()
    }
}

/// True when face `f` traverses the directed edge `a → b`.
#[inline]
pub fn has_directed_edge(f: [u32; 3], a: u32, b: u32) -> bool {
    (0..3).any(|k| f[k] == a && f[(k + 1) % 3] == b)
}

/// Disjoint-set forest with path halving and union by index (the smaller
/// index becomes the root, which keeps labels deterministic).
#[derive(Debug, Clone)]
pub struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    /// `n` singleton sets.
    pub fn new(n: usize) -> Self {
        Self {
            parent: (0..n as u32).collect(),
        }
    }

    /// Representative of `x`'s set.
    pub fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let gp = self.parent[self.parent[x as usize] as usize];
            self.parent[x as usize] = gp;
            x = gp;
        }
        x
    }

    /// Merge the sets of `a` and `b`.
    pub fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = (ra.min(rb), ra.max(rb));
            self.parent[hi as usize] = lo;
        }
    }
}
