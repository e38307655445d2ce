use super::*;
use coarsen_mesh::DVec3;

/// A unit cube of 12 triangles.
fn cube() -> Mesh {
    coarsen_shapes::cube(1.0, 1).unwrap()
}

/// An open tube of radius 1 along z: `around` segments, `rows` rows of faces.
fn tube(around: u32, rows: u32) -> Mesh {
    let mut positions = Vec::new();
    for k in 0..=rows {
        for i in 0..around {
            let a = std::f64::consts::TAU * f64::from(i) / f64::from(around);
            positions.push(DVec3::new(a.cos(), a.sin(), f64::from(k) / f64::from(rows)));
        }
    }
    let id = |k: u32, i: u32| k * around + i % around;
    let mut faces = Vec::new();
    for k in 0..rows {
        for i in 0..around {
            faces.push([id(k, i), id(k, i + 1), id(k + 1, i + 1)]);
            faces.push([id(k, i), id(k + 1, i + 1), id(k + 1, i)]);
        }
    }
    Mesh::new(positions, faces)
}

fn detect(m: &Mesh, opts: &FeatureOptions) -> Features {
    Features::detect(m, &Topology::build(m), opts)
}

/// Every curve is a chain of feature edges: consecutive vertices are joined by one, an
/// open curve ends at corners and has no corner inside, and every feature edge is on
/// exactly one curve.
fn check_curves(m: &Mesh, f: &Features) {
    let topo = Topology::build(m);
    let mut used = vec![0; topo.n_edges()];
    for c in 0..f.n_curves() {
        let vs = f.curve(c);
        let closed = f.curve_closed[c];
        let n = if closed { vs.len() } else { vs.len() - 1 };
        for i in 0..n {
            let e = topo.find_edge(vs[i], vs[(i + 1) % vs.len()]).unwrap();
            assert!(
                self_edge_index(&f.edges, e).is_some(),
                "{c}: not a feature edge"
            );
            used[e as usize] += 1;
        }
        let inner = if closed { vs } else { &vs[1..vs.len() - 1] };
        for &v in inner {
            assert_eq!(f.roles[v as usize], VertexRole::Curve(c as u32));
        }
        if !closed {
            for v in [vs[0], vs[vs.len() - 1]] {
                assert_eq!(f.roles[v as usize], VertexRole::Corner);
            }
        }
    }
    for &(e, _) in &f.edges {
        assert_eq!(
            used[e as usize], 1,
            "edge {e} on {} curves",
            used[e as usize]
        );
    }
}

#[test]
fn a_cube_has_twelve_sharp_edges_eight_corners_and_twelve_curves() {
    let m = cube();
    let f = detect(&m, &FeatureOptions::default());
    let c = f.counts();
    assert_eq!(
        (c.sharp_edges, c.boundary_edges, c.junction_edges),
        (12, 0, 0)
    );
    assert_eq!((c.corners, c.curves, c.closed_curves), (8, 12, 0));
    assert!(f.edges.iter().all(|&(e, _)| {
        let [a, b] = Topology::build(&m).edge(e);
        (m.positions[a as usize] - m.positions[b as usize]).length() == 1.0
    }));
    check_curves(&m, &f);
    // A cube's edges turn by exactly 90°: above that angle nothing is sharp.
    let none = detect(
        &m,
        &FeatureOptions {
            angle_deg: 100.0,
            ..Default::default()
        },
    );
    assert_eq!(
        none,
        Features {
            curve_offsets: vec![0],
            roles: vec![VertexRole::Free; 8],
            ..Default::default()
        }
    );
}

#[test]
fn a_sphere_has_no_features() {
    let m = coarsen_shapes::icosphere(1.0, 3).unwrap();
    let f = detect(&m, &FeatureOptions::default());
    assert_eq!(f.counts(), FeatureCounts::default());
    assert!(f.roles.iter().all(|&r| r == VertexRole::Free));
}

#[test]
fn a_tube_has_two_closed_rims_and_no_corner() {
    let m = tube(24, 6);
    let f = detect(&m, &FeatureOptions::default());
    let c = f.counts();
    assert_eq!((c.boundary_edges, c.sharp_edges), (48, 0));
    assert_eq!((c.curves, c.closed_curves, c.corners), (2, 2, 0));
    assert_eq!((f.curve(0).len(), f.curve(1).len()), (24, 24));
    check_curves(&m, &f);
    // Rims of 6 segments turn by 60° at each vertex: every rim vertex is a corner (the
    // hexagonal prism's own 60° edges kept out by a larger angle).
    let m = tube(6, 2);
    let f = detect(
        &m,
        &FeatureOptions {
            angle_deg: 70.0,
            ..Default::default()
        },
    );
    assert_eq!(f.counts().sharp_edges, 0);
    assert_eq!((f.counts().corners, f.counts().curves), (12, 12));
    check_curves(&m, &f);
    // Without boundary features, nothing.
    let f = detect(
        &m,
        &FeatureOptions {
            angle_deg: 70.0,
            boundary: false,
            ..Default::default()
        },
    );
    assert_eq!(f.counts(), FeatureCounts::default());
    // At 40° the prism's six side edges are sharp: each a curve from rim to rim through
    // the middle row, where it goes straight on.
    let f = detect(&m, &FeatureOptions::default());
    assert_eq!((f.counts().sharp_edges, f.counts().curves), (12, 18));
    check_curves(&m, &f);
}

#[test]
fn a_square_plate_has_four_corners_where_its_rim_turns() {
    let m = coarsen_shapes::plane_grid(5, 5, 1.0).unwrap();
    let f = detect(&m, &FeatureOptions::default());
    assert_eq!(
        (
            f.counts().corners,
            f.counts().curves,
            f.counts().boundary_edges
        ),
        (4, 4, 20)
    );
    check_curves(&m, &f);
}

#[test]
fn a_crease_that_fades_out_ends_at_corners() {
    // A strip folded along y = 0 (the grid is centred): the fold's edges are sharp, the
    // fold a curve from rim to rim.
    let mut m = coarsen_shapes::plane_grid(4, 2, 1.0).unwrap();
    for p in &mut m.positions {
        p.z = 0.5 * p.y.abs();
    }
    let f = detect(
        &m,
        &FeatureOptions {
            angle_deg: 20.0,
            boundary: false,
            ..Default::default()
        },
    );
    let c = f.counts();
    assert!(c.sharp_edges > 0);
    assert_eq!((c.curves, c.corners), (1, 2));
    check_curves(&m, &f);
}

#[test]
fn the_fandisk_has_its_creases_chained_into_curves() {
    let Some(m) = coarsen_testdata::cleaned("fandisk.obj") else {
        eprintln!("skipped: ../shared/data/fandisk.obj is absent");
        return;
    };
    let f = detect(&m, &FeatureOptions::default());
    let c = f.counts();
    check_curves(&m, &f);
    // A closed CAD part: sharp edges only, chained into open curves between corners.
    assert_eq!((c.boundary_edges, c.junction_edges), (0, 0));
    assert!(
        c.sharp_edges > 400 && c.curves >= 10 && c.corners >= 10,
        "{c:?}"
    );
}

/// A flat grid of `nx × ny` unit squares in z = 0, vertex `(i, j)` numbered
/// `i + (nx + 1) j`, each square cut along its diagonal from `(i, j)` to `(i + 1, j + 1)`.
fn flat_grid(nx: u32, ny: u32) -> Mesh {
    let id = |i: u32, j: u32| i + (nx + 1) * j;
    let positions = (0..=ny)
        .flat_map(|j| (0..=nx).map(move |i| DVec3::new(f64::from(i), f64::from(j), 0.0)))
        .collect();
    let mut faces = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Mesh::new(positions, faces)
}

#[test]
fn a_marked_zig_zag_on_a_flat_grid_is_a_chain_of_curves_with_corners_where_it_turns() {
    //   . . . . . . . .
    //   . . . o-o-o . .      the marked line, from (1, 1) to (5, 1):
    //   . . . | . | . .      straight on through (2, 1), (3, 2), (4, 3) and (5, 2),
    //   . o-o-o . o . .      turning by 90° at (3, 1), (3, 3) and (5, 3)
    //   . . . . . . . .
    let mut m = flat_grid(7, 4);
    let id = |i: u32, j: u32| i + 8 * j;
    let path = [
        (1, 1),
        (2, 1),
        (3, 1),
        (3, 2),
        (3, 3),
        (4, 3),
        (5, 3),
        (5, 2),
        (5, 1),
    ];
    // Marked in the file's order and direction, one edge twice.
    m.marked_edges = path
        .windows(2)
        .map(|w| [id(w[0].0, w[0].1), id(w[1].0, w[1].1)])
        .collect();
    m.marked_edges.push([id(2, 1), id(1, 1)]);
    let inner = FeatureOptions {
        boundary: false,
        ..Default::default()
    };
    let f = detect(&m, &inner);
    let c = f.counts();
    assert_eq!((c.marked_edges, c.sharp_edges, c.boundary_edges), (8, 0, 0));
    assert!(f.edges.iter().all(|e| e.1 == FeatureKind::Marked));
    let corners = [(1, 1), (3, 1), (5, 1), (3, 3), (5, 3)].map(|(i, j)| id(i, j));
    assert_eq!(f.corners, corners);
    let curves: Vec<Vec<u32>> = (0..f.n_curves()).map(|c| f.curve(c).to_vec()).collect();
    let along = |k: usize| -> Vec<u32> { path[k..=k + 2].iter().map(|&(i, j)| id(i, j)).collect() };
    // Walked from the corners in index order: the last leg from its far end.
    assert_eq!(
        curves,
        vec![
            along(0),
            along(2),
            along(6).into_iter().rev().collect(),
            along(4),
        ]
    );
    assert_eq!(c.closed_curves, 0);
    check_curves(&m, &f);
    // With the boundary: its loop of 22 edges beside the marked line, which it does not
    // touch.
    let f = detect(&m, &FeatureOptions::default());
    let c = f.counts();
    assert_eq!((c.marked_edges, c.boundary_edges), (8, 22));
    assert_eq!((c.curves, c.corners), (8, 9));
    check_curves(&m, &f);
}

#[test]
fn a_marked_pair_that_is_no_edge_of_the_mesh_is_ignored() {
    let mut m = flat_grid(3, 3);
    let plain = detect(&m, &FeatureOptions::default());
    // The other diagonal of a square, two vertices far apart, a vertex with itself, and a
    // vertex that does not exist.
    m.marked_edges = vec![[1, 4], [0, 15], [5, 5], [2, 99]];
    assert_eq!(detect(&m, &FeatureOptions::default()), plain);
}

#[test]
fn a_marked_edge_that_is_sharp_or_boundary_is_of_the_marked_kind() {
    // A cube edge, marked: one marked edge instead of a sharp one, the same curves.
    let mut m = cube();
    let plain = detect(&m, &FeatureOptions::default());
    let [a, b, _] = m.faces[0];
    m.marked_edges = vec![[b, a]];
    let f = detect(&m, &FeatureOptions::default());
    let topo = Topology::build(&m);
    let e = topo.find_edge(a, b).unwrap();
    let kind = f.edges[self_edge_index(&f.edges, e).unwrap()].1;
    let sharp = plain.edges[self_edge_index(&plain.edges, e).unwrap()].1;
    assert_eq!((sharp, kind), (FeatureKind::Sharp, FeatureKind::Marked));
    let c = f.counts();
    assert_eq!((c.sharp_edges, c.marked_edges), (11, 1));
    assert_eq!(
        (f.corners.clone(), f.curve_vertices.clone()),
        (plain.corners, plain.curve_vertices)
    );
    // A boundary edge of a plate, marked: the rim's curves as they were.
    let mut m = flat_grid(3, 3);
    let plain = detect(&m, &FeatureOptions::default());
    m.marked_edges = vec![[0, 1]];
    let f = detect(&m, &FeatureOptions::default());
    let c = f.counts();
    assert_eq!((c.boundary_edges, c.marked_edges), (11, 1));
    assert_eq!(
        (f.corners, f.curve_vertices),
        (plain.corners, plain.curve_vertices)
    );
    // Marked edges count whatever the options leave out.
    let none = FeatureOptions {
        angle_deg: 100.0,
        boundary: false,
        ..Default::default()
    };
    assert_eq!(detect(&m, &none).counts().marked_edges, 1);
}
