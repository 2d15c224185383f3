//! The surface through oriented samples: a signed distance to the
//! samples' tangent planes (Hoppe et al. 1992, blended over the nearest
//! samples), its zero set extracted by surface nets on a sparse grid near
//! the samples, and trimmed to where the samples are.

use super::neighbours::Neighbours;
use super::normals::LocalPlane;
use crate::mesh::{cross, dot, norm, sub, Mesh};
use crate::union_find::UnionFind;
use rayon::prelude::*;
use rustc_hash::{FxHashMap, FxHashSet};

/// Samples blended into the signed distance at a point.
const BLEND_NEIGHBOURS: usize = 8;
/// Samples whose centroid tells whether a point lies among the samples.
const TRIM_NEIGHBOURS: usize = 8;

/// Oriented samples of a surface: positions, tangent planes (consistently
/// oriented normals) and local spacing, all indexed alike.
pub(super) struct OrientedSamples<'a> {
    /// Nearest-neighbour queries over the sample positions.
    pub neighbours: &'a Neighbours<'a>,
    /// Tangent plane of each sample (through its neighbourhood's centroid).
    pub planes: &'a [LocalPlane],
    /// Mean distance of each sample to its neighbours.
    pub spacing: &'a [f64],
}

/// The signed distance from `x` to the surface and the surface's normal
/// direction there: the distances to the tangent planes of the nearest
/// samples, blended with Gaussian weights of width `width` (normalised to
/// the nearest sample, so far points do not underflow).
pub(super) fn signed_distance(
    samples: &OrientedSamples,
    x: [f64; 3],
    width: f64,
) -> (f64, [f64; 3]) {
    let near = samples.neighbours.nearest(x, BLEND_NEIGHBOURS);
    let d0 = near.first().map_or(0.0, |n| n.1);
    let (mut value, mut normal, mut total) = (0.0, [0.0; 3], 0.0);
    for &(j, d) in &near {
        let w = (-(d * d - d0 * d0) / (width * width)).exp();
        let plane = &samples.planes[j];
        value += w * dot(sub(x, plane.centroid), plane.normal);
        for k in 0..3 {
            normal[k] += w * plane.normal[k];
        }
        total += w;
    }
    let len = norm(normal);
    if total <= 0.0 || len <= 0.0 {
        return (f64::INFINITY, [0.0, 0.0, 1.0]);
    }
    (value / total, normal.map(|c| c / len))
}

/// A cubic grid: node `[i, j, k]` sits at `origin + h · (i, j, k)`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Grid {
    /// Position of node `[0, 0, 0]`.
    pub origin: [f64; 3],
    /// Node spacing.
    pub h: f64,
}

impl Grid {
    fn position(&self, node: [i32; 3]) -> [f64; 3] {
        [0, 1, 2].map(|d| self.origin[d] + self.h * node[d] as f64)
    }
}

/// The grid nodes within `radius(i)` of some sample `i`, sorted.
pub(super) fn band_nodes(
    points: &[[f64; 3]],
    grid: &Grid,
    radius: impl Fn(usize) -> f64,
) -> Vec<[i32; 3]> {
    let mut set: FxHashSet<[i32; 3]> = FxHashSet::default();
    for (i, p) in points.iter().enumerate() {
        let r = radius(i);
        let lo = [0, 1, 2].map(|d| ((p[d] - r - grid.origin[d]) / grid.h).ceil() as i32);
        let hi = [0, 1, 2].map(|d| ((p[d] + r - grid.origin[d]) / grid.h).floor() as i32);
        for a in lo[0]..=hi[0] {
            for b in lo[1]..=hi[1] {
                for c in lo[2]..=hi[2] {
                    let node = [a, b, c];
                    if norm(sub(grid.position(node), *p)) <= r {
                        set.insert(node);
                    }
                }
            }
        }
    }
    let mut nodes: Vec<[i32; 3]> = set.into_iter().collect();
    nodes.sort_unstable();
    nodes
}

/// The corners of the cell whose lowest corner is `n`, in the bit order
/// `x + 2y + 4z`.
fn corners(n: [i32; 3]) -> [[i32; 3]; 8] {
    std::array::from_fn(|b| {
        [
            n[0] + (b & 1) as i32,
            n[1] + ((b >> 1) & 1) as i32,
            n[2] + ((b >> 2) & 1) as i32,
        ]
    })
}

/// The twelve edges of a cell as pairs of corner bits.
const CELL_EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// Surface nets: the zero set of the values at `nodes` (sorted; a node
/// missing from the list has no value and no cell touching it makes a
/// vertex). Each cell with corners of both signs gets one vertex, the mean
/// of the zero crossings on its edges; each grid edge with a sign change
/// gives the quad of the four cells around it, split along its shorter
/// diagonal, turned so that its normal points towards positive values.
pub(super) fn surface_nets(grid: &Grid, nodes: &[[i32; 3]], values: &[f64]) -> Mesh {
    let value: FxHashMap<[i32; 3], f64> =
        nodes.iter().copied().zip(values.iter().copied()).collect();
    let mut vertices: Vec<[f64; 3]> = Vec::new();
    let mut cell_vertex: FxHashMap<[i32; 3], u32> = FxHashMap::default();
    for &n in nodes {
        let c = corners(n);
        let mut f = [0.0; 8];
        let mut complete = true;
        for b in 0..8 {
            match value.get(&c[b]) {
                Some(&v) if v.is_finite() => f[b] = v,
                _ => complete = false,
            }
        }
        if !complete || f.iter().all(|&v| v < 0.0) || f.iter().all(|&v| v >= 0.0) {
            continue;
        }
        let (mut sum, mut count) = ([0.0; 3], 0.0);
        for &(a, b) in &CELL_EDGES {
            if (f[a] < 0.0) != (f[b] < 0.0) {
                let t = f[a] / (f[a] - f[b]);
                let (pa, pb) = (grid.position(c[a]), grid.position(c[b]));
                for d in 0..3 {
                    sum[d] += pa[d] + t * (pb[d] - pa[d]);
                }
                count += 1.0;
            }
        }
        cell_vertex.insert(n, vertices.len() as u32);
        vertices.push(sum.map(|s| s / count));
    }
    let mut faces: Vec<[u32; 3]> = Vec::new();
    for &a in nodes {
        let Some(&fa) = value.get(&a) else { continue };
        for d in 0..3 {
            let mut b = a;
            b[d] += 1;
            let Some(&fb) = value.get(&b) else { continue };
            if (fa < 0.0) == (fb < 0.0) {
                continue;
            }
            let (u, v) = ((d + 1) % 3, (d + 2) % 3);
            let shift = |du: i32, dv: i32| {
                let mut c = a;
                c[u] += du;
                c[v] += dv;
                cell_vertex.get(&c).copied()
            };
            let (Some(c00), Some(c10), Some(c11), Some(c01)) =
                (shift(-1, -1), shift(0, -1), shift(0, 0), shift(-1, 0))
            else {
                continue;
            };
            // (c00, c10, c11, c01) turns counter-clockwise seen from +d.
            let mut quad = [c00, c10, c11, c01];
            if fa >= 0.0 {
                quad.reverse();
            }
            let p = |k: usize| vertices[quad[k] as usize];
            if norm(sub(p(0), p(2))) <= norm(sub(p(1), p(3))) {
                faces.push([quad[0], quad[1], quad[2]]);
                faces.push([quad[0], quad[2], quad[3]]);
            } else {
                faces.push([quad[1], quad[2], quad[3]]);
                faces.push([quad[1], quad[3], quad[0]]);
            }
        }
    }
    Mesh::new(vertices, faces)
}

/// Move each vertex onto the zero set by `steps` Newton steps along the
/// blended normal.
pub(super) fn project_to_zero_set(
    samples: &OrientedSamples,
    mesh: &Mesh,
    width: f64,
    steps: usize,
) -> Mesh {
    let vertices = mesh
        .vertices
        .par_iter()
        .map(|&p| {
            let mut x = p;
            for _ in 0..steps {
                let (f, n) = signed_distance(samples, x, width);
                if !f.is_finite() {
                    break;
                }
                x = [0, 1, 2].map(|d| x[d] - f * n[d]);
            }
            x
        })
        .collect();
    Mesh::new(vertices, mesh.faces.clone())
}

/// Whether each triangle lies among the samples: the nearest sample is
/// within `max_gap` of its local spacing of the triangle's centroid, and
/// the centroid of the nearest samples is, along the triangle's plane,
/// within `max_offset` local spacings of it (past the edge of the sampled
/// region all samples lie on one side, so that centroid moves away).
pub(super) fn among_samples(
    samples: &OrientedSamples,
    mesh: &Mesh,
    max_gap: f64,
    max_offset: f64,
) -> Vec<bool> {
    let points = samples.neighbours.points();
    mesh.faces
        .par_iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| mesh.vertices[i as usize]);
            let x = [0, 1, 2].map(|d| (a[d] + b[d] + c[d]) / 3.0);
            let n = cross(sub(b, a), sub(c, a));
            let len = norm(n);
            let near = samples.neighbours.nearest(x, TRIM_NEIGHBOURS);
            let Some(&(first, gap)) = near.first() else {
                return false;
            };
            let s = samples.spacing[first];
            let mut mean = [0.0; 3];
            for &(j, _) in &near {
                for d in 0..3 {
                    mean[d] += points[j][d] / near.len() as f64;
                }
            }
            let mut offset = sub(mean, x);
            if len > 0.0 {
                let n = n.map(|v| v / len);
                let along = dot(offset, n);
                offset = [0, 1, 2].map(|d| offset[d] - along * n[d]);
            }
            gap <= max_gap * s && norm(offset) <= max_offset * s
        })
        .collect()
}

/// Trim the surface to the sampled region: drop the triangles that are
/// not `among` the samples and are reached from the surface's boundary
/// across such triangles. A triangle not among the samples but enclosed
/// by ones that are (a gap in a random sampling) stays, so trimming makes
/// no holes.
pub(super) fn trim_from_boundary(mesh: &Mesh, among: &[bool]) -> Mesh {
    use crate::mesh::{triangle_adjacency, NO_TRIANGLE};
    let adjacency = triangle_adjacency(&mesh.faces);
    let mut outside = vec![false; mesh.faces.len()];
    let mut stack: Vec<usize> = (0..mesh.faces.len())
        .filter(|&f| !among[f] && adjacency[f].contains(&NO_TRIANGLE))
        .collect();
    for &f in &stack {
        outside[f] = true;
    }
    while let Some(f) = stack.pop() {
        for &g in &adjacency[f] {
            let g = g as usize;
            if g < mesh.faces.len() && !among[g] && !outside[g] {
                outside[g] = true;
                stack.push(g);
            }
        }
    }
    let faces = mesh
        .faces
        .iter()
        .zip(&outside)
        .filter(|(_, &o)| !o)
        .map(|(f, _)| *f)
        .collect();
    crate::clean::faces::remove_unreferenced_vertices(&Mesh::new(mesh.vertices.clone(), faces))
}

/// Drop the triangles that make the surface non-manifold, where surface
/// nets meets two sheets in one cell: all triangles on an edge with more
/// than two, and at a vertex whose triangles form several fans, all but
/// the largest fan. Repeated until nothing changes (at most `rounds`
/// times). The holes left are small; cleaning fills them.
pub(super) fn drop_nonmanifold(mesh: &Mesh, rounds: usize) -> Mesh {
    use crate::mesh::edge_key;
    let mut faces = mesh.faces.clone();
    for _ in 0..rounds {
        let mut drop = vec![false; faces.len()];
        let edges = crate::mesh::edge_face_map(&Mesh::new(Vec::new(), faces.clone()));
        for list in edges.values() {
            if list.len() > 2 {
                for &f in list {
                    drop[f as usize] = true;
                }
            }
        }
        let mut around: Vec<Vec<usize>> = vec![Vec::new(); mesh.vertices.len()];
        for (f, t) in faces.iter().enumerate() {
            for &v in t {
                around[v as usize].push(f);
            }
        }
        for (v, list) in around.iter().enumerate() {
            if list.len() < 2 {
                continue;
            }
            // Fans: the triangles at v joined across the edges from v.
            let mut fan = UnionFind::new(list.len());
            let mut by_edge: FxHashMap<crate::mesh::EdgeKey, usize> = FxHashMap::default();
            for (k, &f) in list.iter().enumerate() {
                for &w in &faces[f] {
                    if w as usize == v {
                        continue;
                    }
                    match by_edge.get(&edge_key(v as u32, w)) {
                        Some(&other) => fan.union(k as u32, other as u32),
                        None => {
                            by_edge.insert(edge_key(v as u32, w), k);
                        }
                    }
                }
            }
            let roots: Vec<usize> = (0..list.len())
                .map(|k| fan.find(k as u32) as usize)
                .collect();
            let mut sizes: FxHashMap<usize, usize> = FxHashMap::default();
            for &r in &roots {
                *sizes.entry(r).or_default() += 1;
            }
            if sizes.len() < 2 {
                continue;
            }
            let largest = sizes
                .iter()
                .max_by_key(|&(r, n)| (*n, std::cmp::Reverse(*r)))
                .map_or(0, |(r, _)| *r);
            for (k, &f) in list.iter().enumerate() {
                if roots[k] != largest {
                    drop[f] = true;
                }
            }
        }
        if !drop.contains(&true) {
            break;
        }
        faces = faces
            .iter()
            .zip(&drop)
            .filter(|(_, &d)| !d)
            .map(|(f, _)| *f)
            .collect();
    }
    crate::clean::faces::remove_unreferenced_vertices(&Mesh::new(mesh.vertices.clone(), faces))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nets_of_a_plane_are_a_flat_sheet_facing_positive_values() {
        let grid = Grid {
            origin: [0.0; 3],
            h: 1.0,
        };
        let mut nodes = Vec::new();
        for i in 0..6 {
            for j in 0..6 {
                for k in 0..4 {
                    nodes.push([i, j, k]);
                }
            }
        }
        nodes.sort_unstable();
        let values: Vec<f64> = nodes.iter().map(|n| n[2] as f64 - 1.3).collect();
        let m = surface_nets(&grid, &nodes, &values);
        assert_eq!(m.vertices.len(), 25);
        assert_eq!(m.faces.len(), 32);
        for v in &m.vertices {
            assert!((v[2] - 1.3).abs() < 1e-12);
        }
        for f in &m.faces {
            let [a, b, c] = f.map(|i| m.vertices[i as usize]);
            assert!(cross(sub(b, a), sub(c, a))[2] > 0.0);
        }
    }
}
