//! Edge flips that raise the smallest angle (or, above the floor, the shape).

use super::*;
use coarsen_edit::Editable;

/// One sweep of edge flips over `mesh` (in edge order, each face flipped at most once):
/// the interior edge a–b of faces abc and bad becomes c–d when the smallest angle of the
/// two faces grows, c–d is not an edge yet, neither new face turns by more than `cos_turn`
/// from the face it replaces, both agree with `surface`, and the input points `watch` keeps
/// near the two faces stay near the new ones; rail edges (`rails`) stay. `topo` is `mesh`'s
/// adjacency before the sweep.
/// Returns the flips made.
pub(crate) fn flip_sweep(
    mesh: &mut Mesh,
    topo: &Topology,
    surface: Option<&Surface<'_>>,
    rails: &Rails,
    watch: Option<&Watch>,
    cos_turn: f64,
    floor: f64,
) -> usize {
    let mut round = FlipRound::new(mesh, rails);
    let mut flips = 0;
    for e in 0..topo.n_edges() as u32 {
        let [a, b] = topo.edge(e);
        // f1 holds a → b, f2 holds b → a (no rail edge: the round's constraints).
        let Some(parts) = round.edit.flip_parts(a, b) else {
            continue;
        };
        let (f1, f2, c, d) = parts;
        if round.touched(f1 as usize) || round.touched(f2 as usize) {
            continue;
        }
        if c == d || round.has_edge(topo, c, d) {
            continue;
        }
        let ef = [f1, f2];
        let p = |v: u32| mesh.positions[v as usize];
        let old = [[a, b, c], [b, a, d]];
        let new = [[a, d, c], [d, b, c]];
        let worst = |fs: &[[u32; 3]; 2]| {
            fs.iter()
                .map(|f| triangle::min_angle(p(f[0]), p(f[1]), p(f[2])))
                .fold(f64::INFINITY, f64::min)
        };
        // With a floor: the smallest angle capped at it first, summed quality second.
        let (w_new, w_old) = (worst(&new), worst(&old));
        let better = if floor > 0.0 && w_new.min(floor) == w_old.min(floor) {
            let sum_q = |fs: &[[u32; 3]; 2]| {
                fs.iter()
                    .map(|f| triangle::quality(p(f[0]), p(f[1]), p(f[2])))
                    .sum::<f64>()
            };
            sum_q(&new) > sum_q(&old)
        } else if floor > 0.0 {
            w_new.min(floor) > w_old.min(floor)
        } else {
            w_new > w_old
        };
        if !better {
            continue;
        }
        let n_old = [0, 1].map(|i| triangle::normal(p(old[i][0]), p(old[i][1]), p(old[i][2])));
        let ok = new.iter().all(|f| {
            let n = triangle::normal(p(f[0]), p(f[1]), p(f[2]));
            n_old.iter().all(|o| n.dot(*o) >= cos_turn)
                && surface.is_none_or(|s| s.agrees(p(f[0]), p(f[1]), p(f[2])))
        });
        if !ok
            || watch.is_some_and(|w| {
                let tris = new.map(|f| f.map(p));
                !w.allows(&ef, &tris)
            })
        {
            continue;
        }
        round.flip(mesh, [a, b], parts);
        flips += 1;
    }
    flips
}

/// What one round of flips has done so far: the mesh's faces as an [`Editable`] that
/// follows the flips, and the faces flipped (each at most once a round). An edge counts
/// as there when the adjacency from before the round has it or the round made it.
pub(crate) struct FlipRound {
    /// The faces, flipped as the round goes.
    pub(crate) edit: Editable,
    touched: Vec<bool>,
}

impl FlipRound {
    /// A round over the faces of `mesh`, nothing flipped yet, no rail edge of `rails`
    /// flippable.
    pub(crate) fn new(mesh: &Mesh, rails: &Rails) -> Self {
        FlipRound {
            edit: Editable::new(mesh.n_vertices(), mesh.faces.clone())
                .with_constraints(rails.constraints().clone()),
            touched: vec![false; mesh.n_faces()],
        }
    }

    /// Whether face `f` was flipped this round.
    pub(crate) fn touched(&self, f: usize) -> bool {
        self.touched[f]
    }

    /// Whether `c`–`d` is an edge: in `topo` (from before the round) or made this round.
    pub(crate) fn has_edge(&self, topo: &Topology, c: u32, d: u32) -> bool {
        topo.find_edge(c, d).is_some() || self.edit.has_edge(c, d)
    }

    /// Flips edge `a`–`b` (its [`Editable::flip_parts`]) in the round's faces and in
    /// `mesh`'s, and marks its two faces.
    pub(crate) fn flip(&mut self, mesh: &mut Mesh, ab: [u32; 2], parts: (u32, u32, u32, u32)) {
        let new = self.edit.flip(ab, parts);
        let (g, h, _, _) = parts;
        mesh.faces[g as usize] = new[0];
        mesh.faces[h as usize] = new[1];
        self.touched[g as usize] = true;
        self.touched[h as usize] = true;
    }
}
