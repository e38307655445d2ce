//! Times the facade's run on a file: the Rust side of the Python package's benchmark
//! (`python/bench/bench.py` compares `coarsen.remesh` with it, same input and pipeline).
//!
//! ```sh
//! cargo run --release -p coarsen --example time_remesh -- FILE VERTICES PIPELINE RUNS
//! ```
//!
//! Reads `FILE` once, then runs `PIPELINE` to `VERTICES` vertices `RUNS` times in a row
//! (`Remesher::run` on the mesh: the clean-up, every stage, the report) and prints the
//! seconds of each run on one line, space-separated.

use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [file, vertices, pipeline, runs] = args.as_slice() else {
        return Err("usage: time_remesh FILE VERTICES PIPELINE RUNS".into());
    };
    let mesh = coarsen::read(file)?;
    let remesher = coarsen::Remesher::new()
        .pipeline(pipeline.as_str())
        .target(coarsen::Target::Vertices(vertices.parse()?));
    let mut seconds = Vec::new();
    for _ in 0..runs.parse::<usize>()? {
        let start = Instant::now();
        let (out, _report) = remesher.run(&mesh)?;
        seconds.push(start.elapsed().as_secs_f64());
        assert_eq!(out.n_vertices().to_string(), *vertices);
    }
    let line: Vec<String> = seconds.iter().map(|s| format!("{s:.6}")).collect();
    println!("{}", line.join(" "));
    Ok(())
}
