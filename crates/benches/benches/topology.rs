//! Benchmarks of the mesh topology (`cargo bench -p coarsen-benches --bench topology`).
//!
//! * `topology/build torus 70K` and `topology/build torus 1M`: [`Topology::build`] on
//!   closed tori of about 70K and 1M faces (every vertex of valence 6, the common case);
//! * `topology/build grid 70K`: an open grid, whose border takes the boundary paths;
//! * `topology/summary torus 70K`: the counts of the metrics report (components,
//!   boundary loops, genus) from a built topology;
//! * `topology/split 1M: build` and `topology/split 1M: of_split`: the adjacency of the
//!   uniform 1-to-4 split of a 250K-face torus, built from its faces or derived from the
//!   torus's adjacency by [`Topology::of_split`] (compare the two in the same run).
//!
//! The meshes are built here (the shapes crate depends on this one).

use coarsen_mesh::{DVec3, Mesh, Topology};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::f64::consts::TAU;
use std::hint::black_box;

/// A torus of `rings × segments` quads, each cut in two: `2·rings·segments` faces.
fn torus(rings: u32, segments: u32) -> Mesh {
    let (big, small) = (1.0, 0.3);
    let mut positions = Vec::with_capacity((rings * segments) as usize);
    for r in 0..rings {
        let theta = TAU * r as f64 / rings as f64;
        for s in 0..segments {
            let phi = TAU * s as f64 / segments as f64;
            let d = big + small * phi.cos();
            positions.push(DVec3::new(
                d * theta.cos(),
                d * theta.sin(),
                small * phi.sin(),
            ));
        }
    }
    let at = |r: u32, s: u32| (r % rings) * segments + s % segments;
    let mut faces = Vec::with_capacity(2 * (rings * segments) as usize);
    for r in 0..rings {
        for s in 0..segments {
            let (a, b, c, d) = (at(r, s), at(r + 1, s), at(r + 1, s + 1), at(r, s + 1));
            faces.push([a, b, c]);
            faces.push([a, c, d]);
        }
    }
    Mesh::new(positions, faces)
}

/// An open `n × n` grid of quads, each cut in two: `2·n²` faces.
fn grid(n: u32) -> Mesh {
    let mut positions = Vec::with_capacity(((n + 1) * (n + 1)) as usize);
    for j in 0..=n {
        for i in 0..=n {
            positions.push(DVec3::new(i as f64, j as f64, 0.0));
        }
    }
    let mut faces = Vec::with_capacity(2 * (n * n) as usize);
    for j in 0..n {
        for i in 0..n {
            let v = j * (n + 1) + i;
            faces.push([v, v + 1, v + n + 2]);
            faces.push([v, v + n + 2, v + n + 1]);
        }
    }
    Mesh::new(positions, faces)
}

fn bench_topology(c: &mut Criterion) {
    let mut g = c.benchmark_group("topology");
    g.sample_size(20);
    let cases = [
        ("build torus 70K", torus(150, 232)),
        ("build torus 1M", torus(600, 834)),
        ("build grid 70K", grid(187)),
    ];
    for (name, mesh) in &cases {
        eprintln!("{name}: {} faces", mesh.n_faces());
        g.throughput(Throughput::Elements(mesh.n_faces() as u64));
        g.bench_function(*name, |b| b.iter(|| Topology::build(black_box(mesh))));
    }
    let small = &cases[0].1;
    let built = Topology::build(small);
    g.throughput(Throughput::Elements(small.n_faces() as u64));
    g.bench_function("summary torus 70K", |b| {
        b.iter(|| black_box(&built).summary(black_box(small)))
    });
    let coarse = torus(300, 417);
    let coarse_topo = Topology::build(&coarse);
    let fine = coarse_topo.uniform_split(&coarse);
    eprintln!("split 1M: {} faces", fine.n_faces());
    g.throughput(Throughput::Elements(fine.n_faces() as u64));
    g.bench_function("split 1M: build", |b| {
        b.iter(|| Topology::build(black_box(&fine)))
    });
    g.bench_function("split 1M: of_split", |b| {
        b.iter(|| black_box(&coarse_topo).of_split(black_box(&coarse), black_box(&fine)))
    });
    g.finish();
}

criterion_group!(benches, bench_topology);
criterion_main!(benches);
