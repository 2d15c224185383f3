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
    let field = PaddedField::new(grid, iso);
    let [px, py, pz] = field.dims;
    let mut edges = EdgeVertices {
        vertices: Vec::new(),
        on_edge: FxHashMap::default(),
        total: (px * py * pz) as u64,
    };
    let mut faces: Vec<[u32; 3]> = Vec::new();
    // Most cubes of a scan lie in air: a row of cubes is only visited
    // when one of its four rows of samples holds a sample inside. (Every
    // row holds outside samples, its padding.)
    let holds_inside = field.rows_holding_inside();
    let row = |y: usize, z: usize| holds_inside[y + py * z];
    for z in 0..pz - 1 {
        for y in 0..py - 1 {
            if !(row(y, z) || row(y + 1, z) || row(y, z + 1) || row(y + 1, z + 1)) {
                continue;
            }
            for x in 0..px - 1 {
                let cube = field.cube([x, y, z]);
                if cube.inside == 0 || cube.inside == 8 {
                    continue;
                }
                cube_triangles(&field, &cube, &mut edges, &mut faces);
            }
        }
    }
    Mesh::new(edges.vertices, faces)
}

/// The grid padded by one sample of "outside" on every side, and the
/// level of the surface.
struct PaddedField<'a> {
    grid: &'a Grid,
    /// The level: samples above it are inside.
    iso: f32,
    /// Samples along x, y, z, padding included.
    dims: [usize; 3],
    /// The value of the padding: below the level and every sample.
    low: f32,
}

/// One cube of the padded grid.
struct Cube {
    /// The padded sample at its corner 0.
    corner: [usize; 3],
    /// Its corners' padded sample numbers, by corner number.
    idx: [usize; 8],
    /// Its corners' values, by corner number.
    val: [f32; 8],
    /// How many of its corners are inside.
    inside: u32,
}

impl<'a> PaddedField<'a> {
    /// `grid` padded, with the surface at level `iso`.
    fn new(grid: &'a Grid, iso: f32) -> Self {
        let [nx, ny, nz] = grid.dims;
        Self {
            grid,
            iso,
            dims: [nx + 2, ny + 2, nz + 2],
            low: grid.values.iter().copied().fold(iso, f32::min) - 1.0,
        }
    }

    /// Whether each row of the padded grid along x holds a sample above
    /// the level, by `y + py·z`.
    fn rows_holding_inside(&self) -> Vec<bool> {
        let [px, py, pz] = self.dims;
        let mut out = Vec::with_capacity(py * pz);
        for z in 0..pz {
            for y in 0..py {
                out.push((0..px).any(|x| self.value(x, y, z) > self.iso));
            }
        }
        out
    }

    /// The value at padded sample (x, y, z).
    fn value(&self, x: usize, y: usize, z: usize) -> f32 {
        let [nx, ny, nz] = self.grid.dims;
        if x == 0 || y == 0 || z == 0 || x > nx || y > ny || z > nz {
            self.low
        } else {
            self.grid.values[self.grid.index(x - 1, y - 1, z - 1)]
        }
    }

    /// The physical position of padded sample (x, y, z).
    fn position(&self, x: usize, y: usize, z: usize) -> [f64; 3] {
        let grid = self.grid;
        [
            grid.origin[0] + (x as f64 - 1.0) * grid.spacing[0],
            grid.origin[1] + (y as f64 - 1.0) * grid.spacing[1],
            grid.origin[2] + (z as f64 - 1.0) * grid.spacing[2],
        ]
    }

    /// The cube whose corner 0 is padded sample `[x, y, z]`.
    fn cube(&self, [x, y, z]: [usize; 3]) -> Cube {
        let [px, py, _] = self.dims;
        let mut idx = [0usize; 8];
        let mut val = [0f32; 8];
        let mut inside = 0u32;
        for c in 0..8 {
            let (cx, cy, cz) = (x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1));
            idx[c] = cx + px * (cy + py * cz);
            val[c] = self.value(cx, cy, cz);
            inside += u32::from(val[c] > self.iso);
        }
        Cube {
            corner: [x, y, z],
            idx,
            val,
            inside,
        }
    }

    /// The physical position of corner `c` of `cube`.
    fn corner_position(&self, cube: &Cube, c: usize) -> [f64; 3] {
        let [x, y, z] = cube.corner;
        self.position(x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1))
    }

    /// The mean physical position of the corners `cs` of `cube`.
    fn corner_centroid(&self, cube: &Cube, cs: &[usize]) -> [f64; 3] {
        let mut s = [0.0; 3];
        for &c in cs {
            let p = self.corner_position(cube, c);
            (0..3).for_each(|a| s[a] += p[a] / cs.len() as f64);
        }
        s
    }
}

/// The surface's vertices, one on each grid edge it crosses.
struct EdgeVertices {
    vertices: Vec<[f64; 3]>,
    /// The vertex of each crossed edge, by the edge's key.
    on_edge: FxHashMap<u64, u32>,
    /// Samples of the padded grid: an edge's key is its lower sample
    /// number times this plus its higher one.
    total: u64,
}

impl EdgeVertices {
    /// The vertex on the edge between corners `a` and `b` of `cube`, where
    /// the values interpolate linearly to the level; made on first use.
    fn on_edge(&mut self, field: &PaddedField, cube: &Cube, a: usize, b: usize) -> u32 {
        let (ia, ib) = (cube.idx[a], cube.idx[b]);
        let key = ia.min(ib) as u64 * self.total + ia.max(ib) as u64;
        let vertices = &mut self.vertices;
        let (iso, val) = (field.iso, &cube.val);
        *self.on_edge.entry(key).or_insert_with(|| {
            let t = f64::from((iso - val[a]) / (val[b] - val[a])).clamp(1e-3, 1.0 - 1e-3);
            let (pa, pb) = (
                field.corner_position(cube, a),
                field.corner_position(cube, b),
            );
            vertices.push([
                pa[0] + t * (pb[0] - pa[0]),
                pa[1] + t * (pb[1] - pa[1]),
                pa[2] + t * (pb[2] - pa[2]),
            ]);
            (vertices.len() - 1) as u32
        })
    }
}

/// Append the triangles of one cube to `faces`, tetrahedron by
/// tetrahedron, each turned so that its normal does not point against the
/// direction from its tetrahedron's inside corners to its outside ones.
fn cube_triangles(
    field: &PaddedField,
    cube: &Cube,
    edges: &mut EdgeVertices,
    faces: &mut Vec<[u32; 3]>,
) {
    let iso = field.iso;
    for tet in KUHN {
        let (mut ins, mut out) = (Corners::default(), Corners::default());
        for c in tet {
            if cube.val[c] > iso {
                ins.push(c);
            } else {
                out.push(c);
            }
        }
        let (ins, out) = (ins.as_slice(), out.as_slice());
        let (tris, count) =
            tetrahedron_triangles(ins, out, |a, b| edges.on_edge(field, cube, a, b));
        let outward = sub(
            field.corner_centroid(cube, out),
            field.corner_centroid(cube, ins),
        );
        for t in &tris[..count] {
            let [a, b, c] = t.map(|v| edges.vertices[v as usize]);
            let n = cross(sub(b, a), sub(c, a));
            faces.push(if dot(n, outward) >= 0.0 {
                *t
            } else {
                [t[0], t[2], t[1]]
            });
        }
    }
}

/// Up to four corner numbers of a cube, without allocating.
#[derive(Default)]
struct Corners {
    list: [usize; 4],
    len: usize,
}

impl Corners {
    fn push(&mut self, c: usize) {
        self.list[self.len] = c;
        self.len += 1;
    }

    fn as_slice(&self) -> &[usize] {
        &self.list[..self.len]
    }
}

/// The triangles (the first `count` of the pair) where the surface crosses
/// a tetrahedron whose corners `ins` are inside and `out` outside;
/// `vertex(a, b)` is the vertex on the edge between corners `a` and `b`.
fn tetrahedron_triangles(
    ins: &[usize],
    out: &[usize],
    mut vertex: impl FnMut(usize, usize) -> u32,
) -> ([[u32; 3]; 2], usize) {
    match (ins.len(), out.len()) {
        (1, 3) => (
            [
                [
                    vertex(ins[0], out[0]),
                    vertex(ins[0], out[1]),
                    vertex(ins[0], out[2]),
                ],
                [0; 3],
            ],
            1,
        ),
        (3, 1) => (
            [
                [
                    vertex(ins[0], out[0]),
                    vertex(ins[1], out[0]),
                    vertex(ins[2], out[0]),
                ],
                [0; 3],
            ],
            1,
        ),
        (2, 2) => {
            let q = [
                vertex(ins[0], out[0]),
                vertex(ins[0], out[1]),
                vertex(ins[1], out[1]),
                vertex(ins[1], out[0]),
            ];
            ([[q[0], q[1], q[2]], [q[0], q[2], q[3]]], 2)
        }
        _ => ([[0; 3]; 2], 0),
    }
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
