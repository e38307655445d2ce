//! Clustering throughput: the bunny into 5000 clusters, and the bunny subdivided 1-to-4
//! three times (4.4M faces) into 30,000 clusters (the 1.5 s bar): run to rest in
//! the file's order, and as `uniform-cvt` runs it (renumbered along the Morton curve as the
//! runner renumbers big inputs, stopped at its tolerance of 1e-4). The adjacency is built
//! before the clock starts (printed apart), as pyacvd builds its neighbour lists when its
//! `Clustering` is made, not in the `cluster` call its figure times. Skipped without
//! `../shared/data`.

use coarsen_mesh::{Mesh, Topology};
use coarsen_stage_cvt::{CvtParams, EnergyKind, cluster};
use criterion::{Criterion, criterion_group, criterion_main};
use std::collections::HashMap;
use std::hint::black_box;

/// The cleaned bunny, if the data folder is there.
fn bunny() -> Option<Mesh> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/stanford-bunny.obj");
    if !path.exists() {
        eprintln!("skipped: {} is absent", path.display());
        return None;
    }
    let mesh = coarsen_io::read_path(&path, &Default::default()).ok()?.mesh;
    Some(coarsen_mesh::clean(mesh, &Default::default()).ok()?.0)
}

/// One 1-to-4 midpoint subdivision.
fn subdivide(m: &Mesh) -> Mesh {
    let mut positions = m.positions.clone();
    let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
    let mut faces = Vec::with_capacity(4 * m.n_faces());
    for f in &m.faces {
        let mut e = [0u32; 3];
        for i in 0..3 {
            let (a, b) = (f[i], f[(i + 1) % 3]);
            let key = (a.min(b), a.max(b));
            e[i] = *mid.entry(key).or_insert_with(|| {
                positions.push((positions[a as usize] + positions[b as usize]) * 0.5);
                positions.len() as u32 - 1
            });
        }
        faces.push([f[0], e[0], e[2]]);
        faces.push([f[1], e[1], e[0]]);
        faces.push([f[2], e[2], e[1]]);
        faces.push(e);
    }
    Mesh::new(positions, faces)
}

/// Times `cluster` of `mesh` into `n` clusters with the area-weighted energy, stopping at
/// `tolerance`.
fn run(c: &mut Criterion, name: &str, mesh: &Mesh, n: usize, tolerance: f64) {
    let topo = Topology::build(mesh);
    let p = CvtParams {
        energy: EnergyKind::Valette2004,
        tolerance,
        ..CvtParams::default()
    };
    c.bench_function(name, |b| {
        b.iter(|| {
            let r = cluster(mesh, &topo, n, &p, None, |_, _, _| {}).unwrap();
            black_box(r.log.moves.len())
        })
    });
}

fn benches(c: &mut Criterion) {
    let Some(bunny) = bunny() else { return };
    run(c, "cluster bunny 70K faces → 5000", &bunny, 5000, 0.0);
    let big = subdivide(&subdivide(&subdivide(&bunny)));
    eprintln!("subdivided bunny: {} faces", big.n_faces());
    let t = std::time::Instant::now();
    let topo = Topology::build(&big);
    eprintln!("topology of the subdivided bunny: {:?}", t.elapsed());
    drop(topo);
    run(c, "cluster subdivided bunny → 30000", &big, 30_000, 0.0);
    let big = coarsen_mesh::order::along_curve(big);
    let t = std::time::Instant::now();
    let topo = Topology::build(&big);
    eprintln!("topology of it along the curve: {:?}", t.elapsed());
    drop(topo);
    run(
        c,
        "cluster subdivided bunny → 30000 as uniform-cvt (curve order, tolerance 1e-4)",
        &big,
        30_000,
        1e-4,
    );
}

criterion_group! {
    name = group;
    config = Criterion::default().sample_size(10);
    targets = benches
}
criterion_main!(group);
