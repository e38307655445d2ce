//! Pipeline files and the runner.
//!
//! A pipeline file is TOML: a `[pipeline]` header and `[[stage]]` tables, each with a
//! `kind` and that stage's parameters (format: `docs/pipelines.md`). [`Pipeline::parse`]
//! checks the whole file before any mesh is loaded — unknown kinds, unknown or mistyped
//! parameters, out-of-range values, attributes read before anything writes them, a missing
//! target — and reports every problem at once with `file:line:column`. [`Pipeline::run`]
//! then runs the stages in order and returns the mesh and a [`RunReport`].
//!
//! Only this crate knows the pipeline file format.

mod check;
mod file;
mod report;
mod run;

pub use file::{Overrides, Pipeline, PipelineStage, SetOverride, parse_set};
pub use report::{RunReport, StageRecord};
pub use run::{
    AfterStage, CUT_EDGES_NOTE, REORDER_MIN_FACES, RunError, RunOptions, SPLIT_FANS_NOTE,
    panic_message,
};

use std::fmt;

/// One problem found in a pipeline file or its command-line overrides.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Diagnostic {
    /// Where: `file:line:column`, or the command-line option to blame.
    pub origin: String,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.origin, self.message)
    }
}

/// Every problem of a pipeline file, found before anything ran.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}", self.0.iter().map(|d| d.to_string()).collect::<Vec<_>>().join("\n"))]
pub struct Diagnostics(pub Vec<Diagnostic>);

#[cfg(test)]
mod tests;
