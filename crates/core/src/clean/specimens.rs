//! Several specimens in one surface file: the closed components of a batch
//! export, each to be cleaned and identified on its own.
//!
//! A component is a specimen when it is closed (or nearly: every hole
//! small, as [`super::NEARLY_CLOSED`] says), holds at least
//! [`SPECIMEN_SHARE`] of the largest component's area, and lies inside no
//! other closed component (a pulp cavity, a root canal or a crack exported
//! as an inner surface belongs to the tooth around it). Everything else is
//! debris, counted. Only a file with two or more specimens is split: one
//! specimen (with or without debris) goes to [`super::clean`] whole, as
//! before, and an open crop is never split.

use super::components::face_components;
use super::faces::remove_unreferenced_vertices;
use super::weld::weld_vertices;
use super::NEARLY_CLOSED;
use crate::mesh::{
    bbox_diagonal, bounding_box, face_areas, point_inside_by_parity, widest_boundary_loop_extent,
    Mesh,
};

/// A closed component is a specimen of its own when its area is at least
/// this share of the largest component's; smaller ones are fragments.
pub(super) const SPECIMEN_SHARE: f64 = 0.2;

/// At most this many small components are tested for lying inside a
/// specimen; the rest count as debris.
const MAX_NESTED_CHECKS: usize = 256;

/// A component's lowest corner, highest corner and one of its vertices.
type BoxAndPoint = ([f64; 3], [f64; 3], [f64; 3]);

/// The specimens of a surface file that holds several.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceSpecimens {
    /// Each specimen's surface, in order along the longest axis of the
    /// file's bounding box (by the centre of each specimen's box).
    pub parts: Vec<Mesh>,
    /// Components dropped as debris or fragments (open, or too small).
    pub debris: usize,
    /// Closed components inside another (cavities, canals, cracks).
    pub nested: usize,
}

/// The specimens of `mesh` when it holds two or more (see the module
/// documentation), else `None`. `weld_tolerance` is the cleaning's, as a
/// share of the bounding-box diagonal: a triangle soup is welded first to
/// see its components.
pub fn surface_specimens(mesh: &Mesh, weld_tolerance: f64) -> Option<SurfaceSpecimens> {
    if mesh.faces.len() < 8 {
        return None;
    }
    let welded;
    let m = if is_soup(mesh) {
        welded = weld_vertices(mesh, weld_tolerance * bbox_diagonal(mesh)).0;
        &welded
    } else {
        mesh
    };
    let (labels, count) = face_components(m);
    if count < 2 {
        return None;
    }
    let large = large_components(m, &labels, count);
    // The common case, one large component and debris: nothing to split,
    // and nothing more to compute on a surface of millions of faces.
    if large.len() < 2 {
        return None;
    }
    let closed = closed_parts(m, &labels, &large);
    if closed.len() < 2 {
        return None;
    }
    let boxes: Vec<([f64; 3], [f64; 3])> = closed
        .iter()
        .map(|p| bounding_box(p).unwrap_or(([0.0; 3], [0.0; 3])))
        .collect();
    let outer = outermost_parts(&closed, &boxes);
    let nested_parts = closed.len() - outer.len();
    if outer.len() < 2 {
        return None;
    }
    let order = in_order_along_longest_axis(m, outer, &boxes)?;
    let nested =
        nested_parts + nested_small_components(m, &labels, count, &large, &order, &closed, &boxes);
    let debris = count - order.len() - nested;
    let mut closed: Vec<Option<Mesh>> = closed.into_iter().map(Some).collect();
    let parts = order.iter().filter_map(|&k| closed[k].take()).collect();
    Some(SurfaceSpecimens {
        parts,
        debris,
        nested,
    })
}

/// Whether `mesh` is a triangle soup (about three vertices a face) that
/// must be welded to show its components; a surface that shares its
/// vertices has them already.
fn is_soup(mesh: &Mesh) -> bool {
    mesh.vertices.len() >= mesh.faces.len()
}

/// The components (by face `labels`, `count` of them) holding at least
/// [`SPECIMEN_SHARE`] of the largest one's area.
fn large_components(m: &Mesh, labels: &[u32], count: usize) -> Vec<usize> {
    let mut area = vec![0.0; count];
    for (l, a) in labels.iter().zip(face_areas(m)) {
        area[*l as usize] += a;
    }
    let largest = area.iter().copied().fold(0.0, f64::max);
    (0..count)
        .filter(|&c| area[c] >= SPECIMEN_SHARE * largest)
        .collect()
}

/// The `large` components of `m` as surfaces of their own, those closed
/// or nearly (every hole small), in the order of `large`.
fn closed_parts(m: &Mesh, labels: &[u32], large: &[usize]) -> Vec<Mesh> {
    let part = |c: usize| {
        let faces = m
            .faces
            .iter()
            .zip(labels)
            .filter_map(|(f, &l)| (l as usize == c).then_some(*f))
            .collect();
        remove_unreferenced_vertices(&Mesh::new(m.vertices.clone(), faces))
    };
    large
        .iter()
        .map(|&c| part(c))
        .filter(|p| {
            widest_boundary_loop_extent(p)
                .is_none_or(|extent| extent < NEARLY_CLOSED * bbox_diagonal(p))
        })
        .collect()
}

/// The indices of the `closed` parts that lie inside no other (by their
/// `boxes`, then by ray parity from one vertex).
fn outermost_parts(closed: &[Mesh], boxes: &[([f64; 3], [f64; 3])]) -> Vec<usize> {
    let inside = |i: usize, j: usize| {
        let (a, b) = (boxes[i], boxes[j]);
        (0..3).all(|k| a.0[k] >= b.0[k] && a.1[k] <= b.1[k])
            && closed[i]
                .vertices
                .first()
                .is_some_and(|&p| point_inside_by_parity(&closed[j], p))
    };
    (0..closed.len())
        .filter(|&i| !(0..closed.len()).any(|j| j != i && inside(i, j)))
        .collect()
}

/// The `outer` parts in order along the longest axis of `m`'s bounding
/// box, by the centre of each of their `boxes` (`None` when `m` has no
/// box).
fn in_order_along_longest_axis(
    m: &Mesh,
    outer: Vec<usize>,
    boxes: &[([f64; 3], [f64; 3])],
) -> Option<Vec<usize>> {
    let (lo, hi) = bounding_box(m)?;
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])).then(b.cmp(&a)))
        .unwrap_or(0);
    let mut order = outer;
    order.sort_by(|&a, &b| {
        let c = |k: usize| boxes[k].0[axis] + boxes[k].1[axis];
        c(a).total_cmp(&c(b)).then(a.cmp(&b))
    });
    Some(order)
}

/// How many of the small components (not `large`) lie inside one of the
/// specimens (`order` indexes `closed` and `boxes`): a cavity, a canal.
/// Each test casts rays through a specimen, so a crowd of crumbs is
/// checked only as far as [`MAX_NESTED_CHECKS`]; the rest are debris.
fn nested_small_components(
    m: &Mesh,
    labels: &[u32],
    count: usize,
    large: &[usize],
    order: &[usize],
    closed: &[Mesh],
    boxes: &[([f64; 3], [f64; 3])],
) -> usize {
    small_component_boxes(m, labels, count, large)
        .into_iter()
        .flatten()
        .take(MAX_NESTED_CHECKS)
        .filter(|&(a, b, p)| {
            order.iter().any(|&k| {
                let (lo, hi) = boxes[k];
                (0..3).all(|i| a[i] >= lo[i] && b[i] <= hi[i])
                    && point_inside_by_parity(&closed[k], p)
            })
        })
        .count()
}

/// Each small component's box and one of its vertices (`None` for the
/// `large` ones), in one pass over the faces.
fn small_component_boxes(
    m: &Mesh,
    labels: &[u32],
    count: usize,
    large: &[usize],
) -> Vec<Option<BoxAndPoint>> {
    let mut small_box: Vec<Option<BoxAndPoint>> = vec![None; count];
    for (f, &l) in m.faces.iter().zip(labels) {
        let l = l as usize;
        if large.contains(&l) {
            continue;
        }
        for &v in f {
            let p = m.vertices[v as usize];
            let b = small_box[l].get_or_insert((p, p, p));
            for i in 0..3 {
                b.0[i] = b.0[i].min(p[i]);
                b.1[i] = b.1[i].max(p[i]);
            }
        }
    }
    small_box
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed ball (an icosahedron) of radius `r` around `c`.
    fn ball(c: [f64; 3], r: f64) -> Mesh {
        let m = crate::testing::synth::closed_sphere(12);
        Mesh::new(
            m.vertices
                .iter()
                .map(|p| [0, 1, 2].map(|i| c[i] + r * p[i]))
                .collect(),
            m.faces,
        )
    }

    fn join(parts: &[Mesh]) -> Mesh {
        let mut out = Mesh::new(Vec::new(), Vec::new());
        for p in parts {
            let base = out.vertices.len() as u32;
            out.vertices.extend(&p.vertices);
            out.faces
                .extend(p.faces.iter().map(|f| f.map(|i| i + base)));
        }
        out
    }

    #[test]
    fn three_closed_specimens_come_in_order_with_the_nested_and_small_dropped() {
        let m = join(&[
            ball([20.0, 0.0, 0.0], 3.0),
            ball([0.0, 0.0, 0.0], 3.0),
            // A cavity inside the second specimen.
            ball([0.0, 0.0, 0.0], 2.0),
            ball([10.0, 0.5, 0.0], 2.5),
            // Debris.
            ball([5.0, 5.0, 5.0], 0.3),
        ]);
        let s = surface_specimens(&m, 1e-9).unwrap();
        assert_eq!((s.parts.len(), s.nested, s.debris), (3, 1, 1));
        let xs: Vec<f64> = s
            .parts
            .iter()
            .map(|p| bounding_box(p).unwrap().0[0])
            .collect();
        assert!(xs[0] < xs[1] && xs[1] < xs[2], "{xs:?}");
    }

    #[test]
    fn one_specimen_with_a_cavity_or_debris_is_not_split() {
        let m = join(&[
            ball([0.0, 0.0, 0.0], 3.0),
            ball([0.0, 0.0, 0.0], 2.0),
            ball([9.0, 0.0, 0.0], 0.5),
        ]);
        assert_eq!(surface_specimens(&m, 1e-9), None);
    }
}
