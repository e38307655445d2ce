//! The `coarsen` command: exit codes, outputs, reports, and never a partial output file.

use coarsen_tests::{pipeline_file, read_mesh, run_cli, run_pipeline, stderr, stdout, write_mesh};
use std::fs;
use std::path::{Path, PathBuf};

const EXE: &str = env!("CARGO_BIN_EXE_coarsen-under-test");

#[test]
fn run_without_input_uses_the_demo_mesh_and_writes_output_and_report() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo.ply");
    let report = dir.path().join("report.json");
    let o = run_cli(
        EXE,
        &[
            "run",
            "demo",
            "-o",
            out.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let mesh = read_mesh(&out);
    let demo = coarsen_shapes::demo();
    // The demo pipeline removes 75 % of the faces.
    assert_eq!(mesh.n_faces(), demo.n_faces() / 4);
    let json: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["input"], "demo");
    assert_eq!(json["stages"][0]["kind"], "simplify.qem");
    assert_eq!(json["stages"][1]["kind"], "metrics");
    assert_eq!(json["stages"][1]["figures"]["validity"]["manifold"], true);
    assert!(stdout(&o).contains("simplify.qem"));
}

#[test]
fn no_command_runs_adaptive_cvt_on_the_file_or_the_demo_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("sphere.ply");
    write_mesh(&coarsen_shapes::icosphere(1.0, 4).unwrap(), &input);
    let out = dir.path().join("out.ply");
    let report = dir.path().join("report.json");
    for with_input in [true, false] {
        let mut args = vec!["-q"];
        if with_input {
            args.push(input.to_str().unwrap());
        }
        args.extend([
            "-o",
            out.to_str().unwrap(),
            "--vertices",
            "300",
            "--report",
            report.to_str().unwrap(),
        ]);
        let o = run_cli(EXE, &args);
        assert!(o.status.success(), "{with_input}: {}", stderr(&o));
        let json: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(&report).unwrap()).unwrap();
        assert_eq!(json["pipeline"], "adaptive-cvt", "{with_input}");
        let mesh = read_mesh(&out);
        assert_eq!(mesh.n_vertices(), 300, "{with_input}");
    }
    // A mistyped command is still reported as one, not read as a file.
    let o = run_cli(EXE, &["rnu", "x"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("unrecognized subcommand 'rnu'"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn a_pipeline_error_exits_2_and_names_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.toml");
    fs::write(
        &p,
        "[pipeline]\nname = \"bad\"\n\n[[stage]]\nkind = \"simplify.qme\"\n",
    )
    .unwrap();
    let out = dir.path().join("x.ply");
    let o = run_cli(
        EXE,
        &["run", p.to_str().unwrap(), "-o", out.to_str().unwrap()],
    );
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(
        e.contains(
            "bad.toml:5:8: unknown stage kind `simplify.qme` (did you mean `simplify.qem`?)"
        ),
        "{e}"
    );
    assert!(!out.exists());
    let o = run_cli(EXE, &["check", p.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn usage_errors_exit_2() {
    assert_eq!(run_cli(EXE, &["run"]).status.code(), Some(2));
    assert_eq!(run_cli(EXE, &["frobnicate"]).status.code(), Some(2));
    let o = run_cli(EXE, &["run", "no-such-pipeline", "-o", "x.ply"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("shipped: ") && stderr(&o).contains("demo, "),
        "{}",
        stderr(&o)
    );
    let o = run_cli(
        EXE,
        &["check", "demo", "--set", "simplify.qem.min_quality=2"],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--set simplify.qem.min_quality=2: simplify.qem: must be in 0..=1"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn a_failed_run_exits_1_and_leaves_an_existing_output_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("broken.obj");
    fs::write(&input, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n").unwrap();
    let out = dir.path().join("out.ply");
    fs::write(&out, b"precious").unwrap();
    let o = run_pipeline(EXE, "demo", &input, &out, &[]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.contains("broken.obj:4"), "{e}");
    assert_eq!(fs::read(&out).unwrap(), b"precious");
    // Nothing else was left behind in the folder (no temporary files).
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 2);
}

#[test]
fn the_input_is_never_overwritten() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("sphere.ply");
    write_mesh(&coarsen_shapes::icosphere(1.0, 2).unwrap(), &input);
    let before = fs::read(&input).unwrap();
    let o = run_pipeline(EXE, "demo", &input, &input, &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("refusing to overwrite the input"),
        "{}",
        stderr(&o)
    );
    assert_eq!(fs::read(&input).unwrap(), before);
}

#[test]
fn command_line_target_and_set_reach_the_stages() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("sphere.off");
    write_mesh(&coarsen_shapes::icosphere(1.0, 3).unwrap(), &input);
    let out = dir.path().join("small.obj");
    let report = dir.path().join("r.json");
    let qem = pipeline_file("qem");
    let o = run_cli(
        EXE,
        &[
            "run",
            qem.to_str().unwrap(),
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--vertices",
            "100",
            "--set",
            "simplify.qem.min_quality=0.2",
            "--report",
            report.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(read_mesh(&out).n_vertices(), 100);
    let json: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["target"]["vertices"], 100);
    assert_eq!(json["stages"][0]["params"]["min_quality"], 0.2);
}

#[test]
fn stages_lists_builtins_and_the_linked_plugin_with_defaults() {
    let o = run_cli(EXE, &["stages"]);
    assert!(o.status.success());
    let s = stdout(&o);
    for kind in ["metrics", "simplify.qem", "smooth.taubin"] {
        assert!(
            s.lines().any(|l| l.starts_with(kind)),
            "{kind} missing from:\n{s}"
        );
    }
    assert!(s.contains("lambda"), "{s}");
    let md = stdout(&run_cli(EXE, &["stages", "--markdown"]));
    assert!(
        md.contains("## `smooth.taubin`") && md.contains("| `mu` | `f64` | `-0.53` |"),
        "{md}"
    );
}

#[test]
fn convert_and_info_on_a_procedural_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("torus.stl");
    let torus = coarsen_shapes::torus(2.0, 0.5, 24, 12).unwrap();
    write_mesh(&torus, &a);
    let b = dir.path().join("torus.ply");
    // STL is a soup on disk; --clean welds it back into a closed torus.
    let o = run_cli(
        EXE,
        &[
            "convert",
            "--clean",
            a.to_str().unwrap(),
            b.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run_cli(EXE, &["info", "--json", b.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(json["topology"]["genus_total"], 1);
    assert_eq!(json["topology"]["n_boundary_loops"], 0);
    assert_eq!(json["topology"]["n_vertices"], torus.n_vertices());
    // A smooth closed surface: no feature edge, curve or corner.
    let counts = &json["features"]["counts"];
    assert_eq!(counts["sharp_edges"], 0, "{counts}");
    assert_eq!(
        (counts["curves"].as_u64(), counts["corners"].as_u64()),
        (Some(0), Some(0))
    );
}

#[test]
fn batch_processes_a_folder_keeps_going_past_failures_resumes_and_shards() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = dir.path().join("in");
    fs::create_dir_all(inputs.join("sub")).unwrap();
    write_mesh(
        &coarsen_shapes::icosphere(1.0, 3).unwrap(),
        &inputs.join("a.obj"),
    );
    write_mesh(
        &coarsen_shapes::torus(2.0, 0.5, 32, 16).unwrap(),
        &inputs.join("sub/b.ply"),
    );
    fs::write(inputs.join("broken.off"), "OFF\n3 1 0\n0 0 0\n1 0 0\n").unwrap();
    fs::write(inputs.join("notes.txt"), "not a mesh").unwrap();
    let out = dir.path().join("out");
    let args = |extra: &[&str]| {
        let mut v = vec![
            "batch",
            inputs.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--pipeline",
            "qem",
            "--ratio",
            "0.5",
        ];
        v.extend_from_slice(extra);
        v.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let run = |extra: &[&str]| {
        let a = args(extra);
        run_cli(EXE, &a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let o = run(&[]);
    assert_eq!(
        o.status.code(),
        Some(1),
        "one file is broken: {}",
        stderr(&o)
    );
    let table = stdout(&o);
    assert!(
        table.contains("3 files: 2 ok, 0 skipped, 1 failed"),
        "{table}"
    );
    assert!(out.join("a.ply").is_file() && out.join("sub/b.ply").is_file());
    let summary: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let failed: Vec<_> = summary
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["status"] == "failed")
        .collect();
    assert_eq!(failed.len(), 1);
    assert!(
        failed[0]["error"].as_str().unwrap().contains("broken.off"),
        "{}",
        failed[0]
    );
    assert_eq!(
        fs::read_to_string(out.join("summary.csv"))
            .unwrap()
            .lines()
            .count(),
        4
    );
    // Resumable: up-to-date outputs are skipped, --force redoes them.
    assert!(stdout(&run(&[])).contains("3 files: 0 ok, 2 skipped, 1 failed"));
    assert!(stdout(&run(&["--force"])).contains("3 files: 2 ok, 0 skipped, 1 failed"));
    // Shards partition the files.
    let mut total = 0;
    for i in 0..3 {
        let shard = format!("{i}/3");
        let o = run(&["--force", "--shard", &shard]);
        let line = stdout(&o).lines().last().unwrap().to_string();
        total += line
            .split_whitespace()
            .next()
            .unwrap()
            .parse::<usize>()
            .unwrap();
        assert!(out.join(format!("summary-{i}-of-3.json")).is_file());
    }
    assert_eq!(total, 3);
}

#[test]
fn render_writes_a_png_of_one_mesh_or_two_side_by_side() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.ply");
    let b = dir.path().join("b.ply");
    write_mesh(&coarsen_shapes::icosphere(1.0, 3).unwrap(), &a);
    write_mesh(&coarsen_shapes::icosphere(1.0, 1).unwrap(), &b);
    let png = dir.path().join("pair.png");
    let o = run_cli(
        EXE,
        &[
            "render",
            a.to_str().unwrap(),
            b.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--size",
            "40x30",
            "--wireframe",
            "--view",
            "iso",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    // IHDR: width and height, big-endian, at bytes 16..24.
    assert_eq!(u32::from_be_bytes(bytes[16..20].try_into().unwrap()), 80);
    assert_eq!(u32::from_be_bytes(bytes[20..24].try_into().unwrap()), 30);
    let o = run_cli(
        EXE,
        &[
            "render",
            a.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--attribute",
            "nope",
        ],
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("no vertex or face attribute `nope`"),
        "{}",
        stderr(&o)
    );
}

/// `coarsen stages | head -1`: a reader that goes away early ends the command quietly, with
/// success, instead of a panic about a broken pipe.
#[test]
fn a_closed_stdout_pipe_ends_quietly() {
    let mut child = std::process::Command::new(EXE)
        .arg("stages")
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert!(out.status.success(), "{:?}: {err}", out.status);
}

/// A stage's error reaches the terminal once, named with its stage, and nothing is written.
#[test]
fn a_stage_error_is_printed_once_with_its_stage() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.ply");
    let o = run_cli(
        EXE,
        &[
            "run",
            "uniform-cvt",
            "-o",
            out.to_str().unwrap(),
            "--vertices",
            "2",
            "-q",
        ],
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("stage 3 `dual` failed"), "{err}");
    assert_eq!(err.matches("cannot make a valid mesh").count(), 1, "{err}");
    assert!(!out.exists());
}

/// A folder of three meshes of 80, 320 and 1280 faces, and a pipeline that runs
/// `test.misbehave` with `params` and then QEM to half the faces.
fn misbehaving_batch(dir: &Path, params: &str) -> (PathBuf, PathBuf) {
    let inputs = dir.join("in");
    fs::create_dir_all(&inputs).unwrap();
    for (name, level) in [("small.obj", 1), ("medium.obj", 2), ("large.obj", 3)] {
        write_mesh(
            &coarsen_shapes::icosphere(1.0, level).unwrap(),
            &inputs.join(name),
        );
    }
    let pipeline = dir.join("misbehave.toml");
    fs::write(
        &pipeline,
        format!(
            "[pipeline]\nname = \"m\"\ndescription = \"m\"\ntarget = {{ ratio = 0.5 }}\n\
             [[stage]]\nkind = \"test.misbehave\"\n{params}\n[[stage]]\nkind = \"simplify.qem\"\n"
        ),
    )
    .unwrap();
    (inputs, pipeline)
}

/// The rows of a batch's summary (`summary.json` in `out`, or a shard's), by input file
/// name.
fn summary_rows(out: &Path, file: &str) -> std::collections::BTreeMap<String, serde_json::Value> {
    let summary: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(out.join(file)).unwrap()).unwrap();
    summary
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            let name = Path::new(r["input"].as_str().unwrap())
                .file_name()
                .unwrap()
                .to_string_lossy()
                .into_owned();
            (name, r.clone())
        })
        .collect()
}

#[test]
fn batch_reports_a_panicking_stage_as_that_files_failure_and_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let (inputs, pipeline) = misbehaving_batch(dir.path(), "panic_above_faces = 500");
    let out = dir.path().join("out");
    let o = run_cli(
        EXE,
        &[
            "batch",
            inputs.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--pipeline",
            pipeline.to_str().unwrap(),
            "--jobs",
            "1",
        ],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("3 files: 2 ok, 0 skipped, 1 failed"),
        "{}",
        stdout(&o)
    );
    let rows = summary_rows(&out, "summary.json");
    assert_eq!(rows["small.obj"]["status"], "ok");
    assert_eq!(rows["medium.obj"]["status"], "ok");
    assert_eq!(rows["large.obj"]["status"], "failed");
    let error = rows["large.obj"]["error"].as_str().unwrap();
    assert!(
        error.contains("stage 1 `test.misbehave` failed with an internal error")
            && error.contains("index out of bounds"),
        "{error}"
    );
    assert!(out.join("small.ply").is_file() && !out.join("large.ply").exists());
}

#[test]
fn batch_timeout_ends_a_stuck_file_and_the_rest_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let (inputs, pipeline) = misbehaving_batch(dir.path(), "hang_above_faces = 500");
    let out = dir.path().join("out");
    let started = std::time::Instant::now();
    let o = run_cli(
        EXE,
        &[
            "batch",
            inputs.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--pipeline",
            pipeline.to_str().unwrap(),
            "--timeout",
            "1.5",
        ],
    );
    // Not a speed assertion: without the timeout the stuck file would take 60 s.
    assert!(started.elapsed().as_secs() < 50, "the stuck file was ended");
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let rows = summary_rows(&out, "summary.json");
    assert_eq!(rows["small.obj"]["status"], "ok");
    assert_eq!(rows["medium.obj"]["status"], "ok");
    assert_eq!(rows["large.obj"]["status"], "failed");
    assert_eq!(rows["large.obj"]["error"], "timed out after 1.5 s");
    assert!(!out.join("large.ply").exists());
    let bad = run_cli(
        EXE,
        &[
            "batch",
            inputs.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--timeout",
            "0",
        ],
    );
    assert_eq!(bad.status.code(), Some(2));
    assert!(stderr(&bad).contains("expected a number of seconds above 0, got `0`"));
}

#[test]
fn batch_shards_by_the_path_below_the_input_folder_however_it_is_spelled() {
    let dir = tempfile::tempdir().unwrap();
    let (inputs, _) = misbehaving_batch(dir.path(), "");
    let spelled = dir.path().join("in/../in/.");
    let taken = |root: &Path, out: &str, shard: &str| {
        let out = dir.path().join(out);
        let o = run_cli(
            EXE,
            &[
                "batch",
                root.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--pipeline",
                "qem",
                "--ratio",
                "0.5",
                "--shard",
                shard,
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let suffix = shard.replace('/', "-of-");
        summary_rows(&out, &format!("summary-{suffix}.json"))
            .into_keys()
            .collect::<Vec<_>>()
    };
    let mut all = Vec::new();
    for i in 0..2 {
        let shard = format!("{i}/2");
        let plain = taken(&inputs, "a", &shard);
        assert_eq!(plain, taken(&spelled, "b", &shard), "shard {shard}");
        all.extend(plain);
    }
    all.sort();
    assert_eq!(all, ["large.obj", "medium.obj", "small.obj"]);
}
