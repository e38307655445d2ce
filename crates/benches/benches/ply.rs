//! Throughput of the binary PLY writer and reader on a ~4M-triangle mesh, and of the OBJ
//! reader on the Stanford bunny.
//!
//! Run: `cargo bench -p coarsen-benches --bench ply`. Criterion prints MB/s (MiB/s) for each.
//! The mesh is generated here: a wavy height field on a 1415 × 1415 grid (2.0M vertices,
//! 4.0M triangles), so the bench depends on nothing but this crate.

use coarsen_io::{Format, ReadOptions, WriteOptions, read_bytes, read_path, write_path};
use coarsen_mesh::{DVec3, Mesh};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::Path;

/// A `(n + 1)²`-vertex grid with `2n²` triangles, lifted by a smooth wave.
fn wavy_grid(n: u32) -> Mesh {
    let side = n + 1;
    let positions = (0..side * side)
        .map(|i| {
            let (x, y) = (
                f64::from(i % side) / f64::from(n),
                f64::from(i / side) / f64::from(n),
            );
            DVec3::new(x, y, 0.1 * (7.0 * x).sin() * (5.0 * y).cos())
        })
        .collect();
    let mut faces = Vec::with_capacity(2 * (n * n) as usize);
    for r in 0..n {
        for c in 0..n {
            let a = r * side + c;
            faces.push([a, a + 1, a + side + 1]);
            faces.push([a, a + side + 1, a + side]);
        }
    }
    Mesh::new(positions, faces)
}

fn ply(c: &mut Criterion) {
    let mesh = wavy_grid(1415);
    let dir = tempfile::tempdir().expect("temporary directory");
    let path = dir.path().join("grid.ply");
    write_path(&mesh, &path, &WriteOptions::default()).expect("write PLY");
    let bytes = std::fs::metadata(&path).expect("PLY size").len();
    eprintln!(
        "binary PLY: {} vertices, {} faces, {:.1} MB",
        mesh.n_vertices(),
        mesh.n_faces(),
        bytes as f64 / 1e6
    );
    let mut g = c.benchmark_group("ply_binary_4m_faces");
    g.sample_size(10);
    g.throughput(Throughput::Bytes(bytes));
    g.bench_function("write_path", |b| {
        b.iter(|| write_path(black_box(&mesh), &path, &WriteOptions::default()).expect("write"))
    });
    g.bench_function("read_path", |b| {
        b.iter(|| read_path(black_box(&path), &ReadOptions::default()).expect("read"))
    });
    g.finish();
}

fn obj(c: &mut Criterion) {
    let bunny =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/stanford-bunny.obj");
    let Ok(bytes) = std::fs::read(&bunny) else {
        eprintln!("skipping the OBJ bench: {} is not there", bunny.display());
        return;
    };
    let mut g = c.benchmark_group("obj_bunny");
    g.throughput(Throughput::Bytes(bytes.len() as u64));
    g.bench_function("read_bytes", |b| {
        b.iter(|| {
            read_bytes(
                black_box(&bytes),
                Format::Obj,
                "bunny.obj",
                &ReadOptions::default(),
            )
            .expect("read")
        })
    });
    g.finish();
}

criterion_group!(benches, ply, obj);
criterion_main!(benches);
