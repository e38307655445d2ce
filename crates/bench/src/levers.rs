//! Issue #5's lever rows: what each lever (adaptive density, vertex placement, projection
//! onto the input, the relaxations and their fidelity bound) does to the bunny at 5000
//! vertices, as a shipped pipeline plus `--set`-style overrides, one row each.

use anyhow::Result;
use coarsen_mesh::Mesh;
use coarsen_metrics::{MetricsOptions, measure};
use coarsen_stage::{Registry, Target};
use std::fmt::Write as _;
use std::time::Instant;

/// The mesh of the rows.
pub const MESH: &str = "stanford-bunny.obj";

/// The vertex count of every row.
const VERTICES: u64 = 5000;

/// The rows: what the lever shows, the shipped pipeline, and the overrides.
const ROWS: &[(&str, &str, &[&str])] = &[
    ("paper 1 as shipped (r = 2, relax)", "adaptive-cvt", &[]),
    ("paper 1 without relax", "adaptive-cvt", &["relax.sweeps=0"]),
    (
        "paper 1, no projection in the post-process",
        "adaptive-cvt",
        &["postprocess.project=false"],
    ),
    (
        "paper 1, quadric placement",
        "adaptive-cvt",
        &[
            "dual.placement=\"quadric\"",
            "postprocess.placement=\"quadric\"",
        ],
    ),
    (
        "uniform density (Valette–Chassery 2004)",
        "uniform-cvt",
        &[],
    ),
    (
        "uniform density, the worst faces not polished",
        "uniform-cvt",
        &["relax.polish=0"],
    ),
    ("goal as shipped (r = 3, two relaxations)", "goal", &[]),
    (
        "goal, r = 2",
        "goal",
        &["cluster.cvt.r=2.0", "postprocess.r=2.0"],
    ),
    (
        "goal, r = 4",
        "goal",
        &["cluster.cvt.r=4.0", "postprocess.r=4.0"],
    ),
    (
        "goal without the fidelity relaxation",
        "goal",
        &["fit.fit=0", "fit.sweeps=0"],
    ),
    (
        "goal, fidelity edits but no bound on the sweeps",
        "goal",
        &["fit.max_dev_pct=0.0"],
    ),
    ("goal, bound 0.25 %", "goal", &["fit.max_dev_pct=0.25"]),
    ("goal, bound 0.35 %", "goal", &["fit.max_dev_pct=0.35"]),
    ("goal without rebalancing", "goal", &["shape.rebalance=0"]),
    (
        "goal, smallest angle only (no floor)",
        "goal",
        &["shape.floor_deg=0.0", "fit.floor_deg=0.0"],
    ),
    (
        "goal, quadric placement",
        "goal",
        &[
            "dual.placement=\"quadric\"",
            "postprocess.placement=\"quadric\"",
        ],
    ),
    (
        "goal, no projection in the post-process",
        "goal",
        &["postprocess.project=false"],
    ),
];

/// Runs `pipeline` with `sets` on `input` to the rows' vertex count; the output mesh and
/// the seconds the run took (the input already loaded).
fn run(registry: &Registry, pipeline: &str, sets: &[&str], input: &Mesh) -> Result<(Mesh, f64)> {
    let t = Instant::now();
    let (out, _) = crate::run_shipped(registry, pipeline, sets, input, Target::Vertices(VERTICES))?;
    Ok((out, t.elapsed().as_secs_f64()))
}

/// The section: one row per lever on `input` (the bunny), with the Goal row's figures.
pub fn section(registry: &Registry, input: &Mesh) -> Result<String> {
    // What "valid" keeps of the input: components, boundary loops, genus.
    let kept = coarsen_metrics::validity(None, input)?;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "## Levers — {} at {VERTICES} vertices\n",
        MESH.trim_end_matches(".obj")
    );
    let _ = writeln!(
        s,
        "Each row is a shipped pipeline with `--set` overrides (as `coarsen run PIPELINE IN -o OUT \
         --vertices {VERTICES} --set …`). Goal (issue #5): α_min ≥ 30°, P<30° = 0, Q_avg ≥ 0.90, \
         Hausdorff ≤ 0.4 %. Valid: exact vertex count, manifold, no degenerate or flipped face, \
         the input's components, boundary loops and genus. Seconds: the pipeline in this process, input already loaded, one run \
         (compare rows with each other only).\n"
    );
    let _ = writeln!(
        s,
        "| lever | pipeline | overrides | α_min | α_avg | P<30° % | Q_min | Q_avg | Hausdorff % | valid | s |"
    );
    let _ = writeln!(
        s,
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for &(label, pipeline, sets) in ROWS {
        eprintln!("levers · {label}");
        let shown = if sets.is_empty() {
            "—".to_string()
        } else {
            sets.iter()
                .map(|x| format!("`{}`", x.replace('|', "/")))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let (out, seconds) = match run(registry, pipeline, sets, input) {
            Ok(r) => r,
            Err(e) => {
                let _ = writeln!(
                    s,
                    "| {label} | `{pipeline}` | {shown} | failed: {} | | | | | | | |",
                    e.to_string().replace('|', "/").replace('\n', " ")
                );
                continue;
            }
        };
        let m = measure(Some(input), &out, &MetricsOptions::default())?;
        let q = &m.quality;
        let h = m
            .fidelity
            .map_or("—".to_string(), |f| format!("{:.3}", f.hausdorff_pct));
        let v = &m.validity;
        let valid = v.manifold
            && v.n_degenerate == 0
            && v.n_flipped.is_none_or(|n| n == 0)
            && v.n_vertices as u64 == VERTICES
            && (v.n_components, v.n_boundary_loops, v.genus)
                == (kept.n_components, kept.n_boundary_loops, kept.genus);
        let _ = writeln!(
            s,
            "| {label} | `{pipeline}` | {shown} | {} | {h} | {} | {seconds:.2} |",
            crate::quality_cells(q),
            if valid { "yes" } else { "no" },
        );
    }
    s.push('\n');
    Ok(s)
}
