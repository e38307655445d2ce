//! The `simplify.svec` stage: triangle constriction driven by the squared volume error
//! with constraint (SVEC) of Zhou, Zhang & Cheng (paper 2), down to the run target.
//!
//! A collapse merges a triangle's three vertices into one new vertex v̄; the triangle and
//! its (up to three) edge-neighbours disappear. The shared collapse engine
//! (`coarsen-collapse`) keeps the queue, the checks and the boundary rules; [`SvecModel`]
//! is the paper's error:
//!
//! * **Per face** i (current geometry): unit plane p, area Sᵢ, smallest angle αᵢ, shape
//!   factor Wᵢ = 2(1 − cos αᵢ)·Sᵢ, normal factor Nᵢ = mean over the faces j sharing a
//!   vertex with i of (1 − |nᵢ·nⱼ|)/2, and Qᵢ = (1/9)·Wᵢ·Nᵢ·Sᵢ²·p pᵀ (Eq. 4).
//! * **Cost** of a triangle: Δ = v̄ᵀ Q̄ v̄ with Q̄ = Σ Qᵢ over the faces around its three
//!   vertices (the triangle itself included, each face once; Eq. 5). Costs are those of the
//!   mesh scaled to a unit bounding-box diagonal.
//! * **Placement**: v̄ minimises Δ (guarded 3×3 solve: relative determinant above 1e-10,
//!   and within 4× the triangle's circumradius-like spread of its centroid); otherwise the
//!   A_v-weighted mean of its vertices (§3.4, A_v = area of the faces around v; Step 3
//!   cites it as Eq. 8, the extracted text prints no number on it).
//! * **Feature filter** (§3.3): K_t = Σ|angle deficit| / Σ A_v over the triangle's vertices
//!   (angle-deficit Gauss curvature; the deficit is 2π − Σα inside and π − Σα on a
//!   boundary). Above `feature_threshold` (by default mean + `feature_sigma`·σ of K_t over
//!   the stage's input) v̄ is the vertex of largest |K_v| = deficit/A_v. The paper tests
//!   this when the triangle leaves the queue; here it is part of the plan, so the queued
//!   cost is Δ at the vertex actually used (a strong-feature triangle costs what
//!   collapsing onto its feature vertex costs, and so tends to go later).
//! * **Boundaries** (§3.5): one boundary vertex → v̄ is that vertex; two (joined by a
//!   boundary edge) → v̄ = ω vᵢ + (1 − ω) vⱼ, ω ∈ [0, 1] minimising Δ in closed form
//!   (A_v-weighted when Δ is flat along the segment); three → never collapsed; an interior
//!   edge joining two boundary vertices is never collapsed either (the engine's rules).
//! * **Updates after a collapse**: the paper re-computes "the temporary matrices Qᵢ of the
//!   new triangles" and the costs of the triangles around them. Here the faces around the
//!   new vertex get new planes, areas and Wᵢ; the new vertex and its neighbours get new
//!   angle deficits and A_v; every face sharing a vertex with a changed face gets a new
//!   Nᵢ and Qᵢ: those around the new vertex are summed afresh, the others get the terms of
//!   the reshaped and deleted faces replaced in a kept sum. The terms 1 − |nᵢ·nⱼ| are
//!   multiples of 2⁻⁵³, so the sums are kept as integers in those units: exact, the same in
//!   any order, and zero on flat regions (recomputing every sum over two rings took a
//!   fifth of the run on the bunny subdivided three times). Q is not accumulated (unlike
//!   QEM): the error always measures the volume swept from the current mesh, as in the
//!   paper. As in the paper, the triangles around
//!   the new vertex are re-costed (the engine's `Reach::Kept`); a triangle farther out whose
//!   sum changed (its Nᵢ moved) keeps its queued cost, and is re-costed when it comes off
//!   the queue: if it grew dearer it goes back in line, so every collapse is made at its
//!   exact current cost, and only a triangle that got *cheaper* may go later than an exact
//!   order would take it. Re-costing every triangle within two edges (`Reach::TwoRings`,
//!   exact order) took 2.4× the time on the bunny subdivided twice (1.1M faces), for
//!   quality and fidelity figures that differ either way by a little (issue #6).
//! * **Zero costs**: on flat regions Nᵢ = 0, every cost is 0 and triangles go in the order
//!   they were queued (the engine's FIFO ties, paper 2's re-queuing rule).
//!
//! **Equation numbers** are the printed ones: (3) Qᵢ = (1/9)Sᵢ²ppᵀ, (4) the same with
//! Wᵢ·Nᵢ, (5) Δ = v̄ᵀ(Σ Qᵢ)v̄, (6) K_t. The algorithm's steps cite one above them (Step 1:
//! "Eq.(5)" for Qᵢ, printed (4); Step 4: "Eq.(6)" for the error, printed (5)).
//!
//! **Readings** (issue #53). Where the text admits more than one reading, each is a
//! parameter; the literal reading is each one's default, and `pipelines/svec.toml` ships
//! the combination that best matches what the paper reports (docs/results.md, *Paper 2's
//! readings*, measured on the ten rows of its Table 1 against its two baselines):
//!
//! 1. `factors` — whose shape and normal factors: `face` puts Wᵢ·Nᵢ inside every face's
//!    Qᵢ (Eq. 4); `triangle` reads the abstract ("constricting error defined by a
//!    combination of square volume error variation with constraint (SVEC), shape factor and
//!    normal constraint factor of triangle") as cost = W_t·N_t · v̄ᵀ Q̄ v̄ with Q̄ = Σ
//!    (1/9)Sᵢ²ppᵀ (Eq. 3) and v̄ its minimiser: no face is weightless because its
//!    neighbours are coplanar, and faces weigh by Sᵢ² instead of Sᵢ³. For the finishing
//!    edge collapses, W·N is the mean over the edge's faces.
//! 2. `normal_abs` — N₀ = Σ (1 − |n₀·nᵢ|)/2 / m as extracted, or `false`: (1 − n₀·nᵢ)/2,
//!    which alone spans the stated "0 ≤ N₀ ≤ 1" and reads a fold (Fig. 5's normals "near to
//!    180 degree") as the sharpest place rather than a flat one.
//! 3. `volume_constraint` — the φ weights below (the method is named for them; Eq. 4,
//!    which Step 1 uses, has none).
//! 4. `feature_rule` — `plan` costs a strong-feature triangle at its feature vertex;
//!    `dequeue` (Step 5 ①: "Extract the top triangle in the heap queue and compute its
//!    Gauss curvature factor") queues it at its free placement's cost and moves it to the
//!    feature vertex only when it is collapsed.
//! 5. `reach` — `kept` re-costs the triangles around the new vertex (others when they
//!    come off the queue, see *Updates*); `two_rings` (Step 5 ②: "re-compute the
//!    constriction error of the new triangles and the adjacent triangles of them")
//!    re-costs every triangle within two edges.
//!
//! Readings 6 (the paper's baselines) and 7 (what its Table 1's SVE is) are not SVEC's:
//! `simplify.qem` has `area_weighted = false` (its \[3\]) and `unit = "triangle"` (its \[8\]),
//! and both stages report `sve`, `sve_max` and, with `sve_weighted = true`, the sum
//! weighted as Eq. (4) (`coarsen_collapse::stage`).
//!
//! **The φ volume constraint** (`volume_constraint`, §3.1 "SVEC"). The paper weights each
//! Qᵢ by "φᵢ, the square volume of the tetrahedron whose vertex is v̄ and whose bottom face
//! is triangle i", "the original square volume variation", to reduce the *largest* volume
//! change. Our reading: φᵢ = Vᵢ²(v̄₀) / mean_j Vⱼ²(v̄₀), where v̄₀ is the unconstrained
//! placement and Vᵢ² = (1/9)Sᵢ²(p·v̄₀)² the plain squared volume of face i; v̄ is then
//! placed again with Σ φᵢQᵢ (unless a boundary or feature rule fixed it) and the cost is
//! v̄ᵀ(Σ φᵢQᵢ)v̄. Normalising by the mean keeps the cost's units, and weights the faces
//! whose volume would change most — one reweighting step towards a smaller maximum. When
//! every Vᵢ² is 0, φᵢ = 1. Measured on the bunny and the rocker arm at 70 % and 95 %
//! removed, φ gives a 5–12× larger `sve`, lower α_avg (by 1–4°) and a larger Hausdorff
//! distance in three cases of four (bunny 70 %: 0.488 % against 0.514 %), so the default
//! is `false`.
//!
//! The ω rule moves a boundary vertex along a boundary edge, so a corner of a boundary
//! (where the boundary turns) may be cut: the paper's cost has no term that keeps it.
//! `boundary_weight` (beyond the paper, off by default) adds one, as QEM's boundary planes
//! do: for each boundary edge at a merged vertex, the plane through the edge perpendicular
//! to its face, weighted by `boundary_weight` × that face's Wᵢ·(1/9)Sᵢ² (its own term with
//! Nᵢ = 1), enters Q̄, so the cost prices a cut corner and ω keeps the end that holds it.
//! With a weight of 1, Hausdorff distance at 70 % / 95 % of faces removed: the bunny 0.514
//! → 0.118 % / 0.516 → 0.472 % (`sve` +0.5 % / +3.2 %), the teapot 4.12 → 0.58 % / 10.6
//! → 3.8 %, the beetle at 70 % 3.20 → 1.99 %; suzanne at 70 % 7.22 → 7.84 % (its worst
//! point is not on a boundary; P<30° 62.1 → 56.2 %).
//!
//! **Exact targets**: a triangle collapse removes two vertices and (inside) four faces. The
//! stage runs triangle collapses until one more collapse could overshoot the target, then
//! finishes with at most a few edge collapses of the same error (Q̄ over the faces around
//! the two vertices, same rules), so a vertex count is met exactly and a face count or
//! ratio (of the run input's faces) too where the mesh has a boundary (on a closed mesh,
//! whose face count stays even, to within one face, with a warning). When every triangle is refused
//! before that, edge collapses carry on to the target; the report counts both.
//!
//! | parameter | default | meaning |
//! | --- | --- | --- |
//! | `feature_sigma` | `2` | automatic feature threshold: mean + this many σ of K_t over the input |
//! | `feature_threshold` | `0` (automatic) | absolute K_t threshold (unit-diagonal units, 1/length²) |
//! | `volume_constraint` | `false` | weight the quadrics by φ (see above) |
//! | `boundary_weight` | `0` | weight of the boundary-edge planes added to the cost (see above; 0 = the paper's cost) |
//! | `max_error` | `0` (none) | stop before the first collapse costing more |
//! | `min_quality` | `0` (off) | refuse collapses leaving a triangle below this quality and below its previous quality |
//! | `target_scale` | `1` | stop at this multiple of the target's count, for a later stage to finish (`svec-then-cvt`) |
//! | `facing_guard` | `true` | refuse collapses turning a face away from the run input's surface nearest it (see below) |
//! | `parallel` | `true` | on meshes of 2¹⁹ faces or more, make most collapses in parts of the mesh side by side (see below) |
//! | `factors` | `"face"` | reading 1: `face` or `triangle` (see *Readings*) |
//! | `normal_abs` | `true` | reading 2: N from 1 − \|nᵢ·nⱼ\| (`true`) or 1 − nᵢ·nⱼ |
//! | `feature_rule` | `"plan"` | reading 4: `plan` or `dequeue` |
//! | `reach` | `"kept"` | reading 5: `kept` or `two_rings` |
//! | `sve_weighted` | `false` | also report `sve_weighted` (Eq. 4's weights on the swept volumes) |
//!
//! The run is the collapse stages' shared skeleton (`coarsen_collapse::stage`, described
//! in `simplify.qem`'s docs): target, progressive record, the **facing guard**
//! (`facing_guard`), progress, attribute carrying, and the report's common figures and
//! warnings. SVEC adds `triangle_collapses` and `edge_collapses` (their sum is
//! `collapses`), `feature_collapses`, `feature_threshold`, and a warning when more than
//! two edge collapses finished the run.
//!
//! **Beside `simplify.qem`**, which runs the same skeleton: SVEC collapses triangles and
//! finishes with edge collapses (QEM collapses edges only); its cost is measured from the
//! current faces, not summed as the collapses merge (so a ring is re-costed after each,
//! QEM only the new vertex's candidates); the new vertex goes by the paper's rules (a
//! feature filter, the ω rule on boundaries; no boundary planes by default, QEM's are on);
//! the parallel phase's second round goes on in up to 16 steps (QEM one); `target_scale`
//! stops it short of the target for a later stage.
//!
//! **Parallel phase** (`parallel`): on a mesh of 2¹⁹ faces or more, the engine first cuts
//! the mesh into parts of about 2¹⁷ faces and collapses them side by side, up to nine tenths
//! of the collapses needed, then once more with the cuts moved halfway, in up to 16 steps
//! each up to the cost that the collapses still needed reach among the parts' candidates,
//! and leaves the rest to one greedy order (`LiveMesh::collapse_in_parts`). The steps
//! move most of the coarse end, where a collapse costs the most (five to ten refusals
//! each), from one thread to both: at 4.4M faces the serial finish fell from 85K
//! collapses to 15K, the stage by 11–14 % (QEM, whose second round already makes nine
//! tenths of what is left, keeps one step: continuing its parts' queues instead of the
//! serial run's fresh ranking took P<30° at 4.4M from 16 % to 35 %). The output does not
//! depend on the thread count, but it is not the purely serial one; with `--progressive`
//! the run is serial (the record needs every collapse made on the whole mesh), so its
//! output may differ from a run without. Before the steps, on
//! the bunny subdivided twice (1.1M faces) to 15,000 faces: 6.4 s instead of 10.8 s, with
//! the same triangles (P<30° 47.6 % against 47.4 %, Q_avg 0.575 against 0.576) and less
//! error (`sve` 2.72e-16 against 2.89e-16, Hausdorff 0.49 % against 0.52 %); subdivided three
//! times (4.4M) to 60,000 faces, 32.5 s instead of 53.4 s but worse triangles (P<30° 80 %
//! against 76 %, Q_avg 0.37 against 0.40, Hausdorff 0.52 % against 0.46 %): that mesh is
//! flat inside each original triangle, its costs are zero there up to rounding, and among
//! equal costs the order (first come, first served) differs near the cuts. With noise a
//! third of an edge long, 42 s instead of 74 s and the same figures (P<30° 51.9 % against
//! 52.1 %, Q_avg 0.558 against 0.556, `sve` 2.09e-17 against 2.07e-17). `parallel = false`
//! keeps the serial order. The whole mesh's model is then built only for the feature
//! threshold (`SvecModel::deferred`; peak memory 0.85 GB instead of 1.27 GB at 4.4M).
//!
//! ```
//! use coarsen_stage::{Context, Stage, StageReport, Target};
//! use coarsen_stage_svec::{SimplifySvec, SvecParams};
//! let sphere = coarsen_shapes::icosphere(1.0, 2).unwrap();
//! let mut report = StageReport::default();
//! let mut cx = Context::new(&sphere, &mut report);
//! cx.target = Some(Target::Vertices(42));
//! let out = SimplifySvec::new(SvecParams::default()).run(sphere.clone(), &mut cx)?;
//! assert_eq!(out.n_vertices(), 42);
//! # Ok::<(), coarsen_stage::StageError>(())
//! ```

mod model;

pub use model::{Factors, SvecModel, SvecOptions};

use coarsen_collapse::stage::{Collapsed, Simplifier, triangles_then_edges};
use coarsen_collapse::{FaceGuard, Goal, LiveMesh, Options, PartOptions, Unit};
use coarsen_stage::params::{check_finite_min, check_range};
use coarsen_stage::{
    Context, Contract, Mesh, ParamIssue, Params, Stage, StageError, StageReport, Target,
    TargetCount, params,
};

params! {
    /// Parameters of `simplify.svec`.
    pub struct SvecParams {
        /// How many standard deviations above the mean K_t of the input the automatic
        /// strong-feature threshold sits.
        pub feature_sigma: f64 = 2.0,
        /// Absolute strong-feature threshold on K_t (Σ|angle deficit| / Σ A_v, mesh scaled
        /// to a unit diagonal); 0 means automatic (`feature_sigma`).
        pub feature_threshold: f64 = 0.0,
        /// Weight each face's quadric by φ (its squared volume at the unconstrained
        /// placement over the mean), paper 2's "SVEC" constraint as read in the docs.
        pub volume_constraint: bool = false,
        /// Weight of a plane through each boundary edge at the merged vertices,
        /// perpendicular to its face, in the cost (relative to the face's own term with
        /// Nᵢ = 1), so that corners of a boundary stay; 0 is the paper's cost, which has
        /// no such term.
        pub boundary_weight: f64 = 0.0,
        /// Largest collapse cost allowed (mesh scaled to a unit diagonal); the run stops
        /// before the first collapse costing more. 0 means no limit.
        pub max_error: f64 = 0.0,
        /// Refuse collapses that leave a triangle below this Frey–Borouchaki quality (and
        /// below its quality before); 0 turns the guard off.
        pub min_quality: f64 = 0.0,
        /// Stop at this multiple of the run target's vertex or face count (e.g. 4 leaves
        /// four times as many for a later stage to take to the target); 1 reaches it.
        pub target_scale: f64 = 1.0,
        /// Refuse collapses that would turn a face away from the run input's surface
        /// nearest it (the metrics' flipped-face test), tested where the engine's gate says
        /// a face could fail (thin parts, sharp turns); `false` leaves only the engine's own
        /// flip checks.
        pub facing_guard: bool = true,
        /// On meshes of 2¹⁹ faces or more, make most collapses on parts of the mesh side
        /// by side (`coarsen_collapse::LiveMesh::collapse_in_parts`) before the last ones
        /// in one greedy order; `false` makes them all in that order.
        pub parallel: bool = true,
        /// Whose shape and normal factors weigh the cost (paper 2 readings, 1): `face` —
        /// Wᵢ·Nᵢ inside every face's quadric, Eq. (4) "Qᵢ = (1/9)·W_shape-factorⁱ·
        /// N_normal-factorⁱ·Sᵢ²·ppᵀ"; `triangle` — W_t·N_t of the collapsed triangle times
        /// the plain squared volume, the abstract's "square volume error variation with
        /// constraint (SVEC), shape factor and normal constraint factor of triangle".
        pub factors: String = "face".to_string(),
        /// Normal factor with the absolute value (readings, 2): N₀ = Σ((1 − abs(n₀·nᵢ))/2)/m
        /// as extracted; `false` takes (1 − n₀·nᵢ)/2, which alone reaches the stated
        /// "0 ≤ N₀ ≤ 1" and does not read a fold (normals near 180°, Fig. 5) as flat.
        pub normal_abs: bool = true,
        /// When the Gauss-curvature filter acts (readings, 4): `plan` — a strong-feature
        /// triangle is costed at its feature vertex; `dequeue` — Step 5, "Extract the top
        /// triangle in the heap queue and compute its Gauss curvature factor ... the strong
        /// feature point can be denoted as the new point": queued at its free placement's
        /// cost, moved to the feature vertex when collapsed.
        pub feature_rule: String = "plan".to_string(),
        /// Which triangles are re-costed after a collapse (readings, 5): `kept` — those
        /// around the new vertex (others when they come off the queue); `two_rings` —
        /// Step 5 ②, "re-compute the constriction error of the new triangles and the
        /// adjacent triangles of them".
        pub reach: String = "kept".to_string(),
        /// Also report `sve_weighted`: each collapse's squared volume weighted as Eq. (4)
        /// quadrics (Wᵢ·Nᵢ per face), to compare with `simplify.qem` runs.
        pub sve_weighted: bool = false,
        /// Keep the input's sharp features (`coarsen-features`): its corners (where three or
        /// more sharp or boundary curves meet or one turns sharply) as they are, no collapse
        /// merging or moving them; the vertices of sharp curves between two surface patches
        /// where they are, merged along their curve only.
        pub features: bool = false,
        /// An input edge is sharp when its two faces' normals differ by more than this
        /// (degrees), for `features`.
        pub feature_angle_deg: f64 = 40.0,
        /// Where a collapse's vertex ends: `paper` (the placement rules above) or `surface`
        /// (those, then after the last collapse the nearest point of the input faces the
        /// vertex stands for, where that spoils no face: every output vertex on the input
        /// surface, its UVs exact there; the report gives `settled_vertices` and
        /// `settle_refused`). `auto`: `surface` when the mesh has texture coordinates.
        pub placement: String = "auto".to_string(),
    }
}

/// A string parameter that names none of its choices.
fn check_choice(issues: &mut Vec<ParamIssue>, field: &'static str, value: &str, choices: &[&str]) {
    if !choices.contains(&value) {
        issues.push(ParamIssue {
            field,
            message: format!("`{value}` is not one of {}", choices.join(", ")),
        });
    }
}

impl Params for SvecParams {
    fn validate(&self) -> Vec<ParamIssue> {
        let mut issues = Vec::new();
        check_range(&mut issues, "feature_sigma", self.feature_sigma, -1e6, 1e6);
        check_finite_min(
            &mut issues,
            "feature_threshold",
            self.feature_threshold,
            0.0,
        );
        check_finite_min(&mut issues, "max_error", self.max_error, 0.0);
        check_finite_min(&mut issues, "boundary_weight", self.boundary_weight, 0.0);
        check_range(&mut issues, "min_quality", self.min_quality, 0.0, 1.0);
        check_range(&mut issues, "target_scale", self.target_scale, 1.0, 1e6);
        check_range(
            &mut issues,
            "feature_angle_deg",
            self.feature_angle_deg,
            0.0,
            180.0,
        );
        check_choice(&mut issues, "factors", &self.factors, &["face", "triangle"]);
        check_choice(
            &mut issues,
            "feature_rule",
            &self.feature_rule,
            &["plan", "dequeue"],
        );
        check_choice(&mut issues, "reach", &self.reach, &["kept", "two_rings"]);
        check_choice(
            &mut issues,
            "placement",
            &self.placement,
            &["paper", "surface", "auto"],
        );
        issues
    }
}

/// Paper 2's triangle constriction (SVEC) to the run target.
pub struct SimplifySvec(SvecParams);

impl Stage for SimplifySvec {
    type Params = SvecParams;
    const KIND: &'static str = "simplify.svec";
    const SUMMARY: &'static str = "Triangle constriction by squared volume error with shape, normal and curvature factors (paper 2, SVEC) down to the run target.";

    const RECORDS_COLLAPSES: bool = true;

    fn new(params: SvecParams) -> Self {
        SimplifySvec(params)
    }

    fn contract(&self) -> Contract {
        coarsen_collapse::stage::contract()
    }

    fn run(&self, mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        coarsen_collapse::stage::run(Self::KIND, &mut Svec::new(&self.0), mesh, cx)
    }
}

/// The SVEC side of the collapse-stage skeleton: triangle collapses until one more could
/// overshoot the goal (most of them on parts of the mesh side by side, when it is big:
/// `LiveMesh::collapse_in_parts`), then edge collapses to it; the goal scaled by
/// `target_scale`; its own figures (the two kinds of collapse, the feature rule's).
struct Svec<'a> {
    p: &'a SvecParams,
    parts: PartOptions,
    triangle_collapses: usize,
    edge_collapses: usize,
    feature_collapses: usize,
    feature_threshold: f64,
}

impl<'a> Svec<'a> {
    fn new(p: &'a SvecParams) -> Self {
        Svec {
            p,
            parts: PartOptions {
                steps: PARALLEL_STEPS,
                ..PartOptions::when(p.parallel)
            },
            triangle_collapses: 0,
            edge_collapses: 0,
            feature_collapses: 0,
            feature_threshold: f64::NAN,
        }
    }
}

impl Simplifier for Svec<'_> {
    fn unit(&self) -> Unit {
        Unit::Triangle
    }

    fn goal(&self, count: TargetCount) -> Goal {
        let scaled = |n: u64| {
            let n = (n as f64 * self.p.target_scale).round();
            // A saturating conversion: huge products mean "no collapse at all".
            n as usize
        };
        match count {
            TargetCount::Vertices(n) => Goal::Vertices(scaled(n)),
            TargetCount::Faces(n) => Goal::Faces(scaled(n)),
        }
    }

    fn facing_guard(&self) -> bool {
        self.p.facing_guard
    }

    fn kept_corners(&self) -> Option<f64> {
        self.p.features.then_some(self.p.feature_angle_deg)
    }

    fn max_error(&self) -> f64 {
        self.p.max_error
    }

    fn settles(&self, mesh: &Mesh) -> bool {
        match self.p.placement.as_str() {
            "surface" => true,
            "auto" => coarsen_collapse::stage::has_uvs(mesh),
            _ => false,
        }
    }

    fn weighted_sve(&self) -> bool {
        self.p.sve_weighted
    }

    fn target_words(&self, target: &Target) -> String {
        if self.p.target_scale == 1.0 {
            target.to_string()
        } else {
            format!("{} × {target}", self.p.target_scale)
        }
    }

    fn collapse<G: FaceGuard + Send>(
        &mut self,
        live: &mut LiveMesh,
        goal: Goal,
        new_guard: impl Fn() -> G + Sync,
        progress: &mut dyn FnMut(usize),
    ) -> Collapsed {
        let p = self.p;
        let model_opts = SvecOptions {
            feature_threshold: (p.feature_threshold > 0.0).then_some(p.feature_threshold),
            feature_sigma: p.feature_sigma,
            volume_constraint: p.volume_constraint,
            boundary_weight: p.boundary_weight,
            factors: if p.factors == "triangle" {
                Factors::Triangle
            } else {
                Factors::Face
            },
            normal_abs: p.normal_abs,
            feature_on_dequeue: p.feature_rule == "dequeue",
            two_rings: p.reach == "two_rings",
        };
        // The parts and the joined mesh get models of their own.
        let mut model = if live.will_part(&self.parts) {
            SvecModel::deferred(live, &model_opts)
        } else {
            SvecModel::new(live, &model_opts)
        };
        // Triangle collapses stop short of the goal; edge collapses finish.
        let opts = Options {
            goal,
            max_error: (p.max_error > 0.0).then_some(p.max_error),
            min_quality: p.min_quality,
            keep_log: false,
            weighted_sve: p.sve_weighted,
            ..Options::new(goal)
        };
        let to_edges = |m: &mut SvecModel| m.set_unit(Unit::Edge);
        let parts = &self.parts;
        let (run, edges) = triangles_then_edges(
            live, &mut model, new_guard, &opts, parts, to_edges, progress,
        );
        self.triangle_collapses = run.outcome.collapses - edges;
        self.edge_collapses = edges;
        self.feature_collapses = model.feature_collapses();
        self.feature_threshold = model.feature_threshold();
        run.into()
    }

    fn figures(&self, r: &mut StageReport) {
        r.figure("triangle_collapses", self.triangle_collapses);
        r.figure("edge_collapses", self.edge_collapses);
        r.figure("feature_collapses", self.feature_collapses);
        if self.feature_threshold.is_finite() {
            r.figure("feature_threshold", self.feature_threshold);
        }
    }

    fn warnings(&self, r: &mut StageReport) {
        if self.edge_collapses > 2 {
            r.warn(format!(
                "{} edge collapses finished the run after the triangle collapses ran out",
                self.edge_collapses
            ));
        }
    }
}

coarsen_stage::export_stage!(SimplifySvec);

/// Steps of the parallel phase's second round (crate docs, *Parallel phase*).
const PARALLEL_STEPS: usize = 16;

#[cfg(test)]
mod tests;
