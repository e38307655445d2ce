//! The vertex sweep of [`relax`]: every vertex offered its moves, in index order.
//!
//! Big meshes sweep in [`PARTS`] spatial parts at once: each part's vertices whose whole
//! ring lies in the part move in index order, in parallel with the other parts (a move
//! reads and writes only the vertex's ring), then the vertices on the borders between
//! parts, a class of non-neighbours at a time (each class in parallel; the classes are
//! taken in vertex order). Neither the parts nor the classes depend on the thread count,
//! so neither does the result.

use super::*;

/// Meshes with at least this many vertices sweep in parts (smaller ones in one piece; the
/// bunny at 5000 vertices: a sweep 60 → 40 ms on two threads, 15 % of its vertices on the
/// parts' borders).
pub(crate) const PARTS_MIN: usize = 1 << 11;
/// Number of parts: 2³ cells of a median split along the widest axis, three levels deep.
pub(crate) const PARTS: usize = 8;

/// What a sweep reads besides the vertex positions.
pub(crate) struct Sweep<'a> {
    /// The faces of the mesh being relaxed.
    pub faces: &'a [[u32; 3]],
    /// Their adjacency.
    pub topo: &'a Topology,
    /// The two boundary neighbours of each boundary vertex (rail neighbours on a rail).
    pub ends: &'a [Vec<u32>],
    /// The corners that stay and the rails their vertices slide along.
    pub rails: &'a Rails,
    /// The input surface faces must agree with.
    pub surface: Option<&'a Surface<'a>>,
    /// The input points kept near the mesh.
    pub watch: Option<&'a Watch>,
    /// The stage's parameters.
    pub params: &'a RelaxParams,
    /// Cosine of `params.max_turn_deg`.
    pub cos_turn: f64,
}

/// What every sweep of one relaxation (and its polish) reads besides the mesh's faces,
/// adjacency and fidelity watch as they then are.
pub(crate) struct SweepShared<'a> {
    /// See [`Sweep::ends`].
    pub ends: &'a [Vec<u32>],
    /// See [`Sweep::rails`].
    pub rails: &'a Rails,
    /// See [`Sweep::surface`].
    pub surface: Option<&'a Surface<'a>>,
    /// See [`Sweep::params`].
    pub params: &'a RelaxParams,
    /// See [`Sweep::cos_turn`].
    pub cos_turn: f64,
}

impl SweepShared<'_> {
    /// A sweep over `faces` (adjacency `topo`, fidelity `watch`).
    pub(crate) fn over<'b>(
        &'b self,
        faces: &'b [[u32; 3]],
        topo: &'b Topology,
        watch: Option<&'b Watch>,
    ) -> Sweep<'b> {
        Sweep {
            faces,
            topo,
            ends: self.ends,
            rails: self.rails,
            surface: self.surface,
            watch,
            params: self.params,
            cos_turn: self.cos_turn,
        }
    }
}

/// Scratch buffers of one sweeper.
#[derive(Default)]
struct Scratch {
    normals: Vec<DVec3>,
    cands: Vec<DVec3>,
    tris: Vec<[DVec3; 3]>,
    ranked: Vec<((f64, f64), DVec3)>,
}

impl Sweep<'_> {
    /// One sweep over the vertices of a mesh with `positions`, in `parts` when given (see
    /// [`Parts::new`]); returns the moves kept.
    pub(crate) fn run(&self, positions: &mut [DVec3], parts: Option<&Parts>) -> usize {
        let Some(parts) = parts else {
            let mut sc = Scratch::default();
            let mut moved = 0;
            for v in 0..positions.len() as u32 {
                if let Some(q) = self.best_move(v, |w| positions[w as usize], &mut sc) {
                    positions[v as usize] = q;
                    moved += 1;
                }
            }
            return moved;
        };
        let border = parts.border(self.topo, positions.len());
        // Each part moves its inner vertices on a copy of its own positions.
        let moved_in_parts: Vec<(Vec<DVec3>, usize)> = parts
            .members
            .par_iter()
            .map(|members| {
                let mut local: Vec<DVec3> =
                    members.iter().map(|&v| positions[v as usize]).collect();
                let mut sc = Scratch::default();
                let mut moved = 0;
                for (i, &v) in members.iter().enumerate() {
                    if border[v as usize] {
                        continue;
                    }
                    let at = |w: u32| local[parts.slot[w as usize] as usize];
                    if let Some(q) = self.best_move(v, at, &mut sc) {
                        local[i] = q;
                        moved += 1;
                    }
                }
                (local, moved)
            })
            .collect();
        let mut moved = 0;
        for (members, (local, k)) in parts.members.iter().zip(moved_in_parts) {
            for (&v, p) in members.iter().zip(local) {
                positions[v as usize] = p;
            }
            moved += k;
        }
        // The border vertices class by class, each class's at once: no two of a class are
        // neighbours, so none reads where another of its class goes.
        for class in border_classes(self.topo, &border) {
            let to: Vec<(u32, DVec3)> = class
                .par_iter()
                .map_init(Scratch::default, |sc, &v| {
                    self.best_move(v, |w| positions[w as usize], sc)
                        .map(|q| (v, q))
                })
                .flatten_iter()
                .collect();
            moved += to.len();
            for (v, q) in to {
                positions[v as usize] = q;
            }
        }
        moved
    }

    /// Where vertex `v` goes, if one of its moves is kept (see the crate docs); `pos` gives
    /// the positions of `v` and its ring.
    fn best_move(
        &self,
        v: u32,
        pos: impl Fn(u32) -> DVec3 + Copy,
        sc: &mut Scratch,
    ) -> Option<DVec3> {
        let (params, cos_turn) = (self.params, self.cos_turn);
        let fan = self.topo.vertex_faces(v);
        if fan.is_empty() || self.topo.n_vertex_fans(v) != 1 {
            return None;
        }
        let p = pos(v);
        let place = self.targets(v, pos, &mut sc.normals, &mut sc.cands)?;
        // Inside, the targets are ranked where they are (off the input by its sag alone)
        // and placed on it one by one as they are tried: a projection is a walk of the
        // input's index, and most vertices keep their first candidate.
        let lazy = place.slide.is_none() && self.projecting().is_some();
        if !lazy {
            self.place_all(&place, &mut sc.cands);
        }
        let shape = |q: DVec3, cos: f64, normals: &[DVec3]| {
            fan_shape(self.faces, fan, v, q, pos, normals, cos)
        };
        let before = shape(p, -1.0, &sc.normals)?;
        // Capped smallest angle first, summed quality second (with `floor_deg` 0: the
        // smallest angle alone).
        let floor = params.floor_deg.to_radians();
        let better = |after: (f64, f64)| {
            if floor <= 0.0 {
                return after.0 > before.0;
            }
            let (x, y) = (after.0.min(floor), before.0.min(floor));
            x > y || (x == y && after.1 > before.1)
        };
        // Rank the improving candidates; the (costlier) input tests go in order.
        sc.ranked.clear();
        for &q in sc.cands.iter().filter(|q| q.is_finite() && **q != p) {
            if let Some(after) = shape(q, cos_turn, &sc.normals).filter(|&a| better(a)) {
                sc.ranked.push((after, q));
            }
        }
        sc.ranked.sort_by(|a, b| {
            let key = |s: (f64, f64)| (s.0.min(floor.max(0.0)), s.1);
            if floor <= 0.0 {
                b.0.0.total_cmp(&a.0.0)
            } else {
                let (x, y) = (key(a.0), key(b.0));
                y.0.total_cmp(&x.0).then(y.1.total_cmp(&x.1))
            }
        });
        for &(_, t) in &sc.ranked {
            let q = if lazy { self.place(&place, t) } else { t };
            let still = !lazy
                || (q.is_finite()
                    && q != p
                    && shape(q, cos_turn, &sc.normals).is_some_and(&better));
            if still && self.admits(v, q, pos, &mut sc.tris) {
                return Some(q);
            }
        }
        None
    }

    /// The input surface moves are placed on, when projecting.
    fn projecting(&self) -> Option<&Surface<'_>> {
        self.surface.filter(|_| self.params.project)
    }

    /// The moves offered to vertex `v` (one fan, `pos` the positions of it and its ring):
    /// fills `normals` with its faces' normals and `cands` with its candidate positions,
    /// best first, placed on the input when projecting (NaN where a boundary projection
    /// finds nothing). Returns where a target of `v` is placed (see [`Place`]), or `None`
    /// when `v` cannot move: a boundary vertex without two boundary neighbours, or an
    /// interior one whose faces have no area or no normal.
    pub(crate) fn moves(
        &self,
        v: u32,
        pos: impl Fn(u32) -> DVec3 + Copy,
        normals: &mut Vec<DVec3>,
        cands: &mut Vec<DVec3>,
    ) -> Option<Place> {
        let place = self.targets(v, pos, normals, cands)?;
        self.place_all(&place, cands);
        Some(place)
    }

    /// Places every target of `cands` (see [`Sweep::place`]).
    fn place_all(&self, place: &Place, cands: &mut [DVec3]) {
        for q in cands.iter_mut() {
            *q = self.place(place, *q);
        }
    }

    /// [`Sweep::moves`] with the candidates left where they aim, not yet placed.
    fn targets(
        &self,
        v: u32,
        pos: impl Fn(u32) -> DVec3 + Copy,
        normals: &mut Vec<DVec3>,
        cands: &mut Vec<DVec3>,
    ) -> Option<Place> {
        let (topo, params) = (self.topo, self.params);
        let fan = topo.vertex_faces(v);
        let corners = |f: u32| self.faces[f as usize].map(pos);
        let p = pos(v);
        normals.clear();
        cands.clear();
        let (mut sum, mut area, mut normal) = (DVec3::ZERO, 0.0, DVec3::ZERO);
        for &f in fan {
            let [a, b, c] = corners(f);
            let w = triangle::area(a, b, c);
            sum += w * triangle::centroid(a, b, c);
            area += w;
            normal += triangle::cross(a, b, c);
            normals.push(triangle::normal(a, b, c));
        }
        // Candidate positions, best first: the full move, then partial ones (on the
        // boundary or a rail: a third and two thirds of the way between the two
        // neighbours). A corner stays.
        let rail = match self.rails.role(v) {
            Role::Fixed => return None,
            Role::OnCurve(r) => Some(r),
            Role::Free => None,
        };
        let place = if rail.is_some() || topo.is_boundary_vertex(v) {
            let [u, w] = match self.ends[v as usize][..] {
                [u, w] => [u, w].map(pos),
                _ => return None,
            };
            let place = Place {
                from: p,
                slide: Some((u.distance(p) + w.distance(p)) * BOUNDARY_REACH),
                rail,
            };
            cands.extend([0.5, 1.0 / 3.0, 2.0 / 3.0].map(|s| p + params.step * (u.lerp(w, s) - p)));
            // A rail vertex also finer steps: its faces reach across to other rails.
            if rail.is_some() {
                let finer = [0.4, 0.6, 0.25, 0.75, 0.45, 0.55];
                cands.extend(finer.map(|s| p + params.step * (u.lerp(w, s) - p)));
            }
            place
        } else {
            let normal = normal.normalize_or_zero();
            if area <= 0.0 || normal == DVec3::ZERO {
                return None;
            }
            let d = sum / area - p;
            let d = d - d.dot(normal) * normal;
            // With `floor_deg`, also the mean of the neighbours (evens edge lengths).
            let ring = topo.vertex_neighbors(v);
            let mean = ring.iter().map(|&w| pos(w)).sum::<DVec3>() / ring.len().max(1) as f64;
            let l = mean - p;
            let l = l - l.dot(normal) * normal;
            let n_moves = if params.floor_deg > 0.0 { 5 } else { 3 };
            let moves = [d, 0.5 * d, 0.25 * d, l, 0.5 * l];
            cands.extend(moves.iter().take(n_moves).map(|&m| p + params.step * m));
            Place {
                from: p,
                slide: None,
                rail: None,
            }
        };
        Some(place)
    }

    /// Where `target` takes a vertex leaving `place.from`: onto the input surface (inside),
    /// along the input's boundary (on it) or onto its rail when projecting, else `target`
    /// itself (NaN where a boundary or rail projection finds nothing).
    pub(crate) fn place(&self, place: &Place, target: DVec3) -> DVec3 {
        match (self.projecting(), place.slide, place.rail) {
            (None, _, _) => target,
            (Some(_), Some(reach), Some(r)) => self.rails.project(r, place.from, target, reach),
            (Some(sf), None, _) => sf.project(target).unwrap_or(target),
            (Some(sf), Some(reach), None) => sf
                .project_boundary_along(place.from, target, reach)
                .unwrap_or(DVec3::NAN),
        }
    }

    /// Whether vertex `v` may go to `q` (`pos` the positions of it and its ring): none of
    /// its faces then faces away from the input, and the fidelity bound holds (`tris` is
    /// scratch).
    pub(crate) fn admits(
        &self,
        v: u32,
        q: DVec3,
        pos: impl Fn(u32) -> DVec3 + Copy,
        tris: &mut Vec<[DVec3; 3]>,
    ) -> bool {
        let fan = self.topo.vertex_faces(v);
        // The fan's corners with `v` at `q`.
        let moved_fan = || {
            fan.iter()
                .map(move |&f| self.faces[f as usize].map(|w| if w == v { q } else { pos(w) }))
        };
        self.surface
            .is_none_or(|s| moved_fan().all(|[a, b, c]| s.agrees(a, b, c)))
            && self.watch.is_none_or(|w| {
                tris.clear();
                tris.extend(moved_fan());
                w.allows(fan, tris) && self.chords_fit(v, q, pos, w.tol)
            })
    }

    /// Whether the boundary chords of boundary vertex `v` (to its two boundary
    /// neighbours) with `v` at `q` pass within `tol` of the input, or no farther from it
    /// than with `v` where it is (a chord over a bay of a hole's rim, which no input point
    /// near the mesh sees). True for other vertices.
    fn chords_fit(&self, v: u32, q: DVec3, pos: impl Fn(u32) -> DVec3, tol: f64) -> bool {
        let (Some(sf), &[a, b]) = (self.surface, &self.ends[v as usize][..]) else {
            return true;
        };
        if !self.topo.is_boundary_vertex(v) {
            return true;
        }
        let worst = |p: DVec3| {
            [a, b]
                .into_iter()
                .filter_map(|u| chord_far_point(sf, p, pos(u)))
                .fold(0.0, |m, (d, _)| f64::max(m, d))
        };
        let after = worst(q);
        after <= tol || after <= worst(pos(v))
    }
}

/// The vertices marked in `border` in classes of which no two are neighbours (in `topo`):
/// each, in ascending order, takes the first class none of its smaller neighbours took.
fn border_classes(topo: &Topology, border: &[bool]) -> Vec<Vec<u32>> {
    const NONE: u32 = u32::MAX;
    let mut class = vec![NONE; border.len()];
    let mut classes: Vec<Vec<u32>> = Vec::new();
    let mut taken: Vec<bool> = Vec::new();
    for v in (0..border.len() as u32).filter(|&v| border[v as usize]) {
        taken.clear();
        taken.resize(classes.len() + 1, false);
        for &w in topo.vertex_neighbors(v) {
            if let Some(&c) = class.get(w as usize).filter(|&&c| c != NONE) {
                taken[c as usize] = true;
            }
        }
        let c = taken.iter().position(|&t| !t).unwrap_or(classes.len());
        if c == classes.len() {
            classes.push(Vec::new());
        }
        class[v as usize] = c as u32;
        classes[c].push(v);
    }
    classes
}

/// Where the targets of a vertex's moves are placed (see [`Sweep::place`]).
pub(crate) struct Place {
    /// The vertex's position.
    from: DVec3,
    /// On the boundary or a rail: how far along it (arc length) a target may be looked for.
    slide: Option<f64>,
    /// The rail the vertex is on.
    rail: Option<u32>,
}

/// A fixed split of a mesh's vertices into [`PARTS`] spatial parts.
pub(crate) struct Parts {
    /// Each part's vertices, ascending.
    members: Vec<Vec<u32>>,
    /// Each vertex's place in its part's `members`.
    slot: Vec<u32>,
    /// Each vertex's part.
    part: Vec<u8>,
}

impl Parts {
    /// Splits `positions` at the median of the widest axis of each cell's points, three
    /// times (ties by index), when there are at least [`PARTS_MIN`] of them.
    pub(crate) fn new(positions: &[DVec3]) -> Option<Parts> {
        let n = positions.len();
        if n < PARTS_MIN {
            return None;
        }
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut cells = vec![&mut order[..]];
        while cells.len() < PARTS {
            let mut next = Vec::with_capacity(2 * cells.len());
            for cell in cells {
                let (lo, hi) = cell
                    .iter()
                    .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &v| {
                        (lo.min(positions[v as usize]), hi.max(positions[v as usize]))
                    });
                let axis = (hi - lo).max_position();
                let mid = cell.len() / 2;
                cell.select_nth_unstable_by(mid, |&a, &b| {
                    positions[a as usize][axis]
                        .total_cmp(&positions[b as usize][axis])
                        .then(a.cmp(&b))
                });
                let (l, r) = cell.split_at_mut(mid);
                next.extend([l, r]);
            }
            cells = next;
        }
        let mut part = vec![0u8; n];
        for (k, cell) in cells.iter().enumerate() {
            cell.iter().for_each(|&v| part[v as usize] = k as u8);
        }
        let mut members = vec![Vec::new(); PARTS];
        let mut slot = vec![0u32; n];
        for v in 0..n as u32 {
            let m = &mut members[part[v as usize] as usize];
            slot[v as usize] = m.len() as u32;
            m.push(v);
        }
        Some(Parts {
            members,
            slot,
            part,
        })
    }

    /// Whether each vertex has a neighbour (in `topo`) in another part.
    fn border(&self, topo: &Topology, n: usize) -> Vec<bool> {
        (0..n as u32)
            .map(|v| {
                let k = self.part[v as usize];
                topo.vertex_neighbors(v)
                    .iter()
                    .any(|&w| self.part[w as usize] != k)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// No two vertices of a class are neighbours, every marked vertex is in one class,
    /// and the classes are few (a vertex takes a class its neighbours left).
    #[test]
    fn border_classes_hold_no_two_neighbours() {
        let m = coarsen_shapes::icosphere(1.0, 3).unwrap();
        let topo = Topology::build(&m);
        let border: Vec<bool> = (0..m.n_vertices()).map(|v| v % 3 != 0).collect();
        let classes = border_classes(&topo, &border);
        let mut seen = vec![0; m.n_vertices()];
        for class in &classes {
            assert!(class.windows(2).all(|w| w[0] < w[1]));
            for &v in class {
                seen[v as usize] += 1;
                let nbrs = topo.vertex_neighbors(v);
                assert!(
                    class.iter().all(|w| !nbrs.contains(w)),
                    "{v} beside a classmate"
                );
            }
        }
        assert!((0..m.n_vertices()).all(|v| seen[v] == usize::from(border[v])));
        assert!(classes.len() <= 7, "{} classes", classes.len());
    }

    #[test]
    fn parts_cover_every_vertex_once_and_split_evenly() {
        let n = PARTS_MIN + 37;
        // Points on a spiral, so every axis matters.
        let pos: Vec<DVec3> = (0..n)
            .map(|i| {
                let t = i as f64 * 0.01;
                DVec3::new(t.cos() * (1.0 + t), t.sin(), 0.3 * t)
            })
            .collect();
        assert!(Parts::new(&pos[..PARTS_MIN - 1]).is_none());
        let parts = Parts::new(&pos).unwrap();
        let mut seen = vec![0; n];
        for (k, m) in parts.members.iter().enumerate() {
            assert!(m.windows(2).all(|w| w[0] < w[1]));
            assert!(m.len().abs_diff(n / PARTS) <= 1, "part {k}: {}", m.len());
            for (i, &v) in m.iter().enumerate() {
                seen[v as usize] += 1;
                assert_eq!(parts.part[v as usize] as usize, k);
                assert_eq!(parts.slot[v as usize] as usize, i);
            }
        }
        assert!(seen.iter().all(|&s| s == 1));
    }
}
