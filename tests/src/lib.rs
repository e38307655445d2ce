//! Support for coarsen's integration tests: where the shared meshes are, and running the CLI.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The folder of real test meshes (`../shared/data` beside the checkout, or `$COARSEN_DATA`),
/// or `None` — after printing why — when it is absent, so the calling test can return early.
pub fn shared_data() -> Option<PathBuf> {
    coarsen_testdata::dir()
}

/// The path of a shipped pipeline file.
pub fn pipeline_file(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../pipelines")
        .join(format!("{name}.toml"))
}

/// Runs the CLI binary `exe` with `args`, without standard input.
pub fn run_cli(exe: &str, args: &[&str]) -> Output {
    Command::new(exe)
        .args(args)
        .stdin(std::process::Stdio::null())
        .output()
        .expect("the CLI binary runs")
}

/// Runs `coarsen run PIPELINE INPUT -o OUTPUT EXTRA…` with the CLI binary `exe`.
pub fn run_pipeline(
    exe: &str,
    pipeline: &str,
    input: &Path,
    output: &Path,
    extra: &[&str],
) -> Output {
    let (input, output) = (input.display().to_string(), output.display().to_string());
    let mut args = vec!["run", pipeline, input.as_str(), "-o", output.as_str()];
    args.extend_from_slice(extra);
    run_cli(exe, &args)
}

/// Writes `mesh` to `path` (format by extension), for a test's input files.
pub fn write_mesh(mesh: &coarsen_mesh::Mesh, path: &Path) {
    coarsen_io::write_path(mesh, path, &Default::default()).expect("the test mesh is written");
}

/// Standard error of a finished command, as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Standard output of a finished command, as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Reads the mesh at `path` (a run's output or a test mesh), panicking with the file's
/// error when it cannot.
pub fn read_mesh(path: &Path) -> coarsen_mesh::Mesh {
    coarsen_io::read_path(path, &Default::default())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .mesh
}

/// The adjacency summary of `mesh`, asserting that it is a consistently oriented
/// manifold (`what` names the case in the failure).
pub fn oriented_manifold(mesh: &coarsen_mesh::Mesh, what: &str) -> coarsen_mesh::TopologySummary {
    let s = coarsen_mesh::Topology::build(mesh).summary(mesh);
    assert!(s.manifold && s.consistently_oriented, "{what}: {s:?}");
    s
}
