//! The stage API of coarsen: the [`Stage`] trait every pipeline step implements, the
//! parameter and contract types a stage declares, and the [`Registry`] that finds stages
//! by kind name.
//!
//! # Writing a stage
//!
//! A stage is a struct built from its parameters. Its parameters are declared with
//! [`params!`], which derives serde (unknown keys rejected, every field defaulted) and keeps
//! each field's doc line for `coarsen stages`:
//!
//! ```
//! use coarsen_stage::{params, Contract, Context, Stage, StageError};
//! use coarsen_mesh::Mesh;
//!
//! params! {
//!     /// Parameters of `scale`.
//!     pub struct ScaleParams {
//!         /// Factor applied to every coordinate.
//!         pub factor: f64 = 2.0,
//!     }
//! }
//! impl coarsen_stage::Params for ScaleParams {}
//!
//! /// Scales the mesh about the origin.
//! pub struct Scale(ScaleParams);
//!
//! impl Stage for Scale {
//!     type Params = ScaleParams;
//!     const KIND: &'static str = "scale";
//!     const SUMMARY: &'static str = "Scale every coordinate by a factor.";
//!     fn new(params: ScaleParams) -> Self { Scale(params) }
//!     fn contract(&self) -> Contract { Contract::default() }
//!     fn run(&self, mut mesh: Mesh, _cx: &mut Context<'_>) -> Result<Mesh, StageError> {
//!         mesh.positions.iter_mut().for_each(|p| *p *= self.0.factor);
//!         Ok(mesh)
//!     }
//! }
//!
//! // Makes `descriptor()` public and registers the stage at link time.
//! coarsen_stage::export_stage!(Scale);
//! # fn main() {
//! let reg = coarsen_stage::Registry::from_descriptors([descriptor()]);
//! assert_eq!(reg.get("scale").unwrap().summary, "Scale every coordinate by a factor.");
//! # }
//! ```
//!
//! A stage does no I/O, touches no terminal and uses no unseeded randomness: it receives
//! the current mesh and a [`Context`] (the original input, the run target, a report to
//! fill, a progress sink) and returns the next mesh.
//!
//! # Registration
//!
//! [`export_stage!`] registers a stage with [`inventory`] and exports `descriptor()`. A
//! binary sees a crate's inventory records only if it names the crate (inventory
//! issues #7 and #50), so built-in stages are also listed explicitly by `coarsen-builtin`,
//! and a plug-in author's binary says `use their_stage_crate as _;`.

pub mod context;
pub mod contract;
pub mod error;
pub mod params;
pub mod registry;
pub mod shared;

pub use context::{Context, Handback, NoProgress, Progress, StageReport, Target, TargetCount};
pub use contract::{AttrRef, Contract, Needs};
pub use error::StageError;
pub use params::{FieldDoc, ParamIssue, Params};
pub use registry::{Conflict, DynStage, Registry, RegistryError, StageDescriptor};
pub use shared::Shared;

pub use coarsen_mesh::{AttrKind, AttrValues, DVec3, Domain, Mesh};

#[doc(hidden)]
pub mod __private {
    pub use inventory;
    pub use serde;
    pub use toml;

    /// What [`params!`](crate::params!) brings into the caller's scope with a glob import
    /// (a glob, so that two `params!` in one module do not clash): serde under a name
    /// that its derive's `crate = "…"` can spell without knowing what the caller calls
    /// this crate (`coarsen_stage`, or a re-export such as `coarsen::plugin`).
    pub mod scope {
        pub use serde as __coarsen_stage_serde;
    }
}

/// One step of a pipeline: takes a mesh, returns the next one.
pub trait Stage: Send + Sync + Sized + 'static {
    /// The parameter struct, as a `[[stage]]` table spells it (declare it with [`params!`]).
    type Params: Params;
    /// The kind name pipelines use, e.g. `refine.red-green`.
    const KIND: &'static str;
    /// One line saying what the stage does.
    const SUMMARY: &'static str;
    /// True for a stage that collapses and hands its progressive record back through
    /// [`Context::progressive`] when asked.
    const RECORDS_COLLAPSES: bool = false;
    /// Builds the stage from parameters that passed [`Params::validate`].
    fn new(params: Self::Params) -> Self;
    /// What the stage reads, writes and needs; checked before any mesh is loaded.
    fn contract(&self) -> Contract;
    /// Runs the stage on `mesh`.
    fn run(&self, mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError>;
}

/// Registers a [`Stage`] at link time and exports `pub fn descriptor() -> StageDescriptor`
/// from the calling crate, so that a built-in list can also name it explicitly.
#[macro_export]
macro_rules! export_stage {
    ($stage:ty) => {
        /// The registry record of this crate's stage.
        pub fn descriptor() -> $crate::StageDescriptor {
            $crate::StageDescriptor::of::<$stage>(env!("CARGO_PKG_NAME"))
        }
        $crate::__private::inventory::submit! {
            $crate::registry::Registration(descriptor)
        }
    };
}
