//! Mending faces that face away from the input: the vertices of such a face try nearby
//! points of the input where fewer of their faces do.

use super::*;

/// Rounds over the vertices of faces facing away, at most.
const ROUNDS: usize = 4;

/// What [`mend`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Mended {
    /// Faces facing away from the input before.
    pub before: usize,
    /// And after.
    pub after: usize,
    /// Vertices moved.
    pub moves: usize,
    /// Edges flipped.
    pub flips: usize,
}

/// Moves vertices of the faces of `mesh` (adjacency `topo`, boundary neighbours `ends`)
/// that face away from `surface` to points of the input where fewer of their faces face
/// away, none is degenerate and the smallest angle of their faces stays at least `floor`
/// (radians) or what it was (failing that, at least `smallest`); the best such point by faces facing away, then smallest
/// angle. Vertices in index order, a few rounds; corners and rail vertices (`rails`) stay,
/// and rail edges are not flipped.
pub(crate) fn mend(
    mesh: &mut Mesh,
    topo: &mut Topology,
    surface: &Surface<'_>,
    ends: &[Vec<u32>],
    rails: &Rails,
    floor: f64,
    smallest: f64,
) -> Mended {
    let mut away = facing_away_flags(mesh, surface);
    let before = away.iter().filter(|&&x| x).count();
    let mut out = Mended {
        before,
        after: before,
        moves: 0,
        flips: 0,
    };
    if before == 0 {
        return out;
    }
    let mender = Mender {
        surface,
        ends,
        rails,
        floor,
        smallest,
        tiny: 1e-10 * mesh.bbox().diagonal().powi(2),
    };
    for _ in 0..ROUNDS {
        let mut changed = false;
        for v in vertices_of_faces_away(mesh, &away) {
            if mender.move_vertex(mesh, topo, &mut away, v) {
                out.moves += 1;
                changed = true;
            }
        }
        let flips = mend_flips(mesh, topo, surface, rails, &mut away, mender.tiny, floor);
        if flips > 0 {
            out.flips += flips;
            changed = true;
            match Topology::try_build(mesh) {
                Ok(t) => *topo = t,
                Err(_) => break,
            }
        }
        if !changed {
            break;
        }
    }
    out.after = away.iter().filter(|&&x| x).count();
    out
}

/// For each face of `mesh`, whether it faces away from `surface`.
fn facing_away_flags(mesh: &Mesh, surface: &Surface<'_>) -> Vec<bool> {
    (0..mesh.n_faces())
        .into_par_iter()
        .map(|f| {
            let [a, b, c] = mesh.corners(f);
            !surface.agrees(a, b, c)
        })
        .collect()
}

/// The vertices of the faces flagged in `away`, in index order, each once.
fn vertices_of_faces_away(mesh: &Mesh, away: &[bool]) -> Vec<u32> {
    let mut verts: Vec<u32> = (0..mesh.n_faces())
        .filter(|&f| away[f])
        .flat_map(|f| mesh.faces[f])
        .collect();
    verts.sort_unstable();
    verts.dedup();
    verts
}

/// What [`mend`]'s vertex moves read: the surface, the ends, the rails and the bounds.
struct Mender<'a> {
    /// The input surface.
    surface: &'a Surface<'a>,
    /// The boundary (or rail) neighbours of each vertex.
    ends: &'a [Vec<u32>],
    /// The corners and rail vertices that stay.
    rails: &'a Rails,
    /// The angle (radians) up to which a fan keeps its smallest angle.
    floor: f64,
    /// The smallest angle (radians) a fan keeps when it cannot keep `floor`.
    smallest: f64,
    /// The area at or below which a face is degenerate.
    tiny: f64,
}

impl Mender<'_> {
    /// Moves `v` to a nearby input point where fewer of its faces face away, if any; true if so.
    fn move_vertex(&self, mesh: &mut Mesh, topo: &Topology, away: &mut [bool], v: u32) -> bool {
        let fan = topo.vertex_faces(v);
        if fan.is_empty() || topo.n_vertex_fans(v) != 1 || self.rails.locked(v) {
            return false;
        }
        let p = mesh.positions[v as usize];
        let Some(now) = self.score(mesh, fan, v, p) else {
            return false;
        };
        if now.0 == 0 {
            return false;
        }
        let cands = self.candidates(mesh, topo, v);
        let Some(q) = self.best(mesh, fan, v, now, &cands) else {
            return false;
        };
        mesh.positions[v as usize] = q;
        for &f in fan {
            let [a, b, c] = mesh.corners(f as usize);
            away[f as usize] = !self.surface.agrees(a, b, c);
        }
        true
    }

    /// (faces facing away, smallest angle) of `fan` with `v` at `q`; None if one is degenerate.
    fn score(&self, mesh: &Mesh, fan: &[u32], v: u32, q: DVec3) -> Option<(usize, f64)> {
        let pos = |w: u32| mesh.positions[w as usize];
        let mut n_away = 0;
        let mut worst = f64::INFINITY;
        for &f in fan {
            let [a, b, c] = mesh.faces[f as usize].map(|w| if w == v { q } else { pos(w) });
            if triangle::area(a, b, c) <= self.tiny {
                return None;
            }
            n_away += !self.surface.agrees(a, b, c) as usize;
            worst = worst.min(triangle::min_angle(a, b, c));
        }
        Some((n_away, worst))
    }

    /// The points of the input vertex `v` of `mesh` (adjacency `topo`) tries.
    fn candidates(&self, mesh: &Mesh, topo: &Topology, v: u32) -> Vec<DVec3> {
        let surface = self.surface;
        let fan = topo.vertex_faces(v);
        let pos = |w: u32| mesh.positions[w as usize];
        let p = pos(v);
        let ring = topo.vertex_neighbors(v);
        let mut cands: Vec<DVec3> = Vec::new();
        if topo.is_boundary_vertex(v) {
            for &w in &self.ends[v as usize] {
                for t in [0.25, 0.5] {
                    cands.extend(surface.project_boundary_along(
                        p,
                        p.lerp(pos(w), t),
                        BOUNDARY_REACH * p.distance(pos(w)),
                    ));
                }
            }
        } else {
            for &w in ring {
                for t in [0.25, 0.5] {
                    cands.extend(surface.project(p.lerp(pos(w), t)));
                }
            }
            for &f in fan {
                let [a, b, c] = mesh.faces[f as usize].map(pos);
                cands.extend(surface.project(triangle::centroid(a, b, c)));
            }
            let mean = ring.iter().map(|&w| pos(w)).sum::<DVec3>() / ring.len().max(1) as f64;
            cands.extend(surface.project(mean));
            // On a thin part the nearest side may be the wrong one: the nearest point
            // of the side the fan faces.
            cands.extend(surface.project_facing(p, mesh.faces_cross(fan)));
        }
        cands
    }

    /// The best of `cands` for `v` by [`mend`]'s rule, if one has fewer faces facing away.
    fn best(
        &self,
        mesh: &Mesh,
        fan: &[u32],
        v: u32,
        now: (usize, f64),
        cands: &[DVec3],
    ) -> Option<DVec3> {
        let p = mesh.positions[v as usize];
        let least = now.1.min(self.floor);
        let scored: Vec<((usize, f64), DVec3)> = cands
            .iter()
            .filter(|q| q.is_finite() && **q != p)
            .filter_map(|&q| self.score(mesh, fan, v, q).map(|s| (s, q)))
            .filter(|&((n, _), _)| n < now.0)
            .collect();
        // The fan's smallest angle kept (up to the floor); failing that, the mesh's.
        let best_above = |bound: f64| {
            scored
                .iter()
                .filter(|&&((_, a), _)| a >= bound)
                .min_by(|x, y| x.0.0.cmp(&y.0.0).then(y.0.1.total_cmp(&x.0.1)))
        };
        let best = best_above(least).or_else(|| best_above(least.min(self.smallest)));
        best.map(|&(_, q)| q)
    }
}

/// Flips the interior edges of faces facing away (flags `away`, updated) where the two new
/// faces have fewer facing away than the old, none degenerate (area ≤ `tiny`) and a
/// smallest angle of at least `floor` or what the old had; each face once. `topo` is
/// `mesh`'s adjacency before. Returns the flips made.
fn mend_flips(
    mesh: &mut Mesh,
    topo: &Topology,
    surface: &Surface<'_>,
    rails: &Rails,
    away: &mut [bool],
    tiny: f64,
    floor: f64,
) -> usize {
    let mut round = FlipRound::new(mesh, rails);
    let mut flips = 0;
    for f in 0..mesh.n_faces() {
        if !away[f] || round.touched(f) {
            continue;
        }
        for k in 0..3 {
            let t = mesh.faces[f];
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            if rails.is_rail_edge(a, b) {
                continue;
            }
            let Some(e) = topo.find_edge(a, b) else {
                continue;
            };
            let ef = topo.edge_faces(e);
            if ef.len() != 2 {
                continue;
            }
            let g = if ef[0] as usize == f { ef[1] } else { ef[0] } as usize;
            if round.touched(g) {
                continue;
            }
            // g holds b → a.
            let u = mesh.faces[g];
            let Some(i) = (0..3).find(|&i| u[i] == b && u[(i + 1) % 3] == a) else {
                continue;
            };
            let d = u[(i + 2) % 3];
            if c == d || round.has_edge(topo, c, d) {
                continue;
            }
            let p = |v: u32| mesh.positions[v as usize];
            let old = [[a, b, c], [b, a, d]];
            let new = [[a, d, c], [d, b, c]];
            let judge = |fs: &[[u32; 3]; 2]| -> Option<(usize, f64)> {
                let mut n_away = 0;
                let mut worst = f64::INFINITY;
                for t in fs {
                    let [x, y, z] = t.map(p);
                    if triangle::area(x, y, z) <= tiny {
                        return None;
                    }
                    n_away += !surface.agrees(x, y, z) as usize;
                    worst = worst.min(triangle::min_angle(x, y, z));
                }
                Some((n_away, worst))
            };
            let (Some(before), Some(after)) = (judge(&old), judge(&new)) else {
                continue;
            };
            if after.0 >= before.0 || after.1 < before.1.min(floor) {
                continue;
            }
            for (h, t) in [(f, new[0]), (g, new[1])] {
                let [x, y, z] = t.map(p);
                away[h] = !surface.agrees(x, y, z);
            }
            round.flip(mesh, [a, b], (f as u32, g as u32, c, d));
            flips += 1;
            break;
        }
    }
    flips
}
