//! Benchmarks of the metrics (`cargo bench -p coarsen-metrics`).
//!
//! * `measure/sphere 70K vs 10K`: the full report of a ~70K-face sphere against a
//!   ~10K-face one (two latitude–longitude tessellations of the same sphere);
//! * `measure/bunny 70K vs clustered 10K`: the raw Stanford bunny against a ~10K-face
//!   grid-clustered copy of itself, when `../shared/data` is present;
//! * `bvh/build 70K` and `bvh/closest point`: the spatial index alone, queried with points
//!   near the surface (the Hausdorff query pattern);
//! * `measure/sphere 4M vs 10K`: the large case, only with `COARSEN_BENCH_LARGE=1`.

use coarsen_mesh::{DVec3, Mesh};
use coarsen_metrics::{MetricsOptions, measure};
use coarsen_spatial::Bvh;
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use std::collections::HashMap;
use std::hint::black_box;
use std::path::PathBuf;

/// Latitude–longitude sphere of radius 1: `2·segments·(rings − 1)` faces.
fn uv_sphere(rings: u32, segments: u32) -> Mesh {
    let mut positions = vec![DVec3::Z, -DVec3::Z];
    for r in 1..rings {
        let theta = std::f64::consts::PI * r as f64 / rings as f64;
        for s in 0..segments {
            let phi = std::f64::consts::TAU * s as f64 / segments as f64;
            positions.push(DVec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ));
        }
    }
    let ring = |r: u32, s: u32| 2 + (r - 1) * segments + s % segments;
    let mut faces = Vec::new();
    for s in 0..segments {
        faces.push([0, ring(1, s), ring(1, s + 1)]);
        faces.push([1, ring(rings - 1, s + 1), ring(rings - 1, s)]);
    }
    for r in 1..rings - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (
                ring(r, s),
                ring(r, s + 1),
                ring(r + 1, s),
                ring(r + 1, s + 1),
            );
            faces.push([a, c, d]);
            faces.push([a, d, b]);
        }
    }
    Mesh::new(positions, faces)
}

/// Only `v x y z` and `f a b c` lines: enough for the bunny.
fn read_obj(path: &PathBuf) -> Option<Mesh> {
    let text = std::fs::read_to_string(path).ok()?;
    let (mut positions, mut faces) = (Vec::new(), Vec::new());
    for line in text.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.first() {
            Some(&"v") => {
                let c: Vec<f64> = w[1..4].iter().map(|x| x.parse().unwrap()).collect();
                positions.push(DVec3::new(c[0], c[1], c[2]));
            }
            Some(&"f") => {
                let i: Vec<u32> = w[1..4]
                    .iter()
                    .map(|x| x.parse::<u32>().unwrap() - 1)
                    .collect();
                faces.push([i[0], i[1], i[2]]);
            }
            _ => {}
        }
    }
    Some(Mesh::new(positions, faces))
}

/// A crude coarsening for the benchmark: vertices snapped to a grid of `cells` cells
/// along the longest axis and merged per cell (at their mean), faces that collapse
/// dropped. The result stays close to the input, as a real run's output does.
fn grid_clustered(mesh: &Mesh, cells: f64) -> Mesh {
    let b = mesh.bbox();
    let size = b.extent().max_element() / cells;
    let mut cell_of: HashMap<[i64; 3], u32> = HashMap::new();
    let mut sums: Vec<(DVec3, f64)> = Vec::new();
    let mut remap = vec![u32::MAX; mesh.n_vertices()];
    for f in &mesh.faces {
        for &v in f {
            if remap[v as usize] != u32::MAX {
                continue;
            }
            let p = mesh.positions[v as usize];
            let key = ((p - b.min) / size).floor().as_i64vec3().to_array();
            let id = *cell_of.entry(key).or_insert_with(|| {
                sums.push((DVec3::ZERO, 0.0));
                sums.len() as u32 - 1
            });
            sums[id as usize].0 += p;
            sums[id as usize].1 += 1.0;
            remap[v as usize] = id;
        }
    }
    let positions = sums.iter().map(|(s, n)| *s / *n).collect();
    let faces = mesh
        .faces
        .iter()
        .map(|f| f.map(|v| remap[v as usize]))
        .filter(|[a, b, c]| a != b && b != c && c != a)
        .collect();
    Mesh::new(positions, faces)
}

fn bench_measure(c: &mut Criterion) {
    let fine = uv_sphere(130, 270);
    let coarse = uv_sphere(50, 100);
    eprintln!("sphere faces: {} vs {}", fine.n_faces(), coarse.n_faces());
    let opts = MetricsOptions::default();
    let mut g = c.benchmark_group("measure");
    g.sample_size(10);
    g.bench_function("sphere 70K vs 10K", |b| {
        b.iter(|| measure(Some(&fine), &coarse, &opts).unwrap())
    });
    let bunny_path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/stanford-bunny.obj");
    if let Some(bunny) = read_obj(&bunny_path) {
        let coarse_bunny = grid_clustered(&bunny, 45.0);
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
    if std::env::var_os("COARSEN_BENCH_LARGE").is_some() {
        let huge = uv_sphere(1000, 2000);
        eprintln!("large sphere faces: {}", huge.n_faces());
        g.bench_function("sphere 4M vs 10K", |b| {
            b.iter(|| measure(Some(&huge), &coarse, &opts).unwrap())
        });
    }
    g.finish();
}

fn bench_bvh(c: &mut Criterion) {
    let fine = uv_sphere(130, 270);
    let mut g = c.benchmark_group("bvh");
    g.sample_size(20);
    g.bench_function("build 70K", |b| {
        b.iter(|| Bvh::build(black_box(&fine.positions), black_box(&fine.faces)))
    });
    let bvh = Bvh::build(&fine.positions, &fine.faces);
    // Query points just off the surface, spread over it (a golden-angle spiral).
    let n = 100_000;
    let points: Vec<DVec3> = (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let phi = i as f64 * 2.399_963_229_728_653;
            let r = (1.0 - z * z).sqrt();
            DVec3::new(r * phi.cos(), r * phi.sin(), z) * (1.0 + 0.01 * (i % 7) as f64)
        })
        .collect();
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
    g.finish();
}

criterion_group!(benches, bench_measure, bench_bvh);
criterion_main!(benches);
