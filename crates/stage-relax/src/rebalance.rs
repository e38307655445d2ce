//! Split/collapse pairs that move vertices from short edges to long ones, the vertex
//! count kept.
//!
//! Each pair is chosen on the mesh as the pair before left it. Rather than rebuilding the
//! adjacency for every pair, a table of each vertex's faces and the edges with their face
//! counts follow every pair ([`Kept`]), and answer what planning asks (an edge's faces, a
//! vertex's neighbours and fans, boundary or not) from there. The pairs are the same as
//! with a [`Topology`] built afresh for each pair (tested).

use super::*;
use std::borrow::Cow;

/// An edge longer than this many mean edge lengths, joining two boundary vertices through
/// the interior, is split by [`rebalance`].
pub(crate) const SPLIT_RATIO: f64 = 1.5;
/// Any interior edge longer than this many mean edge lengths is split by [`rebalance`].
pub(crate) const LONG_RATIO: f64 = 1.6;
/// An edge shorter than this many mean edge lengths may be collapsed by [`rebalance`].
pub(crate) const COLLAPSE_RATIO: f64 = 0.8;

/// The third corner of face `f` after the directed edge `x → y`, if `f` has that edge.
pub(crate) fn after_edge(mesh: &Mesh, f: u32, x: u32, y: u32) -> Option<u32> {
    let t = mesh.faces[f as usize];
    (0..3)
        .find(|&i| t[i] == x && t[(i + 1) % 3] == y)
        .map(|i| t[(i + 2) % 3])
}

/// Where each vertex and face of an edited mesh comes from in the mesh the edits started
/// from (weighted vertices, parent face); kept only when that mesh has attributes to carry.
pub(crate) struct Origins {
    /// The mesh the edits started from, when it has attributes.
    pub(crate) before: Option<Mesh>,
    /// Per vertex, the vertices of `before` it blends.
    pub(crate) v_from: Vec<Vec<(u32, f64)>>,
    /// Per face, its face in `before`.
    pub(crate) f_from: Vec<u32>,
}

impl Origins {
    /// Every vertex and face of `mesh` its own origin (nothing kept without attributes).
    pub(crate) fn start(mesh: &Mesh) -> Origins {
        if mesh.vertex_attrs.is_empty() && mesh.face_attrs.is_empty() {
            return Origins {
                before: None,
                v_from: Vec::new(),
                f_from: Vec::new(),
            };
        }
        Origins {
            before: Some(mesh.clone()),
            v_from: (0..mesh.n_vertices() as u32)
                .map(|v| vec![(v, 1.0)])
                .collect(),
            f_from: (0..mesh.n_faces() as u32).collect(),
        }
    }
}

/// Gives the edited `mesh` the attributes of `before`, the mesh the edits started from:
/// each vertex blends the vertices `v_from` names, each face copies the face `f_from` names.
pub(crate) fn carry_attributes(
    mesh: &mut Mesh,
    before: &Mesh,
    v_from: Vec<Vec<(u32, f64)>>,
    f_from: Vec<u32>,
) {
    let mut vo = VertexOrigins::with_capacity(v_from.len());
    for src in v_from {
        vo.push_blend(src);
    }
    let fo = FaceOrigins::from_parents(f_from);
    let positions = std::mem::take(&mut mesh.positions);
    let faces = std::mem::take(&mut mesh.faces);
    *mesh = before.rebuilt(positions, faces, &vo, &fo).0;
}

/// Half of each of two vertices' origins.
pub(crate) fn blend_origins(x: &[(u32, f64)], y: &[(u32, f64)]) -> Vec<(u32, f64)> {
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
pub(crate) struct Collapse {
    pub(crate) keep: u32,
    pub(crate) gone: u32,
    pub(crate) at: DVec3,
    pub(crate) freed: Vec<u32>,
}

/// The adjacency questions planning a pair asks, about the mesh as it is: answered by a
/// [`Topology`] built for it ([`Built`]) or by the table [`Kept`] that follows each pair.
pub(crate) trait Adjacency {
    /// The ends of edge `e`.
    fn edge(&self, e: u32) -> [u32; 2];
    /// The faces of edge `e`, ascending.
    fn edge_faces(&self, e: u32) -> Cow<'_, [u32]>;
    /// True when edge `e` has exactly one face.
    fn is_boundary_edge(&self, e: u32) -> bool {
        self.edge_faces(e).len() == 1
    }
    /// The faces around vertex `v`.
    fn vertex_faces(&self, v: u32) -> Cow<'_, [u32]>;
    /// The vertices joined to `v` by an edge, each once.
    fn vertex_neighbors(&self, v: u32) -> Cow<'_, [u32]>;
    /// The fans the faces around `v` form (one for a manifold vertex).
    fn n_vertex_fans(&self, v: u32) -> usize;
    /// True when `v` is the end of an edge with one face.
    fn is_boundary_vertex(&self, v: u32) -> bool;
    /// The vertices joined to `v` by an edge with one face.
    fn boundary_neighbors(&self, v: u32) -> Cow<'_, [u32]>;
}

/// A [`Topology`] built for the mesh, with its [`boundary_neighbours`].
pub(crate) struct Built<'a> {
    pub(crate) topo: &'a Topology,
    pub(crate) ends: &'a [Vec<u32>],
}

impl Adjacency for Built<'_> {
    fn edge(&self, e: u32) -> [u32; 2] {
        self.topo.edge(e)
    }
    fn edge_faces(&self, e: u32) -> Cow<'_, [u32]> {
        Cow::Borrowed(self.topo.edge_faces(e))
    }
    fn is_boundary_edge(&self, e: u32) -> bool {
        self.topo.is_boundary_edge(e)
    }
    fn vertex_faces(&self, v: u32) -> Cow<'_, [u32]> {
        Cow::Borrowed(self.topo.vertex_faces(v))
    }
    fn vertex_neighbors(&self, v: u32) -> Cow<'_, [u32]> {
        Cow::Borrowed(self.topo.vertex_neighbors(v))
    }
    fn n_vertex_fans(&self, v: u32) -> usize {
        self.topo.n_vertex_fans(v)
    }
    fn is_boundary_vertex(&self, v: u32) -> bool {
        self.topo.is_boundary_vertex(v)
    }
    fn boundary_neighbors(&self, v: u32) -> Cow<'_, [u32]> {
        Cow::Borrowed(&self.ends[v as usize])
    }
}

/// The adjacency of a mesh kept up to date pair by pair: each vertex's faces (ascending)
/// and the edges (sorted) with their face counts. Planning reads it through [`OnMesh`].
pub(crate) struct Kept {
    faces_of: Vec<Vec<u32>>,
    edges: Vec<([u32; 2], u32)>,
}

impl Kept {
    /// The table of `mesh`, whose edges (sorted, with their face counts) are `edges`.
    fn new(mesh: &Mesh, edges: Vec<([u32; 2], u32)>) -> Kept {
        let mut faces_of = vec![Vec::new(); mesh.n_vertices()];
        for (f, face) in mesh.faces.iter().enumerate() {
            for &v in face {
                faces_of[v as usize].push(f as u32);
            }
        }
        Kept { faces_of, edges }
    }

    /// Face `f` was `was` (none for a new face) and is `now`: the table follows.
    fn replace(&mut self, f: u32, was: Option<[u32; 3]>, now: [u32; 3]) {
        if let Some(was) = was {
            count_edges(&mut self.edges, was, false);
            for v in was {
                let list = &mut self.faces_of[v as usize];
                if let Ok(i) = list.binary_search(&f) {
                    list.remove(i);
                }
            }
        }
        count_edges(&mut self.edges, now, true);
        for v in now {
            let list = &mut self.faces_of[v as usize];
            if let Err(i) = list.binary_search(&f) {
                list.insert(i, f);
            }
        }
    }
}

/// A [`Kept`] table read with the faces of its mesh; an edge's id is its place in the
/// table's sorted edges.
pub(crate) struct OnMesh<'a> {
    kept: &'a Kept,
    faces: &'a [[u32; 3]],
}

impl OnMesh<'_> {
    /// The faces of `v` that also have `w`, ascending.
    fn shared(&self, v: u32, w: u32) -> impl Iterator<Item = u32> + '_ {
        self.kept.faces_of[v as usize]
            .iter()
            .copied()
            .filter(move |&f| self.faces[f as usize].contains(&w))
    }
}

impl Adjacency for OnMesh<'_> {
    fn edge(&self, e: u32) -> [u32; 2] {
        self.kept.edges[e as usize].0
    }
    fn edge_faces(&self, e: u32) -> Cow<'_, [u32]> {
        let [a, b] = self.edge(e);
        Cow::Owned(self.shared(a, b).collect())
    }
    fn vertex_faces(&self, v: u32) -> Cow<'_, [u32]> {
        Cow::Borrowed(&self.kept.faces_of[v as usize])
    }
    fn vertex_neighbors(&self, v: u32) -> Cow<'_, [u32]> {
        let mut out: Vec<u32> = Vec::new();
        for &f in &self.kept.faces_of[v as usize] {
            for w in self.faces[f as usize] {
                if w != v && !out.contains(&w) {
                    out.push(w);
                }
            }
        }
        Cow::Owned(out)
    }
    fn n_vertex_fans(&self, v: u32) -> usize {
        // Faces around `v` joined across their edges at `v` (a union-find over a handful).
        let faces = &self.kept.faces_of[v as usize];
        let mut root: Vec<usize> = (0..faces.len()).collect();
        fn find(root: &mut [usize], mut i: usize) -> usize {
            while root[i] != i {
                i = root[i];
            }
            i
        }
        for i in 0..faces.len() {
            for j in i + 1..faces.len() {
                let (fi, fj) = (self.faces[faces[i] as usize], self.faces[faces[j] as usize]);
                if fi.iter().any(|&w| w != v && fj.contains(&w)) {
                    let (ri, rj) = (find(&mut root, i), find(&mut root, j));
                    root[ri.max(rj)] = ri.min(rj);
                }
            }
        }
        (0..faces.len())
            .filter(|&i| find(&mut root, i) == i)
            .count()
    }
    fn is_boundary_vertex(&self, v: u32) -> bool {
        !self.boundary_neighbors(v).is_empty()
    }
    fn boundary_neighbors(&self, v: u32) -> Cow<'_, [u32]> {
        Cow::Owned(
            self.vertex_neighbors(v)
                .iter()
                .copied()
                .filter(|&w| self.shared(v, w).count() == 1)
                .collect(),
        )
    }
}

/// The edges of `topo` (sorted) with their face counts.
fn edge_counts(topo: &Topology) -> Vec<([u32; 2], u32)> {
    (0..topo.n_edges() as u32)
        .map(|e| (topo.edge(e), topo.edge_faces(e).len() as u32))
        .collect()
}

/// Counts the edges of `face` once more (`add`) or once less in the sorted `edges`.
fn count_edges(edges: &mut Vec<([u32; 2], u32)>, face: [u32; 3], add: bool) {
    for i in 0..3 {
        let (a, b) = (face[i], face[(i + 1) % 3]);
        let key = [a.min(b), a.max(b)];
        match (edges.binary_search_by(|(k, _)| k.cmp(&key)), add) {
            (Ok(i), true) => edges[i].1 += 1,
            (Err(i), true) => edges.insert(i, (key, 1)),
            (Ok(i), false) if edges[i].1 > 1 => edges[i].1 -= 1,
            (Ok(i), false) => {
                edges.remove(i);
            }
            (Err(_), false) => {}
        }
    }
}

/// Plans the collapse of edge `e` when it keeps the mesh manifold with its boundary loops
/// (link condition, no interior edge between two boundary vertices, no loop below four
/// vertices) and no remaining face around it turns by more than `cos_turn`, faces away
/// from `surface` or gets a smaller angle than `floor` (radians) or the smallest angle it
/// had around the edge, whichever is lower.
pub(crate) fn plan_collapse(
    mesh: &Mesh,
    topo: &impl Adjacency,
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
    let (na, nb) = (topo.vertex_neighbors(a), topo.vertex_neighbors(b));
    let common = na.iter().filter(|w| nb.contains(w)).count();
    if common != opposite.len() {
        return None;
    }
    let (ba, bb) = (topo.is_boundary_vertex(a), topo.is_boundary_vertex(b));
    let (keep, gone, at) = if topo.is_boundary_edge(e) {
        let (ea, eb) = (topo.boundary_neighbors(a), topo.boundary_neighbors(b));
        if ea.iter().any(|w| eb.contains(w)) {
            return None;
        }
        let mid = mesh.positions[a as usize].lerp(mesh.positions[b as usize], 0.5);
        let at = match surface {
            Some(s) => s.project_boundary_along(
                mesh.positions[a as usize],
                mid,
                BOUNDARY_REACH * mesh.positions[a as usize].distance(mesh.positions[b as usize]),
            )?,
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
    let mut tris: Vec<[DVec3; 3]> = Vec::new();
    for &v in &[a, b] {
        for &f in topo.vertex_faces(v).iter() {
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
            if n_new.dot(n_old) < cos_turn {
                return None;
            }
            after = after.min(triangle::min_angle(new[0], new[1], new[2]));
            tris.push(new);
        }
    }
    // The facing test last: it is the costly one (a query of the input's index per face).
    (after >= before.min(floor)
        && surface.is_none_or(|s| tris.iter().all(|[a, b, c]| s.agrees(*a, *b, *c))))
    .then(|| Collapse {
        keep,
        gone,
        at,
        freed: ef.to_vec(),
    })
}

/// The faces replacing the two faces of interior edge `e` when it is split at a new vertex
/// `m` at `at`, and the two faces they replace; `None` when a new face turns by more than
/// `cos_turn` from the face it comes from or faces away from `surface`.
pub(crate) fn plan_split(
    mesh: &Mesh,
    topo: &impl Adjacency,
    surface: Option<&Surface<'_>>,
    e: u32,
    m: u32,
    at: DVec3,
    cos_turn: f64,
) -> Option<([u32; 2], [[u32; 3]; 4])> {
    let ef = topo.edge_faces(e);
    let &[f1, f2] = &ef[..] else {
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
pub(crate) fn rebalance(
    mesh: &mut Mesh,
    surface: Option<&Surface<'_>>,
    rails: &Rails,
    max_pairs: u32,
    cos_turn: f64,
    floor: f64,
) -> usize {
    rebalance_with(mesh, surface, rails, max_pairs, cos_turn, floor, false).0
}

/// What one round of [`rebalance`] found: the split edge's ends and faces, its new faces
/// and midpoint, and the collapse.
struct Pair {
    ends: [u32; 2],
    old: [u32; 2],
    new: [[u32; 3]; 4],
    at: DVec3,
    col: Collapse,
}

/// The next pair (see [`rebalance`]) of `mesh`, whose adjacency is `topo` and whose edges
/// (sorted, with their face counts) are `edges`; `id` names an edge of `topo` by its ends
/// and its place in `edges`.
// The mesh and its adjacency in either form, what it is kept on and the two bounds.
#[allow(clippy::too_many_arguments)]
fn find_pair<A: Adjacency>(
    mesh: &Mesh,
    topo: &A,
    edges: &[([u32; 2], u32)],
    id: impl Fn([u32; 2], usize) -> Option<u32>,
    surface: Option<&Surface<'_>>,
    rails: &Rails,
    cos_turn: f64,
    floor: f64,
) -> Option<Pair> {
    if edges.is_empty() {
        return None;
    }
    let len = |[a, b]: [u32; 2]| mesh.positions[a as usize].distance(mesh.positions[b as usize]);
    let mean = edges.iter().map(|&(ab, _)| len(ab)).sum::<f64>() / edges.len() as f64;
    // Interior edges long enough (those joining two boundary vertices at a lower bar, asked
    // only of edges between the two bars).
    let bridge = |[a, b]: [u32; 2]| topo.is_boundary_vertex(a) && topo.is_boundary_vertex(b);
    let mut splits: Vec<(f64, usize)> = edges
        .iter()
        .enumerate()
        .filter(|(_, (_, faces))| *faces == 2)
        .map(|(i, &(ab, _))| (len(ab), i, ab))
        .filter(|&(l, _, ab)| l > LONG_RATIO * mean || (l > SPLIT_RATIO * mean && bridge(ab)))
        .filter(|&(_, _, [a, b])| !rails.is_rail_edge(a, b))
        .map(|(l, i, _)| (l, i))
        .collect();
    splits.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
    let mut collapses: Vec<(f64, usize)> = edges
        .iter()
        .enumerate()
        .filter(|(_, ([a, b], _))| !rails.locked(*a) && !rails.locked(*b))
        .map(|(i, &(ab, _))| (len(ab), i))
        .filter(|&(l, _)| l < COLLAPSE_RATIO * mean)
        .collect();
    collapses.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    'pair: for &(_, si) in &splits {
        let sab = edges[si].0;
        let s = id(sab, si)?;
        let [c, d] = sab;
        let mid = mesh.positions[c as usize].lerp(mesh.positions[d as usize], 0.5);
        let at = surface.and_then(|sf| sf.project(mid)).unwrap_or(mid);
        let around: Vec<u32> = topo
            .edge_faces(s)
            .iter()
            .flat_map(|&f| mesh.faces[f as usize])
            .collect();
        for &(_, ki) in &collapses {
            let kab = edges[ki].0;
            let [a, b] = kab;
            if around.contains(&a) || around.contains(&b) {
                continue;
            }
            let k = id(kab, ki)?;
            let Some(col) = plan_collapse(mesh, topo, surface, k, cos_turn, floor) else {
                continue;
            };
            let Some((old, new)) = plan_split(mesh, topo, surface, s, col.gone, at, cos_turn)
            else {
                continue 'pair;
            };
            return Some(Pair {
                ends: sab,
                old,
                new,
                at,
                col,
            });
        }
    }
    None
}

/// [`rebalance`]; with `fresh`, on a [`Topology`] built afresh for every pair (the plain
/// algorithm the kept table must reproduce) instead of the [`Kept`] table. Returns the
/// pairs made and the adjacencies built.
pub(crate) fn rebalance_with(
    mesh: &mut Mesh,
    surface: Option<&Surface<'_>>,
    rails: &Rails,
    max_pairs: u32,
    cos_turn: f64,
    floor: f64,
    fresh: bool,
) -> (usize, usize) {
    let Origins {
        before,
        mut v_from,
        mut f_from,
    } = Origins::start(mesh);
    let mut done = 0;
    let mut built = 0;
    let mut kept: Option<Kept> = None;
    while done < max_pairs as usize {
        let found = match kept.as_ref() {
            Some(k) => pair_on_kept(mesh, k, surface, rails, cos_turn, floor),
            None => {
                let Ok(topo) = Topology::try_build(mesh) else {
                    break;
                };
                built += 1;
                let (found, edges) = pair_on_built(mesh, &topo, surface, rails, cos_turn, floor);
                if !fresh {
                    kept = Some(Kept::new(mesh, edges));
                }
                found
            }
        };
        let Some((pair, around_gone)) = found else {
            break;
        };
        if before.is_some() {
            carry_pair_origins(mesh, &pair, &mut v_from, &mut f_from);
        }
        let (changed, appended) = apply_pair(mesh, pair, &around_gone);
        done += 1;
        // The kept table follows the change.
        if let Some(k) = kept.as_mut() {
            for &(f, was) in &changed {
                k.replace(f, Some(was), mesh.faces[f as usize]);
            }
            if let Some(f) = appended {
                k.replace(f, None, mesh.faces[f as usize]);
            }
        }
    }
    if let Some(before) = before.filter(|_| done > 0) {
        carry_attributes(mesh, &before, v_from, f_from);
    }
    (done, built)
}

/// A pair found, and the faces around its collapsed vertex before it.
type Found = Option<(Pair, Vec<u32>)>;

/// The next pair found on the table `k` that follows the pairs made, and the faces around
/// its collapsed vertex before it.
fn pair_on_kept(
    mesh: &Mesh,
    k: &Kept,
    surface: Option<&Surface<'_>>,
    rails: &Rails,
    cos_turn: f64,
    floor: f64,
) -> Found {
    let adjacency = OnMesh {
        kept: k,
        faces: &mesh.faces,
    };
    let id = |_, i: usize| Some(i as u32);
    find_pair(
        mesh, &adjacency, &k.edges, id, surface, rails, cos_turn, floor,
    )
    .map(|p| {
        let around = k.faces_of[p.col.gone as usize].clone();
        (p, around)
    })
}

/// The next pair found on `topo`, built for `mesh` as it is, and the faces around its
/// collapsed vertex before it; with the edges ([`edge_counts`]) that a [`Kept`] table
/// following the pairs from there starts from.
fn pair_on_built(
    mesh: &Mesh,
    topo: &Topology,
    surface: Option<&Surface<'_>>,
    rails: &Rails,
    cos_turn: f64,
    floor: f64,
) -> (Found, Vec<([u32; 2], u32)>) {
    let edges = edge_counts(topo);
    let ends = boundary_neighbours(topo, mesh.n_vertices());
    let adjacency = Built { topo, ends: &ends };
    let id = |[a, b]: [u32; 2], _| topo.find_edge(a, b);
    let found = find_pair(
        mesh, &adjacency, &edges, id, surface, rails, cos_turn, floor,
    )
    .map(|p| {
        let around = topo.vertex_faces(p.col.gone).to_vec();
        (p, around)
    });
    (found, edges)
}

/// Records where the vertices and faces `pair` changes come from: the collapse's kept
/// vertex blends both ends when it moves, the split's new vertex (the collapse's gone one)
/// the split edge's ends; each new face has the old face it replaces as parent.
fn carry_pair_origins(
    mesh: &Mesh,
    pair: &Pair,
    v_from: &mut [Vec<(u32, f64)>],
    f_from: &mut Vec<u32>,
) {
    let (col, old, [c, d]) = (&pair.col, &pair.old, pair.ends);
    if col.at != mesh.positions[col.keep as usize] {
        v_from[col.keep as usize] =
            blend_origins(&v_from[col.keep as usize], &v_from[col.gone as usize]);
    }
    v_from[col.gone as usize] = blend_origins(&v_from[c as usize], &v_from[d as usize]);
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

/// Makes `pair` (`around_gone`: the faces around its collapsed vertex): the collapse, then
/// the split's new faces in the split's two faces and the collapse's freed ones (two, or
/// one on the boundary: then the last new face is appended). Returns the faces changed as
/// they were, and the appended face.
fn apply_pair(
    mesh: &mut Mesh,
    pair: Pair,
    around_gone: &[u32],
) -> (Vec<(u32, [u32; 3])>, Option<u32>) {
    let Pair {
        old, new, at, col, ..
    } = pair;
    let mut changed: Vec<(u32, [u32; 3])> = Vec::new();
    for &f in around_gone.iter().chain(&old).chain(&col.freed) {
        if !changed.iter().any(|&(g, _)| g == f) {
            changed.push((f, mesh.faces[f as usize]));
        }
    }
    // Collapse: `gone` becomes `keep`; its edge's faces are freed.
    for &f in around_gone {
        for w in &mut mesh.faces[f as usize] {
            if *w == col.gone {
                *w = col.keep;
            }
        }
    }
    mesh.positions[col.keep as usize] = col.at;
    mesh.positions[col.gone as usize] = at;
    let mut slots = vec![old[0], old[1]];
    slots.extend(&col.freed);
    let mut appended = None;
    for (i, t) in new.into_iter().enumerate() {
        match slots.get(i) {
            Some(&f) => mesh.faces[f as usize] = t,
            None => {
                appended = Some(mesh.faces.len() as u32);
                mesh.faces.push(t);
            }
        }
    }
    (changed, appended)
}
