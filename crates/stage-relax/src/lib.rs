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
//! The report gives `moved` (moves kept, per sweep), `flipped` (edges flipped, per sweep),
//! `rebalanced` (split/collapse pairs) and `min_angle_before` / `min_angle_after` in
//! degrees.

use coarsen_geom::{DVec3, triangle};
use coarsen_mesh::{FaceOrigins, Topology, VertexOrigins};
use coarsen_metrics::{Facing, SurfaceIndex};
use coarsen_spatial::closest_point_on_segment;
use coarsen_stage::{
    Context, Contract, Mesh, Needs, ParamIssue, Params, Stage, StageError, params,
};
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
        Surface { facing, boundary }
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
/// from the face it replaces, and both agree with `surface`. `topo` is `mesh`'s adjacency
/// before the sweep. Returns the flips made.
fn flip_sweep(
    mesh: &mut Mesh,
    topo: &Topology,
    surface: Option<&Surface<'_>>,
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
        if !ok {
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
    if params.rebalance > 0 {
        out.rebalanced = rebalance(
            mesh,
            surface.filter(|_| params.project),
            params.rebalance,
            cos_turn,
            params.floor_deg.to_radians(),
        );
    }
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
    for _ in 0..params.sweeps {
        if params.flips {
            let flipped = flip_sweep(
                mesh,
                &topo,
                surface,
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
            if let Some(&(_, q)) = ranked.iter().find(|(_, q)| agrees(*q)) {
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
    const SUMMARY: &'static str = "Tangential relaxation on the input surface: vertex moves and edge flips that raise the smallest angle (or, above `floor_deg`, the shape), optional split/collapse rebalancing; no face flipped, vertex count kept.";

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
}
