//! Times [`Topology::build`] on a mesh file: the median and spread of `N` builds.
//!
//! `cargo bench -p coarsen-benches --bench build_timing -- MESH [N [alternate]]`
//! (`RAYON_NUM_THREADS=1` for the serial figure). With `alternate`, the builds alternate
//! between a one-thread pool and the default one, so that both figures see the same load
//! on a shared machine, and one more line gives the two medians, minimums and the median
//! of the per-pair ratios. Prints one line: faces, vertices,
//! edges, then the median, minimum and maximum build time in seconds, the median CPU
//! time of a build (all threads), and a hash of the tables so that two builds of the same
//! mesh can be compared for identity.

use coarsen_benches::cpu_seconds;
use coarsen_mesh::Topology;
use std::hash::{DefaultHasher, Hash, Hasher};
use std::path::PathBuf;
use std::time::Instant;

fn main() {
    const USAGE: &str = "usage: build_timing MESH [N [alternate]]";
    let Some(args) = coarsen_benches::tool_args(USAGE, |a| std::path::Path::new(a).is_file())
    else {
        return;
    };
    let mut args = args.into_iter();
    let Some(path) = args.next().map(PathBuf::from) else {
        eprintln!("{USAGE}");
        std::process::exit(2);
    };
    let n: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(5);
    let alternate = args.next().is_some_and(|a| a == "alternate");
    let mesh = match coarsen_io::read_path(&path, &coarsen_io::ReadOptions::default()) {
        Ok(loaded) => loaded.mesh,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    let mut times = Vec::with_capacity(n);
    let mut cpu = Vec::with_capacity(n);
    let mut digest = 0;
    let mut edges = 0;
    if alternate {
        alternate_pools(&mesh, n.max(1));
    }
    for _ in 0..n.max(1) {
        let (t0, c0) = (Instant::now(), cpu_seconds());
        let topo = Topology::build(&mesh);
        times.push(t0.elapsed().as_secs_f64());
        cpu.push(cpu_seconds() - c0);
        edges = topo.n_edges();
        digest = fingerprint(&topo);
        drop(topo);
    }
    times.sort_by(f64::total_cmp);
    cpu.sort_by(f64::total_cmp);
    println!(
        "faces {} vertices {} edges {edges} build median {:.3} s min {:.3} max {:.3} cpu {:.3} s tables {digest:016x}",
        mesh.n_faces(),
        mesh.n_vertices(),
        times[times.len() / 2],
        times[0],
        times[times.len() - 1],
        cpu[cpu.len() / 2],
    );
}

/// Builds `n` times on one thread and `n` times on the default pool, alternating, and
/// prints both medians and minimums and the median ratio of the pairs.
fn alternate_pools(mesh: &coarsen_mesh::Mesh, n: usize) {
    let pool = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool")
    };
    let (one, all) = (pool(1), pool(0));
    let time = |p: &rayon::ThreadPool| {
        let t0 = Instant::now();
        let t = p.install(|| Topology::build(mesh));
        let s = t0.elapsed().as_secs_f64();
        (s, fingerprint(&t))
    };
    let (mut serial, mut parallel, mut ratio) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..n {
        let (a, ha) = time(&one);
        let (b, hb) = time(&all);
        assert_eq!(ha, hb, "tables differ between thread counts");
        serial.push(a);
        parallel.push(b);
        ratio.push(b / a);
    }
    for v in [&mut serial, &mut parallel, &mut ratio] {
        v.sort_by(f64::total_cmp);
    }
    println!(
        "1 thread: median {:.3} min {:.3}; {} threads: median {:.3} min {:.3}; ratio median {:.2}",
        serial[n / 2],
        serial[0],
        all.current_num_threads(),
        parallel[n / 2],
        parallel[0],
        ratio[n / 2],
    );
}

/// A hash of every table the public API exposes.
fn fingerprint(t: &Topology) -> u64 {
    let mut h = DefaultHasher::new();
    t.edges().hash(&mut h);
    t.face_components().hash(&mut h);
    let (offsets, faces) = t.vertex_face_table();
    offsets.hash(&mut h);
    faces.hash(&mut h);
    for e in 0..t.n_edges() as u32 {
        t.edge_faces(e).hash(&mut h);
        (
            t.is_boundary_edge(e),
            t.is_non_manifold_edge(e),
            t.is_flipped_edge(e),
        )
            .hash(&mut h);
    }
    for f in 0..t.n_faces() as u32 {
        t.face_edges(f).hash(&mut h);
    }
    for v in 0..t.n_vertices() as u32 {
        t.vertex_neighbors(v).hash(&mut h);
        t.n_vertex_fans(v).hash(&mut h);
        for fan in t.vertex_fans(v) {
            fan.hash(&mut h);
        }
        (
            t.is_boundary_vertex(v),
            t.is_isolated_vertex(v),
            t.is_non_manifold_vertex(v),
        )
            .hash(&mut h);
    }
    t.boundary_loops().hash(&mut h);
    t.n_components().hash(&mut h);
    h.finish()
}
