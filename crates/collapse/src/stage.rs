//! The run of a collapse stage, the skeleton `simplify.qem` and `simplify.svec` share: the
//! target turned into a [`Goal`], the live mesh renumbered for locality, the progressive
//! record asked for and handed back, the facing guard against the run input, progress, the
//! output with its attributes carried, and the report's common figures and warnings.
//!
//! What differs between the stages — the cost model, its phases, their own figures — is a
//! [`Simplifier`]; [`run`] does the rest. The skeleton knows no stage's parameters.
//!
//! **Facing guard**: besides the engine's own flip checks, a collapse is refused
//! (`refused.facing`) when a face it reshapes would point away (> 90°) from the run input's
//! surface at the input point nearest the face's centroid — the metrics' flipped-face test,
//! on `coarsen_metrics::GridFacing`, a light index of the input built on the first face
//! tested. Only faces past the engine's gate are tested ([`Gated`]: their corners' merged
//! input wraps around a thin part, or they turn by more than 45°); the report gives how
//! many (`facing_tests`).
//!
//! **Per-corner attributes** (UV seams, normals across hard edges): carried through the
//! collapses with the seams as constraints ([`LiveMesh::track_seams`]); the report gives
//! the vertices on seams before (`seam_vertices_in`: every vertex of a seam edge) and the
//! output's vertices with two wedges or more (`seam_vertices`). The borders between faces
//! of different materials (the face label column `material`) are seams too, UVs or not,
//! and so are, when the stage keeps sharp features ([`Simplifier::kept_corners`]), the
//! sharp curves between two surface patches.
//!
//! **Settling** ([`Simplifier::settles`]; the stages' `placement = "surface"`, their
//! `auto` default on a mesh with UVs): after the collapses, each vertex that moved goes to
//! the nearest point of the input faces it stands for, where its per-corner values are
//! taken ([`LiveMesh::settled`]); the report gives `settled_vertices` and `settle_refused`
//! (moves left out because they would spoil a face).
//!
//! **Squared volume error** (paper 2's, metrics.md `sve`): each collapse's Σ Vᵢ² over the
//! faces around the merged vertices, Vᵢ the volume swept by face i; the report gives the
//! sum (`sve`), the largest (`sve_max`) and, when the stage asks for it, the sum weighted
//! as paper 2's Eq. (4) quadrics (`sve_weighted`: Wᵢ·Nᵢ·Vᵢ²), all in world units.

use crate::{
    CostModel, FaceGuard, Gated, Goal, GuardCounts, LiveMesh, NoGuard, Options, Outcome,
    PartOptions, Parted, StopReason, Summary, Unit, attributes_only,
};
use coarsen_metrics::LazyGridFacing;
use coarsen_stage::{
    Context, Contract, Handback, Mesh, Needs, StageError, StageReport, Target, TargetCount,
};

/// What differs between the collapse stages: [`run`] asks it for the goal, the collapses
/// and the stage's own figures.
pub trait Simplifier {
    /// What one collapse merges (for the progress total: an edge collapse removes one
    /// vertex and up to two faces, a triangle collapse two and four).
    fn unit(&self) -> Unit;
    /// The goal for the run target's count.
    fn goal(&self, count: TargetCount) -> Goal;
    /// Whether faces are tested against the run input's surface nearest them (the
    /// metrics' flipped-face test behind [`Gated`]'s gate).
    fn facing_guard(&self) -> bool;
    /// The cost limit (0: none), for the warning when the target is not reached.
    fn max_error(&self) -> f64;
    /// Whether the run measured `sve_weighted` ([`crate::Options::weighted_sve`]), for
    /// the report. Default `false`.
    fn weighted_sve(&self) -> bool {
        false
    }
    /// The feature angle (degrees) when the stage keeps the corners of its input's sharp
    /// features as they are (locked: [`LiveMesh::lock`]), else `None`. Default `None`.
    fn kept_corners(&self) -> Option<f64> {
        None
    }
    /// Whether the output's moved vertices go onto the input surface of `mesh` after the
    /// collapses ([`LiveMesh::settle_on_input`]). Default `false`.
    fn settles(&self, mesh: &Mesh) -> bool {
        let _ = mesh;
        false
    }
    /// The target in words, for the warning when it is not reached.
    fn target_words(&self, target: &Target) -> String {
        target.to_string()
    }
    /// Makes the collapses on `live` (the progressive record asked for already) down to
    /// `goal`, each guard made by `new_guard`; `progress` hears the running count.
    fn collapse<G: FaceGuard + Send>(
        &mut self,
        live: &mut LiveMesh,
        goal: Goal,
        new_guard: impl Fn() -> G + Sync,
        progress: &mut dyn FnMut(usize),
    ) -> Collapsed;
    /// Writes the stage's own figures (after `collapses` and `parallel_collapses`).
    fn figures(&self, report: &mut StageReport) {
        let _ = report;
    }
    /// Writes the stage's own warnings (after the one for a target not reached).
    fn warnings(&self, report: &mut StageReport) {
        let _ = report;
    }
}

/// What a [`Simplifier`]'s collapses did.
pub struct Collapsed {
    /// Every phase's collapses, refusals and stop.
    pub outcome: Outcome,
    /// How many collapses the parts made side by side ([`LiveMesh::collapse_in_parts`]).
    pub in_parts: usize,
    /// What the guards did, over the parts and the serial run.
    pub guarded: GuardCounts,
}

impl<G: FaceGuard> From<Parted<G>> for Collapsed {
    fn from(run: Parted<G>) -> Collapsed {
        Collapsed {
            guarded: run.part_counts.plus(&run.guard.counts()),
            outcome: run.outcome,
            in_parts: run.in_parts,
        }
    }
}

/// The goal a run of triangle collapses stops at: a triangle collapse removes 2 vertices
/// and at most 4 faces, so it stops one vertex (three faces) short of `goal`, which edge
/// collapses then reach ([`triangles_then_edges`]).
pub fn triangle_goal(goal: Goal) -> Goal {
    match goal {
        Goal::Vertices(n) => Goal::Vertices(n.saturating_add(1)),
        Goal::Faces(n) => Goal::Faces(n.saturating_add(3)),
    }
}

/// Triangle collapses (in `parts`, then serially) to [`triangle_goal`], then edge
/// collapses down to `opts.goal` with the model switched to edges by `to_edges` (none when
/// the triangles stopped at the error limit). Returns the whole run and, of its collapses,
/// the edge collapses.
pub fn triangles_then_edges<M, G, F>(
    live: &mut LiveMesh,
    model: &mut M,
    new_guard: F,
    opts: &Options,
    parts: &PartOptions,
    to_edges: impl FnOnce(&mut M),
    progress: &mut dyn FnMut(usize),
) -> (Parted<G>, usize)
where
    M: CostModel + Send,
    G: FaceGuard + Send,
    F: Fn() -> G + Sync,
{
    let triangles = Options {
        goal: triangle_goal(opts.goal),
        ..*opts
    };
    let run = live.collapse_parted(model, new_guard, &triangles, parts, progress);
    if matches!(run.outcome.stop, StopReason::MaxError { .. }) {
        return (run, 0);
    }
    let Parted {
        outcome,
        in_parts,
        part_counts,
        mut guard,
    } = run;
    to_edges(model);
    let done = outcome.collapses;
    let finish = live.collapse_guarded(model, &mut guard, opts, &mut |n| progress(done + n));
    let edges = finish.collapses;
    let run = Parted {
        outcome: outcome.then(finish),
        in_parts,
        part_counts,
        guard,
    };
    (run, edges)
}

/// The contract of a collapse stage: a target, and pinched vertices split per face fan
/// (the engine locks what is not manifold; split, they let it work there); per-corner
/// attributes carried (their seams kept, [`LiveMesh::track_seams`]).
pub fn contract() -> Contract {
    Contract {
        needs: Needs {
            target: true,
            split_fans: true,
            ..Needs::default()
        },
        carries_wedges: true,
        ..Contract::default()
    }
}

/// Runs the collapse stage `kind` on `mesh`: the goal from the run target, the collapses
/// of `stage` on a live mesh renumbered for locality (behind the facing guard when the
/// stage asks for it), the output with its attributes carried, the progressive record in
/// `cx.progressive` when asked for, and the report.
pub fn run(
    kind: &'static str,
    stage: &mut impl Simplifier,
    mut mesh: Mesh,
    cx: &mut Context<'_>,
) -> Result<Mesh, StageError> {
    let (target, count) = cx.target_count(kind)?;
    let goal = stage.goal(count);
    let settles = stage.settles(&mesh);
    let mut live =
        LiveMesh::new_renumbered(&mesh).map_err(|e| StageError::Input(format!("`{kind}`: {e}")))?;
    let features = stage.kept_corners().map(|angle| features_of(&mesh, angle));
    let corners = features
        .as_ref()
        .map(|(corners, _)| (corners.len(), live.lock(corners)));
    let patches = features.map(|(_, patch)| patch);
    let Folded { folded, sides } = fold_into_wedges(&mut mesh, patches);
    let on_seams = live.track_seams(&mut mesh);
    if settles {
        live.settle_on_input(&mut mesh);
    }
    // The live mesh holds the input's arrays now: keep only its attributes to carry.
    let attributes = attributes_only(mesh);
    if cx.progressive.is_some() {
        live.record_progressive();
    }
    let before = live.summary();
    let done = collapse_with_progress(kind, stage, &mut live, goal, &before, cx);
    let after = live.summary();
    let (mut out, carry) = live
        .to_mesh_with_attributes(&attributes)
        .map_err(|e| StageError::Internal(e.to_string()))?;
    let settled = settles.then(|| live.settled().unwrap_or_default());
    if sides {
        let mut columns = out.wedges.corner_values();
        columns.remove(MATERIAL_SIDE);
        columns.remove(FEATURE_SIDE);
        out.wedges = coarsen_mesh::Wedges::default();
        out = out.with_corner_attributes(columns);
    }
    if folded {
        let per_vertex = out.wedges.take_per_vertex(&out.faces, out.n_vertices());
        for (name, values) in per_vertex.iter() {
            out.vertex_attrs.insert(name, values.clone());
        }
    }
    if let Some(slot) = cx.progressive.as_mut() {
        **slot = live.take_progressive(&out).map(|p| Box::new(p) as Handback);
    }
    report(cx.report, stage, &target, &done, &before, &after);
    if live.tracks_seams() {
        cx.report.figure("seam_vertices_in", on_seams);
        cx.report
            .figure("seam_vertices", out.wedges.split_vertices());
    }
    if let Some(settled) = settled {
        cx.report.figure("settled_vertices", settled.moved);
        cx.report.figure("settle_refused", settled.refused);
    }
    if let Some((found, locked)) = corners {
        cx.report.figure("corners", found);
        cx.report.figure("corners_locked", locked);
    }
    if let Some(w) = done.outcome.below_face_goal(goal, &after) {
        cx.report.warn(w);
    }
    for w in carry.warnings() {
        cx.report.warn(w);
    }
    Ok(out)
}

/// Whether `mesh` carries texture coordinates (a `uv` column, per corner or per vertex):
/// what the collapse stages' `auto` placement settles the output on the input surface for.
pub fn has_uvs(mesh: &Mesh) -> bool {
    mesh.wedges.attrs().vec2("uv").is_some() || mesh.vertex_attrs.vec2("uv").is_some()
}

/// The vertex columns that [`LiveMesh::track_seams`] carries better than a blend of the
/// merged vertices' values: a moved vertex takes the value at its nearest point on the
/// input, as a wedge's does.
const AS_WEDGES: [&str; 3] = ["uv", "normal", "color"];

/// What [`fold_into_wedges`] put into the wedges.
struct Folded {
    /// Vertex columns of [`AS_WEDGES`]: the output's wedges that agree at every vertex
    /// become vertex columns again.
    folded: bool,
    /// The columns [`MATERIAL_SIDE`] and [`FEATURE_SIDE`]: the output drops them.
    sides: bool,
}

/// The per-corner columns added for the collapses: each corner's face's material, and its
/// face's feature patch.
const MATERIAL_SIDE: &str = "material side";
const FEATURE_SIDE: &str = "feature side";

/// Rebuilds `mesh`'s wedges, once, with what the collapses should track besides them:
///
/// * its vertex columns [`AS_WEDGES`] (one wedge per vertex where it had none);
/// * each corner's face's material when its faces use more than one (the face label
///   column `material`), and its face's feature patch when `patches` are given, so that
///   the edges between two materials or two patches are seams to the collapses
///   (`LiveMesh::track_seams`): their vertices stay, and merge along them only (as
///   gltfpack keeps a primitive's borders).
fn fold_into_wedges(mesh: &mut Mesh, patches: Option<Vec<u32>>) -> Folded {
    let corners: Vec<u32> = mesh.faces.iter().flatten().copied().collect();
    let mut columns = mesh.wedges.corner_values();
    let mut folded = false;
    for name in AS_WEDGES {
        let fits = matches!(
            (name, mesh.vertex_attrs.get(name)),
            ("uv", Some(coarsen_mesh::AttrValues::Vec2(_)))
                | ("normal", Some(coarsen_mesh::AttrValues::Vec3(_)))
                | ("color", Some(coarsen_mesh::AttrValues::Color(_)))
        );
        if fits
            && columns.get(name).is_none()
            && let Some(values) = mesh.vertex_attrs.remove(name)
        {
            columns.insert(name, values.gather(&corners));
            folded = true;
        }
    }
    let per_corner = |labels: &[u32]| {
        let side = labels.iter().flat_map(|&m| [m; 3]).collect();
        coarsen_mesh::AttrValues::Label(side)
    };
    let mut sides = false;
    if let Some(material) = mesh.face_attrs.label(coarsen_mesh::material::MATERIAL)
        && material.iter().any(|&m| m != material[0])
    {
        columns.insert(MATERIAL_SIDE, per_corner(material));
        sides = true;
    }
    if let Some(patch) = patches
        && patch.iter().any(|&p| p != patch[0])
    {
        columns.insert(FEATURE_SIDE, per_corner(&patch));
        sides = true;
    }
    if folded || sides {
        mesh.wedges = coarsen_mesh::Wedges::from_corners(&mesh.faces, columns);
    }
    Folded { folded, sides }
}

/// The corners of `mesh`'s sharp features at `angle_deg` (`coarsen_features`, boundary
/// edges included), and each face's patch: the smallest face it reaches without crossing
/// a sharp edge. No corners and one patch when its adjacency cannot be built.
fn features_of(mesh: &Mesh, angle_deg: f64) -> (Vec<u32>, Vec<u32>) {
    let Ok(topo) = coarsen_mesh::Topology::try_build(mesh) else {
        return (Vec::new(), vec![0; mesh.n_faces()]);
    };
    let opts = coarsen_features::FeatureOptions {
        angle_deg,
        ..Default::default()
    };
    let features = coarsen_features::Features::detect(mesh, &topo, &opts);
    let mut sharp = vec![false; topo.n_edges()];
    for &(e, _) in &features.edges {
        sharp[e as usize] = true;
    }
    let mut patch = vec![u32::MAX; mesh.n_faces()];
    let mut stack = Vec::new();
    for f in 0..mesh.n_faces() as u32 {
        if patch[f as usize] != u32::MAX {
            continue;
        }
        patch[f as usize] = f;
        stack.push(f);
        while let Some(g) = stack.pop() {
            for e in topo.face_edges(g) {
                if sharp[e as usize] {
                    continue;
                }
                for &h in topo.edge_faces(e) {
                    if patch[h as usize] == u32::MAX {
                        patch[h as usize] = f;
                        stack.push(h);
                    }
                }
            }
        }
    }
    (features.corners, patch)
}

/// `stage`'s collapses, behind the facing guard when it asks for one, told to the run's
/// progress.
fn collapse_with_progress(
    kind: &'static str,
    stage: &mut impl Simplifier,
    live: &mut LiveMesh,
    goal: Goal,
    before: &Summary,
    cx: &Context<'_>,
) -> Collapsed {
    let per_collapse = match stage.unit() {
        Unit::Edge => 1,
        Unit::Triangle => 2,
    };
    let to_remove = match goal {
        Goal::Vertices(n) => before.vertices.saturating_sub(n) / per_collapse,
        Goal::Faces(n) => before.faces.saturating_sub(n) / (2 * per_collapse),
    };
    let progress = cx.progress;
    progress.begin(kind, to_remove as u64);
    let mut advance = |n: usize| progress.advance(n as u64, "collapses");
    let done = if stage.facing_guard() {
        let input = LazyGridFacing::new(cx.original);
        let guard = || Gated::standard(|a, b, c| input.allows(a, b, c));
        stage.collapse(live, goal, guard, &mut advance)
    } else {
        stage.collapse(live, goal, || NoGuard, &mut advance)
    };
    progress.end();
    done
}

/// Fills the stage report: the figures (the stage's own after the collapse counts), then
/// the warnings.
fn report(
    r: &mut StageReport,
    stage: &impl Simplifier,
    target: &Target,
    done: &Collapsed,
    before: &Summary,
    after: &Summary,
) {
    let o = &done.outcome;
    r.figure("collapses", o.collapses);
    r.figure("parallel_collapses", done.in_parts);
    stage.figures(r);
    r.figure("refused", o.refused.by_reason());
    if stage.facing_guard() {
        r.figure("facing_tests", done.guarded.tested);
    }
    r.figure("sve", o.sve);
    r.figure("sve_max", o.sve_max);
    if stage.weighted_sve() {
        r.figure("sve_weighted", o.sve_weighted);
    }
    r.figure("max_cost", o.max_cost);
    r.figure("cost_curve", &o.costs.bins);
    r.figure("vertices", after.vertices);
    r.figure("faces", after.faces);
    r.figure("stop", o.stop.name());
    r.figure("locked_vertices", before.locked_vertices);
    r.figure("boundary_loops_in", before.boundary_loops);
    r.figure("boundary_loops", after.boundary_loops);

    let words = stage.target_words(target);
    if let Some(w) = o.shortfall(&words, stage.max_error(), after.vertices, after.faces) {
        r.warn(w);
    }
    stage.warnings(r);
    if before.locked_vertices > 0 {
        r.warn(format!(
            "{} non-manifold vertices (or vertices of faces that repeat a vertex) were locked: \
             they keep their place and no collapse touches them",
            before.locked_vertices
        ));
    }
    if before.isolated_vertices > 0 {
        r.warn(format!(
            "{} vertices used by no face were dropped",
            before.isolated_vertices
        ));
    }
}
