//! Pulling a dual's vertices onto the run's input: the interior onto its surface, the
//! boundary onto its boundary, each move undone where it would spoil a face.

use super::*;

/// Which vertices [`pull_onto_input`] moves, and how far a move must be to count.
#[derive(Clone, Copy, Debug)]
pub struct Pull<'a> {
    /// Points on or near the input's boundary to start each boundary vertex's projection
    /// from (the nearest of them names the loop, through its own nearest boundary point);
    /// boundary vertices stay when empty.
    pub rim: &'a [DVec3],
    /// Move the interior vertices too (onto the nearest point of the input surface).
    pub interior: bool,
    /// A vertex moves only when its new place is farther than this from where it is.
    pub min_move: f64,
}

/// What [`pull_onto_input`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Pulled {
    /// Vertices moved.
    pub moved: usize,
    /// Boundary vertices left off the input's boundary (farther than 10⁻⁹ of its diagonal):
    /// sent back where their move would spoil a face.
    pub boundary_left: usize,
}

/// Pulls the vertices of `mesh` that `pull` names onto the input `facing` indexes: interior
/// vertices onto the nearest point of its surface, boundary vertices onto its boundary,
/// along the loop of the nearest `rim` point (the nearest point of the whole boundary may
/// lie on another loop or across a bay of this one). A vertex whose move would turn one of
/// its faces over, flatten it (area at most 10⁻¹² of `diag2`, the input's squared
/// diagonal) or make it face away from the input goes back: first the farthest moved
/// vertex of each such face, round by round (undoing one move can fix its face, or expose
/// a neighbour's), then all moved vertices of the faces still spoilt (a few rounds each).
/// Returns what moved and what was left, or `None`, leaving the mesh as it came, when the
/// moves would leave a mesh that fails the sanity check.
pub fn pull_onto_input(
    mesh: &mut Mesh,
    topo: &Topology,
    facing: &Facing<'_>,
    pull: Pull<'_>,
    diag2: f64,
) -> Option<Pulled> {
    let before = mesh.clone();
    let rim_index = (!pull.rim.is_empty()).then(|| {
        let points: Vec<[u32; 3]> = (0..pull.rim.len() as u32).map(|i| [i, i, i]).collect();
        Bvh::build(pull.rim, &points)
    });
    let onto_rim = |p: DVec3| {
        let from = rim_index.as_ref()?.closest_point(p)?;
        facing.project_boundary_along(from.point, p, 4.0 * from.distance())
    };
    let mut moved: Vec<bool> = mesh
        .positions
        .par_iter_mut()
        .enumerate()
        .map(|(v, pos)| {
            let to = match topo.is_boundary_vertex(v as u32) {
                true => onto_rim(*pos),
                false if pull.interior => facing.bvh().closest_point(*pos).map(|h| h.point),
                false => None,
            };
            match to {
                Some(q)
                    if q != *pos && (pull.min_move == 0.0 || q.distance(*pos) > pull.min_move) =>
                {
                    *pos = q;
                    true
                }
                _ => false,
            }
        })
        .collect();
    // Faces to look at: all at first, then those with a vertex just sent back (the others
    // are as they were). For the first rounds a spoilt face sends back only the vertex of
    // it that moved farthest (two boundary vertices of one face may each fit alone), the
    // later ones every vertex of it that moved.
    let mut look = vec![true; mesh.n_vertices()];
    for round in 0..16 {
        let one = round < 8;
        let undo: Vec<u32> = (0..mesh.n_faces())
            .into_par_iter()
            .filter(|&f| mesh.faces[f].iter().any(|&v| look[v as usize]))
            .filter(|&f| {
                let [a, b, c] = mesh.corners(f);
                mesh.face_normal(f).dot(before.face_normal(f)) <= 0.0
                    || coarsen_geom::triangle::area(a, b, c) <= 1e-12 * diag2
                    || facing.faces_away(a, b, c)
            })
            .flat_map_iter(|f| {
                let movers = mesh.faces[f].into_iter().filter(|&v| moved[v as usize]);
                let far = |v: u32| {
                    mesh.positions[v as usize].distance_squared(before.positions[v as usize])
                };
                match one {
                    // The farthest moved, the lowest index of equals.
                    true => movers
                        .max_by(|&a, &b| far(a).total_cmp(&far(b)).then(b.cmp(&a)))
                        .into_iter()
                        .collect::<Vec<_>>(),
                    false => movers.collect(),
                }
            })
            .collect();
        if undo.is_empty() {
            break;
        }
        look.iter_mut().for_each(|l| *l = false);
        for v in undo {
            mesh.positions[v as usize] = before.positions[v as usize];
            moved[v as usize] = false;
            look[v as usize] = true;
        }
    }
    if coarsen_mesh::sanity::sanity_check(mesh).is_err() {
        *mesh = before;
        return None;
    }
    Some(Pulled {
        moved: moved.iter().filter(|&&m| m).count(),
        boundary_left: (0..mesh.n_vertices())
            .filter(|&v| rim_index.is_some() && !moved[v] && topo.is_boundary_vertex(v as u32))
            .filter(|&v| {
                let p = mesh.positions[v];
                facing
                    .project_boundary(p)
                    .is_some_and(|q| q.distance_squared(p) > 1e-18 * diag2)
            })
            .count(),
    })
}
