//! The `relax` stage (beyond the papers): a few sweeps of tangential relaxation that lift
//! the worst triangles of a coarse mesh, keeping its vertex count and topology.
//!
//! In each sweep every vertex, in index order, is offered a few moves: an interior vertex
//! towards the area-weighted centroid of its ring of faces, within its tangent plane
//! (`step`, half and a quarter of the way), then onto the nearest point of the run's input
//! surface when `project` is on (the moves ranked where they aim, then placed on the input
//! one by one as they are tried, and each judged again where it lands); a boundary vertex
//! towards the middle (or the thirds) of the segment between its two boundary neighbours,
//! then onto the nearest point of the input's boundary edges along the loop it is on
//! (within twice its two edges' length of where it is, so that it neither jumps to another
//! loop nor across a bay of its own). The best move is kept only when the smallest angle of the vertex's faces grows, none of
//! them turns by more than `max_turn_deg`, and (when projecting) none faces away
//! from the input normal nearest its centroid — so the mesh's minimum angle never drops, no
//! face flips, and every vertex stays on the input surface. Meshes of 2¹¹ vertices or more
//! sweep in eight fixed spatial parts at once, the vertices on the borders between parts
//! last (in classes of which no two are neighbours, each class at once); the result does
//! not depend on the thread count.
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
//! With `mend` (on by default, when projecting), before the sweeps, the faces facing away
//! from the input normal nearest their centroid (a fold the dual left, a part of the input
//! thinner than a face) are mended: each vertex of such a face tries points of the input
//! around it (a quarter and half of the way to each neighbour, its faces' centroids, its
//! neighbours' mean; boundary vertices along the input boundary) and moves to the one where
//! fewest of its faces face away, when that is fewer than now, none is degenerate and the
//! smallest angle of its faces stays at least `floor_deg` or what it was (failing that,
//! the mesh's smallest angle before the stage); then the edges of faces still facing away
//! are flipped where the two new faces face away less (the first guard). A few rounds.
//! Where the input is thinner than the faces (a horn, an ear's rim) a face can stay
//! turned, as no single move or flip turns it: an edge of such a face is split at the
//! input point nearest its centroid on the side it faces (or its midpoint's), when fewer
//! of the new faces face away, paired with the collapse elsewhere that moves the surface
//! least (as `fit` pairs them, so the vertex count stays), and the vertices mended again.
//! Where no split helps either (a turned face held by slivers around it), an edge of one of
//! its corners is collapsed (at the edge's middle on the input or at an end) when fewer
//! faces around it face away after, none turns by 90° or more and none gets an angle under
//! half the floor (or of the smallest around it), paired with the split of a long edge
//! elsewhere, and the vertices mended again.
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
//! the smallest angle) for the sweeps to lift. With `max_dev_pct` set, so do the boundary
//! chords that pass farther than it from the input (over a bay of a hole's rim, where every
//! input point lies near the face and none sees it): the input boundary point nearest the
//! chord's farthest point gets a vertex the same way.
//!
//! With `max_dev_pct` > 0 the sweeps keep fidelity: a move or a flip is refused when an
//! input point near the faces it changes would end farther than that bound from them (or,
//! if already farther, farther than it was), or when a boundary vertex's move takes one of
//! its two boundary chords farther than the bound from the input (or farther than it was).
//!
//! With `polish` > 0, after the sweeps, the vertices of the worst faces by quality (the
//! lowest 0.2 %, at least 8) are offered the sweep's moves and moves towards
//! the apex that would make their worst face equilateral, and take the one that most
//! raises the smallest quality of their faces, when it lowers their summed quality by no
//! more than it adds to the smallest, leaves no face with a smaller smallest angle than it
//! had (capped at `floor_deg`; with no floor, no face may lose angle) and passes the sweeps'
//! guards. A few rounds, each on the worst faces of the round before's result.
//!
//! With `features`, first of all, the input's sharp features are captured (see the
//! `rails` module): each corner of the input gets the nearest vertex, which then never
//! moves; each sharp curve a chain of vertices traced along it, which then slide only along
//! it; no edge of a chain is flipped, and rebalancing and fitting move none of the chains'
//! and corners' vertices. A far input point by a chain edge gets that edge split at the
//! chain's nearest point (paired with a collapse elsewhere), new angles down to 0.4 of the
//! floor. Features are read at the mesh's scale (curves shorter than its mean edge, or no
//! longer sharp at that scale, are not features).
//!
//! The report gives `facing_away` (faces facing away before and after mending, when it
//! ran), `moved` (moves kept, per sweep), `flipped` (edges flipped, per sweep),
//! `rebalanced` (split/collapse pairs), `fitted` and `fit_given_up` (fidelity edits, and
//! input points no edit could bring nearer, when `fit` is on), `polished` (moves kept by
//! the polishing, when it is on), `feature_corners` and `feature_rails` (kept, and found
//! at the mesh's scale) and `feature_rail_vertices` (with `features`), and
//! `min_angle_before` / `min_angle_after` in degrees.

use coarsen_edit::{Constraints, Role};
use coarsen_geom::{DVec3, triangle};
use coarsen_mesh::{FaceOrigins, Topology, VertexOrigins};
use coarsen_metrics::{Facing, SurfaceIndex};
use coarsen_spatial::{Bvh, closest_point_on_segment, closest_point_on_triangle};
use coarsen_stage::{
    Context, Contract, Mesh, Needs, ParamIssue, Params, Stage, StageError, params,
};
use rayon::prelude::*;
use std::sync::Arc;

mod fit;
mod flip;
mod mend;
mod polish;
mod rails;
mod rebalance;
mod sweep;

use fit::*;
use flip::*;
use mend::*;
use polish::*;
use rails::Rails;
pub use rails::{Captured, InputFeatures};
use rebalance::*;
use sweep::*;

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
        /// input lies farthest from the mesh (beyond `max_dev_pct`), or a boundary edge
        /// farthest from the input, a new vertex goes there and an edge is collapsed where
        /// that moves the surface least, or a nearby vertex is pulled there; the vertex
        /// count stays. 0 = none.
        pub fit: u32 = 0,
        /// Moves and flips may not leave a point of the input farther than this from the
        /// mesh (percent of the input's bounding-box diagonal), nor one already farther,
        /// farther still, nor a boundary edge so far from the input; `fit` works on the
        /// points beyond it. 0 = no bound.
        pub max_dev_pct: f64 = 0.0,
        /// Before the sweeps, move the vertices of faces facing away from the input (a
        /// part thinner than a face, a fold) to nearby points of the input where fewer do,
        /// flip their edges, split them paired with a collapse elsewhere, or collapse one of their
        /// edges paired with a split elsewhere.
        pub mend: bool = true,
        /// Rounds of polishing after the sweeps: the vertices of the worst faces by quality
        /// (the lowest 0.2 %, at least 8) move where the smallest quality of their faces
        /// rises, no face losing angle below `floor_deg`. 0 = none.
        pub polish: u32 = 0,
        /// Keep the input's sharp features (when projecting): its corners get a vertex
        /// that never moves, its sharp curves a chain of vertices that slide along them and
        /// whose edges are neither flipped nor collapsed. Off by default: it costs
        /// smallest angle (fandisk at 2000 with `adaptive-cvt`: 30.9 → 21.3°; at 1500 or
        /// 3000 a face may stay turned over), and on a scan it still finds creases (the
        /// bunny at 5000: 24.4 → 7.3°).
        pub features: bool = false,
        /// An input edge is sharp when its two faces' normals differ by more than this
        /// (degrees).
        pub feature_angle_deg: f64 = 40.0,
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
        coarsen_stage::params::check_range(&mut v, "polish", self.polish, 0, 1000);
        coarsen_stage::params::check_range(
            &mut v,
            "feature_angle_deg",
            self.feature_angle_deg,
            0.0,
            180.0,
        );
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
    /// Input points `fit` gave up on: no edit within its limits brought them nearer.
    pub fit_given_up: usize,
    /// Smallest angle of the mesh before, in degrees.
    pub min_angle_before: f64,
    /// Smallest angle of the mesh after, in degrees.
    pub min_angle_after: f64,
    /// Faces facing away from the input before and after mending (when it ran).
    pub facing_away: Option<[usize; 2]>,
    /// Moves kept by the polishing rounds.
    pub polished: usize,
    /// What the capture of the input's features did (when features were kept).
    pub features: Option<Captured>,
}

/// Smallest angle (radians) and summed quality of the faces `fan` (of `faces`, corners at
/// `pos`), with vertex `v` at `p`; `None` when a face normal turns beyond `cos_turn` from
/// `normals`.
fn fan_shape(
    faces: &[[u32; 3]],
    fan: &[u32],
    v: u32,
    p: DVec3,
    pos: impl Fn(u32) -> DVec3,
    normals: &[DVec3],
    cos_turn: f64,
) -> Option<(f64, f64)> {
    let mut worst = f64::INFINITY;
    let mut sum = 0.0;
    for (i, &f) in fan.iter().enumerate() {
        let [a, b, c] = faces[f as usize].map(|w| if w == v { p } else { pos(w) });
        let n = triangle::normal(a, b, c);
        if n.dot(normals[i]) < cos_turn {
            return None;
        }
        worst = worst.min(triangle::min_angle(a, b, c));
        sum += triangle::quality(a, b, c);
    }
    Some((worst, sum))
}

/// How far along the input's boundary (in multiples of the output edges involved) a
/// boundary vertex's new place is looked for: far enough for a ragged hole, whose boundary
/// is longer than the output's chords, and no farther, so that it stays on its loop.
pub(crate) const BOUNDARY_REACH: f64 = 2.0;

/// The surface vertices are kept on: the input mesh, its face index and its boundary edges.
pub struct Surface<'a> {
    mesh: &'a Mesh,
    facing: Facing<'a>,
    features: Option<Arc<InputFeatures>>,
}

impl<'a> Surface<'a> {
    /// Indexes `mesh` (its faces and boundary edges).
    pub fn new(mesh: &'a Mesh) -> Self {
        Surface::with_index(mesh, Arc::new(SurfaceIndex::new(mesh)))
    }

    /// `mesh` with its index built earlier by [`SurfaceIndex::new`] from the same mesh.
    pub fn with_index(mesh: &'a Mesh, index: Arc<SurfaceIndex>) -> Self {
        Surface {
            mesh,
            facing: Facing::with_index(mesh, index),
            features: None,
        }
    }

    /// The same surface with its sharp features, found earlier by
    /// [`InputFeatures::detect`] on the same mesh: [`relax`] keeps them.
    pub fn with_features(self, features: Arc<InputFeatures>) -> Self {
        Surface {
            features: Some(features),
            ..self
        }
    }

    /// The nearest point of the surface.
    fn project(&self, p: DVec3) -> Option<DVec3> {
        self.facing.bvh().closest_point(p).map(|h| h.point)
    }

    /// [`Surface::project`] when the nearest point lies within about `bound` of `p` (a
    /// little farther, for rounding: the caller compares the distance itself), else
    /// `None`; the same point, found faster.
    fn project_within(&self, p: DVec3, bound: f64) -> Option<DVec3> {
        let limit = bound * bound * (1.0 + 1e-9);
        self.facing
            .bvh()
            .closest_point_within(p, limit)
            .map(|h| h.point)
    }

    /// The nearest point of the faces facing the side of `normal`.
    fn project_facing(&self, p: DVec3, normal: DVec3) -> Option<DVec3> {
        self.facing.project_facing(p, normal)
    }

    /// The nearest point of the boundary edges.
    #[cfg(test)]
    fn project_boundary(&self, p: DVec3) -> Option<DVec3> {
        self.facing.project_boundary(p)
    }

    /// The nearest point to `target` of the boundary edges along the loop of the boundary
    /// point nearest `from`, within `reach` of it (arc length).
    fn project_boundary_along(&self, from: DVec3, target: DVec3, reach: f64) -> Option<DVec3> {
        self.facing.project_boundary_along(from, target, reach)
    }

    /// True when the triangle `abc` does not face away from the input (the metrics'
    /// flipped-face test).
    fn agrees(&self, a: DVec3, b: DVec3, c: DVec3) -> bool {
        !self.facing.faces_away(a, b, c)
    }
}

/// The two neighbours each vertex slides between: its boundary neighbours (adjacency
/// `topo`), or its rail neighbours for a vertex on a rail of `rails`.
fn sliding_ends(topo: &Topology, n_vertices: usize, rails: &Rails) -> Vec<Vec<u32>> {
    let mut ends = boundary_neighbours(topo, n_vertices);
    for (v, e) in ends.iter_mut().enumerate() {
        if let Some(pair) = rails.rail_ends(v as u32) {
            *e = pair.to_vec();
        }
    }
    ends
}

/// The boundary neighbours of each of `n_vertices` vertices (two on a boundary loop, none
/// inside).
fn boundary_neighbours(topo: &Topology, n_vertices: usize) -> Vec<Vec<u32>> {
    let mut ends: Vec<Vec<u32>> = vec![Vec::new(); n_vertices];
    for e in 0..topo.n_edges() as u32 {
        if topo.is_boundary_edge(e) {
            let [a, b] = topo.edge(e);
            ends[a as usize].push(b);
            ends[b as usize].push(a);
        }
    }
    ends
}

/// The length of edge `e` of `mesh` (`topo` its adjacency).
fn edge_length(mesh: &Mesh, topo: &Topology, e: u32) -> f64 {
    let [a, b] = topo.edge(e);
    mesh.positions[a as usize].distance(mesh.positions[b as usize])
}

/// Relaxes the vertices of `mesh` in place (see the crate docs), keeping them on `surface`
/// when given.
pub fn relax(mesh: &mut Mesh, surface: Option<&Surface<'_>>, params: &RelaxParams) -> Relaxed {
    let mut out = Relaxed {
        min_angle_before: min_angle_deg(mesh),
        ..Relaxed::default()
    };
    let run = Relaxing::new(surface, params);
    let mut rails = run.capture_features(mesh, &mut out);
    run.rebalance_edges(mesh, &rails, &mut out);
    let samples = run.sample_input(mesh);
    run.fit_far_points(mesh, &mut rails, &samples, &mut out);
    let mut watch = run.deviation_watch(&samples);
    drop(samples);
    let Ok(mut topo) = Topology::try_build(mesh) else {
        out.min_angle_after = out.min_angle_before;
        return out;
    };
    let mut ends = sliding_ends(&topo, mesh.n_vertices(), &rails);
    run.mend_facing_away(mesh, &mut topo, &mut ends, &mut rails, &mut out);
    let shared = run.sweep_shared(&ends, &rails);
    run.run_sweeps(mesh, &mut topo, &shared, &mut watch, &mut out);
    run.polish_worst(mesh, &topo, &shared, &mut watch, &mut out);
    out.min_angle_after = min_angle_deg(mesh);
    out
}

/// The smallest angle of the faces of `m`, in degrees.
fn min_angle_deg(m: &Mesh) -> f64 {
    (0..m.n_faces())
        .map(|f| {
            let [a, b, c] = m.corners(f);
            triangle::min_angle(a, b, c).to_degrees()
        })
        .fold(f64::INFINITY, f64::min)
}

/// What every step of [`relax`] reads: the surface, the parameters and the bounds they give.
struct Relaxing<'a> {
    /// The input surface faces must agree with.
    surface: Option<&'a Surface<'a>>,
    /// `surface` when projecting onto it.
    surface_on: Option<&'a Surface<'a>>,
    /// The stage's parameters.
    params: &'a RelaxParams,
    /// Cosine of `params.max_turn_deg`.
    cos_turn: f64,
    /// The deviation bound `params.max_dev_pct`, as a distance (0 without a surface).
    tol: f64,
}

impl<'a> Relaxing<'a> {
    /// The steps' shared reads for relaxing onto `surface` with `params`.
    fn new(surface: Option<&'a Surface<'a>>, params: &'a RelaxParams) -> Self {
        let cos_turn = params.max_turn_deg.to_radians().cos();
        let surface_on = surface.filter(|_| params.project);
        let tol = surface_on.map_or(0.0, |s| {
            0.01 * params.max_dev_pct * s.mesh.bbox().diagonal()
        });
        Relaxing {
            surface,
            surface_on,
            params,
            cos_turn,
            tol,
        }
    }

    /// The input's corners and rails, put on the mesh (none unless `features`).
    fn capture_features(&self, mesh: &mut Mesh, out: &mut Relaxed) -> Rails {
        // The input's features: corners and rails the vertices are put on and kept on.
        match self
            .surface_on
            .and_then(|s| Some((s, s.features.as_deref()?)))
        {
            Some((sf, input)) if self.params.features => match Topology::try_build(mesh) {
                Ok(topo) => {
                    let (rails, captured) = Rails::capture(mesh, &topo, input, sf.mesh);
                    out.features = Some(captured);
                    rails
                }
                Err(_) => Rails::default(),
            },
            _ => Rails::default(),
        }
    }

    /// Moves vertices from short edges to long ones in split/collapse pairs (`rebalance`).
    fn rebalance_edges(&self, mesh: &mut Mesh, rails: &Rails, out: &mut Relaxed) {
        if self.params.rebalance > 0 {
            out.rebalanced = rebalance(
                mesh,
                self.surface_on,
                rails,
                self.params.rebalance,
                self.cos_turn,
                self.params.floor_deg.to_radians(),
            );
        }
    }

    /// The input points `fit` and the bound look at (none when neither is on).
    fn sample_input(&self, mesh: &Mesh) -> Vec<(DVec3, bool)> {
        match self.surface_on {
            Some(s) if self.params.fit > 0 || self.params.max_dev_pct > 0.0 => {
                input_samples(s, mesh, WATCH_FROM * self.tol)
            }
            _ => Vec::new(),
        }
    }

    /// Puts vertices where the input is farthest from the mesh (`fit`).
    fn fit_far_points(
        &self,
        mesh: &mut Mesh,
        rails: &mut Rails,
        samples: &[(DVec3, bool)],
        out: &mut Relaxed,
    ) {
        if self.params.fit > 0
            && let Some(sf) = self.surface_on
        {
            (out.fitted, out.fit_given_up) = fit(
                mesh,
                sf,
                rails,
                self.params.fit,
                self.cos_turn,
                self.params.floor_deg.to_radians(),
                self.tol,
                samples,
            );
        }
    }

    /// The input points the sweeps keep within the deviation bound (when it is on).
    fn deviation_watch(&self, samples: &[(DVec3, bool)]) -> Option<Watch> {
        self.surface_on
            .filter(|_| self.params.max_dev_pct > 0.0)
            .map(|_| Watch::new(samples, self.tol))
    }

    /// Mends the faces facing away from the input (`mend`), keeping `topo` and `ends` current.
    fn mend_facing_away(
        &self,
        mesh: &mut Mesh,
        topo: &mut Topology,
        ends: &mut Vec<Vec<u32>>,
        rails: &mut Rails,
        out: &mut Relaxed,
    ) {
        let params = self.params;
        if params.mend
            && let Some(sf) = self.surface_on
        {
            // The mesh's smallest angle does not drop (nor one above it below the floor).
            let floor = params.floor_deg.max(out.min_angle_before).to_radians();
            let smallest = out.min_angle_before.to_radians();
            let m = mend(mesh, topo, sf, ends, rails, floor, smallest);
            let mut after = m.after;
            // What moves and flips cannot mend (a part thinner than a face): a new vertex on
            // the side such a face faces, paid for by a collapse elsewhere (`unfold`); what
            // no split mends either, an edge of such a face collapsed, paid for by a split
            // elsewhere (`unturn`). Each followed by mending again.
            let (cos_turn, floor_deg) = (self.cos_turn, params.floor_deg.to_radians());
            let unfolding =
                |m: &mut Mesh, r: &mut Rails, n| unfold(m, sf, r, n, cos_turn, floor_deg);
            let unturning =
                |m: &mut Mesh, r: &mut Rails, n| unturn(m, sf, r, n, cos_turn, floor_deg);
            type Pairs<'p> = &'p dyn Fn(&mut Mesh, &mut Rails, u32) -> usize;
            for pairs in [&unfolding as Pairs<'_>, &unturning] {
                if after == 0 {
                    break;
                }
                let made = pairs(mesh, rails, (4 * after) as u32);
                if made > 0
                    && let Ok(t) = Topology::try_build(mesh)
                {
                    *topo = t;
                    *ends = sliding_ends(topo, mesh.n_vertices(), rails);
                    after = mend(mesh, topo, sf, ends, rails, floor, smallest).after;
                }
            }
            out.facing_away = Some([m.before, after]);
        }
    }

    /// What every sweep and the polish read, with the sliding `ends` and `rails`.
    fn sweep_shared<'b>(&'b self, ends: &'b [Vec<u32>], rails: &'b Rails) -> SweepShared<'b> {
        SweepShared {
            ends,
            rails,
            surface: self.surface,
            params: self.params,
            cos_turn: self.cos_turn,
        }
    }

    /// The sweeps of flips and vertex moves, until one changes nothing (`sweeps`, `flips`).
    fn run_sweeps(
        &self,
        mesh: &mut Mesh,
        topo: &mut Topology,
        shared: &SweepShared<'_>,
        watch: &mut Option<Watch>,
        out: &mut Relaxed,
    ) {
        let params = self.params;
        // The parts of a big mesh's sweeps (its vertices barely move between sweeps).
        let parts = Parts::new(&mesh.positions);
        for _ in 0..params.sweeps {
            if let Some(w) = watch.as_mut() {
                w.assign(mesh);
            }
            if params.flips {
                let flipped = flip_sweep(
                    mesh,
                    topo,
                    self.surface,
                    shared.rails,
                    watch.as_ref(),
                    self.cos_turn,
                    params.floor_deg.to_radians(),
                );
                out.flipped.push(flipped);
                if flipped > 0 {
                    match Topology::try_build(mesh) {
                        Ok(t) => *topo = t,
                        Err(_) => break,
                    }
                }
            }
            let sweep = shared.over(&mesh.faces, topo, watch.as_ref());
            let moved = sweep.run(&mut mesh.positions, parts.as_ref());
            out.moved.push(moved);
            if moved == 0 && out.flipped.last().is_none_or(|&f| f == 0) {
                break;
            }
        }
    }

    /// Lifts the worst faces by quality after the sweeps (`polish`).
    fn polish_worst(
        &self,
        mesh: &mut Mesh,
        topo: &Topology,
        shared: &SweepShared<'_>,
        watch: &mut Option<Watch>,
        out: &mut Relaxed,
    ) {
        if self.params.polish > 0 {
            if let Some(w) = watch.as_mut() {
                w.assign(mesh);
            }
            let sweep = shared.over(&mesh.faces, topo, watch.as_ref());
            out.polished = polish(&mut mesh.positions, &sweep);
        }
    }
}

/// The `relax` stage.
pub struct Relax(RelaxParams);

impl Stage for Relax {
    type Params = RelaxParams;
    const KIND: &'static str = "relax";
    const SUMMARY: &'static str = "Tangential relaxation on the input surface: vertex moves and edge flips that raise the smallest angle (or, above `floor_deg`, the shape), optional split/collapse rebalancing, fidelity edits where the input is farthest and a bound on its distance; faces facing away from the input mended, none turned, vertex count kept.";

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
            true => {
                let input_error =
                    |e| StageError::Input(format!("`{}`: the input: {e}", Self::KIND));
                let index = cx
                    .input_index_with_topology(SurfaceIndex::with_topology)
                    .map_err(input_error)?;
                let surface = Surface::with_index(cx.original, index);
                Some(match self.0.features {
                    false => surface,
                    true => surface.with_features(self.input_features(cx).map_err(input_error)?),
                })
            }
        };
        let r = relax(&mut mesh, surface.as_ref(), &self.0);
        cx.report.figure("moved", &r.moved);
        cx.report.figure("flipped", &r.flipped);
        cx.report.figure("rebalanced", r.rebalanced);
        if self.0.fit > 0 {
            cx.report.figure("fitted", r.fitted);
            cx.report.figure("fit_given_up", r.fit_given_up);
        }
        if let Some(f) = r.facing_away {
            cx.report.figure("facing_away", f);
        }
        if self.0.polish > 0 {
            cx.report.figure("polished", r.polished);
        }
        if let Some(c) = r.features {
            cx.report
                .figure("feature_corners", [c.corners_kept, c.corners]);
            cx.report.figure("feature_rails", [c.rails_kept, c.rails]);
            cx.report.figure("feature_rail_vertices", c.rail_vertices);
        }
        cx.report.figure("min_angle_before", r.min_angle_before);
        cx.report.figure("min_angle_after", r.min_angle_after);
        Ok(mesh)
    }
}

impl Relax {
    /// The run input's features at this stage's angle: the run's shared ones when found at
    /// that angle (the first relaxation finds them), else found anew.
    fn input_features(
        &self,
        cx: &Context<'_>,
    ) -> Result<Arc<InputFeatures>, coarsen_mesh::TopologyError> {
        let angle = self.0.feature_angle_deg;
        let shared = cx.input_index_with_topology(|m, t| InputFeatures::detect(m, t, angle))?;
        if shared.angle_deg == angle {
            return Ok(shared);
        }
        let topo = cx.input_topology()?;
        Ok(Arc::new(InputFeatures::detect(cx.original, &topo, angle)))
    }
}

coarsen_stage::export_stage!(Relax);

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_stage::StageReport;

    /// Four fitting edits, no sweeps.
    fn fit_only() -> RelaxParams {
        RelaxParams {
            fit: 4,
            sweeps: 0,
            floor_deg: 30.0,
            ..RelaxParams::default()
        }
    }

    /// The mean of `f` over the faces of `m`.
    fn mean_over_faces(m: &Mesh, f: impl Fn(DVec3, DVec3, DVec3) -> f64) -> f64 {
        (0..m.n_faces())
            .map(|t| {
                let [a, b, c] = m.corners(t);
                f(a, b, c)
            })
            .sum::<f64>()
            / m.n_faces() as f64
    }

    /// The bits of every coordinate of `m`, for exact comparisons.
    fn position_bits(m: &Mesh) -> Vec<u64> {
        m.positions
            .iter()
            .flat_map(|p| p.to_array().map(f64::to_bits))
            .collect()
    }

    /// Moves each vertex of `m` (a unit sphere) by up to `amount` / 2 along each axis,
    /// pseudo-randomly from `seed`, and back onto the sphere.
    pub(crate) fn jitter_on_sphere(m: &mut Mesh, seed: u64, amount: f64) {
        let mut s = seed;
        for p in &mut m.positions {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let t = DVec3::new(
                ((s >> 11) % 1000) as f64 / 1000.0 - 0.5,
                ((s >> 23) % 1000) as f64 / 1000.0 - 0.5,
                ((s >> 37) % 1000) as f64 / 1000.0 - 0.5,
            );
            *p = (*p + amount * t).normalize();
        }
    }

    /// A sphere whose vertices were pushed around on its surface: relaxing lifts its
    /// smallest angle, keeps every vertex on the sphere and flips nothing.
    #[test]
    fn relaxing_a_jittered_sphere_raises_its_smallest_angle_and_stays_on_it() {
        let original = coarsen_shapes::icosphere(1.0, 4).unwrap();
        let mut m = coarsen_shapes::icosphere(1.0, 3).unwrap();
        jitter_on_sphere(&mut m, 7, 0.08);
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

    /// A flat annulus of `n_theta` × `n_r` rings of triangles, all turned the same way:
    /// inside a circle of radius `r0`, outside a regular octagon of circumradius 1 with a
    /// corner on +x (so that an octagon's outer boundary lies on a finer one's); the rings
    /// between go from circle to octagon. With `twist`, ring `i` is turned by `i` half
    /// steps, so each face on the inner circle has its third corner over its middle.
    fn annulus(n_theta: u32, n_r: u32, r0: f64, twist: bool) -> Mesh {
        use std::f64::consts::{PI, TAU};
        let step = TAU / f64::from(n_theta);
        let mut positions = Vec::new();
        for i in 0..=n_r {
            let s = f64::from(i) / f64::from(n_r);
            let turn = if twist {
                0.5 * step * f64::from(i)
            } else {
                0.0
            };
            for j in 0..n_theta {
                let t = step * f64::from(j) + turn;
                let side = (t / (PI / 4.0)).floor() * (PI / 4.0) + PI / 8.0;
                let outer = (PI / 8.0).cos() / (t - side).cos();
                let r = r0 + (outer - r0) * s;
                positions.push(DVec3::new(r * t.cos(), r * t.sin(), 0.0));
            }
        }
        let at = |i: u32, j: u32| i * n_theta + j % n_theta;
        let mut faces = Vec::new();
        for i in 0..n_r {
            for j in 0..n_theta {
                if twist {
                    faces.push([at(i, j), at(i, j + 1), at(i + 1, j)]);
                    faces.push([at(i, j + 1), at(i + 1, j + 1), at(i + 1, j)]);
                } else {
                    faces.push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
                    faces.push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
                }
            }
        }
        Mesh::new(positions, faces)
    }

    /// The farthest any boundary chord of `m` passes from `surface`.
    fn worst_chord(m: &Mesh, surface: &Surface<'_>) -> f64 {
        let topo = Topology::build(m);
        (0..topo.n_edges() as u32)
            .filter(|&e| topo.is_boundary_edge(e))
            .filter_map(|e| {
                let [a, b] = topo.edge(e).map(|v| m.positions[v as usize]);
                fit::chord_far_point(surface, a, b).map(|x| x.0)
            })
            .fold(0.0, f64::max)
    }

    /// An octagon in a round hole: its chords pass over the hole (1.35 % of the diagonal
    /// from the input at their middles) while every input point lies on the mesh. The
    /// fidelity edits split the chords at the rim, paired with collapses elsewhere, and
    /// the sweeps keep them there: every chord ends within the bound.
    #[test]
    fn boundary_chords_over_a_hole_are_brought_to_its_rim() {
        let original = annulus(64, 8, 0.5, false);
        let surface = Surface::new(&original);
        let mut m = annulus(16, 4, 0.5, true);
        let before = worst_chord(&m, &surface);
        let tol = 0.002 * original.bbox().diagonal();
        assert!(before > 1.5 * tol, "{before}");
        let params = RelaxParams {
            fit: 100,
            max_dev_pct: 0.2,
            ..RelaxParams::default()
        };
        let n = m.n_vertices();
        let r = relax(&mut m, Some(&surface), &params);
        let after = worst_chord(&m, &surface);
        assert!(after <= tol * (1.0 + 1e-9), "{before} -> {after}: {r:?}");
        assert_eq!(m.n_vertices(), n);
        assert!(Topology::try_build(&m).is_ok());
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
        let mean_min_angle = |m: &Mesh| mean_over_faces(m, triangle::min_angle);
        let before = mean_min_angle(&m);
        let r = relax(&mut m, Some(&surface), &RelaxParams::default());
        assert!(r.min_angle_after >= r.min_angle_before, "{r:?}");
        assert!(mean_min_angle(&m) > before, "{r:?}");
        // The jitter folds faces that mending pairs away: the boundary is the result's.
        let topo = Topology::build(&m);
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
    pub(crate) fn uneven_strip() -> Mesh {
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
        let mean_quality = |m: &Mesh| mean_over_faces(m, triangle::quality);
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
        let params = fit_only();
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

    /// On a mesh far too coarse for its bound `fit` stops once [`fit::FIT_MAX_FAILS`] far
    /// points in a row got no edit, instead of trying the input's points one by one (each
    /// given up in turn: fails when the points given up are many more).
    #[test]
    fn fitting_stops_early_on_a_mesh_far_too_coarse_for_its_bound() {
        let rippled = |n: u32| {
            let mut m = coarsen_shapes::plane_grid(n, n, 1.0).unwrap();
            for p in &mut m.positions {
                p.z = 0.02 * (40.0 * p.x).sin() * (40.0 * p.y).sin();
            }
            m
        };
        let original = rippled(128);
        let surface = Surface::new(&original);
        let mut m = rippled(2);
        let params = RelaxParams {
            fit: 300,
            sweeps: 0,
            max_dev_pct: 0.01,
            ..RelaxParams::default()
        };
        let tol = 1e-4 * original.bbox().diagonal();
        let bvh = Bvh::build(&m.positions, &m.faces);
        let far = original
            .positions
            .iter()
            .filter(|&&p| bvh.closest_point(p).unwrap().distance() > tol)
            .count();
        assert!(
            far > 4 * fit::FIT_MAX_FAILS,
            "{far}: the case shows nothing"
        );
        let r = relax(&mut m, Some(&surface), &params);
        assert!(
            r.fit_given_up <= 2 * fit::FIT_MAX_FAILS,
            "{} points given up, {} edits",
            r.fit_given_up,
            r.fitted
        );
        assert_eq!(m.n_vertices(), 9);
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
        let r = relax(&mut m, Some(&surface), &fit_only());
        assert!(r.fitted > 0, "{r:?}");
        assert_eq!(m.vertex_attrs.scalar("x").unwrap().len(), m.n_vertices());
        let ids = m.face_attrs.label("id").unwrap();
        assert_eq!(ids.len(), m.n_faces());
        assert!(ids.iter().all(|&i| i < n_faces));
    }

    /// A mesh big enough to sweep in parts gives the same bytes on one thread and three.
    #[test]
    fn a_big_mesh_sweeps_in_parts_alike_for_any_thread_count() {
        // 2562 vertices: above PARTS_MIN, so the sweeps run in parts.
        let original = coarsen_shapes::icosphere(1.0, 4).unwrap();
        assert!(Parts::new(&original.positions).is_some());
        let mut jittered = original.clone();
        jitter_on_sphere(&mut jittered, 11, 0.004);
        let params = RelaxParams {
            sweeps: 2,
            flips: false,
            ..RelaxParams::default()
        };
        let run = |threads: usize| {
            coarsen_testdata::on_threads(threads, || {
                let surface = Surface::new(&original);
                let mut m = jittered.clone();
                let r = relax(&mut m, Some(&surface), &params);
                (m, r)
            })
        };
        let ((a, ra), (b, rb)) = (run(1), run(3));
        assert_eq!(ra, rb);
        assert_eq!(position_bits(&a), position_bits(&b));
        // The parts moved most vertices and lifted the worst angle, on the sphere.
        assert!(ra.moved[0] > a.n_vertices() / 2, "{ra:?}");
        assert!(ra.min_angle_after > ra.min_angle_before + 1.0, "{ra:?}");
        assert!(a.positions.iter().all(|p| (p.length() - 1.0).abs() < 1e-3));
    }

    /// The boundary's index finds the nearest boundary point a scan of every boundary edge
    /// finds, from 400 points over, under and beside a bumped grid (the grid spans ±0.5,
    /// the points ±0.8).
    #[test]
    fn boundary_projection_finds_the_nearest_boundary_point() {
        let m = bumped_grid(8, 0.0625);
        let surface = Surface::new(&m);
        let t = Topology::build(&m);
        let edges: Vec<[DVec3; 2]> = (0..t.n_edges() as u32)
            .filter(|&e| t.is_boundary_edge(e))
            .map(|e| t.edge(e).map(|v| m.positions[v as usize]))
            .collect();
        assert_eq!(edges.len(), 32);
        for i in 0..400u32 {
            let s = f64::from(i);
            let p = DVec3::new(
                1.6 * (s * 0.618).fract() - 0.8,
                1.6 * (s * 0.414).fract() - 0.8,
                0.3 * (s * 0.732).fract() - 0.1,
            );
            let scan = edges
                .iter()
                .map(|[a, b]| closest_point_on_segment(p, *a, *b).0.distance(p))
                .fold(f64::INFINITY, f64::min);
            let q = surface.project_boundary(p).unwrap();
            assert!(
                (q.distance(p) - scan).abs() <= 1e-12,
                "{p}: {q} at {} against {scan}",
                q.distance(p)
            );
            assert!(
                edges
                    .iter()
                    .any(|[a, b]| closest_point_on_segment(q, *a, *b).0.distance(q) <= 1e-12)
            );
        }
        // An input without a boundary has no boundary point.
        let closed = coarsen_shapes::icosphere(1.0, 1).unwrap();
        assert_eq!(Surface::new(&closed).project_boundary(DVec3::X), None);
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
            coarsen_testdata::on_threads(threads, || {
                let surface = Surface::new(&original);
                let mut m = bumped_grid(8, 0.0625);
                relax(&mut m, Some(&surface), &params);
                m
            })
        };
        let (a, b) = (run(1), run(3));
        assert_eq!(a.faces, b.faces);
        assert_eq!(position_bits(&a), position_bits(&b));
    }

    /// The faces of `m` facing away from `surface`.
    fn facing_away(m: &Mesh, surface: &Surface<'_>) -> usize {
        (0..m.n_faces())
            .filter(|&f| {
                let [a, b, c] = m.corners(f);
                !surface.agrees(a, b, c)
            })
            .count()
    }

    /// A vertex pushed past a neighbour folds faces over; mending moves it back onto the
    /// input where none faces away, without lowering the smallest angle, and with `mend`
    /// off the fold stays.
    #[test]
    fn mending_unfolds_a_vertex_pushed_past_its_neighbour() {
        let original = coarsen_shapes::icosphere(1.0, 4).unwrap();
        let surface = Surface::new(&original);
        let mut folded = coarsen_shapes::icosphere(1.0, 3).unwrap();
        let t = Topology::build(&folded);
        let v = 100u32;
        let w = t.vertex_neighbors(v)[0];
        let (pv, pw) = (folded.positions[v as usize], folded.positions[w as usize]);
        folded.positions[v as usize] = (pw + 0.4 * (pw - pv)).normalize();
        let before = facing_away(&folded, &surface);
        assert!(before > 0, "the push folded nothing");
        // Mending alone (no sweeps), so what it does is seen by itself.
        let params = RelaxParams {
            sweeps: 0,
            ..RelaxParams::default()
        };
        let mut mended = folded.clone();
        let r = relax(&mut mended, Some(&surface), &params);
        assert_eq!(r.facing_away, Some([before, 0]), "{r:?}");
        assert_eq!(facing_away(&mended, &surface), 0);
        assert!(r.min_angle_after >= r.min_angle_before, "{r:?}");
        let off = RelaxParams {
            mend: false,
            ..params
        };
        let mut kept = folded.clone();
        let r = relax(&mut kept, Some(&surface), &off);
        assert_eq!(r.facing_away, None);
        assert_eq!(facing_away(&kept, &surface), before);
    }
}
