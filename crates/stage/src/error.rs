//! Errors a stage returns at run time.

/// Why a stage failed, sorted by who must act.
#[derive(Debug, thiserror::Error)]
pub enum StageError {
    /// The mesh is not something this stage can work on (the user must act).
    #[error("{0}")]
    Input(String),
    /// A parameter value that is valid on its own but cannot work with this mesh.
    #[error("parameter `{name}`: {message}")]
    Param {
        /// The parameter.
        name: &'static str,
        /// What is wrong.
        message: String,
    },
    /// An invariant the stage relies on was broken: a bug in coarsen.
    #[error("internal error (a bug in coarsen; please report it with the input): {0}")]
    Internal(String),
}
