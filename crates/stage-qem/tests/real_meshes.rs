//! `simplify.qem` on the real meshes of `../shared/data` (skipped, with a message, when
//! the directory is absent).

use coarsen_collapse::LiveMesh;
use coarsen_mesh::Mesh;
use coarsen_stage::{Context, Stage, StageReport, Target};
use coarsen_stage_qem::{QemParams, SimplifyQem};

fn load(name: &str) -> Option<Mesh> {
    coarsen_testdata::raw(name)
}

fn simplify(mesh: &Mesh, target: Target) -> (Mesh, StageReport) {
    let mut report = StageReport::default();
    let mut cx = Context::new(mesh, &mut report);
    cx.target = Some(target);
    let out = SimplifyQem::new(QemParams::default())
        .run(mesh.clone(), &mut cx)
        .unwrap();
    (out, report)
}

/// Manifold, no unused vertex, no NaN; returns the boundary loop count.
fn check_output(out: &Mesh) -> usize {
    assert!(out.positions.iter().all(|p| p.is_finite()));
    let s = LiveMesh::new(out).unwrap().summary();
    assert_eq!(s.locked_vertices, 0, "non-manifold output: {s:?}");
    assert_eq!(s.isolated_vertices, 0, "{s:?}");
    s.boundary_loops
}

#[test]
fn bunny_at_70_and_95_percent_removed_keeps_its_five_holes() {
    let Some(bunny) = load("stanford-bunny.obj") else {
        return;
    };
    let input = LiveMesh::new(&bunny).unwrap().summary();
    assert_eq!(input.boundary_loops, 5);
    for ratio in [0.7, 0.95] {
        let (out, report) = simplify(&bunny, Target::Ratio(ratio));
        let goal = Target::Ratio(ratio).faces_for(&bunny) as usize;
        assert!(
            out.n_faces() == goal || out.n_faces() + 1 == goal,
            "{} faces for a goal of {goal}",
            out.n_faces()
        );
        assert_eq!(check_output(&out), 5, "ratio {ratio}");
        assert_eq!(report.get("stop"), Some(&"reached".into()));
        assert_eq!(report.get("boundary_loops"), Some(&5.into()));
    }
}

#[test]
fn bunny_to_an_exact_vertex_count() {
    let Some(bunny) = load("stanford-bunny.obj") else {
        return;
    };
    let (out, _) = simplify(&bunny, Target::Vertices(5000));
    assert_eq!(out.n_vertices(), 5000);
    assert_eq!(check_output(&out), 5);
}

#[test]
fn rocker_arm_keeps_genus_one() {
    let Some(arm) = load("rocker-arm.obj") else {
        return;
    };
    let (out, report) = simplify(&arm, Target::Vertices(2000));
    assert_eq!(out.n_vertices(), 2000);
    assert_eq!(check_output(&out), 0);
    // Closed, genus 1: χ = 0.
    assert_eq!(LiveMesh::new(&out).unwrap().summary().euler, 0);
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    let (out, _) = simplify(&arm, Target::Ratio(0.95));
    assert_eq!(out.n_faces(), 1004);
    assert_eq!(LiveMesh::new(&out).unwrap().summary().euler, 0);
}

#[test]
fn messy_meshes_simplify_without_error() {
    for name in [
        "cow.obj",
        "teapot.obj",
        "beetle.obj",
        "suzanne.obj",
        "spot.obj",
        "fandisk.obj",
    ] {
        let Some(mesh) = load(name) else { return };
        let before = LiveMesh::new(&mesh).unwrap().summary();
        let (out, report) = simplify(&mesh, Target::Ratio(0.8));
        let after = LiveMesh::new(&out).unwrap().summary();
        assert!(out.positions.iter().all(|p| p.is_finite()), "{name}");
        assert!(out.n_faces() < mesh.n_faces(), "{name}");
        assert!(
            after.locked_vertices <= before.locked_vertices,
            "{name}: {before:?} → {after:?}"
        );
        if before.locked_vertices == 0 {
            assert_eq!(after.boundary_loops, before.boundary_loops, "{name}");
        }
        eprintln!(
            "{name}: {} → {} faces, stop {}, {} warnings",
            mesh.n_faces(),
            out.n_faces(),
            report.get("stop").unwrap(),
            report.warnings.len()
        );
    }
}

#[test]
fn no_face_turns_against_the_input_at_the_paper_ratios() {
    // The cow (thin legs, ears, tail) had 6–7 flipped faces and the spot one before the
    // facing guard.
    for name in [
        "stanford-bunny.obj",
        "rocker-arm.obj",
        "fandisk.obj",
        "spot.obj",
        "cow.obj",
    ] {
        let Some(mesh) = load(name) else { return };
        for ratio in [0.7, 0.95] {
            let (out, report) = simplify(&mesh, Target::Ratio(ratio));
            let validity = coarsen_metrics::validity(Some(&mesh), &out).unwrap();
            assert_eq!(validity.n_flipped, Some(0), "{name} {ratio}");
            assert!(report.get("facing_tests").is_some(), "{name} {ratio}");
        }
    }
}
