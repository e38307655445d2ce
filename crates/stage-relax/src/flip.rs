//! Edge flips that raise the smallest angle (or, above the floor, the shape).

use super::*;

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
    let mut round = FlipRound::new(mesh.n_faces());
    let mut flips = 0;
    for e in 0..topo.n_edges() as u32 {
        let ef = topo.edge_faces(e);
        if ef.len() != 2 || round.touched(ef[0] as usize) || round.touched(ef[1] as usize) {
            continue;
        }
        let [a, b] = topo.edge(e);
        if rails.is_rail_edge(a, b) {
            continue;
        }
        // f1 holds a → b, f2 holds b → a.
        let rot = |f: u32, x: u32, y: u32| -> Option<u32> {
            let t = mesh.faces[f as usize];
            (0..3)
                .find(|&i| t[i] == x && t[(i + 1) % 3] == y)
                .map(|i| t[(i + 2) % 3])
        };
        let (c, d) = match (rot(ef[0], a, b), rot(ef[1], b, a)) {
            (Some(c), Some(d)) => (c, d),
            _ => match (rot(ef[1], a, b), rot(ef[0], b, a)) {
                (Some(c), Some(d)) => (c, d),
                _ => continue,
            },
        };
        if c == d || round.has_edge(topo, c, d) {
            continue;
        }
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
                !w.allows(ef, &tris)
            })
        {
            continue;
        }
        let (f1, f2) = (ef[0] as usize, ef[1] as usize);
        let (g1, g2) = if rot(ef[0], a, b) == Some(c) {
            (f1, f2)
        } else {
            (f2, f1)
        };
        mesh.faces[g1] = new[0];
        mesh.faces[g2] = new[1];
        round.flipped([f1, f2], c, d);
        flips += 1;
    }
    flips
}

/// What one round of flips has done so far: the faces flipped (each at most once a
/// round) and the edges made, which its adjacency from before the round does not know.
pub(crate) struct FlipRound {
    touched: Vec<bool>,
    added: std::collections::HashSet<[u32; 2]>,
}

impl FlipRound {
    /// A round over `n_faces` faces, nothing flipped yet.
    pub(crate) fn new(n_faces: usize) -> Self {
        FlipRound {
            touched: vec![false; n_faces],
            added: std::collections::HashSet::new(),
        }
    }

    /// Whether face `f` was flipped this round.
    pub(crate) fn touched(&self, f: usize) -> bool {
        self.touched[f]
    }

    /// Whether `c`–`d` is an edge: in `topo` (from before the round) or made this round.
    pub(crate) fn has_edge(&self, topo: &Topology, c: u32, d: u32) -> bool {
        topo.find_edge(c, d).is_some() || self.added.contains(&[c.min(d), c.max(d)])
    }

    /// Records that faces `faces` were flipped into the new edge `c`–`d`.
    pub(crate) fn flipped(&mut self, faces: [usize; 2], c: u32, d: u32) {
        faces.iter().for_each(|&f| self.touched[f] = true);
        self.added.insert([c.min(d), c.max(d)]);
    }
}
