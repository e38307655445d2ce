//! Running a pipeline on a mesh: the one-call [`remesh`] and the [`Remesher`] builder.

use crate::input::restore;
use crate::{Cleaned, Error, Input, clean};
use coarsen_mesh::Mesh;
use coarsen_pipeline::{AfterStage, Overrides, Pipeline, RunOptions, RunReport, SetOverride};
use coarsen_stage::{Progress, Registry, Target};
use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::AtomicBool;

/// The pipeline [`remesh`] and `coarsen IN -o OUT` run when none is named.
pub const DEFAULT_PIPELINE: &str = "adaptive-cvt";

/// Coarsens `mesh` to `target` with the default pipeline ([`DEFAULT_PIPELINE`]): the same
/// clean-up, stages and output as `coarsen IN -o OUT --vertices N`, byte for byte.
///
/// ```
/// let mesh = coarsen::demo();
/// let (out, report) = coarsen::remesh(&mesh, coarsen::Target::Vertices(500))?;
/// assert_eq!(out.n_vertices(), 500);
/// assert_eq!(report.output_vertices, 500);
/// # Ok::<(), coarsen::Error>(())
/// ```
pub fn remesh(mesh: &Mesh, target: Target) -> Result<(Mesh, RunReport), Error> {
    Remesher::new().target(target).run(mesh)
}

/// Every registered stage: the built-in ones and those linked into the program. A kind
/// that two packages register is listed in [`Registry::conflicts`] and fails only the
/// pipelines that use it.
///
/// ```
/// let registry = coarsen::registry();
/// assert!(registry.conflicts().is_empty());
/// assert!(registry.get("cluster.cvt").is_some());
/// ```
pub fn registry() -> Registry {
    coarsen_builtin::registry()
}

/// What a run gives back ([`Remesher::run_input`]).
///
/// ```
/// let done = coarsen::Remesher::new()
///     .pipeline("qem")
///     .target(coarsen::Target::Ratio(0.5))
///     .progressive(true)
///     .run_input(coarsen::Input::demo())?;
/// let record = done.progressive.expect("asked for");
/// assert_eq!(coarsen::lod::levels(&record), 10_242 - done.mesh.n_vertices());
/// # Ok::<(), coarsen::Error>(())
/// ```
#[derive(Debug)]
pub struct Remeshed {
    /// The output mesh, in the input's units.
    pub mesh: Mesh,
    /// What every stage did: counts, times, figures, warnings (also as JSON:
    /// [`RunReport::to_json`]).
    pub report: RunReport,
    /// The progressive record, when [`Remesher::progressive`] asked for it.
    pub progressive: Option<coarsen_lod::Progressive>,
}

/// Where the pipeline comes from.
#[derive(Clone, Debug)]
enum Source {
    /// A pipeline file's path, else a shipped pipeline's name.
    Spec(String),
    /// A pipeline file's text, and the name its errors are reported under.
    Text { text: String, origin: String },
}

/// A run to make: which pipeline, with which target and parameters, observed how.
///
/// ```
/// use std::sync::atomic::AtomicBool;
///
/// let cancel = AtomicBool::new(false); // another thread may raise it
/// let (out, report) = coarsen::Remesher::new()
///     .pipeline("uniform-cvt")
///     .target(coarsen::Target::Vertices(400))
///     .set("relax.sweeps", "2")
///     .cancel(&cancel)
///     .run(&coarsen::demo())?;
/// assert_eq!(out.n_vertices(), 400);
/// assert_eq!(report.pipeline, "uniform-cvt");
/// # Ok::<(), coarsen::Error>(())
/// ```
#[derive(Clone)]
pub struct Remesher<'a> {
    source: Source,
    target: Option<Target>,
    sets: Vec<Result<SetOverride, String>>,
    weld: bool,
    sanity: bool,
    progressive: bool,
    progress: Option<&'a dyn Progress>,
    cancel: Option<&'a AtomicBool>,
    after_stage: Option<&'a AfterStage<'a>>,
}

impl Default for Remesher<'_> {
    fn default() -> Self {
        Remesher {
            source: Source::Spec(DEFAULT_PIPELINE.to_string()),
            target: None,
            sets: Vec::new(),
            weld: false,
            sanity: RunOptions::default().sanity,
            progressive: false,
            progress: None,
            cancel: None,
            after_stage: None,
        }
    }
}

impl<'a> Remesher<'a> {
    /// The default pipeline, its own target (none for most), no overrides.
    pub fn new() -> Self {
        Self::default()
    }

    /// The pipeline: a pipeline file's path when such a file exists, else the name of a
    /// shipped pipeline ([`pipelines`](crate::pipelines)).
    pub fn pipeline(mut self, spec: impl Into<String>) -> Self {
        self.source = Source::Spec(spec.into());
        self
    }

    /// The pipeline from a pipeline file's text; `origin` names it in error messages.
    pub fn pipeline_text(mut self, text: impl Into<String>, origin: impl Into<String>) -> Self {
        self.source = Source::Text {
            text: text.into(),
            origin: origin.into(),
        };
        self
    }

    /// The target, replacing the pipeline file's.
    pub fn target(mut self, target: Target) -> Self {
        self.target = Some(target);
        self
    }

    /// Sets a stage parameter: `path` is `STAGE.PARAM` (STAGE a kind or a stage id, as
    /// `relax.sweeps` or `cluster.cvt.r`), `value` a TOML value (`4`, `0.5`, `true`; a bare
    /// word is a string). Checked with the whole pipeline when the run starts.
    pub fn set(self, path: &str, value: &str) -> Self {
        self.assign(&format!("{path}={value}"))
    }

    /// Sets a stage parameter from `STAGE.PARAM=VALUE`, as the command line's `--set`.
    pub fn assign(mut self, assignment: &str) -> Self {
        self.sets.push(coarsen_pipeline::parse_set(assignment));
        self
    }

    /// Welds vertices at bit-identical positions during the clean-up (always done for STL
    /// files). Default `false`.
    pub fn weld(mut self, weld: bool) -> Self {
        self.weld = weld;
        self
    }

    /// Runs the exhaustive mesh check after every stage. Default: on in debug builds.
    pub fn sanity(mut self, sanity: bool) -> Self {
        self.sanity = sanity;
        self
    }

    /// Asks for the progressive record of the pipeline's last collapse stage
    /// ([`Remeshed::progressive`]); the pipeline must end with that stage.
    pub fn progressive(mut self, progressive: bool) -> Self {
        self.progressive = progressive;
        self
    }

    /// Where stages report their progress.
    pub fn progress(mut self, progress: &'a dyn Progress) -> Self {
        self.progress = Some(progress);
        self
    }

    /// A flag that stops the run when raised (from another thread, a signal handler, a
    /// deadline): before the next stage, or inside one the next time it reports progress.
    /// The run then fails with an error whose [`Error::is_cancelled`] is true.
    pub fn cancel(mut self, cancel: &'a AtomicBool) -> Self {
        self.cancel = Some(cancel);
        self
    }

    /// Called after every stage with its record and its output mesh (pictures, logs).
    pub fn after_stage(mut self, hook: &'a AfterStage<'a>) -> Self {
        self.after_stage = Some(hook);
        self
    }

    /// The pipeline, parsed and checked whole with the target and overrides applied,
    /// before any mesh is touched.
    pub fn check(&self) -> Result<Pipeline, Error> {
        self.check_with(&registry())
    }

    /// [`check`](Self::check) against the stages of `registry`.
    pub fn check_with(&self, registry: &Registry) -> Result<Pipeline, Error> {
        let sets = self
            .sets
            .iter()
            .cloned()
            .collect::<Result<Vec<_>, _>>()
            .map_err(Error::Set)?;
        let overrides = Overrides {
            target: self.target,
            sets,
        };
        let pipeline = match &self.source {
            Source::Text { text, origin } => Pipeline::parse(text, origin, registry, &overrides)?,
            Source::Spec(spec) if Path::new(spec).exists() => {
                Pipeline::from_path(Path::new(spec), registry, &overrides)?
            }
            Source::Spec(spec) => match coarsen_builtin::pipeline(spec) {
                Some(text) => Pipeline::parse(
                    text,
                    &format!("<shipped pipeline {spec}>"),
                    registry,
                    &overrides,
                )?,
                None => {
                    return Err(Error::UnknownPipeline {
                        name: spec.clone(),
                        shipped: coarsen_builtin::PIPELINES
                            .iter()
                            .map(|(n, _)| *n)
                            .collect::<Vec<_>>()
                            .join(", "),
                    });
                }
            },
        };
        if self.progressive && pipeline.recording_stage().is_none() {
            return Err(Error::NoRecordingStage {
                pipeline: pipeline.name.clone(),
                stages: pipeline
                    .stages
                    .iter()
                    .map(|s| s.kind)
                    .collect::<Vec<_>>()
                    .join(" → "),
            });
        }
        Ok(pipeline)
    }

    /// Runs on a copy of `mesh` and returns the output and the run report.
    pub fn run(&self, mesh: &Mesh) -> Result<(Mesh, RunReport), Error> {
        let done = self.run_input(Input::from(mesh.clone()))?;
        Ok((done.mesh, done.report))
    }

    /// Checks the pipeline, cleans `input` and runs; the report names the input and
    /// starts with its notes.
    pub fn run_input(&self, input: Input) -> Result<Remeshed, Error> {
        let pipeline = self.check()?;
        self.run_checked(&pipeline, input)
    }

    /// Runs `pipeline` (from [`check`](Self::check), e.g. once for many files) on `input`
    /// with this run's other settings. A panic anywhere in the run comes back as an error.
    pub fn run_checked(&self, pipeline: &Pipeline, input: Input) -> Result<Remeshed, Error> {
        let name = input.name.clone();
        let cleaned = catching(|| clean(input, self.weld))?;
        self.run_cleaned(pipeline, &name, cleaned)
    }

    /// Runs `pipeline` on an input already cleaned ([`clean`](crate::clean)), called
    /// `name` in the report. A panic anywhere in the run comes back as an error.
    pub fn run_cleaned(
        &self,
        pipeline: &Pipeline,
        name: &str,
        cleaned: Cleaned,
    ) -> Result<Remeshed, Error> {
        let Cleaned {
            mesh,
            notes,
            scale_exponent,
        } = cleaned;
        let slot = Mutex::new(None);
        let defaults = RunOptions::default();
        let opts = RunOptions {
            sanity: self.sanity,
            progress: self.progress.unwrap_or(defaults.progress),
            after_stage: self.after_stage,
            progressive: self.progressive.then_some(&slot),
            cancel: self.cancel,
            ..defaults
        };
        let (mesh, mut report) = catching(|| Ok(pipeline.run(mesh, opts)?))?;
        report.input = name.to_string();
        report.input_notes = notes;
        let record = match self.progressive {
            true => Some(take_record(pipeline, slot, &mesh)?),
            false => None,
        };
        let mesh = restore(mesh, scale_exponent);
        let progressive = record.map(|mut r| {
            // The record speaks the input's units and describes the mesh as handed back.
            r.scale_by_power_of_two(-scale_exponent);
            r.coarse = coarsen_collapse::fingerprint(&mesh);
            r
        });
        Ok(Remeshed {
            mesh,
            report,
            progressive,
        })
    }
}

/// `work()`, with a panic turned into [`Error::Internal`] (the runner already reports a
/// stage's own panics as that stage's error).
fn catching<T>(work: impl FnOnce() -> Result<T, Error>) -> Result<T, Error> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)).unwrap_or_else(|payload| {
        Err(Error::Internal(coarsen_pipeline::panic_message(
            payload.as_ref(),
        )))
    })
}

/// The record the pipeline's last collapse stage handed back; an error when a later stage
/// changed the mesh it describes.
fn take_record(
    pipeline: &Pipeline,
    slot: Mutex<Option<coarsen_stage::Handback>>,
    out: &Mesh,
) -> Result<coarsen_lod::Progressive, Error> {
    let (index, kind) = pipeline
        .recording_stage()
        .ok_or_else(|| Error::Internal("no stage records its collapses".into()))?;
    let handed = slot.into_inner().unwrap_or_else(|e| e.into_inner());
    let record = handed
        .and_then(|b| b.downcast::<coarsen_lod::Progressive>().ok())
        .ok_or_else(|| {
            Error::Internal(format!(
                "stage {} `{kind}` handed back no progressive record",
                index + 1
            ))
        })?;
    if record.coarse != coarsen_collapse::fingerprint(out) {
        return Err(Error::RecordNotOfOutput {
            index: index + 1,
            kind,
            later: pipeline.stages[index + 1..]
                .iter()
                .map(|s| format!("`{}`", s.kind))
                .collect::<Vec<_>>()
                .join(", "),
        });
    }
    Ok(*record)
}
