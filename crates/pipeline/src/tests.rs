//! Tests of parsing, checking and running, with two small stages defined here.

use crate::{Overrides, Pipeline, RunOptions, parse_set};
use coarsen_mesh::{AttrKind, AttrValues, DVec3, Mesh};
use coarsen_stage::{
    AttrRef, Context, Contract, Needs, ParamIssue, Params, Registry, Stage, StageError, Target,
    params,
};

params! {
    /// Parameters of `test.mark`.
    pub struct MarkParams {
        /// Name of the vertex scalar written.
        pub name: String = "height".to_string(),
        /// Scale applied to the z coordinate.
        pub scale: f64 = 1.0,
    }
}
impl Params for MarkParams {
    fn validate(&self) -> Vec<ParamIssue> {
        let mut v = Vec::new();
        coarsen_stage::params::check_range(&mut v, "scale", self.scale, 0.0, 10.0);
        v
    }
}
/// Writes a vertex scalar: scaled z.
struct Mark(MarkParams);
impl Stage for Mark {
    type Params = MarkParams;
    const KIND: &'static str = "test.mark";
    const SUMMARY: &'static str = "Writes scaled z as a vertex scalar.";
    fn new(p: MarkParams) -> Self {
        Mark(p)
    }
    fn contract(&self) -> Contract {
        Contract {
            writes: vec![AttrRef::vertex(self.0.name.clone(), AttrKind::Scalar)],
            carries_wedges: true,
            ..Default::default()
        }
    }
    fn run(&self, mut mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        let v = mesh.positions.iter().map(|p| p.z * self.0.scale).collect();
        mesh.vertex_attrs
            .insert(self.0.name.clone(), AttrValues::Scalar(v));
        cx.report.figure("marked", mesh.n_vertices());
        cx.report
            .figure("marked edges", cx.original.marked_edges.len());
        Ok(mesh)
    }
}

params! {
    /// Parameters of `test.drop-high`.
    pub struct DropParams {
        /// The vertex scalar read.
        pub field: String = "height".to_string(),
    }
}
impl Params for DropParams {}
/// Drops faces whose vertices' scalars sum above zero; needs a target (unused).
struct DropHigh(DropParams);
impl Stage for DropHigh {
    type Params = DropParams;
    const KIND: &'static str = "test.drop-high";
    const SUMMARY: &'static str = "Drops faces above zero.";
    const RECORDS_COLLAPSES: bool = true;
    fn new(p: DropParams) -> Self {
        DropHigh(p)
    }
    fn contract(&self) -> Contract {
        Contract {
            reads: vec![AttrRef::vertex(self.0.field.clone(), AttrKind::Scalar)],
            needs: Needs {
                target: true,
                split_fans: true,
                ..Default::default()
            },
            ..Default::default()
        }
    }
    fn run(&self, mut mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        cx.require_target(Self::KIND)?;
        let h = mesh
            .vertex_attrs
            .scalar(&self.0.field)
            .ok_or_else(|| StageError::Internal("attribute missing".into()))?
            .to_vec();
        let before = mesh.n_faces();
        mesh.faces
            .retain(|f| f.iter().map(|&v| h[v as usize]).sum::<f64>() <= 0.0);
        // Its "record": how many faces went.
        if let Some(slot) = cx.progressive.as_mut() {
            **slot = Some(Box::new(before - mesh.n_faces()));
        }
        if mesh.faces.is_empty() {
            return Err(StageError::Input("every face was dropped".into()));
        }
        Ok(mesh)
    }
}

params! {
    /// Parameters of `test.manifold`.
    pub struct ManifoldParams {}
}
impl Params for ManifoldParams {}
/// Needs a manifold mesh; passes it through.
struct NeedsManifold;
impl Stage for NeedsManifold {
    type Params = ManifoldParams;
    const KIND: &'static str = "test.manifold";
    const SUMMARY: &'static str = "Needs a manifold mesh.";
    fn new(_: ManifoldParams) -> Self {
        NeedsManifold
    }
    fn contract(&self) -> Contract {
        Contract {
            needs: Needs {
                manifold: true,
                ..Default::default()
            },
            ..Default::default()
        }
    }
    fn run(&self, mesh: Mesh, _: &mut Context<'_>) -> Result<Mesh, StageError> {
        Ok(mesh)
    }
}

params! {
    /// Parameters of `test.trouble`.
    pub struct TroubleParams {
        /// `panic`, or `cancel` (raises [`CANCEL`], then reports progress).
        pub what: String = "panic".to_string(),
    }
}
impl Params for TroubleParams {}

/// The cancel flag of the one test that cancels from inside a stage.
static CANCEL: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Panics, or cancels the run from inside and goes on reporting progress.
struct Trouble(TroubleParams);
impl Stage for Trouble {
    type Params = TroubleParams;
    const KIND: &'static str = "test.trouble";
    const SUMMARY: &'static str = "Panics or cancels.";
    fn new(p: TroubleParams) -> Self {
        Trouble(p)
    }
    fn contract(&self) -> Contract {
        Contract::default()
    }
    fn run(&self, mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        if self.0.what == "cancel" {
            CANCEL.store(true, std::sync::atomic::Ordering::Relaxed);
            cx.progress.begin("spinning", 10);
            cx.progress.advance(1, "");
            return Err(StageError::Internal("went on after the cancel".into()));
        }
        let faces: Vec<usize> = Vec::new();
        Ok(Mesh::new(
            mesh.positions.clone(),
            vec![[0, 1, faces[7] as u32]],
        ))
    }
}

mod mark {
    coarsen_stage::export_stage!(super::Mark);
}
mod trouble {
    coarsen_stage::export_stage!(super::Trouble);
}
mod needs_manifold {
    coarsen_stage::export_stage!(super::NeedsManifold);
}
mod drop_high {
    coarsen_stage::export_stage!(super::DropHigh);
}

fn registry() -> Registry {
    Registry::from_descriptors([
        mark::descriptor(),
        drop_high::descriptor(),
        needs_manifold::descriptor(),
        trouble::descriptor(),
    ])
}

fn parse(text: &str, overrides: &Overrides) -> Result<Pipeline, Vec<String>> {
    Pipeline::parse(text, "p.toml", &registry(), overrides)
        .map_err(|d| d.0.into_iter().map(|d| d.to_string()).collect())
}

fn square() -> Mesh {
    // 3---2
    // | / |      z = −1 at 0 and 1, +1 at 2 and 3
    // 0---1
    Mesh::new(
        vec![
            DVec3::new(0.0, 0.0, -1.0),
            DVec3::new(1.0, 0.0, -1.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(0.0, 1.0, 1.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
}

const GOOD: &str = r#"
[pipeline]
name = "demo"
description = "mark then drop"
target = { vertices = 10 }

[[stage]]
kind = "test.mark"
scale = 2.0

[[stage]]
kind = "test.drop-high"
"#;

#[test]
fn a_good_file_parses_and_runs_with_a_report() {
    let p = parse(GOOD, &Overrides::default()).unwrap();
    assert_eq!(p.name, "demo");
    assert_eq!(p.target, Some(Target::Vertices(10)));
    assert_eq!(p.stages.len(), 2);
    let (out, report) = p.run(square(), RunOptions::default()).unwrap();
    assert_eq!(out.n_faces(), 1);
    assert_eq!(report.stages[0].figures["marked"], 4);
    assert_eq!(report.stages[0].params["scale"], 2.0);
    assert_eq!(
        (report.stages[1].faces_before, report.stages[1].faces_after),
        (2, 1)
    );
    assert_eq!(report.output_faces, 1);
    assert!(report.to_json().contains("\"kind\": \"test.drop-high\""));
    // The runner's own time before each stage is in the report.
    assert!(report.to_json().contains("\"ready_seconds\": "));
}

#[test]
fn every_problem_is_reported_at_once_with_its_line() {
    let text = r#"[pipeline]
name = "bad"

[[stage]]
kind = "test.mrak"

[[stage]]
kind = "test.mark"
scael = 2.0
scale = "big"

[[stage]]
kind = "test.mark"
scale = 20.0
"#;
    let errs = parse(text, &Overrides::default()).unwrap_err();
    assert_eq!(errs.len(), 4, "{errs:#?}");
    assert!(
        errs[0]
            .starts_with("p.toml:5:8: unknown stage kind `test.mrak` (did you mean `test.mark`?)"),
        "{}",
        errs[0]
    );
    assert!(
        errs[1].starts_with(
            "p.toml:9:1: test.mark: `test.mark` has no parameter `scael` (did you mean `scale`?)"
        ),
        "{}",
        errs[1]
    );
    assert!(
        errs[2].starts_with("p.toml:10:1: test.mark: scale: invalid type"),
        "{}",
        errs[2]
    );
    assert_eq!(
        errs[3],
        "p.toml:14:1: test.mark: scale: must be in 0..=10, got 20"
    );
}

#[test]
fn an_unknown_kind_like_no_known_one_says_how_plugins_are_linked_at_its_line() {
    let text = "[pipeline]\nname = \"p\"\n\n[[stage]]\nkind = \"smooth.taubin\"\n";
    let errs = parse(text, &Overrides::default()).unwrap_err();
    assert_eq!(errs.len(), 1, "{errs:#?}");
    assert!(
        errs[0].starts_with("p.toml:5:8: unknown stage kind `smooth.taubin`; known kinds: "),
        "{}",
        errs[0]
    );
    assert!(
        errs[0].ends_with(
            "linked into the binary and named there (`use my_stage as _;`): see docs/writing-a-stage.md"
        ),
        "{}",
        errs[0]
    );
}

/// A kind registered by two packages fails the pipelines that use it, and only those.
#[test]
fn a_kind_registered_twice_fails_only_the_pipelines_that_use_it() {
    let mut registry = registry();
    let mut rogue = mark::descriptor();
    rogue.crate_name = "rogue-mark";
    registry.add(rogue);
    assert_eq!(registry.conflicts().len(), 1);
    let unaffected = "[pipeline]\ntarget = { faces = 1 }\ninputs = [{ domain = \"vertex\", name = \"height\", kind = \"scalar\" }]\n[[stage]]\nkind = \"test.drop-high\"\n";
    let p = Pipeline::parse(unaffected, "ok.toml", &registry, &Overrides::default()).unwrap();
    assert_eq!(p.stages[0].kind, "test.drop-high");
    let errs = Pipeline::parse(GOOD, "p.toml", &registry, &Overrides::default())
        .unwrap_err()
        .0;
    assert_eq!(errs.len(), 1, "{errs:#?}");
    assert_eq!(
        errs[0].to_string(),
        "p.toml:8:8: stage kind `test.mark` is registered twice: by `coarsen-pipeline` and by \
         `rogue-mark`; link only one of them into this binary"
    );
}

#[test]
fn reading_an_attribute_nothing_writes_is_an_error_before_running() {
    let text = "[pipeline]\ntarget = { faces = 1 }\n[[stage]]\nkind = \"test.mark\"\nname = \"z\"\n[[stage]]\nkind = \"test.drop-high\"\n";
    let errs = parse(text, &Overrides::default()).unwrap_err();
    assert_eq!(errs.len(), 1);
    assert!(
        errs[0].contains(
            "stage 2 `test.drop-high` reads vertex scalar `height`, which no earlier stage writes"
        ),
        "{}",
        errs[0]
    );
    assert!(errs[0].starts_with("p.toml:6:"), "{}", errs[0]);
}

#[test]
fn declared_inputs_satisfy_reads_and_kinds_must_match() {
    let ok = "[pipeline]\ntarget = { faces = 1 }\ninputs = [{ domain = \"vertex\", name = \"height\", kind = \"scalar\" }]\n[[stage]]\nkind = \"test.drop-high\"\n";
    assert!(parse(ok, &Overrides::default()).is_ok());
    let bad = ok.replace("\"scalar\"", "\"label\"");
    let errs = parse(&bad, &Overrides::default()).unwrap_err();
    assert!(errs[0].contains("provides it as label"), "{}", errs[0]);
}

#[test]
fn a_missing_target_is_reported_and_the_command_line_supplies_it() {
    let text = GOOD.replace("target = { vertices = 10 }\n", "");
    let errs = parse(&text, &Overrides::default()).unwrap_err();
    assert!(errs[0].contains("needs a target"), "{}", errs[0]);
    let o = Overrides {
        target: Some(Target::Ratio(0.5)),
        ..Default::default()
    };
    assert_eq!(parse(&text, &o).unwrap().target, Some(Target::Ratio(0.5)));
    let o = Overrides {
        target: Some(Target::Ratio(1.5)),
        ..Default::default()
    };
    assert!(parse(&text, &o).unwrap_err()[0].starts_with("command line: ratio"));
}

#[test]
fn set_overrides_apply_by_kind_or_id_and_are_checked_like_the_file() {
    let o = Overrides {
        sets: vec![parse_set("test.mark.scale=3").unwrap()],
        ..Default::default()
    };
    let p = parse(GOOD, &o).unwrap();
    assert_eq!(
        p.stages[0].stage.params()["scale"],
        toml::Value::Integer(3)
            .try_into::<f64>()
            .map(toml::Value::Float)
            .unwrap()
    );
    let o = Overrides {
        sets: vec![parse_set("test.mark.scale=99").unwrap()],
        ..Default::default()
    };
    let errs = parse(GOOD, &o).unwrap_err();
    assert!(
        errs[0] == "--set test.mark.scale=99: test.mark: must be in 0..=10, got 99",
        "{}",
        errs[0]
    );
    let o = Overrides {
        sets: vec![parse_set("nope.scale=1").unwrap()],
        ..Default::default()
    };
    assert!(
        parse(GOOD, &o).unwrap_err()[0]
            .contains("no stage of this pipeline has the id or kind `nope`")
    );
    // An id selects one stage even when another has the same kind.
    let text = format!("{GOOD}\n[[stage]]\nkind = \"test.mark\"\nid = \"second\"\n");
    let o = Overrides {
        sets: vec![parse_set("second.scale=5").unwrap()],
        ..Default::default()
    };
    let p = parse(&text, &o).unwrap();
    assert_eq!(p.stages[0].stage.params()["scale"], toml::Value::Float(2.0));
    assert_eq!(p.stages[2].stage.params()["scale"], toml::Value::Float(5.0));
    assert_eq!(
        parse_set("cluster.cvt.energy=shu2009").unwrap().value,
        toml::Value::String("shu2009".into())
    );
    assert!(parse_set("noequals").is_err());
}

#[test]
fn syntax_errors_and_empty_pipelines_are_located() {
    let errs = parse(
        "[[stage]]\nkind = \"test.mark\"\nscale = [1,\n",
        &Overrides::default(),
    )
    .unwrap_err();
    assert!(errs[0].starts_with("p.toml:3:"), "{}", errs[0]);
    let errs = parse(
        "[pipeline]\nname = \"x\"\nbogus = 1\n",
        &Overrides::default(),
    )
    .unwrap_err();
    assert!(errs[0].contains("bogus"), "{}", errs[0]);
    let errs = parse("[pipeline]\nname = \"x\"\n", &Overrides::default()).unwrap_err();
    assert!(errs[0].contains("no [[stage]]"), "{}", errs[0]);
}

#[test]
fn a_failing_stage_names_itself() {
    let mut m = square();
    m.positions.iter_mut().for_each(|p| p.z = 1.0);
    let p = parse(GOOD, &Overrides::default()).unwrap();
    let e = p.run(m, RunOptions::default()).unwrap_err().to_string();
    assert_eq!(e, "stage 2 `test.drop-high` failed: every face was dropped");
}

#[test]
fn the_last_recording_stage_hands_its_record_back_when_asked() {
    let p = parse(GOOD, &Overrides::default()).unwrap();
    assert_eq!(p.recording_stage(), Some((1, "test.drop-high")));
    let slot = std::sync::Mutex::new(None);
    let opts = RunOptions {
        progressive: Some(&slot),
        ..Default::default()
    };
    p.run(square(), opts).unwrap();
    let record = slot.into_inner().unwrap().expect("handed back");
    assert_eq!(record.downcast::<usize>().ok().map(|b| *b), Some(1));
    let marks_only = parse(
        "[pipeline]\nname = \"m\"\ndescription = \"m\"\n[[stage]]\nkind = \"test.mark\"\n",
        &Overrides::default(),
    )
    .unwrap();
    assert_eq!(marks_only.recording_stage(), None);
}

/// Two triangles sharing only vertex 0 (a bow-tie), below z = 0 so nothing is dropped.
fn bow_tie() -> Mesh {
    let p = |x: f64, y: f64| DVec3::new(x, y, -1.0);
    Mesh::new(
        vec![
            p(0.0, 0.0),
            p(1.0, 0.0),
            p(1.0, 1.0),
            p(-1.0, 0.0),
            p(-1.0, -1.0),
        ],
        vec![[0, 1, 2], [0, 3, 4]],
    )
}

#[test]
fn a_collapse_stage_gets_non_manifold_vertices_split_and_says_so() {
    let p = parse(GOOD, &Overrides::default()).unwrap();
    let (out, report) = p.run(bow_tie(), RunOptions::default()).unwrap();
    assert_eq!(out.n_vertices(), 6, "the bow-tie vertex split in two");
    assert!(coarsen_mesh::Topology::build(&out).summary(&out).manifold);
    assert!(
        report.stages[0].warnings.is_empty(),
        "test.mark is no collapse stage"
    );
    assert_eq!(
        report.stages[1].warnings,
        ["1 non-manifold vertices split into one vertex per face fan (1 copies added)"]
    );
    // The copy carries the attribute the collapse stage reads.
    let h = out.vertex_attrs.scalar("height").unwrap();
    assert_eq!(h[5], h[0]);
}

#[test]
fn a_collapse_stage_takes_edges_of_three_faces_as_they_are() {
    // Three triangles on edge 0-1, and a bow-tie at vertex 0: no split, no refusal.
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z - 2.0);
    let mesh = Mesh::new(
        vec![
            p(0.0, 0.0, 0.0),
            p(1.0, 0.0, 0.0),
            p(0.5, 1.0, 0.0),
            p(0.5, -1.0, 0.0),
            p(0.5, 0.0, 1.0),
            p(-1.0, 0.0, 0.0),
            p(-1.0, -1.0, 0.0),
        ],
        vec![[0, 1, 2], [1, 0, 3], [0, 1, 4], [0, 5, 6]],
    );
    let pl = parse(GOOD, &Overrides::default()).unwrap();
    let (out, report) = pl.run(mesh.clone(), RunOptions::default()).unwrap();
    assert_eq!(out.n_vertices(), mesh.n_vertices());
    assert!(report.stages[1].warnings.is_empty());
}

/// A flat grid of 3 × 2 quads with a fin (a triangle standing up) on the edge between
/// its two interior vertices, 5 and 6: that edge has three faces.
fn finned_grid() -> Mesh {
    let mut positions: Vec<DVec3> = (0..12)
        .map(|i| DVec3::new((i % 4) as f64, (i / 4) as f64, 0.0))
        .collect();
    positions.push(DVec3::new(1.5, 1.0, 1.0));
    let mut faces = Vec::new();
    for y in 0..2 {
        for x in 0..3 {
            let a = y * 4 + x;
            faces.push([a, a + 1, a + 5]);
            faces.push([a, a + 5, a + 4]);
        }
    }
    faces.push([5, 6, 12]);
    Mesh::new(positions, faces)
}

#[test]
fn a_stage_that_needs_a_manifold_mesh_gets_edges_of_three_faces_cut_apart() {
    let mesh = finned_grid();
    let p = parse(
        "[[stage]]\nkind = \"test.manifold\"\n",
        &Overrides::default(),
    )
    .unwrap();
    let (out, report) = p.run(mesh.clone(), RunOptions::default()).unwrap();
    let s = coarsen_mesh::Topology::build(&out).summary(&out);
    assert!(s.manifold && s.consistently_oriented, "{s:?}");
    // The grid stays whole; the fin comes off it with its own copies of 5 and 6, and,
    // a lone triangle then (too small for a dual), is split 1-to-4.
    assert_eq!(out.n_vertices(), mesh.n_vertices() + 2 + 3);
    assert_eq!(out.n_faces(), mesh.n_faces() + 3);
    assert_eq!(out.faces[..12], mesh.faces[..12]);
    assert_eq!((s.n_components, s.n_boundary_loops), (2, 2));
    assert_eq!(
        report.stages[0].warnings,
        [
            "1 edges of three or more faces cut apart, 2 non-manifold vertices split into one vertex per face fan (2 copies added)",
            "1 faces split 1-to-4 in pieces whose boundary runs along fewer than three faces (a dual needs three)"
        ]
    );
    // That work is the runner's, on record apart from the stage's own time.
    assert!(report.stages[0].ready_seconds > 0.0);
    // A collapse stage gets the same mesh as it is.
    let (_, report) = parse(GOOD, &Overrides::default())
        .unwrap()
        .run(mesh, RunOptions::default())
        .unwrap();
    assert!(report.stages[1].warnings.is_empty());
}

/// A grid of `n × n` quads (two triangles each) at z = −1, vertices and faces listed
/// backwards (far from curve order).
fn backwards_grid(n: u32) -> Mesh {
    let nv = (n + 1) * (n + 1);
    let at = |x: u32, y: u32| nv - 1 - (y * (n + 1) + x);
    let mut positions = vec![DVec3::ZERO; nv as usize];
    for y in 0..=n {
        for x in 0..=n {
            positions[at(x, y) as usize] = DVec3::new(x as f64, y as f64, -1.0);
        }
    }
    let mut faces = Vec::new();
    for y in 0..n {
        for x in 0..n {
            faces.push([at(x, y), at(x + 1, y), at(x + 1, y + 1)]);
            faces.push([at(x, y), at(x + 1, y + 1), at(x, y + 1)]);
        }
    }
    faces.reverse();
    Mesh::new(positions, faces)
}

#[test]
fn large_inputs_are_renumbered_along_the_curve_unless_a_record_is_kept() {
    let marks_only = parse(
        "[pipeline]\nname = \"m\"\ndescription = \"m\"\n[[stage]]\nkind = \"test.mark\"\n",
        &Overrides::default(),
    )
    .unwrap();
    let input = backwards_grid(12);
    let ordered = coarsen_mesh::order::along_curve(input.clone());
    assert_ne!(ordered.faces, input.faces);
    let run = |reorder_min_faces: usize, record: bool| {
        let slot = std::sync::Mutex::new(None);
        let opts = RunOptions {
            reorder_min_faces,
            progressive: record.then_some(&slot),
            ..Default::default()
        };
        marks_only.run(input.clone(), opts).unwrap().0
    };
    // Large (at or above the bar): the stages see the renumbered mesh.
    let out = run(input.n_faces(), false);
    assert_eq!(
        (&out.positions, &out.faces),
        (&ordered.positions, &ordered.faces)
    );
    // Below the bar, or with a progressive record asked for: the input's numbering.
    for out in [run(input.n_faces() + 1, false), run(0, true)] {
        assert_eq!(
            (&out.positions, &out.faces),
            (&input.positions, &input.faces)
        );
    }
    // The marked edges go along with the renumbering, on the original only.
    let mut marked = input.clone();
    marked.marked_edges = vec![[0, 1], [1, 2]];
    let opts = RunOptions {
        reorder_min_faces: 0,
        ..Default::default()
    };
    let (out, report) = marks_only.run(marked, opts).unwrap();
    assert_eq!(report.stages[0].figures["marked edges"], 2);
    assert!(out.marked_edges.is_empty());
    // Small meshes by default.
    assert_eq!(
        marks_only
            .run(input.clone(), RunOptions::default())
            .unwrap()
            .0
            .faces,
        input.faces
    );
}

#[test]
fn a_panicking_stage_is_reported_as_an_internal_error_of_that_stage() {
    let text = "[pipeline]\nname = \"t\"\ndescription = \"t\"\n[[stage]]\nkind = \"test.mark\"\n[[stage]]\nkind = \"test.trouble\"\n";
    let p = parse(text, &Overrides::default()).unwrap();
    let e = p.run(square(), RunOptions::default()).unwrap_err();
    assert!(
        matches!(e, crate::RunError::Panicked { index: 2, .. }),
        "{e:?}"
    );
    let e = e.to_string();
    assert!(
        e.starts_with("stage 2 `test.trouble` failed with an internal error (a bug in coarsen"),
        "{e}"
    );
    assert!(e.contains("index out of bounds"), "{e}");
}

#[test]
fn a_cancelled_run_stops_inside_the_stage_or_before_the_next() {
    let text = "[pipeline]\nname = \"t\"\ndescription = \"t\"\n[[stage]]\nkind = \"test.trouble\"\nwhat = \"cancel\"\n[[stage]]\nkind = \"test.mark\"\n";
    let p = parse(text, &Overrides::default()).unwrap();
    let opts = RunOptions {
        cancel: Some(&CANCEL),
        ..Default::default()
    };
    // Inside: the stage raises the flag, and its next progress report ends it.
    let e = p.run(square(), opts).unwrap_err();
    assert!(
        matches!(
            e,
            crate::RunError::Cancelled {
                index: 1,
                kind: "test.trouble"
            }
        ),
        "{e:?}"
    );
    assert_eq!(e.to_string(), "cancelled during stage 1 `test.trouble`");
    // Before: with the flag up, not even the first stage starts.
    let marks = parse(
        "[pipeline]\nname = \"m\"\ndescription = \"m\"\n[[stage]]\nkind = \"test.mark\"\n",
        &Overrides::default(),
    )
    .unwrap();
    let e = marks.run(square(), opts).unwrap_err();
    assert!(
        matches!(e, crate::RunError::Cancelled { index: 1, .. }),
        "{e:?}"
    );
    // Without the flag the same pipeline runs.
    assert!(marks.run(square(), RunOptions::default()).is_ok());
}

#[test]
fn per_corner_columns_become_vertex_columns_stay_or_are_said_to_be_dropped() {
    use coarsen_mesh::{Attributes, DVec2};
    let mut cols = Attributes::default();
    // Vertex 0 takes two UVs (a seam); every corner the same normal.
    let uv = [0.0, 1.0, 2.0, 3.0, 2.0, 4.0].map(|u| DVec2::new(u, 0.0));
    cols.insert("uv", AttrValues::Vec2(uv.to_vec()));
    cols.insert("normal", AttrValues::Vec3(vec![DVec3::Z; 6]));
    let mesh = square().with_corner_attributes(cols);
    assert_eq!(mesh.wedges.split_vertices(), 1);
    let p = parse(GOOD, &Overrides::default()).unwrap();
    let (out, report) = p.run(mesh.clone(), RunOptions::default()).unwrap();
    assert!(out.wedges.is_empty());
    assert!(out.vertex_attrs.vec3("normal").is_some());
    assert_eq!(
        report.notes,
        [
            "per-corner `uv` (1 vertices on seams or hard edges) not carried: stage \
          `test.drop-high` of pipeline `demo` cannot carry per-corner attributes yet, so the \
          output has none"
        ]
    );
    assert!(report.summary().contains("note: per-corner `uv`"));
    // Through stages that all carry them, they stay, and nothing is said.
    let keeps = parse("[[stage]]\nkind = \"test.mark\"\n", &Overrides::default()).unwrap();
    let (out, report) = keeps.run(mesh.clone(), RunOptions::default()).unwrap();
    assert_eq!(out.wedges, mesh.wedges);
    assert!(report.notes.is_empty());
    // Without wedges, nothing is said and the JSON has no `notes`.
    let (_, report) = p.run(square(), RunOptions::default()).unwrap();
    assert!(report.notes.is_empty() && !report.to_json().contains("\"notes\""));
}
