//! The speed section of the tables: the whole `coarsen` process (start, reading the OBJ,
//! the pipeline, writing the output) on the bunny at 5000 vertices, timed from outside
//! over several runs, beside a process that only reads the file — the baseline measured in
//! the same run. The runs of all cases take turns, so that a noisy moment of the machine
//! spreads over every case instead of falling on one.

use anyhow::{Context as _, Result, bail};
use std::fmt::Write as _;
use std::path::Path;
use std::process::{Command, ExitCode};
use std::time::Instant;

/// Runs per case; the table gives the median and the fastest.
const RUNS: usize = 7;

/// The cases: a label and the `coarsen` command line, `IN` and `OUT` standing for the
/// bunny and a temporary output file.
const CASES: &[(&str, &[&str])] = &[
    ("read the OBJ only: `coarsen info IN`", &["info", "IN"]),
    (
        "the default job: `coarsen IN -o OUT --vertices 5000` (adaptive-cvt)",
        &["-q", "IN", "-o", "OUT", "--vertices", "5000"],
    ),
    (
        "`coarsen run uniform-cvt IN -o OUT --vertices 5000`",
        &[
            "-q",
            "run",
            "uniform-cvt",
            "IN",
            "-o",
            "OUT",
            "--vertices",
            "5000",
        ],
    ),
    (
        "`coarsen run qem IN -o OUT --vertices 5000`",
        &["-q", "run", "qem", "IN", "-o", "OUT", "--vertices", "5000"],
    ),
];

/// Runs `coarsen` with `args` in this process (for the child processes of the section).
pub fn child(args: Vec<std::ffi::OsString>) -> ExitCode {
    coarsen_cli::main_from(std::iter::once("coarsen".into()).chain(args))
}

/// Times every case on `bunny` (an OBJ file) and renders the section.
pub fn section(bunny: &Path) -> Result<String> {
    let dir = tempfile::tempdir()?;
    let exe = std::env::current_exe()?;
    let mut times = vec![Vec::with_capacity(RUNS); CASES.len()];
    for run in 0..RUNS {
        for (i, (label, args)) in CASES.iter().enumerate() {
            eprintln!("speed · run {} · {label}", run + 1);
            let mut cmd = Command::new(&exe);
            cmd.arg("cli");
            for &a in *args {
                match a {
                    "IN" => cmd.arg(bunny),
                    "OUT" => cmd.arg(dir.path().join("out.ply")),
                    a => cmd.arg(a),
                };
            }
            cmd.stdout(std::process::Stdio::null());
            times[i].push(timed(&mut cmd, label)?);
        }
    }
    let mut s = String::new();
    let _ = writeln!(
        s,
        "## Speed — the whole `coarsen` process on the bunny\n\n\
         Wall time of a child process that reads `stanford-bunny.obj`, runs the pipeline and \
         writes a binary PLY, {RUNS} runs per case taken in turns (release build, this machine; \
         the children allocate as the `coarsen` binary does). \
         *÷ read* is the median over the median of a process that only reads the file.\n"
    );
    s.push_str("| case | median s | fastest s | ÷ read |\n| --- | ---: | ---: | ---: |\n");
    let medians: Vec<f64> = times.iter_mut().map(|t| median(t)).collect();
    for (i, (label, _)) in CASES.iter().enumerate() {
        let fastest = times[i].iter().copied().fold(f64::INFINITY, f64::min);
        let _ = writeln!(
            s,
            "| {label} | {:.3} | {:.3} | {:.1} |",
            medians[i],
            fastest,
            medians[i] / medians[0]
        );
    }
    s.push('\n');
    Ok(s)
}

/// Runs `cmd` (a copy of this program) to its end: its wall time in seconds, or an error
/// naming `label` with the child's message when it fails.
pub(crate) fn timed(cmd: &mut Command, label: &str) -> Result<f64> {
    let t = Instant::now();
    let out = cmd
        .output()
        .context("the benchmark starts a copy of itself")?;
    let seconds = t.elapsed().as_secs_f64();
    if !out.status.success() {
        bail!(
            "`{label}` failed: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(seconds)
}

/// The median of `t` (sorts it).
pub(crate) fn median(t: &mut [f64]) -> f64 {
    t.sort_by(f64::total_cmp);
    match t.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => t[n / 2],
        n => 0.5 * (t[n / 2 - 1] + t[n / 2]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!(median(&mut []).is_nan());
    }
}
