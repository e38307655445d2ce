//! The parallel phase: the mesh cut into parts collapsed side by side, their collapses then
//! made on the whole mesh (see [`LiveMesh::collapse_in_parts`]).

use super::{DEAD, Derived, LIVE, LiveMesh, Run};
use crate::GuardCounts;
use crate::{
    CostModel, FaceGuard, Goal, Index, NONE, Options, Outcome, StopReason, Unit, VertexKind,
};
use coarsen_geom::DVec3;
use rayon::prelude::*;

/// Settings of [`LiveMesh::collapse_in_parts`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PartOptions {
    /// No parallel phase on a mesh with fewer live faces than this.
    pub min_faces: usize,
    /// No round of parts when fewer collapses than this are left.
    pub min_collapses: usize,
    /// About how many faces each part holds (the part count depends on the mesh alone,
    /// never on the thread count).
    pub faces_per_part: usize,
    /// The share of the collapses the goal needs that the parts may make, at most (each
    /// part its share of them, by its vertices).
    pub share: f64,
    /// From the second round on, the parts stop at the cost of the candidate at this rank
    /// among the round's candidates, as a multiple of the collapses the goal still needs
    /// (ranked over a sample).
    pub bound_rank: f64,
    /// Rounds of parts (each cut halfway between the last one's cuts), at most.
    pub rounds: usize,
    /// Steps of each round after the first, at most: the parts stay and collapse on up to a
    /// higher cost bound at each step (1: one step, the rest is left to the serial run).
    pub steps: usize,
}

impl PartOptions {
    /// The default options when `on`, else [`PartOptions::off`] (a stage's `parallel`).
    pub fn when(on: bool) -> Self {
        if on {
            PartOptions::default()
        } else {
            PartOptions::off()
        }
    }

    /// No parallel phase at all.
    pub fn off() -> Self {
        PartOptions {
            min_faces: usize::MAX,
            ..PartOptions::default()
        }
    }
}

impl Default for PartOptions {
    fn default() -> Self {
        PartOptions {
            min_faces: 1 << 19,
            min_collapses: 1 << 14,
            faces_per_part: 1 << 17,
            share: 0.9,
            bound_rank: 1.0,
            rounds: 2,
            steps: 1,
        }
    }
}

/// What [`LiveMesh::collapse_parted`] did.
pub struct Parted<G> {
    /// Both phases' collapses, refusals and stop.
    pub outcome: Outcome,
    /// How many of the collapses the parts made.
    pub in_parts: usize,
    /// What the parts' guards did.
    pub part_counts: GuardCounts,
    /// The serial phase's guard (for a run that goes on, and its counts).
    pub guard: G,
}

/// One candidate in this many is costed to find the parts' cost bound.
const SAMPLE_EVERY: usize = 16;

/// What the parts of one round share: where they are cut, which vertices are free, how
/// many collapses the goal needs, and the cost bound (from the rank, when bounded).
struct Round<'a> {
    cuts: &'a [usize],
    free: &'a [bool],
    needed: usize,
    bound: f64,
    bound_rank: Option<f64>,
}

/// What one part did, in the whole mesh's indices: what its free vertices and their faces
/// became, and its counts.
struct PartRun<G> {
    /// Each surviving free vertex: index, position, summed input normal and area.
    vertices: Vec<(Index, DVec3, DVec3, f64)>,
    /// The input vertices merged into each surviving free vertex that merged any, the
    /// vertex itself first, in the order it merged them.
    clusters: Vec<Vec<Index>>,
    /// Each surviving face at a free vertex: index, corners and (seams tracked) their
    /// wedges.
    faces: Vec<(Index, [Index; 3], Option<[Index; 3]>)>,
    /// Vertices and faces removed.
    removed_vertices: usize,
    removed_faces: usize,
    /// The part model's [`CostModel::tally`].
    tally: usize,
    outcome: Outcome,
    guard: G,
}

impl LiveMesh {
    /// Collapses most of the way to `opts.goal` on several threads, before
    /// [`LiveMesh::collapse_guarded`] finishes on one (the stages call both, in that order);
    /// returns what it did and the guards the parts used (for their counts).
    ///
    /// In each round the vertices are cut into parts of consecutive indices (close in space
    /// once [`LiveMesh::new_renumbered`] ordered them; about
    /// [`PartOptions::faces_per_part`] faces each). A vertex is *free* when every vertex of
    /// its faces lies in its part: collapses of free vertices in different parts touch no
    /// common vertex or face, so they commute. Each part becomes a live mesh of its own
    /// (every face at one of its vertices, the vertices that are not free locked), with a
    /// model made by [`CostModel::for_part`] and a guard by `new_guard`, and collapses in
    /// its own greedy order, with every check, until it made its share of
    /// [`PartOptions::share`] of the collapses still needed (shared by free vertices) or,
    /// from the second round on, its candidates cost more than the round's bound (the
    /// cost at rank [`PartOptions::bound_rank`] × the collapses still needed among the
    /// round's candidates, from a sample). With [`PartOptions::steps`] above one, the parts
    /// of a bounded round stay and go on in steps, each up to a higher bound: the cost at
    /// the same rank among their queued candidates, each part capped by how many of its
    /// candidates cost that or less (so that they never make more collapses than needed
    /// between them), until fewer than [`PartOptions::min_collapses`] are needed, a step
    /// makes few, or the rank leaves the cheaper half of the queued candidates (where the
    /// one greedy order would take candidates not made yet first). Each part's queue
    /// carries over, so each part goes on exactly as a serial run of it with the higher
    /// bound would.
    ///
    /// What the parts' free vertices and faces became is then written into this mesh, part
    /// after part, the model told through [`CostModel::joined`] and
    /// [`CostModel::after_join`], and the arrays closed up. The second round's cuts fall
    /// halfway between the first's, so that the strips the first left locked are collapsed
    /// too.
    ///
    /// Does nothing (an empty outcome) on a mesh smaller than [`PartOptions::min_faces`],
    /// while a progressive record is kept (its steps must be made on this mesh, one after
    /// the other), when `model` cannot work on parts, or when fewer than
    /// [`PartOptions::min_collapses`] collapses are left. The output differs from a serial run's (the order differs near
    /// the cuts and between parts), but not with the thread count: the parts depend on the
    /// mesh alone, each runs as a serial run would, and they are joined in part order.
    pub fn collapse_in_parts<M, G, F>(
        &mut self,
        model: &mut M,
        new_guard: F,
        opts: &Options,
        parts: &PartOptions,
    ) -> (Outcome, Vec<G>)
    where
        M: CostModel + Send,
        G: FaceGuard + Send,
        F: Fn() -> G + Sync,
    {
        let mut out = Outcome::none();
        let mut guards = Vec::new();
        if !self.will_part(parts) {
            return (out, guards);
        }
        for round in 0..parts.rounds {
            if self.remaining(opts.goal) < parts.min_collapses {
                break;
            }
            // Each round's cuts fall halfway between the last round's.
            let offset = if round % 2 == 0 { 0.0 } else { 0.5 };
            // The first round works on the fine mesh, where the order of collapses hardly
            // matters (the serial run is left a tenth of them to place the last ones); later
            // rounds stop at the cost frontier, so that the dearest collapses, which shape
            // the result, are taken in one order.
            let bound_rank = (round > 0).then_some(parts.bound_rank);
            let (o, g) = self.part_round(model, &new_guard, opts, parts, bound_rank, offset);
            out = out.then(o);
            guards.extend(g);
        }
        out.stop = StopReason::Reached;
        (out, guards)
    }

    /// Whether [`LiveMesh::collapse_in_parts`] cuts this mesh into parts with `parts` (when
    /// collapses are left to make).
    pub fn will_part(&self, parts: &PartOptions) -> bool {
        // A progressive record needs every collapse made on this mesh.
        self.n_faces >= parts.min_faces && self.history.is_none()
    }

    /// [`LiveMesh::collapse_in_parts`], then [`LiveMesh::collapse_guarded`] to the goal with
    /// a fresh guard: what the stages run. `progress` hears the collapses of both.
    pub fn collapse_parted<M, G, F>(
        &mut self,
        model: &mut M,
        new_guard: F,
        opts: &Options,
        parts: &PartOptions,
        progress: &mut dyn FnMut(usize),
    ) -> Parted<G>
    where
        M: CostModel + Send,
        G: FaceGuard + Send,
        F: Fn() -> G + Sync,
    {
        let (first, guards) = self.collapse_in_parts(model, &new_guard, opts, parts);
        let in_parts = first.collapses;
        progress(in_parts);
        let mut guard = new_guard();
        let rest = self.collapse_guarded(model, &mut guard, opts, &mut |n| progress(in_parts + n));
        Parted {
            outcome: first.then(rest),
            in_parts,
            part_counts: guards
                .iter()
                .fold(GuardCounts::default(), |sum, g| sum.plus(&g.counts())),
            guard,
        }
    }

    /// One round of [`LiveMesh::collapse_in_parts`], its cuts `offset` parts along: the
    /// vertices cut into parts, those whose faces all lie in their part freed, the parts
    /// collapsed side by side, and what they left written back into this mesh.
    fn part_round<M, G, F>(
        &mut self,
        model: &mut M,
        new_guard: &F,
        opts: &Options,
        parts: &PartOptions,
        bound_rank: Option<f64>,
        offset: f64,
    ) -> (Outcome, Vec<G>)
    where
        M: CostModel + Send,
        G: FaceGuard + Send,
        F: Fn() -> G + Sync,
    {
        let unit = model.unit();
        let needed = self.needed_collapses(unit, opts.goal);
        let cuts = self.part_cuts(parts, offset);
        let free = self.free_vertices(&cuts);
        let bound = match bound_rank {
            Some(rank) => {
                model.prepare(self);
                self.sample_bound(model, unit, &free, needed, rank)
            }
            None => f64::INFINITY,
        };
        let round = Round {
            cuts: &cuts,
            free: &free,
            needed,
            bound,
            bound_rank,
        };
        let runs = self.run_parts(model, new_guard, opts, parts, &round);
        if runs.iter().all(|r| r.outcome.collapses == 0) {
            let mut out = Outcome::none();
            out.refused = runs.iter().fold(out.refused, |mut sum, r| {
                sum.add(&r.outcome.refused);
                sum
            });
            return (out, runs.into_iter().map(|r| r.guard).collect());
        }
        self.join_parts(model, runs, &free, opts)
    }

    /// How many collapses of `unit` the goal still needs (at most: a collapse removes one
    /// or two vertices, two or four faces).
    fn needed_collapses(&self, unit: Unit, goal: Goal) -> usize {
        let per_collapse = match (unit, goal) {
            (Unit::Edge, Goal::Vertices(_)) => 1,
            (Unit::Edge, Goal::Faces(_)) => 2,
            (Unit::Triangle, Goal::Vertices(_)) => 2,
            (Unit::Triangle, Goal::Faces(_)) => 4,
        };
        let left = match goal {
            Goal::Vertices(n) => self.n_vertices.saturating_sub(n),
            Goal::Faces(n) => self.n_faces.saturating_sub(n),
        };
        left / per_collapse
    }

    /// Where the parts start: part `k` holds the vertices `cuts[k]..cuts[k + 1]` (every cut
    /// `offset` parts along; the count depends on the mesh alone).
    fn part_cuts(&self, parts: &PartOptions, offset: f64) -> Vec<usize> {
        let n_parts = (self.n_faces / parts.faces_per_part.max(1)).clamp(2, 64);
        let slots = self.pos.len();
        let mut cuts: Vec<usize> = vec![0];
        cuts.extend(
            (0..=n_parts)
                .map(|k| ((k as f64 + offset) * slots as f64 / n_parts as f64) as usize)
                .filter(|&c| c > 0 && c < slots),
        );
        cuts.push(slots);
        cuts.dedup();
        cuts
    }

    /// Per vertex: free, i.e. live, neither locked nor isolated, and every vertex of its
    /// faces in its part (`cuts`).
    fn free_vertices(&self, cuts: &[usize]) -> Vec<bool> {
        let slots = self.pos.len();
        let mut part_id = vec![0u32; slots];
        for (k, w) in cuts.windows(2).enumerate() {
            part_id[w[0]..w[1]].fill(k as u32);
        }
        let part_of = |v: Index| part_id[v as usize];
        (0..slots as Index)
            .into_par_iter()
            .map(|v| {
                let ok_kind = matches!(
                    self.kind[v as usize],
                    VertexKind::Interior | VertexKind::Boundary
                );
                ok_kind
                    && self.alive[v as usize]
                    && self.lists.get(v).iter().all(|&f| {
                        self.faces[f as usize]
                            .iter()
                            .all(|&u| part_of(u) == part_of(v))
                    })
            })
            .collect()
    }

    /// Collapses the parts of `round` side by side, each up to its share of the collapses
    /// needed and the round's cost bound (in steps when the round is bounded and
    /// [`PartOptions::steps`] asks for several).
    fn run_parts<M, G, F>(
        &self,
        model: &M,
        new_guard: &F,
        opts: &Options,
        parts: &PartOptions,
        round: &Round<'_>,
    ) -> Vec<PartRun<G>>
    where
        M: CostModel + Send,
        G: FaceGuard + Send,
        F: Fn() -> G + Sync,
    {
        let (cuts, free, needed) = (round.cuts, round.free, round.needed);
        let free_total = free.iter().filter(|&&f| f).count().max(1);
        let max_error = error_limit(opts, round.bound);
        let share_cap = |(lo, hi): (usize, usize)| {
            let free_here = free[lo..hi].iter().filter(|&&f| f).count();
            (parts.share * needed as f64 * free_here as f64 / free_total as f64) as usize
        };
        match round.bound_rank.filter(|_| parts.steps > 1) {
            // One step per part: it is built, collapsed and done with on one thread.
            None => cuts
                .par_windows(2)
                .map(|w| {
                    let (lo, hi) = (w[0], w[1]);
                    let mut part =
                        self.start_part(model, new_guard, (lo as Index, hi as Index), free);
                    part.step(opts, share_cap((lo, hi)), max_error);
                    part.finish(free)
                })
                .collect(),
            Some(rank) => {
                let mut all: Vec<Part<M, G>> = cuts
                    .par_windows(2)
                    .map(|w| {
                        self.start_part(model, new_guard, (w[0] as Index, w[1] as Index), free)
                    })
                    .collect();
                let caps: Vec<usize> = cuts.windows(2).map(|w| share_cap((w[0], w[1]))).collect();
                let limits = StepLimits {
                    bound_rank: rank,
                    needed,
                    min_collapses: parts.min_collapses,
                    steps: parts.steps,
                };
                stepped(&mut all, caps, opts, round.bound, &limits);
                all.into_par_iter().map(|p| p.finish(free)).collect()
            }
        }
    }

    /// Writes what the parts made back into this mesh: the faces and vertices they owned
    /// (at `free` vertices) go, what they left comes back, part after part, the model
    /// told; then the arrays are closed up. Returns the parts' outcomes added up and
    /// their guards.
    fn join_parts<M, G>(
        &mut self,
        model: &mut M,
        runs: Vec<PartRun<G>>,
        free: &[bool],
        opts: &Options,
    ) -> (Outcome, Vec<G>)
    where
        M: CostModel + Send,
        G: FaceGuard + Send,
    {
        for f in 0..self.faces.len() {
            if self.face_state[f] == LIVE && self.faces[f].iter().any(|&v| free[v as usize]) {
                self.face_state[f] = DEAD;
            }
        }
        for (alive, &free) in self.alive.iter_mut().zip(free) {
            *alive &= !free;
        }
        let mut out = Outcome::none();
        let mut guards = Vec::with_capacity(runs.len());
        for run in runs {
            let mut o = run.outcome;
            // Candidates at vertices the cut locked, or refused by the boundary rules, are
            // ranked (and counted) again by the serial phase.
            o.refused.locked = 0;
            o.refused.boundary = 0;
            if opts.keep_log {
                for r in &mut o.log {
                    r.kept = self.original(r.kept);
                    r.removed = r
                        .removed
                        .map(|v| if v == NONE { NONE } else { self.original(v) });
                }
            } else {
                o.log = Vec::new();
            }
            out = out.then(o);
            guards.push(run.guard);
            for &(v, p, normal, area) in &run.vertices {
                let v = v as usize;
                self.alive[v] = true;
                self.pos[v] = p;
                self.region_normal[v] = normal;
                self.region_area[v] = area;
            }
            for &(f, corners, wedges) in &run.faces {
                self.face_state[f as usize] = LIVE;
                self.faces[f as usize] = corners;
                if let (Some(seams), Some(w)) = (&mut self.seams, wedges) {
                    seams.wedge[f as usize] = w;
                }
            }
            for members in &run.clusters {
                // As `merge` links them: each merged vertex's own list after the kept one's.
                let kept = members[0] as usize;
                for &m in &members[1..] {
                    let tail = self.cluster_tail[kept] as usize;
                    self.cluster_next[tail] = self.base(m);
                    self.cluster_tail[kept] = self.cluster_tail[m as usize];
                }
                model.joined(self, members[0], members);
            }
            model.add_tally(run.tally);
            self.n_vertices -= run.removed_vertices;
            self.n_faces -= run.removed_faces;
        }
        self.rebuild_closed_up(model);
        model.after_join(self);
        (out, guards)
    }

    /// The cost of the candidate at rank `bound_rank · needed` among the candidates of free
    /// vertices, estimated from one in [`SAMPLE_EVERY`] of them.
    fn sample_bound<M: CostModel>(
        &self,
        model: &M,
        unit: Unit,
        free: &[bool],
        needed: usize,
        bound_rank: f64,
    ) -> f64 {
        let n = self.faces.len();
        let mut costs: Vec<f64> = (0..n.div_ceil(SAMPLE_EVERY))
            .into_par_iter()
            .flat_map_iter(|k| {
                let f = k * SAMPLE_EVERY;
                let face = self.faces[f];
                let live = self.face_state[f] == LIVE && face.iter().all(|&v| free[v as usize]);
                let cands: [Option<[Index; 3]>; 3] = if !live {
                    [None; 3]
                } else {
                    match unit {
                        Unit::Triangle => [Some(face), None, None],
                        Unit::Edge => std::array::from_fn(|c| {
                            let (a, b) = (face[c], face[(c + 1) % 3]);
                            (a < b || self.is_boundary_edge(a, b)).then_some([
                                a.min(b),
                                a.max(b),
                                NONE,
                            ])
                        }),
                    }
                };
                cands.into_iter().flatten().filter_map(move |c| {
                    let verts = &c[..if unit == Unit::Edge { 2 } else { 3 }];
                    let pin = self.rule(verts).ok()?;
                    self.plan_pinned(model, verts, pin).map(|(p, _)| p.cost)
                })
            })
            .collect();
        if costs.is_empty() {
            return 0.0;
        }
        let rank =
            ((bound_rank * needed as f64 / SAMPLE_EVERY as f64) as usize).min(costs.len() - 1);
        let (_, c, _) = costs.select_nth_unstable_by(rank, f64::total_cmp);
        *c
    }

    /// The part of vertices `lo..hi` as a live mesh of its own.
    fn start_part<M, G, F>(
        &self,
        model: &M,
        new_guard: &F,
        (lo, hi): (Index, Index),
        free: &[bool],
    ) -> Part<M, G>
    where
        M: CostModel,
        G: FaceGuard,
        F: Fn() -> G,
    {
        // Every live face at a vertex of the part, once (from its first corner in the part).
        let inside = |v: Index| v >= lo && v < hi;
        let mut faces: Vec<Index> = Vec::new();
        for v in lo..hi {
            for &f in self.lists.get(v) {
                let face = self.faces[f as usize];
                if face.iter().find(|&&u| inside(u)) == Some(&v) {
                    faces.push(f);
                }
            }
        }
        faces.sort_unstable();
        let mut verts: Vec<Index> = faces.iter().flat_map(|&f| self.faces[f as usize]).collect();
        verts.sort_unstable();
        verts.dedup();
        let local = |v: Index| verts.binary_search(&v).unwrap_or(0) as Index;
        let positions: Vec<DVec3> = verts.iter().map(|&v| self.pos[v as usize]).collect();
        let local_faces: Vec<[Index; 3]> = faces
            .iter()
            .map(|&f| self.faces[f as usize].map(local))
            .collect();
        // The part speaks this mesh's indices as its input's: its log, and
        // `LiveMesh::input_index` for the models.
        // Its vertices that are not free are locked; the rest is the whole's.
        let derived = Derived {
            kind: verts
                .iter()
                .map(|&v| match free[v as usize] {
                    true => self.kind[v as usize],
                    false => VertexKind::Locked,
                })
                .collect(),
            diagonal: self.diagonal,
            min_cross: self.min_cross,
            input_normal: faces
                .iter()
                .map(|&f| self.input_normal[f as usize])
                .collect(),
            region_normal: verts
                .iter()
                .map(|&v| self.region_normal[v as usize])
                .collect(),
            region_area: verts
                .iter()
                .map(|&v| self.region_area[v as usize])
                .collect(),
        };
        let mut mesh =
            LiveMesh::build_with(positions, local_faces, Some(verts.clone()), Some(derived));
        mesh.seams = self.seams.as_ref().map(|s| super::seams::SeamState {
            class: verts.iter().map(|&v| s.class[v as usize]).collect(),
            wedge: faces.iter().map(|&f| s.wedge[f as usize]).collect(),
            seam_of: s.seam_of.clone(),
            uv: None,
            source: None,
        });
        mesh.subset = self.subset;
        Part {
            vertices_before: mesh.n_vertices,
            model: model.for_part(&mesh),
            mesh,
            faces,
            guard: new_guard(),
            run: None,
        }
    }
}

/// The parts' error limit: the run's own, or `bound` when that is lower (no limit when
/// neither is finite).
fn error_limit(opts: &Options, bound: f64) -> Option<f64> {
    match opts.max_error {
        Some(m) => Some(m.min(bound)),
        None => bound.is_finite().then_some(bound),
    }
}

/// When [`stepped`] raises its bound and when it stops.
struct StepLimits {
    /// Each next bound is the cost at rank `bound_rank` × the collapses still needed.
    bound_rank: f64,
    /// The collapses the goal needs.
    needed: usize,
    /// No next step once fewer collapses than this are needed, or after a step that made
    /// fewer than a sixteenth of this.
    min_collapses: usize,
    /// Steps at most.
    steps: usize,
}

/// Collapses `parts` side by side in steps up to a rising cost bound, as one greedy run
/// over all of them would up to each bound (except for the ties between parts): the first
/// step up to `bound` and `caps`, each next one up to the cost at the rank the limits give
/// among the parts' queued candidates, each part at most as many times as it has
/// candidates at that cost or less (so that the parts never make more than the collapses
/// needed between them).
fn stepped<M, G>(
    parts: &mut [Part<M, G>],
    mut caps: Vec<usize>,
    opts: &Options,
    mut bound: f64,
    limits: &StepLimits,
) where
    M: CostModel + Send,
    G: FaceGuard + Send,
{
    let mut made = 0;
    for _ in 0..limits.steps {
        parts
            .par_iter_mut()
            .zip(&caps)
            .for_each(|(p, &cap)| p.step(opts, cap, error_limit(opts, bound)));
        let now: usize = parts.iter().map(|p| p.collapses()).sum();
        let left = limits.needed.saturating_sub(now);
        if left < limits.min_collapses || now - made < limits.min_collapses / 16 {
            break;
        }
        made = now;
        let costs: Vec<Vec<f64>> = parts
            .iter()
            .map(|p| {
                let mut c = Vec::new();
                p.queued_costs(&mut c);
                c
            })
            .collect();
        let mut all: Vec<f64> = costs.concat();
        let rank = (limits.bound_rank * left as f64) as usize;
        // The rank must lie among the cheaper half of the queued candidates: when the
        // parts hold few more candidates than collapses needed (the rest are parked or
        // locked), the one greedy order would take many candidates not made yet before
        // their dearest, and the bound would run ahead of it.
        if 2 * rank > all.len() {
            break;
        }
        let (_, &mut next, _) = all.select_nth_unstable_by(rank, f64::total_cmp);
        if next <= bound {
            break;
        }
        bound = next;
        let below: Vec<usize> = costs
            .iter()
            .map(|c| c.iter().filter(|&&x| x <= bound).count())
            .collect();
        let total: usize = below.iter().sum();
        let scale = (left as f64 / total.max(1) as f64).min(1.0);
        caps = below.iter().map(|&n| (n as f64 * scale) as usize).collect();
    }
}

/// One part of a round: a live mesh of its own with its model, guard and collapse run.
struct Part<M, G> {
    mesh: LiveMesh,
    /// The whole mesh's index of each of its faces.
    faces: Vec<Index>,
    vertices_before: usize,
    /// `None` when the model cannot work on parts.
    model: Option<M>,
    guard: G,
    run: Option<Run>,
}

impl<M: CostModel, G: FaceGuard> Part<M, G> {
    /// Collapses at most `cap` more times and up to cost `max_error` (its candidates are
    /// ranked at the first step that may collapse).
    fn step(&mut self, opts: &Options, cap: usize, max_error: Option<f64>) {
        let Some(model) = self.model.as_mut() else {
            return;
        };
        let removes = match model.unit() {
            Unit::Edge => 1,
            Unit::Triangle => 2,
        };
        let goal = Goal::Vertices(self.mesh.n_vertices.saturating_sub(cap * removes));
        if self.mesh.reached(goal) {
            return;
        }
        let part_opts = Options {
            goal,
            max_error,
            ..*opts
        };
        let run = self
            .run
            .get_or_insert_with(|| self.mesh.start(model, &part_opts));
        self.mesh
            .resume(run, model, &mut self.guard, &part_opts, &mut |_| {});
    }

    /// Collapses made so far.
    fn collapses(&self) -> usize {
        self.run.as_ref().map_or(0, |r| r.out.collapses)
    }

    /// The costs of its current queued candidates, added to `costs`.
    fn queued_costs(&self, costs: &mut Vec<f64>) {
        if let Some(run) = &self.run {
            run.queued_costs(&self.mesh, costs);
        }
    }

    /// What the free vertices (by `free`, in the whole mesh's indices) and their faces
    /// became.
    fn finish(self, free: &[bool]) -> PartRun<G> {
        let part = self.mesh;
        let faces = self.faces;
        let (outcome, tally) = match (self.run, &self.model) {
            (Some(run), Some(m)) => (run.out, m.tally()),
            _ => (Outcome::none(), 0),
        };
        let guard = self.guard;
        let part_vertices_before = self.vertices_before;
        // What the free vertices and their faces became, in this mesh's indices.
        let owned = |i: Index| free[part.input_index(i) as usize];
        let mut vertices = Vec::new();
        let mut clusters = Vec::new();
        for i in 0..part.pos.len() as Index {
            if !part.alive[i as usize] || !owned(i) {
                continue;
            }
            let iu = i as usize;
            vertices.push((
                part.input_index(i),
                part.pos[iu],
                part.region_normal[iu],
                part.region_area[iu],
            ));
            let first = part.base(i);
            if part.cluster_next[first as usize] != NONE {
                let mut members = Vec::new();
                let mut b = first;
                while b != NONE {
                    members.push(part.original_of_base(b));
                    b = part.cluster_next[b as usize];
                }
                clusters.push(members);
            }
        }
        let mut kept_faces = Vec::new();
        for (j, &state) in part.face_state.iter().enumerate() {
            let face = part.faces[j];
            if state == LIVE && face.iter().any(|&v| owned(v)) {
                let input_face = match &part.base_face {
                    Some(b) => b[j],
                    None => j as Index,
                };
                kept_faces.push((
                    faces[input_face as usize],
                    face.map(|v| part.input_index(v)),
                    part.seams.as_ref().map(|s| s.wedge[j]),
                ));
            }
        }
        PartRun {
            vertices,
            clusters,
            faces: kept_faces,
            removed_vertices: part_vertices_before - part.n_vertices,
            removed_faces: faces.len() - part.n_faces,
            tally,
            outcome,
            guard,
        }
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::fixtures::*;
    use crate::{NoGuard, QemOptions, QuadricModel};
    use coarsen_mesh::Mesh;

    /// Parts of a few hundred faces, so that a small mesh is cut into many.
    const SMALL: PartOptions = PartOptions {
        min_faces: 0,
        min_collapses: 0,
        faces_per_part: 512,
        share: 0.9,
        bound_rank: 1.0,
        rounds: 2,
        steps: 1,
    };

    /// [`SMALL`] with the second round in steps.
    const STEPPED: PartOptions = PartOptions { steps: 16, ..SMALL };

    /// Parts big enough, and a first round short enough, for steps to find candidates
    /// left in them.
    const BIG_STEPPED: PartOptions = PartOptions {
        faces_per_part: 4096,
        share: 0.5,
        ..STEPPED
    };

    /// An icosphere with bumps, so that costs vary over it.
    pub(in crate::live) fn bumpy(levels: u32) -> Mesh {
        let mut m = icosphere(levels);
        for p in &mut m.positions {
            *p *= 1.0 + 0.05 * (5.0 * p.x).sin() * (4.0 * p.y).sin() * (3.0 * p.z).sin();
        }
        m
    }

    /// QEM on `mesh` to `goal`: in parts, then serially; the output and both outcomes.
    fn qem_in_parts(mesh: &Mesh, goal: Goal, parts: &PartOptions) -> (Mesh, Outcome, Outcome) {
        let mut live = LiveMesh::new_renumbered(mesh).unwrap();
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let opts = Options::new(goal);
        let (first, _) = live.collapse_in_parts(&mut model, || NoGuard, &opts, parts);
        live.check_invariants().unwrap();
        assert_input_vertices_merged_once(&live);
        let rest = live.collapse(&mut model, &opts, &mut |_| {});
        live.check_invariants().unwrap();
        assert_input_vertices_merged_once(&live);
        (live.to_mesh(mesh).unwrap().0, first, rest)
    }

    /// Every input vertex used by a face stands in exactly one live vertex's list.
    pub(super) fn assert_input_vertices_merged_once(live: &LiveMesh) {
        let mut seen = vec![0u32; live.input_vertices];
        for v in 0..live.pos.len() as Index {
            if !live.alive[v as usize] {
                continue;
            }
            let mut b = live.base(v);
            while b != NONE {
                seen[b as usize] += 1;
                b = live.cluster_next[b as usize];
            }
        }
        assert!(
            seen.iter().all(|&n| n == 1),
            "an input vertex merged twice or lost"
        );
    }

    #[test]
    fn parts_make_most_collapses_and_the_result_is_exact_and_closed() {
        let sphere = bumpy(5);
        let n = sphere.n_vertices();
        let (out, first, rest) = qem_in_parts(&sphere, Goal::Vertices(500), &SMALL);
        assert_eq!(out.n_vertices(), 500);
        assert_eq!(assert_closed_manifold(&out).euler, 2);
        assert_eq!(first.collapses + rest.collapses, n - 500);
        assert!(first.collapses > (n - 500) * 3 / 4, "{}", first.collapses);
        assert!(
            rest.collapses > 0,
            "the dearest collapses are left to one order"
        );
        let placed_close = out.positions.iter().all(|p| (p.length() - 1.0).abs() < 0.1);
        assert!(placed_close, "a vertex left the surface");
    }

    #[test]
    fn the_output_does_not_depend_on_the_thread_count() {
        let sphere = bumpy(4);
        let on = |threads: usize, parts: &PartOptions| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| qem_in_parts(&sphere, Goal::Vertices(300), parts).0)
        };
        let one = on(1, &SMALL);
        assert_eq!(one, on(2, &SMALL));
        assert_eq!(one, on(3, &SMALL));
        let one = on(1, &STEPPED);
        assert_eq!(one, on(2, &STEPPED));
        assert_eq!(one, on(3, &STEPPED));
    }

    #[test]
    fn steps_leave_less_to_the_serial_run_and_never_overshoot() {
        let sphere = bumpy(5);
        let n = sphere.n_vertices();
        let goal = Goal::Vertices(500);
        let once = PartOptions {
            steps: 1,
            ..BIG_STEPPED
        };
        let (_, once, _) = qem_in_parts(&sphere, goal, &once);
        let (out, stepped, rest) = qem_in_parts(&sphere, goal, &BIG_STEPPED);
        assert!(
            stepped.collapses > once.collapses,
            "{} in steps against {} in one",
            stepped.collapses,
            once.collapses
        );
        assert_eq!(stepped.collapses + rest.collapses, n - 500);
        assert_eq!(out.n_vertices(), 500);
        assert_eq!(assert_closed_manifold(&out).euler, 2);
        // Each step stops at its bound: the parts' dearest collapse costs no more than the
        // serial run's dearest.
        assert!(stepped.max_cost <= rest.max_cost);
    }

    #[test]
    fn a_torus_keeps_its_genus_and_a_grid_its_border() {
        let t = torus(1.0, 0.3, 96, 48);
        let (out, first, _) = qem_in_parts(&t, Goal::Vertices(200), &SMALL);
        assert!(first.collapses > 0);
        assert_eq!(out.n_vertices(), 200);
        assert_eq!(assert_closed_manifold(&out).euler, 0);

        let g = grid(64, 64, |x, y| 0.1 * (6.0 * x).sin() * (5.0 * y).cos());
        let (out, first, _) = qem_in_parts(&g, Goal::Vertices(150), &SMALL);
        assert!(first.collapses > 0);
        assert_eq!(out.n_vertices(), 150);
        let s = LiveMesh::new(&out).unwrap().summary();
        assert_eq!((s.locked_vertices, s.boundary_loops), (0, 1));
        // Boundary vertices only move along the square's sides.
        for p in &out.positions {
            let on_side = [p.x, p.y].iter().any(|&c| c == 0.0 || c == 1.0);
            let inside = p.x > 0.0 && p.x < 1.0 && p.y > 0.0 && p.y < 1.0;
            assert!(on_side || inside, "{p:?} left the square");
        }
        assert_eq!((out.bbox().min.x, out.bbox().max.y), (0.0, 1.0));
    }

    #[test]
    fn small_meshes_and_progressive_records_are_left_to_the_serial_run() {
        let sphere = bumpy(3);
        let mut live = LiveMesh::new(&sphere).unwrap();
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let opts = Options::new(Goal::Vertices(100));
        let default = PartOptions::default();
        let (o, _) = live.collapse_in_parts(&mut model, || NoGuard, &opts, &default);
        assert_eq!(o.collapses, 0, "below min_faces");
        live.record_progressive();
        let (o, _) = live.collapse_in_parts(&mut model, || NoGuard, &opts, &SMALL);
        assert_eq!(o.collapses, 0, "while recording");
    }

    #[test]
    fn a_model_that_cannot_work_on_parts_leaves_the_mesh_as_it_was() {
        let sphere = bumpy(4);
        let mut live = LiveMesh::new_renumbered(&sphere).unwrap();
        let before = live.clone();
        let mut model = shortest_edge();
        let opts = Options::new(Goal::Vertices(100));
        let (o, guards) = live.collapse_in_parts(&mut model, || NoGuard, &opts, &SMALL);
        assert_eq!((o.collapses, guards.len() > 1), (0, true));
        assert_eq!(live.faces, before.faces);
        assert_eq!(live.summary(), before.summary());
    }

    #[test]
    fn the_log_names_every_collapse_in_input_indices() {
        let sphere = bumpy(4);
        let mut live = LiveMesh::new_renumbered(&sphere).unwrap();
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let opts = Options::new(Goal::Vertices(400));
        let (first, _) = live.collapse_in_parts(&mut model, || NoGuard, &opts, &SMALL);
        assert_eq!(first.log.len(), first.collapses);
        let mut gone = vec![false; sphere.n_vertices()];
        for r in &first.log {
            assert!(!gone[r.kept as usize], "a removed vertex kept");
            assert_eq!(r.removed[1], NONE);
            assert!(!std::mem::replace(&mut gone[r.removed[0] as usize], true));
        }
    }
}

#[cfg(test)]
pub(super) mod properties {
    use super::tests::{assert_input_vertices_merged_once, bumpy};
    use super::*;
    use crate::{NoGuard, QemOptions, QuadricModel};
    use coarsen_mesh::Mesh;
    use proptest::prelude::*;

    /// The cases of the properties of per-corner attributes: a [`shape`] (lightly noised)
    /// with random UV islands, a vertex goal between 2 and 60 % of its vertices (at least
    /// 20), and parts cut small, or none.
    pub(in crate::live) fn charted_cases() -> impl Strategy<Value = (Mesh, crate::Goal, PartOptions)>
    {
        let charts = (1u32..40, 1u32..97);
        (
            0u8..3,
            1u64..u64::MAX,
            charts,
            0.02f64..0.6,
            proptest::bool::ANY,
        )
            .prop_map(|(kind, seed, (charts, stride), frac, parted)| {
                let mesh =
                    coarsen_shapes::with_uv_islands(shape(kind, seed, 0.002), charts, stride);
                let n = ((mesh.n_vertices() as f64 * frac) as usize).max(20);
                let parts = match parted {
                    true => PartOptions {
                        min_faces: 0,
                        faces_per_part: 512,
                        ..PartOptions::default()
                    },
                    false => PartOptions::off(),
                };
                (mesh, crate::Goal::Vertices(n), parts)
            })
    }

    /// A sphere, a torus or a disc with two holes, each vertex moved by up to `noise`.
    pub(in crate::live) fn shape(kind: u8, seed: u64, noise: f64) -> Mesh {
        let mut m = match kind % 3 {
            0 => bumpy(4),
            1 => coarsen_shapes::torus(1.0, 0.35, 64, 32).unwrap(),
            _ => coarsen_shapes::disk_with_holes(2, 40, 1.0).unwrap(),
        };
        let mut s = seed;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for p in &mut m.positions {
            *p += DVec3::new(next(), next(), next()) * noise;
        }
        m
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 24,
            rng_seed: proptest::test_runner::RngSeed::Fixed(0x00C0_11A9_5E00_0001),
            ..ProptestConfig::default()
        })]

        /// Whatever the cut, the share, the steps and the target: the whole mesh is sound after the
        /// parts are joined and after the serial finish, every input vertex is merged
        /// into exactly one output vertex, and the target and the topology are met as a
        /// serial run meets them.
        #[test]
        fn joined_parts_keep_the_mesh_sound(
            kind in 0u8..3,
            seed in 1u64..u64::MAX,
            frac in 0.05f64..0.8,
            faces_per_part in 128usize..4096,
            share in 0.3f64..0.95,
            steps in 1usize..20,
        ) {
            let mesh = shape(kind, seed, 0.002);
            let target = ((mesh.n_vertices() as f64 * frac) as usize).max(30);
            let parts = PartOptions {
                min_faces: 0,
                min_collapses: 0,
                faces_per_part,
                share,
                steps,
                ..PartOptions::default()
            };
            let opts = Options::new(Goal::Vertices(target));
            let run = |parts: &PartOptions| {
                let mut live = LiveMesh::new_renumbered(&mesh).unwrap();
                let mut model = QuadricModel::new(&live, &QemOptions::default());
                let (first, _) = live.collapse_in_parts(&mut model, || NoGuard, &opts, parts);
                live.check_invariants().unwrap();
                assert_input_vertices_merged_once(&live);
                let rest = live.collapse(&mut model, &opts, &mut |_| {});
                live.check_invariants().unwrap();
                assert_input_vertices_merged_once(&live);
                (live.summary(), first, rest)
            };
            let (s, first, rest) = run(&parts);
            let (serial, _, _) = run(&PartOptions::off());
            let before = LiveMesh::new(&mesh).unwrap().summary();
            prop_assert!(first.collapses > 0);
            prop_assert_eq!(rest.stop, StopReason::Reached);
            prop_assert_eq!(s.vertices, target);
            prop_assert_eq!(s.vertices, serial.vertices);
            prop_assert_eq!((s.euler, s.boundary_loops), (before.euler, before.boundary_loops));
            prop_assert_eq!(s.locked_vertices, 0);
        }
    }
}
