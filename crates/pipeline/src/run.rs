//! Running a checked pipeline on a mesh.
//!
//! Before a stage that needs a manifold mesh or asks for it (`Needs::split_fans`, the
//! collapse stages), non-manifold vertices (several face fans at one point) are split into
//! one vertex per fan, with a warning in that stage's report. A stage that only asks for
//! the split skips the adjacency altogether when every vertex is one oriented fan
//! ([`coarsen_mesh::ring::one_fan_everywhere`]), a far cheaper test (0.16 against 0.8 s
//! on the bunny subdivided three times, 4.4M faces).
//!
//! Edges of three or more faces are cut apart before the first stage of a pipeline that
//! has a stage needing a manifold mesh (so that the stages between, clustering above all,
//! see the surface that stage will get), and again before such a stage if one appeared
//! meanwhile: two-sided faces (two faces back to back on the same vertices, which no dual
//! can represent) are first made one-sided ([`coarsen_mesh::hygiene::drop_two_sided_faces`]),
//! then the faces on each such edge are paired, the two sides of a surface first, and the
//! others come off ([`coarsen_mesh::hygiene::cut_non_manifold_edges`]: a fin on a surface
//! leaves the surface whole). Then the faces of pieces whose boundary runs along fewer
//! than three faces (a lone triangle cut off; no dual exists for them) are split 1-to-4
//! ([`coarsen_mesh::hygiene::split_small_pieces`]). Warnings of that stage count each.
//! In a pipeline with no such stage, a collapse stage gets those edges as they are (their
//! vertices stay in place). Two faces using an edge in the same direction are no matter
//! of manifoldness (the stage itself may refuse them); [`RunError::NotManifold`] guards
//! what is left.
//!
//! A large input (see [`RunOptions::reorder_min_faces`]) is first renumbered along a
//! Morton curve ([`coarsen_mesh::order::along_curve`]): the same surface, its vertices and
//! faces close in memory when they are close in space. Every stage then reads memory more
//! in order — on the bunny subdivided three times (4.4M faces), uniform-cvt takes about a
//! tenth less time and qem about a sixth less; subdivided once (278K faces), qem about a
//! tenth less. Stages see the renumbered mesh as the run's input and original. A run that
//! records a progressive record keeps the input's numbering, so that rebuilding its finest
//! level gives the input back vertex for vertex.

use crate::{Pipeline, RunReport, StageRecord};
use coarsen_mesh::{Mesh, sanity};
use coarsen_stage::{Context, Handback, NoProgress, Progress, StageError, StageReport};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// The words of the warning a stage's report carries when the runner split the mesh's
/// non-manifold vertices before it (one vertex per face fan).
pub const SPLIT_FANS_NOTE: &str = "split into one vertex per face fan";

/// The words of the warning a stage's report carries when the runner cut edges of three or
/// more faces apart before it (after making two-sided faces one-sided).
pub const CUT_EDGES_NOTE: &str = "edges of three or more faces cut apart";

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
        let input = opts.prepare(input);
        let original = input.clone();
        let mut mesh = input;
        let mut report = RunReport {
            pipeline: self.name.clone(),
            target: self.target,
            input_vertices: mesh.n_vertices(),
            input_faces: mesh.n_faces(),
            ..Default::default()
        };
        let shared = coarsen_stage::Shared::new();
        for (i, s) in self.stages.iter().enumerate() {
            let readying = Instant::now();
            let index = i + 1;
            if opts.cancel.is_some_and(|flag| flag.load(Ordering::Relaxed)) {
                return Err(RunError::Cancelled {
                    index,
                    kind: s.kind,
                });
            }
            let contract = s.stage.contract();
            let mut notes = Vec::new();
            let topology_of = |mesh: &Mesh| {
                shared.topology(mesh).map_err(|e| RunError::Stage {
                    index,
                    kind: s.kind,
                    error: StageError::Input(e.to_string()),
                })
            };
            let summary_of = |mesh: &Mesh| topology_of(mesh).map(|t| t.summary(mesh));
            // When some stage of the pipeline needs a manifold mesh, edges of three or
            // more faces are cut before the first one: the stages between (clustering
            // above all) then work on the surface that stage will get.
            let prepare = i == 0
                && self
                    .stages
                    .iter()
                    .any(|s| s.stage.contract().needs.manifold);
            let cut_first = prepare && !topology_of(&mesh)?.is_manifold();
            // A stage that only asks for the split needs no adjacency when every vertex is
            // one oriented fan (the usual case), which is much cheaper to tell.
            let check = contract.needs.manifold
                || cut_first
                || (contract.needs.split_fans && !coarsen_mesh::ring::one_fan_everywhere(&mesh));
            // A manifold mesh has nothing to split, cut or refuse: its summary (the
            // components and loops counted, every face's area measured) is not needed.
            if check && !topology_of(&mesh)?.is_manifold() {
                let mut summary = summary_of(&mesh)?;
                // Edges of three or more faces are cut only for a stage that cannot work
                // with them, or before one: a collapse stage keeps them joined (its
                // vertices there stay).
                let multi_edges = summary.n_non_manifold_edges - summary.n_flipped_edges;
                let cut = (contract.needs.manifold || cut_first) && multi_edges > 0;
                let split_only =
                    multi_edges == 0 && (contract.needs.manifold || contract.needs.split_fans);
                if summary.n_non_manifold_vertices > 0 && (split_only || cut) {
                    // One vertex per face fan makes non-manifold vertices workable.
                    let (split, cut_edges, copies) = if cut {
                        // A two-sided face (two faces back to back) has no dual: one side
                        // stays.
                        let (m, dropped) = coarsen_mesh::hygiene::drop_two_sided_faces(mesh);
                        if dropped > 0 {
                            notes.push(format!(
                                "{dropped} faces dropped that lay back to back on another face (two-sided faces made one-sided)"
                            ));
                        }
                        let (m, c) = coarsen_mesh::hygiene::cut_non_manifold_edges(m);
                        (m, c.edges, c.copies)
                    } else {
                        let (m, copies) = coarsen_mesh::hygiene::split_non_manifold_vertices(mesh);
                        (m, 0, copies)
                    };
                    mesh = split;
                    let after = summary_of(&mesh)?;
                    if copies > 0 {
                        let cut_note = if cut_edges > 0 {
                            format!("{cut_edges} {CUT_EDGES_NOTE}, ")
                        } else {
                            String::new()
                        };
                        notes.push(format!(
                            "{cut_note}{} non-manifold vertices {SPLIT_FANS_NOTE} ({copies} copies added)",
                            summary.n_non_manifold_vertices - after.n_non_manifold_vertices
                        ));
                    }
                    summary = after;
                }
                if contract.needs.manifold && !summary.manifold {
                    return Err(RunError::NotManifold {
                        index,
                        kind: s.kind,
                        edges: summary.n_non_manifold_edges,
                        vertices: summary.n_non_manifold_vertices,
                    });
                }
            }
            // Pieces too small for a dual (a boundary loop along fewer than three faces, as
            // a lone triangle cut off) are split 1-to-4 before the first stage.
            let topo = if prepare {
                Some(topology_of(&mesh)?)
            } else {
                None
            };
            if let Some(topo) = topo
                && !coarsen_mesh::hygiene::small_pieces(&topo).is_empty()
            {
                let (split, n) = coarsen_mesh::hygiene::split_small_pieces(mesh, &topo);
                mesh = split;
                notes.push(format!(
                    "{n} faces split 1-to-4 in pieces whose boundary runs along fewer than three faces (a dual needs three)"
                ));
            }
            if s.stage.records_collapses() {
                // Collapse stages build adjacency of their own: the kept one would only
                // add to their peak (350 MiB at 4.4M faces).
                shared.forget_topology();
            }
            let ready_seconds = readying.elapsed().as_secs_f64();
            let (vb, fb) = (mesh.n_vertices(), mesh.n_faces());
            tracing::info!(
                stage = index,
                kind = s.kind,
                vertices = vb,
                faces = fb,
                "stage starts"
            );
            let mut stage_report = StageReport::default();
            for note in notes {
                stage_report.warn(note);
            }
            let t = Instant::now();
            let mut slot = opts
                .progressive
                .map(|m| m.lock().unwrap_or_else(|poisoned| poisoned.into_inner()));
            let cancelling = opts.cancel.map(|flag| Cancelling {
                inner: opts.progress,
                flag,
            });
            let mut cx = Context {
                original: &original,
                target: self.target,
                report: &mut stage_report,
                progress: match &cancelling {
                    Some(c) => c as &dyn Progress,
                    None => opts.progress,
                },
                progressive: slot.as_deref_mut(),
                shared: Some(&shared),
            };
            let ran = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                s.stage.run(mesh, &mut cx)
            }));
            mesh = match ran {
                Ok(Ok(mesh)) => mesh,
                Ok(Err(error)) => {
                    return Err(RunError::Stage {
                        index,
                        kind: s.kind,
                        error,
                    });
                }
                Err(payload) if payload.is::<Cancelled>() => {
                    return Err(RunError::Cancelled {
                        index,
                        kind: s.kind,
                    });
                }
                Err(payload) => {
                    return Err(RunError::Panicked {
                        index,
                        kind: s.kind,
                        message: panic_message(payload.as_ref()),
                    });
                }
            };
            drop(slot);
            let seconds = t.elapsed().as_secs_f64();
            tracing::info!(
                stage = index,
                kind = s.kind,
                vertices = mesh.n_vertices(),
                faces = mesh.n_faces(),
                seconds,
                "stage done"
            );
            for (name, value) in &stage_report.figures {
                tracing::debug!(stage = index, kind = s.kind, "{name} = {value}");
            }
            for w in &stage_report.warnings {
                tracing::warn!(stage = index, kind = s.kind, "{w}");
            }
            if opts.sanity {
                sanity::sanity_check_with(&mesh, &STAGE_OUTPUT).map_err(|e| RunError::Invalid {
                    index,
                    kind: s.kind,
                    detail: e.to_string(),
                })?;
            }
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
        report.seconds = start.elapsed().as_secs_f64();
        report.output_vertices = mesh.n_vertices();
        report.output_faces = mesh.n_faces();
        Ok((mesh, report))
    }
}
