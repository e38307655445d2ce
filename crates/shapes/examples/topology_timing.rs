//! Times `Topology::build` on icospheres of growing size and on a 4.0 M-face torus
//! (run with `--release`; timings are the best of three builds).
//!
//! `cargo run --release -p coarsen-shapes --example topology_timing [max_subdivisions [min]]`

use coarsen_mesh::{Mesh, Topology};
use std::time::Instant;

fn main() {
    let max: u32 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(9);
    let min: u32 = std::env::args()
        .nth(2)
        .and_then(|a| a.parse().ok())
        .unwrap_or(6);
    for k in min..=max {
        match coarsen_shapes::icosphere(1.0, k) {
            Ok(mesh) => time(&format!("icosphere({k})"), &mesh),
            Err(e) => eprintln!("icosphere({k}): {e}"),
        }
    }
    match coarsen_shapes::torus(2.0, 0.5, 1415, 1414) {
        Ok(mesh) => time("torus(1415 × 1414)", &mesh),
        Err(e) => eprintln!("torus: {e}"),
    }
}

fn time(name: &str, mesh: &Mesh) {
    let mut best = f64::INFINITY;
    let mut edges = 0;
    for _ in 0..3 {
        let t0 = Instant::now();
        let topo = Topology::build(mesh);
        best = best.min(t0.elapsed().as_secs_f64());
        edges = topo.n_edges();
    }
    println!(
        "{name}: {} vertices, {} faces, {edges} edges: Topology::build {:.1} ms",
        mesh.n_vertices(),
        mesh.n_faces(),
        best * 1e3
    );
}
