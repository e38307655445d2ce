//! Split/collapse pairs that move vertices from short edges to long ones, the vertex
//! count kept.
//!
//! Each pair is chosen on the mesh as the pair before left it. Rather than rebuilding the
//! adjacency for every pair, one is kept until a candidate touches a vertex whose faces
//! changed since it was built (then it is rebuilt); the edges and their face counts follow
//! every pair. The pairs are the same as with a fresh adjacency each time (tested).

use super::*;

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

/// Plans the collapse of edge `e` when it keeps the mesh manifold with its boundary loops
/// (link condition, no interior edge between two boundary vertices, no loop below four
/// vertices) and no remaining face around it turns by more than `cos_turn`, faces away
/// from `surface` or gets a smaller angle than `floor` (radians) or the smallest angle it
/// had around the edge, whichever is lower.
pub(crate) fn plan_collapse(
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
    let mut tris: Vec<[DVec3; 3]> = Vec::new();
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
pub(crate) fn rebalance(
    mesh: &mut Mesh,
    surface: Option<&Surface<'_>>,
    max_pairs: u32,
    cos_turn: f64,
    floor: f64,
) -> usize {
    rebalance_with(mesh, surface, max_pairs, cos_turn, floor, false).0
}

/// The adjacency a pair is planned with: built for the mesh as it was some pairs ago, with
/// the vertices whose faces changed since (`dirty`) and the current edges, sorted, with
/// their face counts. A pair that involves only clean vertices plans exactly as on a fresh
/// adjacency; one that would need a dirty vertex asks for a rebuild.
struct Snapshot {
    topo: Topology,
    ends: Vec<Vec<u32>>,
    dirty: Vec<bool>,
    edges: Vec<([u32; 2], u32)>,
}

impl Snapshot {
    fn new(mesh: &Mesh) -> Option<Snapshot> {
        let topo = Topology::try_build(mesh).ok()?;
        let edges = (0..topo.n_edges() as u32)
            .map(|e| (topo.edge(e), topo.edge_faces(e).len() as u32))
            .collect();
        Some(Snapshot {
            ends: boundary_neighbours(&topo, mesh.n_vertices()),
            dirty: vec![false; mesh.n_vertices()],
            edges,
            topo,
        })
    }

    fn clean(&self, [a, b]: [u32; 2]) -> bool {
        !self.dirty[a as usize] && !self.dirty[b as usize]
    }

    /// The snapshot's id of clean edge `ab`.
    fn id(&self, [a, b]: [u32; 2]) -> Option<u32> {
        self.topo.find_edge(a, b)
    }

    /// Counts the edges of `face` once more (`add`) or once less.
    fn count(&mut self, face: [u32; 3], add: bool) {
        for i in 0..3 {
            let (a, b) = (face[i], face[(i + 1) % 3]);
            let key = [a.min(b), a.max(b)];
            match (self.edges.binary_search_by(|(k, _)| k.cmp(&key)), add) {
                (Ok(i), true) => self.edges[i].1 += 1,
                (Err(i), true) => self.edges.insert(i, (key, 1)),
                (Ok(i), false) if self.edges[i].1 > 1 => self.edges[i].1 -= 1,
                (Ok(i), false) => {
                    self.edges.remove(i);
                }
                (Err(_), false) => {}
            }
        }
    }
}

/// What one round of [`rebalance`] found.
enum Found {
    /// This pair: the split edge's ends and faces, its new faces and midpoint, and the
    /// collapse.
    Pair {
        ends: [u32; 2],
        old: [u32; 2],
        new: [[u32; 3]; 4],
        at: DVec3,
        col: Collapse,
    },
    /// Nothing more to do.
    Nothing,
    /// A candidate touches a vertex whose faces changed since the snapshot.
    Stale,
}

/// The next pair (see [`rebalance`]), planned on `snap`.
fn find_pair(
    mesh: &Mesh,
    snap: &Snapshot,
    surface: Option<&Surface<'_>>,
    cos_turn: f64,
    floor: f64,
) -> Found {
    let edges = &snap.edges;
    if edges.is_empty() {
        return Found::Nothing;
    }
    let len = |[a, b]: [u32; 2]| mesh.positions[a as usize].distance(mesh.positions[b as usize]);
    let mean = edges.iter().map(|&(ab, _)| len(ab)).sum::<f64>() / edges.len() as f64;
    let topo = &snap.topo;
    // Interior edges long enough; on a dirty edge the boundary test is unknown, so it is
    // listed at the lower bar and planning it asks for a fresh snapshot.
    let mut splits: Vec<(f64, usize)> = edges
        .iter()
        .enumerate()
        .filter(|(_, (_, faces))| *faces == 2)
        .map(|(i, &(ab, _))| {
            let bridge = !snap.clean(ab)
                || (topo.is_boundary_vertex(ab[0]) && topo.is_boundary_vertex(ab[1]));
            (len(ab), i, bridge)
        })
        .filter(|&(l, _, bridge)| l > if bridge { SPLIT_RATIO } else { LONG_RATIO } * mean)
        .map(|(l, i, _)| (l, i))
        .collect();
    splits.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
    let mut collapses: Vec<(f64, usize)> = edges
        .iter()
        .enumerate()
        .map(|(i, &(ab, _))| (len(ab), i))
        .filter(|&(l, _)| l < COLLAPSE_RATIO * mean)
        .collect();
    collapses.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    'pair: for &(_, si) in &splits {
        let sab = edges[si].0;
        let Some(s) = snap.id(sab).filter(|_| snap.clean(sab)) else {
            return Found::Stale;
        };
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
            let Some(k) = snap.id(kab).filter(|_| snap.clean(kab)) else {
                return Found::Stale;
            };
            let Some(col) = plan_collapse(mesh, topo, &snap.ends, surface, k, cos_turn, floor)
            else {
                continue;
            };
            let Some((old, new)) = plan_split(mesh, topo, surface, s, col.gone, at, cos_turn)
            else {
                continue 'pair;
            };
            return Found::Pair {
                ends: sab,
                old,
                new,
                at,
                col,
            };
        }
    }
    Found::Nothing
}

/// [`rebalance`]; with `fresh`, the adjacency is rebuilt before every pair (the plain
/// algorithm the snapshots must reproduce). Returns the pairs made and the adjacencies
/// built.
pub(crate) fn rebalance_with(
    mesh: &mut Mesh,
    surface: Option<&Surface<'_>>,
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
    let carry = before.is_some();
    let mut done = 0;
    let mut snapshot: Option<Snapshot> = None;
    let mut built = 0;
    while done < max_pairs as usize {
        if snapshot.is_none() {
            snapshot = Snapshot::new(mesh);
            built += 1;
        }
        let Some(snap) = snapshot.as_mut() else {
            break;
        };
        let (ends, old, new, at, col) = match find_pair(mesh, snap, surface, cos_turn, floor) {
            Found::Nothing => break,
            Found::Stale => {
                snapshot = None;
                continue;
            }
            Found::Pair {
                ends,
                old,
                new,
                at,
                col,
            } => (ends, old, new, at, col),
        };
        let [c, d] = ends;
        if carry {
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
        // The faces the pair changes, as they were.
        let mut changed: Vec<(u32, [u32; 3])> = Vec::new();
        let touched = snap
            .topo
            .vertex_faces(col.gone)
            .iter()
            .chain(&old)
            .chain(&col.freed);
        for &f in touched {
            if !changed.iter().any(|&(g, _)| g == f) {
                changed.push((f, mesh.faces[f as usize]));
            }
        }
        // Collapse: `gone` becomes `keep`; its edge's faces are freed.
        for &f in snap.topo.vertex_faces(col.gone) {
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
        done += 1;
        if fresh {
            snapshot = None;
            continue;
        }
        // The snapshot's edges and dirty vertices follow the change.
        for &(f, was) in &changed {
            let now = mesh.faces[f as usize];
            snap.count(was, false);
            snap.count(now, true);
            for v in was.into_iter().chain(now) {
                snap.dirty[v as usize] = true;
            }
        }
        if let Some(f) = appended {
            let now = mesh.faces[f as usize];
            snap.count(now, true);
            for v in now {
                snap.dirty[v as usize] = true;
            }
        }
    }
    if let Some(before) = before.filter(|_| done > 0) {
        carry_attributes(mesh, &before, v_from, f_from);
    }
    (done, built)
}
