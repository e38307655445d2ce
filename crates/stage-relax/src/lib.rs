//! The `relax` stage (beyond the papers): a few sweeps of tangential relaxation that lift
//! the worst triangles of a coarse mesh, keeping its vertex count and topology.
//!
//! In each sweep every vertex, in index order, is offered a few moves: an interior vertex
//! towards the area-weighted centroid of its ring of faces, within its tangent plane
//! (`step`, half and a quarter of the way), then onto the nearest point of the run's input
//! surface when `project` is on; a boundary vertex towards the middle (or the thirds) of
//! the segment between its two boundary neighbours, then onto the nearest point of the
//! input's boundary edges. The best move is kept only when the smallest angle of the vertex's faces grows,
//! none of them turns by more than `max_turn_deg`, and (when projecting) none faces away
//! from the input normal nearest its centroid — so the mesh's minimum angle never drops, no
//! face flips, and every vertex stays on the input surface. Deterministic (one thread,
//! fixed order).
//!
//! With `flips`, each sweep first flips the interior edges whose two faces get a larger
//! smallest angle that way (same guards: no new edge duplicating one, no face turned by
//! more than `max_turn_deg`, none facing away from the input); the vertex count and the
//! topology stay.
//!
//! With `floor_deg` > 0 both vertex moves and flips rank by the smallest angle capped at
//! that floor first and the summed quality of the faces second (interior vertices are also
//! offered the mean of their neighbours): above the floor, angle is traded for shape, so the
//! mean angle and quality rise while the smallest angle never ends below the floor or where
//! it started.
//!
//! With `rebalance` > 0, before the sweeps, pairs of one split and one collapse move
//! vertices from short edges to long ones: the longest interior edges (those joining two
//! boundary vertices first: the slivers of a narrow strip between two holes) are split at
//! their midpoint on the input, and for each the shortest edge that can go (link condition,
//! boundary loops kept, no face turned or facing away, no angle below the floor or what it
//! had) is collapsed; its vertex index is reused, so the vertex count stays exact and
//! attributes follow through `Mesh::rebuilt`.
//!
//! With `fit` > 0, after rebalancing, the input points farthest from the mesh (its
//! vertices, edge midpoints and points inside its faces; beyond `max_dev_pct` when set) get
//! a vertex: a split at that point paired with the collapse that moves the surface least
//! elsewhere, or a nearby vertex pulled there; new angles may dip to 0.8 of the floor (or of
//! the smallest angle) for the sweeps to lift.
//!
//! With `max_dev_pct` > 0 the sweeps keep fidelity: a move or a flip is refused when an
//! input point near the faces it changes would end farther than that bound from them (or,
//! if already farther, farther than it was).
//!
//! The report gives `moved` (moves kept, per sweep), `flipped` (edges flipped, per sweep),
//! `rebalanced` (split/collapse pairs), `fitted` (fidelity edits, when `fit` is on) and
//! `min_angle_before` / `min_angle_after` in degrees.

use coarsen_geom::{DVec3, triangle};
use coarsen_mesh::{FaceOrigins, Topology, VertexOrigins};
use coarsen_metrics::{Facing, SurfaceIndex};
use coarsen_spatial::{Bvh, closest_point_on_segment, closest_point_on_triangle};
use coarsen_stage::{
    Context, Contract, Mesh, Needs, ParamIssue, Params, Stage, StageError, params,
};
use rayon::prelude::*;
use std::sync::Arc;

params! {
    /// Parameters of `relax`.
    pub struct RelaxParams {
        /// Sweeps over the vertices.
        pub sweeps: u32 = 4,
        /// Fraction of the way to the ring centroid tried in each move.
        pub step: f64 = 1.0,
        /// Pull each moved vertex onto the nearest point of the run's input surface.
        pub project: bool = true,
        /// A move is refused if it turns a face normal by more than this many degrees.
        pub max_turn_deg: f64 = 30.0,
        /// Also flip interior edges where that raises the smallest angle of their two faces.
        pub flips: bool = true,
        /// Angle (degrees) above which moves and flips may trade smallest angle for shape:
        /// one is kept when it raises the smallest angle capped at this value, or keeps that
        /// and raises the summed quality of its faces. 0 = smallest angle only.
        pub floor_deg: f64 = 0.0,
        /// At most this many rebalancing pairs before the sweeps: each splits a long edge
        /// joining two boundary points (a narrow strip between holes gets a middle row) and
        /// collapses a short edge elsewhere, so the vertex count stays. 0 = none.
        pub rebalance: u32 = 0,
        /// At most this many fidelity edits before the sweeps (after rebalancing): where the
        /// input lies farthest from the mesh (beyond `max_dev_pct`) a new vertex goes there
        /// and an edge is collapsed where that moves the surface least, or a nearby vertex
        /// is pulled there; the vertex count stays. 0 = none.
        pub fit: u32 = 0,
        /// Moves and flips may not leave a point of the input farther than this from the
        /// mesh (percent of the input's bounding-box diagonal), nor one already farther,
        /// farther still; `fit` works on the points beyond it. 0 = no bound.
        pub max_dev_pct: f64 = 0.0,
    }
}

impl Params for RelaxParams {
    fn validate(&self) -> Vec<ParamIssue> {
        let mut v = Vec::new();
        coarsen_stage::params::check_range(&mut v, "sweeps", self.sweeps, 0, 1000);
        coarsen_stage::params::check_range(&mut v, "step", self.step, 0.0, 1.0);
        coarsen_stage::params::check_range(&mut v, "max_turn_deg", self.max_turn_deg, 0.0, 90.0);
        coarsen_stage::params::check_range(&mut v, "floor_deg", self.floor_deg, 0.0, 60.0);
        coarsen_stage::params::check_range(&mut v, "rebalance", self.rebalance, 0, 100_000);
        coarsen_stage::params::check_range(&mut v, "fit", self.fit, 0, 100_000);
        coarsen_stage::params::check_range(&mut v, "max_dev_pct", self.max_dev_pct, 0.0, 100.0);
        v
    }
}

/// What [`relax`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Relaxed {
    /// Moves kept in each sweep.
    pub moved: Vec<usize>,
    /// Edges flipped in each sweep.
    pub flipped: Vec<usize>,
    /// Rebalancing pairs made (one split and one collapse each).
    pub rebalanced: usize,
    /// Fidelity edits made (split/collapse pairs at far input points, and pulls).
    pub fitted: usize,
    /// Smallest angle of the mesh before, in degrees.
    pub min_angle_before: f64,
    /// Smallest angle of the mesh after, in degrees.
    pub min_angle_after: f64,
}

/// Smallest angle (radians) and summed quality of the faces `fan` of `mesh`, with vertex
/// `v` at `p`; `None` when a face normal turns beyond `cos_turn` from `normals`.
fn fan_shape(
    mesh: &Mesh,
    fan: &[u32],
    v: u32,
    p: DVec3,
    normals: &[DVec3],
    cos_turn: f64,
) -> Option<(f64, f64)> {
    let mut worst = f64::INFINITY;
    let mut sum = 0.0;
    for (i, &f) in fan.iter().enumerate() {
        let [a, b, c] = mesh.faces[f as usize].map(|w| {
            if w == v {
                p
            } else {
                mesh.positions[w as usize]
            }
        });
        let n = triangle::normal(a, b, c);
        if n.dot(normals[i]) < cos_turn {
            return None;
        }
        worst = worst.min(triangle::min_angle(a, b, c));
        sum += triangle::quality(a, b, c);
    }
    Some((worst, sum))
}

/// The surface vertices are kept on: the input mesh, its face index and its boundary edges.
pub struct Surface<'a> {
    mesh: &'a Mesh,
    facing: Facing<'a>,
    boundary: Vec<[DVec3; 2]>,
}

impl<'a> Surface<'a> {
    /// Indexes `mesh` (its faces and boundary edges).
    pub fn new(mesh: &'a Mesh) -> Self {
        Surface::with_index(mesh, Arc::new(SurfaceIndex::new(mesh)))
    }

    /// `mesh` with its index built earlier by [`SurfaceIndex::new`] from the same mesh.
    pub fn with_index(mesh: &'a Mesh, index: Arc<SurfaceIndex>) -> Self {
        let facing = Facing::with_index(mesh, index);
        let t = facing.topology();
        let boundary = (0..t.n_edges() as u32)
            .filter(|&e| t.is_boundary_edge(e))
            .map(|e| t.edge(e).map(|v| mesh.positions[v as usize]))
            .collect();
        Surface {
            mesh,
            facing,
            boundary,
        }
    }

    /// The nearest point of the surface.
    fn project(&self, p: DVec3) -> Option<DVec3> {
        self.facing.bvh().closest_point(p).map(|h| h.point)
    }

    /// The nearest point of the boundary edges.
    fn project_boundary(&self, p: DVec3) -> Option<DVec3> {
        self.boundary
            .iter()
            .map(|[a, b]| {
                let q = closest_point_on_segment(p, *a, *b).0;
                (q, q.distance_squared(p))
            })
            .min_by(|x, y| x.1.total_cmp(&y.1))
            .map(|(q, _)| q)
    }

    /// True when the triangle `abc` does not face away from the input (the metrics'
    /// flipped-face test).
    fn agrees(&self, a: DVec3, b: DVec3, c: DVec3) -> bool {
        !self.facing.faces_away(a, b, c)
    }
}

/// One sweep of edge flips over `mesh` (in edge order, each face flipped at most once):
/// the interior edge a–b of faces abc and bad becomes c–d when the smallest angle of the
/// two faces grows, c–d is not an edge yet, neither new face turns by more than `cos_turn`
/// from the face it replaces, both agree with `surface`, and the input points `watch` keeps
/// near the two faces stay near the new ones. `topo` is `mesh`'s adjacency before the sweep.
/// Returns the flips made.
fn flip_sweep(
    mesh: &mut Mesh,
    topo: &Topology,
    surface: Option<&Surface<'_>>,
    watch: Option<&Watch>,
    cos_turn: f64,
    floor: f64,
) -> usize {
    let mut touched = vec![false; mesh.n_faces()];
    let mut added: std::collections::HashSet<[u32; 2]> = std::collections::HashSet::new();
    let key = |a: u32, b: u32| if a < b { [a, b] } else { [b, a] };
    let mut flips = 0;
    for e in 0..topo.n_edges() as u32 {
        let ef = topo.edge_faces(e);
        if ef.len() != 2 || touched[ef[0] as usize] || touched[ef[1] as usize] {
            continue;
        }
        let [a, b] = topo.edge(e);
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
        if c == d || topo.find_edge(c, d).is_some() || added.contains(&key(c, d)) {
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
        touched[f1] = true;
        touched[f2] = true;
        added.insert(key(c, d));
        flips += 1;
    }
    flips
}

/// An edge longer than this many mean edge lengths, joining two boundary vertices through
/// the interior, is split by [`rebalance`].
const SPLIT_RATIO: f64 = 1.5;
/// Any interior edge longer than this many mean edge lengths is split by [`rebalance`].
const LONG_RATIO: f64 = 1.6;
/// An edge shorter than this many mean edge lengths may be collapsed by [`rebalance`].
const COLLAPSE_RATIO: f64 = 0.8;

/// The third corner of face `f` after the directed edge `x → y`, if `f` has that edge.
fn after_edge(mesh: &Mesh, f: u32, x: u32, y: u32) -> Option<u32> {
    let t = mesh.faces[f as usize];
    (0..3)
        .find(|&i| t[i] == x && t[(i + 1) % 3] == y)
        .map(|i| t[(i + 2) % 3])
}

/// Half of each of two vertices' origins.
fn blend_origins(x: &[(u32, f64)], y: &[(u32, f64)]) -> Vec<(u32, f64)> {
    let mut out: Vec<(u32, f64)> = Vec::new();
    for &(v, w) in x.iter().chain(y) {
        match out.iter_mut().find(|(u, _)| *u == v) {
            Some(e) => e.1 += 0.5 * w,
            None => out.push((v, 0.5 * w)),
        }
    }
    out
}

/// A planned collapse of edge `keep`–`gone` into `keep` at `at`, freeing the faces `freed`.
struct Collapse {
    keep: u32,
    gone: u32,
    at: DVec3,
    freed: Vec<u32>,
}

/// Plans the collapse of edge `e` when it keeps the mesh manifold with its boundary loops
/// (link condition, no interior edge between two boundary vertices, no loop below four
/// vertices) and no remaining face around it turns by more than `cos_turn`, faces away
/// from `surface` or gets a smaller angle than `floor` (radians) or the smallest angle it
/// had around the edge, whichever is lower.
fn plan_collapse(
    mesh: &Mesh,
    topo: &Topology,
    ends: &[Vec<u32>],
    surface: Option<&Surface<'_>>,
    e: u32,
    cos_turn: f64,
    floor: f64,
) -> Option<Collapse> {
    let [a, b] = topo.edge(e);
    let ef = topo.edge_faces(e);
    if topo.n_vertex_fans(a) != 1 || topo.n_vertex_fans(b) != 1 || ef.is_empty() {
        return None;
    }
    let opposite: Vec<u32> = ef
        .iter()
        .filter_map(|&f| {
            mesh.faces[f as usize]
                .into_iter()
                .find(|&w| w != a && w != b)
        })
        .collect();
    let common = topo
        .vertex_neighbors(a)
        .iter()
        .filter(|w| topo.vertex_neighbors(b).contains(w))
        .count();
    if common != opposite.len() {
        return None;
    }
    let (ba, bb) = (topo.is_boundary_vertex(a), topo.is_boundary_vertex(b));
    let (keep, gone, at) = if topo.is_boundary_edge(e) {
        if ends[a as usize]
            .iter()
            .any(|w| ends[b as usize].contains(w))
        {
            return None;
        }
        let mid = mesh.positions[a as usize].lerp(mesh.positions[b as usize], 0.5);
        let at = match surface {
            Some(s) => s.project_boundary(mid)?,
            None => mid,
        };
        (a.min(b), a.max(b), at)
    } else {
        match (ba, bb) {
            (true, true) => return None,
            (true, false) => (a, b, mesh.positions[a as usize]),
            (false, true) => (b, a, mesh.positions[b as usize]),
            (false, false) => {
                let mid = mesh.positions[a as usize].lerp(mesh.positions[b as usize], 0.5);
                let at = surface.and_then(|s| s.project(mid)).unwrap_or(mid);
                (a.min(b), a.max(b), at)
            }
        }
    };
    let mut before = f64::INFINITY;
    let mut after = f64::INFINITY;
    for &v in &[a, b] {
        for &f in topo.vertex_faces(v) {
            let t = mesh.faces[f as usize];
            let old = t.map(|w| mesh.positions[w as usize]);
            before = before.min(triangle::min_angle(old[0], old[1], old[2]));
            if ef.contains(&f) || (v == b && t.contains(&a)) {
                continue;
            }
            let new = t.map(|w| {
                if w == a || w == b {
                    at
                } else {
                    mesh.positions[w as usize]
                }
            });
            let n_old = triangle::normal(old[0], old[1], old[2]);
            let n_new = triangle::normal(new[0], new[1], new[2]);
            if n_new.dot(n_old) < cos_turn
                || surface.is_some_and(|s| !s.agrees(new[0], new[1], new[2]))
            {
                return None;
            }
            after = after.min(triangle::min_angle(new[0], new[1], new[2]));
        }
    }
    (after >= before.min(floor)).then(|| Collapse {
        keep,
        gone,
        at,
        freed: ef.to_vec(),
    })
}

/// The faces replacing the two faces of interior edge `e` when it is split at a new vertex
/// `m` at `at`, and the two faces they replace; `None` when a new face turns by more than
/// `cos_turn` from the face it comes from or faces away from `surface`.
fn plan_split(
    mesh: &Mesh,
    topo: &Topology,
    surface: Option<&Surface<'_>>,
    e: u32,
    m: u32,
    at: DVec3,
    cos_turn: f64,
) -> Option<([u32; 2], [[u32; 3]; 4])> {
    let ef = topo.edge_faces(e);
    let &[f1, f2] = ef else {
        return None;
    };
    let [c, d] = topo.edge(e);
    let (f1, f2) = if after_edge(mesh, f1, c, d).is_some() {
        (f1, f2)
    } else {
        (f2, f1)
    };
    let x = after_edge(mesh, f1, c, d)?;
    let y = after_edge(mesh, f2, d, c)?;
    let new = [[c, m, x], [m, d, x], [d, m, y], [m, c, y]];
    let pos = |w: u32| {
        if w == m {
            at
        } else {
            mesh.positions[w as usize]
        }
    };
    for (i, t) in new.iter().enumerate() {
        let parent = if i < 2 { f1 } else { f2 };
        let [p, q, r] = mesh.corners(parent as usize);
        let [a, b, c] = t.map(pos);
        if triangle::normal(a, b, c).dot(triangle::normal(p, q, r)) < cos_turn.min(0.0)
            || triangle::area(a, b, c) <= 0.0
            || surface.is_some_and(|s| !s.agrees(a, b, c))
        {
            return None;
        }
    }
    Some(([f1, f2], new))
}

/// Up to `max_pairs` times: splits the longest interior edge joining two boundary vertices
/// (longer than [`SPLIT_RATIO`] mean edges: the middle of a narrow strip between boundary
/// loops) at its midpoint on `surface`, and collapses the shortest edge (shorter than
/// [`COLLAPSE_RATIO`] mean edges) that can go without touching it (see [`plan_collapse`]);
/// the collapsed vertex's index is the new vertex, so the vertex count stays. Attributes
/// follow through [`Mesh::rebuilt`] (a split vertex blends its edge's ends, a collapsed
/// one its edge's). Returns the pairs made.
fn rebalance(
    mesh: &mut Mesh,
    surface: Option<&Surface<'_>>,
    max_pairs: u32,
    cos_turn: f64,
    floor: f64,
) -> usize {
    let carry = !mesh.vertex_attrs.is_empty() || !mesh.face_attrs.is_empty();
    let before = carry.then(|| mesh.clone());
    // Where each vertex and face comes from in `before` (weighted vertices, parent face).
    let mut v_from: Vec<Vec<(u32, f64)>> = Vec::new();
    let mut f_from: Vec<u32> = Vec::new();
    if carry {
        v_from = (0..mesh.n_vertices() as u32)
            .map(|v| vec![(v, 1.0)])
            .collect();
        f_from = (0..mesh.n_faces() as u32).collect();
    }
    let blend = |x: &[(u32, f64)], y: &[(u32, f64)]| {
        let mut out: Vec<(u32, f64)> = Vec::new();
        for &(v, w) in x.iter().chain(y) {
            match out.iter_mut().find(|(u, _)| *u == v) {
                Some(e) => e.1 += 0.5 * w,
                None => out.push((v, 0.5 * w)),
            }
        }
        out
    };
    let mut done = 0;
    while done < max_pairs as usize {
        let Ok(topo) = Topology::try_build(mesh) else {
            break;
        };
        let n_edges = topo.n_edges();
        if n_edges == 0 {
            break;
        }
        let len = |e: u32| {
            let [a, b] = topo.edge(e);
            mesh.positions[a as usize].distance(mesh.positions[b as usize])
        };
        let mean = (0..n_edges as u32).map(len).sum::<f64>() / n_edges as f64;
        let mut ends: Vec<Vec<u32>> = vec![Vec::new(); mesh.n_vertices()];
        for e in 0..n_edges as u32 {
            if topo.is_boundary_edge(e) {
                let [a, b] = topo.edge(e);
                ends[a as usize].push(b);
                ends[b as usize].push(a);
            }
        }
        let mut splits: Vec<(f64, u32)> = (0..n_edges as u32)
            .filter(|&e| topo.edge_faces(e).len() == 2)
            .map(|e| {
                let [a, b] = topo.edge(e);
                let bridge = topo.is_boundary_vertex(a) && topo.is_boundary_vertex(b);
                (len(e), e, bridge)
            })
            .filter(|&(l, _, bridge)| l > if bridge { SPLIT_RATIO } else { LONG_RATIO } * mean)
            .map(|(l, e, _)| (l, e))
            .collect();
        splits.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
        let mut collapses: Vec<(f64, u32)> = (0..n_edges as u32)
            .map(|e| (len(e), e))
            .filter(|&(l, _)| l < COLLAPSE_RATIO * mean)
            .collect();
        collapses.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        let mut made = false;
        'pair: for &(_, s) in &splits {
            let [c, d] = topo.edge(s);
            let mid = mesh.positions[c as usize].lerp(mesh.positions[d as usize], 0.5);
            let at = surface.and_then(|sf| sf.project(mid)).unwrap_or(mid);
            let around: Vec<u32> = topo
                .edge_faces(s)
                .iter()
                .flat_map(|&f| mesh.faces[f as usize])
                .collect();
            for &(_, k) in &collapses {
                let [a, b] = topo.edge(k);
                if around.contains(&a) || around.contains(&b) {
                    continue;
                }
                let Some(col) = plan_collapse(mesh, &topo, &ends, surface, k, cos_turn, floor)
                else {
                    continue;
                };
                let Some((old, new)) = plan_split(mesh, &topo, surface, s, col.gone, at, cos_turn)
                else {
                    continue 'pair;
                };
                if carry {
                    if col.at != mesh.positions[col.keep as usize] {
                        v_from[col.keep as usize] =
                            blend(&v_from[col.keep as usize], &v_from[col.gone as usize]);
                    }
                    v_from[col.gone as usize] = blend(&v_from[c as usize], &v_from[d as usize]);
                    let parents = [old[0], old[0], old[1], old[1]].map(|f| f_from[f as usize]);
                    let slots = [old[0], old[1]]
                        .into_iter()
                        .chain(col.freed.iter().copied());
                    for (i, f) in slots.enumerate() {
                        f_from[f as usize] = parents[i];
                    }
                    if col.freed.len() == 1 {
                        f_from.push(parents[3]);
                    }
                }
                // Collapse: `gone` becomes `keep`; its edge's faces are freed.
                for &f in topo.vertex_faces(col.gone) {
                    for w in &mut mesh.faces[f as usize] {
                        if *w == col.gone {
                            *w = col.keep;
                        }
                    }
                }
                mesh.positions[col.keep as usize] = col.at;
                mesh.positions[col.gone as usize] = at;
                // The split's two faces and the collapse's freed ones (two, or one on the
                // boundary: then the last new face is appended).
                let mut slots = vec![old[0], old[1]];
                slots.extend(&col.freed);
                for (i, t) in new.into_iter().enumerate() {
                    match slots.get(i) {
                        Some(&f) => mesh.faces[f as usize] = t,
                        None => mesh.faces.push(t),
                    }
                }
                done += 1;
                made = true;
                break 'pair;
            }
        }
        if !made {
            break;
        }
    }
    if let Some(before) = before.filter(|_| done > 0) {
        let mut vo = VertexOrigins::with_capacity(v_from.len());
        for src in v_from {
            vo.push_blend(src);
        }
        let fo = FaceOrigins::from_parents(f_from);
        let positions = std::mem::take(&mut mesh.positions);
        let faces = std::mem::take(&mut mesh.faces);
        *mesh = before.rebuilt(positions, faces, &vo, &fo).0;
    }
    done
}

/// Points of the input whose distance to `mesh` is watched (true: on the boundary): its
/// used vertices, edge midpoints, face centroids and the points halfway from each centroid
/// to a corner; only those farther than `min_dist` from `mesh`.
fn input_samples(surface: &Surface<'_>, mesh: &Mesh, min_dist: f64) -> Vec<(DVec3, bool)> {
    let input = surface.mesh;
    let t = surface.facing.topology();
    let mut samples: Vec<(DVec3, bool)> = (0..input.n_vertices() as u32)
        .filter(|&v| !t.is_isolated_vertex(v))
        .map(|v| (input.positions[v as usize], t.is_boundary_vertex(v)))
        .collect();
    samples.extend((0..t.n_edges() as u32).map(|e| {
        let [a, b] = t.edge(e);
        let mid = input.positions[a as usize].lerp(input.positions[b as usize], 0.5);
        (mid, t.is_boundary_edge(e))
    }));
    for f in 0..input.n_faces() {
        let [a, b, c] = input.corners(f);
        let g = (a + b + c) / 3.0;
        samples.extend([g, g.lerp(a, 0.5), g.lerp(b, 0.5), g.lerp(c, 0.5)].map(|q| (q, false)));
    }
    if mesh.n_faces() == 0 {
        return samples;
    }
    let bvh = Bvh::build(&mesh.positions, &mesh.faces);
    // In parallel; `collect` keeps the order, so the result is the same on any thread count.
    samples
        .into_par_iter()
        .filter(|(q, _)| {
            bvh.closest_point(*q)
                .is_none_or(|h| h.distance() > min_dist)
        })
        .collect()
}

/// Input points nearer the mesh than this fraction of `max_dev_pct` are not watched (a
/// move or a flip changes the surface too little to take them beyond it).
const WATCH_FROM: f64 = 0.5;

/// The input points the sweeps keep near the mesh (`max_dev_pct`), grouped by the mesh
/// face nearest to each.
struct Watch {
    /// The points.
    samples: Vec<DVec3>,
    /// The bound.
    tol: f64,
    /// Where each face's points start in `ids` (one more entry than faces).
    offsets: Vec<u32>,
    /// Point indices, face by face.
    ids: Vec<u32>,
    /// Each point's distance to the mesh when grouped.
    dist: Vec<f64>,
}

impl Watch {
    /// The points `samples` (from [`input_samples`]), kept within `tol`.
    fn new(samples: &[(DVec3, bool)], tol: f64) -> Watch {
        Watch {
            samples: samples.iter().map(|x| x.0).collect(),
            tol,
            offsets: Vec::new(),
            ids: Vec::new(),
            dist: Vec::new(),
        }
    }

    /// Groups the points by their nearest face of `mesh`.
    fn assign(&mut self, mesh: &Mesh) {
        let bvh = Bvh::build(&mesh.positions, &mesh.faces);
        let near: Vec<(u32, f64)> = self
            .samples
            .par_iter()
            .map(|&q| {
                bvh.closest_point(q)
                    .map_or((u32::MAX, 0.0), |h| (h.face, h.distance()))
            })
            .collect();
        let mut counts = vec![0u32; mesh.n_faces() + 1];
        for &(f, _) in &near {
            if (f as usize) < mesh.n_faces() {
                counts[f as usize + 1] += 1;
            }
        }
        for i in 1..counts.len() {
            counts[i] += counts[i - 1];
        }
        let mut fill = counts.clone();
        self.ids = vec![0; counts[mesh.n_faces()] as usize];
        for (i, &(f, _)) in near.iter().enumerate() {
            if (f as usize) < mesh.n_faces() {
                self.ids[fill[f as usize] as usize] = i as u32;
                fill[f as usize] += 1;
            }
        }
        self.offsets = counts;
        self.dist = near.into_iter().map(|x| x.1).collect();
    }

    /// True when every point grouped on `faces` stays within the bound (or within its
    /// distance when grouped) of the triangles `tris` that replace them.
    fn allows(&self, faces: &[u32], tris: &[[DVec3; 3]]) -> bool {
        faces.iter().all(|&f| {
            let (a, b) = (self.offsets[f as usize], self.offsets[f as usize + 1]);
            self.ids[a as usize..b as usize].iter().all(|&i| {
                let limit = self.tol.max(self.dist[i as usize]) * (1.0 + 1e-9);
                distance_to(self.samples[i as usize], tris) <= limit
            })
        })
    }
}

/// [`fit`] splits, in one round, only where the input lies at least this fraction of the
/// round's largest distance from the mesh.
const FIT_BAND: f64 = 0.7;
/// A collapse made by [`fit`] may move the surface by at most this fraction of the distance
/// its split removes (or by `max_dev_pct`, whichever is larger).
const FIT_TRADE: f64 = 0.5;
/// Without `max_dev_pct`, [`fit`] works on the input points farther from the mesh than
/// this fraction of the farthest.
const FIT_FROM: f64 = 0.5;
/// [`fit`]'s new faces keep at least this fraction of the smaller of `floor_deg` and the
/// mesh's smallest angle (the sweeps after it lift them again).
const FIT_GUARD: f64 = 0.8;

/// Distance from `p` to the nearest of the triangles `tris` (infinite when there is none).
fn distance_to(p: DVec3, tris: &[[DVec3; 3]]) -> f64 {
    tris.iter()
        .map(|[a, b, c]| closest_point_on_triangle(p, *a, *b, *c).0.distance(p))
        .fold(f64::INFINITY, f64::min)
}

/// True when the centroid or an edge midpoint of one of `tris` lies farther than `bound`
/// from the input surface.
fn leaves_input(surface: &Surface<'_>, tris: &[[DVec3; 3]], bound: f64) -> bool {
    tris.iter().any(|[a, b, c]| {
        [
            (*a + *b + *c) / 3.0,
            a.lerp(*b, 0.5),
            b.lerp(*c, 0.5),
            c.lerp(*a, 0.5),
        ]
        .into_iter()
        .any(|x| surface.project(x).is_none_or(|y| y.distance(x) > bound))
    })
}

/// How far collapsing edge `e` into `at` moves the surface: the larger distance from its two
/// ends to the faces left around `at`.
fn collapse_error(
    mesh: &Mesh,
    topo: &Topology,
    e: u32,
    at: DVec3,
    tris: &mut Vec<[DVec3; 3]>,
) -> f64 {
    let [a, b] = topo.edge(e);
    tris.clear();
    for v in [a, b] {
        for &f in topo.vertex_faces(v) {
            let t = mesh.faces[f as usize];
            if t.contains(&a) && t.contains(&b) {
                continue;
            }
            tris.push(t.map(|w| {
                if w == a || w == b {
                    at
                } else {
                    mesh.positions[w as usize]
                }
            }));
        }
    }
    let (pa, pb) = (mesh.positions[a as usize], mesh.positions[b as usize]);
    distance_to(pa, tris).max(distance_to(pb, tris))
}

/// The faces replacing the one face of boundary edge `e` when it is split at a new vertex
/// `m` at `at`, and the face they replace; `None` when a new face turns by more than
/// `cos_turn`, has no area or faces away from `surface`.
fn plan_boundary_split(
    mesh: &Mesh,
    topo: &Topology,
    surface: &Surface<'_>,
    e: u32,
    m: u32,
    at: DVec3,
    cos_turn: f64,
) -> Option<([u32; 1], [[u32; 3]; 2])> {
    let &[f] = topo.edge_faces(e) else {
        return None;
    };
    let [c, d] = topo.edge(e);
    let (c, d, x) = match after_edge(mesh, f, c, d) {
        Some(x) => (c, d, x),
        None => (d, c, after_edge(mesh, f, d, c)?),
    };
    let new = [[c, m, x], [m, d, x]];
    let [p, q, r] = mesh.corners(f as usize);
    let n_old = triangle::normal(p, q, r);
    for t in &new {
        let [a, b, c] = t.map(|w| {
            if w == m {
                at
            } else {
                mesh.positions[w as usize]
            }
        });
        if triangle::normal(a, b, c).dot(n_old) < cos_turn.min(0.0)
            || triangle::area(a, b, c) <= 0.0
            || !surface.agrees(a, b, c)
        {
            return None;
        }
    }
    Some(([f], new))
}

/// Moves the end of one of `edges` (nearest to `p` first) nearest to `p`, on the same
/// side of the boundary as `p`, to `p` or halfway there on the input, when no face around
/// it gets an angle below `guard`, turns by more than `cos_turn` or faces away from
/// `surface`, and neither its old place nor the new faces end farther than `back` from the
/// other surface. Marks the vertices of its faces in `touched`. True when a vertex moved.
#[allow(clippy::too_many_arguments)]
fn pull(
    mesh: &mut Mesh,
    topo: &Topology,
    surface: &Surface<'_>,
    edges: &[(f64, u32)],
    p: DVec3,
    on_boundary: bool,
    back: f64,
    guard: f64,
    cos_turn: f64,
    touched: &mut [bool],
    tris: &mut Vec<[DVec3; 3]>,
) -> bool {
    let mut normals = Vec::new();
    for &(_, e) in edges {
        let mut ends = topo.edge(e);
        let pos = |w: u32| mesh.positions[w as usize];
        if pos(ends[1]).distance(p) < pos(ends[0]).distance(p) {
            ends.swap(0, 1);
        }
        for w in ends {
            let fan = topo.vertex_faces(w);
            if touched[w as usize]
                || topo.is_boundary_vertex(w) != on_boundary
                || topo.n_vertex_fans(w) != 1
                || fan
                    .iter()
                    .any(|&f| mesh.faces[f as usize].iter().any(|&x| touched[x as usize]))
            {
                continue;
            }
            let old = pos(w);
            let half = old.lerp(p, 0.5);
            let half = if on_boundary {
                surface.project_boundary(half)
            } else {
                surface.project(half)
            };
            normals.clear();
            normals.extend(fan.iter().map(|&f| {
                let [a, b, c] = mesh.corners(f as usize);
                triangle::normal(a, b, c)
            }));
            for q in std::iter::once(p).chain(half) {
                let Some((worst, _)) = fan_shape(mesh, fan, w, q, &normals, cos_turn) else {
                    continue;
                };
                if worst < guard {
                    continue;
                }
                tris.clear();
                tris.extend(
                    fan.iter()
                        .map(|&f| mesh.faces[f as usize].map(|x| if x == w { q } else { pos(x) })),
                );
                if distance_to(old, tris) > back
                    || leaves_input(surface, tris, back)
                    || tris.iter().any(|[a, b, c]| !surface.agrees(*a, *b, *c))
                {
                    continue;
                }
                mesh.positions[w as usize] = q;
                for &f in fan {
                    for x in mesh.faces[f as usize] {
                        touched[x as usize] = true;
                    }
                }
                return true;
            }
        }
    }
    false
}

/// Up to `max_pairs` times, in rounds, for the input points (see [`input_samples`])
/// farthest from `mesh` and beyond `tol`: puts a new vertex at the point (splitting the
/// nearest edge of its nearest face, or the nearest boundary edge for a point of the input
/// boundary, at the point or halfway to the edge's midpoint on the input) and collapses the
/// edge whose collapse moves the surface least (at most `tol` or [`FIT_TRADE`] of the
/// distance gained); where no split fits, pulls a nearby vertex there instead (see
/// [`pull`]). No new face gets an angle below [`FIT_GUARD`] of `floor` or the mesh's
/// smallest angle, whichever is lower, turns by more than `cos_turn` or faces away from the
/// input. Within a round no vertex takes part twice. Attributes follow through
/// [`Mesh::rebuilt`]. Returns the edits made (pairs and pulls).
fn fit(
    mesh: &mut Mesh,
    surface: &Surface<'_>,
    max_pairs: u32,
    cos_turn: f64,
    floor: f64,
    tol: f64,
    samples: &[(DVec3, bool)],
) -> usize {
    let carry = !mesh.vertex_attrs.is_empty() || !mesh.face_attrs.is_empty();
    let before = carry.then(|| mesh.clone());
    let mut v_from: Vec<Vec<(u32, f64)>> = Vec::new();
    let mut f_from: Vec<u32> = Vec::new();
    if carry {
        v_from = (0..mesh.n_vertices() as u32)
            .map(|v| vec![(v, 1.0)])
            .collect();
        f_from = (0..mesh.n_faces() as u32).collect();
    }
    let smallest = (0..mesh.n_faces())
        .map(|f| {
            let [a, b, c] = mesh.corners(f);
            triangle::min_angle(a, b, c)
        })
        .fold(f64::INFINITY, f64::min);
    let guard = FIT_GUARD
        * if floor > 0.0 {
            floor.min(smallest)
        } else {
            smallest
        };
    // Points no split, collapse or pull could bring nearer: left alone from then on.
    let mut given_up = vec![false; samples.len()];
    // The points looked at: after the first round, only those that were beyond `tol` (the
    // edits keep the others within it), or without a bound beyond [`FIT_FROM`] of the
    // farthest.
    let mut active: Vec<u32> = (0..samples.len() as u32).collect();
    let mut first = true;
    let mut tris = Vec::new();
    let mut done = 0;
    while done < max_pairs as usize {
        let Ok(topo) = Topology::try_build(mesh) else {
            break;
        };
        let n_edges = topo.n_edges();
        if n_edges == 0 || mesh.n_faces() == 0 {
            break;
        }
        let bvh = Bvh::build(&mesh.positions, &mesh.faces);
        let mut far: Vec<(f64, u32, u32)> = active
            .par_iter()
            .filter(|&&i| !given_up[i as usize])
            .filter_map(|&i| {
                bvh.closest_point(samples[i as usize].0)
                    .map(|h| (h.distance(), i, h.face))
            })
            .collect();
        if std::mem::take(&mut first) {
            let d_max = far.iter().map(|x| x.0).fold(0.0, f64::max);
            let keep = if tol > 0.0 { tol } else { FIT_FROM * d_max };
            far.retain(|x| x.0 > keep);
            active = far.iter().map(|x| x.1).collect();
            active.sort_unstable();
        }
        far.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
        let Some(&(d_max, _, _)) = far.first() else {
            break;
        };
        if d_max.is_nan() || d_max <= tol {
            break;
        }
        let len = |e: u32| {
            let [a, b] = topo.edge(e);
            mesh.positions[a as usize].distance(mesh.positions[b as usize])
        };
        let mean = (0..n_edges as u32).map(len).sum::<f64>() / n_edges as f64;
        let mut ends: Vec<Vec<u32>> = vec![Vec::new(); mesh.n_vertices()];
        let mut boundary_edges = Vec::new();
        for e in 0..n_edges as u32 {
            if topo.is_boundary_edge(e) {
                let [a, b] = topo.edge(e);
                ends[a as usize].push(b);
                ends[b as usize].push(a);
                boundary_edges.push(e);
            }
        }
        // Collapse candidates, least surface moved first (at the edge's midpoint).
        let mut collapses: Vec<(f64, f64, u32)> = (0..n_edges as u32)
            .map(|e| (len(e), e))
            .filter(|&(l, _)| l < mean)
            .map(|(l, e)| {
                let [a, b] = topo.edge(e);
                let mid = mesh.positions[a as usize].lerp(mesh.positions[b as usize], 0.5);
                (collapse_error(mesh, &topo, e, mid, &mut tris), l, e)
            })
            .collect();
        collapses.sort_by(|x, y| {
            x.0.total_cmp(&y.0)
                .then(x.1.total_cmp(&y.1))
                .then(x.2.cmp(&y.2))
        });
        let mut touched = vec![false; mesh.n_vertices()];
        let mut made = 0;
        for &(d, iv, f) in far
            .iter()
            .take_while(|x| x.0 >= FIT_BAND * d_max && x.0 > tol)
        {
            if done >= max_pairs as usize {
                break;
            }
            let face = mesh.faces[f as usize];
            if face.iter().any(|&w| touched[w as usize]) {
                continue;
            }
            let (p, on_boundary) = samples[iv as usize];
            // The edges to split, nearest to `p` first.
            let seg = |e: u32| {
                let [a, b] = topo.edge(e);
                closest_point_on_segment(p, mesh.positions[a as usize], mesh.positions[b as usize])
                    .0
                    .distance(p)
            };
            let mut edges: Vec<(f64, u32)> = if on_boundary {
                boundary_edges.iter().map(|&e| (seg(e), e)).collect()
            } else {
                topo.face_edges(f)
                    .into_iter()
                    .filter(|&e| topo.edge_faces(e).len() == 2)
                    .map(|e| (seg(e), e))
                    .collect()
            };
            edges.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            if on_boundary {
                edges.truncate(2);
            }
            const M: u32 = u32::MAX;
            let mut plan = None;
            'edges: for &(_, s) in &edges {
                let [c, dd] = topo.edge(s);
                let around: Vec<u32> = topo
                    .edge_faces(s)
                    .iter()
                    .flat_map(|&g| mesh.faces[g as usize])
                    .collect();
                if around.iter().any(|&w| touched[w as usize]) {
                    continue;
                }
                let mid = mesh.positions[c as usize].lerp(mesh.positions[dd as usize], 0.5);
                let half = p.lerp(mid, 0.5);
                let half = if on_boundary {
                    surface.project_boundary(half)
                } else {
                    surface.project(half)
                };
                for at in std::iter::once(p).chain(half) {
                    let split = if on_boundary {
                        plan_boundary_split(mesh, &topo, surface, s, M, at, cos_turn)
                            .map(|(o, n)| (o.to_vec(), n.to_vec()))
                    } else {
                        plan_split(mesh, &topo, Some(surface), s, M, at, cos_turn)
                            .map(|(o, n)| (o.to_vec(), n.to_vec()))
                    };
                    let Some((old, new)) = split else {
                        continue;
                    };
                    let shape_ok = new.iter().all(|t| {
                        let [a, b, c] = t.map(|w| {
                            if w == M {
                                at
                            } else {
                                mesh.positions[w as usize]
                            }
                        });
                        triangle::min_angle(a, b, c) >= guard
                    }) && {
                        tris.clear();
                        tris.extend(new.iter().map(|t| {
                            t.map(|w| {
                                if w == M {
                                    at
                                } else {
                                    mesh.positions[w as usize]
                                }
                            })
                        }));
                        !leaves_input(surface, &tris, tol.max(FIT_TRADE * d))
                    };
                    if shape_ok {
                        plan = Some((s, at, old, new, around.clone()));
                        break 'edges;
                    }
                }
            }
            let Some((s, at, old, new, around)) = plan else {
                // No split fits here: pull the nearest end of the nearest edge towards `p`.
                if pull(
                    mesh,
                    &topo,
                    surface,
                    &edges,
                    p,
                    on_boundary,
                    tol.max(FIT_TRADE * d),
                    guard,
                    cos_turn,
                    &mut touched,
                    &mut tris,
                ) {
                    done += 1;
                    made += 1;
                } else {
                    given_up[iv as usize] = true;
                }
                continue;
            };
            // Distance the split removes (the far point's distance is at most this after).
            let gain = d - at.distance(p);
            let mut chosen = None;
            for &(err, _, k) in &collapses {
                if err > tol.max(FIT_TRADE * gain) {
                    break;
                }
                let [a, b] = topo.edge(k);
                if touched[a as usize]
                    || touched[b as usize]
                    || around.contains(&a)
                    || around.contains(&b)
                {
                    continue;
                }
                let Some(col) =
                    plan_collapse(mesh, &topo, &ends, Some(surface), k, cos_turn, floor)
                else {
                    continue;
                };
                if collapse_error(mesh, &topo, k, col.at, &mut tris) > tol.max(FIT_TRADE * gain)
                    || leaves_input(surface, &tris, tol.max(FIT_TRADE * gain))
                {
                    continue;
                }
                chosen = Some(col);
                break;
            }
            let Some(col) = chosen else {
                given_up[iv as usize] = true;
                continue;
            };
            let [c, dd] = topo.edge(s);
            let new: Vec<[u32; 3]> = new
                .iter()
                .map(|t| t.map(|w| if w == M { col.gone } else { w }))
                .collect();
            for v in [col.keep, col.gone] {
                for &g in topo.vertex_faces(v) {
                    for w in mesh.faces[g as usize] {
                        touched[w as usize] = true;
                    }
                }
            }
            for &w in &around {
                touched[w as usize] = true;
            }
            if carry {
                if col.at != mesh.positions[col.keep as usize] {
                    v_from[col.keep as usize] =
                        blend_origins(&v_from[col.keep as usize], &v_from[col.gone as usize]);
                }
                v_from[col.gone as usize] =
                    blend_origins(&v_from[c as usize], &v_from[dd as usize]);
            }
            // Each new face's parent in the mesh `fit` started from.
            let parents: Vec<u32> = (0..new.len())
                .map(|i| old[i * old.len() / new.len()])
                .map(|g| if carry { f_from[g as usize] } else { g })
                .collect();
            for &g in topo.vertex_faces(col.gone) {
                for w in &mut mesh.faces[g as usize] {
                    if *w == col.gone {
                        *w = col.keep;
                    }
                }
            }
            mesh.positions[col.keep as usize] = col.at;
            mesh.positions[col.gone as usize] = at;
            // The split's faces and the collapse's freed ones take the new faces; a slot
            // left over is removed, a face left over is appended (then the face indices
            // change: the round ends).
            let mut slots: Vec<u32> = old.iter().chain(&col.freed).copied().collect();
            let reindexed = slots.len() != new.len();
            for (i, t) in new.into_iter().enumerate() {
                let parent = parents[i];
                match slots.get(i) {
                    Some(&g) => {
                        mesh.faces[g as usize] = t;
                        if carry {
                            f_from[g as usize] = parent;
                        }
                    }
                    None => {
                        mesh.faces.push(t);
                        if carry {
                            f_from.push(parent);
                        }
                    }
                }
            }
            let mut extra = slots.split_off(parents.len().min(slots.len()));
            extra.sort_unstable_by(|x, y| y.cmp(x));
            for g in extra {
                mesh.faces.swap_remove(g as usize);
                if carry {
                    f_from.swap_remove(g as usize);
                }
            }
            done += 1;
            made += 1;
            if reindexed {
                break;
            }
        }
        if made == 0 && !far.iter().any(|x| x.0 > tol && !given_up[x.1 as usize]) {
            break;
        }
    }
    if let Some(before) = before.filter(|_| done > 0) {
        let mut vo = VertexOrigins::with_capacity(v_from.len());
        for src in v_from {
            vo.push_blend(src);
        }
        let fo = FaceOrigins::from_parents(f_from);
        let positions = std::mem::take(&mut mesh.positions);
        let faces = std::mem::take(&mut mesh.faces);
        *mesh = before.rebuilt(positions, faces, &vo, &fo).0;
    }
    done
}

/// Relaxes the vertices of `mesh` in place (see the crate docs), keeping them on `surface`
/// when given.
pub fn relax(mesh: &mut Mesh, surface: Option<&Surface<'_>>, params: &RelaxParams) -> Relaxed {
    let min_angle = |m: &Mesh| {
        (0..m.n_faces())
            .map(|f| {
                let [a, b, c] = m.corners(f);
                triangle::min_angle(a, b, c).to_degrees()
            })
            .fold(f64::INFINITY, f64::min)
    };
    let mut out = Relaxed {
        min_angle_before: min_angle(mesh),
        ..Relaxed::default()
    };
    let cos_turn = params.max_turn_deg.to_radians().cos();
    let surface_on = surface.filter(|_| params.project);
    let tol = surface_on.map_or(0.0, |s| {
        0.01 * params.max_dev_pct * s.mesh.bbox().diagonal()
    });
    if params.rebalance > 0 {
        out.rebalanced = rebalance(
            mesh,
            surface_on,
            params.rebalance,
            cos_turn,
            params.floor_deg.to_radians(),
        );
    }
    // The input points `fit` and the bound look at.
    let samples = match surface_on {
        Some(s) if params.fit > 0 || params.max_dev_pct > 0.0 => {
            input_samples(s, mesh, WATCH_FROM * tol)
        }
        _ => Vec::new(),
    };
    if params.fit > 0
        && let Some(sf) = surface_on
    {
        out.fitted = fit(
            mesh,
            sf,
            params.fit,
            cos_turn,
            params.floor_deg.to_radians(),
            tol,
            &samples,
        );
    }
    let mut watch = surface_on
        .filter(|_| params.max_dev_pct > 0.0)
        .map(|_| Watch::new(&samples, tol));
    drop(samples);
    let Ok(topo) = Topology::try_build(mesh) else {
        out.min_angle_after = out.min_angle_before;
        return out;
    };
    // The two boundary neighbours of each boundary vertex.
    let mut ends: Vec<Vec<u32>> = vec![Vec::new(); mesh.n_vertices()];
    for e in 0..topo.n_edges() as u32 {
        if topo.is_boundary_edge(e) {
            let [a, b] = topo.edge(e);
            ends[a as usize].push(b);
            ends[b as usize].push(a);
        }
    }
    let mut normals = Vec::new();
    let mut topo = topo;
    let mut tris = Vec::new();
    for _ in 0..params.sweeps {
        if let Some(w) = watch.as_mut() {
            w.assign(mesh);
        }
        if params.flips {
            let flipped = flip_sweep(
                mesh,
                &topo,
                surface,
                watch.as_ref(),
                cos_turn,
                params.floor_deg.to_radians(),
            );
            out.flipped.push(flipped);
            if flipped > 0 {
                match Topology::try_build(mesh) {
                    Ok(t) => topo = t,
                    Err(_) => break,
                }
            }
        }
        let mut moved = 0;
        for v in 0..mesh.n_vertices() as u32 {
            let fan = topo.vertex_faces(v);
            if fan.is_empty() || topo.n_vertex_fans(v) != 1 {
                continue;
            }
            let p = mesh.positions[v as usize];
            normals.clear();
            let (mut sum, mut area, mut normal) = (DVec3::ZERO, 0.0, DVec3::ZERO);
            for &f in fan {
                let [a, b, c] = mesh.corners(f as usize);
                let w = triangle::area(a, b, c);
                sum += w * triangle::centroid(a, b, c);
                area += w;
                normal += triangle::cross(a, b, c);
                normals.push(triangle::normal(a, b, c));
            }
            // Candidate positions, best first: the full move, then partial ones (on the
            // boundary: a third and two thirds of the way between the two neighbours).
            let mut cands = [DVec3::NAN; 5];
            if topo.is_boundary_vertex(v) {
                let [u, w] = match ends[v as usize][..] {
                    [u, w] => [u, w].map(|i| mesh.positions[i as usize]),
                    _ => continue,
                };
                for (c, s) in cands.iter_mut().zip([0.5, 1.0 / 3.0, 2.0 / 3.0]) {
                    let target = p + params.step * (u.lerp(w, s) - p);
                    *c = match surface.filter(|_| params.project) {
                        Some(sf) => sf.project_boundary(target).unwrap_or(DVec3::NAN),
                        None => target,
                    };
                }
            } else {
                let normal = normal.normalize_or_zero();
                if area <= 0.0 || normal == DVec3::ZERO {
                    continue;
                }
                let d = sum / area - p;
                let d = d - d.dot(normal) * normal;
                // With `floor_deg`, also the mean of the neighbours (evens edge lengths).
                let ring = topo.vertex_neighbors(v);
                let mean = ring
                    .iter()
                    .map(|&w| mesh.positions[w as usize])
                    .sum::<DVec3>()
                    / ring.len().max(1) as f64;
                let l = mean - p;
                let l = l - l.dot(normal) * normal;
                let n_moves = if params.floor_deg > 0.0 { 5 } else { 3 };
                let moves = [d, 0.5 * d, 0.25 * d, l, 0.5 * l];
                for (c, m) in cands.iter_mut().zip(moves).take(n_moves) {
                    let q = p + params.step * m;
                    *c = match surface.filter(|_| params.project) {
                        Some(sf) => sf.project(q).unwrap_or(q),
                        None => q,
                    };
                }
            }
            let Some(before) = fan_shape(mesh, fan, v, p, &normals, -1.0) else {
                continue;
            };
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
            let agrees = |q: DVec3| {
                surface.is_none_or(|s| {
                    fan.iter().all(|&f| {
                        let [a, b, c] = mesh.faces[f as usize].map(|w| {
                            if w == v {
                                q
                            } else {
                                mesh.positions[w as usize]
                            }
                        });
                        s.agrees(a, b, c)
                    })
                })
            };
            // Rank the improving candidates; the (costlier) input-normal test goes in order.
            let mut ranked: Vec<((f64, f64), DVec3)> = cands
                .iter()
                .filter(|q| q.is_finite() && **q != p)
                .filter_map(|&q| {
                    fan_shape(mesh, fan, v, q, &normals, cos_turn)
                        .filter(|&after| better(after))
                        .map(|after| (after, q))
                })
                .collect();
            ranked.sort_by(|a, b| {
                let key = |s: (f64, f64)| (s.0.min(floor.max(0.0)), s.1);
                if floor <= 0.0 {
                    b.0.0.total_cmp(&a.0.0)
                } else {
                    let (x, y) = (key(a.0), key(b.0));
                    y.0.total_cmp(&x.0).then(y.1.total_cmp(&x.1))
                }
            });
            let close = |q: DVec3, tris: &mut Vec<[DVec3; 3]>| {
                watch.as_ref().is_none_or(|w| {
                    tris.clear();
                    tris.extend(fan.iter().map(|&f| {
                        mesh.faces[f as usize].map(|x| {
                            if x == v {
                                q
                            } else {
                                mesh.positions[x as usize]
                            }
                        })
                    }));
                    w.allows(fan, tris)
                })
            };
            if let Some(&(_, q)) = ranked
                .iter()
                .find(|(_, q)| agrees(*q) && close(*q, &mut tris))
            {
                mesh.positions[v as usize] = q;
                moved += 1;
            }
        }
        out.moved.push(moved);
        if moved == 0 && out.flipped.last().is_none_or(|&f| f == 0) {
            break;
        }
    }
    out.min_angle_after = min_angle(mesh);
    out
}

/// The `relax` stage.
pub struct Relax(RelaxParams);

impl Stage for Relax {
    type Params = RelaxParams;
    const KIND: &'static str = "relax";
    const SUMMARY: &'static str = "Tangential relaxation on the input surface: vertex moves and edge flips that raise the smallest angle (or, above `floor_deg`, the shape), optional split/collapse rebalancing, fidelity edits where the input is farthest and a bound on its distance; no face flipped, vertex count kept.";

    fn new(params: RelaxParams) -> Self {
        Relax(params)
    }

    fn contract(&self) -> Contract {
        Contract {
            needs: Needs {
                manifold: true,
                ..Needs::default()
            },
            ..Contract::default()
        }
    }

    fn run(&self, mut mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        let surface = match self.0.project && cx.original.n_faces() > 0 {
            false => None,
            true => Some(Surface::with_index(
                cx.original,
                cx.input_index_with_topology(SurfaceIndex::with_topology)
                    .map_err(|e| StageError::Input(format!("`{}`: the input: {e}", Self::KIND)))?,
            )),
        };
        let r = relax(&mut mesh, surface.as_ref(), &self.0);
        cx.report.figure("moved", &r.moved);
        cx.report.figure("flipped", &r.flipped);
        cx.report.figure("rebalanced", r.rebalanced);
        if self.0.fit > 0 {
            cx.report.figure("fitted", r.fitted);
        }
        cx.report.figure("min_angle_before", r.min_angle_before);
        cx.report.figure("min_angle_after", r.min_angle_after);
        Ok(mesh)
    }
}

coarsen_stage::export_stage!(Relax);

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_stage::StageReport;

    /// A sphere whose vertices were pushed around on its surface: relaxing lifts its
    /// smallest angle, keeps every vertex on the sphere and flips nothing.
    #[test]
    fn relaxing_a_jittered_sphere_raises_its_smallest_angle_and_stays_on_it() {
        let original = coarsen_shapes::icosphere(1.0, 4).unwrap();
        let mut m = coarsen_shapes::icosphere(1.0, 3).unwrap();
        let mut s = 7u64;
        for p in &mut m.positions {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let t = DVec3::new(
                ((s >> 11) % 1000) as f64 / 1000.0 - 0.5,
                ((s >> 23) % 1000) as f64 / 1000.0 - 0.5,
                ((s >> 37) % 1000) as f64 / 1000.0 - 0.5,
            );
            *p = (*p + 0.08 * t).normalize();
        }
        let before = m.clone();
        let mut report = StageReport::default();
        // Moves only, so the faces stay comparable one by one.
        let params = RelaxParams {
            flips: false,
            ..RelaxParams::default()
        };
        let out = Relax::new(params)
            .run(m, &mut Context::new(&original, &mut report))
            .unwrap();
        let a0 = report.get("min_angle_before").unwrap().as_f64().unwrap();
        let a1 = report.get("min_angle_after").unwrap().as_f64().unwrap();
        assert!(a1 > a0 + 1.0, "{a0} → {a1}");
        assert!(out.faces == before.faces, "faces changed");
        for p in &out.positions {
            // On the input polyhedron: within its chord error of the unit sphere.
            assert!((p.length() - 1.0).abs() < 0.01, "{p}");
        }
        for f in 0..out.n_faces() {
            assert!(
                out.face_normal(f).dot(before.face_normal(f)) > 0.5,
                "face {f}"
            );
        }
    }

    /// A flat rhombus split along its long diagonal gets the short one.
    #[test]
    fn a_long_diagonal_is_flipped_to_the_short_one() {
        let positions = vec![
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 0.3, 0.0),
            DVec3::new(0.0, -0.3, 0.0),
        ];
        let mut m = Mesh::new(positions, vec![[0, 1, 2], [1, 0, 3]]);
        let params = RelaxParams {
            step: 0.0,
            sweeps: 1,
            ..RelaxParams::default()
        };
        let r = relax(&mut m, None, &params);
        assert_eq!(r.flipped, vec![1]);
        assert!(r.min_angle_after > r.min_angle_before + 10.0, "{r:?}");
        let t = Topology::build(&m);
        assert!(t.find_edge(2, 3).is_some() && t.find_edge(0, 1).is_none());
        assert!(t.is_consistently_oriented());
        for f in 0..2 {
            assert!(m.face_normal(f).z > 0.0);
        }
    }

    /// On a disc with holes, boundary vertices only slide along the input's boundary edges.
    #[test]
    fn boundary_vertices_stay_on_the_input_boundary() {
        let original = coarsen_shapes::disk_with_holes(2, 24, 1.0).unwrap();
        let surface = Surface::new(&original);
        let topo = Topology::build(&original);
        let mut m = original.clone();
        // Jitter the interior within the plane; the boundary starts where it is.
        for (v, p) in m.positions.iter_mut().enumerate() {
            if !topo.is_boundary_vertex(v as u32) {
                let t = (v as f64 * 12.9898).sin() * 0.01;
                *p += DVec3::new(t, -t, 0.0);
            }
        }
        let mean_min_angle = |m: &Mesh| {
            (0..m.n_faces())
                .map(|f| {
                    let [a, b, c] = m.corners(f);
                    triangle::min_angle(a, b, c)
                })
                .sum::<f64>()
                / m.n_faces() as f64
        };
        let before = mean_min_angle(&m);
        let r = relax(&mut m, Some(&surface), &RelaxParams::default());
        assert!(r.min_angle_after >= r.min_angle_before, "{r:?}");
        assert!(mean_min_angle(&m) > before, "{r:?}");
        let mut slid = 0;
        for v in 0..m.n_vertices() as u32 {
            let p = m.positions[v as usize];
            if topo.is_boundary_vertex(v) {
                let d = surface.project_boundary(p).unwrap().distance(p);
                assert!(d < 1e-12, "vertex {v} left the boundary by {d}");
                slid += usize::from(p != original.positions[v as usize]);
            }
            assert_eq!(p.z, 0.0);
        }
        assert!(slid > 0);
    }

    /// A flat strip of sliver triangles between two boundary rows (every corner on the
    /// boundary, as between two of the bunny's base holes): the bottom row at `xs`, the top
    /// row at the midpoints of consecutive bottom vertices, at height `h`; counter-clockwise
    /// seen from +z.
    fn strip(xs: &[f64], h: f64) -> Mesh {
        let n = xs.len() as u32;
        let mut positions: Vec<DVec3> = xs.iter().map(|&x| DVec3::new(x, 0.0, 0.0)).collect();
        for w in xs.windows(2) {
            positions.push(DVec3::new(0.5 * (w[0] + w[1]), h, 0.0));
        }
        let top = |i: u32| n + i;
        let mut faces = Vec::new();
        for i in 0..n - 1 {
            faces.push([i, i + 1, top(i)]);
            if i + 1 < n - 1 {
                faces.push([i + 1, top(i + 1), top(i)]);
            }
        }
        Mesh::new(positions, faces)
    }

    /// A strip whose bottom row is twice as dense at its start.
    fn uneven_strip() -> Mesh {
        let xs: Vec<f64> = (0..30)
            .map(|i| {
                if i < 4 {
                    0.25 * f64::from(i)
                } else {
                    1.0 + 0.5 * f64::from(i - 4)
                }
            })
            .collect();
        strip(&xs, 1.6)
    }

    /// Rebalancing a strip of slivers gives it interior vertices: same vertex count, still
    /// one boundary loop, no face turned over, and a larger smallest angle.
    #[test]
    fn rebalancing_a_sliver_strip_keeps_the_count_and_lifts_its_smallest_angle() {
        let mut m = uneven_strip();
        let n = m.n_vertices();
        let params = RelaxParams {
            rebalance: 10,
            floor_deg: 40.0,
            ..RelaxParams::default()
        };
        let r = relax(&mut m, None, &params);
        assert!(r.rebalanced > 0, "{r:?}");
        assert!(r.min_angle_after > r.min_angle_before + 5.0, "{r:?}");
        assert_eq!(m.n_vertices(), n);
        let t = Topology::build(&m);
        assert!(t.is_manifold() && t.is_consistently_oriented());
        assert_eq!(t.n_boundary_loops(), 1);
        assert!((0..n as u32).all(|v| !t.is_isolated_vertex(v)));
        assert!(
            (0..n as u32).any(|v| !t.is_boundary_vertex(v)),
            "no interior vertex"
        );
        for f in 0..m.n_faces() {
            assert!(m.face_normal(f).z > 0.99, "face {f} turned");
        }
        // Without rebalancing the strip keeps its slivers.
        let mut plain = uneven_strip();
        let r0 = relax(
            &mut plain,
            None,
            &RelaxParams {
                floor_deg: 40.0,
                ..RelaxParams::default()
            },
        );
        assert!(
            r.min_angle_after > r0.min_angle_after + 5.0,
            "{r:?} vs {r0:?}"
        );
    }

    /// Attributes follow rebalancing: a vertex scalar equal to x stays equal to x (split
    /// and collapsed vertices sit at edge midpoints, their values blend the ends), and a
    /// face label keeps one value per face.
    #[test]
    fn rebalancing_carries_attributes() {
        let mut m = uneven_strip();
        let xs = m.positions.iter().map(|p| p.x).collect();
        m.vertex_attrs
            .insert("x", coarsen_mesh::AttrValues::Scalar(xs));
        let labels = (0..m.n_faces() as u32).collect();
        m.face_attrs
            .insert("id", coarsen_mesh::AttrValues::Label(labels));
        let params = RelaxParams {
            rebalance: 10,
            sweeps: 0,
            ..RelaxParams::default()
        };
        let r = relax(&mut m, None, &params);
        assert!(r.rebalanced > 0, "{r:?}");
        let x = m.vertex_attrs.scalar("x").unwrap();
        assert_eq!(x.len(), m.n_vertices());
        for (v, p) in m.positions.iter().enumerate() {
            assert!(
                (x[v] - p.x).abs() < 1e-12,
                "vertex {v}: {} vs {}",
                x[v],
                p.x
            );
        }
        assert_eq!(m.face_attrs.label("id").unwrap().len(), m.n_faces());
    }

    /// With `floor_deg`, moves also even the triangles out: the mean quality grows beyond
    /// what smallest-angle moves reach, and the smallest angle ends no lower than the
    /// floor or where it started.
    #[test]
    fn a_floor_trades_angle_above_it_for_shape() {
        let original = coarsen_shapes::icosphere(1.0, 4).unwrap();
        let surface = Surface::new(&original);
        let mut m = coarsen_shapes::icosphere(1.0, 3).unwrap();
        for (i, p) in m.positions.iter_mut().enumerate() {
            let t = (i as f64 * 12.9898).sin() * 0.05;
            *p = (*p + DVec3::new(t, -t, 0.5 * t)).normalize();
        }
        let mean_quality = |m: &Mesh| {
            (0..m.n_faces())
                .map(|f| {
                    let [a, b, c] = m.corners(f);
                    triangle::quality(a, b, c)
                })
                .sum::<f64>()
                / m.n_faces() as f64
        };
        let (mut plain, mut even) = (m.clone(), m);
        relax(&mut plain, Some(&surface), &RelaxParams::default());
        let params = RelaxParams {
            floor_deg: 40.0,
            ..RelaxParams::default()
        };
        let r = relax(&mut even, Some(&surface), &params);
        assert!(mean_quality(&even) > mean_quality(&plain) + 1e-3);
        assert!(
            r.min_angle_after >= r.min_angle_before.min(40.0) - 1e-9,
            "{r:?}"
        );
    }

    /// The largest distance from a vertex of `from` to the surface of `to`.
    fn farthest_vertex(from: &Mesh, to: &Mesh) -> f64 {
        let bvh = Bvh::build(&to.positions, &to.faces);
        from.positions
            .iter()
            .map(|&p| bvh.closest_point(p).unwrap().distance())
            .fold(0.0, f64::max)
    }

    /// Height of a narrow bump (0.02 high) centred at (`cx`, 0).
    fn bump(p: DVec3, cx: f64) -> f64 {
        let r2 = (p.x - cx).powi(2) + p.y.powi(2);
        0.02 * (-r2 / (0.03 * 0.03)).exp()
    }

    /// A flat grid of `n × n` cells, 1 wide, with every vertex lifted onto the bump at
    /// (`cx`, 0).
    fn bumped_grid(n: u32, cx: f64) -> Mesh {
        let mut m = coarsen_shapes::plane_grid(n, n, 1.0).unwrap();
        for p in &mut m.positions {
            p.z = bump(*p, cx);
        }
        m
    }

    /// `fit` puts a vertex on a bump the coarse mesh misses: the input's farthest point
    /// comes much nearer, the vertex count, the boundary loop and the orientation stay.
    #[test]
    fn fitting_puts_a_vertex_where_the_input_is_farthest() {
        let original = bumped_grid(64, 0.0625);
        let surface = Surface::new(&original);
        let mut m = bumped_grid(8, 0.0625);
        let before = farthest_vertex(&original, &m);
        let params = RelaxParams {
            fit: 4,
            sweeps: 0,
            floor_deg: 30.0,
            ..RelaxParams::default()
        };
        let r = relax(&mut m, Some(&surface), &params);
        assert!(r.fitted > 0, "{r:?}");
        let after = farthest_vertex(&original, &m);
        assert!(after < 0.8 * before, "{before} → {after}");
        assert_eq!(m.n_vertices(), 81);
        let t = Topology::build(&m);
        assert!(t.is_manifold() && t.is_consistently_oriented());
        assert_eq!(t.n_boundary_loops(), 1);
        assert!((0..81).all(|v| !t.is_isolated_vertex(v)));
        for f in 0..m.n_faces() {
            assert!(m.face_normal(f).z > 0.5, "face {f} turned");
        }
        // Without `fit` the bump stays missed.
        let mut plain = bumped_grid(8, 0.0625);
        relax(
            &mut plain,
            Some(&surface),
            &RelaxParams {
                sweeps: 0,
                ..RelaxParams::default()
            },
        );
        assert!(farthest_vertex(&original, &plain) > 0.9 * before);
    }

    /// With `max_dev_pct`, relaxing keeps a coarse vertex on the top of a bump (the input
    /// stays within the bound there) while still lifting the smallest angle elsewhere;
    /// without it the vertex slides off and the bump's top ends farther away.
    #[test]
    fn a_deviation_bound_keeps_the_input_near() {
        let original = bumped_grid(64, 0.0);
        let surface = Surface::new(&original);
        let top = DVec3::new(0.0, 0.0, 0.02);
        let mut m = bumped_grid(8, 0.0);
        let topo = Topology::build(&m);
        // Jitter the interior vertices in the plane, all but the one on the top.
        for (v, p) in m.positions.iter_mut().enumerate() {
            if !topo.is_boundary_vertex(v as u32) && p.truncate() != coarsen_geom::DVec2::ZERO {
                let t = (v as f64 * 12.9898).sin() * 0.03;
                p.x += t;
                p.y -= 0.7 * t;
                p.z = bump(*p, 0.0);
            }
        }
        let to_top = |m: &Mesh| farthest_vertex(&Mesh::new(vec![top], vec![]), m);
        assert!(to_top(&m) < 1e-12);
        let tol_pct = 0.05;
        let tol = 0.01 * tol_pct * original.bbox().diagonal();
        let (mut free, mut bound) = (m.clone(), m);
        let params = RelaxParams {
            floor_deg: 40.0,
            ..RelaxParams::default()
        };
        relax(&mut free, Some(&surface), &params);
        let r = relax(
            &mut bound,
            Some(&surface),
            &RelaxParams {
                max_dev_pct: tol_pct,
                ..params
            },
        );
        assert!(r.min_angle_after > r.min_angle_before, "{r:?}");
        assert!(
            to_top(&free) > tol,
            "{}: the case shows nothing",
            to_top(&free)
        );
        assert!(to_top(&bound) <= tol, "{} > {tol}", to_top(&bound));
    }

    /// Attributes follow `fit`'s edits: one value per vertex and per face, each face label
    /// one of the labels it started with.
    #[test]
    fn fitting_carries_attributes() {
        let original = bumped_grid(64, 0.0625);
        let surface = Surface::new(&original);
        let mut m = bumped_grid(8, 0.0625);
        let xs = m.positions.iter().map(|p| p.x).collect();
        m.vertex_attrs
            .insert("x", coarsen_mesh::AttrValues::Scalar(xs));
        let n_faces = m.n_faces() as u32;
        m.face_attrs.insert(
            "id",
            coarsen_mesh::AttrValues::Label((0..n_faces).collect()),
        );
        let params = RelaxParams {
            fit: 4,
            sweeps: 0,
            floor_deg: 30.0,
            ..RelaxParams::default()
        };
        let r = relax(&mut m, Some(&surface), &params);
        assert!(r.fitted > 0, "{r:?}");
        assert_eq!(m.vertex_attrs.scalar("x").unwrap().len(), m.n_vertices());
        let ids = m.face_attrs.label("id").unwrap();
        assert_eq!(ids.len(), m.n_faces());
        assert!(ids.iter().all(|&i| i < n_faces));
    }

    /// `fit` and the bound give the same bytes on any thread count.
    #[test]
    fn fitting_is_deterministic_across_thread_counts() {
        let original = bumped_grid(64, 0.0625);
        let params = RelaxParams {
            fit: 4,
            floor_deg: 30.0,
            max_dev_pct: 0.5,
            ..RelaxParams::default()
        };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let surface = Surface::new(&original);
                let mut m = bumped_grid(8, 0.0625);
                relax(&mut m, Some(&surface), &params);
                m
            })
        };
        let (a, b) = (run(1), run(3));
        assert_eq!(a.faces, b.faces);
        let bits = |m: &Mesh| {
            m.positions
                .iter()
                .flat_map(|p| p.to_array().map(f64::to_bits))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&a), bits(&b));
    }
}
