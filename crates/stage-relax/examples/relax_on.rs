//! Developer tool: relaxes a coarse mesh on its input and prints the figures before and after.
//!
//! `cargo run --release -p coarsen-stage-relax --example relax_on -- INPUT COARSE [OUT] [key=value …]`
//! with the keys of `RelaxParams` (`sweeps`, `step`, `project`, `max_turn_deg`, `flips`, …)
//! and `fidelity=true` to add the Hausdorff figures.

use coarsen_io::{ReadOptions, WriteOptions, read_path, write_path};
use coarsen_mesh::hygiene;
use coarsen_metrics::{MetricsOptions, measure};
use coarsen_stage_relax::{RelaxParams, Surface, relax};
use std::path::Path;
use std::time::Instant;

fn load(p: &str) -> coarsen_mesh::Mesh {
    let m = read_path(Path::new(p), &ReadOptions::default())
        .unwrap_or_else(|e| panic!("{p}: {e}"))
        .mesh;
    hygiene::clean(m, &hygiene::HygieneOptions::default())
        .unwrap_or_else(|e| panic!("{p}: {e}"))
        .0
}

fn show(label: &str, input: &coarsen_mesh::Mesh, m: &coarsen_mesh::Mesh, fidelity: bool) {
    let r = measure(fidelity.then_some(input), m, &MetricsOptions::default()).unwrap();
    let q = &r.quality;
    let h = r
        .fidelity
        .map(|f| {
            format!(
                " H {:.3} (fwd {:.3} bwd {:.3})",
                f.hausdorff_pct, f.forward_max_pct, f.backward_max_pct
            )
        })
        .unwrap_or_default();
    println!(
        "{label}: α_min {:.2} α_avg {:.2} P<30 {:.2} Q_min {:.3} Q_avg {:.4}{h}",
        q.alpha_min_deg, q.alpha_avg_deg, q.p_lt30_pct, q.q_min, q.q_avg
    );
}

/// Prints where each mesh is farthest from the other (vertices and face centroids).
fn farthest(input: &coarsen_mesh::Mesh, out: &coarsen_mesh::Mesh) {
    let diag = input.bbox().diagonal();
    for (name, from, to) in [
        ("input → output", input, out),
        ("output → input", out, input),
    ] {
        let index = coarsen_metrics::Facing::new(to);
        let topo = coarsen_mesh::Topology::build(from);
        let mut d: Vec<(f64, usize, bool, coarsen_geom::DVec3)> = (0..from.n_vertices())
            .map(|v| (from.positions[v], v, topo.is_boundary_vertex(v as u32)))
            .chain((0..from.n_faces()).flat_map(|f| {
                // A barycentric grid of 10 points inside each face.
                let [a, b, c] = from.corners(f);
                (0..4)
                    .flat_map(move |i| (0..4 - i).map(move |j| (i, j)))
                    .map(move |(i, j)| {
                        let (u, v) = ((i as f64 + 0.5) / 4.5, (j as f64 + 0.5) / 4.5);
                        (a + u * (b - a) + v * (c - a), usize::MAX - f, false)
                    })
            }))
            .map(|(p, i, b)| {
                let q = index.bvh().closest_point(p).unwrap().point;
                (100.0 * p.distance(q) / diag, i, b, p)
            })
            .collect();
        d.sort_by(|a, b| b.0.total_cmp(&a.0));
        println!("{name}:");
        for (x, i, b, p) in d.iter().take(8) {
            println!(
                "  {x:.3} % at {p:.4} {}",
                if *b {
                    "boundary vertex"
                } else if *i > from.n_vertices() {
                    "face centroid"
                } else {
                    "vertex"
                }
            );
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let input = load(&args[0]);
    let mut m = load(&args[1]);
    let mut out = None;
    let mut p = RelaxParams::default();
    let mut fidelity = false;
    let mut locate = false;
    for a in &args[2..] {
        let Some((k, v)) = a.split_once('=') else {
            out = Some(a.clone());
            continue;
        };
        match k {
            "sweeps" => p.sweeps = v.parse().unwrap(),
            "step" => p.step = v.parse().unwrap(),
            "project" => p.project = v.parse().unwrap(),
            "max_turn_deg" => p.max_turn_deg = v.parse().unwrap(),
            "flips" => p.flips = v.parse().unwrap(),
            "floor_deg" => p.floor_deg = v.parse().unwrap(),
            "rebalance" => p.rebalance = v.parse().unwrap(),
            "fit" => p.fit = v.parse().unwrap(),
            "max_dev_pct" => p.max_dev_pct = v.parse().unwrap(),
            "fidelity" => fidelity = v.parse().unwrap(),
            "where" => locate = v.parse().unwrap(),
            _ => panic!("unknown key {k}"),
        }
    }
    show("before", &input, &m, fidelity);
    if locate {
        farthest(&input, &m);
        return;
    }
    let t = Instant::now();
    let surface = Surface::new(&input);
    let t1 = t.elapsed().as_secs_f64();
    let r = relax(&mut m, Some(&surface), &p);
    let t2 = t.elapsed().as_secs_f64();
    println!(
        "index {t1:.3} s, relax {:.3} s; moved {:?} flipped {:?} rebalanced {} fitted {}",
        t2 - t1,
        r.moved,
        r.flipped,
        r.rebalanced,
        r.fitted
    );
    show("after ", &input, &m, fidelity);
    if let Some(o) = out {
        write_path(&m, Path::new(&o), &WriteOptions::default()).unwrap();
    }
}
