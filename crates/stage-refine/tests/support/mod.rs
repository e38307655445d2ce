//! Shared by the tests and the benchmark: the real meshes and the curvature field.

use coarsen_mesh::{AttrValues, Mesh};

/// A real mesh of `../shared/data`, cleaned as the CLI cleans it; `None` (with a printed
/// message) when the directory is absent.
pub fn load(name: &str) -> Option<Mesh> {
    coarsen_testdata::cleaned(name)
}

/// `mesh` with the `curvature` stage's hybrid curvature F (default estimator) as the
/// vertex attribute `hybrid_curvature`.
pub fn with_curvature(mut mesh: Mesh) -> Mesh {
    let e = coarsen_stage_curvature::estimate(&mesh, &Default::default()).expect("curvature");
    mesh.vertex_attrs.insert(
        coarsen_stage_curvature::HYBRID,
        AttrValues::Scalar(e.hybrid),
    );
    mesh
}
