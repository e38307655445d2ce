//! Every shipped pipeline checks against the built-in registry and runs on a procedural mesh.

use coarsen_pipeline::{Overrides, Pipeline, RunOptions};
use coarsen_stage::Target;

#[test]
fn every_shipped_pipeline_checks_and_runs_on_a_sphere() {
    let registry = coarsen_builtin::registry().unwrap();
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
