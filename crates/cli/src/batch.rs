//! `coarsen batch`: one pipeline over many files, in parallel across files, resumable,
//! shardable, with a summary table.

use crate::Failure;
use crate::load;
use coarsen_io::Format;
use coarsen_pipeline::Pipeline;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use serde::Serialize;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// `--shard I/N`: this process handles the files whose stable hash is `I` modulo `N`; the
/// hash is of a file's path relative to the input folder it was found in (its name for a
/// file given by itself), so workers that spell the folder differently agree.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This shard, `0 ≤ index < count`.
    pub index: u64,
    /// Number of shards.
    pub count: u64,
}

impl FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| format!("expected I/N, got `{s}`"))?;
        let index: u64 = i
            .trim()
            .parse()
            .map_err(|_| format!("bad shard index `{i}`"))?;
        let count: u64 = n
            .trim()
            .parse()
            .map_err(|_| format!("bad shard count `{n}`"))?;
        if count == 0 || index >= count {
            return Err(format!("shard index must be in 0..{count}, got {index}"));
        }
        Ok(Shard { index, count })
    }
}

impl Shard {
    /// True when `key` belongs to this shard (FNV-1a of the key, stable across runs and machines).
    pub fn takes(&self, key: &str) -> bool {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in key.bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
        h % self.count == self.index
    }
}

/// Options of one batch.
pub struct Batch<'a> {
    /// Files and folders to process.
    pub inputs: &'a [PathBuf],
    /// Output folder.
    pub out: &'a Path,
    /// The checked pipeline.
    pub pipeline: &'a Arc<Pipeline>,
    /// Output format.
    pub format: Format,
    /// Redo outputs that are already up to date.
    pub force: bool,
    /// This process's shard.
    pub shard: Option<Shard>,
    /// Parallel files.
    pub jobs: usize,
    /// Weld coincident vertices on load.
    pub weld: bool,
    /// Hide progress.
    pub quiet: bool,
    /// A file whose run takes longer is stopped and reported failed.
    pub timeout: Option<Duration>,
}

/// One line of the summary.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// Input file.
    pub input: String,
    /// Output file.
    pub output: String,
    /// `ok`, `skipped` (output up to date) or `failed`.
    pub status: &'static str,
    /// Input vertices after clean-up.
    pub vertices_in: Option<usize>,
    /// Input faces after clean-up.
    pub faces_in: Option<usize>,
    /// Output vertices.
    pub vertices_out: Option<usize>,
    /// Output faces.
    pub faces_out: Option<usize>,
    /// Wall time of load, run and write, in seconds.
    pub seconds: Option<f64>,
    /// Smallest angle of the output, degrees.
    pub alpha_min_deg: Option<f64>,
    /// Mean smallest angle of the output, degrees.
    pub alpha_avg_deg: Option<f64>,
    /// Hausdorff distance, when the pipeline measured it (a `metrics` stage).
    pub hausdorff_pct: Option<f64>,
    /// Why it failed.
    pub error: Option<String>,
}

impl Row {
    fn new(input: &Path, output: &Path, status: &'static str) -> Row {
        Row {
            input: input.display().to_string(),
            output: output.display().to_string(),
            status,
            vertices_in: None,
            faces_in: None,
            vertices_out: None,
            faces_out: None,
            seconds: None,
            alpha_min_deg: None,
            alpha_avg_deg: None,
            hausdorff_pct: None,
            error: None,
        }
    }
}

/// One file of a batch.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Job {
    /// The input file.
    pub input: PathBuf,
    /// The output file it maps to.
    pub output: PathBuf,
    /// Its path relative to the input folder (its name when given by itself), `/`
    /// between components: what `--shard` hashes.
    pub key: String,
}

/// Every mesh file under the inputs, with the output path it maps to (sorted, stable).
pub fn collect(inputs: &[PathBuf], out: &Path, format: Format) -> Result<Vec<Job>, Failure> {
    let mut jobs = Vec::new();
    let mut add = |input: PathBuf, rel: &Path| {
        let key = rel
            .components()
            .map(|c| c.as_os_str().to_string_lossy())
            .collect::<Vec<_>>()
            .join("/");
        let output = out.join(rel).with_extension(format.extension());
        jobs.push(Job { input, output, key });
    };
    for input in inputs {
        if input.is_dir() {
            let mut files = Vec::new();
            walk(input, &mut files)
                .map_err(|e| Failure::Runtime(anyhow::anyhow!("{}: {e}", input.display())))?;
            files.sort();
            for f in files {
                let rel = f.strip_prefix(input).unwrap_or(&f).to_path_buf();
                add(f, &rel);
            }
        } else if input.is_file() {
            let name = input
                .file_name()
                .map(PathBuf::from)
                .unwrap_or_else(|| PathBuf::from("mesh"));
            add(input.clone(), &name);
        } else {
            return Err(Failure::Usage(format!(
                "{}: no such file or folder",
                input.display()
            )));
        }
    }
    Ok(jobs)
}

fn walk(dir: &Path, files: &mut Vec<PathBuf>) -> std::io::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        if path.is_dir() {
            walk(&path, files)?;
        } else if Format::from_path(&path).is_some() {
            files.push(path);
        }
    }
    Ok(())
}

fn up_to_date(input: &Path, output: &Path) -> bool {
    let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    matches!((modified(input), modified(output)), (Some(i), Some(o)) if o >= i)
}

/// Runs the batch; returns one row per file, in input order.
pub fn run(b: &Batch<'_>) -> Result<Vec<Row>, Failure> {
    let mut jobs = collect(b.inputs, b.out, b.format)?;
    if let Some(shard) = b.shard {
        jobs.retain(|job| shard.takes(&job.key));
    }
    let bar = if !b.quiet && std::io::stderr().is_terminal() {
        let style =
            ProgressStyle::with_template("{prefix:>10} [{bar:30}] {pos}/{len} files ({eta})")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> ");
        let bar =
            ProgressBar::with_draw_target(Some(jobs.len() as u64), ProgressDrawTarget::stderr())
                .with_style(style);
        bar.set_prefix("batch");
        bar
    } else {
        ProgressBar::hidden()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(b.jobs.max(1))
        .build()
        .map_err(|e| Failure::Runtime(e.into()))?;
    let rows = pool.install(|| {
        jobs.par_iter()
            .map(|job| {
                let row = one(b, &job.input, &job.output);
                bar.inc(1);
                row
            })
            .collect::<Vec<_>>()
    });
    bar.finish_and_clear();
    Ok(rows)
}

/// Loads, runs and writes one file; whatever happens (an error, a panic, the timeout) ends
/// up in its row, never in the rest of the batch.
fn one(b: &Batch<'_>, input: &Path, output: &Path) -> Row {
    if !b.force && up_to_date(input, output) {
        return Row::new(input, output, "skipped");
    }
    let mut row = Row::new(input, output, "ok");
    let t = Instant::now();
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        process(b, input, output, &mut row)
    }))
    .unwrap_or_else(|payload| {
        Err(anyhow::anyhow!(
            "internal error (a bug in coarsen; please report it with the input): {}",
            coarsen_pipeline::panic_message(payload.as_ref())
        ))
    });
    row.seconds = Some(t.elapsed().as_secs_f64());
    if let Err(e) = result {
        row.status = "failed";
        row.error = Some(format!("{e:#}"));
    }
    row
}

fn process(b: &Batch<'_>, input: &Path, output: &Path, row: &mut Row) -> anyhow::Result<()> {
    let loaded = load::open(input)?;
    let name = loaded.name.clone();
    let cleaned = coarsen::clean(loaded, b.weld)?;
    row.vertices_in = Some(cleaned.mesh.n_vertices());
    row.faces_in = Some(cleaned.mesh.n_faces());
    let done = match b.timeout {
        None => coarsen::Remesher::new().run_cleaned(b.pipeline, &name, cleaned)?,
        Some(limit) => with_timeout(b.pipeline, name, cleaned, limit)?,
    };
    let (mesh, report) = (done.mesh, done.report);
    if let Some(parent) = output.parent() {
        std::fs::create_dir_all(parent)?;
    }
    coarsen_io::write_path(&mesh, output, &Default::default())?;
    row.vertices_out = Some(mesh.n_vertices());
    row.faces_out = Some(mesh.n_faces());
    if let Ok(q) = coarsen_metrics::quality(&mesh) {
        row.alpha_min_deg = Some(q.alpha_min_deg);
        row.alpha_avg_deg = Some(q.alpha_avg_deg);
    }
    row.hausdorff_pct = report.stages.iter().rev().find_map(|s| {
        s.figures
            .get("fidelity")
            .and_then(|f| f["hausdorff_pct"].as_f64())
    });
    Ok(())
}

/// How long a run may go on after its timeout before the batch leaves it behind: a stage
/// stops at its next progress report or at the next stage, which is usually at once.
const GRACE: Duration = Duration::from_secs(5);

/// Runs `pipeline` on its own thread and cancels it after `limit`. A run that does not
/// stop within [`GRACE`] is left to finish on its own (its result is dropped), so that the
/// batch goes on.
fn with_timeout(
    pipeline: &Arc<Pipeline>,
    name: String,
    cleaned: coarsen::Cleaned,
    limit: Duration,
) -> anyhow::Result<coarsen::Remeshed> {
    let cancel = Arc::new(AtomicBool::new(false));
    let (send, receive) = std::sync::mpsc::channel();
    let (flag, pipeline) = (Arc::clone(&cancel), Arc::clone(pipeline));
    std::thread::Builder::new()
        .name(format!("batch {name}"))
        .spawn(move || {
            let done = coarsen::Remesher::new()
                .cancel(&flag)
                .run_cleaned(&pipeline, &name, cleaned);
            // The batch may have stopped waiting: then nobody reads this.
            let _ = send.send(done);
        })?;
    let timed_out = || anyhow::anyhow!("timed out after {} s", limit.as_secs_f64());
    match receive.recv_timeout(limit) {
        Ok(done) => return Ok(done?),
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
            anyhow::bail!("the run's thread ended without a result")
        }
        Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
    }
    cancel.store(true, std::sync::atomic::Ordering::Relaxed);
    match receive.recv_timeout(GRACE) {
        // Finished just as the time ran out: the result is good.
        Ok(Ok(done)) => Ok(done),
        Ok(Err(e)) if e.is_cancelled() => Err(timed_out()),
        Ok(Err(e)) => Err(e.into()),
        Err(_) => Err(timed_out().context(format!(
            "the run did not stop within {} s of being cancelled and was left behind",
            GRACE.as_secs()
        ))),
    }
}

/// The summary as a table for people.
pub fn table(rows: &[Row]) -> String {
    let opt = |x: Option<usize>| x.map(|v| v.to_string()).unwrap_or_else(|| "—".into());
    let optf =
        |x: Option<f64>, d: usize| x.map(|v| format!("{v:.d$}")).unwrap_or_else(|| "—".into());
    let mut s = String::from(
        "| file | status | V in → out | F in → out | s | α_min | α_avg | Hausdorff % | error |\n",
    );
    s.push_str("| --- | --- | --- | --- | ---: | ---: | ---: | ---: | --- |\n");
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {} → {} | {} → {} | {} | {} | {} | {} | {} |\n",
            r.input,
            r.status,
            opt(r.vertices_in),
            opt(r.vertices_out),
            opt(r.faces_in),
            opt(r.faces_out),
            optf(r.seconds, 3),
            optf(r.alpha_min_deg, 2),
            optf(r.alpha_avg_deg, 2),
            optf(r.hausdorff_pct, 3),
            r.error
                .as_deref()
                .unwrap_or("")
                .replace('|', "/")
                .replace('\n', " "),
        ));
    }
    let failed = rows.iter().filter(|r| r.status == "failed").count();
    let skipped = rows.iter().filter(|r| r.status == "skipped").count();
    s.push_str(&format!(
        "\n{} files: {} ok, {skipped} skipped, {failed} failed\n",
        rows.len(),
        rows.len() - failed - skipped
    ));
    s
}

/// The summary as CSV (one header line, one line per file).
pub fn csv(rows: &[Row]) -> String {
    let field = |s: &str| {
        if s.contains([',', '"', '\n']) {
            format!("\"{}\"", s.replace('"', "\"\""))
        } else {
            s.to_string()
        }
    };
    let n = |x: Option<usize>| x.map(|v| v.to_string()).unwrap_or_default();
    let f = |x: Option<f64>| x.map(|v| v.to_string()).unwrap_or_default();
    let mut s = String::from(
        "input,output,status,vertices_in,faces_in,vertices_out,faces_out,seconds,alpha_min_deg,alpha_avg_deg,hausdorff_pct,error\n",
    );
    for r in rows {
        let line = [
            field(&r.input),
            field(&r.output),
            r.status.to_string(),
            n(r.vertices_in),
            n(r.faces_in),
            n(r.vertices_out),
            n(r.faces_out),
            f(r.seconds),
            f(r.alpha_min_deg),
            f(r.alpha_avg_deg),
            f(r.hausdorff_pct),
            field(r.error.as_deref().unwrap_or("")),
        ];
        s.push_str(&line.join(","));
        s.push('\n');
    }
    s
}

/// Parses `--format`.
pub fn format_arg(s: &str) -> Result<Format, Failure> {
    s.parse::<Format>()
        .map_err(|e| Failure::Usage(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_keys_stably() {
        let keys: Vec<String> = (0..200).map(|i| format!("models/part{i}.obj")).collect();
        let shards: Vec<Shard> = (0..3).map(|i| Shard { index: i, count: 3 }).collect();
        for k in &keys {
            assert_eq!(shards.iter().filter(|s| s.takes(k)).count(), 1, "{k}");
        }
        let sizes: Vec<usize> = shards
            .iter()
            .map(|s| keys.iter().filter(|k| s.takes(k)).count())
            .collect();
        assert!(sizes.iter().all(|&n| n > 40), "{sizes:?}");
        // Stable: the same key always lands in the same shard (FNV-1a, fixed constants).
        assert!(Shard { index: 0, count: 1 }.takes("anything"));
        assert_eq!("2/3".parse::<Shard>(), Ok(Shard { index: 2, count: 3 }));
        assert!("3/3".parse::<Shard>().is_err());
        assert!("1".parse::<Shard>().is_err());
    }

    #[test]
    fn csv_quotes_fields_with_commas() {
        let mut r = Row::new(Path::new("a,b.obj"), Path::new("out/a.ply"), "failed");
        r.error = Some("bad \"thing\"".into());
        let text = csv(&[r]);
        assert!(
            text.lines()
                .nth(1)
                .unwrap()
                .starts_with("\"a,b.obj\",out/a.ply,failed,"),
            "{text}"
        );
        assert!(text.contains("\"bad \"\"thing\"\"\""), "{text}");
    }
}
