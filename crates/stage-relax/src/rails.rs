//! Sharp features as constraints of [`relax`]: the input's feature curves become rails
//! that chains of output vertices are put on, and its corners vertices that never move.
//!
//! * The input's features ([`InputFeatures`], found once per run by `coarsen-features`)
//!   are read at the scale of the mesh being relaxed (`h`, its mean edge length): a sharp
//!   curve shorter than `h`, or no longer sharp when each side's normal is averaged over
//!   the input within `h` (a scan's noise), is dropped (not a curve with an edge the input
//!   marks, `FeatureKind::Marked`: kept whatever its length and angle); the remaining curves are chained
//!   through the corners where exactly two of them meet, and the chains cut at the points
//!   where they turn by more than [`CORNER_TURN_DEG`] over `h` on each side, at least
//!   [`CONCENTRATED`] of it within `h / 2` (neither a ragged hole's boundary nor a small
//!   round hole is a corner at every step). Corners are those cuts and the points
//!   where one, or three or more, curves end.
//! * Capture ([`Rails::capture`]): each corner takes the nearest output vertex of its
//!   kind (boundary or not) within [`TUBE`]·`h` and moves onto it; each sharp rail is then
//!   traced on the output mesh by a shortest path between its corners (closed rails: between
//!   two points half a rail apart) through the vertices within [`TUBE`]·`h` of the rail,
//!   each edge costing its length plus [`OFF_RAIL_COST`] times its far end's distance from
//!   the rail; the path's inner vertices go onto the rail in path order, evenly spaced
//!   between the corners (or the two points). Rails are traced longest first; one that no
//!   path reaches (others' chains wall it off) is tried in wider tubes (2 and 5 times), and
//!   when some stay untraced the capture is made once more with those first, the trial that
//!   keeps more rails winning. Boundary rails are not traced: the boundary vertices already
//!   stay on the input's boundary.
//! * Then, during the relaxation, a corner never moves, a rail vertex slides only along its
//!   rail, no rail edge is flipped or collapsed, the split/collapse edits of rebalancing
//!   and fitting move no rail or corner vertex, and fitting may split a rail edge at a
//!   point of its rail (the new vertex joins the rail). Corners and rails are the fixed
//!   vertices and curves of a `coarsen_edit::Constraints`: the flips and the
//!   split/collapse pairs made on an `Editable` are refused by it; the vertex moves and
//!   the mending flips ask the roles here.

use super::*;
use coarsen_features::{FeatureKind, FeatureOptions, Features};
use std::collections::{BinaryHeap, HashMap, HashSet};

/// A chain of curves is cut where it turns by more than this (degrees), measured one
/// output edge along each side.
pub(crate) const CORNER_TURN_DEG: f64 = 45.0;
/// A turn is a corner when at least this share of it happens within half its reach.
pub(crate) const CONCENTRATED: f64 = 0.75;
/// How near a rail or corner (in mean output edges) the output vertices it may take lie.
pub(crate) const TUBE: f64 = 1.5;
/// The cost of a path vertex's distance from the rail, per unit of distance (its length
/// counts once).
pub(crate) const OFF_RAIL_COST: f64 = 4.0;
/// Sharp curves shorter than this many mean output edges are not features at that scale.
pub(crate) const MIN_CURVE: f64 = 1.0;

/// The feature curves of a run's input, as polylines, with the corners they end at.
pub struct InputFeatures {
    /// The dihedral angle they were found at (degrees).
    pub angle_deg: f64,
    curves: Vec<InputCurve>,
}

/// One feature curve of the input.
struct InputCurve {
    /// Its vertices in order; a closed curve's last vertex joins its first (not repeated).
    ids: Vec<u32>,
    /// Their positions.
    pts: Vec<DVec3>,
    /// The input vertices it starts and ends at (corners); `None` when closed.
    ends: Option<[u32; 2]>,
    /// Whether it runs along the input's boundary.
    boundary: bool,
    /// Whether the input marks one of its edges (`FeatureKind::Marked`): kept whatever
    /// its sharpness at scale.
    marked: bool,
    /// A few of its edges, evenly spread: midpoint, direction and the unit normals of
    /// the two faces, for its sharpness at a coarser scale ([`sharp_at_scale`]).
    samples: Vec<[DVec3; 4]>,
}

/// Edges of a sharp curve whose sharpness at the output's scale is measured.
const SCALE_SAMPLES: usize = 5;

impl InputCurve {
    fn length(&self) -> f64 {
        let open: f64 = self.pts.windows(2).map(|w| w[0].distance(w[1])).sum();
        match (self.ends, self.pts.first(), self.pts.last()) {
            (None, Some(a), Some(b)) => open + a.distance(*b),
            _ => open,
        }
    }
}

impl InputFeatures {
    /// The features of `mesh` (adjacency `topo`) at dihedral angle `angle_deg`.
    pub fn detect(mesh: &Mesh, topo: &Topology, angle_deg: f64) -> InputFeatures {
        let opts = FeatureOptions {
            angle_deg,
            corner_angle_deg: CORNER_TURN_DEG,
            boundary: true,
        };
        let f = Features::detect(mesh, topo, &opts);
        let kind: HashMap<u32, FeatureKind> = f.edges.iter().copied().collect();
        let curves = (0..f.n_curves())
            .filter_map(|c| {
                let vs = f.curve(c);
                let (&first, &last) = (vs.first()?, vs.last()?);
                // A marked boundary edge is of kind `Marked`: its face count tells.
                let boundary = vs.len() >= 2
                    && topo
                        .find_edge(vs[0], vs[1])
                        .is_some_and(|e| topo.edge_faces(e).len() == 1);
                let n_edges = vs.len() - 1 + usize::from(f.curve_closed[c]);
                let marked = (0..n_edges).any(|i| {
                    topo.find_edge(vs[i], vs[(i + 1) % vs.len()])
                        .is_some_and(|e| kind.get(&e) == Some(&FeatureKind::Marked))
                });
                let samples = (0..n_edges.min(SCALE_SAMPLES))
                    .filter(|_| !boundary && !marked)
                    .filter_map(|k| {
                        let i = k * n_edges / n_edges.min(SCALE_SAMPLES);
                        let (a, b) = (vs[i], vs[(i + 1) % vs.len()]);
                        let e = topo.find_edge(a, b)?;
                        let &[f1, f2] = topo.edge_faces(e) else {
                            return None;
                        };
                        let (p, q) = (mesh.positions[a as usize], mesh.positions[b as usize]);
                        let normal = |f: u32| {
                            let [x, y, z] = mesh.corners(f as usize);
                            triangle::normal(x, y, z)
                        };
                        Some([
                            p.lerp(q, 0.5),
                            (q - p).normalize_or_zero(),
                            normal(f1),
                            normal(f2),
                        ])
                    })
                    .collect();
                Some(InputCurve {
                    samples,
                    ids: vs.to_vec(),
                    pts: vs.iter().map(|&v| mesh.positions[v as usize]).collect(),
                    ends: (!f.curve_closed[c]).then_some([first, last]),
                    boundary,
                    marked,
                })
            })
            .filter(|c| c.pts.len() >= 2)
            .collect();
        InputFeatures { angle_deg, curves }
    }
}

/// One rail: a polyline of the input that output vertices are kept on.
#[derive(Clone)]
struct Rail {
    /// Its points; a closed rail repeats its first point at the end.
    pts: Vec<DVec3>,
    /// Arc length at each point.
    cum: Vec<f64>,
    boundary: bool,
    /// The corners (input vertices) an open rail runs between.
    ends: Option<[u32; 2]>,
}

impl Rail {
    fn new(pts: Vec<DVec3>, closed: bool, boundary: bool, ends: Option<[u32; 2]>) -> Rail {
        let mut pts = pts;
        if closed && let Some(&p) = pts.first() {
            pts.push(p);
        }
        let mut cum = Vec::with_capacity(pts.len());
        let mut s = 0.0;
        for (i, p) in pts.iter().enumerate() {
            if i > 0 {
                s += pts[i - 1].distance(*p);
            }
            cum.push(s);
        }
        Rail {
            pts,
            cum,
            boundary,
            ends,
        }
    }

    fn length(&self) -> f64 {
        self.cum.last().copied().unwrap_or(0.0)
    }

    /// The point at arc length `t`.
    fn at(&self, t: f64) -> DVec3 {
        let i = self
            .cum
            .partition_point(|&c| c <= t)
            .clamp(1, self.pts.len() - 1);
        let (a, b) = (self.pts[i - 1], self.pts[i]);
        let l = self.cum[i] - self.cum[i - 1];
        if l > 0.0 {
            a.lerp(b, ((t - self.cum[i - 1]) / l).clamp(0.0, 1.0))
        } else {
            a
        }
    }

    /// The nearest point to `p` of the part of the rail between arc lengths `t0` and
    /// `t1`, its arc length and distance.
    fn nearest_between(&self, p: DVec3, t0: f64, t1: f64) -> (DVec3, f64, f64) {
        let mut best = (self.at(t0), t0, f64::INFINITY);
        best.2 = best.0.distance(p);
        for i in 1..self.pts.len() {
            if self.cum[i] < t0 || self.cum[i - 1] > t1 {
                continue;
            }
            let (q, s) = closest_point_on_segment(p, self.pts[i - 1], self.pts[i]);
            let on = self.cum[i - 1] + s * (self.cum[i] - self.cum[i - 1]);
            let t = on.clamp(t0, t1);
            let q = if t == on { q } else { self.at(t) };
            let d = q.distance(p);
            if d < best.2 {
                best = (q, t, d);
            }
        }
        best
    }

    /// Reverses the direction of travel.
    fn reverse(&mut self) {
        let l = self.length();
        self.pts.reverse();
        self.cum = self.cum.iter().rev().map(|&c| l - c).collect();
        self.ends = self.ends.map(|[a, b]| [b, a]);
    }
}

/// What the capture did, for the report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Captured {
    /// Input corners kept at the mesh's scale.
    pub corners: usize,
    /// Of which given a vertex.
    pub corners_kept: usize,
    /// Sharp rails at the mesh's scale (boundary rails not counted).
    pub rails: usize,
    /// Of which traced on the mesh.
    pub rails_kept: usize,
    /// Vertices put on rails.
    pub rail_vertices: usize,
}

/// The constraints of one relaxation (see the module docs); empty when features are off.
/// Corners are fixed vertices and rails curves of [`Constraints`], so that every edit made
/// on an [`coarsen_edit::Editable`] given them respects them too.
#[derive(Default)]
pub(crate) struct Rails {
    constraints: Constraints,
    rails: Vec<Rail>,
}

impl Rails {
    /// The corners, rail vertices and rail edges, as edits are given them.
    pub(crate) fn constraints(&self) -> &Constraints {
        &self.constraints
    }

    /// The role of vertex `v`: free, a corner (fixed), or on a rail.
    pub(crate) fn role(&self, v: u32) -> Role {
        self.constraints.role(v)
    }

    /// Whether `v` is a corner or a rail vertex.
    pub(crate) fn locked(&self, v: u32) -> bool {
        self.constraints.locked(v)
    }

    /// Whether `a`–`b` is a rail edge.
    pub(crate) fn is_rail_edge(&self, a: u32, b: u32) -> bool {
        self.constraints.is_curve_edge(a, b)
    }

    /// The rail of edge `a`–`b`, when it is a rail edge.
    pub(crate) fn rail_of_edge(&self, a: u32, b: u32) -> Option<u32> {
        self.constraints.curve_of_edge(a, b)
    }

    /// Records that rail edge `a`–`b` was split at vertex `v`, now on its rail.
    pub(crate) fn split_edge(&mut self, a: u32, b: u32, v: u32) {
        self.constraints.split_edge(a, b, v);
    }

    /// The two rail neighbours of rail vertex `v`.
    pub(crate) fn rail_ends(&self, v: u32) -> Option<[u32; 2]> {
        self.constraints.curve_ends(v)
    }

    /// The nearest point of rail `r` to `target`, when within `reach` of `from`.
    pub(crate) fn project(&self, r: u32, from: DVec3, target: DVec3, reach: f64) -> DVec3 {
        let rail = &self.rails[r as usize];
        let (q, _, _) = rail.nearest_between(target, 0.0, rail.length());
        if q.distance(from) <= reach {
            q
        } else {
            DVec3::NAN
        }
    }

    /// Puts the vertices of `mesh` (adjacency `topo`) on `input`'s corners and rails at
    /// the mesh's scale (see the module docs). The rails are traced longest first; when
    /// some cannot be (others' chains wall them off), once more with those first, and the
    /// trial that keeps more rails wins.
    pub(crate) fn capture(
        mesh: &mut Mesh,
        topo: &Topology,
        input: &InputFeatures,
        surface: &Mesh,
    ) -> (Rails, Captured) {
        let n_edges = topo.n_edges();
        let h = (0..n_edges as u32)
            .map(|e| edge_length(mesh, topo, e))
            .sum::<f64>()
            / n_edges.max(1) as f64;
        // No edges, or none with a length: nothing to put on features.
        if !(h > 0.0 && h.is_finite()) {
            let rails = Rails {
                constraints: Constraints::new(mesh.n_vertices()),
                ..Rails::default()
            };
            return (rails, Captured::default());
        }
        let (chained, fixed) = chain_rails(input, surface, h);
        let mut chained: Vec<Rail> = chained.into_iter().filter(|r| !r.boundary).collect();
        chained.sort_by(|x, y| y.length().total_cmp(&x.length()));
        let grid = Grid::new(&mesh.positions, TUBE * h);
        let first = Trial::run(mesh, topo, &grid, h, &fixed, &chained);
        let trial = match first.missed.is_empty() {
            true => first,
            false => {
                let mut order: Vec<Rail> =
                    first.missed.iter().map(|&i| chained[i].clone()).collect();
                order.extend(
                    (0..chained.len())
                        .filter(|i| !first.missed.contains(i))
                        .map(|i| chained[i].clone()),
                );
                let second = Trial::run(mesh, topo, &grid, h, &fixed, &order);
                match second.missed.len() < first.missed.len() {
                    true => second,
                    false => first,
                }
            }
        };
        mesh.positions = trial.positions;
        (trial.rails, trial.captured)
    }
}

/// One capture of the corners and rails, in a given order of the rails.
struct Trial {
    rails: Rails,
    captured: Captured,
    positions: Vec<DVec3>,
    /// The rails (places in the order given) that could not be traced.
    missed: Vec<usize>,
}

impl Trial {
    /// Captures the corners `fixed` (in their order), then the rails `order` in order, on
    /// a copy of `mesh`'s positions.
    fn run(
        mesh: &Mesh,
        topo: &Topology,
        grid: &Grid,
        h: f64,
        fixed: &[Corner],
        order: &[Rail],
    ) -> Trial {
        let mut positions = mesh.positions.clone();
        let mut out = Captured::default();
        let mut rails = Rails {
            constraints: Constraints::new(mesh.n_vertices()),
            ..Rails::default()
        };
        let mut corner_at: HashMap<u32, u32> = HashMap::new();
        out.corners = fixed.len();
        for &(c, p, on_boundary) in fixed {
            // A corner at the place of one kept already (an input cut apart along an edge
            // of three faces has two there) is that corner's vertex: two vertices on one
            // point would leave a face without area.
            if let Some(v) = corner_at
                .values()
                .copied()
                .find(|&v| positions[v as usize] == p)
            {
                corner_at.insert(c, v);
                out.corners_kept += 1;
                continue;
            }
            let free = |v: u32| {
                rails.role(v) == Role::Free
                    && topo.is_boundary_vertex(v) == on_boundary
                    && topo.n_vertex_fans(v) == 1
            };
            if let Some(v) = grid.nearest(&positions, p, TUBE * h, free)
                && !crowded(&positions, topo, v, p, h)
            {
                rails.constraints.fix(v);
                positions[v as usize] = p;
                corner_at.insert(c, v);
                out.corners_kept += 1;
            }
        }
        let mut missed = Vec::new();
        for (k, rail) in order.iter().enumerate() {
            out.rails += 1;
            let r = rails.rails.len() as u32;
            // A rail whose tube is crowded by others' vertices: again in wider tubes.
            let traced = [1.0, 2.0, 5.0].into_iter().find_map(|w| {
                trace(
                    &positions,
                    topo,
                    grid,
                    &rails,
                    rail,
                    &corner_at,
                    w * TUBE * h,
                )
            });
            let Some(Traced { rail, chain, at }) = traced else {
                missed.push(k);
                continue;
            };
            for (i, &v) in chain.iter().enumerate() {
                if let Some(q) = at[i].filter(|&q| !crowded(&positions, topo, v, q, h)) {
                    positions[v as usize] = q;
                    let (prev, next) = match i {
                        0 => (chain[chain.len() - 2], chain[1]),
                        _ => (chain[i - 1], chain[i + 1]),
                    };
                    rails.constraints.bind(v, r, [prev, next]);
                    out.rail_vertices += 1;
                }
            }
            for w in chain.windows(2) {
                rails.constraints.add_curve_edge(w[0], w[1], r);
            }
            rails.rails.push(rail);
            out.rails_kept += 1;
        }
        Trial {
            rails,
            captured: out,
            positions,
            missed,
        }
    }
}

/// True when a neighbour of `v` lies on `p` (within 10⁻⁹ of the mean edge `h`): moving
/// `v` there would leave their faces without area (an output vertex the dual put on an
/// input corner, of the other kind than the corner's).
fn crowded(positions: &[DVec3], topo: &Topology, v: u32, p: DVec3, h: f64) -> bool {
    topo.vertex_neighbors(v)
        .iter()
        .any(|&w| positions[w as usize].distance(p) <= 1e-9 * h)
}

/// A kept corner: its input vertex, position and whether it is on the input's boundary.
type Corner = (u32, DVec3, bool);

/// A chain of input feature vertices: their ids and positions, whether it closes, and
/// whether it runs along the boundary.
struct Chain {
    ids: Vec<u32>,
    pts: Vec<DVec3>,
    closed: bool,
    boundary: bool,
}

/// The input's curves at scale `h` chained into rails, and the corners kept (see the
/// module docs).
fn chain_rails(input: &InputFeatures, surface: &Mesh, h: f64) -> (Vec<Rail>, Vec<Corner>) {
    let curves = &input.curves;
    let long: Vec<bool> = curves
        .iter()
        .map(|c| c.boundary || c.marked || c.length() >= MIN_CURVE * h)
        .collect();
    let kept = sharp_at_scale(surface, curves, &long, h, input.angle_deg);
    // The kept curves' ends at each corner: (curve, whether it starts there).
    let mut at: HashMap<u32, Vec<(usize, bool)>> = HashMap::new();
    for (i, c) in curves.iter().enumerate() {
        if let (true, Some([a, b])) = (kept[i], c.ends) {
            at.entry(a).or_default().push((i, true));
            at.entry(b).or_default().push((i, false));
        }
    }
    // Where curves end or branch: corners whatever the turn.
    let mut corners: Vec<Corner> = Vec::new();
    let mut nodes: Vec<u32> = at.keys().copied().collect();
    nodes.sort_unstable();
    for v in &nodes {
        let ends = &at[v];
        if ends.len() != 2 {
            let (i, start) = ends[0];
            let c = &curves[i];
            let p = if start {
                c.pts[0]
            } else {
                c.pts[c.pts.len() - 1]
            };
            corners.push((*v, p, ends.iter().any(|e| curves[e.0].boundary)));
        }
    }
    let branch: HashSet<u32> = corners.iter().map(|c| c.0).collect();
    let mut rails = Vec::new();
    for chain in chain_curves(curves, &kept, &at, &branch) {
        let turns = sharp_turns(&chain, h);
        corners.extend(
            turns
                .iter()
                .map(|&i| (chain.ids[i], chain.pts[i], chain.boundary)),
        );
        split_chain(chain, &turns, &mut rails);
    }
    corners.sort_by_key(|c| c.0);
    corners.dedup_by_key(|c| c.0);
    (rails, corners)
}

/// Which of the curves `long` stay sharp at scale `r`: boundary curves, and sharp curves
/// whose edge samples (the median of them) still turn by more than `angle_deg` when each
/// side's normal is the area-weighted mean over the faces of `surface` within `r` of the
/// sample on that side. Noise on a scan makes edges sharp that are not at a coarser scale.
fn sharp_at_scale(
    surface: &Mesh,
    curves: &[InputCurve],
    long: &[bool],
    r: f64,
    angle_deg: f64,
) -> Vec<bool> {
    let sharp: Vec<usize> = (0..curves.len())
        .filter(|&i| {
            long[i] && !curves[i].boundary && !curves[i].marked && !curves[i].samples.is_empty()
        })
        .collect();
    let mut kept: Vec<bool> = (0..curves.len())
        .map(|i| long[i] && (curves[i].boundary || curves[i].marked))
        .collect();
    if sharp.is_empty() || r <= 0.0 {
        return kept;
    }
    // The faces' centroids, in a grid (only the faces near a sample matter; all are put).
    let centroids: Vec<DVec3> = (0..surface.n_faces())
        .map(|f| {
            let [a, b, c] = surface.corners(f);
            triangle::centroid(a, b, c)
        })
        .collect();
    let grid = Grid::new(&centroids, r);
    let cos_limit = angle_deg.to_radians().cos();
    for i in sharp {
        let mut cosines: Vec<f64> = curves[i]
            .samples
            .iter()
            .map(|&[m, d, n1, n2]| {
                // Each face's side: where it lies across the edge. One of the two faces
                // runs along `d`, the other against it, so their directions away from the
                // edge are n1 × d and −n2 × d or the opposite of both; their difference
                // points from one side to the other.
                let split = n1.cross(d) + n2.cross(d);
                let (mut s1, mut s2) = (DVec3::ZERO, DVec3::ZERO);
                let rr = DVec3::splat(r);
                for f in grid.around(m - rr, m + rr) {
                    let c = centroids[f as usize];
                    if c.distance(m) > r {
                        continue;
                    }
                    let [a, b, cc] = surface.corners(f as usize);
                    let n = triangle::cross(a, b, cc);
                    if (c - m).dot(split) >= 0.0 {
                        s1 += n
                    } else {
                        s2 += n
                    }
                }
                let l = s1.length() * s2.length();
                if l > 0.0 { s1.dot(s2) / l } else { n1.dot(n2) }
            })
            .collect();
        cosines.sort_by(f64::total_cmp);
        kept[i] = cosines[cosines.len() / 2] < cos_limit;
    }
    kept
}

/// The kept curves joined end to end through the corners that are not `branch` points.
fn chain_curves(
    curves: &[InputCurve],
    kept: &[bool],
    at: &HashMap<u32, Vec<(usize, bool)>>,
    branch: &HashSet<u32>,
) -> Vec<Chain> {
    let mut used = vec![false; curves.len()];
    let mut chains = Vec::new();
    for i in 0..curves.len() {
        if !kept[i] || used[i] {
            continue;
        }
        used[i] = true;
        let c = &curves[i];
        let Some([a, b]) = c.ends else {
            chains.push(Chain {
                ids: c.ids.clone(),
                pts: c.pts.clone(),
                closed: true,
                boundary: c.boundary,
            });
            continue;
        };
        let mut ids = c.ids.clone();
        let (mut start, mut end) = (a, b);
        let mut closed = false;
        // Forward from the end, then backward from the start.
        for forward in [true, false] {
            while !closed {
                let node = if forward { end } else { start };
                if branch.contains(&node) {
                    break;
                }
                let Some(&(j, j_starts)) = at[&node].iter().find(|e| !used[e.0]) else {
                    // Back at the curve it left: a loop of curves.
                    closed = true;
                    break;
                };
                used[j] = true;
                let cj = &curves[j];
                let [ja, jb] = cj.ends.unwrap_or([node, node]);
                let mut more = cj.ids.clone();
                if forward {
                    if !j_starts {
                        more.reverse();
                    }
                    ids.extend_from_slice(&more[1..]);
                    end = if j_starts { jb } else { ja };
                } else {
                    if j_starts {
                        more.reverse();
                    }
                    more.pop();
                    more.extend_from_slice(&ids);
                    ids = more;
                    start = if j_starts { jb } else { ja };
                }
            }
        }
        if closed {
            ids.pop();
        }
        let position: HashMap<u32, DVec3> = curves
            .iter()
            .enumerate()
            .filter(|(j, _)| used[*j])
            .flat_map(|(_, c)| c.ids.iter().copied().zip(c.pts.iter().copied()))
            .collect();
        chains.push(Chain {
            pts: ids.iter().map(|v| position[v]).collect(),
            ids,
            closed,
            boundary: c.boundary,
        });
    }
    chains
}

/// The points of `chain` where it turns by more than [`CORNER_TURN_DEG`] over an output
/// edge `h` on each side, at least [`CONCENTRATED`] of it within `h / 2`: the sharpest
/// first and none within `h` (along the chain) of one taken before or of an open chain's
/// ends; in chain order.
fn sharp_turns(chain: &Chain, h: f64) -> Vec<usize> {
    let rail = Rail::new(chain.pts.clone(), chain.closed, chain.boundary, None);
    let length = rail.length();
    let n = chain.pts.len();
    let reach = h;
    if length <= 0.0 || (!chain.closed && length < 2.0 * reach) {
        return Vec::new();
    }
    let wrap = |t: f64| {
        if chain.closed {
            t.rem_euclid(length)
        } else {
            t
        }
    };
    let cos_limit = CORNER_TURN_DEG.to_radians().cos();
    let mut cands: Vec<(f64, usize)> = (0..n)
        .filter_map(|i| {
            let t = rail.cum[i];
            if !chain.closed && (t < reach || t > length - reach) {
                return None;
            }
            let p = chain.pts[i];
            let turn = |s: f64| {
                let (d1, d2) = (p - rail.at(wrap(t - s)), rail.at(wrap(t + s)) - p);
                let l = d1.length() * d2.length();
                if l > 0.0 {
                    (d1.dot(d2) / l).clamp(-1.0, 1.0).acos()
                } else {
                    0.0
                }
            };
            // A corner turns at the point: over half the reach nearly as much (an arc of a
            // small hole turns half as much).
            let (wide, narrow) = (turn(reach), turn(0.5 * reach));
            (wide.cos() < cos_limit && narrow >= CONCENTRATED * wide).then(|| (wide.cos(), i))
        })
        .collect();
    cands.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    let apart = |i: usize, j: usize| {
        let d = (rail.cum[i] - rail.cum[j]).abs();
        let d = if chain.closed { d.min(length - d) } else { d };
        d >= reach
    };
    let mut taken: Vec<usize> = Vec::new();
    for (_, i) in cands {
        if taken.iter().all(|&j| apart(i, j)) {
            taken.push(i);
        }
    }
    taken.sort_unstable();
    taken
}

/// Cuts `chain` at its points `at` (ascending) into rails, pushed onto `rails`.
fn split_chain(chain: Chain, at: &[usize], rails: &mut Vec<Rail>) {
    let Chain {
        mut ids,
        mut pts,
        closed,
        boundary,
    } = chain;
    let mut cuts = vec![0];
    if closed {
        let Some(&first) = at.first() else {
            rails.push(Rail::new(pts, true, boundary, None));
            return;
        };
        // Start at the first cut and end there again.
        ids.rotate_left(first);
        pts.rotate_left(first);
        ids.push(ids[0]);
        pts.push(pts[0]);
        cuts.extend(at[1..].iter().map(|&i| i - first));
    } else {
        cuts.extend_from_slice(at);
    }
    cuts.push(ids.len() - 1);
    for w in cuts.windows(2) {
        let (a, b) = (w[0], w[1]);
        let ends = Some([ids[a], ids[b]]);
        rails.push(Rail::new(pts[a..=b].to_vec(), false, boundary, ends));
    }
}

/// A uniform grid over the vertices, for nearness queries.
struct Grid {
    cell: f64,
    cells: HashMap<[i64; 3], Vec<u32>>,
}

impl Grid {
    fn new(positions: &[DVec3], cell: f64) -> Grid {
        let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        for (v, p) in positions.iter().enumerate() {
            cells.entry(Grid::key(cell, *p)).or_default().push(v as u32);
        }
        Grid { cell, cells }
    }

    fn key(cell: f64, p: DVec3) -> [i64; 3] {
        (p / cell).floor().to_array().map(|x| x as i64)
    }

    /// The vertices of the cells meeting the box `lo`–`hi`, cell by cell.
    fn around(&self, lo: DVec3, hi: DVec3) -> impl Iterator<Item = u32> + '_ {
        let (a, b) = (Grid::key(self.cell, lo), Grid::key(self.cell, hi));
        let span = move |i: usize| a[i]..=b[i];
        span(0).flat_map(move |x| {
            span(1).flat_map(move |y| {
                span(2).flat_map(move |z| self.cells.get(&[x, y, z]).into_iter().flatten().copied())
            })
        })
    }

    /// The vertex nearest `p` within `radius` that `ok` accepts (the lower index on ties).
    fn nearest(
        &self,
        positions: &[DVec3],
        p: DVec3,
        radius: f64,
        ok: impl Fn(u32) -> bool,
    ) -> Option<u32> {
        let r = DVec3::splat(radius);
        self.around(p - r, p + r)
            .filter(|&v| ok(v))
            .map(|v| (positions[v as usize].distance(p), v))
            .filter(|&(d, _)| d <= radius)
            .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)))
            .map(|(_, v)| v)
    }
}

/// A rail traced on the mesh: the vertex chain along it (a closed one ends where it
/// starts) and where each vertex goes (`None`: a corner, already there).
struct Traced {
    rail: Rail,
    chain: Vec<u32>,
    at: Vec<Option<DVec3>>,
}

/// Traces `rail` on the mesh (vertex `positions`, adjacency `topo`) through the vertices within `radius` of it (see the module
/// docs); `None` when a corner of it has no vertex or no path joins its anchors.
fn trace(
    positions: &[DVec3],
    topo: &Topology,
    grid: &Grid,
    rails: &Rails,
    rail: &Rail,
    corner_at: &HashMap<u32, u32>,
    radius: f64,
) -> Option<Traced> {
    let mut rail = rail.clone();
    let length = rail.length();
    if length <= 0.0 {
        return None;
    }
    // Each vertex near the rail: its distance from it.
    let mut near: HashMap<u32, f64> = HashMap::new();
    for i in 1..rail.pts.len() {
        let (a, b) = (rail.pts[i - 1], rail.pts[i]);
        let r = DVec3::splat(radius);
        for v in grid.around(a.min(b) - r, a.max(b) + r) {
            let p = positions[v as usize];
            let d = closest_point_on_segment(p, a, b).0.distance(p);
            if d <= radius {
                let e = near.entry(v).or_insert(d);
                *e = e.min(d);
            }
        }
    }
    let usable = |v: u32| {
        rails.role(v) == Role::Free && !topo.is_boundary_vertex(v) && topo.n_vertex_fans(v) == 1
    };
    // Anchors: (vertex, arc length, whether it is a corner).
    let pseudo = |t: f64, taken: &[u32]| -> Option<u32> {
        let p = rail.at(t);
        grid.nearest(positions, p, radius, |v| {
            usable(v) && near.contains_key(&v) && !taken.contains(&v)
        })
    };
    let ends = match rail.ends {
        Some([a, b]) => Some([*corner_at.get(&a)?, *corner_at.get(&b)?]),
        None => None,
    };
    let mut anchors: Vec<(u32, f64, bool)> = match ends {
        Some([a, b]) if a != b => vec![(a, 0.0, true), (b, length, true)],
        Some([a, _]) => {
            let m = pseudo(0.5 * length, &[])?;
            vec![(a, 0.0, true), (m, 0.5 * length, false), (a, length, true)]
        }
        None => {
            let p = pseudo(0.0, &[])?;
            let m = pseudo(0.5 * length, &[p])?;
            vec![
                (p, 0.0, false),
                (m, 0.5 * length, false),
                (p, length, false),
            ]
        }
    };
    let mut chain: Vec<u32> = vec![anchors[0].0];
    let mut taken: HashSet<u32> = anchors.iter().map(|a| a.0).collect();
    for k in 1..anchors.len() {
        let (from, to) = (anchors[k - 1].0, anchors[k].0);
        let path = shortest_path(positions, topo, &near, &taken, from, to, usable);
        let path = path?;
        let path = shortcut(topo, path);
        // A loop's first half may have gone the other way round: turn the rail.
        if k == 1 && anchors.len() == 3 && path.len() > 2 {
            let inner = &path[1..path.len() - 1];
            let mean_t = inner
                .iter()
                .map(|&v| rail.nearest_between(positions[v as usize], 0.0, length).1)
                .sum::<f64>()
                / inner.len() as f64;
            if mean_t > 0.5 * length {
                rail.reverse();
                anchors[1].1 = length - anchors[1].1;
            }
        }
        taken.extend(path.iter().copied());
        chain.extend_from_slice(&path[1..]);
    }
    // Where each vertex goes: anchors where they are (a pseudo anchor onto its point),
    // inner vertices onto the rail between their anchors, in order.
    let mut at: Vec<Option<DVec3>> = vec![None; chain.len()];
    let mut start = 0;
    for k in 1..anchors.len() {
        let (t0, t1) = (anchors[k - 1].1, anchors[k].1);
        let end = start + 1 + chain[start + 1..].iter().position(|&v| v == anchors[k].0)?;
        let inner = &chain[start + 1..end];
        // Evenly along the rail between the anchors, in path order (the path's own
        // spacing, projected, left vertices bunched where it cut across a bend).
        let n = inner.len() as f64 + 1.0;
        for i in 0..inner.len() {
            let even = t0 + (t1 - t0) * (i as f64 + 1.0) / n;
            at[start + 1 + i] = Some(rail.at(even));
        }
        start = end;
    }
    for (i, &(v, t, corner)) in anchors.iter().enumerate() {
        if !corner && let Some(j) = chain.iter().position(|&w| w == v) {
            at[j] = Some(rail.at(t));
            if i == 0 {
                let last = chain.len() - 1;
                at[last] = None;
            }
        }
    }
    Some(Traced { rail, chain, at })
}

/// The cheapest path from `from` to `to` over vertices `usable` and `near` the rail (not
/// `taken`, but for `to`): an edge costs its length plus [`OFF_RAIL_COST`] times its far
/// end's distance from the rail.
fn shortest_path(
    positions: &[DVec3],
    topo: &Topology,
    near: &HashMap<u32, f64>,
    taken: &HashSet<u32>,
    from: u32,
    to: u32,
    usable: impl Fn(u32) -> bool,
) -> Option<Vec<u32>> {
    #[derive(PartialEq)]
    struct Item(f64, u32);
    impl Eq for Item {}
    impl PartialOrd for Item {
        fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
            Some(self.cmp(o))
        }
    }
    impl Ord for Item {
        fn cmp(&self, o: &Self) -> std::cmp::Ordering {
            o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
        }
    }
    let mut dist: HashMap<u32, (f64, u32)> = HashMap::new();
    let mut heap = BinaryHeap::new();
    dist.insert(from, (0.0, from));
    heap.push(Item(0.0, from));
    while let Some(Item(d, v)) = heap.pop() {
        if v == to {
            let mut path = vec![to];
            let mut w = to;
            while w != from {
                w = dist[&w].1;
                path.push(w);
            }
            path.reverse();
            return Some(path);
        }
        if dist.get(&v).is_some_and(|x| x.0 < d) {
            continue;
        }
        let p = positions[v as usize];
        for &w in topo.vertex_neighbors(v) {
            let ok = w == to || (usable(w) && !taken.contains(&w));
            let Some(&off) = near.get(&w).or(if w == to { Some(&0.0) } else { None }) else {
                continue;
            };
            if !ok {
                continue;
            }
            let c = d + p.distance(positions[w as usize]) + OFF_RAIL_COST * off;
            if dist.get(&w).is_none_or(|x| c < x.0) {
                dist.insert(w, (c, v));
                heap.push(Item(c, w));
            }
        }
    }
    None
}

/// `path` without detours: from each vertex kept, on to the last later vertex it shares
/// an edge with.
fn shortcut(topo: &Topology, path: Vec<u32>) -> Vec<u32> {
    let mut out = Vec::with_capacity(path.len());
    let mut i = 0;
    while i < path.len() {
        out.push(path[i]);
        let ring = topo.vertex_neighbors(path[i]);
        i = (i + 1..path.len())
            .rev()
            .find(|&j| ring.contains(&path[j]))
            .unwrap_or(i + 1);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_geom::SplitMix64;

    /// The cube of side 2 (8 cells a side) and a copy whose vertices were pushed along
    /// its surface, corners and edges included.
    fn cube_and_jittered() -> (Mesh, Mesh) {
        let input = coarsen_shapes::cube(2.0, 8).unwrap();
        let surface = Surface::new(&input);
        let mut moved = input.clone();
        let mut rng = SplitMix64::new(7);
        for p in &mut moved.positions {
            *p = surface.project(*p + rng.point(-0.04, 0.04)).unwrap();
        }
        (input, moved)
    }

    /// The largest distance from the cube's edges (12 segments, sampled) to `m`'s edges.
    fn farthest_cube_edge(m: &Mesh) -> f64 {
        let topo = Topology::build(m);
        let corners: Vec<DVec3> = (0..8)
            .map(|i| {
                DVec3::new(
                    [-1.0, 1.0][i & 1],
                    [-1.0, 1.0][(i >> 1) & 1],
                    [-1.0, 1.0][i >> 2],
                )
            })
            .collect();
        let mut worst: f64 = 0.0;
        for (i, &a) in corners.iter().enumerate() {
            for &b in &corners[i + 1..] {
                if a.distance(b) != 2.0 {
                    continue;
                }
                for k in 0..=40 {
                    let x = a.lerp(b, k as f64 / 40.0);
                    let d = (0..topo.n_edges() as u32)
                        .map(|e| {
                            let [u, v] = topo.edge(e);
                            let (p, q) = (m.positions[u as usize], m.positions[v as usize]);
                            closest_point_on_segment(x, p, q).0.distance(x)
                        })
                        .fold(f64::INFINITY, f64::min);
                    worst = worst.max(d);
                }
            }
        }
        worst
    }

    #[test]
    fn a_jittered_cube_gets_its_corners_and_edges_back() {
        let (input, mut m) = cube_and_jittered();
        let before = farthest_cube_edge(&m);
        let topo = Topology::build(&input);
        let features = Arc::new(InputFeatures::detect(&input, &topo, 40.0));
        let surface = Surface::new(&input).with_features(features);
        let params = RelaxParams {
            features: true,
            ..RelaxParams::default()
        };
        let r = relax(&mut m, Some(&surface), &params);
        let c = r.features.unwrap();
        assert_eq!((c.corners, c.corners_kept), (8, 8));
        assert_eq!((c.rails, c.rails_kept), (12, 12));
        for i in 0..8 {
            let corner = DVec3::new(
                [-1.0, 1.0][i & 1],
                [-1.0, 1.0][(i >> 1) & 1],
                [-1.0, 1.0][i >> 2],
            );
            assert!(
                m.positions.contains(&corner),
                "corner {corner} has no vertex"
            );
        }
        let after = farthest_cube_edge(&m);
        assert!(
            before > 0.02 && after < 1e-9,
            "cube edges {before} → {after} away"
        );
        assert!(
            r.min_angle_after > 5.0,
            "smallest angle {}",
            r.min_angle_after
        );
    }

    #[test]
    fn a_mesh_collapsed_to_a_point_captures_nothing() {
        let input = coarsen_shapes::cube(2.0, 2).unwrap();
        let topo = Topology::build(&input);
        let features = Arc::new(InputFeatures::detect(&input, &topo, 40.0));
        let surface = Surface::new(&input).with_features(features);
        let mut m = input.clone();
        m.positions.iter_mut().for_each(|p| *p = DVec3::ZERO);
        let params = RelaxParams {
            features: true,
            ..RelaxParams::default()
        };
        let r = relax(&mut m, Some(&surface), &params);
        assert_eq!(r.features, Some(Captured::default()));
    }

    #[test]
    fn without_features_the_cube_edges_stay_rounded() {
        let (input, mut m) = cube_and_jittered();
        let r = relax(&mut m, Some(&Surface::new(&input)), &RelaxParams::default());
        assert!(r.features.is_none());
        assert!(farthest_cube_edge(&m) > 0.01);
    }

    /// A latitude ring the input marks on a smooth sphere is a rail at any scale; unmarked,
    /// the sphere has none.
    #[test]
    fn a_marked_ring_on_a_sphere_is_a_rail() {
        let mut input = coarsen_shapes::uv_sphere(1.0, 12, 24).unwrap();
        let z0 = input
            .positions
            .iter()
            .map(|p| p.z)
            .filter(|&z| z > 0.3)
            .fold(1.0, f64::min);
        let mut ring: Vec<u32> = (0..input.n_vertices() as u32)
            .filter(|&v| (input.positions[v as usize].z - z0).abs() < 1e-12)
            .collect();
        let angle = |v: u32| {
            let p = input.positions[v as usize];
            p.y.atan2(p.x)
        };
        ring.sort_by(|&a, &b| angle(a).total_cmp(&angle(b)));
        assert_eq!(ring.len(), 24);
        let topo = Topology::build(&input);
        let rails = |input: &Mesh| {
            let features = InputFeatures::detect(input, &topo, 40.0);
            chain_rails(&features, input, 0.5).0
        };
        assert!(rails(&input).is_empty());
        input.marked_edges = (0..ring.len())
            .map(|i| {
                let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
                [a.min(b), a.max(b)]
            })
            .collect();
        let marked = rails(&input);
        assert_eq!(marked.len(), 1);
        assert!(!marked[0].boundary && marked[0].ends.is_none());
    }

    #[test]
    fn a_sphere_has_no_rails_and_relaxes_as_without_features() {
        let input = coarsen_shapes::icosphere(1.0, 3).unwrap();
        let topo = Topology::build(&input);
        let features = Arc::new(InputFeatures::detect(&input, &topo, 40.0));
        let mut with = input.clone();
        crate::tests::jitter_on_sphere(&mut with, 3, 0.05);
        let mut without = with.clone();
        let on = RelaxParams {
            features: true,
            ..RelaxParams::default()
        };
        let sf = Surface::new(&input).with_features(features);
        let r = relax(&mut with, Some(&sf), &on);
        relax(
            &mut without,
            Some(&Surface::new(&input)),
            &RelaxParams::default(),
        );
        assert_eq!(r.features, Some(Captured::default()));
        assert_eq!(with.positions, without.positions);
    }

    #[test]
    fn splitting_a_rail_edge_puts_the_new_vertex_between_its_ends() {
        // Corner 0, rail vertices 1 and 2 of rail 0, corner 3; vertex 4 free.
        let mut constraints = Constraints::new(5);
        constraints.fix(0);
        constraints.bind(1, 0, [0, 2]);
        constraints.bind(2, 0, [1, 3]);
        constraints.fix(3);
        for (a, b) in [(0, 1), (1, 2), (2, 3)] {
            constraints.add_curve_edge(a, b, 0);
        }
        let mut rails = Rails {
            constraints,
            rails: Vec::new(),
        };
        rails.split_edge(2, 1, 4);
        assert_eq!(rails.role(4), Role::OnCurve(0));
        assert_eq!(rails.rail_ends(4), Some([2, 1]));
        assert_eq!(rails.rail_ends(1), Some([0, 4]));
        assert_eq!(rails.rail_ends(2), Some([4, 3]));
        assert!(!rails.is_rail_edge(1, 2));
        assert!(rails.is_rail_edge(1, 4) && rails.is_rail_edge(4, 2));
        // Not a rail edge: nothing changes.
        rails.split_edge(0, 3, 4);
        assert!(!rails.is_rail_edge(0, 4));
    }

    #[test]
    fn a_small_round_hole_has_no_corners() {
        // A circle of circumference 2π seen at h = 1.5: it turns far more than 45° over
        // ±h, but evenly, half of it over ±h / 2.
        let pts: Vec<DVec3> = (0..64)
            .map(|i| {
                let a = i as f64 * std::f64::consts::TAU / 64.0;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let chain = Chain {
            ids: (0..64).collect(),
            pts,
            closed: true,
            boundary: true,
        };
        assert!(sharp_turns(&chain, 1.5).is_empty());
    }

    #[test]
    fn a_chain_turning_sharply_is_cut_once_at_the_turn() {
        // An L of 20 + 20 unit steps, seen at h = 4: one cut, at the bend.
        let pts: Vec<DVec3> = (0..=20)
            .map(|i| DVec3::new(i as f64, 0.0, 0.0))
            .chain((1..=20).map(|i| DVec3::new(20.0, i as f64, 0.0)))
            .collect();
        let chain = Chain {
            ids: (0..pts.len() as u32).collect(),
            pts,
            closed: false,
            boundary: false,
        };
        assert_eq!(sharp_turns(&chain, 4.0), vec![20]);
        let mut rails = Vec::new();
        split_chain(chain, &[20], &mut rails);
        assert_eq!(rails.len(), 2);
        assert_eq!(rails[0].ends, Some([0, 20]));
        assert_eq!(rails[1].ends, Some([20, 40]));
    }
}
