//! Several phantoms scanned together: side by side along x, their lower
//! part in a block of textured foam (batch scanning of loose teeth).

use morphoid_core::mesh::Grid;
use rand::{Rng, SeedableRng};

/// `teeth` (phantoms of one scan: the same sampling) side by side along x,
/// `gap` samples apart and aligned at the bottom, with foam of grey `foam`
/// (±`texture`, in cells 3 samples wide) filling the lower `fill` of the
/// stack around them. Air is the first phantom's corner value.
pub fn batch_in_foam(
    teeth: &[Grid],
    gap: usize,
    foam: f32,
    texture: f32,
    fill: f64,
    seed: u64,
) -> Grid {
    let air = teeth.first().map_or(0.0, |g| g.values[0]);
    let width =
        teeth.iter().map(|g| g.dims[0]).sum::<usize>() + gap * teeth.len().saturating_sub(1);
    let dims = [
        width.max(1),
        teeth.iter().map(|g| g.dims[1]).max().unwrap_or(1),
        teeth.iter().map(|g| g.dims[2]).max().unwrap_or(1),
    ];
    let spacing = teeth.first().map_or([1.0; 3], |g| g.spacing);
    let mut out = Grid::filled(dims, [0.0; 3], spacing, air);
    let mut x0 = 0;
    for g in teeth {
        let y0 = (dims[1] - g.dims[1]) / 2;
        for z in 0..g.dims[2] {
            for y in 0..g.dims[1] {
                for x in 0..g.dims[0] {
                    let i = out.index(x0 + x, y0 + y, z);
                    out.values[i] = g.values[g.index(x, y, z)];
                }
            }
        }
        x0 += g.dims[0] + gap;
    }
    // Foam where the scan shows air, up to the fill height.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let cell = 3;
    let cells = dims.map(|d| d / cell + 1);
    let grey: Vec<f32> = (0..cells[0] * cells[1] * cells[2])
        .map(|_| foam + rng.gen_range(-texture..texture))
        .collect();
    let top = (fill * dims[2] as f64) as usize;
    for z in 0..top.min(dims[2]) {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let i = out.index(x, y, z);
                let v = out.values[i];
                if v < foam {
                    let c = grey[x / cell + cells[0] * (y / cell + cells[1] * (z / cell))];
                    out.values[i] = v.max(c);
                }
            }
        }
    }
    out
}
