//! Fidelity edits (a split where the input is farthest, paired with the least-moving
//! collapse) and the watch that bounds how far the sweeps may leave the input.

use super::*;
use coarsen_edit::Editable;
use std::collections::HashSet;

/// Points of the input whose distance to `mesh` is watched (true: on the boundary): its
/// used vertices, edge midpoints, face centroids and the points halfway from each centroid
/// to a corner; only those farther than `min_dist` from `mesh`. Builds the input's
/// adjacency for its edges (the surface index keeps only what the projections need).
/// The points are tested as they are made, so only those kept are ever held (at 4.4M
/// input faces all of them would be 27M points, 850 MB).
pub(crate) fn input_samples(
    surface: &Surface<'_>,
    mesh: &Mesh,
    min_dist: f64,
) -> Vec<(DVec3, bool)> {
    let input = surface.mesh;
    let t = &Topology::build(input);
    let bvh = (mesh.n_faces() > 0).then(|| Bvh::build(&mesh.positions, &mesh.faces));
    let far = |q: DVec3| {
        bvh.as_ref()
            .is_none_or(|bvh| bvh.closest_point(q).is_none_or(|h| h.distance() > min_dist))
    };
    // In parallel; `collect` keeps the order, so the result is the same on any thread count.
    let mut samples: Vec<(DVec3, bool)> = (0..input.n_vertices() as u32)
        .into_par_iter()
        .filter(|&v| !t.is_isolated_vertex(v))
        .map(|v| (input.positions[v as usize], t.is_boundary_vertex(v)))
        .filter(|&(q, _)| far(q))
        .collect();
    samples.par_extend((0..t.n_edges() as u32).into_par_iter().filter_map(|e| {
        let [a, b] = t.edge(e);
        let mid = input.positions[a as usize].lerp(input.positions[b as usize], 0.5);
        far(mid).then(|| (mid, t.is_boundary_edge(e)))
    }));
    samples.par_extend((0..input.n_faces()).into_par_iter().flat_map_iter(|f| {
        let [a, b, c] = input.corners(f);
        let g = (a + b + c) / 3.0;
        [g, g.lerp(a, 0.5), g.lerp(b, 0.5), g.lerp(c, 0.5)]
            .into_iter()
            .filter(|&q| far(q))
            .map(|q| (q, false))
    }));
    samples
}

/// Input points nearer the mesh than this fraction of `max_dev_pct` are not watched (a
/// move or a flip changes the surface too little to take them beyond it).
pub(crate) const WATCH_FROM: f64 = 0.5;

/// The input points the sweeps keep near the mesh (`max_dev_pct`), grouped by the mesh
/// face nearest to each.
pub(crate) struct Watch {
    /// The points.
    pub(crate) samples: Vec<DVec3>,
    /// The bound.
    pub(crate) tol: f64,
    /// Where each face's points start in `ids` (one more entry than faces).
    pub(crate) offsets: Vec<u32>,
    /// Point indices, face by face.
    pub(crate) ids: Vec<u32>,
    /// Each point's distance to the mesh when grouped.
    pub(crate) dist: Vec<f64>,
}

impl Watch {
    /// The points `samples` (from [`input_samples`]), kept within `tol`.
    pub(crate) fn new(samples: &[(DVec3, bool)], tol: f64) -> Watch {
        Watch {
            samples: samples.iter().map(|x| x.0).collect(),
            tol,
            offsets: Vec::new(),
            ids: Vec::new(),
            dist: Vec::new(),
        }
    }

    /// Groups the points by their nearest face of `mesh`.
    pub(crate) fn assign(&mut self, mesh: &Mesh) {
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
    pub(crate) fn allows(&self, faces: &[u32], tris: &[[DVec3; 3]]) -> bool {
        faces.iter().all(|&f| {
            let (a, b) = (self.offsets[f as usize], self.offsets[f as usize + 1]);
            self.ids[a as usize..b as usize].iter().all(|&i| {
                let limit = self.tol.max(self.dist[i as usize]) * (1.0 + 1e-9);
                distance_to(self.samples[i as usize], tris) <= limit
            })
        })
    }
}

/// The farthest from the input of the points a quarter, half and three quarters along the
/// segment `a`–`b` (a boundary chord), with its distance; `None` when none projects.
pub(crate) fn chord_far_point(surface: &Surface<'_>, a: DVec3, b: DVec3) -> Option<(f64, DVec3)> {
    [0.25, 0.5, 0.75]
        .map(|t| a.lerp(b, t))
        .into_iter()
        .filter_map(|q| surface.project(q).map(|on| (q.distance(on), q)))
        .max_by(|x, y| x.0.total_cmp(&y.0))
}

/// [`fit`] splits, in one round, only where the input lies at least this fraction of the
/// round's largest distance from the mesh.
pub(crate) const FIT_BAND: f64 = 0.7;
/// A collapse made by [`fit`] may move the surface by at most this fraction of the distance
/// its split removes (or by `max_dev_pct`, whichever is larger).
pub(crate) const FIT_TRADE: f64 = 0.5;
/// Without `max_dev_pct`, [`fit`] works on the input points farther from the mesh than
/// this fraction of the farthest.
pub(crate) const FIT_FROM: f64 = 0.5;
/// [`fit`]'s new faces keep at least this fraction of the smaller of `floor_deg` and the
/// mesh's smallest angle (the sweeps after it lift them again).
pub(crate) const FIT_GUARD: f64 = 0.8;
/// [`fit`] stops once this many far points in a row, farthest first, got no edit: on a mesh
/// far too coarse for the bound, each of the input's points would otherwise be tried and
/// given up one by one (the bunny at 35 vertices with `max_dev_pct` 0.3: 390K points, 95 s).
/// Of the `goal` runs measured, only the beetle at 380 vertices reaches it (after 39 edits;
/// 40 without the stop); the others give up at most 299 in a row (suzanne at 500).
pub(crate) const FIT_MAX_FAILS: usize = 2048;

/// Distance from `p` to the nearest of the triangles `tris` (infinite when there is none).
pub(crate) fn distance_to(p: DVec3, tris: &[[DVec3; 3]]) -> f64 {
    tris.iter()
        .map(|[a, b, c]| closest_point_on_triangle(p, *a, *b, *c).0.distance(p))
        .fold(f64::INFINITY, f64::min)
}

/// True when the centroid or an edge midpoint of one of `tris` lies farther than `bound`
/// from the input surface.
pub(crate) fn leaves_input(surface: &Surface<'_>, tris: &[[DVec3; 3]], bound: f64) -> bool {
    tris.iter().any(|[a, b, c]| {
        [
            (*a + *b + *c) / 3.0,
            a.lerp(*b, 0.5),
            b.lerp(*c, 0.5),
            c.lerp(*a, 0.5),
        ]
        .into_iter()
        .any(|x| {
            surface
                .project_within(x, bound)
                .is_none_or(|y| y.distance(x) > bound)
        })
    })
}

/// How far collapsing edge `e` into `at` moves the surface: the larger distance from its two
/// ends to the faces left around `at`.
pub(crate) fn collapse_error(
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
pub(crate) fn plan_boundary_split(
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
pub(crate) fn pull(
    mesh: &mut Mesh,
    topo: &Topology,
    surface: &Surface<'_>,
    edges: &[(f64, u32)],
    p: DVec3,
    on_boundary: bool,
    back: f64,
    guard: f64,
    cos_turn: f64,
    stays: &dyn Fn(u32) -> bool,
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
                || stays(w)
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
                surface.project_boundary_along(old, half, BOUNDARY_REACH * old.distance(p))
            } else {
                surface.project(half)
            };
            normals.clear();
            normals.extend(fan.iter().map(|&f| {
                let [a, b, c] = mesh.corners(f as usize);
                triangle::normal(a, b, c)
            }));
            for q in std::iter::once(p).chain(half) {
                let Some((worst, _)) = fan_shape(
                    &mesh.faces,
                    fan,
                    w,
                    q,
                    |x| mesh.positions[x as usize],
                    &normals,
                    cos_turn,
                ) else {
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
/// [`Mesh::rebuilt`]. Stops early once [`FIT_MAX_FAILS`] far points in a row got no edit.
/// Returns the edits made (pairs and pulls) and the points given up.
// The mesh, what it is kept on and to, and the four bounds of the edits.
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit(
    mesh: &mut Mesh,
    surface: &Surface<'_>,
    rails: &mut Rails,
    max_pairs: u32,
    cos_turn: f64,
    floor: f64,
    tol: f64,
    samples: &[(DVec3, bool)],
) -> (usize, usize) {
    let limits = Limits {
        max_pairs: max_pairs as usize,
        cos_turn,
        floor,
        tol,
        guard: fit_guard(mesh, floor),
    };
    let (mut run, before) = Fitting::begin(mesh, surface, rails, samples, limits);
    while run.done < run.limits.max_pairs && run.round() {}
    run.end(before)
}

/// Up to `max_pairs` times, in rounds, for the faces of `mesh` facing away from `surface`
/// that moves and flips left (a part of the input thinner than a face): splits an edge
/// of such a face at a point of the input on the side the face faces, where fewer of the
/// new faces face away than of the old, paired with the collapse elsewhere that moves the
/// surface least (at most [`FIT_TRADE`] of how far the face's centroid is from that side);
/// the angle guard and the rails as in [`fit`]. Returns the pairs made.
pub(crate) fn unfold(
    mesh: &mut Mesh,
    surface: &Surface<'_>,
    rails: &mut Rails,
    max_pairs: u32,
    cos_turn: f64,
    floor: f64,
) -> usize {
    let limits = Limits {
        max_pairs: max_pairs as usize,
        cos_turn,
        floor,
        tol: 0.0,
        guard: fit_guard(mesh, floor),
    };
    let (mut run, before) = Fitting::begin(mesh, surface, rails, &[], limits);
    while run.done < run.limits.max_pairs && run.unfold_round() {}
    run.end(before).0
}

/// The smallest angle [`fit`] lets a new face have: [`FIT_GUARD`] of `floor` or of the
/// mesh's smallest angle, whichever is lower (of the mesh's without a floor).
fn fit_guard(mesh: &Mesh, floor: f64) -> f64 {
    let smallest = (0..mesh.n_faces())
        .map(|f| {
            let [a, b, c] = mesh.corners(f);
            triangle::min_angle(a, b, c)
        })
        .fold(f64::INFINITY, f64::min);
    FIT_GUARD
        * if floor > 0.0 {
            floor.min(smallest)
        } else {
            smallest
        }
}

/// Whether the faces `new` of a split at `at` (its new vertex written [`NEW_VERTEX`]) have
/// no angle under `guard` and leave no input point near them beyond `bound` (`tris` is
/// scratch).
fn split_fits(
    mesh: &Mesh,
    surface: &Surface<'_>,
    new: &[[u32; 3]],
    at: DVec3,
    guard: f64,
    bound: f64,
    tris: &mut Vec<[DVec3; 3]>,
) -> bool {
    let place = |t: &[u32; 3]| {
        t.map(|w| match w {
            NEW_VERTEX => at,
            w => mesh.positions[w as usize],
        })
    };
    new.iter().all(|t| {
        let [a, b, c] = place(t);
        triangle::min_angle(a, b, c) >= guard
    }) && {
        tris.clear();
        tris.extend(new.iter().map(place));
        !leaves_input(surface, tris, bound)
    }
}

/// The bounds of one [`fit`].
struct Limits {
    max_pairs: usize,
    cos_turn: f64,
    floor: f64,
    tol: f64,
    /// The smallest angle of a new face ([`fit_guard`]).
    guard: f64,
}

/// What [`fit`] carries from round to round.
struct Fitting<'m, 's> {
    mesh: &'m mut Mesh,
    surface: &'m Surface<'s>,
    samples: &'m [(DVec3, bool)],
    limits: Limits,
    /// Whether the origins below are kept (the mesh has attributes).
    carry: bool,
    v_from: Vec<Vec<(u32, f64)>>,
    f_from: Vec<u32>,
    /// The corners and rails (see [`Rails`]): no edit moves their vertices; a far point
    /// by a rail edge gets a split of it on the rail (see [`Fitting::visit_rail`]).
    rails: &'m mut Rails,
    /// Points no split, collapse or pull could bring nearer: left alone from then on.
    given_up: Vec<bool>,
    /// The round's far points on the mesh's boundary chords (see
    /// [`Fitting::chord_points`]), numbered after `samples`: the input boundary point
    /// nearest each, and the chord it is for.
    chords: Vec<(DVec3, [u32; 2])>,
    /// Chords (ends ascending) none of whose far points could be brought nearer.
    chords_given_up: HashSet<[u32; 2]>,
    /// The points looked at: after the first round, only those that were beyond `tol`
    /// (the edits keep the others within it), or without a bound beyond [`FIT_FROM`] of the
    /// farthest.
    active: Vec<u32>,
    first: bool,
    tris: Vec<[DVec3; 3]>,
    /// Edits made.
    done: usize,
    /// Far points given up in a row since the last edit.
    fails: usize,
}

/// The mesh of one round as its edits read it (the edits touch no vertex twice in a round,
/// so what they read stays true for the vertices not yet touched).
struct RoundMesh<'t> {
    topo: &'t Topology,
    /// The same adjacency (as `topo`, from the round's start), as planning asks it.
    edit: Editable,
    boundary_edges: Vec<u32>,
    /// Collapse candidates, least surface moved first: (error, length, edge).
    collapses: Vec<(f64, f64, u32)>,
    /// The largest bound at which each collapse candidate was refused this round
    /// (infinite: not plannable): refused at no larger one either, it is not planned
    /// again. A candidate whose ends are not touched keeps its neighbourhood all round
    /// (every edit marks the vertices of the faces it changes and moves).
    refused_at: Vec<f64>,
    touched: Vec<bool>,
}

/// A split planned at a far point: edge `edge` split at `at`, the faces `old` replaced by
/// `new` (the new vertex written [`NEW_VERTEX`]), `around` the vertices of `old`.
struct SplitPlan {
    edge: u32,
    at: DVec3,
    old: Vec<u32>,
    new: Vec<[u32; 3]>,
    around: Vec<u32>,
}

/// The new vertex of a planned split, until the collapse paired with it frees one.
const NEW_VERTEX: u32 = u32::MAX;

/// What one far point's visit did to the round.
enum Visited {
    /// Nothing, or an edit after which the round goes on.
    Next,
    /// An edit that changed the face indices: the round ends.
    Reindexed,
}

impl<'m, 's> Fitting<'m, 's> {
    /// A run of edits on `mesh` watching the input points `samples` (all active, the
    /// first round to come), with the mesh as it was when it has attributes to carry.
    fn begin(
        mesh: &'m mut Mesh,
        surface: &'m Surface<'s>,
        rails: &'m mut Rails,
        samples: &'m [(DVec3, bool)],
        limits: Limits,
    ) -> (Fitting<'m, 's>, Option<Mesh>) {
        let origins = Origins::start(mesh);
        let run = Fitting {
            mesh,
            surface,
            samples,
            limits,
            carry: origins.before.is_some(),
            v_from: origins.v_from,
            f_from: origins.f_from,
            rails,
            given_up: vec![false; samples.len()],
            chords: Vec::new(),
            chords_given_up: HashSet::new(),
            active: (0..samples.len() as u32).collect(),
            first: true,
            tris: Vec::new(),
            done: 0,
            fails: 0,
        };
        (run, origins.before)
    }

    /// Ends the run: the attributes of `before` carried onto the edited mesh; the edits
    /// made and the points given up.
    fn end(self, before: Option<Mesh>) -> (usize, usize) {
        let Fitting {
            mesh,
            done,
            given_up,
            v_from,
            f_from,
            ..
        } = self;
        if let Some(before) = before.filter(|_| done > 0) {
            carry_attributes(mesh, &before, v_from, f_from);
        }
        (done, given_up.iter().filter(|&&g| g).count())
    }

    /// One round: the far points, then an edit at each in turn. False when [`fit`] ends.
    fn round(&mut self) -> bool {
        let Ok(topo) = Topology::try_build(self.mesh) else {
            return false;
        };
        if topo.n_edges() == 0 || self.mesh.n_faces() == 0 {
            return false;
        }
        let mut far = self.far_points();
        far.extend(self.chord_points(&topo));
        far.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
        let Some(&(d_max, _, _)) = far.first() else {
            return false;
        };
        let tol = self.limits.tol;
        if d_max.is_nan() || d_max <= tol {
            return false;
        }
        let mut round = self.round_mesh(&topo);
        let mut made = 0;
        for &(d, iv, f) in far
            .iter()
            .take_while(|x| x.0 >= FIT_BAND * d_max && x.0 > tol)
        {
            if self.done >= self.limits.max_pairs {
                break;
            }
            if self.fails >= FIT_MAX_FAILS {
                return false;
            }
            let before = self.done;
            let visited = self.visit(&mut round, d, iv, f);
            made += self.done - before;
            if let Visited::Reindexed = visited {
                break;
            }
        }
        made > 0 || far.iter().any(|x| x.0 > tol && !self.is_given_up(x.1))
    }

    /// One round of [`unfold`]: a pair at each face facing away in turn. False when no
    /// pair was made.
    fn unfold_round(&mut self) -> bool {
        let Ok(topo) = Topology::try_build(self.mesh) else {
            return false;
        };
        let surface = self.surface;
        let away: Vec<u32> = (0..self.mesh.n_faces() as u32)
            .filter(|&f| {
                let [a, b, c] = self.mesh.corners(f as usize);
                !surface.agrees(a, b, c)
            })
            .collect();
        if away.is_empty() {
            return false;
        }
        let mut round = self.round_mesh(&topo);
        let before = self.done;
        for f in away {
            if self.done >= self.limits.max_pairs {
                break;
            }
            if let Visited::Reindexed = self.visit_away(&mut round, f) {
                break;
            }
        }
        self.done > before
    }

    /// Face `f`, facing away: the first split of one of its interior edges (longest first)
    /// at a point of the input on the side it faces that leaves fewer new faces facing away
    /// than old, paired with a collapse elsewhere.
    fn visit_away(&mut self, round: &mut RoundMesh<'_>, f: u32) -> Visited {
        let (mesh, topo, surface) = (&*self.mesh, round.topo, self.surface);
        let face = mesh.faces[f as usize];
        if face
            .iter()
            .any(|&w| round.touched[w as usize] || self.rails.locked(w))
        {
            return Visited::Next;
        }
        let pos = |w: u32| mesh.positions[w as usize];
        let [a, b, c] = face.map(pos);
        let normal = triangle::cross(a, b, c);
        let centroid = triangle::centroid(a, b, c);
        let Some(side) = surface.project_facing(centroid, normal) else {
            return Visited::Next;
        };
        let mut edges: Vec<(f64, u32)> = topo
            .face_edges(f)
            .into_iter()
            .filter(|&e| topo.edge_faces(e).len() == 2)
            .map(|e| (edge_length(mesh, topo, e), e))
            .collect();
        edges.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
        let l = &self.limits;
        let n_away = |tris: &mut dyn Iterator<Item = [DVec3; 3]>| {
            tris.filter(|[x, y, z]| !surface.agrees(*x, *y, *z)).count()
        };
        let mut plan = None;
        'edges: for &(_, e) in &edges {
            let [p, q] = topo.edge(e);
            let old: Vec<u32> = topo.edge_faces(e).to_vec();
            let around: Vec<u32> = old.iter().flat_map(|&g| mesh.faces[g as usize]).collect();
            if around
                .iter()
                .any(|&w| round.touched[w as usize] || self.rails.locked(w))
            {
                continue;
            }
            let mid = pos(p).lerp(pos(q), 0.5);
            let was = n_away(&mut old.iter().map(|&g| mesh.corners(g as usize)));
            let cands = [
                Some(side),
                surface.project_facing(mid, normal),
                surface.project(mid),
            ];
            for at in cands.into_iter().flatten() {
                let Some((old, new)) =
                    plan_split(mesh, &round.edit, None, [p, q], NEW_VERTEX, at, l.cos_turn)
                else {
                    continue;
                };
                let place = |t: &[u32; 3]| t.map(|w| if w == NEW_VERTEX { at } else { pos(w) });
                if new.iter().any(|t| {
                    let [x, y, z] = place(t);
                    triangle::min_angle(x, y, z) < 0.5 * l.guard
                }) {
                    continue;
                }
                if n_away(&mut new.iter().map(place)) < was {
                    plan = Some(SplitPlan {
                        edge: e,
                        at,
                        old: old.to_vec(),
                        new: new.to_vec(),
                        around,
                    });
                    break 'edges;
                }
            }
        }
        let Some(split) = plan else {
            return Visited::Next;
        };
        let gain = centroid.distance(side);
        let Some(col) = self.pick_collapse(round, &split, gain) else {
            return Visited::Next;
        };
        self.done += 1;
        match self.apply_pair(round, split, col) {
            true => Visited::Reindexed,
            false => Visited::Next,
        }
    }

    /// The active points not given up with their distance to the mesh and nearest face
    /// (in no order); after the first round's, only the points beyond the bound stay
    /// active.
    fn far_points(&mut self) -> Vec<(f64, u32, u32)> {
        let bvh = Bvh::build(&self.mesh.positions, &self.mesh.faces);
        let (samples, given_up) = (self.samples, &self.given_up);
        let mut far: Vec<(f64, u32, u32)> = self
            .active
            .par_iter()
            .filter(|&&i| !given_up[i as usize])
            .filter_map(|&i| {
                bvh.closest_point(samples[i as usize].0)
                    .map(|h| (h.distance(), i, h.face))
            })
            .collect();
        if std::mem::take(&mut self.first) {
            let d_max = far.iter().map(|x| x.0).fold(0.0, f64::max);
            let tol = self.limits.tol;
            let keep = if tol > 0.0 { tol } else { FIT_FROM * d_max };
            far.retain(|x| x.0 > keep);
            self.active = far.iter().map(|x| x.1).collect();
            self.active.sort_unstable();
        }
        far
    }

    /// The far points of the mesh's boundary chords: where a boundary edge (adjacency
    /// `topo`) passes farther than `tol` from the input (over a bay of a hole's rim that
    /// the input points by it do not see, being near the face), the point of the input
    /// boundary along the chord's loop nearest its farthest sample (a quarter, half and
    /// three quarters along), as `(distance, number after the samples, the edge's face)`.
    /// Chords given up are left out.
    fn chord_points(&mut self, topo: &Topology) -> Vec<(f64, u32, u32)> {
        self.chords.clear();
        let (mesh, surface, tol) = (&*self.mesh, self.surface, self.limits.tol);
        if tol <= 0.0 {
            return Vec::new();
        }
        let mut out = Vec::new();
        for e in 0..topo.n_edges() as u32 {
            let &[f] = topo.edge_faces(e) else {
                continue;
            };
            let [a, b] = topo.edge(e);
            let key = [a.min(b), a.max(b)];
            if self.chords_given_up.contains(&key) {
                continue;
            }
            let (pa, pb) = (mesh.positions[a as usize], mesh.positions[b as usize]);
            let Some((d, q)) = chord_far_point(surface, pa, pb).filter(|&(d, _)| d > tol) else {
                continue;
            };
            // On the loop the chord's ends lie on, within reach of them.
            let reach = BOUNDARY_REACH * pa.distance(pb);
            let Some(p) = surface.project_boundary_along(pa, q, reach) else {
                continue;
            };
            out.push((d, (self.samples.len() + self.chords.len()) as u32, f));
            self.chords.push((p, key));
        }
        out
    }

    /// Far point `iv`: an input sample, or after them the round's chord points; with
    /// whether it lies on the boundary.
    fn sample(&self, iv: u32) -> (DVec3, bool) {
        match (iv as usize).checked_sub(self.samples.len()) {
            None => self.samples[iv as usize],
            Some(k) => (self.chords[k].0, true),
        }
    }

    /// Leaves far point `iv` alone from now on (a chord point: its chord).
    fn give_up(&mut self, iv: u32) {
        match (iv as usize).checked_sub(self.samples.len()) {
            None => self.given_up[iv as usize] = true,
            Some(k) => {
                self.chords_given_up.insert(self.chords[k].1);
            }
        }
    }

    /// Whether far point `iv` was given up.
    fn is_given_up(&self, iv: u32) -> bool {
        match (iv as usize).checked_sub(self.samples.len()) {
            None => self.given_up[iv as usize],
            Some(k) => self.chords_given_up.contains(&self.chords[k].1),
        }
    }

    /// The round's view of the mesh (adjacency `topo`) and its collapse candidates: edges
    /// shorter than the mean, ranked by the surface their collapse at the midpoint moves.
    fn round_mesh<'t>(&mut self, topo: &'t Topology) -> RoundMesh<'t> {
        let mesh = &*self.mesh;
        let n_edges = topo.n_edges();
        let len = |e: u32| edge_length(mesh, topo, e);
        let mean = (0..n_edges as u32).map(len).sum::<f64>() / n_edges as f64;
        let boundary_edges: Vec<u32> = (0..n_edges as u32)
            .filter(|&e| topo.is_boundary_edge(e))
            .collect();
        let tris = &mut self.tris;
        let mut collapses: Vec<(f64, f64, u32)> = (0..n_edges as u32)
            .map(|e| (len(e), e))
            .filter(|&(l, _)| l < mean)
            .map(|(l, e)| {
                let [a, b] = topo.edge(e);
                let mid = mesh.positions[a as usize].lerp(mesh.positions[b as usize], 0.5);
                (collapse_error(mesh, topo, e, mid, tris), l, e)
            })
            .collect();
        collapses.sort_by(|x, y| {
            x.0.total_cmp(&y.0)
                .then(x.1.total_cmp(&y.1))
                .then(x.2.cmp(&y.2))
        });
        RoundMesh {
            topo,
            edit: Editable::new(mesh.n_vertices(), mesh.faces.clone())
                .with_constraints(self.rails.constraints().clone()),
            boundary_edges,
            refused_at: vec![f64::NEG_INFINITY; collapses.len()],
            collapses,
            touched: vec![false; mesh.n_vertices()],
        }
    }

    /// The far point `iv` (at distance `d`, nearest face `f`): a split there paired with a
    /// collapse, or a pull, or the point given up.
    fn visit(&mut self, round: &mut RoundMesh<'_>, d: f64, iv: u32, f: u32) -> Visited {
        let face = self.mesh.faces[f as usize];
        if face.iter().any(|&w| round.touched[w as usize]) {
            return Visited::Next;
        }
        if face.iter().any(|&w| self.rails.locked(w)) {
            return self.visit_rail(round, d, iv, f);
        }
        let (p, on_boundary) = self.sample(iv);
        let edges = self.split_edges(round, p, on_boundary, f);
        let Some(split) = self.plan_split_at(round, &edges, p, on_boundary, d) else {
            // No split fits here: pull the nearest end of the nearest edge towards `p`.
            let l = &self.limits;
            if pull(
                self.mesh,
                round.topo,
                self.surface,
                &edges,
                p,
                on_boundary,
                l.tol.max(FIT_TRADE * d),
                l.guard,
                l.cos_turn,
                &|w| self.rails.locked(w),
                &mut round.touched,
                &mut self.tris,
            ) {
                self.done += 1;
                self.fails = 0;
            } else {
                self.give_up(iv);
                self.fails += 1;
            }
            return Visited::Next;
        };
        // Distance the split removes (the far point's distance is at most this after).
        let gain = d - split.at.distance(p);
        let Some(col) = self.pick_collapse(round, &split, gain) else {
            self.give_up(iv);
            self.fails += 1;
            return Visited::Next;
        };
        self.fails = 0;
        self.done += 1;
        match self.apply_pair(round, split, col) {
            true => Visited::Reindexed,
            false => Visited::Next,
        }
    }

    /// The far point `iv` (at distance `d`) by face `f`, which has a corner or rail vertex:
    /// the rail edge of `f` nearest it split at the rail point nearest it, paired with a
    /// collapse elsewhere; or the point given up.
    fn visit_rail(&mut self, round: &mut RoundMesh<'_>, d: f64, iv: u32, f: u32) -> Visited {
        let (p, _) = self.sample(iv);
        let split = self.plan_rail_split(round, p, d, f);
        let gain = split.as_ref().map_or(0.0, |(s, _)| d - s.at.distance(p));
        let col = match split.as_ref() {
            Some((s, _)) if gain > 0.0 => self.pick_collapse(round, s, gain),
            _ => None,
        };
        let (Some((split, [a, b])), Some(col)) = (split, col) else {
            self.give_up(iv);
            self.fails += 1;
            return Visited::Next;
        };
        self.fails = 0;
        self.done += 1;
        let v = col.gone;
        let reindexed = self.apply_pair(round, split, col);
        self.rails.split_edge(a, b, v);
        match reindexed {
            true => Visited::Reindexed,
            false => Visited::Next,
        }
    }

    /// The split of the rail edge of face `f` nearest `p` at the point of its rail nearest
    /// `p` (away from the edge's ends), when its new faces keep the angle guard and stay
    /// near the input (as [`Fitting::plan_split_at`] asks for a point at distance `d`);
    /// with the edge's ends.
    fn plan_rail_split(
        &self,
        round: &RoundMesh<'_>,
        p: DVec3,
        d: f64,
        f: u32,
    ) -> Option<(SplitPlan, [u32; 2])> {
        let (mesh, topo, rails) = (&*self.mesh, round.topo, &*self.rails);
        let pos = |w: u32| mesh.positions[w as usize];
        let face = mesh.faces[f as usize];
        let (_, a, b) = (0..3)
            .map(|k| (face[k], face[(k + 1) % 3]))
            .filter(|&(a, b)| rails.is_rail_edge(a, b))
            .map(|(a, b)| {
                (
                    closest_point_on_segment(p, pos(a), pos(b)).0.distance(p),
                    a,
                    b,
                )
            })
            .min_by(|x, y| x.0.total_cmp(&y.0))?;
        let r = rails.rail_of_edge(a, b)?;
        let (pa, pb) = (pos(a), pos(b));
        let at = rails.project(r, pa.lerp(pb, 0.5), p, 0.5 * pa.distance(pb));
        let away = 0.25 * pa.distance(pb);
        if !at.is_finite() || at.distance(pa) < away || at.distance(pb) < away {
            return None;
        }
        let e = topo.find_edge(a, b)?;
        let (old, new) = plan_split(
            mesh,
            &round.edit,
            Some(self.surface),
            topo.edge(e),
            NEW_VERTEX,
            at,
            self.limits.cos_turn,
        )?;
        let around: Vec<u32> = old.iter().flat_map(|&g| mesh.faces[g as usize]).collect();
        if around.iter().any(|&w| round.touched[w as usize]) {
            return None;
        }
        let l = &self.limits;
        let bound = l.tol.max(FIT_TRADE * d);
        let mut tris = Vec::new();
        split_fits(
            mesh,
            self.surface,
            &new,
            at,
            0.5 * l.guard,
            bound,
            &mut tris,
        )
        .then(|| {
            let split = SplitPlan {
                edge: e,
                at,
                old: old.to_vec(),
                new: new.to_vec(),
                around,
            };
            (split, [a, b])
        })
    }

    /// The edges a split for point `p` (nearest face `f`) may cut, nearest to `p` first:
    /// the interior edges of `f`, or for a point of the input's boundary the two nearest
    /// boundary edges.
    fn split_edges(
        &self,
        round: &RoundMesh<'_>,
        p: DVec3,
        on_boundary: bool,
        f: u32,
    ) -> Vec<(f64, u32)> {
        let (mesh, topo) = (&*self.mesh, round.topo);
        let seg = |e: u32| {
            let [a, b] = topo.edge(e);
            closest_point_on_segment(p, mesh.positions[a as usize], mesh.positions[b as usize])
                .0
                .distance(p)
        };
        let mut edges: Vec<(f64, u32)> = if on_boundary {
            round.boundary_edges.iter().map(|&e| (seg(e), e)).collect()
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
        edges
    }

    /// The first split of `edges` whose faces round none of the touched vertices, at `p`
    /// or halfway to the edge's midpoint on the input, whose new faces keep the angle guard
    /// and stay near the input (within `tol` or [`FIT_TRADE`] of `d`).
    fn plan_split_at(
        &mut self,
        round: &RoundMesh<'_>,
        edges: &[(f64, u32)],
        p: DVec3,
        on_boundary: bool,
        d: f64,
    ) -> Option<SplitPlan> {
        let (mesh, topo, surface) = (&*self.mesh, round.topo, self.surface);
        let l = &self.limits;
        for &(_, s) in edges {
            let [c, dd] = topo.edge(s);
            let around: Vec<u32> = topo
                .edge_faces(s)
                .iter()
                .flat_map(|&g| mesh.faces[g as usize])
                .collect();
            if around
                .iter()
                .any(|&w| round.touched[w as usize] || self.rails.locked(w))
            {
                continue;
            }
            let mid = mesh.positions[c as usize].lerp(mesh.positions[dd as usize], 0.5);
            let half = p.lerp(mid, 0.5);
            let half = if on_boundary {
                surface.project_boundary_along(p, half, BOUNDARY_REACH * p.distance(mid))
            } else {
                surface.project(half)
            };
            for at in std::iter::once(p).chain(half) {
                let split = if on_boundary {
                    plan_boundary_split(mesh, topo, surface, s, NEW_VERTEX, at, l.cos_turn)
                        .map(|(o, n)| (o.to_vec(), n.to_vec()))
                } else {
                    plan_split(
                        mesh,
                        &round.edit,
                        Some(surface),
                        [c, dd],
                        NEW_VERTEX,
                        at,
                        l.cos_turn,
                    )
                    .map(|(o, n)| (o.to_vec(), n.to_vec()))
                };
                let Some((old, new)) = split else {
                    continue;
                };
                let bound = l.tol.max(FIT_TRADE * d);
                if split_fits(mesh, surface, &new, at, l.guard, bound, &mut self.tris) {
                    return Some(SplitPlan {
                        edge: s,
                        at,
                        old,
                        new,
                        around,
                    });
                }
            }
        }
        None
    }

    /// The least-moving collapse to pair with `split` (it moves the surface by at most
    /// `tol` or [`FIT_TRADE`] of `gain`), away from the split and the touched vertices.
    fn pick_collapse(
        &mut self,
        round: &mut RoundMesh<'_>,
        split: &SplitPlan,
        gain: f64,
    ) -> Option<Collapse> {
        let (mesh, topo, surface) = (&*self.mesh, round.topo, self.surface);
        let l = &self.limits;
        let bound = l.tol.max(FIT_TRADE * gain);
        for (i, &(err, _, k)) in round.collapses.iter().enumerate() {
            if err > bound {
                break;
            }
            let [a, b] = topo.edge(k);
            if round.touched[a as usize]
                || round.touched[b as usize]
                || split.around.contains(&a)
                || split.around.contains(&b)
                || bound <= round.refused_at[i]
            {
                continue;
            }
            let Some(col) = plan_collapse(
                mesh,
                &round.edit,
                Some(surface),
                [a, b],
                l.cos_turn,
                l.floor,
            ) else {
                round.refused_at[i] = f64::INFINITY;
                continue;
            };
            if collapse_error(mesh, topo, k, col.at, &mut self.tris) > bound
                || leaves_input(surface, &self.tris, bound)
            {
                round.refused_at[i] = bound;
                continue;
            }
            return Some(col);
        }
        None
    }

    /// Makes the split and the collapse: the collapse's freed vertex becomes the split's
    /// new one, the split's and the collapse's faces take the new faces (a slot left over
    /// is removed, a face left over appended). True when the face indices changed.
    fn apply_pair(&mut self, round: &mut RoundMesh<'_>, split: SplitPlan, col: Collapse) -> bool {
        let (mesh, topo) = (&mut *self.mesh, round.topo);
        let [c, dd] = topo.edge(split.edge);
        let new: Vec<[u32; 3]> = split
            .new
            .iter()
            .map(|t| t.map(|w| if w == NEW_VERTEX { col.gone } else { w }))
            .collect();
        for v in [col.keep, col.gone] {
            for &g in topo.vertex_faces(v) {
                for w in mesh.faces[g as usize] {
                    round.touched[w as usize] = true;
                }
            }
        }
        for &w in &split.around {
            round.touched[w as usize] = true;
        }
        let carry = self.carry;
        if carry {
            let v_from = &mut self.v_from;
            if col.at != mesh.positions[col.keep as usize] {
                v_from[col.keep as usize] =
                    blend_origins(&v_from[col.keep as usize], &v_from[col.gone as usize]);
            }
            v_from[col.gone as usize] = blend_origins(&v_from[c as usize], &v_from[dd as usize]);
        }
        let old = &split.old;
        // Each new face's parent in the mesh `fit` started from.
        let parents: Vec<u32> = (0..new.len())
            .map(|i| old[i * old.len() / new.len()])
            .map(|g| if carry { self.f_from[g as usize] } else { g })
            .collect();
        for &g in topo.vertex_faces(col.gone) {
            for w in &mut mesh.faces[g as usize] {
                if *w == col.gone {
                    *w = col.keep;
                }
            }
        }
        mesh.positions[col.keep as usize] = col.at;
        mesh.positions[col.gone as usize] = split.at;
        let mut slots: Vec<u32> = old.iter().chain(&col.freed).copied().collect();
        let reindexed = slots.len() != new.len();
        let f_from = &mut self.f_from;
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
        reindexed
    }
}
