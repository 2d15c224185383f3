//! Correspondences over a whole collection: the template's vertices
//! carried to every specimen, either directly (one cP map from the
//! template) or step by step along the minimum spanning tree of the cP
//! distances (so each map joins two similar specimens). Either way every
//! specimen receives one image of the template, so the maps between two
//! specimens that go through the template are consistent by construction:
//! `A → B → C → A` returns to the start.

use morphoid_core::cp::{self, CompareParams, Handedness, Prepared};
use morphoid_core::mesh::Mesh;
use morphoid_data::landmarks::{
    self, minimum_spanning_tree, surface_point, Landmarks, PropagateError, Surface,
};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// How the template is carried to the specimens.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Consistency {
    /// Along the minimum spanning tree of the distances, from the template.
    SpanningTree,
    /// One cP map from the template to each specimen.
    Direct,
    /// Along the minimum spanning tree, then synchronized with the maps
    /// from each specimen's nearest neighbours (see `sync`).
    Synchronized(super::SyncParams),
}

impl Consistency {
    /// How many directed cP maps carrying the template to `n` specimens
    /// takes (at most, for the synchronization: neighbours may be fewer).
    pub fn maps(&self, n: usize) -> usize {
        let steps = n.saturating_sub(1);
        match self {
            Consistency::SpanningTree | Consistency::Direct => steps,
            Consistency::Synchronized(p) => steps + steps * p.neighbours.min(steps),
        }
    }
}

/// The specimen whose summed distance to all others is smallest (the
/// medoid); non-finite distances count as missing; ties go to the lower
/// index. `None` for an empty matrix.
pub fn medoid(d: &[Vec<f64>]) -> Option<usize> {
    let sum = |i: usize| -> f64 { d[i].iter().filter(|v| v.is_finite()).sum() };
    let mut best: Option<(usize, f64)> = None;
    for i in 0..d.len() {
        let s = sum(i);
        if best.is_none_or(|(_, b)| s < b) {
            best = Some((i, s));
        }
    }
    best.map(|(i, _)| i)
}

/// The steps `(from, to)` that carry the template `root` to every
/// specimen, in an order where each `from` is reached before it is left:
/// breadth-first over the minimum spanning tree of `d` (children in index
/// order; the synchronization starts from it), or `(root, i)` for every
/// other `i`. Specimens the tree does not reach (non-finite distances) get
/// no step.
pub(crate) fn carrying_steps(d: &[Vec<f64>], root: usize, how: Consistency) -> Vec<(usize, usize)> {
    let n = d.len();
    match how {
        Consistency::Direct => (0..n).filter(|&i| i != root).map(|i| (root, i)).collect(),
        Consistency::SpanningTree | Consistency::Synchronized(_) => {
            let mut adjacency = vec![Vec::new(); n];
            for (a, b) in minimum_spanning_tree(d) {
                adjacency[a].push(b);
                adjacency[b].push(a);
            }
            for list in &mut adjacency {
                list.sort_unstable();
            }
            let mut seen = vec![false; n];
            let mut steps = Vec::with_capacity(n.saturating_sub(1));
            let mut queue = std::collections::VecDeque::new();
            if root < n {
                seen[root] = true;
                queue.push_back(root);
            }
            while let Some(u) = queue.pop_front() {
                for &v in &adjacency[u] {
                    if !seen[v] {
                        seen[v] = true;
                        steps.push((u, v));
                        queue.push_back(v);
                    }
                }
            }
            steps
        }
    }
}

/// The template's vertices on every specimen.
#[derive(Debug, Clone)]
pub struct TemplateImages {
    /// For each specimen, the image of each template vertex (on that
    /// specimen's surface, in its file units); `None` where no step
    /// reaches it.
    pub images: Vec<Option<Vec<[f64; 3]>>>,
    /// Whether the composed map to each specimen reverses orientation (an
    /// odd number of mirror-image steps).
    pub reflected: Vec<bool>,
    /// The directed cP distance of each step, in the order of the steps.
    pub step_distances: Vec<f64>,
}

/// Why the template cannot be carried.
#[derive(Debug, thiserror::Error)]
pub enum CarryError {
    /// Carrying points from one surface to the next failed.
    #[error("carrying the template from `{from}` to `{to}`: {source}")]
    Step {
        /// The surface carried from.
        from: String,
        /// The surface carried to.
        to: String,
        /// Why.
        #[source]
        source: PropagateError,
    },
}

/// The directed cP map of each `(from, to)` pair, computed in parallel, in
/// the order given; `progress` gets the count of maps done so far.
pub(crate) fn directed_maps(
    prepared: &[Prepared],
    pairs: &[(usize, usize)],
    params: &CompareParams,
    progress: impl Fn(usize) + Sync,
) -> Vec<cp::Directed> {
    let done = AtomicUsize::new(0);
    pairs
        .par_iter()
        .map(|&(a, b)| {
            let _span =
                tracing::info_span!("map", from = %prepared[a].name(), to = %prepared[b].name())
                    .entered();
            let m = cp::compare_directed(&prepared[a], &prepared[b], params);
            progress(done.fetch_add(1, Ordering::Relaxed) + 1);
            m
        })
        .collect()
}

/// Carry the vertices of `surfaces[root]` along `steps` (each `from`
/// reached before it is left; see [`carrying_steps`]): the directed cP map
/// of every step (in parallel; `progress` receives the number done), then
/// the images from surface to surface. `surfaces[i]` is the surface of
/// `prepared[i]` in file units ([`Surface::from_normalized`]).
pub(crate) fn carry_template(
    prepared: &[Prepared],
    surfaces: &[Surface],
    root: usize,
    steps: &[(usize, usize)],
    params: &CompareParams,
    progress: impl Fn(usize) + Sync,
) -> Result<TemplateImages, CarryError> {
    let maps = directed_maps(prepared, steps, params, progress);
    let n = surfaces.len();
    let mut images: Vec<Option<Vec<[f64; 3]>>> = vec![None; n];
    let mut reflected = vec![false; n];
    images[root] = Some(surfaces[root].mesh().vertices.clone());
    for (&(a, b), map) in steps.iter().zip(&maps) {
        let err = |source| CarryError::Step {
            from: prepared[a].name().to_string(),
            to: prepared[b].name().to_string(),
            source,
        };
        let from = images[a]
            .clone()
            .ok_or_else(|| err(PropagateError::InvalidSurface))?;
        let carried = landmarks::propagate(
            &Landmarks::from_points(from),
            &surfaces[a],
            &surfaces[b],
            &map.correspondence,
        )
        .map_err(err)?;
        images[b] = Some(carried.landmarks.points().to_vec());
        reflected[b] = reflected[a] ^ map.reflected;
    }
    Ok(TemplateImages {
        images,
        reflected,
        step_distances: maps.iter().map(|m| m.distance).collect(),
    })
}

impl TemplateImages {
    /// The handedness each specimen's configuration is fitted with.
    pub fn handedness(&self) -> Vec<Handedness> {
        self.reflected
            .iter()
            .map(|&r| {
                if r {
                    Handedness::Improper
                } else {
                    Handedness::Proper
                }
            })
            .collect()
    }
}

/// The point of `to` that corresponds to the point `p` of a specimen
/// through the template: `p` is located on `from_template` (the template's
/// triangles on the first specimen: its vertex images with the template's
/// faces), the same triangle and barycentric coordinates are taken on
/// `to_images` (the template's vertex images on the second specimen) and
/// the result is projected onto `to`. `None` when the images do not fit
/// the faces.
pub fn transfer_through_template(
    p: [f64; 3],
    from_template: &Surface,
    to_images: &[[f64; 3]],
    to: &Surface,
) -> Option<[f64; 3]> {
    let at = surface_point(from_template, p);
    let point = super::MeshPoint {
        face: at.face,
        bary: at.bary,
    };
    let q = point.position(to_images, &from_template.mesh().faces)?;
    Some(to.closest(q))
}

/// The template's triangles laid on a specimen: its vertex images with
/// the template's faces, as a surface to locate points on.
pub fn template_on(
    images: &[[f64; 3]],
    template_faces: &[[u32; 3]],
) -> Result<Surface, PropagateError> {
    Surface::new(Mesh::new(images.to_vec(), template_faces.to_vec()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn medoid_and_steps() {
        // Points on a line at 0, 1, 2.5, 4: the medoid is 1 (or 2; 1 is
        // lower and has the smaller sum: 1+1.5+3 = 5.5 vs 2.5+1.5+1.5 = 5.5).
        let x: [f64; 4] = [0.0, 1.0, 2.5, 4.0];
        let d: Vec<Vec<f64>> = x
            .iter()
            .map(|a| x.iter().map(|b| (a - b).abs()).collect())
            .collect();
        assert_eq!(medoid(&d), Some(1));
        assert_eq!(medoid(&[]), None);
        assert_eq!(
            carrying_steps(&d, 1, Consistency::SpanningTree),
            vec![(1, 0), (1, 2), (2, 3)]
        );
        assert_eq!(
            carrying_steps(&d, 1, Consistency::Direct),
            vec![(1, 0), (1, 2), (1, 3)]
        );
        let mut cut = d.clone();
        for row in cut.iter_mut().take(3) {
            row[3] = f64::NAN;
        }
        cut[3] = vec![f64::NAN, f64::NAN, f64::NAN, 0.0];
        assert_eq!(
            carrying_steps(&cut, 0, Consistency::SpanningTree),
            vec![(0, 1), (1, 2)]
        );
    }
}
