//! A small z-buffer rasterizer: a triangle mesh with per-vertex colours,
//! seen by an orthographic [`Camera`], shaded by a headlight, to an RGBA
//! image. Pure functions over plain data; the report encodes the image as
//! PNG.

use morphoid_core::mesh::{cross, dot, sub};
pub use morphoid_core::mesh::{unit, vertex_normals};
use morphoid_data::present::{png_bytes, Channels};

/// An orthographic view: an orthonormal frame and the square of the scene
/// it shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// The point at the centre of the picture.
    pub centre: [f64; 3],
    /// Screen right, in scene coordinates (unit).
    pub right: [f64; 3],
    /// Screen up (unit, orthogonal to `right`).
    pub up: [f64; 3],
    /// Half the side of the square shown, in scene units.
    pub half_extent: f64,
}

impl Camera {
    /// The direction from the scene towards the viewer
    /// (`right × up`).
    pub fn toward_viewer(&self) -> [f64; 3] {
        cross(self.right, self.up)
    }

    /// Screen coordinates of `p` in a `size`×`size` picture (x right, y
    /// down, in pixels) and its depth (larger: nearer the viewer).
    fn project(&self, p: [f64; 3], size: usize) -> [f64; 3] {
        let d = sub(p, self.centre);
        let s = size as f64 / 2.0;
        let h = self.half_extent.max(f64::MIN_POSITIVE);
        [
            (dot(d, self.right) / h + 1.0) * s,
            (1.0 - dot(d, self.up) / h) * s,
            dot(d, self.toward_viewer()),
        ]
    }
}

/// An RGBA picture, row by row from the top, 4 bytes a pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Width and height in pixels.
    pub size: usize,
    /// `size * size * 4` bytes; the background is transparent.
    pub rgba: Vec<u8>,
}

impl Image {
    /// The picture as PNG bytes (`None` only if the encoder fails).
    pub fn to_png(&self) -> Option<Vec<u8>> {
        let side = u32::try_from(self.size).ok()?;
        png_bytes(side, side, Channels::Rgba, &self.rgba).ok()
    }

    /// Number of pixels something was drawn on (alpha not zero).
    #[cfg(test)]
    fn covered_pixels(&self) -> usize {
        self.rgba.chunks_exact(4).filter(|p| p[3] != 0).count()
    }
}

/// Headlight shading: ambient plus diffuse light from the viewer, lit the
/// same from both sides (a crown is an open surface).
fn headlight(normal: [f64; 3], toward_viewer: [f64; 3]) -> f64 {
    0.35 + 0.65 * dot(normal, toward_viewer).abs()
}

/// The mesh seen by `camera` in a `size`×`size` picture: colours
/// interpolated across each triangle, shaded by a headlight, nearest
/// surface kept per pixel. Faces with an index out of range are skipped.
pub fn render(
    vertices: &[[f64; 3]],
    faces: &[[u32; 3]],
    colours: &[[u8; 3]],
    camera: &Camera,
    size: usize,
) -> Image {
    let mut rgba = vec![0u8; size * size * 4];
    let mut depth = vec![f64::NEG_INFINITY; size * size];
    let normals = vertex_normals(vertices, faces);
    let toward = camera.toward_viewer();
    let projected: Vec<[f64; 3]> = vertices.iter().map(|&p| camera.project(p, size)).collect();
    let shade: Vec<[f64; 3]> = (0..vertices.len())
        .map(|i| {
            let l = headlight(normals[i], toward);
            let c = colours.get(i).copied().unwrap_or([200, 200, 200]);
            c.map(|x| f64::from(x) * l)
        })
        .collect();
    for f in faces {
        let idx = f.map(|i| i as usize);
        if idx.iter().any(|&i| i >= vertices.len()) {
            continue;
        }
        let [p0, p1, p2] = idx.map(|i| projected[i]);
        let area = edge(p0, p1, p2);
        if area.abs() < 1e-12 {
            continue;
        }
        let (x0, x1) = bounds(&[p0[0], p1[0], p2[0]], size);
        let (y0, y1) = bounds(&[p0[1], p1[1], p2[1]], size);
        for y in y0..y1 {
            for x in x0..x1 {
                let q = [x as f64 + 0.5, y as f64 + 0.5, 0.0];
                let w = [edge(p1, p2, q), edge(p2, p0, q), edge(p0, p1, q)].map(|e| e / area);
                if w.iter().any(|&b| b < 0.0) {
                    continue;
                }
                let z = w[0] * p0[2] + w[1] * p1[2] + w[2] * p2[2];
                let at = y * size + x;
                if z <= depth[at] {
                    continue;
                }
                depth[at] = z;
                let [c0, c1, c2] = idx.map(|i| shade[i]);
                for d in 0..3 {
                    let v = w[0] * c0[d] + w[1] * c1[d] + w[2] * c2[d];
                    rgba[at * 4 + d] = v.clamp(0.0, 255.0) as u8;
                }
                rgba[at * 4 + 3] = 255;
            }
        }
    }
    Image { size, rgba }
}

/// Twice the signed area of the screen triangle `a b c`.
fn edge(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// The pixel range `[lo, hi)` covering coordinates `c`, clipped to the
/// picture.
fn bounds(c: &[f64; 3], size: usize) -> (usize, usize) {
    let lo = c
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min)
        .floor()
        .max(0.0);
    let hi = c
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max)
        .ceil()
        .min(size as f64);
    if hi.is_nan() || lo.is_nan() || hi <= lo {
        return (0, 0);
    }
    (lo as usize, hi as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            centre: [0.0; 3],
            right: [1.0, 0.0, 0.0],
            up: [0.0, 1.0, 0.0],
            half_extent: 1.0,
        }
    }

    #[test]
    fn a_square_covers_its_share_of_the_picture() {
        // Two triangles covering [-0.5, 0.5]²: a quarter of the [-1, 1]² view.
        let v = [
            [-0.5, -0.5, 0.0],
            [0.5, -0.5, 0.0],
            [0.5, 0.5, 0.0],
            [-0.5, 0.5, 0.0],
        ];
        let f = [[0, 1, 2], [0, 2, 3]];
        let img = render(&v, &f, &[[255, 0, 0]; 4], &camera(), 100);
        let covered = img.covered_pixels();
        assert!((2400..=2600).contains(&covered), "{covered}");
        // Facing the viewer: full headlight, pure red.
        let centre = (50 * 100 + 50) * 4;
        assert_eq!(&img.rgba[centre..centre + 4], &[255, 0, 0, 255]);
        // The corner stays background.
        assert_eq!(&img.rgba[0..4], &[0, 0, 0, 0]);
    }

    #[test]
    fn the_nearer_surface_hides_the_farther_one() {
        let quad = |z: f64, base: u32| {
            (
                vec![
                    [-1.0, -1.0, z],
                    [1.0, -1.0, z],
                    [1.0, 1.0, z],
                    [-1.0, 1.0, z],
                ],
                vec![[base, base + 1, base + 2], [base, base + 2, base + 3]],
            )
        };
        let (mut v, mut f) = quad(-0.5, 0);
        let (v2, f2) = quad(0.5, 4);
        v.extend(v2);
        f.extend(f2);
        let mut colours = vec![[0, 0, 255]; 4];
        colours.extend([[0, 255, 0]; 4]);
        // Draw order must not matter: the near (green, z = 0.5) one wins.
        for faces in [f.clone(), f.iter().rev().copied().collect()] {
            let img = render(&v, &faces, &colours, &camera(), 20);
            let at = (10 * 20 + 10) * 4;
            assert_eq!(&img.rgba[at..at + 3], &[0, 255, 0]);
        }
    }

    #[test]
    fn normals_of_a_flat_patch_point_along_its_normal() {
        let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let n = vertex_normals(&v, &[[0, 1, 2]]);
        for x in n {
            assert!((x[2] - 1.0).abs() < 1e-12);
        }
    }
}
