//! Benchmarks of the metrics (`cargo bench -p coarsen-benches --bench metrics`).
//!
//! * `measure/sphere 70K vs 10K`: the full report of a ~70K-face sphere against a
//!   ~10K-face one (two latitude–longitude tessellations of the same sphere);
//! * `measure/bunny 70K vs clustered 10K`: the raw Stanford bunny against a ~10K-face
//!   grid-clustered copy of itself, when `../shared/data` is present;
//! * `hausdorff/fidelity 70K vs 10K`: the sampled two-sided distances alone;
//! * `hausdorff/closest point`: the spatial index alone, queried with points just off
//!   the surface;
//! * `hausdorff/face samples`: the forward direction's pattern, ten points on each face
//!   of the 70K sphere against the 10K sphere's tree, one tree walk per point or the
//!   points of one face answered from one gathering;
//! * `bvh/build 70K`: building the spatial index;
//! * with `COARSEN_BENCH_LARGE=1` only: `measure/sphere 4M vs 10K` and `bvh/build 4M`.
//!
//! `cargo bench -p coarsen-benches --bench scale -- CASE` times the same cases once
//! each, with the thread count and peak memory.

use coarsen_mesh::DVec3;
use coarsen_metrics::{FidelityOptions, MetricsOptions, fidelity, measure};
use coarsen_spatial::{Bvh, NearSet};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;

use coarsen_benches::meshes;

fn large() -> bool {
    std::env::var_os("COARSEN_BENCH_LARGE").is_some_and(|v| v == "1")
}

fn bench_measure(c: &mut Criterion) {
    let (fine, coarse) = meshes::spheres_70k_10k();
    eprintln!("sphere faces: {} vs {}", fine.n_faces(), coarse.n_faces());
    let opts = MetricsOptions::default();
    let mut g = c.benchmark_group("measure");
    g.sample_size(10);
    g.bench_function("sphere 70K vs 10K", |b| {
        b.iter(|| measure(Some(&fine), &coarse, &opts).unwrap())
    });
    if let Some(bunny) = meshes::read_obj(&meshes::bunny_path()) {
        let coarse_bunny = meshes::grid_clustered(&bunny, 45.0);
        eprintln!(
            "bunny faces: {} vs {}",
            bunny.n_faces(),
            coarse_bunny.n_faces()
        );
        g.bench_function("bunny 70K vs clustered 10K", |b| {
            b.iter(|| measure(Some(&bunny), &coarse_bunny, &opts).unwrap())
        });
    } else {
        eprintln!("skipped bunny: ../shared/data not found");
    }
    if large() {
        let huge = meshes::sphere_4m();
        eprintln!("large sphere faces: {}", huge.n_faces());
        g.bench_function("sphere 4M vs 10K", |b| {
            b.iter(|| measure(Some(&huge), &coarse, &opts).unwrap())
        });
    }
    g.finish();
}

/// Points just off the unit sphere, spread over it (a golden-angle spiral).
fn spiral(n: usize) -> Vec<DVec3> {
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let phi = i as f64 * 2.399_963_229_728_653;
            let r = (1.0 - z * z).sqrt();
            DVec3::new(r * phi.cos(), r * phi.sin(), z) * (1.0 + 0.01 * (i % 7) as f64)
        })
        .collect()
}

fn bench_hausdorff(c: &mut Criterion) {
    let (fine, coarse) = meshes::spheres_70k_10k();
    let mut g = c.benchmark_group("hausdorff");
    g.sample_size(10);
    let opts = FidelityOptions::default();
    g.bench_function("fidelity 70K vs 10K", |b| {
        b.iter(|| fidelity(&fine, &coarse, &opts).unwrap())
    });
    let bvh = Bvh::build(&fine.positions, &fine.faces);
    let n = 100_000;
    let points = spiral(n);
    g.throughput(Throughput::Elements(n as u64));
    g.bench_with_input(
        BenchmarkId::new("closest point", "70K faces"),
        &points,
        |b, pts| {
            b.iter(|| {
                pts.iter()
                    .map(|p| bvh.closest_point(*p).map_or(0.0, |h| h.distance_squared))
                    .sum::<f64>()
            })
        },
    );
    // The forward direction's pattern: ten points on each face of the 70K sphere,
    // measured against the 10K sphere's tree, one walk per point or one gathering per face.
    let tree = Bvh::build(&coarse.positions, &coarse.faces);
    let faces: Vec<(DVec3, f64, [DVec3; 10])> = (0..fine.n_faces())
        .map(|f| {
            let [a, b, c] = fine.corners(f);
            let centre = (a + b + c) / 3.0;
            let radius = [a, b, c]
                .iter()
                .map(|x| (*x - centre).length())
                .fold(0.0, f64::max);
            let points = std::array::from_fn(|j| {
                let (u, v) = (
                    (j as f64 * 0.618_034).fract(),
                    (j as f64 * 0.381_966).fract(),
                );
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                a + (b - a) * u + (c - a) * v
            });
            (centre, radius, points)
        })
        .collect();
    g.throughput(Throughput::Elements(10 * faces.len() as u64));
    g.bench_with_input(
        BenchmarkId::new("face samples", "one walk per point"),
        &faces,
        |b, faces| {
            b.iter(|| {
                let mut sum = 0.0;
                for (_, _, points) in faces {
                    for p in points {
                        sum += tree.closest_point(*p).map_or(0.0, |h| h.distance_squared);
                    }
                }
                sum
            })
        },
    );
    g.bench_with_input(
        BenchmarkId::new("face samples", "one gathering per face"),
        &faces,
        |b, faces| {
            let mut set = NearSet::new();
            b.iter(|| {
                let mut sum = 0.0;
                for (centre, radius, points) in faces {
                    tree.gather_near(*centre, *radius, 32, &mut set);
                    for p in points {
                        sum += tree
                            .closest_point_near(&set, *p)
                            .map_or(0.0, |h| h.distance_squared);
                    }
                }
                sum
            })
        },
    );
    g.finish();
}

fn bench_bvh(c: &mut Criterion) {
    let (fine, _) = meshes::spheres_70k_10k();
    let mut g = c.benchmark_group("bvh");
    g.sample_size(20);
    g.bench_function("build 70K", |b| {
        b.iter(|| Bvh::build(black_box(&fine.positions), black_box(&fine.faces)))
    });
    if large() {
        let huge = meshes::sphere_4m();
        g.sample_size(10);
        g.bench_function("build 4M", |b| {
            b.iter(|| Bvh::build(black_box(&huge.positions), black_box(&huge.faces)))
        });
    }
    g.finish();
}

criterion_group!(benches, bench_measure, bench_hausdorff, bench_bvh);
criterion_main!(benches);
