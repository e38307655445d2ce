//! The pyacvd section of the tables: pyacvd (uniform ACVD in Python, the reference issue #5
//! measures the CVT pipelines against) run on this machine in the same session as
//! coarsen's CVT pipelines, turn about, with the outputs of both measured by the same
//! metrics. Two cases: the bunny at 5000 vertices (pyacvd subdividing it three times
//! first, the setting of its published row) and the bunny subdivided 1-to-4 three times
//! (4.4M faces) at 30,000 (no subdivision: it is fine already).
//!
//! pyacvd is not a dependency of the workspace: the section runs it through a Python that
//! has it (`COARSEN_BENCH_PYTHON`, else `python3`) and says so when there is none.

use crate::speed::{median, timed};
use crate::{load, quality_cells, validity_text};
use anyhow::{Context as _, Result, bail};
use coarsen_mesh::Mesh;
use std::borrow::Cow;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs of each tool per case, one after another; the table gives medians.
const RUNS: usize = 3;

/// The Python script that runs pyacvd once.
const SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/pyacvd_run.py");

/// One tool's run of a case.
#[derive(Clone, Copy)]
enum Tool {
    /// pyacvd, subdividing the input this many times first.
    Pyacvd { subdivisions: u32 },
    /// A shipped coarsen pipeline, as `coarsen run PIPELINE`.
    Coarsen(&'static str),
}

impl Tool {
    fn label(self) -> String {
        match self {
            Tool::Pyacvd { subdivisions: 0 } => "pyacvd".into(),
            Tool::Pyacvd { subdivisions } => format!("pyacvd, subdivide({subdivisions})"),
            Tool::Coarsen(p) => format!("`{p}`"),
        }
    }
}

/// What one run measured: seconds of the clustering and of the whole job.
struct Timing {
    clustering: f64,
    total: f64,
}

/// The Python to run pyacvd with, and pyacvd's version, if one has it.
fn python() -> Option<(String, String)> {
    let python = std::env::var("COARSEN_BENCH_PYTHON").unwrap_or_else(|_| "python3".into());
    let out = Command::new(&python)
        .args(["-c", "import pyacvd, pyvista; print(pyacvd.__version__)"])
        .output()
        .ok()?;
    out.status.success().then(|| {
        (
            python,
            String::from_utf8_lossy(&out.stdout).trim().to_string(),
        )
    })
}

/// Renders the section: the bunny OBJ at `bunny`, and the subdivided bunny that `big`
/// gives (asked for only when pyacvd is there to run).
pub fn section<'m>(bunny: &Path, big: impl FnOnce() -> Result<Cow<'m, Mesh>>) -> Result<String> {
    let mut s = String::from("## pyacvd, measured here\n\n");
    let Some((python, version)) = python() else {
        s.push_str(
            "Not measured: no Python with pyacvd and pyvista was found (`pip install pyacvd`, \
             then set `COARSEN_BENCH_PYTHON` to that Python if it is not `python3`).\n\n",
        );
        return Ok(s);
    };
    let _ = writeln!(
        s,
        "pyacvd {version} (uniform ACVD on the mesh's points) and coarsen's CVT pipelines on the \
         same inputs, {RUNS} runs of each tool in a row (on this machine a process pays for \
         memory the host has taken back: in runs taken in turns each tool would pay for what \
         the other's peak left cold); the outputs of the last run measured by the same \
         metrics against the input. *Clustering*: for pyacvd its `Clustering` \
         set-up (point weights, neighbour lists; after a subdivision, the subdivided mesh's \
         set-up is part of the subdivision and left out) and `cluster` call; for coarsen \
         the `cluster.cvt` stage with the time the runner spent readying the mesh before it and \
         the stages before (the adjacency it builds before the first stage, which the \
         clustering takes over). *Total*: for pyacvd from reading the \
         file to the remeshed output in memory (the interpreter's start, the imports and the \
         saving left out); for coarsen the wall time of the whole `coarsen run` process \
         (start, reading, every stage, writing the file). Medians; the ratios are to pyacvd's \
         medians in the same run.\n"
    );
    s.push_str(
        "| input | target | tool | V | F | α_min | α_avg | P<30° % | Q_min | Q_avg | Hausdorff % | valid | clustering s | clustering ÷ pyacvd | total s | total ÷ pyacvd |\n\
         | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: |\n",
    );
    let dir = tempfile::tempdir()?;
    let big_file = dir.path().join("bunny-subdivided-3.ply");
    coarsen_io::write_path(big()?.as_ref(), &big_file, &Default::default())?;
    let cases: [(&str, &Path, usize, Vec<Tool>); 2] = [
        (
            "stanford-bunny",
            bunny,
            5000,
            vec![
                Tool::Pyacvd { subdivisions: 3 },
                Tool::Coarsen("uniform-cvt"),
                Tool::Coarsen("adaptive-cvt"),
            ],
        ),
        (
            "bunny subdivided 3×",
            &big_file,
            30_000,
            vec![
                Tool::Pyacvd { subdivisions: 0 },
                Tool::Coarsen("uniform-cvt"),
            ],
        ),
    ];
    for (name, file, n, tools) in &cases {
        let input = load(file)?;
        let input_validity = coarsen_metrics::validity(None, &input)?;
        let mut timings: Vec<Vec<Timing>> = tools.iter().map(|_| Vec::new()).collect();
        let outputs: Vec<PathBuf> = (0..tools.len())
            .map(|i| dir.path().join(format!("out-{i}.ply")))
            .collect();
        for (i, tool) in tools.iter().enumerate() {
            for k in 1..=RUNS {
                eprintln!("pyacvd · {name} · {} · run {}", tool.label(), k);
                let t = run(&python, *tool, file, *n, &outputs[i], dir.path())
                    .with_context(|| format!("{} on {name}", tool.label()))?;
                timings[i].push(t);
            }
        }
        let pyacvd_total = median(&mut timings[0].iter().map(|t| t.total).collect::<Vec<_>>());
        let pyacvd_clustering =
            median(&mut timings[0].iter().map(|t| t.clustering).collect::<Vec<_>>());
        for (i, tool) in tools.iter().enumerate() {
            let output = coarsen_io::read_path(&outputs[i], &Default::default())?.mesh;
            let m = coarsen_metrics::measure(Some(&input), &output, &Default::default())?;
            let (q, v) = (&m.quality, &m.validity);
            let clustering =
                median(&mut timings[i].iter().map(|t| t.clustering).collect::<Vec<_>>());
            let total = median(&mut timings[i].iter().map(|t| t.total).collect::<Vec<_>>());
            let _ = writeln!(
                s,
                "| {name} | {n} v | {} | {} | {} | {} | {} | {} | {clustering:.2} | {:.2} | {total:.2} | {:.2} |",
                tool.label(),
                v.n_vertices,
                v.n_faces,
                quality_cells(q),
                m.fidelity
                    .as_ref()
                    .map_or("—".into(), |f| format!("{:.3}", f.hausdorff_pct)),
                validity_text(v, &input_validity),
                clustering / pyacvd_clustering,
                total / pyacvd_total,
            );
        }
    }
    s.push('\n');
    Ok(s)
}

/// Runs `tool` once on `file` to `n` vertices, writing `out`.
fn run(python: &str, tool: Tool, file: &Path, n: usize, out: &Path, dir: &Path) -> Result<Timing> {
    match tool {
        Tool::Pyacvd { subdivisions } => {
            let o = Command::new(python)
                .arg(SCRIPT)
                .arg(file)
                .args([n.to_string(), subdivisions.to_string()])
                .arg(out)
                .output()
                .context("starting Python")?;
            if !o.status.success() {
                bail!("{}", String::from_utf8_lossy(&o.stderr).trim());
            }
            let text = String::from_utf8_lossy(&o.stdout);
            let get = |k: &str| -> Result<f64> {
                text.split_whitespace()
                    .find_map(|w| w.strip_prefix(k).and_then(|v| v.strip_prefix('=')))
                    .and_then(|v| v.parse().ok())
                    .with_context(|| format!("no `{k}` in pyacvd's line `{}`", text.trim()))
            };
            Ok(Timing {
                clustering: get("setup")? + get("cluster")?,
                total: get("total")?,
            })
        }
        Tool::Coarsen(pipeline) => {
            let report = dir.join("report.json");
            let mut cmd = Command::new(std::env::current_exe()?);
            cmd.args(["cli", "-q", "run", pipeline])
                .arg(file)
                .arg("-o")
                .arg(out)
                .args(["--vertices", &n.to_string(), "--report"])
                .arg(&report);
            let total = timed(&mut cmd, pipeline)?;
            let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report)?)?;
            // The clustering stage, and the runner's readying up to it: the adjacency it
            // builds before the first stage is the clustering's, as pyacvd's neighbour
            // lists are its.
            let stages = json["stages"]
                .as_array()
                .context("no stages in the run report")?;
            let at = stages
                .iter()
                .position(|s| s["kind"] == "cluster.cvt")
                .context("no cluster.cvt stage in the run report")?;
            let clustering = stages[at]["seconds"].as_f64().context("no stage seconds")?
                + stages[..=at]
                    .iter()
                    .map(|s| s["ready_seconds"].as_f64().context("no ready_seconds"))
                    .sum::<Result<f64>>()?;
            Ok(Timing { clustering, total })
        }
    }
}
