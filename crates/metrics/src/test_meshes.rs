//! Small meshes for the tests.

use coarsen_mesh::Mesh;

/// Unit icosphere: the icosahedron split `level` times (20·4^level faces).
pub(crate) fn icosphere(level: u32) -> Mesh {
    coarsen_shapes::icosphere(1.0, level).expect("a valid icosphere level")
}
