//! Time of the `curvature` stage (Meyer et al., the default) on the Stanford bunny
//! (69,451 faces, when `../shared/data` has it) and on an 81,920-face bumpy sphere.
//!
//! Run: `cargo bench -p coarsen-benches --bench curvature`. The time covers the
//! whole stage: adjacency, per-face terms, per-vertex sums, the boundary rings and the
//! three attribute columns (the input mesh is cloned outside the timing). `topology_only`
//! times the adjacency build alone, the stage's one sequential phase.

use coarsen_mesh::Mesh;
use coarsen_stage::{Context, Stage, StageReport};
use coarsen_stage_curvature::{Curvature, CurvatureParams, Method};
use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use std::path::Path;

fn run(mesh: Mesh, original: &Mesh, params: &CurvatureParams) -> Mesh {
    let mut report = StageReport::default();
    let mut cx = Context::new(original, &mut report);
    Curvature::new(params.clone())
        .run(mesh, &mut cx)
        .expect("curvature runs")
}

fn case(c: &mut Criterion, name: &str, mesh: &Mesh) {
    let mut g = c.benchmark_group(name);
    g.throughput(Throughput::Elements(mesh.n_faces() as u64));
    for (label, method) in [
        ("meyer", Method::Meyer),
        ("angle-deficit", Method::AngleDeficit),
    ] {
        let params = CurvatureParams {
            method,
            ..Default::default()
        };
        g.bench_function(label, |b| {
            b.iter_batched(
                || mesh.clone(),
                |m| run(m, mesh, &params),
                BatchSize::LargeInput,
            )
        });
    }
    // The adjacency alone, for reference: the stage builds it first.
    g.bench_function("topology_only", |b| {
        b.iter(|| coarsen_mesh::Topology::build(std::hint::black_box(mesh)))
    });
    g.finish();
}

fn curvature(c: &mut Criterion) {
    let bunny =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/stanford-bunny.obj");
    match coarsen_io::read_path(&bunny, &Default::default()) {
        Ok(loaded) => case(c, "curvature_bunny", &loaded.mesh),
        Err(e) => eprintln!("skipping the bunny: {e}"),
    }
    let sphere = coarsen_shapes::bumpy_sphere(1.0, 6, 0.25, 7.0).expect("bumpy sphere");
    case(c, "curvature_bumpy_sphere_82k", &sphere);
}

criterion_group!(benches, curvature);
criterion_main!(benches);
