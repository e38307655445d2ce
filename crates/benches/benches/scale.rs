//! Times the metrics on large inputs and reports the peak memory, one case per run so
//! that the peak belongs to that case:
//!
//! ```text
//! cargo bench -p coarsen-benches --bench scale -- CASE [THREADS] [REPEATS]
//! ```
//!
//! `CASE` is `measure-70k` (a ~70K-face sphere against a ~10K-face one), `measure-4m`
//! (a ~4M-face sphere against the same ~10K one), `measure-bunny` (the raw bunny against a
//! grid-clustered copy, when `../shared/data` is present), `bvh-70k` or `bvh-4m` (the
//! spatial index of the input alone). `THREADS` defaults to rayon's choice; each case runs
//! `REPEATS` times (default 3) and prints every wall time, then the process's peak resident
//! memory (`VmHWM`, Linux only) and what the meshes alone hold.

use coarsen_benches::{cpu_seconds, meshes};
use coarsen_mesh::Mesh;
use coarsen_metrics::{MetricsOptions, measure};
use coarsen_spatial::Bvh;
use std::time::Instant;

/// Peak resident memory of this process so far, in MiB, from `/proc/self/status`.
fn peak_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

fn mesh_mib(m: &Mesh) -> f64 {
    (m.positions.len() * 24 + m.faces.len() * 12) as f64 / (1024.0 * 1024.0)
}

fn main() {
    const CASES: [&str; 5] = [
        "measure-70k",
        "measure-4m",
        "measure-bunny",
        "bvh-70k",
        "bvh-4m",
    ];
    let usage = format!(
        "usage: scale CASE [THREADS] [REPEATS], CASE one of {}",
        CASES.join(", ")
    );
    let Some(args) = coarsen_benches::tool_args(&usage, |a| CASES.contains(&a)) else {
        return;
    };
    let case = args
        .first()
        .map_or("measure-70k", String::as_str)
        .to_owned();
    let threads: usize = args.get(1).and_then(|t| t.parse().ok()).unwrap_or(0);
    let repeats: usize = args.get(2).and_then(|t| t.parse().ok()).unwrap_or(3);
    let pool = match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
        Ok(pool) => pool,
        Err(e) => {
            eprintln!("cannot start the thread pool: {e}");
            std::process::exit(2);
        }
    };
    let (input, output) = match case.as_str() {
        "measure-70k" | "bvh-70k" => meshes::spheres_70k_10k(),
        "measure-4m" | "bvh-4m" => (meshes::sphere_4m(), meshes::spheres_70k_10k().1),
        "measure-bunny" => match meshes::read_obj(&meshes::bunny_path()) {
            Some(bunny) => {
                let coarse = meshes::grid_clustered(&bunny, 45.0);
                (bunny, coarse)
            }
            None => {
                eprintln!("../shared/data/stanford-bunny.obj not found");
                std::process::exit(2);
            }
        },
        other => {
            eprintln!("unknown case `{other}`; {usage}");
            std::process::exit(2);
        }
    };
    println!(
        "case {case}: input {} faces, output {} faces, {} threads; meshes hold {:.0} MiB, peak so far {:.0} MiB",
        input.n_faces(),
        output.n_faces(),
        pool.current_num_threads(),
        mesh_mib(&input) + mesh_mib(&output),
        peak_mib().unwrap_or(f64::NAN),
    );
    let opts = MetricsOptions::default();
    for _ in 0..repeats {
        let (start, cpu) = (Instant::now(), cpu_seconds());
        let line = if case.starts_with("bvh") {
            let bvh = pool.install(|| Bvh::build(&input.positions, &input.faces));
            format!("{} nodes", bvh.node_count())
        } else {
            let report = match pool.install(|| measure(Some(&input), &output, &opts)) {
                Ok(report) => report,
                Err(e) => {
                    eprintln!("measure failed: {e}");
                    std::process::exit(1);
                }
            };
            let f = report
                .fidelity
                .unwrap_or_else(|| unreachable!("an input was given"));
            format!(
                "hausdorff {:.6} %, mean {:.6} %, rms {:.6} %, {} samples, {:?} flipped",
                f.hausdorff_pct,
                f.mean_dist_pct,
                f.rms_dist_pct,
                f.n_samples,
                report.validity.n_flipped
            )
        };
        println!(
            "  {:.3} s wall  {:.2} s cpu  {line}",
            start.elapsed().as_secs_f64(),
            cpu_seconds() - cpu
        );
    }
    println!(
        "peak resident memory {:.0} MiB",
        peak_mib().unwrap_or(f64::NAN)
    );
}
