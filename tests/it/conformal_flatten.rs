//! Conformal flattening against surfaces whose conformal map to the disk is
//! known in closed form, plus the error cases.

use morphoid_core::conformal::{
    conformal_factor, cotangent_edge_weights, flatten_to_disk, flatten_to_disk_with,
    flipped_triangles, normalize, quasi_conformal_ratios, FlattenError, LaplacianWeights,
};
use morphoid_core::mesh::Mesh;
use std::f64::consts::{PI, TAU};

type C = (f64, f64);

fn cmul(a: C, b: C) -> C {
    (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
}
fn cdiv(a: C, b: C) -> C {
    let d = b.0 * b.0 + b.1 * b.1;
    ((a.0 * b.0 + a.1 * b.1) / d, (a.1 * b.0 - a.0 * b.1) / d)
}
fn cabs(a: C) -> f64 {
    a.0.hypot(a.1)
}
/// Disk automorphism z ↦ (z − a)/(1 − ā z).
fn mobius(z: C, a: C) -> C {
    cdiv(
        (z.0 - a.0, z.1 - a.1),
        (1.0 - (a.0 * z.0 + a.1 * z.1), -(a.0 * z.1 - a.1 * z.0)),
    )
}

/// Concentric-ring triangulation of the unit disk: a centre vertex and
/// `rings` rings, ring k with 6k vertices at radius k/rings, each ring
/// turned by an irrational fraction of its spacing so there is no symmetry.
/// Returns planar positions (as complex numbers) and CCW faces.
fn ring_disk(rings: usize) -> (Vec<C>, Vec<[u32; 3]>) {
    let mut pts = vec![(0.0, 0.0)];
    let mut angles: Vec<Vec<f64>> = vec![vec![]];
    let mut start = vec![0usize];
    for k in 1..=rings {
        let n = 6 * k;
        let offset = ((k as f64 * 0.618_034) % 1.0) * 0.9 * TAU / n as f64;
        start.push(pts.len());
        let a: Vec<f64> = (0..n).map(|i| offset + TAU * i as f64 / n as f64).collect();
        let r = k as f64 / rings as f64;
        pts.extend(a.iter().map(|t| (r * t.cos(), r * t.sin())));
        angles.push(a);
    }
    let mut faces = Vec::new();
    for j in 0..6u32 {
        faces.push([0, 1 + j, 1 + (j + 1) % 6]);
    }
    for k in 2..=rings {
        let (a, b) = (&angles[k - 1], &angles[k]);
        let (na, nb) = (a.len(), b.len());
        let (sa, sb) = (start[k - 1] as u32, start[k] as u32);
        let ang = |v: &Vec<f64>, i: usize| v[i % v.len()] + TAU * (i / v.len()) as f64;
        let (mut i, mut j) = (0, 0);
        while i < na || j < nb {
            let ai = sa + (i % na) as u32;
            let bj = sb + (j % nb) as u32;
            if j < nb && (i == na || ang(b, j + 1) <= ang(a, i + 1)) {
                faces.push([ai, bj, sb + ((j + 1) % nb) as u32]);
                j += 1;
            } else {
                faces.push([ai, bj, sa + ((i + 1) % na) as u32]);
                i += 1;
            }
        }
    }
    (pts, faces)
}

fn planar(pts: &[C], faces: Vec<[u32; 3]>) -> Mesh {
    Mesh::new(pts.iter().map(|p| [p.0, p.1, 0.0]).collect(), faces)
}

fn uv_c(uv: &[[f64; 2]]) -> Vec<C> {
    uv.iter().map(|z| (z[0], z[1])).collect()
}

/// Largest deviation between `got` and `e^{iφ} want` after the best-fitting
/// rotation φ (least squares), over the vertices `keep` selects.
fn error_up_to_rotation(got: &[C], want: &[C], keep: impl Fn(usize) -> bool) -> f64 {
    let mut s = (0.0, 0.0);
    for i in (0..got.len()).filter(|&i| keep(i)) {
        s = {
            let p = cmul(got[i], (want[i].0, -want[i].1));
            (s.0 + p.0, s.1 + p.1)
        };
    }
    let rot = (s.0 / cabs(s), s.1 / cabs(s));
    (0..got.len())
        .filter(|&i| keep(i))
        .map(|i| {
            let w = cmul(rot, want[i]);
            cabs((got[i].0 - w.0, got[i].1 - w.1))
        })
        .fold(0.0, f64::max)
}

fn check_disk_invariants(mesh: &Mesh, uv: &[[f64; 2]]) {
    assert_eq!(flipped_triangles(&mesh.faces, uv), 0);
    let mut on_boundary = vec![false; mesh.vertices.len()];
    for v in morphoid_core::mesh::boundary_loops(mesh).concat() {
        on_boundary[v as usize] = true;
    }
    for (v, z) in uv.iter().enumerate() {
        let r = z[0].hypot(z[1]);
        if on_boundary[v] {
            assert!((r - 1.0).abs() < 1e-9, "boundary vertex {v} at radius {r}");
        } else {
            assert!(r < 1.0, "interior vertex {v} at radius {r}");
        }
    }
}

#[test]
fn planar_disk_maps_to_itself() {
    let mut errors = Vec::new();
    for rings in [8, 16, 32] {
        let (pts, faces) = ring_disk(rings);
        let mesh = planar(&pts, faces);
        let map = flatten_to_disk(&mesh).unwrap();
        assert_eq!(map.center, 0, "the centre vertex is the most central");
        check_disk_invariants(&mesh, &map.uv);
        errors.push(error_up_to_rotation(&uv_c(&map.uv), &pts, |_| true));
    }
    println!("planar disk, max error for 8/16/32 rings: {errors:?}");
    assert!(errors[2] < 1e-4, "{errors:?}");
    assert!(errors[2] < errors[1] && errors[1] < errors[0], "{errors:?}");
}

#[test]
fn mobius_image_of_a_disk_maps_back_by_a_mobius_transformation() {
    // Vertices moved by a disk automorphism: the mesh still covers the unit
    // disk, now unevenly. The flattening sends the chosen centre c to 0, so
    // it must be z ↦ e^{iφ} m_c(z).
    let a = (0.35, -0.2);
    let (pts, faces) = ring_disk(32);
    let moved: Vec<C> = pts.iter().map(|&z| mobius(z, a)).collect();
    let mesh = planar(&moved, faces);
    let map = flatten_to_disk(&mesh).unwrap();
    check_disk_invariants(&mesh, &map.uv);
    let c = moved[map.center as usize];
    let want: Vec<C> = moved.iter().map(|&z| mobius(z, c)).collect();
    let err = error_up_to_rotation(&uv_c(&map.uv), &want, |_| true);
    println!("Möbius-distorted disk: max error {err:.2e}");
    assert!(err < 5e-4, "{err}");
}

/// Spherical cap of polar angle `alpha` on the unit sphere, with the ring
/// topology of [`ring_disk`]; CCW seen from outside.
fn spherical_cap(rings: usize, alpha: f64) -> (Mesh, Vec<f64>) {
    let (pts, faces) = ring_disk(rings);
    let mut polar = Vec::new();
    let vertices = pts
        .iter()
        .map(|&(x, y)| {
            let r = x.hypot(y);
            let phi = alpha * r;
            polar.push(phi);
            let (c, s) = if r > 0.0 { (x / r, y / r) } else { (1.0, 0.0) };
            [phi.sin() * c, phi.sin() * s, phi.cos()]
        })
        .collect();
    (Mesh::new(vertices, faces), polar)
}

#[test]
fn spherical_cap_matches_stereographic_projection() {
    // Stereographic projection from the south pole is conformal and sends
    // polar angle φ to radius tan(φ/2); scaled to the unit disk it is the
    // flattening with the north pole at 0, up to rotation.
    let alpha = 0.6 * PI;
    let t = (alpha / 2.0).tan();
    let mut errors = Vec::new();
    for rings in [12, 24] {
        let (mesh, polar) = spherical_cap(rings, alpha);
        let map = flatten_to_disk(&mesh).unwrap();
        assert_eq!(map.center, 0);
        check_disk_invariants(&mesh, &map.uv);
        let want: Vec<C> = mesh
            .vertices
            .iter()
            .zip(&polar)
            .map(|(p, &phi)| {
                let r = (phi / 2.0).tan() / t;
                let h = p[0].hypot(p[1]);
                if h > 0.0 {
                    (r * p[0] / h, r * p[1] / h)
                } else {
                    (0.0, 0.0)
                }
            })
            .collect();
        errors.push(error_up_to_rotation(&uv_c(&map.uv), &want, |_| true));
        if rings == 24 {
            // Conformal factor: area element of the sphere over dx dy,
            // 4 t² / (1 + t² |z|²)², away from the boundary.
            let f = conformal_factor(&mesh, &map.uv);
            let (mut worst, mut sum, mut count) = (0.0f64, 0.0, 0);
            for (z, fv) in map.uv.iter().zip(&f) {
                let r2 = z[0] * z[0] + z[1] * z[1];
                if r2 < 0.8 {
                    let exact = 4.0 * t * t / (1.0 + t * t * r2).powi(2);
                    let e = (fv / exact - 1.0).abs();
                    worst = worst.max(e);
                    sum += e;
                    count += 1;
                }
            }
            let mean = sum / count as f64;
            println!(
                "spherical cap: conformal-factor relative error mean {mean:.3e}, worst {worst:.3e}"
            );
            // Per-vertex star ratios carry the mesh's irregularity (valence
            // changes between rings); the average is what matters.
            assert!(mean < 0.02, "{mean}");
            assert!(worst < 0.08, "{worst}");
            let mut q = quasi_conformal_ratios(&mesh, &map.uv);
            q.sort_by(f64::total_cmp);
            assert!(q[q.len() / 2] < 1.05);
        }
    }
    println!("spherical cap, max error for 12/24 rings: {errors:?}");
    assert!(errors[1] < 5e-4, "{errors:?}");
    assert!(errors[1] < errors[0], "{errors:?}");
}

/// The Schwarz–Christoffel map of the disk onto a square,
/// `F(w) = ∫₀^w (1 − t⁴)^{−1/2} dt = Σ c_n w^{4n+1}/(4n+1)`, with
/// `c_n = binom(2n, n)/4ⁿ` (for |w| ≤ 0.95).
fn disk_to_square(w: C) -> C {
    let w4 = cmul(cmul(w, w), cmul(w, w));
    let mut term = w; // w^{4n+1}
    let mut c = 1.0;
    let mut sum = (0.0, 0.0);
    for n in 0..2000 {
        if n > 0 {
            c *= (2 * n - 1) as f64 / (2 * n) as f64;
            term = cmul(term, w4);
        }
        let k = c / (4 * n + 1) as f64;
        sum = (sum.0 + k * term.0, sum.1 + k * term.1);
        if cabs(term) < 1e-17 {
            break;
        }
    }
    sum
}

#[test]
fn square_matches_its_schwarz_christoffel_map() {
    // F maps 1 to K = Γ(1/4)²/(4√(2π)), the corners of the square on the
    // axes. Mesh: a grid of the square with corners (±1, 0), (0, ±1).
    const K: f64 = 1.311_028_777_146_059_9;
    let n = 24usize;
    let idx = |i: usize, j: usize| (j * (n + 1) + i) as u32;
    let mut pts = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (
                -1.0 + 2.0 * i as f64 / n as f64,
                -1.0 + 2.0 * j as f64 / n as f64,
            );
            pts.push(((x - y) / 2.0, (x + y) / 2.0));
        }
    }
    let mut faces = Vec::new();
    for j in 0..n {
        for i in 0..n {
            // Alternate the diagonals so the grid has no preferred direction.
            if (i + j) % 2 == 0 {
                faces.push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
                faces.push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
            } else {
                faces.push([idx(i, j), idx(i + 1, j), idx(i, j + 1)]);
                faces.push([idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)]);
            }
        }
    }
    let mesh = planar(&pts, faces);
    let map = flatten_to_disk(&mesh).unwrap();
    assert_eq!(map.center, idx(n / 2, n / 2));
    check_disk_invariants(&mesh, &map.uv);
    // The corner (1, 0) is vertex (n, 0); it must map to the preimage of K,
    // i.e. 1, after rotating by −arg.
    let corner = map.uv[idx(n, 0) as usize];
    let r = corner[0].hypot(corner[1]);
    let rot = (corner[0] / r, -corner[1] / r);
    let mut worst: f64 = 0.0;
    for (z, p) in map.uv.iter().zip(&pts) {
        let w = cmul(rot, (z[0], z[1]));
        if cabs(w) <= 0.9 {
            let f = disk_to_square(w);
            worst = worst.max(cabs((f.0 / K - p.0, f.1 / K - p.1)));
        }
    }
    println!("square: max error of F(z)/K against the mesh, |z| ≤ 0.9: {worst:.3e}");
    assert!(worst < 2e-3, "{worst}");
}

#[test]
fn reflected_surface_gives_reflected_map() {
    // A mirror image with outward normals kept (x negated, faces reversed)
    // must flatten to the complex conjugate of the original map, up to
    // rotation: counter-clockwise faces stay counter-clockwise.
    let (mesh, _) = spherical_cap(16, 0.5 * PI);
    let map = flatten_to_disk(&mesh).unwrap();
    let mirror = Mesh::new(
        mesh.vertices.iter().map(|p| [-p[0], p[1], p[2]]).collect(),
        mesh.faces.iter().map(|f| [f[0], f[2], f[1]]).collect(),
    );
    let mmap = flatten_to_disk(&mirror).unwrap();
    assert_eq!(flipped_triangles(&mirror.faces, &mmap.uv), 0);
    let conj: Vec<C> = uv_c(&map.uv).iter().map(|z| (z.0, -z.1)).collect();
    let err = error_up_to_rotation(&uv_c(&mmap.uv), &conj, |_| true);
    assert!(err < 1e-9, "{err}");
    // ... and is not the map itself up to rotation.
    let direct = error_up_to_rotation(&uv_c(&mmap.uv), &uv_c(&map.uv), |_| true);
    assert!(direct > 0.1, "{direct}");
}

#[test]
fn rigid_motion_and_scaling_do_not_change_the_map() {
    let (mut mesh, _) = spherical_cap(16, 0.55 * PI);
    // Break the symmetry so that the centre is decided by geometry.
    for (i, p) in mesh.vertices.iter_mut().enumerate() {
        let s = 1.0 + 0.05 * ((i as f64 * 1.7).sin());
        *p = [p[0] * s, p[1] * s * 1.2, p[2] * s];
    }
    let map = flatten_to_disk(&normalize(&mesh).unwrap().mesh).unwrap();
    let (c, s) = (0.3f64.cos(), 0.3f64.sin());
    let moved = Mesh::new(
        mesh.vertices
            .iter()
            .map(|p| {
                [
                    7.5 * (c * p[0] - s * p[2]) + 3.0,
                    7.5 * p[1] - 1.0,
                    7.5 * (s * p[0] + c * p[2]) + 0.5,
                ]
            })
            .collect(),
        mesh.faces.clone(),
    );
    let map2 = flatten_to_disk(&normalize(&moved).unwrap().mesh).unwrap();
    assert_eq!(map.center, map2.center);
    let d = map
        .uv
        .iter()
        .zip(&map2.uv)
        .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
        .fold(0.0, f64::max);
    assert!(d < 1e-9, "{d}");
}

#[test]
fn closed_surface_is_not_a_disk() {
    // Octahedron.
    let v = vec![
        [1., 0., 0.],
        [-1., 0., 0.],
        [0., 1., 0.],
        [0., -1., 0.],
        [0., 0., 1.],
        [0., 0., -1.],
    ];
    let f = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    let err = flatten_to_disk(&Mesh::new(v, f)).unwrap_err();
    assert_eq!(
        err,
        FlattenError::NotDisk {
            boundary_loops: 0,
            euler_characteristic: 2
        }
    );
    assert!(err.to_string().contains("not a topological disk"));
}

#[test]
fn annulus_is_not_a_disk() {
    // The disk with its centre fan removed: two boundary loops.
    let (pts, faces) = ring_disk(6);
    let faces: Vec<[u32; 3]> = faces.into_iter().filter(|f| !f.contains(&0)).collect();
    // Drop the now unused centre vertex and shift indices.
    let faces = faces.iter().map(|f| f.map(|v| v - 1)).collect();
    let mesh = planar(&pts[1..], faces);
    assert_eq!(
        flatten_to_disk(&mesh).unwrap_err(),
        FlattenError::NotDisk {
            boundary_loops: 2,
            euler_characteristic: 0
        }
    );
}

#[test]
fn degenerate_meshes_give_errors_not_nan() {
    // All vertices on a line.
    let (pts, faces) = ring_disk(3);
    let line: Vec<C> = pts.iter().map(|p| (p.0, 0.0)).collect();
    let err = flatten_to_disk(&planar(&line, faces.clone())).unwrap_err();
    assert!(matches!(err, FlattenError::Degenerate { .. }), "{err}");
    assert!(matches!(
        normalize(&planar(&line, faces.clone())),
        Err(FlattenError::Degenerate { .. })
    ));
    // One collapsed face.
    let mut squashed = pts.clone();
    squashed[0] = (0.5 * (pts[1].0 + pts[2].0), 0.5 * (pts[1].1 + pts[2].1));
    let err = flatten_to_disk(&planar(&squashed, faces.clone())).unwrap_err();
    assert!(matches!(err, FlattenError::Degenerate { .. }), "{err}");
    // NaN coordinate.
    let mut nan = pts.clone();
    nan[5].1 = f64::NAN;
    assert_eq!(
        flatten_to_disk(&planar(&nan, faces.clone())).unwrap_err(),
        FlattenError::NonFinite { vertex: 5 }
    );
    // A single triangle has no interior vertex.
    let tri = planar(&[(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)], vec![[0, 1, 2]]);
    assert!(matches!(
        flatten_to_disk(&tri),
        Err(FlattenError::Degenerate { .. })
    ));
    assert_eq!(
        flatten_to_disk(&Mesh::default()).unwrap_err(),
        FlattenError::Empty
    );
}

#[test]
fn disk_map_round_trips_through_json() {
    let (pts, faces) = ring_disk(4);
    let map = flatten_to_disk(&planar(&pts, faces)).unwrap();
    let json = serde_json::to_string(&map).unwrap();
    let back: morphoid_core::conformal::DiskMap = serde_json::from_str(&json).unwrap();
    assert_eq!(back.center, map.center);
    for (a, b) in back.uv.iter().zip(&map.uv) {
        // serde_json's default float parser may be off by one unit in the
        // last place.
        assert!((a[0] - b[0]).abs() <= 1e-15 && (a[1] - b[1]).abs() <= 1e-15);
    }
}

#[test]
fn badly_shaped_triangles_still_give_an_embedding() {
    // On a spherical cap, insert vertices just inside edges (each splits a
    // face into three, one of them a sliver with an angle near π): the
    // cotangent weights opposite those angles are strongly negative and the
    // new vertices have only three edges, which intrinsic flips cannot fix.
    let alpha = 0.6 * PI;
    let (mut mesh, _) = spherical_cap(12, alpha);
    let n0 = mesh.vertices.len();
    let mut split = 0;
    for fi in (7..mesh.faces.len()).step_by(23) {
        let [a, b, c] = mesh.faces[fi];
        let [pa, pb, pc] = [a, b, c].map(|v| mesh.vertices[v as usize]);
        // 2% of the way from the midpoint of ab towards c, back on the sphere.
        let q: [f64; 3] = std::array::from_fn(|k| {
            let m = 0.5 * (pa[k] + pb[k]);
            m + 0.02 * (pc[k] - m)
        });
        let r = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
        let v = mesh.vertices.len() as u32;
        mesh.vertices.push(q.map(|x| x / r));
        mesh.faces[fi] = [a, b, v];
        mesh.faces.push([b, c, v]);
        mesh.faces.push([c, a, v]);
        split += 1;
    }
    let negative = cotangent_edge_weights(&mesh)
        .iter()
        .filter(|&&(_, w)| w < -0.5)
        .count();
    assert!(negative >= split, "{negative} strongly negative weights");
    let map = flatten_to_disk(&mesh).unwrap();
    check_disk_invariants(&mesh, &map.uv);
    // No squeezed image: the slivers stay proper triangles.
    let q = quasi_conformal_ratios(&mesh, &map.uv);
    let worst = q.iter().copied().fold(0.0, f64::max);
    // Away from the inserted vertices the map is still the scaled
    // stereographic projection up to rotation.
    let t = (alpha / 2.0).tan();
    let want: Vec<C> = mesh
        .vertices
        .iter()
        .map(|p| {
            let phi = p[2].clamp(-1.0, 1.0).acos();
            let h = p[0].hypot(p[1]);
            let r = (phi / 2.0).tan() / t;
            if h > 0.0 {
                (r * p[0] / h, r * p[1] / h)
            } else {
                (0.0, 0.0)
            }
        })
        .collect();
    let err = error_up_to_rotation(&uv_c(&map.uv), &want, |i| i < n0);
    println!("cap with {split} slivers: max error {err:.2e}, worst ratio {worst:.1}");
    assert!(worst < 1e3, "{worst}");
    assert!(err < 1e-2, "{err}");
    match flatten_to_disk_with(&mesh, LaplacianWeights::IntrinsicDelaunay) {
        Ok(m) => println!(
            "intrinsic Delaunay alone: worst ratio {:.3e}",
            quasi_conformal_ratios(&mesh, &m.uv)
                .iter()
                .copied()
                .fold(0.0, f64::max)
        ),
        Err(e) => println!("intrinsic Delaunay alone: {e}"),
    }
    // The clamped extrinsic Laplacian is an embedding too (Tutte).
    let clamped = flatten_to_disk_with(&mesh, LaplacianWeights::ClampedCotangent).unwrap();
    assert_eq!(flipped_triangles(&mesh.faces, &clamped.uv), 0);
}
