use super::*;
use proptest::prelude::*;

/// A closed tetrahedron, outward.
fn tetrahedron() -> Editable {
    Editable::new(4, vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
}

/// A `n` × `n` grid of squares, two triangles each, with its vertices `(n + 1)²`.
fn grid(n: u32) -> Editable {
    let mut faces = Vec::new();
    let at = |i: u32, j: u32| i * (n + 1) + j;
    for i in 0..n {
        for j in 0..n {
            faces.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            faces.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    Editable::new(((n + 1) * (n + 1)) as usize, faces).with_edges()
}

/// The lists and edge counts built afresh from the alive faces of `e`.
fn fresh(e: &Editable) -> Editable {
    let mut faces = e.faces().to_vec();
    let alive: Vec<bool> = (0..faces.len() as u32).map(|f| e.is_alive(f)).collect();
    // Dead slots stay dead: rebuild with them, then kill them.
    let mut out = Editable::new(e.n_vertices(), std::mem::take(&mut faces)).with_edges();
    for (f, a) in alive.into_iter().enumerate() {
        if !a {
            out.replace_face(f as u32, None);
        }
    }
    out
}

#[test]
fn an_interior_edge_of_a_grid_collapses_and_its_faces_die() {
    let mut g = grid(4);
    // Vertex 6 (row 1, column 1) into 7: both interior.
    assert_eq!(g.can_collapse(6, 7, Rules::default()), Ok(()));
    let freed = g.collapse(7, 6);
    assert_eq!(freed.len(), 2);
    assert!(g.faces_around(6).is_empty());
    assert!(g.alive_faces().all(|f| !f.contains(&6)));
    assert_eq!(g.faces_around(7), fresh(&g).faces_around(7));
    assert_eq!(g.edges(), fresh(&g).edges());
}

#[test]
fn the_link_condition_refuses_to_pinch_a_tetrahedron() {
    // Every pair of ends has the other two as common neighbours, both opposite the edge:
    // the faces off the edge, renamed, fold onto each other.
    let t = tetrahedron();
    assert_eq!(t.can_collapse(0, 1, Rules::default()), Err(Refusal::Link));
    assert_eq!(t.can_collapse(2, 3, Rules::default()), Err(Refusal::Link));
    assert_eq!(t.n_fans(0), 1);
    assert!(!t.is_boundary_vertex(0));
}

#[test]
fn a_common_neighbour_off_the_edge_fails_the_link_condition() {
    // Edge 0–1 has one face (0 1 4); 0 and 1 also share the neighbours 2 and 3.
    let e = Editable::new(5, vec![[0, 1, 4], [0, 2, 3], [1, 3, 2]]);
    assert_eq!(e.can_collapse(0, 1, Rules::default()), Err(Refusal::Link));
}

#[test]
fn vertices_sharing_no_face_are_no_edge() {
    let g = grid(2);
    assert_eq!(
        g.can_collapse(0, 8, Rules::default()),
        Err(Refusal::NotAnEdge)
    );
}

#[test]
fn an_interior_edge_between_two_boundary_vertices_is_a_bridge() {
    // A strip one square wide: the diagonal of each square joins the two sides.
    let mut faces = Vec::new();
    for i in 0..4u32 {
        faces.push([i, i + 5, i + 6]);
        faces.push([i, i + 6, i + 1]);
    }
    let s = Editable::new(10, faces);
    assert_eq!(s.can_collapse(1, 7, Rules::default()), Err(Refusal::Bridge));
    // A boundary edge along the side may go.
    assert_eq!(s.can_collapse(1, 2, Rules::default()), Ok(()));
}

#[test]
fn a_lone_triangle_is_a_loop_of_three_and_would_leave_a_vertex() {
    let t = Editable::new(3, vec![[0, 1, 2]]);
    assert_eq!(t.can_collapse(0, 1, Rules::default()), Ok(()));
    let loops = Rules {
        loops_of_three: true,
        ..Rules::default()
    };
    assert_eq!(t.can_collapse(0, 1, loops), Err(Refusal::LoopOfThree));
    let kept = Rules {
        every_vertex_kept: true,
        ..Rules::default()
    };
    assert_eq!(t.can_collapse(0, 1, kept), Err(Refusal::VertexLeft));
    assert_eq!(t.boundary_neighbors(0), vec![1, 2]);
}

#[test]
fn two_fans_at_a_vertex_are_counted() {
    // Two triangles meeting at vertex 0 only (a bow-tie).
    let e = Editable::new(5, vec![[0, 1, 2], [0, 3, 4]]);
    assert_eq!(e.n_fans(0), 2);
    let rules = Rules {
        one_fan: true,
        ..Rules::default()
    };
    assert_eq!(e.can_collapse(0, 1, rules), Err(Refusal::NotOneFan));
}

#[test]
fn pushed_faces_and_vertices_join_the_lists() {
    let mut e = Editable::new(3, vec![[0, 1, 2]]).with_edges();
    let v = e.add_vertex();
    assert_eq!(v, 3);
    let f = e.push_face([0, 2, 3]);
    assert_eq!(f, 1);
    assert_eq!(e.faces_around(0), &[0, 1]);
    assert_eq!(e.faces_around(3), &[1]);
    assert_eq!(e.edges().unwrap().get(&[0, 2]), Some(&2));
    assert!(!e.is_boundary_edge(0, 2));
    assert_eq!(e.edges(), fresh(&e).edges());
}

proptest! {
    /// Any sequence of allowed collapses on a grid keeps the lists and edge counts what
    /// building them afresh gives, and the mesh a manifold disc (one fan everywhere,
    /// Euler characteristic 1).
    #[test]
    fn collapses_keep_the_tables_true_and_the_disc_a_disc(
        picks in proptest::collection::vec((0u32..36, 0usize..6), 1..40)
    ) {
        let mut g = grid(5);
        let rules = Rules {
            one_fan: true,
            loops_of_three: true,
            every_vertex_kept: true,
        };
        for (v, k) in picks {
            let n = g.neighbors(v);
            if n.is_empty() {
                continue;
            }
            let w = n[k % n.len()];
            if g.can_collapse(w, v, rules).is_ok() {
                g.collapse(w, v);
            }
        }
        let f = fresh(&g);
        for v in 0..g.n_vertices() as u32 {
            prop_assert_eq!(g.faces_around(v), f.faces_around(v));
            if !g.faces_around(v).is_empty() {
                prop_assert_eq!(g.n_fans(v), 1);
            }
        }
        prop_assert_eq!(g.edges(), f.edges());
        let nv = (0..g.n_vertices() as u32).filter(|&v| !g.faces_around(v).is_empty()).count();
        let ne = g.edges().unwrap().len();
        let nf = g.alive_faces().count();
        prop_assert_eq!(nv as i64 - ne as i64 + nf as i64, 1);
    }
}

#[test]
fn a_flip_turns_the_shared_edge_and_keeps_the_slots() {
    // Square 0 1 2 3 split along 0–2.
    let mut e = Editable::new(4, vec![[0, 1, 2], [0, 2, 3]]).with_edges();
    let parts = e.flip_parts(0, 2).unwrap();
    assert_eq!(parts, (1, 0, 3, 1));
    let new = e.flip([0, 2], parts);
    assert_eq!(new, [[0, 1, 3], [1, 2, 3]]);
    assert_eq!(e.face(1), [0, 1, 3]);
    assert_eq!(e.face(0), [1, 2, 3]);
    assert!(e.edges().unwrap().get(&[0, 2]).is_none());
    assert_eq!(e.edges().unwrap().get(&[1, 3]), Some(&2));
    assert_eq!(e.edges(), fresh(&e).edges());
    let tracked: Vec<([u32; 2], u32)> = e.edges().unwrap().iter().map(|(&k, &n)| (k, n)).collect();
    assert_eq!(e.edges_now(), tracked);
    assert!(e.has_edge(3, 1) && !e.has_edge(0, 2));
    assert!(e.flip_parts(0, 1).is_none(), "a boundary edge has one face");
}

#[test]
fn a_split_edge_makes_four_faces_in_the_old_and_reused_slots() {
    // Square 0 1 2 3 split along 0–2; vertex 4 is free.
    let mut e = Editable::new(5, vec![[0, 1, 2], [0, 2, 3], [4, 4, 4]]).with_edges();
    e.replace_face(2, None);
    assert_eq!(e.split_edge([0, 2], 1, [None, None]), None, "1 has faces");
    assert_eq!(
        e.split_edge([0, 1], 4, [None, None]),
        None,
        "a boundary edge"
    );
    assert_eq!(
        e.split_edge([0, 2], 4, [Some(0), None]),
        None,
        "slot 0 is alive"
    );
    // g = 2 → 0 → 1 (face 0), h = 0 → 2 → 3 (face 1).
    let slots = e.split_edge([2, 0], 4, [Some(2), None]).unwrap();
    assert_eq!(slots, [0, 1, 2, 3]);
    assert_eq!(e.face(0), [2, 4, 1]);
    assert_eq!(e.face(1), [4, 0, 1]);
    assert_eq!(e.face(2), [0, 4, 3]);
    assert_eq!(e.face(3), [4, 2, 3]);
    assert!(!e.has_edge(0, 2));
    assert_eq!(e.faces_around(4), &[0, 1, 2, 3]);
    assert_eq!(e.n_fans(4), 1);
    assert!(!e.is_boundary_vertex(4));
    assert_eq!(e.edges(), fresh(&e).edges());
    for v in 0..5 {
        assert_eq!(e.faces_around(v), fresh(&e).faces_around(v));
    }
}

#[test]
fn constraints_hold_fixed_and_curve_vertices_and_curve_edges() {
    // The 2 × 2 grid: vertices 0..9, centre 4. Curve 0 runs 3 → 4 → 5 across the middle;
    // corner 0 is fixed.
    let mut c = Constraints::new(9);
    c.fix(0);
    c.bind(4, 0, [3, 5]);
    c.bind(3, 0, [4, 4]);
    c.bind(5, 0, [4, 4]);
    c.add_curve_edge(3, 4, 0);
    c.add_curve_edge(4, 5, 0);
    assert!(!c.is_empty());
    let mut g = grid(2).with_constraints(c);
    assert_eq!(
        g.can_collapse(1, 0, Rules::default()),
        Err(Refusal::Constrained)
    );
    assert_eq!(
        g.can_collapse(4, 7, Rules::default()),
        Err(Refusal::Constrained)
    );
    assert_eq!(g.can_collapse(1, 2, Rules::default()), Ok(()));
    assert!(g.flip_parts(4, 5).is_none(), "a curve edge is not flipped");
    assert!(g.flip_parts(4, 8).is_some());
    // Splitting curve edge 4–5 at a new vertex puts it on the curve between them.
    let m = g.add_vertex();
    assert!(g.split_edge([4, 5], m, [None, None]).is_some());
    let c = g.constraints();
    assert_eq!(c.role(m), Role::OnCurve(0));
    assert_eq!(c.curve_ends(m), Some([4, 5]));
    assert_eq!(c.curve_ends(4), Some([3, m]));
    assert!(!c.is_curve_edge(4, 5));
    assert!(c.is_curve_edge(4, m) && c.is_curve_edge(m, 5));
    assert_eq!(
        g.can_collapse(m, 4, Rules::default()),
        Err(Refusal::Constrained)
    );
    assert!(Constraints::new(3).is_empty());
}
