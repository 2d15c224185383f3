//! Time the cleaning pipeline on a tooth and on its 16× denser version
//! (two midpoint subdivisions), and print the triangle quality.
//!
//! `cargo run --release --example clean_timing [TOOTH.ply]`

use morphoid_core::clean::{clean, CleanOptions};
use morphoid_core::mesh::subdivide_midpoint;
use morphoid_core::mesh::{dot, norm, sub, Mesh};
use std::path::Path;
use std::time::Instant;

fn angles(m: &Mesh) -> (f64, f64, f64) {
    // (min angle, max angle in degrees, fraction of obtuse triangles)
    let (mut lo, mut hi, mut obtuse) = (180.0f64, 0.0f64, 0usize);
    for f in &m.faces {
        let p = f.map(|v| m.vertices[v as usize]);
        let mut mx = 0.0f64;
        for k in 0..3 {
            let (u, v) = (sub(p[(k + 1) % 3], p[k]), sub(p[(k + 2) % 3], p[k]));
            let a = (dot(u, v) / (norm(u) * norm(v)))
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees();
            lo = lo.min(a);
            mx = mx.max(a);
        }
        hi = hi.max(mx);
        if mx > 90.0 {
            obtuse += 1;
        }
    }
    (lo, hi, obtuse as f64 / m.faces.len() as f64)
}

fn main() {
    let path = std::env::args().nth(1).unwrap_or_else(|| {
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shared/data/pnas-teeth/meshes/J12.ply"
        )
        .to_string()
    });
    if !Path::new(&path).exists() {
        println!("skipped: data not found");
        return;
    }
    let tooth = match morphoid_data::mesh_io::load(Path::new(&path)) {
        Ok(loaded) => loaded.mesh,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    let dense = subdivide_midpoint(&tooth, 2);
    let opts = CleanOptions::default();
    let (a0, a1, ob) = angles(&tooth);
    println!(
        "input: {} vertices, angles {a0:.1}..{a1:.1}°, obtuse {:.1} %",
        tooth.vertices.len(),
        100.0 * ob
    );
    let cloud = morphoid_synth::mesh::to_point_cloud(&tooth);
    for (label, m) in [
        ("tooth", &tooth),
        ("16x denser", &dense),
        ("point cloud", &cloud),
    ] {
        let runs = 5;
        let t = Instant::now();
        let mut out = None;
        for _ in 0..runs {
            out = Some(clean(m, &opts));
        }
        let dt = t.elapsed().as_secs_f64() / runs as f64;
        match out {
            Some(Ok(c)) => {
                let (a0, a1, ob) = angles(&c.mesh);
                println!(
                    "{label}: {} -> {} vertices in {:.1} ms; angles {a0:.1}..{a1:.1}°, obtuse {:.1} %",
                    m.vertices.len(),
                    c.mesh.vertices.len(),
                    1e3 * dt,
                    100.0 * ob
                );
                println!(
                    "  report: {}",
                    serde_json::to_string(&c.report).unwrap_or_default()
                );
            }
            Some(Err(e)) => println!("{label}: error {e}"),
            None => {}
        }
    }
}
