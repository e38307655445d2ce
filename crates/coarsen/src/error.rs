//! The one error type of the facade.

use coarsen_pipeline::{Diagnostics, RunError};

/// Why a call of the facade failed.
///
/// [`Error::is_usage`] sorts the errors by who must act: a bad pipeline, parameter or
/// request (the caller) or a bad file, a bad mesh or a failed run.
///
/// ```
/// let e = coarsen::Remesher::new()
///     .set("cluster.cvt.no_such_parameter", "1")
///     .check()
///     .unwrap_err();
/// assert!(e.is_usage());
/// assert!(e.to_string().contains("no_such_parameter"));
/// ```
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A mesh file could not be read or written (the message names the file and, where
    /// there is one, the line or element).
    #[error(transparent)]
    Io(#[from] coarsen_io::IoError),
    /// The input mesh cannot be used: bad indices, non-finite coordinates, or no face left
    /// after the clean-up.
    #[error("{name}: {message}")]
    Input {
        /// The input's name (its file, or what the caller called it).
        name: String,
        /// What is wrong.
        message: String,
    },
    /// Arrays given for a mesh have the wrong shape or values out of range.
    #[error("{0}")]
    Arrays(String),
    /// No pipeline file and no shipped pipeline has this name.
    #[error("no pipeline file `{name}` and no shipped pipeline of that name (shipped: {shipped})")]
    UnknownPipeline {
        /// The name or path asked for.
        name: String,
        /// The shipped pipelines' names, comma-separated.
        shipped: String,
    },
    /// The pipeline file or its overrides have problems, every one found before any work.
    #[error("pipeline has errors:\n{0}")]
    Pipeline(#[from] Diagnostics),
    /// A parameter override is not `STAGE.PARAM=VALUE`.
    #[error("{0}")]
    Set(String),
    /// A progressive record was asked for from a pipeline without a collapse stage.
    #[error(
        "a progressive record needs a stage that records its collapses (simplify.qem, simplify.svec), but pipeline `{pipeline}` has none (stages: {stages})"
    )]
    NoRecordingStage {
        /// The pipeline's name.
        pipeline: String,
        /// Its stages, `a → b → c`.
        stages: String,
    },
    /// The progressive record does not describe the output, because a stage after the
    /// collapse stage changed the mesh.
    #[error(
        "the progressive record of stage {index} `{kind}` does not describe the run's output, because a later stage ({later}) changed the mesh; end the pipeline with the collapse stage"
    )]
    RecordNotOfOutput {
        /// 1-based position of the collapse stage.
        index: usize,
        /// Its kind.
        kind: &'static str,
        /// The later stages, quoted and comma-separated.
        later: String,
    },
    /// A stage failed, the run was cancelled, or a stage broke an invariant.
    #[error(transparent)]
    Run(#[from] RunError),
    /// The measurement of a mesh failed.
    #[error(transparent)]
    Metrics(#[from] coarsen_metrics::MetricsError),
    /// A bug in coarsen outside any stage (a stage's own panics are [`RunError::Panicked`]).
    #[error("internal error (a bug in coarsen; please report it with the input): {0}")]
    Internal(String),
}

impl Error {
    /// True for errors of the request itself: an unknown or invalid pipeline, a bad
    /// parameter or override, arrays of the wrong shape. The command line exits with 2 for
    /// these and 1 for the others.
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            Error::UnknownPipeline { .. }
                | Error::Pipeline(_)
                | Error::Set(_)
                | Error::NoRecordingStage { .. }
                | Error::Arrays(_)
        )
    }

    /// True when the run stopped because it was cancelled.
    pub fn is_cancelled(&self) -> bool {
        matches!(self, Error::Run(RunError::Cancelled { .. }))
    }
}
