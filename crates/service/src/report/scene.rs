//! What a report shows in 3D: the scan, each of its nearest references
//! moved onto it by the rigid part of the cP map, a colouring of each
//! reference by position carried onto the scan through the cP
//! correspondence (so cusps that went to cusps show the same colour), and
//! the carried landmarks. All in the scan's normalized coordinates
//! (centroid at the origin, area 1), so every picture shares one pose.

use super::render::{unit, Camera};
use morphoid_core::cp::{self, CompareParams, Correspondence, Prepared};
use morphoid_core::mesh::{boundary_vertices, cross, dot, principal_axes, sub, Mesh};
use rayon::prelude::*;

/// A triangle mesh with a colour per vertex.
#[derive(Debug, Clone, PartialEq)]
pub struct ColouredMesh {
    /// Vertices in the scan's normalized coordinates.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles.
    pub faces: Vec<[u32; 3]>,
    /// One colour per vertex.
    pub colours: Vec<[u8; 3]>,
}

/// The scan and one nearest reference, matched.
#[derive(Debug, Clone, PartialEq)]
pub struct Pairing {
    /// The reference's name.
    pub reference: String,
    /// The recorded cP distance.
    pub distance: f64,
    /// Whether the scan matched the reference's mirror image.
    pub reflected: bool,
    /// The reference moved onto the scan, coloured by position.
    pub aligned: ColouredMesh,
    /// The scan's vertices coloured by the reference colour at their image
    /// under the cP map scan → reference (same vertices and faces as the
    /// scene's scan).
    pub carried: Vec<[u8; 3]>,
}

/// A landmark carried onto the scan, in the scan's normalized coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenePoint {
    /// Its label, if any.
    pub label: Option<String>,
    /// Position.
    pub position: [f64; 3],
}

/// Everything a report draws.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// The scan's vertices (normalized) and faces.
    pub scan: Mesh,
    /// The nearest references, nearest first.
    pub pairings: Vec<Pairing>,
    /// Landmarks carried onto the scan.
    pub landmarks: Vec<ScenePoint>,
    /// The shared view.
    pub camera: Camera,
}

/// One nearest reference to put in a scene.
#[derive(Debug, Clone, Copy)]
pub struct SceneReference<'a> {
    /// Its name.
    pub name: &'a str,
    /// Its recorded distance to the scan.
    pub distance: f64,
    /// Its prepared form.
    pub prepared: &'a Prepared,
}

impl Scene {
    /// The scene of a prepared scan and its nearest references: each
    /// reference is matched to the scan by the directed cP map scan →
    /// reference (`params`), moved onto the scan by the inverse of that
    /// map's rigid motion and coloured by position; the scan gets each
    /// reference's colours through the map. `landmarks` are in the scan
    /// file's units (as recorded).
    pub fn build(
        scan: &Prepared,
        references: &[SceneReference<'_>],
        landmarks: &[(Option<String>, [f64; 3])],
        params: &CompareParams,
    ) -> Scene {
        let mesh = Mesh::new(scan.vertices().to_vec(), scan.faces().to_vec());
        let camera = crown_view(&mesh);
        let pairings = references
            .par_iter()
            .map(|r| pairing(scan, r, &camera, params))
            .collect();
        let (centroid, scale) = (scan.centroid(), scan.scale().max(f64::MIN_POSITIVE));
        let landmarks = landmarks
            .iter()
            .map(|(label, p)| ScenePoint {
                label: label.clone(),
                position: [0, 1, 2].map(|d| (p[d] - centroid[d]) / scale),
            })
            .collect();
        Scene {
            scan: mesh,
            pairings,
            landmarks,
            camera,
        }
    }
}

/// The scan and one reference matched (see [`Scene::build`]).
fn pairing(
    scan: &Prepared,
    reference: &SceneReference<'_>,
    camera: &Camera,
    params: &CompareParams,
) -> Pairing {
    let map = cp::compare_directed(scan, reference.prepared, params);
    let aligned = inverse_rigid_motion(
        &map.rotation,
        map.translation,
        reference.prepared.vertices(),
    );
    let colours = position_colours(&aligned, camera);
    let carried = carried_colours(&map.correspondence, reference.prepared.faces(), &colours);
    Pairing {
        reference: reference.name.to_string(),
        distance: reference.distance,
        reflected: map.reflected,
        aligned: ColouredMesh {
            vertices: aligned,
            faces: reference.prepared.faces().to_vec(),
            colours,
        },
        carried,
    }
}

/// The points `y` mapped back through the rigid motion `x ↦ R x + t`:
/// `Rᵀ (y − t)` (`R` orthogonal, row-major).
pub(crate) fn inverse_rigid_motion(
    rotation: &[[f64; 3]; 3],
    translation: [f64; 3],
    points: &[[f64; 3]],
) -> Vec<[f64; 3]> {
    points
        .iter()
        .map(|&y| {
            let d = sub(y, translation);
            [0, 1, 2].map(|j| (0..3).map(|i| rotation[i][j] * d[i]).sum())
        })
        .collect()
}

/// A smooth colouring by position in the camera's frame: red grows to the
/// right, green upwards, blue towards the viewer, over the square the
/// camera shows.
pub(crate) fn position_colours(points: &[[f64; 3]], camera: &Camera) -> Vec<[u8; 3]> {
    let h = camera.half_extent.max(f64::MIN_POSITIVE);
    let axes = [camera.right, camera.up, camera.toward_viewer()];
    points
        .iter()
        .map(|&p| {
            let d = sub(p, camera.centre);
            axes.map(|a| {
                let t = (0.5 + 0.5 * dot(d, a) / h).clamp(0.0, 1.0);
                (40.0 + 215.0 * t).round() as u8
            })
        })
        .collect()
}

/// For each source vertex, the target colours interpolated at its image
/// (a target face and barycentric coordinates); grey where the face is out
/// of range.
pub(crate) fn carried_colours(
    correspondence: &Correspondence,
    target_faces: &[[u32; 3]],
    target_colours: &[[u8; 3]],
) -> Vec<[u8; 3]> {
    correspondence
        .iter()
        .map(|&(face, bary)| {
            let corners = target_faces
                .get(face as usize)
                .and_then(|f| {
                    let c = f.map(|i| target_colours.get(i as usize).copied());
                    Some([c[0]?, c[1]?, c[2]?])
                })
                .unwrap_or([[128; 3]; 3]);
            [0, 1, 2].map(|d| {
                let v: f64 = (0..3).map(|k| bary[k] * f64::from(corners[k][d])).sum();
                v.round().clamp(0.0, 255.0) as u8
            })
        })
        .collect()
}

/// An oblique view of a crown from above: screen right along its longest
/// principal axis, looking down its least-spread axis from the side away
/// from its rim (the boundary), tilted 35° towards the second axis; the
/// square shown holds the whole surface.
pub(crate) fn crown_view(mesh: &Mesh) -> Camera {
    let axes = principal_axes(&mesh.vertices);
    let (centre, [a0, a1, a2]) = match axes {
        Some(p) => (p.centroid, p.axes),
        None => (
            [0.0; 3],
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        ),
    };
    let rim = boundary_vertices(mesh);
    let (sum, n) = mesh
        .vertices
        .iter()
        .zip(&rim)
        .filter(|(_, &b)| b)
        .fold(([0.0; 3], 0usize), |(s, n), (v, _)| {
            ([s[0] + v[0], s[1] + v[1], s[2] + v[2]], n + 1)
        });
    // The crown's top is on the side of its centroid away from the rim.
    let top = if n > 0 && dot(sub(centre, sum.map(|x| x / n as f64)), a2) < 0.0 {
        a2.map(|x| -x)
    } else {
        a2
    };
    let tilt = 35f64.to_radians();
    let toward = unit([0, 1, 2].map(|d| top[d] * tilt.cos() - a1[d] * tilt.sin()));
    let right = unit(a0);
    let up = unit(cross(toward, right));
    let half_extent = mesh
        .vertices
        .iter()
        .map(|&v| {
            let d = sub(v, centre);
            dot(d, right).abs().max(dot(d, up).abs())
        })
        .fold(0.0, f64::max)
        * 1.08;
    Camera {
        centre,
        right,
        up,
        half_extent: if half_extent > 0.0 { half_extent } else { 1.0 },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_inverse_motion_undoes_the_motion() {
        let (s, c) = (0.6f64.sin(), 0.6f64.cos());
        let r = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
        let t = [1.0, -2.0, 0.5];
        let x = [0.3, 0.7, -1.1];
        let y: [f64; 3] = [0, 1, 2].map(|i| (0..3).map(|j| r[i][j] * x[j]).sum::<f64>() + t[i]);
        let back = inverse_rigid_motion(&r, t, &[y]);
        for d in 0..3 {
            assert!((back[0][d] - x[d]).abs() < 1e-12);
        }
    }

    #[test]
    fn carried_colours_interpolate_the_target() {
        let faces = [[0, 1, 2]];
        let colours = [[0, 0, 0], [200, 0, 0], [0, 100, 0]];
        let corr = vec![
            (0, [0.5, 0.5, 0.0]),
            (0, [0.0, 0.0, 1.0]),
            (7, [1.0, 0.0, 0.0]),
        ];
        let out = carried_colours(&corr, &faces, &colours);
        assert_eq!(out, vec![[100, 0, 0], [0, 100, 0], [128, 128, 128]]);
    }

    #[test]
    fn a_moved_copy_lands_on_the_scan_and_carries_its_own_colours() {
        use morphoid_synth::mesh::{self as synth, RigidMotion, CROWN_GENERA};
        let mut settings = morphoid_data::pipeline::Settings::default();
        settings.clean.target_vertices = 1500;
        let crown = synth::crown(&CROWN_GENERA[0], 5, 1500);
        let moved = RigidMotion::random(9, 20.0).apply(&crown);
        let prepare = |m: &Mesh, name: &str| {
            morphoid_data::pipeline::prepare_mesh(m, name, &settings)
                .unwrap()
                .prepared
        };
        let (scan, reference) = (prepare(&moved, "scan"), prepare(&crown, "ref"));
        let refs = [SceneReference {
            name: "ref",
            distance: 0.0,
            prepared: &reference,
        }];
        let scene = Scene::build(&scan, &refs, &[], &settings.cp.compare);
        let p = &scene.pairings[0];
        // The reference, moved by the inverse rigid motion, lies on the
        // scan (area-1 surfaces: about 1 across; vertices ~0.03 apart).
        let nearest = |q: [f64; 3]| {
            scene
                .scan
                .vertices
                .iter()
                .map(|&v| morphoid_core::mesh::norm(sub(v, q)))
                .fold(f64::INFINITY, f64::min)
        };
        let n = p.aligned.vertices.len() as f64;
        let mean: f64 = p.aligned.vertices.iter().map(|&q| nearest(q)).sum::<f64>() / n;
        assert!(mean < 0.03, "mean offset {mean}");
        // Through a good map, each scan vertex gets about the colour of
        // its own position.
        let own = position_colours(&scene.scan.vertices, &scene.camera);
        let diff: f64 = own
            .iter()
            .zip(&p.carried)
            .map(|(a, b)| (0..3).map(|d| f64::from(a[d].abs_diff(b[d]))).sum::<f64>() / 3.0)
            .sum::<f64>()
            / own.len() as f64;
        assert!(diff < 12.0, "mean colour difference {diff}");
    }

    #[test]
    fn a_dome_is_seen_from_its_top() {
        // A cap z = 1 - x² - y² over a disk: rim at the bottom.
        let mesh = morphoid_core::mesh::unit_disk(60);
        let vertices: Vec<[f64; 3]> = mesh
            .vertices
            .iter()
            .map(|v| [v[0] * 2.0, v[1], 1.0 - v[0] * v[0] - v[1] * v[1]])
            .collect();
        let dome = Mesh::new(vertices, mesh.faces.clone());
        let cam = crown_view(&dome);
        // Looking from above (towards the viewer has +z) and x to the right.
        assert!(cam.toward_viewer()[2] > 0.5, "{cam:?}");
        assert!(cam.right[0].abs() > 0.99, "{cam:?}");
        let colours = position_colours(&dome.vertices, &cam);
        assert_eq!(colours.len(), dome.vertices.len());
    }
}
