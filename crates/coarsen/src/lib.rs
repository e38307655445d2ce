//! coarsen turns big, badly shaped triangle meshes (3-D scans, CAD tessellations) into
//! small ones that are well shaped and stay close to the original.
//!
//! This crate is the door for Rust programs: the same clean-up, pipelines and output as
//! the `coarsen` command, byte for byte (the command is a thin client of it).
//!
//! # One call
//!
//! ```no_run
//! let mesh = coarsen::read("bunny.ply")?;
//! let (out, report) = coarsen::remesh(&mesh, coarsen::Target::Vertices(5000))?;
//! coarsen::write("bunny-5k.ply", &out)?;
//! println!("{}", report.summary());
//! # Ok::<(), coarsen::Error>(())
//! ```
//!
//! # Any pipeline, with parameters, progress and cancellation
//!
//! A [`Remesher`] names a shipped pipeline ([`pipelines`]) or a pipeline file, a
//! [`Target`], parameter overrides (`STAGE.PARAM`, as the command line's `--set`), a
//! progress sink and a cancel flag. The whole pipeline is checked before the mesh is
//! touched; every problem comes back at once in one [`Error`].
//!
//! ```
//! let mesh = coarsen::mesh_from_arrays(
//!     coarsen::demo().positions.iter().map(|p| p.to_array()).collect(),
//!     coarsen::demo().faces.clone(),
//! )?;
//! let (out, report) = coarsen::Remesher::new()
//!     .pipeline("qem")
//!     .target(coarsen::Target::Ratio(0.9))
//!     .set("simplify.qem.min_quality", "0.2")
//!     .run(&mesh)?;
//! assert!(out.n_faces() <= mesh.n_faces() / 10 + 2);
//! println!("{}", report.to_json());
//! # Ok::<(), coarsen::Error>(())
//! ```
//!
//! # Measuring
//!
//! [`metrics`] gives the figures of `coarsen metrics`: shape quality, Hausdorff and mean
//! distances, validity.
//!
//! # Writing stages
//!
//! A stage of your own implements [`plugin::Stage`]; linking its crate into a program
//! registers it, and pipelines name it by its kind (`docs/writing-a-stage.md`).

mod error;
mod input;
mod remesh;

pub use error::Error;
pub use input::{Cleaned, Input, clean, demo, mesh_from_arrays, open, read, write, write_with};
pub use remesh::{DEFAULT_PIPELINE, Remeshed, Remesher, registry, remesh};

pub use coarsen_io::{Format, PlyEncoding, ReadOptions, WriteOptions};
pub use coarsen_mesh::{DVec3, Index, Mesh};
pub use coarsen_metrics::{MetricsOptions, MetricsReport};
pub use coarsen_pipeline::{Pipeline, RunError, RunReport as Report, StageRecord};
pub use coarsen_stage::{Progress, Target};

/// Levels of detail: a collapse pipeline's progressive record
/// ([`Remesher::progressive`]) rebuilds any level between its output and its input by
/// undoing collapses.
///
/// ```
/// let done = coarsen::Remesher::new()
///     .pipeline("qem")
///     .target(coarsen::Target::Vertices(2000))
///     .progressive(true)
///     .run_input(coarsen::Input::demo())?;
/// let record = done.progressive.expect("asked for");
/// let level = coarsen::lod::level_with_vertices(&record, 5000).unwrap();
/// let finer = coarsen::lod::rebuild(&done.mesh, &record, level).unwrap();
/// assert_eq!(finer.n_vertices(), 5000);
/// # Ok::<(), coarsen::Error>(())
/// ```
pub mod lod {
    pub use coarsen_lod::{
        LodError, Progressive, level_vertices, level_with_vertices, levels, read, rebuild, write,
    };
}

/// What a stage crate needs: the [`Stage`](plugin::Stage) trait, its parameter and
/// contract types, and the macros that declare parameters and register a stage.
pub mod plugin {
    pub use coarsen_mesh::{Aabb, Attributes, CarryReport, FaceOrigins, VertexOrigins};
    pub use coarsen_stage::params::{check_finite_min, check_range};
    pub use coarsen_stage::{
        AttrKind, AttrRef, AttrValues, Context, Contract, DVec3, Domain, Mesh, Needs, ParamIssue,
        Params, Stage, StageError, StageReport, Target, export_stage, params,
    };
}

/// One shipped pipeline.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PipelineInfo {
    /// The name [`Remesher::pipeline`] and `coarsen run NAME` take.
    pub name: &'static str,
    /// What it does (its file's `description`).
    pub description: String,
    /// The pipeline file's text.
    pub text: &'static str,
}

/// The shipped pipelines (`pipelines/*.toml`), by name.
///
/// ```
/// let names: Vec<_> = coarsen::pipelines().iter().map(|p| p.name).collect();
/// assert!(names.contains(&coarsen::DEFAULT_PIPELINE) && names.contains(&"qem"));
/// ```
pub fn pipelines() -> Vec<PipelineInfo> {
    coarsen_builtin::PIPELINES
        .iter()
        .map(|&(name, text)| PipelineInfo {
            name,
            description: toml::from_str::<toml::Table>(text)
                .ok()
                .and_then(|t| {
                    t.get("pipeline")?
                        .get("description")?
                        .as_str()
                        .map(|d| d.split_whitespace().collect::<Vec<_>>().join(" "))
                })
                .unwrap_or_default(),
            text,
        })
        .collect()
}

/// One registered stage, as `coarsen stages` lists it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StageInfo {
    /// The kind name pipeline files use.
    pub kind: &'static str,
    /// One line saying what it does.
    pub summary: &'static str,
    /// The package that provides it.
    pub crate_name: &'static str,
    /// Its parameters, in declaration order.
    pub params: Vec<ParamInfo>,
}

/// One parameter of a stage.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParamInfo {
    /// The key a pipeline file uses.
    pub name: &'static str,
    /// Its Rust type.
    pub ty: &'static str,
    /// Its default as TOML, if it has one.
    pub default: Option<String>,
    /// What it means (its doc comment on one line).
    pub doc: String,
}

/// Every registered stage (built-in and linked), sorted by kind, with its parameters.
///
/// ```
/// let stages = coarsen::stages()?;
/// let relax = stages.iter().find(|s| s.kind == "relax").unwrap();
/// assert!(relax.params.iter().any(|p| p.name == "sweeps"));
/// # Ok::<(), coarsen::Error>(())
/// ```
pub fn stages() -> Result<Vec<StageInfo>, Error> {
    let registry = registry();
    Ok(registry
        .iter()
        .map(|d| {
            let defaults = (d.defaults)();
            StageInfo {
                kind: d.kind,
                summary: d.summary,
                crate_name: d.crate_name,
                params: (d.fields)()
                    .iter()
                    .map(|f| ParamInfo {
                        name: f.name,
                        ty: f.ty,
                        default: defaults.get(f.name).map(|v| v.to_string()),
                        doc: f.doc.split_whitespace().collect::<Vec<_>>().join(" "),
                    })
                    .collect(),
            }
        })
        .collect())
}

/// Measures `output` against the `input` it came from, as `coarsen metrics` does: both
/// cleaned as a run's input is, then shape quality, fidelity and validity.
///
/// ```
/// let input = coarsen::demo();
/// let (output, _) = coarsen::remesh(&input, coarsen::Target::Vertices(800))?;
/// let m = coarsen::metrics(&input, &output, &Default::default())?;
/// assert!(m.quality.alpha_min_deg > 10.0);
/// assert!(m.fidelity.unwrap().hausdorff_pct < 2.0);
/// # Ok::<(), coarsen::Error>(())
/// ```
pub fn metrics(input: &Mesh, output: &Mesh, opts: &MetricsOptions) -> Result<MetricsReport, Error> {
    measure(
        Input::new(input.clone(), "input"),
        Input::new(output.clone(), "output"),
        opts,
    )
}

/// [`metrics`] of meshes read with [`open`] (an STL file's corners welded, as a run
/// welds them), named in errors by their files.
///
/// ```no_run
/// let limits = coarsen::ReadOptions::default();
/// let m = coarsen::measure(
///     coarsen::open("bunny.obj", &limits)?,
///     coarsen::open("bunny-5k.ply", &limits)?,
///     &Default::default(),
/// )?;
/// println!("{}", m.to_markdown());
/// # Ok::<(), coarsen::Error>(())
/// ```
pub fn measure(input: Input, output: Input, opts: &MetricsOptions) -> Result<MetricsReport, Error> {
    let input = clean(input, false)?;
    let output = clean(output, false)?;
    Ok(coarsen_metrics::measure(
        Some(&input.mesh),
        &output.mesh,
        opts,
    )?)
}

/// [`measure`], with each mesh's fields (`coarsen_metrics::fields`) attached to it as
/// attribute columns: the cleaned input and output, in their files' units, the distances
/// too, ready to be written as PLY for MeshLab or ParaView.
///
/// ```
/// let input = coarsen::Input::new(coarsen::demo(), "input");
/// let (output, _) = coarsen::remesh(&input.mesh, coarsen::Target::Vertices(800))?;
/// let output = coarsen::Input::new(output, "output");
/// let (m, input, output) = coarsen::measure_fields(input, output, &Default::default())?;
/// let distance = output.vertex_attrs.scalar("quality").unwrap();
/// assert_eq!(distance.len(), output.n_vertices());
/// assert!(input.face_attrs.scalar("min_angle").is_some() && m.fidelity.is_some());
/// # Ok::<(), coarsen::Error>(())
/// ```
pub fn measure_fields(
    input: Input,
    output: Input,
    opts: &MetricsOptions,
) -> Result<(MetricsReport, Mesh, Mesh), Error> {
    let input = clean(input, false)?;
    let output = clean(output, false)?;
    let (report, fields) = coarsen_metrics::measure_with_fields(&input.mesh, &output.mesh, opts)?;
    let with_fields = |cleaned: &Cleaned, mut f: coarsen_metrics::MeshFields| {
        // Distances are lengths: back to the file's units as the positions are.
        let unit = 2f64.powi(-cleaned.scale_exponent);
        for d in f.vertex_distance.iter_mut().chain(&mut f.face_distance) {
            *d *= unit;
        }
        let mut mesh = cleaned.restore(cleaned.mesh.clone());
        f.attach(&mut mesh);
        mesh
    };
    let (in_mesh, out_mesh) = (
        with_fields(&input, fields.input),
        with_fields(&output, fields.output),
    );
    Ok((report, in_mesh, out_mesh))
}
