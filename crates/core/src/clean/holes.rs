//! Hole filling.

use crate::mesh::{boundary_loops_by_length, Mesh};

/// Fill every boundary loop except the longest (by geometric length; the
/// others are filled longest first, see [`boundary_loops_by_length`]): a
/// triangle for a 3-loop, otherwise a fan around a new vertex at the loop's
/// centroid, oriented like the surrounding faces. Expects a consistently oriented manifold
/// mesh. Returns the mesh and the number of holes filled.
pub(super) fn fill_holes_except_longest(mesh: &Mesh) -> (Mesh, usize) {
    fill_loops(mesh, 1)
}

/// Fill every boundary loop, closing the surface (see
/// [`fill_holes_except_longest`] for how). Returns the mesh and the number
/// of holes filled.
pub(super) fn fill_all_holes(mesh: &Mesh) -> (Mesh, usize) {
    fill_loops(mesh, 0)
}

/// Fill the boundary loops after the `keep` longest.
fn fill_loops(mesh: &Mesh, keep: usize) -> (Mesh, usize) {
    let loops = boundary_loops_by_length(mesh);
    let mut out = mesh.clone();
    let mut filled = 0;
    for lp in loops.iter().skip(keep) {
        let n = lp.len();
        if n < 3 {
            continue;
        }
        // Boundary half-edges run lp[i] → lp[i+1]; the patch runs them back.
        if n == 3 {
            out.faces.push([lp[2], lp[1], lp[0]]);
        } else {
            let mut c = [0.0; 3];
            for &v in lp {
                for d in 0..3 {
                    c[d] += mesh.vertices[v as usize][d] / n as f64;
                }
            }
            let ci = out.vertices.len() as u32;
            out.vertices.push(c);
            for i in 0..n {
                out.faces.push([lp[(i + 1) % n], lp[i], ci]);
            }
        }
        filled += 1;
    }
    (out, filled)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{boundary_loops, euler_characteristic};

    use crate::testing::synth::square_annulus as annulus;

    #[test]
    fn disk_with_a_hole_is_filled() {
        let m = annulus();
        assert_eq!(euler_characteristic(&m), 0);
        let loops = boundary_loops_by_length(&m);
        assert_eq!(loops.len(), 2);
        assert_eq!(loops[0].len(), 12);
        let (f, n) = fill_holes_except_longest(&m);
        assert_eq!(n, 1);
        assert_eq!(euler_characteristic(&f), 1);
        assert_eq!(boundary_loops(&f).len(), 1);
        // The patch vertex is at the hole's centre.
        assert_eq!(f.vertices.last().copied(), Some([1.5, 1.5, 0.0]));
        // Orientation stays consistent: every interior edge is used once in
        // each direction.
        let mut dir = std::collections::HashSet::new();
        for t in &f.faces {
            for k in 0..3 {
                assert!(dir.insert((t[k], t[(k + 1) % 3])));
            }
        }
    }
}
