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

/// `test.misbehave`, linked into the CLI under test: a stage that panics or hangs on
/// purpose, for the tests of what a batch survives.
pub mod misbehave {
    use coarsen_stage::{Context, Contract, Mesh, ParamIssue, Params, Stage, StageError, params};
    use std::time::{Duration, Instant};

    params! {
        /// Parameters of `test.misbehave`.
        pub struct MisbehaveParams {
            /// Panic (index out of bounds) on meshes with more faces than this; 0 never.
            pub panic_above_faces: u64 = 0,
            /// Spin, reporting progress, on meshes with more faces than this, until the
            /// run is cancelled (or 60 s pass, then fail); 0 never.
            pub hang_above_faces: u64 = 0,
        }
    }
    impl Params for MisbehaveParams {
        fn validate(&self) -> Vec<ParamIssue> {
            Vec::new()
        }
    }

    /// Passes the mesh through, unless it is one to panic or hang on.
    pub struct Misbehave(MisbehaveParams);

    impl Stage for Misbehave {
        type Params = MisbehaveParams;
        const KIND: &'static str = "test.misbehave";
        const SUMMARY: &'static str = "Panics or hangs on purpose (tests only).";
        fn new(p: MisbehaveParams) -> Self {
            Misbehave(p)
        }
        fn contract(&self) -> Contract {
            Contract::default()
        }
        fn run(&self, mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
            let faces = mesh.n_faces() as u64;
            let p = &self.0;
            if p.panic_above_faces > 0 && faces > p.panic_above_faces {
                let none: Vec<u32> = Vec::new();
                let _ = none[faces as usize];
            }
            if p.hang_above_faces > 0 && faces > p.hang_above_faces {
                let start = Instant::now();
                cx.progress.begin("hanging", 0);
                while start.elapsed() < Duration::from_secs(60) {
                    std::thread::sleep(Duration::from_millis(10));
                    cx.progress.advance(0, "still hanging");
                }
                return Err(StageError::Internal("never cancelled".into()));
            }
            Ok(mesh)
        }
    }

    coarsen_stage::export_stage!(Misbehave);
}
