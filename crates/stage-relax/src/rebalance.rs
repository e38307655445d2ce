//! Split/collapse pairs that move vertices from short edges to long ones, the vertex
//! count kept.
//!
//! Each pair is chosen on the mesh as the pair before left it: an [`Editable`] with its
//! edges, built once, follows every pair and answers what planning asks.

use super::*;
use coarsen_edit::{Editable, Rules};

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
#[derive(Clone)]
pub(crate) struct Collapse {
    pub(crate) keep: u32,
    pub(crate) gone: u32,
    pub(crate) at: DVec3,
    pub(crate) freed: Vec<u32>,
}

/// The topological checks of [`plan_collapse`]: both ends one fan, and no boundary loop
/// left below four vertices (besides the checks every collapse passes).
const COLLAPSE_RULES: Rules = Rules {
    one_fan: true,
    loops_of_three: true,
    every_vertex_kept: false,
};

/// Plans the collapse of edge `a`–`b` (of `edit`, the adjacency of `mesh`) when it keeps
/// the mesh manifold with its boundary loops ([`Editable::can_collapse`] with
/// [`COLLAPSE_RULES`]) and no remaining face around it turns by more than `cos_turn`,
/// faces away from `surface` or gets a smaller angle than `floor` (radians) or the
/// smallest angle it had around the edge, whichever is lower.
pub(crate) fn plan_collapse(
    mesh: &Mesh,
    edit: &Editable,
    surface: Option<&Surface<'_>>,
    [a, b]: [u32; 2],
    cos_turn: f64,
    floor: f64,
) -> Option<Collapse> {
    edit.can_collapse(a, b, COLLAPSE_RULES).ok()?;
    let ef = edit.edge_faces(a, b);
    let (keep, gone, at) = if ef.len() == 1 {
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
        // Not both ends on the boundary: `can_collapse` refused that bridge.
        match (edit.is_boundary_vertex(a), edit.is_boundary_vertex(b)) {
            (true, _) => (a, b, mesh.positions[a as usize]),
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
        for &f in edit.faces_around(v) {
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
    .then_some(Collapse {
        keep,
        gone,
        at,
        freed: ef,
    })
}

/// The faces replacing the two faces of interior edge `c`–`d` (of `edit`, the adjacency
/// of `mesh`) when it is split at a new vertex `m` at `at`, and the two faces they
/// replace; `None` when a new face turns by more than `cos_turn` from the face it comes
/// from or faces away from `surface`.
pub(crate) fn plan_split(
    mesh: &Mesh,
    edit: &Editable,
    surface: Option<&Surface<'_>>,
    [c, d]: [u32; 2],
    m: u32,
    at: DVec3,
    cos_turn: f64,
) -> Option<([u32; 2], [[u32; 3]; 4])> {
    let &[f1, f2] = &edit.edge_faces(c, d)[..] else {
        return None;
    };
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
    let mut run = Pairing::start(mesh, rails);
    while run.done < max_pairs as usize {
        let Some(pair) = find_pair(mesh, &run.edit, surface, rails, cos_turn, floor) else {
            break;
        };
        run.apply(mesh, pair);
    }
    run.finish(mesh)
}

/// A run of split/collapse pairs: the adjacency that follows them (with the corners and
/// rails as its constraints), where each vertex and face comes from (when there are
/// attributes to carry), the pairs made.
struct Pairing {
    origins: Origins,
    edit: Editable,
    done: usize,
}

impl Pairing {
    /// A run starting on `mesh`, its collapses keeping the corners and rails of `rails`.
    fn start(mesh: &Mesh, rails: &Rails) -> Pairing {
        Pairing {
            origins: Origins::start(mesh),
            edit: Editable::new(mesh.n_vertices(), mesh.faces.clone())
                .with_edges()
                .with_constraints(rails.constraints().clone()),
            done: 0,
        }
    }

    /// Makes `pair` on `mesh`, recording where what it changes comes from.
    fn apply(&mut self, mesh: &mut Mesh, pair: Pair) {
        let o = &mut self.origins;
        if o.before.is_some() {
            carry_pair_origins(mesh, &pair, &mut o.v_from, &mut o.f_from);
        }
        apply_pair(mesh, &mut self.edit, pair);
        self.done += 1;
    }

    /// Gives `mesh` its attributes back (see [`carry_attributes`]); the pairs made.
    fn finish(self, mesh: &mut Mesh) -> usize {
        let Origins {
            before,
            v_from,
            f_from,
        } = self.origins;
        if let Some(before) = before.filter(|_| self.done > 0) {
            carry_attributes(mesh, &before, v_from, f_from);
        }
        self.done
    }
}

/// Split edges [`unturn`] tries for one collapse, longest first, at most.
const UNTURN_SPLIT_TRIES: usize = 64;

/// Up to `max_pairs` times: collapses an edge of a face facing away from `surface` (the
/// face goes with it, or is renamed off the fold) where fewer faces around the edge face
/// away after than before, none that did not face away turns by 90° or more (or more than
/// `cos_turn` allows, if that is looser: where a part is thinner than the faces, mending
/// turns faces far) and none gets an angle under half of `floor` (radians) or of the
/// smallest angle around the edge, whichever is lower; paired with the
/// split of a long interior edge elsewhere at its midpoint on `surface`, so the vertex
/// count stays. What moves, flips and splits cannot mend (a turned face whose every
/// vertex is held by the others) goes this way. Rounds over the faces facing away until
/// one makes no pair. Attributes follow as in [`rebalance`]. Returns the pairs made.
pub(crate) fn unturn(
    mesh: &mut Mesh,
    surface: &Surface<'_>,
    rails: &Rails,
    max_pairs: u32,
    cos_turn: f64,
    floor: f64,
) -> usize {
    let mut run = Pairing::start(mesh, rails);
    while run.done < max_pairs as usize {
        let away: Vec<u32> = (0..mesh.n_faces() as u32)
            .filter(|&f| {
                let [a, b, c] = mesh.corners(f as usize);
                !surface.agrees(a, b, c)
            })
            .collect();
        // The interior edges, longest first (stale once pairs are made: checked again).
        let pos = |v: u32| mesh.positions[v as usize];
        let mut splits: Vec<(f64, [u32; 2])> = run
            .edit
            .edges()
            .expect("unturn keeps the edges")
            .iter()
            .filter(|&(&[a, b], &faces)| faces == 2 && !rails.is_rail_edge(a, b))
            .map(|(&[a, b], _)| (pos(a).distance(pos(b)), [a, b]))
            .collect();
        splits.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
        let start = run.done;
        for f in away {
            if run.done >= max_pairs as usize {
                break;
            }
            let found = unturning_pair(mesh, &run.edit, surface, &splits, f, cos_turn, floor);
            if let Some(pair) = found {
                run.apply(mesh, pair);
            }
        }
        if run.done == start {
            break;
        }
    }
    run.finish(mesh)
}

/// The pair of [`unturn`] for face `f` when it still faces away: the first edge of its
/// corners that can go (its own edges shortest first, then the corners' other edges
/// shortest first; no corner or rail vertex, `edit`'s constraints), and the first edge of
/// `splits` away from that collapse that splits
/// without a new face facing away.
fn unturning_pair(
    mesh: &Mesh,
    edit: &Editable,
    surface: &Surface<'_>,
    splits: &[(f64, [u32; 2])],
    f: u32,
    cos_turn: f64,
    floor: f64,
) -> Option<Pair> {
    let pos = |v: u32| mesh.positions[v as usize];
    let len = |[a, b]: [u32; 2]| pos(a).distance(pos(b));
    let t = mesh.faces[f as usize];
    let [a, b, c] = t.map(pos);
    if !edit.is_alive(f) || surface.agrees(a, b, c) {
        return None;
    }
    let mut sides: Vec<[u32; 2]> = (0..3).map(|k| [t[k], t[(k + 1) % 3]]).collect();
    sides.sort_by(|&x, &y| len(x).total_cmp(&len(y)));
    let mut others: Vec<[u32; 2]> = Vec::new();
    for v in t {
        for &g in edit.faces_around(v) {
            for w in edit.face(g) {
                if !t.contains(&w) && !others.contains(&[v, w]) {
                    others.push([v, w]);
                }
            }
        }
    }
    others.sort_by(|&x, &y| len(x).total_cmp(&len(y)).then(x.cmp(&y)));
    sides.extend(others);
    for side in sides {
        let Some(col) = plan_unturning_collapse(mesh, edit, surface, side, cos_turn, floor) else {
            continue;
        };
        // Still an interior edge, and no face of it touches the collapse.
        let splittable = |&&(_, [c, d]): &&(f64, [u32; 2])| {
            let faces = edit.edge_faces(c, d);
            faces.len() == 2
                && !faces
                    .iter()
                    .flat_map(|&g| edit.face(g))
                    .any(|w| w == col.keep || w == col.gone)
        };
        for &(_, sab) in splits.iter().filter(splittable).take(UNTURN_SPLIT_TRIES) {
            let [c, d] = sab;
            let Some(at) = surface.project(pos(c).lerp(pos(d), 0.5)) else {
                continue;
            };
            let pair = Pair::with_split(mesh, edit, Some(surface), sab, at, &col, cos_turn);
            if pair.is_some() {
                return pair;
            }
        }
    }
    None
}

/// Plans the collapse of edge `a`–`b` (of `edit`, the adjacency of `mesh`) of a face
/// facing away from `surface`, for [`unturn`]: the topological checks of
/// [`plan_collapse`]; the merged vertex at a boundary end, else at the edge's midpoint on
/// the input or at either end, whichever leaves fewest faces around it facing away (fewer
/// than before), then the largest smallest angle; none that did not face away turning by
/// 90° or more (or more than `cos_turn` allows, if looser), none with an angle under half
/// of `floor` (when above 0) or of the smallest angle around the edge, whichever is lower.
fn plan_unturning_collapse(
    mesh: &Mesh,
    edit: &Editable,
    surface: &Surface<'_>,
    [a, b]: [u32; 2],
    cos_turn: f64,
    floor: f64,
) -> Option<Collapse> {
    edit.can_collapse(a, b, COLLAPSE_RULES).ok()?;
    let ef = edit.edge_faces(a, b);
    let pos = |v: u32| mesh.positions[v as usize];
    let (keep, gone) = (a.min(b), a.max(b));
    let spots: Vec<DVec3> = match (edit.is_boundary_vertex(a), edit.is_boundary_vertex(b)) {
        (true, true) if ef.len() == 1 => vec![pos(a), pos(b)],
        (true, true) => return None,
        (true, false) => vec![pos(a)],
        (false, true) => vec![pos(b)],
        (false, false) => surface
            .project(pos(a).lerp(pos(b), 0.5))
            .into_iter()
            .chain([pos(a), pos(b)])
            .collect(),
    };
    // The faces left around the merged vertex, with whether each faced away before.
    let mut before = f64::INFINITY;
    let mut away_before = 0;
    let mut kept: Vec<([u32; 3], bool, DVec3)> = Vec::new();
    for v in [a, b] {
        for &f in edit.faces_around(v) {
            let t = mesh.faces[f as usize];
            if v == b && t.contains(&a) {
                continue;
            }
            let [x, y, z] = t.map(pos);
            before = before.min(triangle::min_angle(x, y, z));
            let away = !surface.agrees(x, y, z);
            away_before += away as usize;
            if !ef.contains(&f) {
                kept.push((t, away, triangle::normal(x, y, z)));
            }
        }
    }
    let guard = 0.5
        * if floor > 0.0 {
            before.min(floor)
        } else {
            before
        };
    // (faces left facing away, smallest angle) with the merged vertex at `at`.
    let judge = |at: DVec3| -> Option<(usize, f64)> {
        let mut worst = f64::INFINITY;
        let mut n_away = 0;
        for &(t, away, n_old) in &kept {
            let [x, y, z] = t.map(|w| if w == a || w == b { at } else { pos(w) });
            let n_new = triangle::normal(x, y, z);
            let angle = triangle::min_angle(x, y, z);
            if (!away && n_new.dot(n_old) < cos_turn.min(0.0)) || angle < guard {
                return None;
            }
            n_away += !surface.agrees(x, y, z) as usize;
            worst = worst.min(angle);
        }
        (n_away < away_before).then_some((n_away, worst))
    };
    let (_, at) = spots
        .into_iter()
        .filter_map(|at| judge(at).map(|w| (w, at)))
        .min_by(|x, y| x.0.0.cmp(&y.0.0).then(y.0.1.total_cmp(&x.0.1)))?;
    Some(Collapse {
        keep,
        gone,
        at,
        freed: ef,
    })
}

/// What one round of [`rebalance`] found: the split edge's ends and faces, its midpoint,
/// and the collapse.
struct Pair {
    ends: [u32; 2],
    old: [u32; 2],
    at: DVec3,
    col: Collapse,
}

impl Pair {
    /// Collapse `col` paired with the split of edge `ends` at `at`, when the split can be
    /// made (see [`plan_split`]).
    fn with_split(
        mesh: &Mesh,
        edit: &Editable,
        surface: Option<&Surface<'_>>,
        ends: [u32; 2],
        at: DVec3,
        col: &Collapse,
        cos_turn: f64,
    ) -> Option<Pair> {
        let (old, _) = plan_split(mesh, edit, surface, ends, col.gone, at, cos_turn)?;
        Some(Pair {
            ends,
            old,
            at,
            col: col.clone(),
        })
    }
}

/// The next pair (see [`rebalance`]) of `mesh`, whose adjacency is `edit` (with its
/// edges); among edges of equal length the first in `edit`'s order goes first.
fn find_pair(
    mesh: &Mesh,
    edit: &Editable,
    surface: Option<&Surface<'_>>,
    rails: &Rails,
    cos_turn: f64,
    floor: f64,
) -> Option<Pair> {
    // One pass over the edges (ends ascending, in ascending order), then a list's.
    let len = |[a, b]: [u32; 2]| mesh.positions[a as usize].distance(mesh.positions[b as usize]);
    let edges: Vec<(f64, [u32; 2], u32)> = edit
        .edges()
        .expect("rebalance keeps the edges")
        .iter()
        .map(|(&ab, &faces)| (len(ab), ab, faces))
        .collect();
    if edges.is_empty() {
        return None;
    }
    let mean = edges.iter().map(|e| e.0).sum::<f64>() / edges.len() as f64;
    // Interior edges long enough (those joining two boundary vertices at a lower bar, asked
    // only of edges between the two bars).
    let bridge = |[a, b]: [u32; 2]| edit.is_boundary_vertex(a) && edit.is_boundary_vertex(b);
    // Candidates as (length, place in `edges`): ties go in `edges`' order.
    let mut splits: Vec<(f64, usize)> = edges
        .iter()
        .enumerate()
        .filter(|&(_, &(l, ab, faces))| {
            faces == 2 && (l > LONG_RATIO * mean || (l > SPLIT_RATIO * mean && bridge(ab)))
        })
        .filter(|&(_, &(_, [a, b], _))| !rails.is_rail_edge(a, b))
        .map(|(i, &(l, _, _))| (l, i))
        .collect();
    splits.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
    let mut collapses: Vec<(f64, usize)> = edges
        .iter()
        .enumerate()
        .filter(|&(_, &(l, _, _))| l < COLLAPSE_RATIO * mean)
        .map(|(i, &(l, _, _))| (l, i))
        .collect();
    collapses.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    'pair: for &(_, si) in &splits {
        let sab = edges[si].1;
        let [c, d] = sab;
        let mid = mesh.positions[c as usize].lerp(mesh.positions[d as usize], 0.5);
        let at = surface.and_then(|sf| sf.project(mid)).unwrap_or(mid);
        let around: Vec<u32> = edit
            .edge_faces(c, d)
            .iter()
            .flat_map(|&f| mesh.faces[f as usize])
            .collect();
        for &(_, ki) in &collapses {
            let kab = edges[ki].1;
            let [a, b] = kab;
            if around.contains(&a) || around.contains(&b) {
                continue;
            }
            let Some(col) = plan_collapse(mesh, edit, surface, kab, cos_turn, floor) else {
                continue;
            };
            let Some(pair) = Pair::with_split(mesh, edit, surface, sab, at, &col, cos_turn) else {
                continue 'pair;
            };
            return Some(pair);
        }
    }
    None
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

/// Makes `pair` on `edit` and `mesh`: the collapse, then the split
/// ([`Editable::split_edge`]) at the collapse's freed vertex, its new faces in the split's
/// two faces and the collapse's freed ones (two, or one on the boundary: then the last
/// new face is appended).
fn apply_pair(mesh: &mut Mesh, edit: &mut Editable, pair: Pair) {
    let Pair { ends, at, col, .. } = pair;
    // The faces the collapse renames (its freed ones among them).
    let renamed = edit.faces_around(col.gone).to_vec();
    let freed = edit.collapse(col.keep, col.gone);
    debug_assert_eq!(freed, col.freed);
    mesh.positions[col.keep as usize] = col.at;
    mesh.positions[col.gone as usize] = at;
    let reuse = [freed.first().copied(), freed.get(1).copied()];
    let slots = edit
        .split_edge(ends, col.gone, reuse)
        .expect("a split planned on this mesh, away from the collapse");
    // The mesh's faces follow, slot for slot.
    mesh.faces
        .extend_from_slice(&edit.faces()[mesh.faces.len()..]);
    for &f in renamed.iter().chain(&slots) {
        mesh.faces[f as usize] = edit.face(f);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tests::{jitter_on_sphere, uneven_strip};

    /// A vertex pushed past a neighbour folds faces over; the pairs collapse the fold away
    /// and split a long edge elsewhere: none faces away after, the vertex count stays, the
    /// mesh stays closed and manifold. A mesh with nothing facing away is left as it is.
    #[test]
    fn unturning_pairs_collapse_a_fold_away() {
        let original = coarsen_shapes::icosphere(1.0, 4).unwrap();
        let surface = Surface::new(&original);
        let clean = coarsen_shapes::icosphere(1.0, 3).unwrap();
        let mut folded = clean.clone();
        let t = Topology::build(&folded);
        let (v, w) = (100u32, t.vertex_neighbors(100)[0]);
        let (pv, pw) = (folded.positions[v as usize], folded.positions[w as usize]);
        folded.positions[v as usize] = (pw + 0.4 * (pw - pv)).normalize();
        let away = |m: &Mesh| {
            (0..m.n_faces())
                .filter(|&f| {
                    let [a, b, c] = m.corners(f);
                    !surface.agrees(a, b, c)
                })
                .count()
        };
        let before = away(&folded);
        assert!(before > 0, "the push folded nothing");
        let (floor, cos_turn) = (40f64.to_radians(), 30f64.to_radians().cos());
        let rails = Rails::default();
        let mut m = folded.clone();
        let made = unturn(&mut m, &surface, &rails, 8, cos_turn, floor);
        assert!(made > 0);
        assert_eq!(away(&m), 0, "{made} pairs");
        assert_eq!(m.n_vertices(), folded.n_vertices());
        assert_eq!(m.n_faces(), folded.n_faces());
        let topo = Topology::try_build(&m).expect("manifold");
        assert!((0..topo.n_edges() as u32).all(|e| topo.edge_faces(e).len() == 2));
        let mut same = clean.clone();
        assert_eq!(unturn(&mut same, &surface, &rails, 8, cos_turn, floor), 0);
        assert_eq!(same.positions, clean.positions);
        assert_eq!(same.faces, clean.faces);
    }

    /// The editable mesh following the pairs is, after each pair, the one built afresh
    /// from the mesh (faces slot for slot, each vertex's faces, the edges with their
    /// counts): the pairs are those planned on an adjacency built afresh for each.
    #[test]
    fn the_editable_following_the_pairs_is_the_one_built_afresh() {
        let sphere = coarsen_shapes::icosphere(1.0, 4).unwrap();
        let mut jittered = coarsen_shapes::icosphere(1.0, 3).unwrap();
        jitter_on_sphere(&mut jittered, 11, 0.12);
        let surface = Surface::new(&sphere);
        let (floor, cos_turn) = (40f64.to_radians(), 30f64.to_radians().cos());
        for (name, mut m, surface) in [
            ("strip", uneven_strip(), None),
            ("sphere", jittered.clone(), None),
            ("sphere on its input", jittered, Some(&surface)),
        ] {
            let rails = Rails::default();
            let mut edit = Editable::new(m.n_vertices(), m.faces.clone()).with_edges();
            let mut pairs = 0;
            while pairs < 40 {
                let Some(pair) = find_pair(&m, &edit, surface, &rails, cos_turn, floor) else {
                    break;
                };
                apply_pair(&mut m, &mut edit, pair);
                pairs += 1;
                let fresh = Editable::new(m.n_vertices(), m.faces.clone()).with_edges();
                assert_eq!(edit.faces(), &m.faces[..], "{name}: pair {pairs}");
                assert!((0..m.n_faces() as u32).all(|f| edit.is_alive(f)), "{name}");
                assert_eq!(edit.edges(), fresh.edges(), "{name}: pair {pairs}");
                for v in 0..m.n_vertices() as u32 {
                    assert_eq!(edit.faces_around(v), fresh.faces_around(v), "{name}: {v}");
                }
            }
            assert!(pairs >= 5, "{name}: {pairs} pairs");
        }
    }
}
