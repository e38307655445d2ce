//! Times the facade's run on a file: the Rust side of the Python package's benchmark
//! (`python/bench/bench.py` compares `coarsen.remesh` with it, same input and pipeline).
//!
//! ```sh
//! cargo run --release -p coarsen --example time_remesh -- FILE VERTICES PIPELINE RUNS
//! ```
//!
//! Reads `FILE` once, then runs `PIPELINE` to `VERTICES` vertices `RUNS` times in a row
//! (`Remesher::run` on the mesh: the clean-up, every stage, the report) and prints the
//! seconds of each run on one line, space-separated. With `RUNS` = `-`, runs once per line
//! read from its standard input and prints each run's seconds on a line of its own, so
//! that another program can take turns with it run by run.

use std::io::{BufRead, Write};
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
    let once = || -> Result<f64, coarsen::Error> {
        let start = Instant::now();
        let (out, _report) = remesher.run(&mesh)?;
        let seconds = start.elapsed().as_secs_f64();
        assert_eq!(out.n_vertices().to_string(), *vertices);
        Ok(seconds)
    };
    if runs == "-" {
        for line in std::io::stdin().lock().lines() {
            line?;
            let mut stdout = std::io::stdout().lock();
            writeln!(stdout, "{:.6}", once()?)?;
            stdout.flush()?;
        }
        return Ok(());
    }
    let mut seconds = Vec::new();
    for _ in 0..runs.parse::<usize>()? {
        seconds.push(once()?);
    }
    let line: Vec<String> = seconds.iter().map(|s| format!("{s:.6}")).collect();
    println!("{}", line.join(" "));
    Ok(())
}
