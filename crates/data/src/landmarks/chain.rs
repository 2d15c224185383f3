//! Landmarks carried along a chain of surfaces: the route (given, or the
//! path between two specimens in the minimum spanning tree of a library's
//! cP distances, the paper's Figure 3) and the cP maps along it.

use super::{minimum_spanning_tree, propagate_along, tree_path};
use super::{Landmarks, PropagateError, Propagated, Surface};
use crate::pipeline::PreparedSurface;
use crate::table::csv_text::CsvString;
use crate::table::DistanceMatrix;
use morphoid_core::cp::{self, CompareParams, Directed};
use morphoid_core::mesh::{bbox_diagonal, Mesh};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Why landmarks cannot be carried along a chain.
#[derive(Debug, thiserror::Error)]
pub enum ChainError {
    /// The cleaned and prepared forms of a surface disagree, or a map
    /// does not fit its surfaces.
    #[error("surface `{name}`: {source}")]
    Surface {
        /// The surface.
        name: String,
        /// Why.
        #[source]
        source: PropagateError,
    },
    /// Propagating failed.
    #[error("propagating the landmarks: {0}")]
    Propagate(#[source] PropagateError),
    /// The spanning tree does not connect the two ends.
    #[error("the spanning tree does not connect `{from}` and `{to}`")]
    NotConnected {
        /// The reference.
        from: String,
        /// The target.
        to: String,
    },
}

/// The files of a route through a library: the library's specimens with
/// the reference and the target put in, and where those two are.
#[derive(Debug, Clone, PartialEq)]
pub struct Specimens {
    /// Names (file stems).
    pub names: Vec<String>,
    /// Surface files, one per name.
    pub files: Vec<PathBuf>,
    /// Index of the reference.
    pub from: usize,
    /// Index of the target.
    pub to: usize,
}

/// The library's specimens (`names`, `files`) with the reference `from`
/// and the target `to` added; a specimen of the same name is replaced by
/// the given file (the one the landmarks were placed on).
pub fn with_ends(names: Vec<String>, files: Vec<PathBuf>, from: &Path, to: &Path) -> Specimens {
    let mut s = Specimens {
        names,
        files,
        from: 0,
        to: 0,
    };
    let mut index_of = |file: &Path| {
        let name = crate::pipeline::specimen_name(file);
        match s.names.iter().position(|n| *n == name) {
            Some(i) => {
                s.files[i] = file.to_path_buf();
                i
            }
            None => {
                s.names.push(name);
                s.files.push(file.to_path_buf());
                s.files.len() - 1
            }
        }
    };
    let (f, t) = (index_of(from), index_of(to));
    s.from = f;
    s.to = t;
    s
}

/// The full matrix of cP distances between `surfaces` (named `names`):
/// entries that `known` holds (matched by name, finite) are taken from
/// it, the others computed in parallel. Also returns how many were
/// computed.
pub fn complete_distances(
    names: &[String],
    surfaces: &[PreparedSurface],
    known: Option<&DistanceMatrix>,
    params: &CompareParams,
) -> (Vec<Vec<f64>>, usize) {
    let n = surfaces.len();
    let lookup = |i: usize, j: usize| -> Option<f64> {
        let m = known?;
        let a = m.names().iter().position(|x| *x == names[i])?;
        let b = m.names().iter().position(|x| *x == names[j])?;
        Some(m.get(a, b)).filter(|d| d.is_finite())
    };
    let pairs: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .collect();
    let values: Vec<(f64, bool)> = pairs
        .par_iter()
        .map(|&(i, j)| match lookup(i, j) {
            Some(d) => (d, false),
            None => (
                cp::compare(&surfaces[i].prepared, &surfaces[j].prepared, params).distance,
                true,
            ),
        })
        .collect();
    let mut d = vec![vec![0.0; n]; n];
    for (&(i, j), &(v, _)) in pairs.iter().zip(&values) {
        d[i][j] = v;
        d[j][i] = v;
    }
    (d, values.iter().filter(|(_, computed)| *computed).count())
}

/// The path from `from` to `to` in the minimum spanning tree of the
/// distances `d`, both ends included.
pub fn spanning_tree_route(
    d: &[Vec<f64>],
    names: &[String],
    from: usize,
    to: usize,
) -> Result<Vec<usize>, ChainError> {
    let tree = minimum_spanning_tree(d);
    tree_path(d.len(), &tree, from, to).ok_or_else(|| ChainError::NotConnected {
        from: names.get(from).cloned().unwrap_or_default(),
        to: names.get(to).cloned().unwrap_or_default(),
    })
}

/// Landmarks carried along a route.
#[derive(Debug, Clone)]
pub struct Carried {
    /// The directed cP map of each step of the route.
    pub maps: Vec<Directed>,
    /// The landmarks on the last surface, and their offsets from the first.
    pub result: Propagated,
}

/// Carry `landmarks` (on `surfaces[route[0]]`, in its file units) along
/// `route` to its last surface: the directed cP map of each step (steps
/// in parallel), then the landmarks from surface to surface.
pub fn carry_along(
    landmarks: &Landmarks,
    surfaces: &[PreparedSurface],
    route: &[usize],
    params: &CompareParams,
) -> Result<Carried, ChainError> {
    let steps: Vec<(usize, usize)> = route.windows(2).map(|w| (w[0], w[1])).collect();
    let maps: Vec<Directed> = steps
        .par_iter()
        .map(|&(a, b)| cp::compare_directed(&surfaces[a].prepared, &surfaces[b].prepared, params))
        .collect();
    let along: Vec<Surface> = route
        .iter()
        .map(|&i| {
            Surface::from_prepared(&surfaces[i]).map_err(|source| ChainError::Surface {
                name: surfaces[i].prepared.name().to_string(),
                source,
            })
        })
        .collect::<Result<_, _>>()?;
    let along: Vec<&Surface> = along.iter().collect();
    let map_refs: Vec<&[(u32, [f64; 3])]> =
        maps.iter().map(|m| m.correspondence.as_slice()).collect();
    let result = propagate_along(landmarks, &along, &map_refs).map_err(ChainError::Propagate)?;
    Ok(Carried { maps, result })
}

/// How many landmarks lie more than 2 % of the bounding-box diagonal
/// from `surface` (usually a sign of other coordinates, e.g. RAS against
/// a surface in LPS), and the largest offset in percent of the diagonal;
/// `None` when all are close.
pub fn far_landmarks(surface: &Mesh, offsets: &[f64]) -> Option<(usize, f64)> {
    let diagonal = bbox_diagonal(surface);
    let far = offsets.iter().filter(|&&d| d > 0.02 * diagonal).count();
    let worst = offsets.iter().copied().fold(0.0, f64::max);
    (far > 0).then(|| (far, 100.0 * worst / diagonal))
}

/// The correspondence `forward` from `a` to `b` as CSV: for each vertex
/// of the cleaned `a` (in its file units), the triangle of `b`, the
/// barycentric coordinates in it and the image point in `b`'s file units.
pub fn correspondence_csv(
    a: &PreparedSurface,
    b: &PreparedSurface,
    forward: &Directed,
) -> Result<String, PropagateError> {
    let faces = b.prepared.faces().len();
    let mut w = CsvString::new();
    w.record([
        "vertex", "x", "y", "z", "face", "b0", "b1", "b2", "tx", "ty", "tz",
    ]);
    for (v, (x, &(face, bary))) in a
        .cleaned
        .vertices
        .iter()
        .zip(&forward.correspondence)
        .enumerate()
    {
        let out_of_range = PropagateError::FaceOutOfRange { face, faces };
        let tri = b.prepared.faces().get(face as usize).ok_or(out_of_range)?;
        let mut image = [0.0; 3];
        for (k, &corner) in tri.iter().enumerate() {
            let p =
                b.cleaned
                    .vertices
                    .get(corner as usize)
                    .ok_or(PropagateError::Inconsistent {
                        prepared: b.prepared.vertices().len(),
                        cleaned: b.cleaned.vertices.len(),
                    })?;
            for d in 0..3 {
                image[d] += bary[k] * p[d];
            }
        }
        let row = [
            v.to_string(),
            x[0].to_string(),
            x[1].to_string(),
            x[2].to_string(),
            face.to_string(),
            bary[0].to_string(),
            bary[1].to_string(),
            bary[2].to_string(),
            image[0].to_string(),
            image[1].to_string(),
            image[2].to_string(),
        ];
        w.record(&row);
    }
    Ok(w.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_join_or_replace_library_specimens() {
        let names = vec!["a".to_string(), "b".to_string()];
        let files = vec![PathBuf::from("lib/a.ply"), PathBuf::from("lib/b.ply")];
        let s = with_ends(names, files, Path::new("x/b.obj"), Path::new("y/c.ply"));
        assert_eq!(s.names, ["a", "b", "c"]);
        assert_eq!(s.files[1], PathBuf::from("x/b.obj"));
        assert_eq!((s.from, s.to), (1, 2));
    }

    #[test]
    fn route_follows_the_tree() {
        // A line a – b – c: a is far from c, so the route goes through b.
        let d = vec![
            vec![0.0, 1.0, 5.0],
            vec![1.0, 0.0, 1.0],
            vec![5.0, 1.0, 0.0],
        ];
        let names = ["a", "b", "c"].map(String::from);
        assert_eq!(spanning_tree_route(&d, &names, 0, 2).unwrap(), [0, 1, 2]);
        let cut = vec![vec![0.0, f64::NAN], vec![f64::NAN, 0.0]];
        let e = spanning_tree_route(&cut, &names[..2], 0, 1).unwrap_err();
        assert!(e.to_string().contains("`a` and `b`"), "{e}");
    }

    #[test]
    fn far_landmarks_are_counted() {
        let m = Mesh::new(vec![[0.0; 3], [3.0, 4.0, 0.0]], vec![]);
        assert_eq!(far_landmarks(&m, &[0.0, 0.05]), None);
        let (n, worst) = far_landmarks(&m, &[0.0, 0.2, 0.5]).unwrap();
        assert_eq!(n, 2);
        assert!((worst - 10.0).abs() < 1e-12);
    }
}
