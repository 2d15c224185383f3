//! The prepared surface: what [`prepare`](super::prepare) computes once per
//! surface and every comparison reads.

use super::error::{CpError, Inconsistency};
use super::locate::{LocateGrid, Location};
use super::moser::{disk_measure, is_disk_measure};
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

/// A surface ready for cP comparisons (cacheable).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Prepared {
    // The engine's parts read the fields directly; everyone else goes
    // through the accessors, so the layout stays the engine's business.
    /// Name of the specimen (set by the caller; used for matrices).
    pub(super) name: String,
    /// Vertices after normalization (area-weighted centroid at the origin,
    /// area 1).
    pub(super) vertices: Vec<[f64; 3]>,
    /// Faces, oriented so that the surface capped at its boundary has
    /// positive volume (a canonical orientation).
    pub(super) faces: Vec<[u32; 3]>,
    /// Whether the input faces were reversed to get that orientation.
    pub(super) reoriented: bool,
    /// Area-weighted centroid of the input surface.
    pub(super) centroid: [f64; 3],
    /// Square root of the input surface area (the size that was divided
    /// out).
    pub(super) scale: f64,
    /// Disk coordinates of the vertices.
    pub(super) uv: Vec<[f64; 2]>,
    /// Vertex areas of the normalized surface (sum 1).
    pub(super) vertex_areas: Vec<f64>,
    /// Smoothed hyperbolic conformal density at each vertex.
    pub(super) density: Vec<f64>,
    /// Feature vertices, strongest first.
    pub(super) features: Vec<u32>,
    /// Sample vertices.
    pub(super) samples: Vec<u32>,
    /// Voronoi-cell area of each sample (sum 1).
    pub(super) sample_weights: Vec<f64>,
    /// Point-location grid over the disk triangulation.
    pub(super) grid: LocateGrid,
    /// The vertices in breadth-first order, each as `[vertex, parent]`
    /// with the parent an earlier neighbour: mapping vertices in this
    /// order, each image is searched from a nearby one's triangle.
    pub(super) sweep: Vec<[u32; 2]>,
    /// The surface's area as a measure on the vertices of the fixed disk
    /// triangulation of the area correction (the target of the flow when
    /// this surface is the target); empty if it could not be computed.
    pub(super) disk_mass: Vec<f64>,
}

impl Prepared {
    /// Name of the specimen (empty unless the caller set one).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Name the specimen (matrices and cWn landscapes carry the name).
    pub fn set_name(&mut self, name: impl Into<String>) {
        self.name = name.into();
    }

    /// Vertices after normalization (area-weighted centroid at the origin,
    /// area 1), in the order of the input vertices.
    pub fn vertices(&self) -> &[[f64; 3]] {
        &self.vertices
    }

    /// Faces, oriented so that the surface capped at its boundary has
    /// positive volume; correspondences refer to these triangles and their
    /// corner order.
    pub fn faces(&self) -> &[[u32; 3]] {
        &self.faces
    }

    /// Whether the input faces were reversed to get that orientation.
    pub fn reoriented(&self) -> bool {
        self.reoriented
    }

    /// Area-weighted centroid of the input surface (file units).
    pub fn centroid(&self) -> [f64; 3] {
        self.centroid
    }

    /// Square root of the input surface area (the size that was divided
    /// out): a vertex in file units is `vertex · scale + centroid`.
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// The vertices in the file's units (`vertex · scale + centroid`), in
    /// the order of [`Prepared::vertices`].
    pub fn vertices_in_file_units(&self) -> Vec<[f64; 3]> {
        self.vertices
            .iter()
            .map(|v| [0, 1, 2].map(|d| v[d] * self.scale + self.centroid[d]))
            .collect()
    }

    /// For a surface prepared from a mesh given in units where the file's
    /// are `v · scale + centroid` (a part cut from another prepared
    /// surface's normalized vertices): its [`Prepared::scale`] and
    /// [`Prepared::centroid`] made to refer to the file's units. Nothing
    /// the comparisons read changes.
    pub fn refer_to_file_units(&mut self, scale: f64, centroid: [f64; 3]) {
        self.centroid = [0, 1, 2].map(|d| centroid[d] + scale * self.centroid[d]);
        self.scale *= scale;
    }

    /// Disk coordinates of the vertices (the conformal flattening).
    pub fn uv(&self) -> &[[f64; 2]] {
        &self.uv
    }

    /// Vertex areas of the normalized surface (sum 1).
    pub fn vertex_areas(&self) -> &[f64] {
        &self.vertex_areas
    }

    /// Smoothed hyperbolic conformal density at each vertex.
    pub fn density(&self) -> &[f64] {
        &self.density
    }

    /// Feature vertices, strongest first.
    pub fn features(&self) -> &[u32] {
        &self.features
    }

    /// Sample vertices, in farthest-point order.
    pub fn samples(&self) -> &[u32] {
        &self.samples
    }

    /// Voronoi-cell area of each sample (sum 1).
    pub fn sample_weights(&self) -> &[f64] {
        &self.sample_weights
    }

    /// Locate a point of the disk in the flattened triangulation (see
    /// [`Location`]); `None` only for a surface without triangles.
    pub fn locate(&self, z: [f64; 2]) -> Option<Location> {
        self.grid.locate(&self.uv, &self.faces, z)
    }

    /// Locate `z` as [`Prepared::locate`] does, walking from the triangle
    /// `hint` (the triangle of a nearby point, or
    /// [`NO_TRIANGLE`](super::locate::NO_TRIANGLE)).
    #[inline]
    pub(super) fn locate_near(&self, z: [f64; 2], hint: u32) -> Option<Location> {
        self.grid.locate_near(&self.uv, &self.faces, z, hint)
    }

    /// The surface's area as a measure on the fixed disk triangulation of
    /// the area correction: the one computed at preparation, or computed
    /// now if that one is missing. `None` if it cannot be computed.
    pub(super) fn disk_measure(&self) -> Option<Cow<'_, [f64]>> {
        if is_disk_measure(&self.disk_mass) {
            Some(Cow::Borrowed(&self.disk_mass))
        } else {
            disk_measure(&self.uv, &self.vertex_areas, &self.sweep).map(Cow::Owned)
        }
    }

    /// The same surface with its flattening composed with `map` (another
    /// flattening of it when `map` is a disk automorphism).
    #[cfg(test)]
    pub(crate) fn reflattened(&self, map: impl Fn([f64; 2]) -> [f64; 2]) -> Self {
        let mut p = self.clone();
        p.uv = self.uv.iter().map(|&z| map(z)).collect();
        p.grid = LocateGrid::build(&p.uv, &p.faces);
        p.disk_mass = disk_measure(&p.uv, &p.vertex_areas, &p.sweep).unwrap_or_default();
        p
    }

    /// Check internal consistency (lengths and indices), e.g. after reading
    /// a cached copy.
    pub fn validate(&self) -> Result<(), CpError> {
        let n = self.vertices.len();
        let bad = |what| Err(CpError::Inconsistent(what));
        if self.uv.len() != n || self.vertex_areas.len() != n || self.density.len() != n {
            return bad(Inconsistency::VertexArrays);
        }
        if self.faces.iter().flatten().any(|&v| v as usize >= n)
            || self
                .features
                .iter()
                .chain(&self.samples)
                .any(|&v| v as usize >= n)
        {
            return bad(Inconsistency::IndexOutOfRange);
        }
        if self.samples.len() != self.sample_weights.len() || self.samples.is_empty() {
            return bad(Inconsistency::Samples);
        }
        if !self.grid.fits(self.faces.len()) {
            return bad(Inconsistency::LocateGrid);
        }
        let mut seen = vec![false; n];
        for &[v, parent] in &self.sweep {
            let Some(&parent_seen) = seen.get(parent as usize) else {
                return bad(Inconsistency::SweepIndex);
            };
            let Some(s) = seen.get_mut(v as usize) else {
                return bad(Inconsistency::SweepIndex);
            };
            if *s || !(parent_seen || parent == v) {
                return bad(Inconsistency::SweepOrder);
            }
            *s = true;
        }
        if self.sweep.len() != n {
            return bad(Inconsistency::SweepIncomplete);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cp::{prepare, PrepareParams};
    use crate::testing::synth;

    fn crown() -> Prepared {
        let genus = &synth::CROWN_GENERA[0];
        prepare(&synth::crown(genus, 1, 1500), &PrepareParams::default()).expect("prepare")
    }

    #[test]
    fn a_prepared_surface_is_consistent_and_its_sweep_visits_every_vertex_once() {
        let p = crown();
        p.validate().expect("consistent");
        assert_eq!(p.sweep.len(), p.vertices.len());
        assert_eq!(p.grid.adjacency.len(), p.faces.len());
        let total: f64 = p.disk_mass.iter().sum();
        assert!((total - 1.0).abs() < 1e-9, "disk measure total {total}");
    }

    #[test]
    fn damaged_walk_data_is_caught() {
        let p = crown();
        let err = |q: &Prepared| match q.validate() {
            Err(CpError::Inconsistent(what)) => Some(what),
            _ => None,
        };
        let mut q = p.clone();
        q.sweep.swap(1, 5);
        q.sweep.swap(0, 4);
        assert_eq!(err(&q), Some(Inconsistency::SweepOrder), "a child first");
        let mut q = p.clone();
        q.sweep.pop();
        assert_eq!(err(&q), Some(Inconsistency::SweepIncomplete));
        let mut q = p.clone();
        q.grid.adjacency[0][0] = q.faces.len() as u32;
        assert_eq!(err(&q), Some(Inconsistency::LocateGrid), "a neighbour");
        let mut q = p.clone();
        q.samples.push(q.vertices.len() as u32);
        assert_eq!(err(&q), Some(Inconsistency::IndexOutOfRange));
        let mut q = p.clone();
        q.sample_weights.pop();
        assert_eq!(err(&q), Some(Inconsistency::Samples));
        let mut q = p;
        q.density.pop();
        assert_eq!(err(&q), Some(Inconsistency::VertexArrays));
    }

    #[test]
    fn a_missing_disk_measure_is_computed_again() {
        let p = crown();
        let stored = p.disk_measure().expect("measure").into_owned();
        let mut q = p.clone();
        q.disk_mass.clear();
        let again = q.disk_measure().expect("measure");
        assert!(matches!(again, Cow::Owned(_)));
        assert_eq!(again.as_ref(), stored.as_slice());
    }

    #[test]
    fn accessors_and_location_agree_with_the_data() {
        let mut p = crown();
        p.set_name("tooth");
        assert_eq!(p.name(), "tooth");
        let v = p.samples()[0] as usize;
        let loc = p.locate(p.uv()[v]).expect("located");
        let f = p.faces()[loc.face as usize];
        let z: [f64; 2] =
            [0, 1].map(|d| (0..3).map(|k| loc.bary[k] * p.uv()[f[k] as usize][d]).sum());
        assert!((z[0] - p.uv()[v][0]).hypot(z[1] - p.uv()[v][1]) < 1e-12);
        let total: f64 = p.sample_weights().iter().sum();
        assert!((total - 1.0).abs() < 1e-9);
        assert_eq!(p.density().len(), p.vertices().len());
    }
}
