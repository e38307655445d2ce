//! Timing of curvature + `refine.red-green` on the Stanford bunny (when `../shared/data`
//! has it): the `curvature` stage's estimate of F, then the refinement passes to λ ≥ 2 with
//! the default parameters, and a single pass alone.
//!
//! `cargo bench -p coarsen-benches --bench refine`.

use coarsen_mesh::Mesh;
use coarsen_stage_refine::{RefineParams, refine};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

#[path = "../../stage-refine/tests/support/mod.rs"]
mod support;

fn bench(c: &mut Criterion) {
    let Some(bunny) = support::load("stanford-bunny.obj") else {
        return;
    };
    let with_f = support::with_curvature(bunny.clone());
    let mut group = c.benchmark_group("refine");
    group.sample_size(20);
    group.bench_function("bunny: curvature + red-green to λ ≥ 2", |b| {
        b.iter(|| {
            let m: Mesh = support::with_curvature(black_box(&bunny).clone());
            refine(m, &RefineParams::default()).expect("refines").0
        })
    });
    let one_pass = RefineParams {
        max_passes: 1,
        ..RefineParams::default()
    };
    group.bench_function("bunny: one red-green pass", |b| {
        b.iter(|| {
            refine(black_box(&with_f).clone(), &one_pass)
                .expect("refines")
                .0
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
