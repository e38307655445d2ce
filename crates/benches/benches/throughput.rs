//! Times the phases of one clustering (adjacency, set-up, seeding, minimisation) on a mesh
//! file: `cargo bench -p coarsen-benches --bench throughput -- FILE N [ENERGY]`.

use coarsen_benches::cpu_seconds;
use coarsen_mesh::Topology;
use coarsen_stage_cvt::{Clusterer, Energy, Shu2009, Valette2004};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    const USAGE: &str = "usage: throughput FILE N [valette2004|shu2009]";
    let Some(args) = coarsen_benches::tool_args(USAGE, |a| std::path::Path::new(a).is_file())
    else {
        return Ok(());
    };
    let (Some(path), Some(n)) = (args.first(), args.get(1)) else {
        return Err(USAGE.into());
    };
    let n: usize = n.parse()?;
    let mesh = coarsen_io::read_path(std::path::Path::new(path), &Default::default())?.mesh;
    let mesh = coarsen_mesh::clean(mesh, &Default::default())?.0;
    let (t, u) = (Instant::now(), cpu_seconds());
    let topo = Topology::build(&mesh);
    eprintln!("cpu: topology {:.2} s", cpu_seconds() - u);
    eprintln!(
        "faces {}, topology {:.3} s",
        mesh.n_faces(),
        t.elapsed().as_secs_f64()
    );
    match args.get(2).map(String::as_str) {
        Some("shu2009") => time(&mesh, &topo, &Shu2009 { r: 2.0 }, n),
        _ => time(&mesh, &topo, &Valette2004, n),
    }
}

/// Times set-up, seeding and minimisation with `energy`.
fn time<E: Energy>(
    mesh: &coarsen_mesh::Mesh,
    topo: &Topology,
    energy: &E,
    n: usize,
) -> Result<(), Box<dyn std::error::Error>> {
    let (t, u) = (Instant::now(), cpu_seconds());
    let mut c = Clusterer::new(mesh, topo, energy, None)?;
    let t_new = t.elapsed().as_secs_f64();
    let u_new = cpu_seconds() - u;
    let (t, u) = (Instant::now(), cpu_seconds());
    c.set_tolerance(1e-4);
    c.seed(n, 1)?;
    let t_seed = t.elapsed().as_secs_f64();
    let u_seed = cpu_seconds() - u;
    let (t, u) = (Instant::now(), cpu_seconds());
    let log = c.minimize(200, None, |_, _, _| {});
    let t_min = t.elapsed().as_secs_f64();
    let u_min = cpu_seconds() - u;
    eprintln!("cpu: new {u_new:.2} s, seed {u_seed:.2} s, minimize {u_min:.2} s");
    eprintln!(
        "new {t_new:.3} s, seed {t_seed:.3} s, minimize {t_min:.3} s; passes {}, moves {}, refused {}, E0 {:.6e}, E {:.6e}",
        log.moves.len(),
        log.moves.iter().sum::<u64>(),
        log.refused,
        log.initial_energy,
        log.energy.last().copied().unwrap_or(f64::NAN)
    );
    Ok(())
}
