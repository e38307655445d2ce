//! The third-party path: a stage crate that no coarsen crate names, linked by this test
//! binary, found through the registry and run from a TOML file by the same runner.

use coarsen_pipeline::{Overrides, Pipeline, RunOptions};
use coarsen_stage_smooth as _;

#[test]
fn the_example_plugin_is_registered_at_link_time_next_to_the_builtins() {
    let registry = coarsen_builtin::registry();
    let smooth = registry
        .get("smooth.taubin")
        .expect("the linked plug-in is registered");
    assert_eq!(smooth.crate_name, "coarsen-stage-smooth");
    assert!(
        coarsen_builtin::builtin_stages()
            .iter()
            .all(|d| d.kind != "smooth.taubin")
    );
    assert!(registry.get("simplify.qem").is_some());
}

#[test]
fn the_plugin_runs_from_toml_through_the_runner() {
    let text = r#"
[pipeline]
name = "smooth-then-measure"

[[stage]]
kind = "smooth.taubin"
iterations = 5

[[stage]]
kind = "metrics"
"#;
    let registry = coarsen_builtin::registry();
    let p = Pipeline::parse(text, "smooth.toml", &registry, &Overrides::default()).unwrap();
    let mut noisy = coarsen_shapes::icosphere(1.0, 3).unwrap();
    for (i, v) in noisy.positions.iter_mut().enumerate() {
        *v *= if i % 3 == 0 { 1.02 } else { 0.99 };
    }
    let (out, report) = p
        .run(
            noisy.clone(),
            RunOptions {
                sanity: true,
                ..Default::default()
            },
        )
        .unwrap();
    assert_eq!(out.faces, noisy.faces);
    assert_ne!(out.positions, noisy.positions);
    assert_eq!(report.stages[0].kind, "smooth.taubin");
    assert_eq!(report.stages[0].figures["iterations"], 5);
    let h = report.stages[1].figures["fidelity"]["hausdorff_pct"]
        .as_f64()
        .unwrap();
    assert!(h > 0.0 && h < 5.0, "{h}");
}

#[test]
fn plugin_parameters_are_checked_like_builtin_ones() {
    let registry = coarsen_builtin::registry();
    let text = "[[stage]]\nkind = \"smooth.taubin\"\nmu = 0.3\nlamda = 0.5\n";
    let e = Pipeline::parse(text, "s.toml", &registry, &Overrides::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("s.toml:4:1: smooth.taubin: `smooth.taubin` has no parameter `lamda` (did you mean `lambda`?)"), "{e}");
}
