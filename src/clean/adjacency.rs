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
        // Sort (edge key, face) pairs; the key packs the two indices.
        let mut list: Vec<(u64, u32)> = Vec::with_capacity(faces.len() * 3);
        for (fi, f) in faces.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                list.push((((a.min(b) as u64) << 32) | a.max(b) as u64, fi as u32));
            }
        }
        list.sort_unstable();
        let mut out = EdgeFaces {
            edges: Vec::with_capacity(list.len() / 2 + 1),
            offsets: Vec::with_capacity(list.len() / 2 + 2),
            faces: Vec::with_capacity(list.len()),
        };
        for (i, &(key, f)) in list.iter().enumerate() {
            if i == 0 || list[i - 1].0 != key {
                out.offsets.push(out.faces.len());
                out.edges.push(((key >> 32) as u32, key as u32));
            }
            out.faces.push(f);
        }
        out.offsets.push(out.faces.len());
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

/// A small multiplicative hasher (Fx-style) for integer keys: much faster
/// than SipHash for the grid and edge maps, and seedless, so deterministic.
#[derive(Debug, Clone, Copy, Default)]
pub struct FxHasher {
    hash: u64,
}

impl std::hash::Hasher for FxHasher {
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut b = [0u8; 8];
            b[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(b));
        }
    }
    fn write_u64(&mut self, x: u64) {
        self.hash = (self.hash.rotate_left(5) ^ x).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_i64(&mut self, x: i64) {
        self.write_u64(x as u64);
    }
    fn write_u32(&mut self, x: u32) {
        self.write_u64(x as u64);
    }
    fn finish(&self) -> u64 {
        self.hash
    }
}

/// Hash map with [`FxHasher`]. Only ever used for lookups, never iterated
/// where order matters.
pub type FxHashMap<K, V> = std::collections::HashMap<K, V, std::hash::BuildHasherDefault<FxHasher>>;

/// Boundary loops of an oriented manifold mesh, each following its boundary
/// half-edges, in order of their smallest starting half-edge. Built from
/// sorted arrays (deterministic, no hashing).
pub fn boundary_loops_sorted(faces: &[[u32; 3]]) -> Vec<Vec<u32>> {
    let ef = EdgeFaces::new(faces);
    let mut half: Vec<(u32, u32)> = Vec::new();
    for e in 0..ef.len() {
        let fs = ef.faces_of(e);
        if fs.len() == 1 {
            let (a, b) = ef.edges[e];
            if has_directed_edge(faces[fs[0] as usize], a, b) {
                half.push((a, b));
            } else {
                half.push((b, a));
            }
        }
    }
    half.sort_unstable();
    let mut used = vec![false; half.len()];
    let mut loops = Vec::new();
    for s in 0..half.len() {
        if used[s] {
            continue;
        }
        let mut lp = Vec::new();
        let mut cur = s;
        loop {
            used[cur] = true;
            lp.push(half[cur].0);
            let to = half[cur].1;
            // First unused half-edge leaving `to`.
            let start = half.partition_point(|h| h.0 < to);
            let next = (start..half.len())
                .take_while(|&i| half[i].0 == to)
                .find(|&i| !used[i]);
            match next {
                Some(n) => cur = n,
                None => break,
            }
        }
        loops.push(lp);
    }
    loops
}

/// Euler characteristic V − E + F counting only referenced vertices.
pub fn euler_characteristic_sorted(num_vertices: usize, faces: &[[u32; 3]]) -> i64 {
    let mut used = vec![false; num_vertices];
    for f in faces {
        for &v in f {
            if let Some(u) = used.get_mut(v as usize) {
                *u = true;
            }
        }
    }
    let v = used.iter().filter(|&&u| u).count() as i64;
    v - EdgeFaces::new(faces).len() as i64 + faces.len() as i64
}
