//! Shared by the tests and the benchmark: the real meshes and the curvature field.

use coarsen_mesh::{AttrValues, HygieneOptions, Mesh, clean};
use std::path::PathBuf;

/// A real mesh of `../shared/data`, cleaned as the CLI cleans it; `None` (with a printed
/// message) when the directory is absent.
pub fn load(name: &str) -> Option<Mesh> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(name);
    if !path.exists() {
        println!("skipped: {} is absent", path.display());
        return None;
    }
    let mesh = coarsen_io::read_path(&path, &Default::default())
        .expect("the mesh loads")
        .mesh;
    Some(
        clean(mesh, &HygieneOptions::default())
            .expect("the mesh cleans")
            .0,
    )
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
