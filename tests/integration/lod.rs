//! Progressive levels of detail through the CLI: `run --progressive` then `lod` gives back
//! the input exactly, and any vertex count in between.

use coarsen_mesh::Mesh;
use coarsen_tests::{run_cli, run_pipeline, shared_data, stderr, write_mesh};
use std::path::Path;

const EXE: &str = env!("CARGO_BIN_EXE_coarsen-under-test");

fn read(path: &Path) -> Mesh {
    coarsen_io::read_path(path, &Default::default())
        .unwrap_or_else(|e| panic!("{e}"))
        .mesh
}

/// Faces rotated so that their smallest index comes first, then sorted: equal exactly when
/// the faces are the same up to order and cyclic rotation.
fn face_set(m: &Mesh) -> Vec<[u32; 3]> {
    let mut f: Vec<[u32; 3]> = m
        .faces
        .iter()
        .map(|&f| {
            let i = (0..3).min_by_key(|&i| f[i]).unwrap_or(0);
            [f[i], f[(i + 1) % 3], f[(i + 2) % 3]]
        })
        .collect();
    f.sort_unstable();
    f
}

fn bits(m: &Mesh) -> Vec<[u64; 3]> {
    m.positions
        .iter()
        .map(|p| p.to_array().map(f64::to_bits))
        .collect()
}

/// Runs `pipeline --ratio ratio --progressive`, then rebuilds every collapse (checked
/// against `input`, the mesh as the run loaded it), the level of `vertices` vertices, half
/// the collapses, and level 0.
fn round_trip(
    input_file: &Path,
    input: &Mesh,
    pipeline: &str,
    ratio: &str,
    vertices: Option<usize>,
) {
    let dir = tempfile::tempdir().unwrap();
    let (coarse, record, report) = (
        dir.path().join("coarse.ply"),
        dir.path().join("record.lod"),
        dir.path().join("report.json"),
    );
    let o = run_pipeline(
        EXE,
        pipeline,
        input_file,
        &coarse,
        &[
            "--ratio",
            ratio,
            "--progressive",
            record.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{pipeline}: {}", stderr(&o));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let collapses = json["stages"][0]["figures"]["collapses"].as_u64().unwrap();
    assert!(collapses > 0);
    let all = dir.path().join("all.obj");
    let lod = |which: &str, n: String, out: &Path| {
        run_cli(
            EXE,
            &[
                "lod",
                coarse.to_str().unwrap(),
                record.to_str().unwrap(),
                which,
                &n,
                "-o",
                out.to_str().unwrap(),
            ],
        )
    };
    let o = lod("--level", collapses.to_string(), &all);
    assert!(o.status.success(), "{pipeline}: {}", stderr(&o));
    let back = read(&all);
    assert_eq!(back.n_vertices(), input.n_vertices(), "{pipeline}");
    assert!(bits(&back) == bits(input), "{pipeline}: positions differ");
    assert_eq!(face_set(&back), face_set(input), "{pipeline}");

    let mid = dir.path().join("mid.ply");
    if let Some(n) = vertices {
        let o = lod("--vertices", n.to_string(), &mid);
        assert!(o.status.success(), "{pipeline}: {}", stderr(&o));
        let m = read(&mid);
        assert_eq!(m.n_vertices(), n, "{pipeline}");
        let t = coarsen_mesh::Topology::build(&m).summary(&m);
        assert!(t.manifold && t.consistently_oriented, "{pipeline}");
    }
    // Half the collapses undone; `--vertices` of its count picks the same level.
    let o = lod("--level", (collapses / 2).to_string(), &mid);
    assert!(o.status.success(), "{pipeline}: {}", stderr(&o));
    let half = read(&mid);
    let again = dir.path().join("again.ply");
    let o = lod("--vertices", half.n_vertices().to_string(), &again);
    assert!(o.status.success(), "{pipeline}: {}", stderr(&o));
    assert_eq!(read(&again), half, "{pipeline}");
    let t = coarsen_mesh::Topology::build(&half).summary(&half);
    assert!(t.manifold && t.consistently_oriented, "{pipeline}");
    let level0 = dir.path().join("level0.ply");
    assert!(lod("--level", "0".into(), &level0).status.success());
    assert_eq!(read(&level0), read(&coarse), "{pipeline}");
}

#[test]
fn run_progressive_then_lod_gives_back_the_input_and_any_level() {
    let dir = tempfile::tempdir().unwrap();
    let input = coarsen_shapes::torus(3.0, 1.0, 40, 20).unwrap();
    let file = dir.path().join("torus.ply");
    write_mesh(&input, &file);
    round_trip(&file, &input, "qem", "0.9", Some(333));
    // SVEC removes two vertices per triangle collapse: not every count is a level.
    round_trip(&file, &input, "svec", "0.9", None);
}

#[test]
fn run_progressive_on_the_bunny_gives_back_the_cleaned_input() {
    let Some(data) = shared_data() else { return };
    let file = data.join("stanford-bunny.obj");
    let Some(input) = coarsen_testdata::cleaned("stanford-bunny.obj") else {
        return;
    };
    round_trip(&file, &input, "qem", "0.9", Some(20_000));
}

#[test]
fn progressive_needs_a_collapse_stage_ending_the_run_and_a_sound_record() {
    let dir = tempfile::tempdir().unwrap();
    let input = coarsen_shapes::icosphere(1.0, 3).unwrap();
    let file = dir.path().join("sphere.ply");
    write_mesh(&input, &file);
    let (out, record) = (dir.path().join("out.ply"), dir.path().join("r.lod"));
    let progressive = ["--progressive", record.to_str().unwrap()];

    // No collapse stage: a usage error before any work, nothing written.
    let mut args = vec!["--vertices", "100"];
    args.extend(progressive);
    let o = run_pipeline(EXE, "uniform-cvt", &file, &out, &args);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--progressive needs a stage that records its collapses"));
    assert!(!out.exists() && !record.exists());

    // A stage after the collapse stage changes the mesh: an error, nothing written.
    let mut args = vec!["--vertices", "60"];
    args.extend(progressive);
    let o = run_pipeline(EXE, "svec-then-cvt", &file, &out, &args);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("a later stage"), "{}", stderr(&o));
    assert!(!out.exists() && !record.exists());

    // A damaged record: an error naming the file, no output.
    let mut args = vec!["--ratio", "0.5"];
    args.extend(progressive);
    let o = run_pipeline(EXE, "qem", &file, &out, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut bytes = std::fs::read(&record).unwrap();
    let n = bytes.len();
    bytes[n / 2] ^= 1;
    let damaged = dir.path().join("damaged.lod");
    std::fs::write(&damaged, &bytes).unwrap();
    let level = dir.path().join("level.ply");
    let lod = |coarse: &Path, record: &Path, which: &str| {
        run_cli(
            EXE,
            &[
                "lod",
                coarse.to_str().unwrap(),
                record.to_str().unwrap(),
                "--level",
                which,
                "-o",
                level.to_str().unwrap(),
            ],
        )
    };
    let o = lod(&out, &damaged, "3");
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("damaged.lod") && stderr(&o).contains("checksum"),
        "{}",
        stderr(&o)
    );
    assert!(!level.exists());
    // The wrong coarse mesh, and a level that does not exist.
    let o = lod(&file, &record, "3");
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("is not the one the record was taken from"));
    let o = lod(&out, &record, "100000");
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("level 100000 does not exist"),
        "{}",
        stderr(&o)
    );
    assert!(!level.exists());
}
