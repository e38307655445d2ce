//! `curvature` on the real meshes of `../shared/data` (skipped, with a message, when the
//! directory is absent).

use coarsen_mesh::Mesh;
use coarsen_stage::{Context, Stage, StageReport};
use coarsen_stage_curvature::{
    BoundaryMode, Curvature, CurvatureParams, GAUSSIAN, GaussianMode, HYBRID, MEAN, Method,
    VertexClass, estimate,
};

fn load(name: &str) -> Option<Mesh> {
    coarsen_testdata::raw(name)
}

/// Every combination of the options.
fn all_params() -> Vec<CurvatureParams> {
    let mut v = Vec::new();
    for method in [Method::Meyer, Method::AngleDeficit] {
        for boundary in [BoundaryMode::Neighbors, BoundaryMode::Geodesic] {
            for gaussian in [GaussianMode::Signed, GaussianMode::Absolute] {
                v.push(CurvatureParams {
                    method,
                    boundary,
                    gaussian,
                    ..Default::default()
                });
            }
        }
    }
    v
}

#[test]
fn bunny_and_fandisk_get_finite_curvature_at_every_vertex() {
    for name in ["stanford-bunny.obj", "fandisk.obj"] {
        let Some(mesh) = load(name) else {
            return;
        };
        let mut report = StageReport::default();
        let mut cx = Context::new(&mesh, &mut report);
        let out = Curvature::new(CurvatureParams::default())
            .run(mesh.clone(), &mut cx)
            .unwrap();
        for column in [GAUSSIAN, MEAN, HYBRID] {
            let values = out.vertex_attrs.scalar(column).unwrap();
            assert_eq!(values.len(), mesh.n_vertices());
            assert!(values.iter().all(|x| x.is_finite()), "{name}: {column}");
        }
        eprintln!("{name}: {:?}", report.figures);
        assert_eq!(report.get("vertices").unwrap()["clamped"], 0, "{name}");
        for params in all_params() {
            let e = estimate(&mesh, &params).unwrap();
            assert!(
                [&e.gaussian, &e.mean, &e.hybrid]
                    .iter()
                    .all(|c| c.iter().all(|x| x.is_finite())),
                "{name}: {params:?}"
            );
        }
    }
}

#[test]
fn bunny_holes_and_unused_vertices_are_handled_apart() {
    let Some(bunny) = load("stanford-bunny.obj") else {
        return;
    };
    let e = estimate(&bunny, &CurvatureParams::default()).unwrap();
    assert_eq!(e.counts.isolated, 1113);
    assert!(e.counts.boundary > 0);
    assert_eq!(
        e.counts.from_neighbors,
        e.counts.boundary + e.counts.degenerate_area
    );
    assert_eq!(e.counts.unresolved, 0);
    for (v, c) in e.class.iter().enumerate() {
        if *c == VertexClass::Isolated {
            assert_eq!((e.gaussian[v], e.mean[v], e.hybrid[v]), (0.0, 0.0, 0.0));
        }
    }
}

#[test]
fn messy_meshes_give_finite_values_without_errors() {
    for name in [
        "cow.obj",
        "teapot.obj",
        "beetle.obj",
        "suzanne.obj",
        "spot.obj",
        "rocker-arm.obj",
    ] {
        let Some(mesh) = load(name) else {
            return;
        };
        for params in all_params() {
            let e = estimate(&mesh, &params).unwrap();
            assert!(
                [&e.gaussian, &e.mean, &e.hybrid]
                    .iter()
                    .all(|c| c.iter().all(|x| x.is_finite())),
                "{name}: {params:?}"
            );
        }
    }
}
