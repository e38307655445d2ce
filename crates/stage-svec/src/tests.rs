//! Tests of the `simplify.svec` stage and its cost model.

use super::*;
use coarsen_collapse::{CostModel, Index, Merge, NONE, NoGuard, VertexKind};
use coarsen_mesh::DVec3;
use coarsen_shapes::{icosphere, plane_grid, torus};
use std::collections::BTreeMap as Map;

fn run(
    mesh: &Mesh,
    target: Option<Target>,
    params: SvecParams,
) -> (Result<Mesh, StageError>, StageReport) {
    let mut report = StageReport::default();
    let mut cx = Context::new(mesh, &mut report);
    cx.target = target;
    let out = SimplifySvec::new(params).run(mesh.clone(), &mut cx);
    (out, report)
}

/// Manifold without boundary, no unused vertex, no NaN; returns V − E + F.
fn closed_euler(mesh: &Mesh) -> i64 {
    assert!(mesh.positions.iter().all(|p| p.is_finite()), "NaN");
    let s = LiveMesh::new(mesh).unwrap().summary();
    assert_eq!(s.locked_vertices, 0, "non-manifold: {s:?}");
    assert_eq!(s.boundary_edges, 0, "open: {s:?}");
    assert_eq!(s.isolated_vertices, 0, "{s:?}");
    s.euler
}

/// A cube of side 2 centred at the origin, each side an `n × n` grid of split squares,
/// faces outward.
fn tessellated_cube(n: u32) -> Mesh {
    let mut index: Map<[i64; 3], u32> = Map::new();
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    let n = n as i64;
    // (outward axis, sign, u axis, v axis) with u × v outward.
    let sides = [
        (0, 1, 1, 2),
        (0, -1, 2, 1),
        (1, 1, 2, 0),
        (1, -1, 0, 2),
        (2, 1, 0, 1),
        (2, -1, 1, 0),
    ];
    for (axis, sign, u, v) in sides {
        let mut at = |i: i64, j: i64| {
            let mut k = [0i64; 3];
            k[axis] = if sign > 0 { n } else { 0 };
            k[u] = i;
            k[v] = j;
            *index.entry(k).or_insert_with(|| {
                positions
                    .push(DVec3::new(k[0] as f64, k[1] as f64, k[2] as f64) * 2.0 / n as f64 - 1.0);
                (positions.len() - 1) as u32
            })
        };
        for j in 0..n {
            for i in 0..n {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                faces.push([a, b, c]);
                faces.push([a, c, d]);
            }
        }
    }
    Mesh::new(positions, faces)
}

/// A `n × n` grid on the unit square with a smooth bump, boundary on the square's sides.
fn bumpy_grid(n: u32) -> Mesh {
    let mut mesh = plane_grid(n, n, 1.0).unwrap();
    for p in &mut mesh.positions {
        p.z = 0.15 * (3.0 * p.x).sin() * (2.0 * p.y + 0.3).cos();
    }
    mesh
}

#[test]
fn needs_a_target_and_checks_its_parameters() {
    let stage = SimplifySvec::new(SvecParams::default());
    assert!(stage.contract().needs.target);
    let (out, _) = run(&icosphere(1.0, 1).unwrap(), None, SvecParams::default());
    let e = out.unwrap_err().to_string();
    assert!(e.contains("`simplify.svec` needs a target"), "{e}");
    let bad = SvecParams {
        feature_sigma: f64::NAN,
        feature_threshold: -1.0,
        volume_constraint: false,
        boundary_weight: -1.0,
        max_error: -2.0,
        min_quality: 3.0,
        target_scale: 0.5,
        facing_guard: true,
        parallel: true,
        factors: "vertex".into(),
        normal_abs: true,
        feature_rule: "later".into(),
        reach: "one_ring".into(),
        sve_weighted: false,
        features: true,
        feature_angle_deg: -1.0,
        placement: "optimal".into(),
    };
    let fields: Vec<_> = bad.validate().iter().map(|i| i.field).collect();
    assert_eq!(
        fields,
        [
            "feature_sigma",
            "feature_threshold",
            "max_error",
            "boundary_weight",
            "min_quality",
            "target_scale",
            "feature_angle_deg",
            "factors",
            "feature_rule",
            "reach",
            "placement"
        ]
    );
    assert!(SvecParams::default().validate().is_empty());
}

#[test]
fn example_table_builds_through_the_registry() {
    let d = descriptor();
    let mut table: toml::Table =
        toml::from_str(&d.example_toml().replace("[[stage]]\n", "")).unwrap();
    assert_eq!(table.remove("kind"), Some("simplify.svec".into()));
    let stage = (d.build)(&table).ok().unwrap();
    assert_eq!(stage.kind(), "simplify.svec");
    assert_eq!(stage.params()["feature_sigma"].as_float(), Some(2.0));
}

#[test]
fn an_interior_triangle_and_its_three_neighbours_go_in_one_collapse() {
    let sphere = icosphere(1.0, 2).unwrap();
    let mut live = LiveMesh::new(&sphere).unwrap();
    let mut model = SvecModel::new(&live, &SvecOptions::default());
    let goal = Goal::Faces(sphere.n_faces() - 1);
    let outcome = live.collapse(&mut model, &Options::new(goal), &mut |_| {});
    assert_eq!(outcome.collapses, 1);
    let r = outcome.log[0];
    assert!(r.removed.iter().all(|&v| v != NONE), "3 vertices → 1");
    assert_eq!(live.n_faces(), sphere.n_faces() - 4);
    assert_eq!(live.n_vertices(), sphere.n_vertices() - 2);
    live.check_invariants().unwrap();
}

#[test]
fn strong_feature_triangles_collapse_onto_the_cube_corners() {
    let cube = tessellated_cube(8);
    let corners: Vec<DVec3> = cube
        .positions
        .iter()
        .copied()
        .filter(|p| p.abs() == DVec3::ONE)
        .collect();
    assert_eq!(corners.len(), 8);
    let (out, report) = run(&cube, Some(Target::Ratio(0.8)), SvecParams::default());
    let out = out.unwrap();
    assert_eq!(closed_euler(&out), 2);
    // Kept by the feature rule while the corner's K_t is high, by the quadric (three
    // planes meet there) once coarsening has spread its deficit over a larger area.
    for c in &corners {
        let nearest = out
            .positions
            .iter()
            .map(|p| (*p - *c).length())
            .fold(f64::INFINITY, f64::min);
        assert!(nearest < 1e-12, "corner {c} moved by {nearest}");
    }
    let features = report.get("feature_collapses").unwrap().as_u64().unwrap();
    assert!(features > 0, "{report:?}");
    // A threshold above every K_t turns the filter off.
    let off = SvecParams {
        feature_threshold: 1e300,
        ..SvecParams::default()
    };
    let (_, report) = run(&cube, Some(Target::Ratio(0.8)), off);
    assert_eq!(report.get("feature_collapses"), Some(&0.into()));
}

#[test]
fn feature_vertex_is_the_one_of_largest_curvature() {
    let cube = tessellated_cube(8);
    let live = LiveMesh::new(&cube).unwrap();
    let model = SvecModel::new(&live, &SvecOptions::default());
    let corner = cube
        .positions
        .iter()
        .position(|p| *p == DVec3::ONE)
        .unwrap() as Index;
    let f = live.faces_around(corner)[0];
    let t = live.face(f);
    assert!(model.triangle_curvature(&t) > model.feature_threshold());
    let plan = model
        .plan(
            &live,
            &Merge {
                vertices: &t,
                pinned: None,
            },
        )
        .unwrap();
    assert_eq!(plan.position, DVec3::ONE);
    // Angle deficit π/2 at a cube corner.
    let k = model.vertex_curvature(corner);
    assert!(k > 0.0 && t.iter().all(|&v| model.vertex_curvature(v) <= k));
}

#[test]
fn boundary_rules_pin_one_slide_two_and_never_merge_three() {
    let grid = bumpy_grid(12);
    let mut live = LiveMesh::new(&grid).unwrap();
    let kind: Vec<VertexKind> = (0..grid.n_vertices() as Index)
        .map(|v| live.kind(v))
        .collect();
    let mut model = SvecModel::new(&live, &SvecOptions::default());
    let outcome = live.collapse(&mut model, &Options::new(Goal::Vertices(20)), &mut |_| {});
    live.check_invariants().unwrap();
    let mut pos = grid.positions.clone();
    let (mut one, mut two) = (0, 0);
    for r in &outcome.log {
        let merged: Vec<Index> = [r.kept, r.removed[0], r.removed[1]]
            .into_iter()
            .filter(|&v| v != NONE)
            .collect();
        let b: Vec<Index> = merged
            .iter()
            .copied()
            .filter(|&v| kind[v as usize] == VertexKind::Boundary)
            .collect();
        match b.len() {
            0 => {}
            1 => {
                assert_eq!(r.position, pos[b[0] as usize]);
                one += 1;
            }
            2 => {
                let (a, c) = (pos[b[0] as usize], pos[b[1] as usize]);
                let (d, x) = (c - a, r.position - a);
                assert!(
                    x.cross(d).length() <= 1e-12 * d.length_squared(),
                    "off the segment"
                );
                assert!((-1e-12..=d.length_squared() * (1.0 + 1e-12)).contains(&x.dot(d)));
                two += 1;
            }
            _ => panic!("three boundary vertices merged: {r:?}"),
        }
        pos[r.kept as usize] = r.position;
    }
    assert!(one > 0 && two > 0, "{one} pinned, {two} slid");
    assert!(outcome.refused.boundary > 0);
    let (out, _) = live.to_mesh(&grid).unwrap();
    assert_eq!(LiveMesh::new(&out).unwrap().summary().boundary_loops, 1);
}

#[test]
fn exact_targets_on_spheres_keep_a_closed_sphere() {
    let sphere = icosphere(1.0, 3).unwrap();
    for n in [300, 101, 40] {
        let (out, report) = run(&sphere, Some(Target::Vertices(n)), SvecParams::default());
        let out = out.unwrap();
        assert_eq!(out.n_vertices(), n as usize);
        assert_eq!(closed_euler(&out), 2);
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        let t = report.get("triangle_collapses").unwrap().as_u64().unwrap();
        let e = report.get("edge_collapses").unwrap().as_u64().unwrap();
        assert!(e <= 1 && t > 0, "{t} triangles, {e} edges");
    }
    for ratio in [0.7, 0.95] {
        let (out, _) = run(&sphere, Some(Target::Ratio(ratio)), SvecParams::default());
        let goal = Target::Ratio(ratio).faces_for(&sphere) as usize;
        let faces = out.unwrap().n_faces();
        assert!(faces == goal || faces + 1 == goal, "{faces} for {goal}");
    }
}

#[test]
fn tori_keep_their_genus_at_exact_face_counts() {
    let ring = torus(2.0, 0.6, 40, 16).unwrap();
    for faces in [600, 202, 100] {
        let (out, report) = run(&ring, Some(Target::Faces(faces)), SvecParams::default());
        let out = out.unwrap();
        // A closed mesh has an even face count: 202 is met, 600 and 100 too.
        assert_eq!(out.n_faces(), faces as usize, "{report:?}");
        assert_eq!(closed_euler(&out), 0);
    }
}

#[test]
fn same_input_gives_the_same_bytes() {
    let grid = bumpy_grid(16);
    let params = SvecParams {
        volume_constraint: true,
        ..SvecParams::default()
    };
    let (a, ra) = run(&grid, Some(Target::Ratio(0.8)), params.clone());
    let (b, rb) = run(&grid, Some(Target::Ratio(0.8)), params);
    let (a, b) = (a.unwrap(), b.unwrap());
    let bits = |m: &Mesh| -> Vec<u64> {
        m.positions
            .iter()
            .flat_map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
            .collect()
    };
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(a.faces, b.faces);
    assert_eq!(ra.figures, rb.figures);
}

#[test]
fn the_output_does_not_depend_on_the_thread_count() {
    // The model's setup and the engine's first ranking run on rayon's threads.
    let mesh = coarsen_shapes::bumpy_sphere(1.0, 4, 0.15, 3.0).unwrap();
    let run_on = |threads: usize| {
        coarsen_testdata::on_threads(threads, || {
            let (out, report) = run(&mesh, Some(Target::Ratio(0.9)), SvecParams::default());
            (out.unwrap(), report.figures)
        })
    };
    let one = run_on(1);
    for threads in [2, 3] {
        assert_eq!(run_on(threads), one, "{threads} threads");
    }
}

#[test]
fn flat_regions_cost_nothing_and_keep_their_outline() {
    let grid = plane_grid(12, 12, 1.0).unwrap();
    let (out, report) = run(&grid, Some(Target::Vertices(40)), SvecParams::default());
    let out = out.unwrap();
    assert_eq!(out.n_vertices(), 40);
    assert_eq!(report.get("max_cost"), Some(&0.0.into()));
    assert_eq!(report.get("sve"), Some(&0.0.into()));
    assert!(out.positions.iter().all(|p| p.z == 0.0));
    assert_eq!(report.get("boundary_loops"), Some(&1.into()));
}

#[test]
fn volume_constraint_changes_the_plan_but_not_the_validity() {
    let sphere = coarsen_shapes::bumpy_sphere(1.0, 3, 0.1, 5.0).unwrap();
    let plain = run(&sphere, Some(Target::Ratio(0.8)), SvecParams::default());
    let phi = SvecParams {
        volume_constraint: true,
        ..SvecParams::default()
    };
    let weighted = run(&sphere, Some(Target::Ratio(0.8)), phi);
    let (a, b) = (plain.0.unwrap(), weighted.0.unwrap());
    assert_eq!(closed_euler(&a), 2);
    assert_eq!(closed_euler(&b), 2);
    assert_ne!(a.positions, b.positions);
}

#[test]
fn every_reading_changes_the_collapses_and_keeps_the_mesh_valid() {
    let sphere = coarsen_shapes::bumpy_sphere(1.0, 3, 0.1, 5.0).unwrap();
    let weighted = SvecParams {
        sve_weighted: true,
        // A low threshold: strong-feature triangles in plenty, for the filter's reading.
        feature_sigma: 0.0,
        ..SvecParams::default()
    };
    let (literal, report) = run(&sphere, Some(Target::Ratio(0.8)), weighted.clone());
    let literal = literal.unwrap();
    let figure = |r: &StageReport, name: &str| r.get(name).and_then(|x| x.as_f64()).unwrap();
    let (sve, max, w) = (
        figure(&report, "sve"),
        figure(&report, "sve_max"),
        figure(&report, "sve_weighted"),
    );
    assert!(
        0.0 < max && max < sve && 0.0 < w && w < sve,
        "{sve} {max} {w}"
    );
    let readings = [
        SvecParams {
            factors: "triangle".into(),
            ..weighted.clone()
        },
        SvecParams {
            feature_rule: "dequeue".into(),
            ..weighted.clone()
        },
        SvecParams {
            reach: "two_rings".into(),
            ..weighted.clone()
        },
    ];
    for params in readings {
        let what = format!("{params:?}");
        let (out, report) = run(&sphere, Some(Target::Ratio(0.8)), params);
        let out = out.unwrap();
        assert_eq!(closed_euler(&out), 2, "{what}");
        assert_eq!(out.n_faces(), literal.n_faces(), "{what}");
        assert_ne!(out.positions, literal.positions, "{what}");
        assert!(figure(&report, "sve_weighted") > 0.0, "{what}");
    }
    // Normals more than 90° apart around a vertex: a needle's tips.
    let mut needle = icosphere(1.0, 3).unwrap();
    needle.positions.iter_mut().for_each(|p| p.z *= 40.0);
    let at = |normal_abs| {
        let params = SvecParams {
            normal_abs,
            ..SvecParams::default()
        };
        let out = run(&needle, Some(Target::Ratio(0.8)), params).0.unwrap();
        assert_eq!(closed_euler(&out), 2);
        out
    };
    assert_ne!(at(true).positions, at(false).positions);
}

#[test]
fn without_the_absolute_value_a_fold_is_not_flat() {
    // Two faces folded onto each other (normals opposite): |n₀·n₁| = 1 reads as flat,
    // n₀·n₁ = −1 as the sharpest fold.
    let mesh = Mesh::new(
        vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 1e-9)],
        vec![[0, 1, 2], [1, 0, 3]],
    );
    let live = LiveMesh::new(&mesh).unwrap();
    let n = |normal_abs| {
        let opts = SvecOptions {
            normal_abs,
            ..SvecOptions::default()
        };
        let model = SvecModel::new(&live, &opts);
        model.face_quadric(0).eval(DVec3::Z)
    };
    assert!(n(true) < 1e-12 * n(false), "{} {}", n(true), n(false));
    assert!(n(false) > 0.0);
}

#[test]
fn unreachable_target_is_a_warning_not_an_error() {
    let tet = Mesh::new(
        vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
        vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
    );
    let (out, report) = run(&tet, Some(Target::Vertices(3)), SvecParams::default());
    assert_eq!(out.unwrap(), tet);
    assert_eq!(report.get("stop"), Some(&"exhausted".into()));
    assert!(
        report.warnings[0].contains("not reached"),
        "{:?}",
        report.warnings
    );
}

#[test]
fn hands_back_one_record_of_both_phases_only_when_asked() {
    // A vertex target of odd distance: triangle collapses, then an edge collapse finish.
    let mesh = torus(3.0, 1.0, 20, 10).unwrap();
    let goal = Target::Vertices(51);
    let mut report = StageReport::default();
    let mut slot = None;
    let mut cx = Context::new(&mesh, &mut report);
    cx.target = Some(goal);
    cx.progressive = Some(&mut slot);
    let out = SimplifySvec::new(SvecParams::default())
        .run(mesh.clone(), &mut cx)
        .unwrap();
    let record = slot
        .expect("a record")
        .downcast::<coarsen_collapse::Progressive>()
        .expect("the engine's record");
    let collapses = report.get("collapses").and_then(|v| v.as_u64()).unwrap();
    assert!(
        report
            .get("edge_collapses")
            .and_then(|v| v.as_u64())
            .unwrap()
            > 0
    );
    assert_eq!(record.steps.len() as u64, collapses);
    assert!(record.steps.iter().any(|s| s.n_removed() == 2));
    assert!(record.steps.iter().any(|s| s.n_removed() == 1));
    assert_eq!(record.coarse, coarsen_collapse::fingerprint(&out));
    assert_eq!(record.coarse_vertices(), 51);
    let (plain, _) = run(&mesh, Some(goal), SvecParams::default());
    assert_eq!(plain.unwrap(), out, "recording changes nothing");
}

#[test]
fn target_scale_stops_at_a_multiple_of_the_target() {
    let mesh = icosphere(1.0, 3).unwrap();
    let params = SvecParams {
        target_scale: 3.0,
        ..SvecParams::default()
    };
    let (out, _) = run(&mesh, Some(Target::Vertices(50)), params.clone());
    assert_eq!(out.unwrap().n_vertices(), 150);
    let (out, _) = run(&mesh, Some(Target::Faces(100)), params);
    assert!((299..=300).contains(&out.unwrap().n_faces()));
}

#[test]
fn a_big_mesh_collapses_in_parts_first_and_ends_close_to_the_serial_result() {
    let mesh = tessellated_cube(40);
    // As the stage runs it, in steps.
    let in_parts = PartOptions {
        min_faces: 0,
        min_collapses: 0,
        faces_per_part: 1024,
        steps: crate::PARALLEL_STEPS,
        ..PartOptions::default()
    };
    let serial = PartOptions {
        min_faces: usize::MAX,
        ..PartOptions::default()
    };
    let run_with = |parts: &PartOptions| {
        let mut live = LiveMesh::new_renumbered(&mesh).unwrap();
        let params = SvecParams::default();
        let mut svec = Svec::new(&params);
        svec.parts = *parts;
        let done = svec.collapse(&mut live, Goal::Faces(1000), || NoGuard, &mut |_| {});
        let totals = (svec.feature_collapses, done.outcome.sve);
        (live.to_mesh(&mesh).unwrap().0, totals)
    };
    let (a, ta) = run_with(&in_parts);
    let (b, tb) = run_with(&serial);
    assert_ne!(a, b, "the parts changed the order of collapses");
    assert_eq!(closed_euler(&a), 2);
    assert!((999..=1000).contains(&a.n_faces()), "{}", a.n_faces());
    // The cube's corners are strong features, whichever part collapses next to them.
    let ((fa, sve_a), (fb, sve_b)) = (ta, tb);
    assert!(fa > 0 && fb > 0);
    assert!(fa * 2 > fb && fb * 2 > fa, "{fa} against {fb}");
    assert!(sve_a < 1.5 * sve_b, "{sve_a} against {sve_b}");
}

#[test]
fn a_deferred_model_has_the_full_models_threshold_and_once_prepared_its_plans() {
    for mesh in [tessellated_cube(6), bumpy_grid(12)] {
        let live = LiveMesh::new_renumbered(&mesh).unwrap();
        let opts = SvecOptions::default();
        let full = SvecModel::new(&live, &opts);
        let mut deferred = SvecModel::deferred(&live, &opts);
        assert!(full.feature_threshold().is_finite());
        assert_eq!(
            deferred.feature_threshold().to_bits(),
            full.feature_threshold().to_bits()
        );
        deferred.prepare(&live);
        // A threshold given rather than measured is kept as given.
        let given = SvecOptions {
            feature_threshold: Some(0.5 * full.feature_threshold()),
            ..opts
        };
        let mut deferred_given = SvecModel::deferred(&live, &given);
        deferred_given.prepare(&live);
        let full_given = SvecModel::new(&live, &given);
        assert_eq!(
            deferred_given.feature_threshold(),
            given.feature_threshold.unwrap()
        );
        for f in live.live_faces() {
            let t = live.face(f);
            let merge = Merge {
                vertices: &t,
                pinned: None,
            };
            assert_eq!(deferred.plan(&live, &merge), full.plan(&live, &merge));
            assert_eq!(
                deferred_given.plan(&live, &merge),
                full_given.plan(&live, &merge)
            );
        }
        // A serial run handed a deferred model (as when no part could collapse anything)
        // builds it before ranking: the same output as from a full model.
        let run = |mut model: SvecModel| {
            let mut live = LiveMesh::new_renumbered(&mesh).unwrap();
            let opts = Options {
                keep_log: false,
                ..Options::new(Goal::Faces(mesh.n_faces() / 4))
            };
            let o = live.collapse(&mut model, &opts, &mut |_| {});
            assert!(o.collapses > 0);
            live.to_mesh(&mesh).unwrap().0
        };
        let from_deferred = run(SvecModel::deferred(&live, &opts));
        assert_eq!(from_deferred, run(SvecModel::new(&live, &opts)));
    }
}

#[test]
fn with_features_the_vertices_of_sharp_curves_stay_on_them() {
    // A cube whose sides are slightly bent outwards: the cube's edges are sharp curves
    // (90°), and a vertex that leaves one is off the lattice of the input's edge vertices.
    let mut mesh = coarsen_shapes::cube(2.0, 10).unwrap();
    for p in &mut mesh.positions {
        let bulge = 0.02 * (1.0 - p.x * p.x) * (1.0 - p.y * p.y) * (1.0 - p.z * p.z);
        *p += *p * bulge;
    }
    let on_edge = |p: DVec3| p.to_array().iter().filter(|c| c.abs() == 1.0).count() >= 2;
    let params = SvecParams {
        features: true,
        ..SvecParams::default()
    };
    let (out, report) = run(&mesh, Some(Target::Vertices(100)), params);
    let out = out.unwrap();
    assert_eq!(out.n_vertices(), 100);
    assert_eq!(report.get("corners_locked"), Some(&8.into()));
    // Every vertex of an output edge whose faces meet at more than 45° lies on a cube edge.
    let mut sharp_ends = 0;
    for f in 0..out.n_faces() {
        for g in f + 1..out.n_faces() {
            let shared: Vec<u32> = out.faces[f]
                .iter()
                .copied()
                .filter(|v| out.faces[g].contains(v))
                .collect();
            if shared.len() == 2 && out.face_normal(f).dot(out.face_normal(g)) < 0.7 {
                for v in shared {
                    let p = out.positions[v as usize];
                    assert!(on_edge(p), "{p} ends a sharp edge off the cube's edges");
                    sharp_ends += 1;
                }
            }
        }
    }
    assert!(sharp_ends >= 24, "{sharp_ends}");
}
