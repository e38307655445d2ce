//! The collapse engine of coarsen: greedy mesh simplification by merging vertices.
//!
//! Both simplifiers of the project are built on it:
//!
//! * `simplify.qem` (Garland & Heckbert 1997) collapses **edges**: 2 vertices → 1;
//! * `simplify.svec` (Zhou, Zhang & Cheng, paper 2) collapses **triangles**: 3 vertices → 1,
//!   and the triangle's three edge-neighbours disappear with it.
//!
//! Both are "merge a connected set of vertices into one new vertex at a chosen position".
//! The engine owns everything that does not depend on the error metric: incremental
//! adjacency, the priority queue, the validity checks, the boundary rules, the targets, the
//! collapse log and the output mesh. A [`CostModel`] says what a merge costs and where the
//! new vertex goes ([`QuadricModel`] is the QEM one).
//!
//! ```
//! use coarsen_collapse::{Goal, LiveMesh, Options, QemOptions, QuadricModel};
//! use coarsen_mesh::{DVec3, Mesh};
//! // An octahedron: 6 vertices, 8 faces.
//! let p = [DVec3::X, DVec3::Y, -DVec3::X, -DVec3::Y, DVec3::Z, -DVec3::Z];
//! let faces = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4],
//!                  [1, 0, 5], [2, 1, 5], [3, 2, 5], [0, 3, 5]];
//! let mesh = Mesh::new(p.to_vec(), faces);
//! let mut live = LiveMesh::new(&mesh)?;
//! let mut model = QuadricModel::new(&live, &QemOptions::default());
//! let outcome = live.collapse(&mut model, &Options::new(Goal::Vertices(5)), &mut |_| {});
//! let (out, _carry) = live.to_mesh(&mesh)?;
//! assert_eq!((out.n_vertices(), out.n_faces()), (5, 6));
//! assert_eq!(outcome.collapses, 1);
//! # Ok::<(), coarsen_collapse::CollapseError>(())
//! ```
//!
//! # How a run goes
//!
//! 1. **Classify vertices** ([`LiveMesh::new`]): each vertex's faces, walked around it, must
//!    form one closed fan (*interior*) or one open fan (*boundary*). Anything else — a
//!    bow-tie, an edge with three faces, two faces using an edge in the same direction, a
//!    face that repeats a vertex — makes the vertex *locked*: it never moves and no
//!    collapse touches it. A caller may lock more before collapsing ([`LiveMesh::lock`]:
//!    the collapse stages' `features` lock the input's sharp corners). Non-manifold input is therefore accepted, and left alone where
//!    it is non-manifold, instead of refused. Vertices that no face uses are dropped from
//!    the output (and counted by [`LiveMesh::summary`]).
//! 2. **Rank candidates**: every edge (or triangle) whose vertex kinds allow a collapse
//!    (see the table below) is costed by the model and queued by `(cost, insertion
//!    sequence)` (this initial ranking is sorted once; later entries go on a heap), so equal
//!    costs — zero costs on flat regions in particular — are taken first-in first-out, as
//!    paper 2 prescribes.
//! 3. **Collapse** the cheapest candidate unless a check refuses it or it costs more now
//!    than when it was queued (its neighbourhood changed beyond the model's [`Reach`]: it
//!    goes back in line at its current cost); entries go stale
//!    lazily (each holds the sum of its vertices' version stamps) rather than being
//!    removed from the queue. After a collapse the candidates around the new vertex are
//!    re-costed and pushed again, and refused candidates whose neighbourhood changed are
//!    re-queued — except those the link condition refused for a ring vertex that two ring
//!    edges leave or enter (the witness), which wait until a collapse merges it: nothing
//!    else can lift the refusal. The loop stops at the goal, at the error limit, or when no
//!    candidate is left.
//! 4. **Compact** ([`LiveMesh::to_mesh`]): surviving vertices and faces keep their input
//!    order; every attribute is carried by `Mesh::rebuilt` (a merged vertex is the equal
//!    blend of all input vertices merged into it; a face keeps its input face as parent).
//!
//! # Rules
//!
//! Which merges the vertex kinds allow (`B` = boundary vertices among the merged ones):
//!
//! | kinds merged | allowed | position |
//! | --- | --- | --- |
//! | any locked vertex | never | — |
//! | no boundary vertex | yes | the model's choice |
//! | one boundary vertex | yes | that boundary vertex (it does not move) |
//! | two boundary vertices | only if the edge joining them is a boundary edge | the model's choice (QEM keeps it on the boundary with constraint planes) |
//! | three boundary vertices | never | — |
//!
//! So a boundary vertex moves only along its boundary, an interior vertex may collapse onto
//! the boundary, and an interior edge joining two boundary vertices is never collapsed.
//!
//! Checks made before every collapse, with the reason counted in [`Refusals`] (the
//! degenerate test runs first, as the commonest refusal; a collapse failing several checks
//! counts under the first that fails):
//!
//! * **link** — the faces kept around the new vertex must form exactly one fan: a closed
//!   fan of at least 3 faces when no merged vertex was on the boundary, one open fan
//!   otherwise. This is the link condition of Dey et al. in a form that holds for edge and
//!   triangle merges alike: a common neighbour that is not an opposite vertex (paper 2's
//!   "hidden cycle") shows up as a vertex twice in the fan; a tetrahedron's collapse leaves
//!   a fan of two faces (a duplicated face); closing a boundary loop turns an open fan into
//!   a closed one; a collapse that would remove every face of a vertex leaves no fan.
//! * **degenerate** — a kept face whose area would fall below `1e-12 · diagonal²` (the
//!   metrics' definition of a degenerate face), unless it already was degenerate;
//! * **flip** — a kept face whose normal would turn by 90° or more, or by 60° or more from
//!   its input face's normal (a bound on the drift over many collapses, which the per-collapse
//!   test alone lets faces accumulate until they face away from the input), or would turn
//!   to face away (over 90°) from the input surface merged into one of its corners (a face
//!   of a noisy input that already did is left alone): each vertex
//!   carries the summed area-weighted normal of the input faces around the input vertices
//!   merged into it (O(1) per face), tested while that region is coherent (the sum at least
//!   half the region's area). This keeps faces from cutting a sharp crease and leaning over
//!   it. A face may still end nearest to *another* part of the input that faces the other
//!   way (a thin part, two sheets close together); only a spatial query sees that: see
//!   *facing* below;
//! * **quality** (only with [`Options::min_quality`] > 0) — a kept face whose quality
//!   (Frey–Borouchaki Q) would end below the minimum *and* below its current quality;
//! * **facing** (only through [`LiveMesh::collapse_guarded`]) — a kept face fails the
//!   caller's [`FaceGuard`], asked last, once every other check passed. The engine knows no
//!   spatial index: the stages pass the metrics' flipped-face test against the run input,
//!   behind the cheap gate of [`Gated`] (a face is tested when the input merged into its
//!   corners is not coherent — it wraps around a thin part — or when it turns by more than
//!   45°), so that the test costs little where it cannot fail. Each face is given as a
//!   [`Reshape`]: its corners before and after, and that coherence.
//! * **boundary** and **locked** — counted when a candidate is ranked, per the table above.
//!
//! # Targets
//!
//! [`Goal::Vertices`] is met exactly whenever the checks allow it: each edge collapse
//! removes exactly one vertex (a triangle collapse removes two, so it may end one below).
//! [`Goal::Faces`] is met exactly where the mesh has a boundary, else to within one face:
//! an interior edge collapse removes two faces, a boundary one removes one, so with one face
//! left the run looks for a boundary edge it may collapse before taking an interior one (a
//! closed mesh keeps an even face count; [`Outcome::below_face_goal`] says so). When the
//! goal cannot be reached, [`Outcome::stop`] says why.
//!
//! # Progressive record
//!
//! After [`LiveMesh::record_progressive`], each collapse also records what undoing it needs
//! (the kept and removed vertices' positions before it, the faces it deleted with their
//! corners, the faces it renamed), in flat arenas without per-collapse allocations;
//! [`LiveMesh::take_progressive`] hands the [`Progressive`] record over. Off by default, it
//! then costs one branch per collapse. `coarsen-lod` stores it and rebuilds levels from it.
//!
//! # Memory order
//!
//! Collapsing is bound by memory latency: every check and plan reads the positions, face
//! lists and model data of a few neighbouring vertices. [`LiveMesh::new_renumbered`] (what
//! the stages use) numbers the vertices internally in the order the faces first use them,
//! so that neighbours sit close in memory; the output, the log and the progressive record
//! still speak the input's indices. On the bunny subdivided three times (4.4M faces, whose
//! new vertices are appended level by level far from their neighbours) this takes a fifth
//! off the run. An input already in that order runs exactly as with [`LiveMesh::new`];
//! another may collapse candidates of equal cost in another order.
//!
//! As the mesh shrinks its survivors spread thin over arrays sized for the input, and each
//! collapse reads more cache lines for the same work: on that bunny the last fifth of QEM's
//! collapses took twice as long each as the first. So whenever fewer than half the faces
//! are live (and there are at least [`Options::compact_min_faces`]), the engine closes up
//! its arrays: live vertices and faces are renumbered in their order, the queue renamed and
//! cleared of stale entries, and the model renamed through [`CostModel::renumber`] (a model
//! that cannot keeps the numbering). Every comparison of indices comes out as before, so
//! the collapses, the log and the output are the same. Not while recording a progressive
//! record, whose steps speak the numbering of their time.
//!
//! # Determinism
//!
//! No hash map, no randomness, and the same output bytes for any thread count: the initial
//! ranking runs on rayon's threads, and its candidates are queued in the order a single
//! thread would queue them; [`LiveMesh::collapse_in_parts`] (the parallel phase the stages
//! run first on big meshes) cuts the mesh into parts that depend on the mesh alone, each
//! collapsed as a serial run would be, and joins them in part order.

mod guard;
mod live;
mod progressive;
mod qem;
mod queue;
pub mod stage;
mod volume;

#[cfg(test)]
mod fixtures;

pub use guard::{FaceGuard, GATE_COHERENCE, GATE_TURN_DEG, Gated, GuardCounts, NoGuard, Reshape};
pub use live::{LiveMesh, MAX_FACES, PartOptions, Parted, Settled, Summary, attributes_only};
pub use progressive::{ChangedFace, DeletedFace, Fnv, Progressive, Step, fingerprint};
pub use qem::{QemOptions, QuadricModel, edge_plane};
pub use volume::weighted_sve;

use coarsen_geom::DVec3;

/// A vertex or face index.
pub type Index = u32;

/// The "no such vertex" value in fixed-size vertex lists.
pub const NONE: Index = Index::MAX;

/// What one collapse merges.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unit {
    /// The two ends of an edge (Garland–Heckbert edge collapse).
    Edge,
    /// The three corners of a triangle (paper 2's triangle constriction).
    Triangle,
}

/// Which candidates are re-costed right after a collapse.
///
/// A candidate outside the reach whose cost changed keeps its queued cost; it is costed
/// again when it comes off the queue, and queued again at its current cost if that grew.
/// Every collapse is therefore made at its exact current cost; only a candidate that got
/// cheaper may be taken later than an exact order would take it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reach {
    /// Only those containing the new vertex (the cost depends on per-vertex data only,
    /// as with quadrics accumulated per vertex).
    Kept,
    /// Those containing the new vertex or one of its neighbours (the cost depends on the
    /// faces around the candidate, as with paper 2's per-face quadrics).
    Ring,
    /// Those containing a vertex within two edges of the new vertex (the cost sums
    /// per-face data around the candidate, and a face's data depends on the faces sharing
    /// a vertex with it, as with paper 2's normal factor).
    TwoRings,
}

/// The kind of a vertex, fixed when the [`LiveMesh`] is built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VertexKind {
    /// Its faces form one closed fan.
    Interior,
    /// Its faces form one open fan.
    Boundary,
    /// Non-manifold, or used by a face that repeats a vertex: never moved nor merged.
    Locked,
    /// Used by no face: dropped from the output.
    Isolated,
}

/// A merge the engine asks a [`CostModel`] about.
#[derive(Clone, Copy, Debug)]
pub struct Merge<'a> {
    /// The vertices to merge (2 for an edge, 3 for a triangle), in ascending order for edges.
    pub vertices: &'a [Index],
    /// When set, the new vertex must sit at this (boundary) vertex's position.
    pub pinned: Option<Index>,
}

/// A cost model's answer: where the merged vertex goes and what that costs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// Position of the merged vertex.
    pub position: DVec3,
    /// Cost (finite, ≥ 0); lower collapses first.
    pub cost: f64,
}

/// An error metric: costs merges, places merged vertices, and keeps its per-vertex data
/// up to date as the engine collapses. `Sync`: the engine costs the initial candidates on
/// several threads (and queues them in one fixed order).
pub trait CostModel: Sync {
    /// What a candidate is: an edge or a triangle.
    fn unit(&self) -> Unit;
    /// Which candidates a collapse makes stale.
    fn reach(&self) -> Reach;
    /// The position and cost of `merge`, or `None` to refuse it. Must be deterministic:
    /// the engine calls it again when the candidate comes off the queue.
    fn plan(&self, mesh: &LiveMesh, merge: &Merge<'_>) -> Option<Plan>;
    /// Makes the model ready to cost `mesh`'s candidates: called before a serial run ranks
    /// them and before a round of parts samples their costs. A model made without its
    /// per-candidate data (because the parts would rebuild it) builds it here. Default:
    /// nothing.
    fn prepare(&mut self, mesh: &LiveMesh) {
        let _ = mesh;
    }
    /// Called after `merged` (which includes `kept`) became vertex `kept`, already at its
    /// new position and with its new faces.
    fn merged(&mut self, mesh: &LiveMesh, kept: Index, merged: &[Index]);
    /// Renames the model's vertices and faces before the engine closes up its arrays: the
    /// new vertex `i` is the old `vertices[i]` and the new face `j` the old `faces[j]`
    /// (both ascending: the order stays). Returns false, changing nothing, when the model
    /// cannot (the default): the engine then keeps its numbering.
    fn renumber(&mut self, vertices: &[Index], faces: &[Index]) -> bool {
        let _ = (vertices, faces);
        false
    }
    /// A model with this one's settings for `part`, a piece of the mesh this model was
    /// made for (see [`LiveMesh::collapse_in_parts`]), or `None` (the default) when the
    /// model cannot work on parts.
    fn for_part(&self, part: &LiveMesh) -> Option<Self>
    where
        Self: Sized,
    {
        let _ = part;
        None
    }
    /// After [`LiveMesh::collapse_in_parts`]: vertex `kept` of the whole mesh now stands for
    /// `merged` (`kept` first, then every vertex the parts merged into it, in their order).
    /// Called for each such vertex, part after part, while the mesh's vertex → faces lists
    /// are not rebuilt yet: read the positions and faces only. The default calls
    /// [`CostModel::merged`].
    fn joined(&mut self, mesh: &LiveMesh, kept: Index, merged: &[Index]) {
        self.merged(mesh, kept, merged);
    }
    /// After [`LiveMesh::collapse_in_parts`] joined the parts (and closed up the mesh, when
    /// the model could follow): the mesh is whole and current again. Default: nothing.
    fn after_join(&mut self, mesh: &LiveMesh) {
        let _ = mesh;
    }
    /// A count the model keeps of its collapses (SVEC: those placed by the feature rule),
    /// which [`LiveMesh::collapse_in_parts`] adds up over the parts. Default 0.
    fn tally(&self) -> usize {
        0
    }
    /// Adds a part's [`CostModel::tally`] to this model's. Default: nothing.
    fn add_tally(&mut self, n: usize) {
        let _ = n;
    }
}

/// The size a run stops at.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Goal {
    /// At most this many vertices used by faces (exactly this many when reachable).
    Vertices(usize),
    /// At most this many faces (one fewer at worst: see the crate docs).
    Faces(usize),
}

/// Settings of one run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Where to stop.
    pub goal: Goal,
    /// Stop before the first collapse costing more than this (model units). Default `None`.
    pub max_error: Option<f64>,
    /// Refuse collapses leaving a face below this quality (and below its current quality);
    /// `0` turns the check off. Default `0`.
    pub min_quality: f64,
    /// Keep every collapse in [`Outcome::log`] (56 bytes each); `false` leaves the log
    /// empty, for runs that only need the totals. Default `true`.
    pub keep_log: bool,
    /// Close up the arrays (see the crate docs, *Memory order*) whenever fewer than half
    /// their faces are live and they hold at least this many; `usize::MAX` never. Default
    /// [`COMPACT_MIN_FACES`].
    pub compact_min_faces: usize,
    /// Also sum each collapse's squared volume weighted as paper 2's Eq. (4) quadrics
    /// ([`Outcome::sve_weighted`]; a few hundred dot products per collapse). Default
    /// `false`.
    pub weighted_sve: bool,
}

/// Keeps the entries `kept` (ascending indices) of `values`, in their order, in place (no
/// new allocation): what a model does with its per-vertex and per-face arrays in
/// [`CostModel::renumber`].
///
/// ```
/// let mut v = vec![10, 11, 12, 13, 14];
/// coarsen_collapse::keep_in_order(&mut v, &[1, 2, 4]);
/// assert_eq!(v, [11, 12, 14]);
/// ```
pub fn keep_in_order<T: Copy>(values: &mut Vec<T>, kept: &[Index]) {
    for (new, &old) in kept.iter().enumerate() {
        // `old ≥ new`: nothing still to be read is overwritten.
        values[new] = values[old as usize];
    }
    values.truncate(kept.len());
}

/// The default of [`Options::compact_min_faces`]: below it the arrays fit the caches.
pub const COMPACT_MIN_FACES: usize = 1 << 16;

impl Options {
    /// Stop at `goal`, no error limit, no quality guard.
    pub fn new(goal: Goal) -> Self {
        Options {
            goal,
            max_error: None,
            min_quality: 0.0,
            keep_log: true,
            compact_min_faces: COMPACT_MIN_FACES,
            weighted_sve: false,
        }
    }
}

/// Why a run stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StopReason {
    /// The goal was met.
    Reached,
    /// The cheapest remaining collapse costs more than the error limit.
    MaxError {
        /// Its cost.
        cost: f64,
    },
    /// Every remaining candidate is refused by a check or a rule.
    Exhausted,
}

/// How many candidates each check or rule refused (a candidate refused again after its
/// neighbourhood changed counts again).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Refusals {
    /// The result would not be a manifold, or would close a hole or lose a vertex.
    pub link: u64,
    /// A kept face would turn by 90° or more, drift 60° from its input face, or face away
    /// from a corner's input region.
    pub flip: u64,
    /// A kept face would become degenerate.
    pub degenerate: u64,
    /// A kept face would fall below the minimum quality.
    pub quality: u64,
    /// A kept face would fail the run's [`FaceGuard`] (e.g. face away from the input).
    pub facing: u64,
    /// The boundary rules forbid the merge.
    pub boundary: u64,
    /// A locked vertex is involved.
    pub locked: u64,
    /// The seam rules forbid the merge (per-corner attributes tracked: it would move a
    /// seam vertex, remove a seam's corner, or cross a seam).
    pub seam: u64,
    /// The cost model refused (or returned a non-finite plan).
    pub model: u64,
}

impl Refusals {
    /// The counts by reason name, for reports.
    pub fn by_reason(&self) -> std::collections::BTreeMap<&'static str, u64> {
        std::collections::BTreeMap::from([
            ("link", self.link),
            ("flip", self.flip),
            ("degenerate", self.degenerate),
            ("quality", self.quality),
            ("facing", self.facing),
            ("boundary", self.boundary),
            ("locked", self.locked),
            ("seam", self.seam),
            ("model", self.model),
        ])
    }
}

impl StopReason {
    /// A one-word name for reports: `reached`, `max_error` or `exhausted`.
    pub fn name(&self) -> &'static str {
        match self {
            StopReason::Reached => "reached",
            StopReason::MaxError { .. } => "max_error",
            StopReason::Exhausted => "exhausted",
        }
    }
}

impl Outcome {
    /// A run that did nothing (and reached its goal).
    pub fn none() -> Outcome {
        Outcome {
            stop: StopReason::Reached,
            collapses: 0,
            refused: Refusals::default(),
            sve: 0.0,
            sve_max: 0.0,
            sve_weighted: 0.0,
            max_cost: 0.0,
            costs: CostCurve::default(),
            log: Vec::new(),
        }
    }

    /// This run followed by `next` (on the same mesh): counts and logs added up, `next`'s
    /// stop.
    pub fn then(mut self, next: Outcome) -> Outcome {
        self.stop = next.stop;
        self.collapses += next.collapses;
        self.refused.add(&next.refused);
        self.sve += next.sve;
        self.sve_max = self.sve_max.max(next.sve_max);
        self.sve_weighted += next.sve_weighted;
        self.max_cost = self.max_cost.max(next.max_cost);
        self.costs.append(&next.costs);
        self.log.extend(next.log);
        self
    }

    /// Why the run stopped short of its goal, for a report warning; `None` when it reached it.
    /// `target` says the goal in words, `max_error` is the limit the run had.
    pub fn shortfall(
        &self,
        target: &str,
        max_error: f64,
        vertices: usize,
        faces: usize,
    ) -> Option<String> {
        let at = format!("{vertices} vertices and {faces} faces");
        let r = &self.refused;
        match self.stop {
            StopReason::Reached => None,
            StopReason::MaxError { cost } => Some(format!(
                "target ({target}) not reached: stopped at {at}; the next collapse costs {cost:.3e}, above max_error = {max_error}"
            )),
            StopReason::Exhausted => Some(format!(
                "target ({target}) not reached: stopped at {at}; every remaining collapse is refused \
                 (link {}, flip {}, degenerate {}, quality {}, facing {}, boundary {}, locked {}, model {})",
                r.link, r.flip, r.degenerate, r.quality, r.facing, r.boundary, r.locked, r.model
            )),
        }
    }

    /// Why a run that met the face goal `goal` ended below it, if it did (`after`: the
    /// mesh at the end): the last collapse took two faces where one was left.
    pub fn below_face_goal(&self, goal: Goal, after: &Summary) -> Option<String> {
        let Goal::Faces(n) = goal else {
            return None;
        };
        if self.stop != StopReason::Reached || after.faces >= n {
            return None;
        }
        let why = if after.boundary_edges == 0 {
            "a closed mesh keeps an even number of faces (each edge collapse takes two)"
        } else {
            "no boundary edge could take the last face alone (an interior edge collapse takes two)"
        };
        Some(format!(
            "{} faces, {} below the target's {n}: {why}",
            after.faces,
            n - after.faces
        ))
    }
}

/// One collapse performed, in input vertex indices: enough to replay the sequence (undoing
/// it needs more: see [`Progressive`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CollapseRecord {
    /// The vertex that survived (it now sits at `position`).
    pub kept: Index,
    /// The vertices merged into it ([`NONE`] when unused: edges merge one).
    pub removed: [Index; 2],
    /// The new position.
    pub position: DVec3,
    /// The model's cost.
    pub cost: f64,
    /// Paper 2's squared-volume error of this collapse: v̄ᵀ(Σ (1/9) Sᵢ² p pᵀ)v̄ over the
    /// faces around the merged vertices, before the collapse.
    pub sve: f64,
}

/// What a run did.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// Why it stopped.
    pub stop: StopReason,
    /// Collapses performed.
    pub collapses: usize,
    /// Candidates refused, by reason.
    pub refused: Refusals,
    /// Sum of the collapses' squared-volume errors (metrics.md `sve`).
    pub sve: f64,
    /// The largest squared-volume error of one collapse (0 when none).
    pub sve_max: f64,
    /// Sum of the collapses' squared volumes weighted as paper 2's Eq. (4) quadrics, Wᵢ·Nᵢ
    /// per face ([`weighted_sve`]); 0 unless [`Options::weighted_sve`].
    pub sve_weighted: f64,
    /// The largest cost of a collapse performed (0 when none).
    pub max_cost: f64,
    /// The collapses' costs in the order performed, binned ([`CostCurve`]).
    pub costs: CostCurve,
    /// Every collapse, in order (empty unless [`Options::keep_log`]).
    pub log: Vec<CollapseRecord>,
}

/// The cost of the collapses against their count, in at most [`CostCurve::MAX_BINS`]
/// bins of consecutive collapses (for a report's plot): each bin holds the count of
/// collapses up to its end and the largest cost among its own. Bins double in width when
/// they run out, so the curve stays small on any mesh and costs nothing to keep.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CostCurve {
    /// `(collapses up to the bin's end, largest cost in the bin)`, in order.
    pub bins: Vec<(u64, f64)>,
    /// Collapses per bin while filling (0 counts as 1).
    width: u64,
    /// Collapses in the last bin, which takes more while under `width`.
    fill: u64,
    /// Collapses so far.
    count: u64,
}

impl CostCurve {
    /// Bins kept at most.
    pub const MAX_BINS: usize = 512;

    /// Adds the next collapse's cost.
    #[inline]
    pub fn push(&mut self, cost: f64) {
        self.count += 1;
        match self.bins.last_mut() {
            Some(last) if self.fill < self.width.max(1) => {
                *last = (self.count, last.1.max(cost));
                self.fill += 1;
            }
            _ => {
                self.bins.push((self.count, cost));
                self.fill = 1;
            }
        }
        if self.bins.len() > Self::MAX_BINS {
            self.halve();
        }
    }

    /// The curve followed by `next`'s collapses.
    pub fn append(&mut self, next: &CostCurve) {
        let offset = self.count;
        self.bins
            .extend(next.bins.iter().map(|&(end, max)| (end + offset, max)));
        self.count += next.count;
        self.width = self.width.max(next.width);
        while self.bins.len() > Self::MAX_BINS {
            self.halve();
        }
        self.fill = self.width.max(1);
    }

    /// Joins neighbouring bins in pairs; the bins to come are twice as wide.
    fn halve(&mut self) {
        self.bins = self
            .bins
            .chunks(2)
            .map(|pair| {
                let largest = pair.iter().map(|b| b.1).fold(f64::NEG_INFINITY, f64::max);
                (pair[pair.len() - 1].0, largest)
            })
            .collect();
        self.width = self.width.max(1) * 2;
        self.fill = self.width;
    }
}

/// Why a mesh cannot be collapsed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CollapseError {
    /// Indices out of range, too many elements, or attribute columns of the wrong length.
    #[error(transparent)]
    Index(#[from] coarsen_mesh::IndexError),
    /// More faces than the engine's 32-bit tables hold ([`MAX_FACES`]).
    #[error("{faces} faces exceed the {max} that the collapse engine supports")]
    TooLarge {
        /// Faces of the mesh.
        faces: usize,
        /// The limit.
        max: usize,
    },
    /// A vertex position is NaN or infinite.
    #[error("vertex {vertex} has a non-finite position ({x}, {y}, {z})")]
    NonFinite {
        /// The vertex.
        vertex: usize,
        /// Its x coordinate.
        x: f64,
        /// Its y coordinate.
        y: f64,
        /// Its z coordinate.
        z: f64,
    },
    /// [`LiveMesh::to_mesh`] was given a mesh other than the one the live mesh was built from.
    #[error(
        "the mesh given has {vertices} vertices and {faces} faces, but the collapsed mesh was built from {expected_vertices} and {expected_faces}"
    )]
    MeshMismatch {
        /// Vertices of the mesh given.
        vertices: usize,
        /// Faces of the mesh given.
        faces: usize,
        /// Vertices of the mesh built from.
        expected_vertices: usize,
        /// Faces of the mesh built from.
        expected_faces: usize,
    },
}

#[cfg(test)]
mod cost_curve_tests {
    use super::CostCurve;

    #[test]
    fn the_curve_keeps_every_collapse_in_few_bins_with_their_largest_cost() {
        let mut c = CostCurve::default();
        let n = 10_000u64;
        for i in 0..n {
            c.push(i as f64 * if i % 7 == 0 { 2.0 } else { 1.0 });
        }
        assert!(c.bins.len() <= CostCurve::MAX_BINS && c.bins.len() > CostCurve::MAX_BINS / 4);
        assert_eq!(c.bins.last().unwrap().0, n);
        // Ends ascend; each bin's largest is the largest of its own collapses.
        let mut start = 0;
        for &(end, largest) in &c.bins {
            assert!(end > start);
            let want = (start..end)
                .map(|i| i as f64 * if i % 7 == 0 { 2.0 } else { 1.0 })
                .fold(f64::NEG_INFINITY, f64::max);
            assert_eq!(largest, want, "bin ending at {end}");
            start = end;
        }
        // A second run goes on from the first one's count.
        let mut more = CostCurve::default();
        (0..5).for_each(|_| more.push(-1.0));
        let before = c.bins.len();
        c.append(&more);
        assert_eq!(c.bins.last().unwrap(), &(n + 5, -1.0));
        assert!(c.bins.len() <= before + 5);
        c.push(3.0);
        assert_eq!(c.bins.last().unwrap(), &(n + 6, 3.0));
    }
}
