//! Hostile but readable inputs through the CLI (issue 8's corpus, generated here): each has
//! its documented outcome (`docs/robustness.md`) — a clear error with exit code 1 and no
//! output file, or a run whose repairs and refusals are reported.

use coarsen_mesh::{DVec3, Mesh, Topology};
use coarsen_tests::{
    oriented_manifold, read_mesh, run_cli, run_pipeline, stderr, stdout, write_mesh,
};
use serde_json::Value;
use std::path::Path;

const EXE: &str = env!("CARGO_BIN_EXE_coarsen-under-test");

/// The regular octahedron: 6 vertices, 8 faces, closed, genus 0.
fn octahedron() -> Mesh {
    let v = [
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    Mesh::new(
        v.iter().map(|&p| DVec3::from_array(p)).collect(),
        vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ],
    )
}

fn mesh(positions: &[[f64; 3]], faces: &[[u32; 3]]) -> Mesh {
    Mesh::new(
        positions.iter().map(|&p| DVec3::from_array(p)).collect(),
        faces.to_vec(),
    )
}

/// What a successful run said: the report, and the output mesh as read back.
struct Ran {
    report: Value,
    output: Mesh,
}

impl Ran {
    /// Every warning of every stage.
    fn warnings(&self) -> Vec<String> {
        self.report["stages"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|s| s["warnings"].as_array().unwrap().iter())
            .map(|w| w.as_str().unwrap().to_string())
            .collect()
    }

    /// The load-time notes.
    fn notes(&self) -> Vec<String> {
        self.report["input_notes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|n| n.as_str().unwrap().to_string())
            .collect()
    }

    fn counts(&self) -> (usize, usize) {
        (self.output.n_vertices(), self.output.n_faces())
    }
}

/// Writes `input` as `name` in a temporary folder and runs `pipeline` on it with `extra`
/// arguments; the run must succeed without a panic.
fn run_ok(input: &Mesh, name: &str, pipeline: &str, extra: &[&str]) -> Ran {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    write_mesh(input, &path);
    run_file_ok(&path, pipeline, extra)
}

fn run_file_ok(path: &Path, pipeline: &str, extra: &[&str]) -> Ran {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.ply");
    let report = dir.path().join("report.json");
    let mut args = extra.to_vec();
    args.extend(["--report", report.to_str().unwrap()]);
    let o = run_pipeline(EXE, pipeline, path, &out, &args);
    let e = stderr(&o);
    assert!(o.status.success(), "{pipeline} {extra:?}: {e}");
    assert!(!e.contains("panicked"), "{e}");
    let report: Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let output = read_mesh(&out);
    coarsen_mesh::sanity_check_with(
        &output,
        &coarsen_mesh::SanityOptions {
            degenerate_area_rel: 0.0,
            ..Default::default()
        },
    )
    .unwrap();
    Ran { report, output }
}

/// `coarsen info --json` of `input` written as `name`: the topology object.
fn info_topology(input: &Mesh, name: &str) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    write_mesh(input, &path);
    let o = run_cli(EXE, &["info", "--json", path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: Value = serde_json::from_str(&stdout(&o)).unwrap();
    v["topology"].clone()
}

#[test]
fn a_single_triangle_runs_and_is_kept() {
    let tri = mesh(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2]]);
    let ran = run_ok(&tri, "tri.obj", "qem", &["--ratio", "0.5"]);
    assert_eq!(ran.counts(), (3, 1));
    // Asked for fewer vertices than a triangle has: kept, and the report says why.
    let ran = run_ok(&tri, "tri.obj", "qem", &["--vertices", "1"]);
    assert_eq!(ran.counts(), (3, 1));
    let w = ran.warnings();
    assert!(
        w.iter()
            .any(|w| w.starts_with("target (1 vertices) not reached")),
        "{w:?}"
    );
}

#[test]
fn a_bow_tie_vertex_is_reported_and_split_before_a_collapse_stage() {
    let bowtie = mesh(
        &[
            [0.0; 3],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, -1.0, 0.0],
        ],
        &[[0, 1, 2], [0, 3, 4]],
    );
    let t = info_topology(&bowtie, "bowtie.obj");
    assert_eq!(t["n_bowtie_vertices"], 1);
    assert_eq!(t["manifold"], false);
    for pipeline in ["qem", "svec"] {
        let ran = run_ok(&bowtie, "bowtie.obj", pipeline, &["--ratio", "0.5"]);
        // One vertex per face fan: two separate triangles, nothing to collapse.
        assert_eq!(ran.counts(), (6, 2), "{pipeline}");
        assert!(Topology::build(&ran.output).summary(&ran.output).manifold);
        let w = ran.warnings();
        assert!(
            w.iter().any(|w| w
                == "1 non-manifold vertices split into one vertex per face fan (1 copies added)"),
            "{pipeline}: {w:?}"
        );
    }
}

#[test]
fn an_edge_with_three_faces_is_reported_and_its_vertices_locked() {
    let fin = mesh(
        &[
            [0.0; 3],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
        ],
        &[[0, 1, 2], [1, 0, 3], [0, 1, 4]],
    );
    let t = info_topology(&fin, "fin.obj");
    assert_eq!(t["n_non_manifold_edges"], 1);
    assert_eq!(t["manifold"], false);
    let ran = run_ok(&fin, "fin.obj", "qem", &["--ratio", "0.5"]);
    assert_eq!(ran.counts(), (5, 3));
    let w = ran.warnings();
    assert!(
        w.iter()
            .any(|w| w.starts_with("2 non-manifold vertices") && w.contains("locked")),
        "{w:?}"
    );
}

#[test]
fn inconsistent_orientation_is_reported_and_the_run_keeps_it_valid() {
    let mut flipped = octahedron();
    flipped.faces[0].swap(1, 2); // one face against its three neighbours
    let t = info_topology(&flipped, "flip.obj");
    assert_eq!(t["consistently_oriented"], false);
    assert_eq!(t["n_flipped_edges"], 3);
    let ran = run_ok(&flipped, "flip.obj", "qem", &["--faces", "4"]);
    // Runs to a valid mesh (checked in `run_file_ok`), never below a tetrahedron.
    assert!(ran.output.n_faces() >= 4 && ran.output.n_faces() <= 8);
}

#[test]
fn duplicate_faces_are_dropped_and_counted() {
    let mut m = octahedron();
    m.faces.push(m.faces[0]);
    let [a, b, c] = m.faces[1];
    m.faces.push([b, c, a]); // the same face, rotated
    let ran = run_ok(&m, "dup.obj", "qem", &["--faces", "4"]);
    let notes = ran.notes();
    assert!(
        notes.contains(&"drop duplicate faces: 2".to_string()),
        "{notes:?}"
    );
    assert_eq!(ran.report["input_faces"], 8);
    assert_eq!(ran.counts(), (4, 4));
}

#[test]
fn isolated_vertices_are_dropped_and_counted() {
    let mut m = octahedron();
    m.positions.push(DVec3::splat(5.0));
    m.positions.push(DVec3::splat(6.0));
    let ran = run_ok(&m, "iso.obj", "qem", &["--faces", "4"]);
    let notes = ran.notes();
    assert!(
        notes.contains(&"drop unreferenced vertices: 2".to_string()),
        "{notes:?}"
    );
    assert_eq!(ran.report["input_vertices"], 6);
    assert_eq!(ran.counts(), (4, 4));
}

/// The octahedron as a soup: every face with three vertices of its own.
fn octahedron_soup() -> Mesh {
    let o = octahedron();
    let positions = o
        .faces
        .iter()
        .flat_map(|f| f.map(|v| o.positions[v as usize]))
        .collect();
    let faces = (0..o.n_faces() as u32)
        .map(|f| [3 * f, 3 * f + 1, 3 * f + 2])
        .collect();
    Mesh::new(positions, faces)
}

#[test]
fn a_triangle_soup_is_kept_as_it_is_unless_welded() {
    let soup = octahedron_soup();
    // Indexed formats keep the file's vertices: eight separate triangles, none of which
    // can lose an edge; the report says every collapse was refused.
    let ran = run_ok(&soup, "soup.obj", "qem", &["--ratio", "0.5"]);
    assert_eq!(ran.counts(), (24, 8));
    let w = ran.warnings();
    assert!(
        w.iter()
            .any(|w| w.contains("every remaining collapse is refused")),
        "{w:?}"
    );
    // `--weld` (always on for STL) joins the corners first.
    let ran = run_ok(&soup, "soup.obj", "qem", &["--ratio", "0.5", "--weld"]);
    assert!(
        ran.notes()
            .contains(&"weld coincident positions: 18 vertices merged".to_string()),
        "{:?}",
        ran.notes()
    );
    assert_eq!(ran.counts(), (4, 4));
    let ran = run_ok(&soup, "soup.stl", "qem", &["--ratio", "0.5"]);
    assert_eq!(ran.counts(), (4, 4));
}

#[test]
fn a_thousand_components_each_keep_their_topology() {
    let o = octahedron();
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    for c in 0..1000u32 {
        let shift = DVec3::new(
            f64::from(c % 10),
            f64::from(c / 10 % 10),
            f64::from(c / 100),
        ) * 3.0;
        let base = positions.len() as u32;
        positions.extend(o.positions.iter().map(|p| *p + shift));
        faces.extend(o.faces.iter().map(|f| f.map(|v| v + base)));
    }
    let many = Mesh::new(positions, faces);
    for pipeline in ["qem", "svec"] {
        let ran = run_ok(&many, "many.ply", pipeline, &["--ratio", "0.5"]);
        assert_eq!(ran.counts(), (4000, 4000), "{pipeline}");
        let s = oriented_manifold(&ran.output, pipeline);
        assert_eq!(s.n_components, 1000, "{pipeline}");
        assert_eq!(s.n_boundary_edges, 0, "{pipeline}");
        assert!(s.genus.iter().all(|g| *g == Some(0)), "{pipeline}");
    }
}

#[test]
fn a_target_larger_than_the_input_leaves_the_cleaned_input() {
    let m = octahedron();
    for extra in [["--faces", "1000"], ["--vertices", "1000"]] {
        let ran = run_ok(&m, "oct.off", "qem", &extra);
        assert_eq!(ran.counts(), (6, 8), "{extra:?}");
        assert_eq!(ran.output.faces.len(), m.faces.len());
    }
}

#[test]
fn targets_of_zero_to_three_vertices_stop_at_the_smallest_closed_mesh_and_say_so() {
    for pipeline in ["qem", "svec"] {
        for target in ["0", "1", "2", "3"] {
            let ran = run_ok(&octahedron(), "oct.ply", pipeline, &["--vertices", target]);
            // A tetrahedron is the smallest closed surface: no collapse goes below it.
            assert_eq!(ran.counts(), (4, 4), "{pipeline} {target}");
            let w = ran.warnings();
            assert!(
                w.iter().any(|w| w.starts_with(&format!(
                    "target ({target} vertices) not reached: stopped at 4 vertices and 4 faces"
                ))),
                "{pipeline} {target}: {w:?}"
            );
        }
    }
}

#[test]
fn a_two_gigabyte_sparse_file_is_refused_at_once_in_every_format() {
    let dir = tempfile::tempdir().unwrap();
    for ext in ["obj", "ply", "stl", "off"] {
        let input = dir.path().join(format!("huge.{ext}"));
        let file = std::fs::File::create(&input).unwrap();
        file.set_len(2 << 30).unwrap(); // 2 GiB of zeros, no disk blocks
        let out = dir.path().join("out.ply");
        let t = std::time::Instant::now();
        let o = run_pipeline(EXE, "qem", &input, &out, &["--ratio", "0.5"]);
        // Refused from its first bytes: far quicker than reading 2 GiB.
        assert!(t.elapsed().as_secs_f64() < 5.0, "{ext}: {:?}", t.elapsed());
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{ext}: {e}");
        assert!(e.contains(&format!("huge.{ext}: not a")), "{ext}: {e}");
        assert!(!out.exists());
    }
}

#[test]
fn max_faces_refuses_a_bigger_file_before_reading_it_and_names_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.ply");
    for ext in ["obj", "ply", "stl", "off"] {
        let input = dir.path().join(format!("oct.{ext}"));
        write_mesh(&octahedron(), &input);
        let o = run_cli(
            EXE,
            &[
                "--max-faces",
                "7",
                "run",
                "qem",
                input.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
                "--faces",
                "4",
            ],
        );
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{ext}: {e}");
        assert!(
            e.contains("more than 7 faces") && e.contains("--max-faces 7 is in force"),
            "{ext}: {e}"
        );
        assert!(!out.exists());
        // At the limit, it runs (the option goes after the command too).
        let o = run_pipeline(
            EXE,
            "qem",
            &input,
            &out,
            &["--max-faces", "8", "--faces", "4"],
        );
        assert!(o.status.success(), "{ext}: {}", stderr(&o));
        std::fs::remove_file(&out).unwrap();
    }
    // A file longer than 256 bytes a face (and 1 MiB) is refused by its length alone.
    let long = dir.path().join("long.obj");
    let mut text = octahedron_obj_text();
    text.push_str(&"# padding\n".repeat(120_000));
    std::fs::write(&long, text).unwrap();
    let o = run_cli(EXE, &["info", long.to_str().unwrap(), "--max-faces", "100"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("more than the limit of 1048576"), "{e}");
    let o = run_cli(EXE, &["info", long.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// The octahedron as OBJ text.
fn octahedron_obj_text() -> String {
    let mut bytes = Vec::new();
    coarsen_io::write_to(
        &octahedron(),
        coarsen_io::Format::Obj,
        &mut bytes,
        &Default::default(),
    )
    .unwrap();
    String::from_utf8(bytes).unwrap()
}

#[test]
fn the_input_is_never_overwritten_under_another_name() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("oct.ply");
    write_mesh(&octahedron(), &input);
    let before = std::fs::read(&input).unwrap();
    // The same file through `..`, and through a symbolic link.
    let sub = dir.path().join("sub");
    std::fs::create_dir(&sub).unwrap();
    let mut aliases = vec![sub.join("..").join("oct.ply")];
    #[cfg(unix)]
    {
        let link = dir.path().join("link.ply");
        std::os::unix::fs::symlink(&input, &link).unwrap();
        aliases.push(link);
    }
    for alias in &aliases {
        let o = run_pipeline(EXE, "qem", &input, alias, &["--faces", "4"]);
        assert_eq!(o.status.code(), Some(1), "{}", alias.display());
        assert!(
            stderr(&o).contains("refusing to overwrite the input"),
            "{}",
            stderr(&o)
        );
        let o = run_cli(
            EXE,
            &["convert", input.to_str().unwrap(), alias.to_str().unwrap()],
        );
        assert_eq!(o.status.code(), Some(1), "{}", alias.display());
        assert!(stderr(&o).contains("refusing to overwrite the input"));
        assert_eq!(std::fs::read(&input).unwrap(), before);
    }
}

/// A strip of `2·nb − 3` triangles, zigzag between a row of `nb` vertices and one of
/// `nb − 1` (issue #8: every face has a boundary edge).
fn zigzag_strip(nb: u32) -> Mesh {
    let mut positions = Vec::new();
    (0..nb).for_each(|i| positions.push(DVec3::new(f64::from(i), 0.0, 0.0)));
    (0..nb - 1).for_each(|i| positions.push(DVec3::new(f64::from(i) + 0.5, 1.0, 0.0)));
    let mut faces = Vec::new();
    for i in 0..nb - 1 {
        faces.push([i, i + 1, nb + i]);
        if i + 2 < nb {
            faces.push([i + 1, nb + i + 1, nb + i]);
        }
    }
    Mesh::new(positions, faces)
}

/// Issue #8: a 17-face strip through the CVT pipelines used to end in `dual`'s internal
/// "could not be repaired" (every compact cluster touches the boundary twice); the clusters
/// are now rebuilt from single faces, and every count gives a valid open strip.
#[test]
fn a_seventeen_face_strip_goes_through_the_cvt_pipelines_at_every_count() {
    let strip = zigzag_strip(10);
    assert_eq!(strip.n_faces(), 17);
    for pipeline in ["adaptive-cvt", "uniform-cvt"] {
        for n in [3, 5, 10, 17, 20] {
            let what = format!("{pipeline} --vertices {n}");
            let n_arg = n.to_string();
            let ran = run_ok(&strip, "strip.obj", pipeline, &["--vertices", &n_arg]);
            assert_eq!(ran.output.n_vertices(), n, "{what}");
            let t = Topology::build(&ran.output).summary(&ran.output);
            assert!(t.manifold, "{what}");
            assert_eq!((t.n_components, t.n_boundary_loops), (1, 1), "{what}");
            assert_eq!(t.genus_total, Some(0), "{what}");
        }
    }
    let ran = run_ok(&strip, "strip.obj", "adaptive-cvt", &["--vertices", "20"]);
    assert!(
        ran.warnings()
            .iter()
            .any(|w| w.contains("rebuilt from single faces")),
        "{:?}",
        ran.warnings()
    );
}

/// An annulus one face wide (48 faces): every two faces sharing an edge touch both
/// boundary loops, so only one vertex per face makes a valid dual; another count is a
/// parameter error naming the count that works, exit 1, no output.
#[test]
fn an_annulus_one_face_wide_refuses_other_counts_than_one_per_face() {
    let k = 24u32;
    let mut positions = Vec::new();
    for r in 0..2u32 {
        for i in 0..k {
            let a = (f64::from(i) + 0.5 * f64::from(r)) / f64::from(k) * std::f64::consts::TAU;
            let rad = 2.0 - 0.2 * f64::from(r);
            positions.push(DVec3::new(rad * a.cos(), rad * a.sin(), 0.0));
        }
    }
    let v = |r: u32, i: u32| r * k + i % k;
    let faces = (0..k)
        .flat_map(|i| {
            [
                [v(0, i), v(0, i + 1), v(1, i)],
                [v(0, i + 1), v(1, i + 1), v(1, i)],
            ]
        })
        .collect();
    let annulus = Mesh::new(positions, faces);
    // Clustering and dual only: the shipped pipelines subdivide or refine first.
    let dir = tempfile::tempdir().unwrap();
    let pipeline = dir.path().join("cvt-dual.toml");
    std::fs::write(
        &pipeline,
        "[pipeline]\nname = \"cvt-dual\"\ndescription = \"cluster, dual\"\n\
         [[stage]]\nkind = \"cluster.cvt\"\n[[stage]]\nkind = \"dual\"\n",
    )
    .unwrap();
    let pipeline = pipeline.to_str().unwrap();
    let ran = run_ok(&annulus, "annulus.obj", pipeline, &["--vertices", "48"]);
    assert_eq!(ran.output.n_vertices(), 48);
    let (input, out) = (dir.path().join("annulus.obj"), dir.path().join("out.ply"));
    write_mesh(&annulus, &input);
    let o = run_pipeline(EXE, pipeline, &input, &out, &["--vertices", "20"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("parameter `target`"), "{e}");
    assert!(e.contains("only 48 (one per face) works"), "{e}");
    assert!(!e.contains("internal error"), "{e}");
    assert!(!out.exists());
    // Bent by a wave, through adaptive-cvt (refined first, so 20 vertices exist): its
    // post-process once ended in "lies on a degenerate triangle" (clusters whose
    // centroids were in a row); a flat triangle's vertex now moves inside its cluster.
    let mut bent = annulus.clone();
    bent.positions
        .iter_mut()
        .for_each(|p| p.z = 0.3 * (3.0 * p.y.atan2(p.x)).sin());
    let ran = run_ok(&bent, "bent.obj", "adaptive-cvt", &["--vertices", "20"]);
    assert_eq!(ran.output.n_vertices(), 20);
    let t = Topology::build(&ran.output).summary(&ran.output);
    assert!(t.manifold);
    assert_eq!(t.n_boundary_loops, 2);
}

#[test]
fn a_fin_on_an_edge_is_cut_off_before_the_cvt_pipelines() {
    // An icosphere with a fin (a fan of triangles standing out) on one of its edges: that
    // edge has three faces. A collapse stage keeps them joined; the dual cannot, so the
    // fin is cut off the sphere first, and both come out valid.
    let mut finned = coarsen_shapes::icosphere(1.0, 3).unwrap();
    let [a, b, _] = finned.faces[0];
    let (pa, pb) = (finned.positions[a as usize], finned.positions[b as usize]);
    let tip = (pa + pb) * 0.75;
    let n = finned.positions.len() as u32;
    finned
        .positions
        .extend([tip, (pa + tip) * 0.5, (pb + tip) * 0.5]);
    finned
        .faces
        .extend([[a, b, n + 2], [a, n + 2, n + 1], [n + 1, n + 2, n]]);
    let t = info_topology(&finned, "fin.obj");
    assert_eq!(t["n_non_manifold_edges"], 1);
    for pipeline in ["uniform-cvt", "adaptive-cvt"] {
        let ran = run_ok(&finned, "fin.obj", pipeline, &["--vertices", "120"]);
        let s = oriented_manifold(&ran.output, pipeline);
        assert_eq!(ran.output.n_vertices(), 120, "{pipeline}");
        // The sphere and the fin, a disc.
        assert_eq!((s.n_components, s.n_boundary_loops), (2, 1), "{pipeline}");
        let w = ran.warnings();
        assert!(
            // The uniform pipeline subdivides first: two edges then.
            w.iter()
                .any(|w| w.contains("edges of three or more faces cut apart")),
            "{pipeline}: {w:?}"
        );
    }
}

#[test]
fn a_lone_triangle_beside_a_surface_is_split_before_the_cvt_pipelines() {
    // A piece whose boundary runs along fewer than three faces has no dual; split 1-to-4
    // first, it has (three faces along its loop).
    let mut input = coarsen_shapes::icosphere(1.0, 3).unwrap();
    let n = input.positions.len() as u32;
    input.positions.extend([
        DVec3::new(2.0, 0.0, 0.0),
        DVec3::new(2.5, 0.0, 0.0),
        DVec3::new(2.0, 0.5, 0.0),
    ]);
    input.faces.push([n, n + 1, n + 2]);
    for pipeline in ["adaptive-cvt", "uniform-cvt"] {
        let ran = run_ok(&input, "lone.obj", pipeline, &["--vertices", "120"]);
        let s = oriented_manifold(&ran.output, pipeline);
        assert_eq!(ran.output.n_vertices(), 120, "{pipeline}");
        assert_eq!((s.n_components, s.n_boundary_loops), (2, 1), "{pipeline}");
        let w = ran.warnings();
        assert!(
            w.iter().any(|w| w.starts_with(
                "1 faces split 1-to-4 in pieces whose boundary runs along fewer than three faces"
            )),
            "{pipeline}: {w:?}"
        );
    }
}
