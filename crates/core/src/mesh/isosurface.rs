//! The isosurface of a grid: marching tetrahedra on the Kuhn split of each
//! cube into six tetrahedra around its main diagonal. Neighbouring cubes
//! split their shared face along the same diagonal, so the surface is
//! closed and manifold wherever it does not leave the grid; outside the
//! grid counts as outside, so it never does. Vertices sit on grid edges and
//! are shared through an edge key; triangles face from inside to outside.

use super::grid::Grid;
use crate::mesh::{cross, dot, sub, Mesh};
use rustc_hash::FxHashMap;

/// The six tetrahedra of a cube, as cube corner numbers (bit 0: +x,
/// bit 1: +y, bit 2: +z), each a path 0 → one axis → two axes → 7.
const KUHN: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 1, 5, 7],
    [0, 2, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 4, 6, 7],
];

/// The closed surface `{ field = iso }` around the samples above `iso`,
/// in the grid's physical coordinates.
pub fn isosurface(grid: &Grid, iso: f32) -> Mesh {
    let [nx, ny, nz] = grid.dims;
    // Padded by one sample of "outside" on every side.
    let (px, py, pz) = (nx + 2, ny + 2, nz + 2);
    let low = grid.values.iter().copied().fold(iso, f32::min) - 1.0;
    let value = |x: usize, y: usize, z: usize| -> f32 {
        if x == 0 || y == 0 || z == 0 || x > nx || y > ny || z > nz {
            low
        } else {
            grid.values[grid.index(x - 1, y - 1, z - 1)]
        }
    };
    let position = |x: usize, y: usize, z: usize| -> [f64; 3] {
        [
            grid.origin[0] + (x as f64 - 1.0) * grid.spacing[0],
            grid.origin[1] + (y as f64 - 1.0) * grid.spacing[1],
            grid.origin[2] + (z as f64 - 1.0) * grid.spacing[2],
        ]
    };
    let total = (px * py * pz) as u64;
    let mut vertices: Vec<[f64; 3]> = Vec::new();
    let mut faces: Vec<[u32; 3]> = Vec::new();
    let mut on_edge: FxHashMap<u64, u32> = FxHashMap::default();
    for z in 0..pz - 1 {
        for y in 0..py - 1 {
            for x in 0..px - 1 {
                let mut idx = [0usize; 8];
                let mut val = [0f32; 8];
                let mut inside = 0u32;
                for c in 0..8 {
                    let (cx, cy, cz) = (x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1));
                    idx[c] = cx + px * (cy + py * cz);
                    val[c] = value(cx, cy, cz);
                    inside += u32::from(val[c] > iso);
                }
                if inside == 0 || inside == 8 {
                    continue;
                }
                let corner_pos =
                    |c: usize| position(x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1));
                let mut pending: Vec<([u32; 3], [f64; 3])> = Vec::new();
                let mut vertex = |a: usize, b: usize| -> u32 {
                    let (ia, ib) = (idx[a], idx[b]);
                    let key = ia.min(ib) as u64 * total + ia.max(ib) as u64;
                    *on_edge.entry(key).or_insert_with(|| {
                        let t =
                            f64::from((iso - val[a]) / (val[b] - val[a])).clamp(1e-3, 1.0 - 1e-3);
                        let (pa, pb) = (corner_pos(a), corner_pos(b));
                        vertices.push([
                            pa[0] + t * (pb[0] - pa[0]),
                            pa[1] + t * (pb[1] - pa[1]),
                            pa[2] + t * (pb[2] - pa[2]),
                        ]);
                        (vertices.len() - 1) as u32
                    })
                };
                for tet in KUHN {
                    let ins: Vec<usize> = tet.iter().copied().filter(|&c| val[c] > iso).collect();
                    let out: Vec<usize> = tet.iter().copied().filter(|&c| val[c] <= iso).collect();
                    let tris: Vec<[u32; 3]> = match (ins.len(), out.len()) {
                        (1, 3) => vec![[
                            vertex(ins[0], out[0]),
                            vertex(ins[0], out[1]),
                            vertex(ins[0], out[2]),
                        ]],
                        (3, 1) => vec![[
                            vertex(ins[0], out[0]),
                            vertex(ins[1], out[0]),
                            vertex(ins[2], out[0]),
                        ]],
                        (2, 2) => {
                            let q = [
                                vertex(ins[0], out[0]),
                                vertex(ins[0], out[1]),
                                vertex(ins[1], out[1]),
                                vertex(ins[1], out[0]),
                            ];
                            vec![[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
                        }
                        _ => Vec::new(),
                    };
                    let centroid = |cs: &[usize]| {
                        let mut s = [0.0; 3];
                        for &c in cs {
                            let p = corner_pos(c);
                            (0..3).for_each(|a| s[a] += p[a] / cs.len() as f64);
                        }
                        s
                    };
                    let outward = sub(centroid(&out), centroid(&ins));
                    pending.extend(tris.into_iter().map(|t| (t, outward)));
                }
                for (t, outward) in pending {
                    let [a, b, c] = t.map(|v| vertices[v as usize]);
                    let n = cross(sub(b, a), sub(c, a));
                    faces.push(if dot(n, outward) >= 0.0 {
                        t
                    } else {
                        [t[0], t[2], t[1]]
                    });
                }
            }
        }
    }
    Mesh::new(vertices, faces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{euler_characteristic, surface_area, EdgeMap};

    #[test]
    fn a_ball_is_closed_manifold_sphere_with_the_right_area() {
        let n = 40;
        let r = 14.3;
        let mut g = Grid::filled([n, n, n], [0.0; 3], [0.5; 3], 0.0);
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let p = [x as f64 - 19.5, y as f64 - 19.5, z as f64 - 19.5];
                    let i = g.index(x, y, z);
                    g.values[i] = (r - dot(p, p).sqrt()) as f32;
                }
            }
        }
        let m = isosurface(&g, 0.0);
        assert_eq!(euler_characteristic(&m), 2);
        let edges = EdgeMap::new(&m.faces);
        assert!(edges.values().all(|f| f.len() == 2));
        let area = surface_area(&m);
        let expected = 4.0 * std::f64::consts::PI * (r * 0.5).powi(2);
        assert!((area / expected - 1.0).abs() < 0.03, "{area} vs {expected}");
        // Outward: the signed volume is positive.
        let vol: f64 = m
            .faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|v| m.vertices[v as usize]);
                dot(a, cross(b, c)) / 6.0
            })
            .sum();
        assert!(vol > 0.0);
    }
}
