//! The synthetic generators for this crate's unit tests.
//!
//! `morphoid-synth` builds on the non-test build of this crate, so its
//! meshes are of that build's `Mesh` type; these wrappers hand them over
//! field by field (the type is plain data).

pub(crate) mod synth {
    use crate::mesh::Mesh;
    pub(crate) use generators::CROWN_GENERA;
    use morphoid_synth::mesh as generators;

    fn own(m: generators::Mesh) -> Mesh {
        Mesh::new(m.vertices, m.faces)
    }

    fn theirs(m: &Mesh) -> generators::Mesh {
        generators::Mesh::new(m.vertices.clone(), m.faces.clone())
    }

    /// [`generators::crown`].
    pub(crate) fn crown(genus: &generators::CrownGenus, seed: u64, vertices: usize) -> Mesh {
        own(generators::crown(genus, seed, vertices))
    }

    /// [`generators::square_grid`].
    pub(crate) fn square_grid(n: u32) -> Mesh {
        own(generators::square_grid(n))
    }

    /// [`generators::square_annulus`].
    pub(crate) fn square_annulus() -> Mesh {
        own(generators::square_annulus())
    }

    /// [`generators::closed_sphere`].
    pub(crate) fn closed_sphere(vertices: usize) -> Mesh {
        own(generators::closed_sphere(vertices))
    }

    /// [`generators::rigid_motion`].
    pub(crate) fn rigid_motion(mesh: &Mesh, seed: u64) -> Mesh {
        own(generators::rigid_motion(&theirs(mesh), seed))
    }

    /// [`generators::scale`].
    pub(crate) fn scale(mesh: &Mesh, factor: f64) -> Mesh {
        own(generators::scale(&theirs(mesh), factor))
    }

    /// [`generators::mirror`].
    pub(crate) fn mirror(mesh: &Mesh) -> Mesh {
        own(generators::mirror(&theirs(mesh)))
    }
}
