//! Running a checked pipeline on a mesh.
//!
//! Before each stage the mesh is readied for what the stage's contract needs
//! ([`coarsen_mesh::repair::ready`], which says what is repaired and when): pinched
//! vertices split per face fan before a stage that needs a manifold mesh or asks for the
//! split (the collapse stages); edges of three or more faces cut apart, two-sided faces
//! made one-sided and pieces too small for a dual split 1-to-4 before the first stage of a
//! pipeline that has a stage needing a manifold mesh; a stage that needs one and does not
//! get it fails with [`RunError::NotManifold`]. The repairs become that stage's warnings.
//! The adjacency the repairs read is the run's shared one (`Shared::topology`), which the
//! next stage that needs it takes over.
//!
//! A large input (see [`RunOptions::reorder_min_faces`]) is first renumbered along a
//! Morton curve ([`coarsen_mesh::order::along_curve`]): the same surface, its vertices and
//! faces close in memory when they are close in space. Every stage then reads memory more
//! in order — on the bunny subdivided three times (4.4M faces), uniform-cvt takes about a
//! tenth less time and qem about a sixth less; subdivided once (278K faces), qem about a
//! tenth less. Stages see the renumbered mesh as the run's input and original. A run that
//! records a progressive record keeps the input's numbering, so that rebuilding its finest
//! level gives the input back vertex for vertex.
//!
//! The input's marked edges (`Mesh::marked_edges`) stay on the original
//! ([`Context::original`]), where stages read them; the mesh passed from stage to stage
//! carries none.

use crate::{Pipeline, PipelineStage, RunReport, StageRecord};
use coarsen_mesh::material::MATERIAL;
use coarsen_mesh::repair::{self, Readied, RepairError};
use coarsen_mesh::{Materials, Mesh, Wedges, sanity};
use coarsen_stage::Contract;
use coarsen_stage::{Context, Handback, NoProgress, Progress, StageError, StageReport, Target};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// The words of the warning a stage's report carries when the runner split the mesh's
/// non-manifold vertices before it (one vertex per face fan), and when it cut edges of
/// three or more faces apart before it (after making two-sided faces one-sided).
pub use coarsen_mesh::repair::{CUT_EDGES_NOTE, SPLIT_FANS_NOTE};

/// What every stage's output must satisfy: valid indices, finite values, no face repeating
/// a vertex, no duplicate face, no face of exactly zero area — the same bar as load-time
/// hygiene, so an input that hygiene kept never fails it by itself.
const STAGE_OUTPUT: sanity::SanityOptions = sanity::SanityOptions {
    require_manifold: false,
    require_oriented: false,
    degenerate_area_rel: 0.0,
};

/// A hook called after every stage with its record and its output mesh.
pub type AfterStage<'a> = dyn Fn(&StageRecord, &Mesh) + 'a;

/// How to run a pipeline.
#[derive(Clone, Copy)]
pub struct RunOptions<'a> {
    /// Where stages report progress.
    pub progress: &'a dyn Progress,
    /// Run the exhaustive `sanity_check` after every stage (default: in debug builds).
    pub sanity: bool,
    /// Called after every stage with its record and its output mesh (snapshots, reports).
    pub after_stage: Option<&'a AfterStage<'a>>,
    /// Where the last stage that records its collapses leaves its progressive record
    /// (see [`Pipeline::recording_stage`]); `None` records nothing. Default `None`.
    pub progressive: Option<&'a Mutex<Option<Handback>>>,
    /// Inputs of at least this many faces are renumbered along a Morton curve before the
    /// first stage (see the module docs); `usize::MAX` never. Default 2¹⁸.
    pub reorder_min_faces: usize,
    /// When this turns true the run stops with [`RunError::Cancelled`]: before the next
    /// stage, or inside one the next time it reports progress. Default `None`.
    pub cancel: Option<&'a AtomicBool>,
}

/// The default of [`RunOptions::reorder_min_faces`].
pub const REORDER_MIN_FACES: usize = 1 << 18;

impl RunOptions<'_> {
    /// `input` as the stages of a run with these options see it: renumbered along a
    /// Morton curve when large and no progressive record is asked for (see the module
    /// docs), else as it is.
    pub fn prepare(&self, input: Mesh) -> Mesh {
        if input.n_faces() < self.reorder_min_faces || self.progressive.is_some() {
            return input;
        }
        let t = Instant::now();
        let ordered = coarsen_mesh::order::along_curve(input);
        tracing::info!(
            seconds = t.elapsed().as_secs_f64(),
            "input renumbered along a Morton curve"
        );
        ordered
    }
}

impl Default for RunOptions<'_> {
    fn default() -> Self {
        RunOptions {
            progress: &NoProgress,
            sanity: cfg!(debug_assertions),
            after_stage: None,
            progressive: None,
            reorder_min_faces: REORDER_MIN_FACES,
            cancel: None,
        }
    }
}

/// Why a run stopped.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A stage failed.
    // The stage's error is part of this message, not a `source`: shown once at the CLI,
    // which prints whole error chains.
    #[error("stage {index} `{kind}` failed: {error}")]
    Stage {
        /// 1-based position.
        index: usize,
        /// Kind.
        kind: &'static str,
        /// The stage's error.
        error: StageError,
    },
    /// A stage needs a manifold mesh and did not get one.
    #[error(
        "stage {index} `{kind}` needs a manifold mesh, but its input has {edges} non-manifold edges and {vertices} non-manifold vertices"
    )]
    NotManifold {
        /// 1-based position.
        index: usize,
        /// Kind.
        kind: &'static str,
        /// Non-manifold edge count.
        edges: usize,
        /// Non-manifold vertex count.
        vertices: usize,
    },
    /// The run was cancelled ([`RunOptions::cancel`]).
    #[error("cancelled during stage {index} `{kind}`")]
    Cancelled {
        /// 1-based position of the stage that was running or about to run.
        index: usize,
        /// Kind.
        kind: &'static str,
    },
    /// A stage panicked: a bug.
    #[error(
        "stage {index} `{kind}` failed with an internal error (a bug in coarsen; please report it with the input): {message}"
    )]
    Panicked {
        /// 1-based position.
        index: usize,
        /// Kind.
        kind: &'static str,
        /// The panic's message.
        message: String,
    },
    /// A stage produced a mesh that breaks the mesh invariants: a bug.
    #[error(
        "stage {index} `{kind}` produced an invalid mesh (a bug in coarsen; please report it with the input): {detail}"
    )]
    Invalid {
        /// 1-based position.
        index: usize,
        /// Kind.
        kind: &'static str,
        /// What the sanity check found.
        detail: String,
    },
}

/// The payload a cancelled run unwinds a stage with, from inside its progress report.
struct Cancelled;

/// A progress sink that passes reports on and stops the stage once the flag is up.
struct Cancelling<'a> {
    inner: &'a dyn Progress,
    flag: &'a AtomicBool,
}

impl Cancelling<'_> {
    /// Unwinds the stage (without the panic hook's message) when the flag is up; the
    /// runner catches it and reports [`RunError::Cancelled`]. Stages own everything they
    /// build, so nothing outlives the unwinding half-made.
    fn stop_if_cancelled(&self) {
        if self.flag.load(Ordering::Relaxed) {
            std::panic::resume_unwind(Box::new(Cancelled));
        }
    }
}

impl Progress for Cancelling<'_> {
    fn begin(&self, label: &str, total: u64) {
        self.stop_if_cancelled();
        self.inner.begin(label, total);
    }
    fn advance(&self, done: u64, message: &str) {
        self.stop_if_cancelled();
        self.inner.advance(done, message);
    }
    fn end(&self) {
        self.inner.end();
    }
}

/// The message of a panic's payload (a `&str` or a `String`, as `panic!` makes them).
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "a panic with no message".to_string()
    }
}

impl Pipeline {
    /// The last stage that records its collapses (its 0-based position and kind): the one
    /// whose progressive record a run with [`RunOptions::progressive`] hands back.
    pub fn recording_stage(&self) -> Option<(usize, &'static str)> {
        self.stages
            .iter()
            .enumerate()
            .rev()
            .find(|(_, s)| s.stage.records_collapses())
            .map(|(i, s)| (i, s.kind))
    }

    /// Runs every stage in order on `input`.
    ///
    /// `input` (renumbered when large, see the module docs) is also kept as the original
    /// for stages that measure against it or project onto it. The report's `input` and
    /// `input_notes` are left for the caller.
    pub fn run(&self, input: Mesh, opts: RunOptions<'_>) -> Result<(Mesh, RunReport), RunError> {
        let start = Instant::now();
        let had_material_column = input.face_attrs.label(MATERIAL).is_some();
        let input = opts.prepare(input);
        let (input, materials, notes, taken) = self.without_wedges(input);
        // The original keeps the wedges the stages do not see, for a stage that restores
        // them.
        let mut original = input.clone();
        original.wedges = taken;
        let mut mesh = input;
        // The marked edges stay on the original, where stages read them; the mesh the
        // stages change carries none (a stage editing in place would leave them stale).
        mesh.marked_edges = Vec::new();
        let mut report = RunReport {
            pipeline: self.name.clone(),
            target: self.target,
            input_vertices: mesh.n_vertices(),
            input_faces: mesh.n_faces(),
            ..Default::default()
        };
        let shared = coarsen_stage::Shared::new();
        let run = Run {
            original: &original,
            target: self.target,
            opts: &opts,
            shared: &shared,
        };
        // When some stage needs a manifold mesh, edges of three or more faces are cut
        // before the first stage: the stages between (clustering above all) then work on
        // the surface that stage will get.
        let cut_ahead = self
            .stages
            .iter()
            .any(|s| s.stage.contract().needs.manifold);
        for (i, s) in self.stages.iter().enumerate() {
            let index = i + 1;
            stop_if_cancelled(&opts, index, s.kind)?;
            let readying = Instant::now();
            let readied = ready(mesh, s, index, cut_ahead && i == 0, &shared)?;
            let ready_seconds = readying.elapsed().as_secs_f64();
            let (vb, fb) = (readied.mesh.n_vertices(), readied.mesh.n_faces());
            let mut stage_report = StageReport::default();
            for note in readied.notes {
                stage_report.warn(note);
            }
            let t = Instant::now();
            mesh = run_stage(s, index, readied.mesh, &mut stage_report, &run)?;
            let seconds = t.elapsed().as_secs_f64();
            log_stage(s.kind, index, &mesh, seconds, &stage_report);
            check_output(&opts, &mesh, index, s.kind)?;
            report.stages.push(StageRecord {
                index,
                kind: s.kind.to_string(),
                id: s.id.clone(),
                params: serde_json::to_value(s.stage.params()).unwrap_or_default(),
                seconds,
                ready_seconds,
                vertices_before: vb,
                faces_before: fb,
                vertices_after: mesh.n_vertices(),
                faces_after: mesh.n_faces(),
                figures: stage_report.figures.into_iter().collect(),
                warnings: stage_report.warnings,
            });
            if let (Some(observe), Some(record)) = (opts.after_stage, report.stages.last()) {
                observe(record, &mesh);
            }
        }
        report.notes = notes;
        report.notes.extend(keep_materials(
            &mut mesh,
            materials,
            had_material_column,
            &self.name,
        ));
        report.seconds = start.elapsed().as_secs_f64();
        report.output_vertices = mesh.n_vertices();
        report.output_faces = mesh.n_faces();
        Ok((mesh, report))
    }
}

impl Pipeline {
    /// `input` as the stages take it: per-corner columns that are per vertex after all
    /// become vertex columns (carried like every vertex column); the others stay as wedges
    /// when every stage carries them (`Contract::carries_wedges`), else they are taken off
    /// (and returned) and, unless a stage after the last that cannot carry them restores
    /// them from the run's input (`Contract::restores_wedges`), said so. The materials are
    /// taken off too, for [`keep_materials`] to put back on the output.
    fn without_wedges(&self, mut input: Mesh) -> (Mesh, Materials, Vec<String>, Wedges) {
        let mut notes = Vec::new();
        let per_vertex = input
            .wedges
            .take_per_vertex(&input.faces, input.n_vertices());
        for (name, values) in per_vertex.iter() {
            input.vertex_attrs.insert(name, values.clone());
        }
        let contracts: Vec<Contract> = self.stages.iter().map(|s| s.stage.contract()).collect();
        let dropping = contracts
            .iter()
            .position(|c| !c.carries_wedges && !c.restores_wedges);
        let last_dropping = contracts
            .iter()
            .rposition(|c| !c.carries_wedges && !c.restores_wedges);
        let restored = last_dropping
            .is_some_and(|last| contracts[last + 1..].iter().any(|c| c.restores_wedges));
        let mut taken = Wedges::default();
        if let Some(first) = dropping.map(|i| &self.stages[i])
            && !input.wedges.is_empty()
            && !restored
        {
            let names: Vec<String> = input
                .wedges
                .attrs()
                .names()
                .map(|n| format!("`{n}`"))
                .collect();
            notes.push(format!(
                "per-corner {} ({} vertices on seams or hard edges) not carried: stage `{}` of \
                 pipeline `{}` cannot carry per-corner attributes yet, so the output has none",
                names.join(" and "),
                input.wedges.split_vertices(),
                first.kind,
                self.name
            ));
        }
        if dropping.is_some() {
            taken = std::mem::take(&mut input.wedges);
        }
        let materials = std::mem::take(&mut input.materials);
        (input, materials, notes, taken)
    }
}

/// Puts the input's `materials` on the output `mesh`; when the faces lost the column that
/// said which material each uses (`had_column`), every face takes the first, and the note
/// says so.
fn keep_materials(
    mesh: &mut Mesh,
    materials: Materials,
    had_column: bool,
    pipeline: &str,
) -> Option<String> {
    if materials.is_empty() {
        return None;
    }
    mesh.materials = materials;
    if !had_column || mesh.face_attrs.label(MATERIAL).is_some() {
        return None;
    }
    Some(format!(
        "pipeline `{pipeline}` did not carry which material each face uses: every face of the \
         output uses the first material"
    ))
}

/// What every stage of one run sees besides its input mesh.
struct Run<'a> {
    /// The run's input, as the stages measure against it.
    original: &'a Mesh,
    target: Option<Target>,
    opts: &'a RunOptions<'a>,
    /// What the stages share (indexes of the input, the current adjacency).
    shared: &'a coarsen_stage::Shared,
}

/// Runs stage `s` (at 1-based `index`) on `mesh` with the run's context, turning its
/// error, a panic or a cancellation inside it into the run's error.
fn run_stage(
    s: &PipelineStage,
    index: usize,
    mesh: Mesh,
    stage_report: &mut StageReport,
    run: &Run<'_>,
) -> Result<Mesh, RunError> {
    let opts = run.opts;
    tracing::info!(
        stage = index,
        kind = s.kind,
        vertices = mesh.n_vertices(),
        faces = mesh.n_faces(),
        "stage starts"
    );
    let mut slot = opts
        .progressive
        .map(|m| m.lock().unwrap_or_else(|poisoned| poisoned.into_inner()));
    let cancelling = opts.cancel.map(|flag| Cancelling {
        inner: opts.progress,
        flag,
    });
    let mut cx = Context {
        original: run.original,
        target: run.target,
        report: stage_report,
        progress: match &cancelling {
            Some(c) => c as &dyn Progress,
            None => opts.progress,
        },
        progressive: slot.as_deref_mut(),
        shared: Some(run.shared),
    };
    let ran = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| s.stage.run(mesh, &mut cx)));
    let kind = s.kind;
    match ran {
        Ok(Ok(mesh)) => Ok(mesh),
        Ok(Err(error)) => Err(RunError::Stage { index, kind, error }),
        Err(payload) if payload.is::<Cancelled>() => Err(RunError::Cancelled { index, kind }),
        Err(payload) => Err(RunError::Panicked {
            index,
            kind,
            message: panic_message(payload.as_ref()),
        }),
    }
}

/// [`RunError::Cancelled`] when the run's cancel flag is up before stage `index`.
fn stop_if_cancelled(
    opts: &RunOptions<'_>,
    index: usize,
    kind: &'static str,
) -> Result<(), RunError> {
    match opts.cancel.is_some_and(|flag| flag.load(Ordering::Relaxed)) {
        true => Err(RunError::Cancelled { index, kind }),
        false => Ok(()),
    }
}

/// `mesh` readied for stage `s` (at 1-based `index`) by the mesh crate's repairs, reading
/// the run's shared adjacency; `cut_ahead` before the first stage of a pipeline with a
/// stage that needs a manifold mesh.
fn ready(
    mesh: Mesh,
    s: &PipelineStage,
    index: usize,
    cut_ahead: bool,
    shared: &coarsen_stage::Shared,
) -> Result<Readied, RunError> {
    let needs = s.stage.contract().needs;
    let needs = repair::Needs {
        manifold: needs.manifold,
        split_fans: needs.split_fans,
        cut_ahead,
    };
    let readied = repair::ready(mesh, needs, |m| shared.topology(m)).map_err(|e| match e {
        RepairError::NotManifold { edges, vertices } => RunError::NotManifold {
            index,
            kind: s.kind,
            edges,
            vertices,
        },
        RepairError::Topology(e) => RunError::Stage {
            index,
            kind: s.kind,
            error: StageError::Input(e.to_string()),
        },
    })?;
    if s.stage.records_collapses() {
        // Collapse stages build adjacency of their own: the kept one would only add to
        // their peak (350 MiB at 4.4M faces).
        shared.forget_topology();
    }
    Ok(readied)
}

/// Logs what stage `index` made: its counts and time, then its figures and warnings.
fn log_stage(kind: &'static str, index: usize, mesh: &Mesh, seconds: f64, r: &StageReport) {
    tracing::info!(
        stage = index,
        kind,
        vertices = mesh.n_vertices(),
        faces = mesh.n_faces(),
        seconds,
        "stage done"
    );
    for (name, value) in &r.figures {
        tracing::debug!(stage = index, kind, "{name} = {value}");
    }
    for w in &r.warnings {
        tracing::warn!(stage = index, kind, "{w}");
    }
}

/// The exhaustive check of stage `index`'s output, when the run asks for it.
fn check_output(
    opts: &RunOptions<'_>,
    mesh: &Mesh,
    index: usize,
    kind: &'static str,
) -> Result<(), RunError> {
    if !opts.sanity {
        return Ok(());
    }
    sanity::sanity_check_with(mesh, &STAGE_OUTPUT).map_err(|e| RunError::Invalid {
        index,
        kind,
        detail: e.to_string(),
    })
}
