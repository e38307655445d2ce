//! The scale section of the tables: every coarsening pipeline on the bunny subdivided 1-to-4
//! three times (4.4M faces), each run in a child process of its own so that its peak memory
//! (the kernel's high-water mark, `VmHWM`) is its own, beside a child that only loads the
//! file — the baseline the other rows are read against. Each case runs [`RUNS`] times in a
//! row and the table shows the median run.

use anyhow::{Context as _, Result, bail};
use coarsen_mesh::Mesh;
use coarsen_pipeline::{Overrides, Pipeline, RunOptions};
use coarsen_stage::Target;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// The cases: pipeline (`load` = read the file only) and target.
const CASES: &[(&str, Target)] = &[
    ("load", Target::Vertices(0)),
    ("qem", Target::Faces(60_000)),
    ("svec", Target::Faces(60_000)),
    ("uniform-cvt", Target::Vertices(30_000)),
    ("adaptive-cvt", Target::Vertices(30_000)),
];

/// Runs per case, one after another (each but the first follows a run of its own kind).
const RUNS: usize = 3;

/// What one child measured.
struct Row {
    vertices: usize,
    faces: usize,
    load_seconds: f64,
    stage_seconds: Vec<f64>,
    total_seconds: f64,
    peak_mib: Option<f64>,
}

/// The bunny (already cleaned) subdivided three times.
pub fn big_mesh(bunny: &Mesh) -> Result<Mesh> {
    let mut m = bunny.clone();
    for _ in 0..3 {
        let all = vec![true; m.n_faces()];
        m = coarsen_stage_refine::split_once(&m, &all)?.0;
    }
    Ok(m)
}

/// Runs every case in a child process on `big` and renders the section.
pub fn section(big: &Mesh) -> Result<String> {
    let dir = tempfile::tempdir()?;
    let file = dir.path().join("bunny-subdivided-3.ply");
    coarsen_io::write_path(big, &file, &Default::default())?;
    let exe = std::env::current_exe()?;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "## Scale — the bunny subdivided 1-to-4 three times ({} vertices, {} faces)\n",
        big.n_vertices(),
        big.n_faces()
    );
    let _ = writeln!(
        s,
        "Each case runs {RUNS} times in a row, each run a child process that reads the binary PLY \
         and runs the pipeline; the row is the run of median total time (*fastest*: the \
         quickest run's), *peak* the highest memory high-water mark (`VmHWM`) of the {RUNS}, \
         *peak ÷ load* that over the same for a child that only reads the file. The runs of a \
         case follow each other rather than taking turns with other cases: on this machine a \
         process pays, in the kernel, for memory the host has taken back, so a run that \
         follows one of a lower peak pays for the difference (measured: about 6 s of kernel \
         time a GB when none of it is backed), one that follows its own kind much less. Stage \
         times in pipeline order; total includes reading the file and the runner's \
         renumbering of the input along a Morton curve (as for every input of 2¹⁸ faces or more) \
         and, in a pipeline with a stage that needs a manifold mesh, the adjacency the runner \
         builds before the first stage to look for edges of three or more faces (the stage that \
         would build it next takes it over). The children allocate as the `coarsen` binary \
         does (`coarsen-malloc`: freed memory is kept for reuse; big blocks on huge pages).\n"
    );
    s.push_str(
        "| pipeline | target | V | F | load s | stages s | total s | fastest s | peak MiB | peak ÷ load |\n",
    );
    s.push_str("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
    let mut load_peak = None;
    'cases: for (pipeline, target) in CASES {
        let mut rows = Vec::with_capacity(RUNS);
        for run in 1..=RUNS {
            eprintln!("scale · {pipeline} · run {run}");
            let out = std::process::Command::new(&exe)
                .args(["scale-case", pipeline, &target_arg(target)])
                .arg(&file)
                .output()
                .context("the benchmark starts a copy of itself")?;
            let text = String::from_utf8_lossy(&out.stdout);
            match parse(&text) {
                Some(r) if out.status.success() => rows.push(r),
                _ => {
                    let err = String::from_utf8_lossy(&out.stderr);
                    let _ = writeln!(
                        s,
                        "| `{pipeline}` | {} | | | | | | | | failed: {} |",
                        target_text(pipeline, target),
                        err.lines().last().unwrap_or("no message").replace('|', "/")
                    );
                    continue 'cases;
                }
            }
        }
        rows.sort_by(|a, b| a.total_seconds.total_cmp(&b.total_seconds));
        let fastest = rows[0].total_seconds;
        let highest = rows.iter().filter_map(|r| r.peak_mib).reduce(f64::max);
        let row = &rows[RUNS / 2];
        if *pipeline == "load" {
            load_peak = highest;
        }
        let stages: Vec<String> = row
            .stage_seconds
            .iter()
            .map(|x| format!("{x:.2}"))
            .collect();
        let peak = highest.map_or("n/a".into(), |p| format!("{p:.0}"));
        let ratio = match (highest, load_peak) {
            (Some(p), Some(l)) if l > 0.0 => format!("{:.2}", p / l),
            _ => "—".into(),
        };
        let _ = writeln!(
            s,
            "| `{pipeline}` | {} | {} | {} | {:.2} | {} | {:.2} | {fastest:.2} | {peak} | {ratio} |",
            target_text(pipeline, target),
            row.vertices,
            row.faces,
            row.load_seconds,
            if stages.is_empty() {
                "—".into()
            } else {
                stages.join(" + ")
            },
            row.total_seconds,
        );
    }
    s.push('\n');
    Ok(s)
}

fn target_arg(t: &Target) -> String {
    match t {
        Target::Vertices(n) => format!("v{n}"),
        Target::Faces(n) => format!("f{n}"),
        Target::Ratio(r) => format!("r{r}"),
    }
}

fn target_text(pipeline: &str, t: &Target) -> String {
    match (pipeline, t) {
        ("load", _) => "—".into(),
        (_, Target::Vertices(n)) => format!("{n} v"),
        (_, Target::Faces(n)) => format!("{n} f"),
        (_, Target::Ratio(r)) => format!("{:.0} % removed", r * 100.0),
    }
}

/// The child: reads `file`, runs `pipeline` to `target` (`v30000`, `f60000`), prints one
/// line `key=value …` of figures.
pub fn child(pipeline: &str, target: &str, file: &Path) -> Result<()> {
    let start = Instant::now();
    let mesh = coarsen_io::read_path(file, &Default::default())?.mesh;
    let load_seconds = start.elapsed().as_secs_f64();
    let (mesh, stage_seconds) = if pipeline == "load" {
        (mesh, Vec::new())
    } else {
        let target = match target.split_at(1) {
            ("v", n) => Target::Vertices(n.parse()?),
            ("f", n) => Target::Faces(n.parse()?),
            ("r", r) => Target::Ratio(r.parse()?),
            _ => bail!("bad target {target}"),
        };
        let text = coarsen_builtin::pipeline(pipeline)
            .with_context(|| format!("no shipped pipeline `{pipeline}`"))?;
        let registry = coarsen_builtin::registry();
        let overrides = Overrides {
            target: Some(target),
            ..Default::default()
        };
        let p = Pipeline::parse(text, pipeline, &registry, &overrides)
            .map_err(|d| anyhow::anyhow!("{d}"))?;
        let (out, report) = p.run(mesh, RunOptions::default())?;
        let secs = report.stages.iter().map(|s| s.seconds).collect();
        (out, secs)
    };
    let total = start.elapsed().as_secs_f64();
    let peak = peak_mib().map_or("none".into(), |p| format!("{p}"));
    let stages: Vec<String> = stage_seconds.iter().map(|s: &f64| format!("{s}")).collect();
    println!(
        "vertices={} faces={} load={load_seconds} stages={} total={total} peak={peak}",
        mesh.n_vertices(),
        mesh.n_faces(),
        if stages.is_empty() {
            "-".into()
        } else {
            stages.join(",")
        },
    );
    Ok(())
}

/// This process's memory high-water mark in MiB, where `/proc` tells it.
fn peak_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

fn parse(text: &str) -> Option<Row> {
    let line = text.lines().rev().find(|l| l.starts_with("vertices="))?;
    let get = |k: &str| {
        line.split_whitespace()
            .find_map(|w| w.strip_prefix(k).and_then(|v| v.strip_prefix('=')))
    };
    Some(Row {
        vertices: get("vertices")?.parse().ok()?,
        faces: get("faces")?.parse().ok()?,
        load_seconds: get("load")?.parse().ok()?,
        stage_seconds: match get("stages")? {
            "-" => Vec::new(),
            s => s.split(',').filter_map(|x| x.parse().ok()).collect(),
        },
        total_seconds: get("total")?.parse().ok()?,
        peak_mib: get("peak")?.parse().ok(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_child_line_parses_back() {
        let r =
            parse("noise\nvertices=5 faces=6 load=0.5 stages=1,2.5 total=4 peak=12.5\n").unwrap();
        assert_eq!((r.vertices, r.faces), (5, 6));
        assert_eq!(r.stage_seconds, vec![1.0, 2.5]);
        assert_eq!(r.peak_mib, Some(12.5));
        let r = parse("vertices=1 faces=2 load=0 stages=- total=0 peak=none").unwrap();
        assert!(r.stage_seconds.is_empty() && r.peak_mib.is_none());
        assert!(parse("garbage").is_none());
    }
}
