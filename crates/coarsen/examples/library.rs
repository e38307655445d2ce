//! coarsen as a library: read a mesh (or take the demo mesh), coarsen it with a shipped
//! pipeline and a parameter override, watch the progress, measure the result, write it.
//!
//! ```sh
//! cargo run --release -p coarsen --example library -- [INPUT] [VERTICES] [OUTPUT]
//! cargo run --release -p coarsen --example library -- ../shared/data/stanford-bunny.obj 5000 bunny-5k.ply
//! ```

use std::process::ExitCode;

/// Prints each stage's progress steps on one line each.
struct Steps;

impl coarsen::Progress for Steps {
    fn begin(&self, label: &str, total: u64) {
        eprintln!("  {label} ({total} steps)");
    }
    fn advance(&self, _done: u64, _message: &str) {}
    fn end(&self) {}
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let vertices: u64 = match args.get(1).map(|n| n.parse()) {
        None => 2000,
        Some(Ok(n)) => n,
        Some(Err(e)) => {
            eprintln!("error: VERTICES must be a whole number: {e}");
            return ExitCode::from(2);
        }
    };
    match run(args.first(), vertices, args.get(2)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(if e.is_usage() { 2 } else { 1 })
        }
    }
}

fn run(
    input: Option<&String>,
    vertices: u64,
    output: Option<&String>,
) -> Result<(), coarsen::Error> {
    let mesh = match input {
        Some(path) => coarsen::read(path)?,
        None => coarsen::demo(),
    };
    println!(
        "input: {} vertices, {} faces",
        mesh.n_vertices(),
        mesh.n_faces()
    );

    // The one-call form: the default pipeline (adaptive CVT, paper 1).
    let (out, report) = coarsen::remesh(&mesh, coarsen::Target::Vertices(vertices))?;
    println!(
        "{}: {} vertices, {} faces in {:.2} s",
        report.pipeline,
        out.n_vertices(),
        out.n_faces(),
        report.seconds
    );

    // The builder: another pipeline, a parameter, progress.
    let (uniform, report) = coarsen::Remesher::new()
        .pipeline("uniform-cvt")
        .target(coarsen::Target::Vertices(vertices))
        .set("relax.sweeps", "6")
        .progress(&Steps)
        .run(&mesh)?;
    println!(
        "{}: {} vertices in {:.2} s",
        report.pipeline,
        uniform.n_vertices(),
        report.seconds
    );

    // The figures of `coarsen metrics`.
    for (name, m) in [("adaptive-cvt", &out), ("uniform-cvt", &uniform)] {
        let figures = coarsen::metrics(&mesh, m, &Default::default())?;
        println!(
            "{name}: smallest angle {:.1}°, mean smallest angle {:.1}°, Hausdorff {:.3} % of the diagonal",
            figures.quality.alpha_min_deg,
            figures.quality.alpha_avg_deg,
            figures.fidelity.map_or(f64::NAN, |f| f.hausdorff_pct)
        );
    }

    if let Some(path) = output {
        coarsen::write(path, &out)?;
        println!("wrote {path}");
    }
    Ok(())
}
