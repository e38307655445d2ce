//! Every shipped pipeline checks against the built-in registry and runs on a procedural mesh.

use coarsen_pipeline::{Overrides, Pipeline, RunOptions};
use coarsen_stage::Target;

#[test]
fn every_shipped_pipeline_checks_and_runs_on_a_sphere() {
    let registry = coarsen_builtin::registry();
    let overrides = Overrides {
        target: Some(Target::Vertices(200)),
        ..Default::default()
    };
    for (name, text) in coarsen_builtin::PIPELINES {
        let p = Pipeline::parse(text, name, &registry, &overrides)
            .unwrap_or_else(|d| panic!("{name}:\n{d}"));
        let sphere = coarsen_shapes::uv_sphere(1.0, 24, 48).unwrap();
        let (out, report) = p
            .run(
                sphere,
                RunOptions {
                    sanity: true,
                    ..Default::default()
                },
            )
            .unwrap();
        assert!(out.n_faces() > 0, "{name}");
        assert_eq!(report.stages.len(), p.stages.len(), "{name}");
    }
}

#[test]
fn shipped_pipelines_are_the_files_in_pipelines() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../pipelines");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    files.sort();
    let mut shipped: Vec<String> = coarsen_builtin::PIPELINES
        .iter()
        .map(|(n, _)| n.to_string())
        .collect();
    shipped.sort();
    assert_eq!(
        files, shipped,
        "every pipelines/*.toml is shipped in the binary, and only those"
    );
}

#[test]
fn every_stage_example_toml_round_trips_to_its_defaults() {
    let registry = coarsen_builtin::registry();
    for d in registry.iter() {
        // Declare whatever the stage reads with its defaults, so the example stands alone.
        let inputs: Vec<String> = (d.default_contract)()
            .reads
            .iter()
            .map(|a| {
                format!(
                    "{{ domain = \"{}\", name = \"{}\", kind = \"{}\" }}",
                    a.domain, a.name, a.kind
                )
            })
            .collect();
        let text = format!(
            "[pipeline]\ntarget = {{ vertices = 10 }}\ninputs = [{}]\n\n{}",
            inputs.join(", "),
            d.example_toml()
        );
        let p = Pipeline::parse(&text, "example.toml", &registry, &Overrides::default())
            .unwrap_or_else(|e| panic!("{}: example does not parse:\n{text}\n{e}", d.kind));
        assert_eq!(p.stages[0].kind, d.kind);
        assert_eq!(p.stages[0].stage.params(), (d.defaults)(), "{}", d.kind);
    }
}

/// QEM on a mesh big enough for the engine's parallel phase (2¹⁹ faces or more): most
/// collapses are made in parts, and the result is as exact and sound as a serial run's.
/// (SVEC's parallel phase is tested on small parts in its crate: at this size it takes
/// several seconds in the test profile.)
#[test]
fn simplifiers_collapse_a_big_mesh_in_parts_and_keep_it_sound() {
    let registry = coarsen_builtin::registry();
    // 655,360 faces, bumped so that costs vary.
    let mut sphere = coarsen_shapes::icosphere(1.0, 8).unwrap();
    for p in &mut sphere.positions {
        *p *= 1.0 + 0.05 * (5.0 * p.x).sin() * (4.0 * p.y).sin() * (3.0 * p.z).sin();
    }
    let run = |name: &str, text: &str| {
        let overrides = Overrides {
            target: Some(Target::Vertices(20_000)),
            ..Default::default()
        };
        let p = Pipeline::parse(text, name, &registry, &overrides)
            .unwrap_or_else(|d| panic!("{name}:\n{d}"));
        p.run(sphere.clone(), RunOptions::default()).unwrap()
    };
    let figure =
        |r: &coarsen_pipeline::RunReport, what: &str| r.stages[0].figures[what].as_u64().unwrap();
    let shipped = coarsen_builtin::PIPELINES
        .iter()
        .find(|(n, _)| *n == "qem")
        .unwrap()
        .1;
    let (out, report) = run("qem", shipped);
    let collapses = figure(&report, "collapses");
    let in_parts = figure(&report, "parallel_collapses");
    assert!(
        in_parts > collapses * 3 / 4,
        "{in_parts} of {collapses} in parts"
    );
    assert_eq!(coarsen_tests::oriented_manifold(&out, "qem").euler, 2);
    assert_eq!(out.n_vertices(), 20_000);
    // `parallel = false`: one greedy order, another result.
    let (plain, report) = run(
        "qem",
        "[pipeline]\nname = \"qem\"\n\n[[stage]]\nkind = \"simplify.qem\"\nparallel = false\n",
    );
    assert_eq!(figure(&report, "parallel_collapses"), 0);
    assert_eq!(plain.n_vertices(), 20_000);
    assert_ne!(plain, out);
}
