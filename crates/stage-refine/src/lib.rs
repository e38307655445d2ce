//! The `refine.red-green` stage: adaptive red-green refinement (Shu, Wang & Dong 2009,
//! "Adaptive refinement"), splitting triangles where a curvature field is high until the
//! triangle density follows it.
//!
//! # What one pass does
//!
//! 1. **Criterion.** Per triangle D(t) = (F(v₁) + F(v₂) + F(v₃))/3, with F the vertex scalar
//!    named by `field` (the `curvature` stage's `hybrid_curvature` by default). Over the m
//!    triangles: mean D̄, sample standard deviation D̃ (m − 1), the truncation range
//!    D̄ ± 2D̃, and the threshold δ = D̄ + α·D̃. With α < 2, δ lies inside the truncation
//!    range, so truncating D alone changes no colour (the range is reported and scales
//!    the colour output); `truncated_statistics = true` recomputes D̄ and D̃ from the
//!    truncated values first, so that a few extreme values (scan noise) do not raise δ.
//! 2. **Red-green marking.** Triangles with D(t) > δ are red: every edge of a red triangle
//!    is split at its midpoint. Every other triangle is green and is split by how many of
//!    its edges are split, i.e. by its number of red edge-neighbours: 0 → unchanged,
//!    1 → bisected, 2 → three triangles (the remaining quadrilateral cut along the diagonal
//!    with the better worst shape), 3 → 1-to-4. A green triangle never marks an edge
//!    itself, so the closure is immediate and the result is conforming (no T-junctions):
//!    every split edge is split in all of its faces. Boundary edges split into two boundary
//!    edges, so boundary loops, genus, manifoldness and orientation are those of the input.
//! 3. **Area guard.** No pass creates a degenerate triangle: a red candidate is dropped
//!    (and counted as `refused`) when it, or a triangle across one of its edges, has less
//!    than 8·10⁻¹² of the squared bounding-box diagonal in area — its smallest child would
//!    then fall near the `sanity_check` threshold (10⁻¹²). Children are at least a quarter
//!    of their parent.
//! 4. **Carrying.** The new mesh is built by `Mesh::rebuilt`: a midpoint takes the mean of
//!    its edge's ends for every vertex attribute (so F stays that of the input surface, as
//!    the spec rules), child faces inherit their parent's face attributes.
//!
//! # Passes and the stopping rule
//!
//! A₁ = triangles with D(t) > D̄, A₂ = the rest, τ(A) = n(A)/s(A) triangles per unit area,
//! λ = τ(A₁)/τ(A₂). Passes repeat while λ < β (`beta`), at most `max_passes` times, and never
//! when the pass would take the face count above `max_faces` (predicted exactly before the
//! pass).
//!
//! What is recomputed between passes (paper 1 leaves it open; decided here, measured on
//! the bunny with the `curvature` stage's F):
//!
//! * **F** is estimated once, on the input, and carried to midpoints (the spec's ruling);
//!   `recompute_curvature = true` re-estimates it on the refined mesh after every pass.
//! * **D̄, D̃ and δ are recomputed at every pass** on the current mesh: paper 1 repeats
//!   "the adaptive refinement operation on M", statistics included. As curved regions gain
//!   triangles, δ rises, so each pass splits a narrower band of the most curved triangles
//!   and the density grades with the curvature.
//! * **The A₁/A₂ split of λ keeps the input's D̄.** A₁ is where the *surface* is more curved
//!   than average, which carrying F keeps fixed. Splitting at the current mesh's D̄ instead
//!   makes λ chase the refinement: D̄ is a per-triangle mean, so every pass pulls it up
//!   towards the triangles just split, A₁ shrinks onto them and λ inflates (on the bunny
//!   2.7 after one pass, 118 after four, for a face count that only triples), whereas with
//!   the input's D̄ λ goes 1.0 → 1.85 → 3.2 → 5.1, and the bunny needs two passes, as in
//!   paper 1's Fig. 3 ("applied twice").
//!
//! | parameter | default | meaning |
//! | --- | --- | --- |
//! | `field` | `"hybrid_curvature"` | vertex scalar F driving the refinement |
//! | `alpha` | `0.8` | δ = D̄ + α·D̃ (paper 1) |
//! | `beta` | `2` | stop once λ ≥ β (paper 1) |
//! | `max_passes` | `6` | at most this many passes |
//! | `max_faces` | `8000000` | never start a pass that would exceed this face count |
//! | `truncated_statistics` | `false` | take D̄, D̃ (for δ and λ) from the truncated D |
//! | `recompute_curvature` | `false` | re-estimate K, H, F after every pass instead of carrying F |
//! | `color` | `false` | also write F as the vertex colour `color` (viridis, see [`color`]) |
//!
//! `recompute_curvature` runs the `curvature` stage's estimator with its defaults and
//! rewrites its three columns. Beware that midpoint refinement keeps the surface piecewise
//! flat: a midpoint lies on a straight edge, so its angle deficit and K are 0, while an old
//! vertex keeps its deficit over a smaller area, so the recomputed field sharpens at the
//! input's vertices pass after pass. That is why carrying is the default.
//!
//! The report gives `passes`, why the run `stop`ped, λ, τ(A₁) and τ(A₂) before
//! (`lambda_in`, `tau_a1_in`, `tau_a2_in`) and after (`lambda`, `tau_a1`, `tau_a2`), the input's
//! statistics (`d_mean`, `d_std`, `delta`, `truncation`), the face and vertex counts, and
//! `pass_table`: one row per pass with its statistics, red, refused and green counts (by
//! number of red neighbours), face and vertex counts and λ after it. Stopping before λ ≥ β
//! is a warning that says why.
//!
//! ```
//! use coarsen_stage::{AttrValues, Context, Stage, StageReport};
//! use coarsen_stage_refine::{RefineParams, RefineRedGreen};
//! let mut grid = coarsen_shapes::plane_grid(8, 8, 1.0).unwrap();
//! // A field that is high near the corner x = y = 0.5 only.
//! let f = grid.positions.iter().map(|p| (-20.0 * (p.x - 0.5).powi(2) - 20.0 * (p.y - 0.5).powi(2)).exp()).collect();
//! grid.vertex_attrs.insert("hybrid_curvature", AttrValues::Scalar(f));
//! let mut report = StageReport::default();
//! let mut cx = Context::new(&grid, &mut report);
//! let out = RefineRedGreen::new(RefineParams::default()).run(grid.clone(), &mut cx)?;
//! assert!(out.n_faces() > grid.n_faces());
//! assert!(report.get("lambda").unwrap().as_f64().unwrap() >= 2.0);
//! # Ok::<(), coarsen_stage::StageError>(())
//! ```

pub mod color;
mod split;
mod stats;

pub use split::SplitCounts;
pub use stats::{Criterion, Density};

use coarsen_mesh::sanity::DEGENERATE_AREA_REL;
use coarsen_mesh::topology::MAX_FACES;
use coarsen_mesh::{CarryReport, IndexError};
use coarsen_stage::params::check_range;
use coarsen_stage::{
    AttrKind, AttrRef, AttrValues, Context, Contract, Mesh, ParamIssue, Params, Stage, StageError,
    StageReport, params,
};
use coarsen_stage_curvature::{CurvatureError, CurvatureParams, GAUSSIAN, HYBRID, MEAN};
use serde::Serialize;
use split::{EdgeTable, Plan};

/// The vertex columns the `curvature` stage writes (and `recompute_curvature` rewrites).
const CURVATURE_COLUMNS: [&str; 3] = [HYBRID, GAUSSIAN, MEAN];

params! {
    /// Parameters of `refine.red-green`.
    pub struct RefineParams {
        /// Vertex scalar attribute F that drives the refinement (the `curvature` stage writes
        /// `hybrid_curvature`, `gaussian_curvature` and `mean_curvature`).
        pub field: String = "hybrid_curvature".to_string(),
        /// α in the red threshold δ = D̄ + α·D̃ (paper 1: 0.8).
        pub alpha: f64 = 0.8,
        /// Stop once λ = τ(A₁)/τ(A₂) reaches β (paper 1: 2).
        pub beta: f64 = 2.0,
        /// At most this many refinement passes.
        pub max_passes: u32 = 6,
        /// Never start a pass that would take the face count above this.
        pub max_faces: u64 = 8_000_000,
        /// Compute D̄ and D̃ for δ and λ from the truncated D (else, as the spec orders it,
        /// from the raw D, when truncation changes nothing for α < 2).
        pub truncated_statistics: bool = false,
        /// Re-estimate the curvature (the `curvature` stage's defaults: Meyer, signed K,
        /// boundary from the neighbours) on the refined mesh after every pass, instead of
        /// carrying F to the midpoints; `field` must then be one of its three columns.
        pub recompute_curvature: bool = false,
        /// Also write F as the per-vertex colour `color` (viridis over the input's D̄ ± 2D̃:
        /// dark violet low, yellow high), which PLY writes as `red green blue`.
        pub color: bool = false,
    }
}

impl Params for RefineParams {
    fn validate(&self) -> Vec<ParamIssue> {
        let mut issues = Vec::new();
        if self.field.is_empty() {
            issues.push(ParamIssue::new(
                "field",
                "must name a vertex scalar attribute",
            ));
        } else if self.recompute_curvature && !CURVATURE_COLUMNS.contains(&self.field.as_str()) {
            issues.push(ParamIssue::new(
                "field",
                format!(
                    "with recompute_curvature, must be one of the `curvature` stage's columns ({}), got `{}`",
                    CURVATURE_COLUMNS.join(", "),
                    self.field
                ),
            ));
        }
        check_range(&mut issues, "alpha", self.alpha, 0.0, 1e6);
        check_range(&mut issues, "beta", self.beta, 0.0, 1e6);
        check_range(&mut issues, "max_passes", self.max_passes, 0, 64);
        check_range(
            &mut issues,
            "max_faces",
            self.max_faces,
            1,
            MAX_FACES as u64,
        );
        issues
    }
}

/// Why the refiner cannot work on a mesh; every variant names the offending element.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RefineError {
    /// An index out of range or a column of the wrong length.
    #[error(transparent)]
    Index(#[from] IndexError),
    /// A vertex position with a NaN or infinite coordinate.
    #[error("vertex {vertex} has a non-finite position")]
    NonFinitePosition {
        /// The vertex.
        vertex: usize,
    },
    /// A face naming the same vertex twice (load-time hygiene removes these).
    #[error("face {face} repeats vertex {vertex}")]
    RepeatedIndex {
        /// The face.
        face: usize,
        /// The repeated vertex.
        vertex: u32,
    },
    /// The field attribute does not exist.
    #[error(
        "vertex scalar attribute `{name}` is missing (run the `curvature` stage first, or name another with `field`); the mesh has {available}"
    )]
    MissingField {
        /// The attribute named by `field`.
        name: String,
        /// The vertex attributes the mesh has, for the message.
        available: String,
    },
    /// The field attribute exists but is not a scalar.
    #[error("vertex attribute `{name}` holds {kind} values, not scalars")]
    FieldNotScalar {
        /// The attribute.
        name: String,
        /// What it holds.
        kind: AttrKind,
    },
    /// A NaN or infinite field value.
    #[error("vertex attribute `{name}` is not finite at vertex {vertex}")]
    NonFiniteField {
        /// The attribute.
        name: String,
        /// The vertex.
        vertex: usize,
    },
    /// Re-estimating the curvature on the refined mesh failed.
    #[error("re-estimating the curvature after a pass: {0}")]
    Curvature(#[from] CurvatureError),
    /// An invariant of the refiner was broken: a bug in coarsen.
    #[error("{0}")]
    Internal(String),
    /// The split would make more faces or vertices than the adjacency tables address.
    #[error(
        "the split would make {faces} faces and {vertices} vertices, beyond 32-bit adjacency tables"
    )]
    TooLarge {
        /// Faces after the split.
        faces: usize,
        /// Vertices after the split.
        vertices: usize,
    },
    /// A red mask whose length is not the face count.
    #[error("{len} red flags for {faces} faces")]
    RedLength {
        /// Length of the mask.
        len: usize,
        /// Faces of the mesh.
        faces: usize,
    },
}

/// Why the passes ended.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "reason")]
pub enum StopReason {
    /// λ reached β.
    Reached,
    /// `max_passes` passes were made.
    MaxPasses,
    /// The next pass would have made `would_be` faces, above `max_faces`.
    MaxFaces {
        /// Faces the next pass would have made.
        would_be: usize,
    },
    /// The next pass would have made more vertices than 32-bit indices address.
    IndexLimit,
    /// No triangle was red (or every red one was refused by the area guard).
    NoRed,
    /// λ is undefined: the field is constant over the faces (or A₁ has no area).
    Constant,
    /// The mesh has no face.
    Empty,
}

impl StopReason {
    /// The short name the report uses.
    pub fn name(&self) -> &'static str {
        match self {
            StopReason::Reached => "reached",
            StopReason::MaxPasses => "max_passes",
            StopReason::MaxFaces { .. } => "max_faces",
            StopReason::IndexLimit => "index_limit",
            StopReason::NoRed => "no_red",
            StopReason::Constant => "constant",
            StopReason::Empty => "empty",
        }
    }
}

/// One refinement pass as the report lists it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PassRecord {
    /// Pass number, from 1.
    pub pass: u32,
    /// D̄ on the mesh the pass started from.
    pub d_mean: f64,
    /// D̃ on the mesh the pass started from.
    pub d_std: f64,
    /// δ = D̄ + α·D̃ of the pass.
    pub delta: f64,
    /// Red triangles (split 1-to-4).
    pub red: usize,
    /// Red candidates dropped by the area guard.
    pub refused: usize,
    /// Green triangles with one red neighbour (bisected).
    pub green_1: usize,
    /// Green triangles with two red neighbours (split into three).
    pub green_2: usize,
    /// Green triangles with three red neighbours (split 1-to-4).
    pub green_3: usize,
    /// Faces after the pass.
    pub faces: usize,
    /// Vertices after the pass.
    pub vertices: usize,
    /// λ after the pass (`None` when undefined).
    pub lambda: Option<f64>,
}

/// What a refinement run did.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// One record per pass made.
    pub passes: Vec<PassRecord>,
    /// Why the passes ended.
    pub stop: StopReason,
    /// D statistics of the input mesh.
    pub input: Criterion,
    /// A₁/A₂ densities of the input.
    pub before: Density,
    /// A₁/A₂ densities of the result.
    pub after: Density,
    /// Attribute columns that could not be carried (one line each).
    pub carry_warnings: Vec<String>,
}

/// The criterion of the current mesh: D per face, face areas, statistics, densities.
struct Measure {
    d: Vec<f64>,
    areas: Vec<f64>,
    criterion: Criterion,
    density: Density,
}

impl Measure {
    /// Measures `mesh` with the vertex field `field`; A₁ is the faces whose D exceeds
    /// `split_at` (the input's D̄), or this mesh's own D̄ when `None` (the input itself).
    fn new(mesh: &Mesh, field: &[f64], p: &RefineParams, split_at: Option<f64>) -> Measure {
        let d = stats::face_values(mesh, field);
        let areas: Vec<f64> = (0..mesh.n_faces()).map(|f| mesh.face_area(f)).collect();
        let criterion = Criterion::new(&d, p.alpha, p.truncated_statistics);
        let density = Density::new(&d, &areas, split_at.unwrap_or(criterion.mean));
        Measure {
            d,
            areas,
            criterion,
            density,
        }
    }
}

/// Checks what a split relies on: indices in range, finite positions, no repeated index.
fn check_mesh(mesh: &Mesh) -> Result<(), RefineError> {
    mesh.validate_indices()?;
    if let Some(vertex) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(RefineError::NonFinitePosition { vertex });
    }
    for (face, f) in mesh.faces.iter().enumerate() {
        if f[0] == f[1] || f[0] == f[2] {
            return Err(RefineError::RepeatedIndex { face, vertex: f[0] });
        }
        if f[1] == f[2] {
            return Err(RefineError::RepeatedIndex { face, vertex: f[1] });
        }
    }
    Ok(())
}

/// Checks the mesh and the field column, and returns the column.
fn check_input<'m>(mesh: &'m Mesh, field: &str) -> Result<&'m [f64], RefineError> {
    check_mesh(mesh)?;
    let values = field_values(mesh, field)?;
    if let Some(vertex) = values.iter().position(|x| !x.is_finite()) {
        return Err(RefineError::NonFiniteField {
            name: field.to_string(),
            vertex,
        });
    }
    Ok(values)
}

/// The scalar column `field` of `mesh`.
fn field_values<'m>(mesh: &'m Mesh, field: &str) -> Result<&'m [f64], RefineError> {
    match mesh.vertex_attrs.get(field) {
        Some(AttrValues::Scalar(v)) => Ok(v),
        Some(other) => Err(RefineError::FieldNotScalar {
            name: field.to_string(),
            kind: other.kind(),
        }),
        None => {
            let names: Vec<String> = mesh
                .vertex_attrs
                .iter()
                .map(|(n, v)| format!("{} `{n}`", v.kind()))
                .collect();
            Err(RefineError::MissingField {
                name: field.to_string(),
                available: if names.is_empty() {
                    "no vertex attribute".to_string()
                } else {
                    format!("vertex attributes {}", names.join(", "))
                },
            })
        }
    }
}

/// Smallest area of a triangle that may be split: its smallest child (a quarter) then keeps
/// twice the `sanity_check` degenerate threshold of `mesh`'s bounding box.
fn min_split_area(mesh: &Mesh) -> f64 {
    let diag = mesh.bbox().diagonal();
    8.0 * DEGENERATE_AREA_REL * diag * diag
}

/// One red-green split of `mesh` with the faces flagged in `red` as red triangles (all
/// `true` is a uniform 1-to-4 subdivision), closed by green splits and guarded against
/// degenerate children (see the crate docs). Attributes are carried through `Mesh::rebuilt`.
pub fn split_once(
    mesh: &Mesh,
    red: &[bool],
) -> Result<(Mesh, SplitCounts, CarryReport), RefineError> {
    split_once_with(mesh, red, None)
}

/// [`split_once`], with the edges numbered by `topo` (the adjacency of `mesh`, which
/// numbers them the same way) instead of a table built for the split; the same result.
pub fn split_once_with(
    mesh: &Mesh,
    red: &[bool],
    topo: Option<&coarsen_mesh::Topology>,
) -> Result<(Mesh, SplitCounts, CarryReport), RefineError> {
    if red.len() != mesh.n_faces() {
        return Err(RefineError::RedLength {
            len: red.len(),
            faces: mesh.n_faces(),
        });
    }
    check_mesh(mesh)?;
    let splittable = splittable(mesh);
    let table = match topo.and_then(|t| EdgeTable::from_topology(mesh, t)) {
        Some(t) => t,
        None => EdgeTable::build(mesh.n_vertices(), &mesh.faces),
    };
    let plan = Plan::new(&table, mesh.n_vertices(), red, &splittable);
    apply(mesh, &table, &plan)
}

/// Per face of `mesh`, whether it may be split (see [`min_split_area`]).
fn splittable(mesh: &Mesh) -> Vec<bool> {
    let threshold = min_split_area(mesh);
    (0..mesh.n_faces())
        .map(|f| mesh.face_area(f) >= threshold)
        .collect()
}

/// Splits `mesh` as `plan` (over the edges of `table`) says, unless the result would be
/// too large for 32-bit indices; attributes carried through `Mesh::rebuilt`.
fn apply(
    mesh: &Mesh,
    table: &EdgeTable<'_>,
    plan: &Plan,
) -> Result<(Mesh, SplitCounts, CarryReport), RefineError> {
    let c = plan.counts;
    if c.faces > MAX_FACES || c.vertices >= u32::MAX as usize {
        return Err(RefineError::TooLarge {
            faces: c.faces,
            vertices: c.vertices,
        });
    }
    let s = split::split(mesh, table, plan);
    let (out, carry) = mesh.rebuilt(s.positions, s.faces, &s.vertex_origins, &s.face_origins);
    Ok((out, c, carry))
}

/// One split of `mesh`'s edges longer than `max_len` at their midpoints, closed as a
/// red-green pass is (a face splits by how many of its edges are split; no T-junction),
/// and guarded the same way: the edges of a face too small to split stay whole (counted
/// as `refused`). Attributes are carried through `Mesh::rebuilt`.
pub fn split_long_edges(
    mesh: &Mesh,
    max_len: f64,
) -> Result<(Mesh, SplitCounts, CarryReport), RefineError> {
    check_mesh(mesh)?;
    let splittable = splittable(mesh);
    let table = EdgeTable::build(mesh.n_vertices(), &mesh.faces);
    let marked: Vec<bool> = table
        .ends
        .iter()
        .map(|&[a, b]| mesh.positions[a as usize].distance(mesh.positions[b as usize]) > max_len)
        .collect();
    let plan = Plan::of_edges(&table, mesh.n_vertices(), marked, &splittable);
    apply(mesh, &table, &plan)
}

/// Refines `mesh` by red-green passes driven by the vertex scalar `params.field` until the
/// stopping rule holds (see the crate docs). Returns the refined mesh and what was done.
pub fn refine(mesh: Mesh, params: &RefineParams) -> Result<(Mesh, Outcome), RefineError> {
    refine_with(mesh, params, None, &mut |_| {})
}

/// [`refine`], numbering the first pass's edges by `topo` (the adjacency of `mesh`, when at
/// hand; the same numbering) and calling `on_pass` after every pass (for progress display).
pub fn refine_with(
    mesh: Mesh,
    params: &RefineParams,
    mut topo: Option<&coarsen_mesh::Topology>,
    on_pass: &mut dyn FnMut(&PassRecord),
) -> Result<(Mesh, Outcome), RefineError> {
    let p = params;
    let field = check_input(&mesh, &p.field)?;
    let threshold = min_split_area(&mesh);
    let mut state = Measure::new(&mesh, field, p, None);
    let (input, before) = (state.criterion, state.density);
    let mut mesh = mesh;
    let mut passes = Vec::new();
    let mut carry_warnings = Vec::new();
    let max_faces = usize::try_from(p.max_faces).map_or(MAX_FACES, |m| m.min(MAX_FACES));
    let stop = loop {
        if mesh.n_faces() == 0 {
            break StopReason::Empty;
        }
        match state.density.lambda() {
            None => break StopReason::Constant,
            Some(l) if l >= p.beta => break StopReason::Reached,
            Some(_) => {}
        }
        if passes.len() >= p.max_passes as usize {
            break StopReason::MaxPasses;
        }
        let delta = state.criterion.delta;
        let candidates: Vec<bool> = state.d.iter().map(|&d| d > delta).collect();
        let splittable: Vec<bool> = state.areas.iter().map(|&a| a >= threshold).collect();
        let table = match topo.take().and_then(|t| EdgeTable::from_topology(&mesh, t)) {
            Some(t) => t,
            None => EdgeTable::build(mesh.n_vertices(), &mesh.faces),
        };
        let plan = Plan::new(&table, mesh.n_vertices(), &candidates, &splittable);
        let c = plan.counts;
        if c.red == 0 {
            break StopReason::NoRed;
        }
        if c.faces > max_faces {
            break StopReason::MaxFaces { would_be: c.faces };
        }
        if c.vertices >= u32::MAX as usize {
            break StopReason::IndexLimit;
        }
        let s = split::split(&mesh, &table, &plan);
        let (mut next, carry) =
            mesh.rebuilt(s.positions, s.faces, &s.vertex_origins, &s.face_origins);
        carry_warnings.extend(carry.warnings());
        if p.recompute_curvature {
            let e = coarsen_stage_curvature::estimate(&next, &CurvatureParams::default())?;
            let attrs = &mut next.vertex_attrs;
            attrs.insert(HYBRID, AttrValues::Scalar(e.hybrid));
            attrs.insert(GAUSSIAN, AttrValues::Scalar(e.gaussian));
            attrs.insert(MEAN, AttrValues::Scalar(e.mean));
        }
        let field = field_values(&next, &p.field).map_err(|e| {
            RefineError::Internal(format!("the field was not carried through a split: {e}"))
        })?;
        let next_state = Measure::new(&next, field, p, Some(input.mean));
        passes.push(PassRecord {
            pass: passes.len() as u32 + 1,
            d_mean: state.criterion.mean,
            d_std: state.criterion.std,
            delta,
            red: c.red,
            refused: c.refused,
            green_1: c.green[0],
            green_2: c.green[1],
            green_3: c.green[2],
            faces: next.n_faces(),
            vertices: next.n_vertices(),
            lambda: next_state.density.lambda(),
        });
        if let Some(record) = passes.last() {
            on_pass(record);
        }
        mesh = next;
        state = next_state;
    };
    let outcome = Outcome {
        passes,
        stop,
        input,
        before,
        after: state.density,
        carry_warnings,
    };
    if p.color {
        let f = field_values(&mesh, &p.field)?;
        let colors = color::colorize(f, input.low, input.high);
        mesh.vertex_attrs.insert("color", AttrValues::Color(colors));
    }
    Ok((mesh, outcome))
}

/// Adaptive red-green refinement driven by a vertex curvature field (paper 1).
pub struct RefineRedGreen(RefineParams);

impl Stage for RefineRedGreen {
    type Params = RefineParams;
    const KIND: &'static str = "refine.red-green";
    const SUMMARY: &'static str = "Adaptive red-green refinement: split triangles where a curvature field is high until the triangle density follows it (paper 1).";

    fn new(params: RefineParams) -> Self {
        RefineRedGreen(params)
    }

    fn contract(&self) -> Contract {
        Contract {
            reads: vec![AttrRef::vertex(self.0.field.clone(), AttrKind::Scalar)],
            writes: self
                .0
                .recompute_curvature
                .then_some(CURVATURE_COLUMNS)
                .into_iter()
                .flatten()
                .map(|name| AttrRef::vertex(name, AttrKind::Scalar))
                .chain(
                    self.0
                        .color
                        .then(|| AttrRef::vertex("color", AttrKind::Color)),
                )
                .collect(),
            ..Contract::default()
        }
    }

    fn run(&self, mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        let (faces_in, vertices_in) = (mesh.n_faces(), mesh.n_vertices());
        let progress = cx.progress;
        progress.begin(Self::KIND, u64::from(self.0.max_passes));
        let mut on_pass = |r: &PassRecord| {
            progress.advance(
                u64::from(r.pass),
                &format!("λ {:.2}, {} faces", r.lambda.unwrap_or(f64::NAN), r.faces),
            );
        };
        let topo = cx.topology_at_hand(&mesh);
        let result = refine_with(mesh, &self.0, topo.as_deref(), &mut on_pass);
        progress.end();
        let (out, outcome) = result.map_err(|e| match e {
            RefineError::Internal(m) => StageError::Internal(format!("`{}`: {m}", Self::KIND)),
            e => StageError::Input(format!("`{}`: {e}", Self::KIND)),
        })?;
        report(cx.report, &self.0, &outcome, (faces_in, vertices_in), &out);
        Ok(out)
    }
}

/// Fills the stage report: figures, then warnings.
fn report(
    r: &mut StageReport,
    p: &RefineParams,
    o: &Outcome,
    (faces_in, vertices_in): (usize, usize),
    out: &Mesh,
) {
    r.figure("passes", o.passes.len());
    r.figure("stop", o.stop.name());
    r.figure("lambda_in", o.before.lambda());
    r.figure("lambda", o.after.lambda());
    r.figure("tau_a1_in", o.before.tau1());
    r.figure("tau_a2_in", o.before.tau2());
    r.figure("tau_a1", o.after.tau1());
    r.figure("tau_a2", o.after.tau2());
    r.figure("faces_in", faces_in);
    r.figure("faces", out.n_faces());
    r.figure("vertices_in", vertices_in);
    r.figure("vertices", out.n_vertices());
    r.figure("d_mean", o.input.mean);
    r.figure("d_std", o.input.std);
    r.figure("delta", o.input.delta);
    r.figure("truncation", [o.input.low, o.input.high]);
    r.figure("pass_table", &o.passes);

    let lambda = match o.after.lambda() {
        Some(l) => format!("λ = {l:.3}"),
        None => "λ undefined".to_string(),
    };
    let beta = p.beta;
    match o.stop {
        StopReason::Reached | StopReason::Empty => {}
        StopReason::MaxPasses => r.warn(format!(
            "stopped after max_passes = {} passes at {lambda}, below β = {beta}",
            p.max_passes
        )),
        StopReason::MaxFaces { would_be } => r.warn(format!(
            "stopped after {} passes at {lambda}, below β = {beta}: the next pass would make {would_be} faces, above max_faces = {}",
            o.passes.len(),
            p.max_faces
        )),
        StopReason::IndexLimit => r.warn(format!(
            "stopped after {} passes at {lambda}, below β = {beta}: the next pass would exceed 32-bit vertex indices",
            o.passes.len()
        )),
        StopReason::NoRed => r.warn(format!(
            "stopped after {} passes at {lambda}, below β = {beta}: no triangle has D above δ that can be split",
            o.passes.len()
        )),
        StopReason::Constant => r.warn(format!(
            "`{}` is constant over the faces: λ is undefined and nothing was refined",
            p.field
        )),
    }
    let refused: usize = o.passes.iter().map(|x| x.refused).sum();
    if refused > 0 {
        r.warn(format!(
            "{refused} red triangles were left unsplit because they or a neighbour were too small to split without a degenerate child"
        ));
    }
    for w in &o.carry_warnings {
        r.warn(w.clone());
    }
}

coarsen_stage::export_stage!(RefineRedGreen);

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::{DVec3, SanityOptions, Topology, sanity_check_with};
    use coarsen_shapes::{plane_grid, torus};

    /// The uniform split numbers its vertices and faces the way `Topology::of_split`
    /// expects: the adjacency derived from the coarse one is the one built (a torus, a disk
    /// with holes, a sphere, a grid).
    #[test]
    fn the_uniform_split_numbers_as_the_derived_adjacency_expects() {
        let meshes = [
            torus(2.0, 0.7, 16, 9).unwrap(),
            coarsen_shapes::disk_with_holes(3, 6, 2.0).unwrap(),
            coarsen_shapes::icosphere(1.0, 2).unwrap(),
            plane_grid(5, 4, 1.0).unwrap(),
        ];
        for m in &meshes {
            let fine = split_once(m, &vec![true; m.n_faces()]).unwrap().0;
            let coarse = Topology::build(m);
            let reference = coarse.uniform_split(m);
            assert_eq!(
                (&fine.positions, &fine.faces),
                (&reference.positions, &reference.faces)
            );
            assert_eq!(coarse.of_split(m, &fine), Some(Topology::build(&fine)));
        }
    }

    /// The edge table read from the adjacency is the one built, and a split through it
    /// gives the same mesh (a red-green split with green closures, on a holed disk).
    #[test]
    fn the_edge_table_from_the_adjacency_is_the_built_one() {
        let m = coarsen_shapes::disk_with_holes(2, 5, 2.0).unwrap();
        let topo = Topology::build(&m);
        let built = split::EdgeTable::build(m.n_vertices(), &m.faces);
        assert_eq!(split::EdgeTable::from_topology(&m, &topo), Some(built));
        let red: Vec<bool> = (0..m.n_faces()).map(|f| f % 3 == 0).collect();
        let (a, ca, _) = split_once(&m, &red).unwrap();
        let (b, cb, _) = split_once_with(&m, &red, Some(&topo)).unwrap();
        assert_eq!((a, ca), (b, cb));
        // An adjacency of another mesh is not used.
        let other = Topology::build(&torus(2.0, 0.7, 8, 6).unwrap());
        assert_eq!(split::EdgeTable::from_topology(&m, &other), None);
    }

    /// A triangle cut into four, with the centre face last:
    ///
    /// ```text
    ///  2 (C)
    ///  | \
    ///  5---4        faces: 0 = [0, 3, 5] (corner A)
    ///  | \ | \             1 = [3, 1, 4] (corner B)
    ///  0---3---1           2 = [5, 4, 2] (corner C)
    /// (A) (D)  (B)         3 = [3, 4, 5] (centre)
    /// ```
    fn four() -> Mesh {
        let p = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        Mesh::new(
            vec![
                p(0., 0.),
                p(4., 0.),
                p(0., 4.),
                p(2., 0.),
                p(2., 2.),
                p(0., 2.),
            ],
            vec![[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]],
        )
    }

    /// Every edge has at most two faces, used once each way, no face is degenerate, and no
    /// vertex lies inside an edge (no T-junction).
    fn assert_conforming(m: &Mesh) {
        sanity_check_with(m, &SanityOptions::strict()).unwrap();
        let topo = Topology::build(m);
        for &[a, b] in topo.edges() {
            let (pa, pb) = (m.positions[a as usize], m.positions[b as usize]);
            let ab = pb - pa;
            for (v, &p) in m.positions.iter().enumerate() {
                if v as u32 == a || v as u32 == b {
                    continue;
                }
                let t = (p - pa).dot(ab) / ab.length_squared();
                let off = (p - pa).cross(ab).length() / ab.length();
                assert!(
                    !(t > 0.0 && t < 1.0 && off < 1e-12 * ab.length()),
                    "vertex {v} lies inside edge {a}-{b}: a T-junction"
                );
            }
        }
    }

    fn with_field(mut m: Mesh, f: impl Fn(DVec3) -> f64) -> Mesh {
        let values = m.positions.iter().map(|&p| f(p)).collect();
        m.vertex_attrs
            .insert("hybrid_curvature", AttrValues::Scalar(values));
        m
    }

    fn run(mesh: &Mesh, params: RefineParams) -> (Result<Mesh, StageError>, StageReport) {
        let mut report = StageReport::default();
        let mut cx = Context::new(mesh, &mut report);
        let out = RefineRedGreen::new(params).run(mesh.clone(), &mut cx);
        (out, report)
    }

    fn lambdas(report: &StageReport) -> Vec<f64> {
        report
            .get("pass_table")
            .unwrap()
            .as_array()
            .unwrap()
            .iter()
            .map(|row| row["lambda"].as_f64().unwrap())
            .collect()
    }

    #[test]
    fn green_triangle_with_one_red_neighbour_is_bisected() {
        // Corner A red: its edges 0-3 (→ 6), 0-5 (→ 7), 3-5 (→ 8) split; the centre has
        // one split edge (3-5) and becomes [5, 8, 4] + [8, 3, 4]; corners B, C unchanged.
        let (out, counts, _) = split_once(&four(), &[true, false, false, false]).unwrap();
        assert_eq!((counts.red, counts.green), (1, [1, 0, 0]));
        assert_eq!(
            out.faces,
            vec![
                [0, 6, 7],
                [6, 3, 8],
                [7, 8, 5],
                [6, 8, 7],
                [3, 1, 4],
                [5, 4, 2],
                [5, 8, 4],
                [8, 3, 4],
            ]
        );
        assert_eq!(out.positions[8], DVec3::new(1.0, 1.0, 0.0));
        assert_conforming(&out);
    }

    #[test]
    fn green_triangle_with_two_red_neighbours_becomes_three() {
        // Corners A and B red: the centre's edges 3-4 (→ 10) and 5-3 (→ 11) are split.
        // Corner child [11, 3, 10]; the quadrilateral 5-11-10-4 is cut along 11-4 (both
        // halves right isosceles, quality 0.72) rather than 5-10 (worst 0.33).
        let (out, counts, _) = split_once(&four(), &[true, true, false, false]).unwrap();
        assert_eq!((counts.red, counts.green), (2, [0, 1, 0]));
        assert_eq!(out.n_faces(), 4 + 4 + 1 + 3);
        assert_eq!(out.faces[9..], [[11, 3, 10], [5, 11, 4], [11, 10, 4]]);
        assert_conforming(&out);
    }

    #[test]
    fn green_triangle_with_three_red_neighbours_is_split_one_to_four() {
        let (out, counts, _) = split_once(&four(), &[true, true, true, false]).unwrap();
        assert_eq!((counts.red, counts.green), (3, [0, 0, 1]));
        assert_eq!(out.n_faces(), 16);
        // Every edge of the input is split: 9 midpoints, areas all a quarter of a parent.
        assert_eq!(out.n_vertices(), 6 + 9);
        for f in 0..out.n_faces() {
            assert!((out.face_area(f) - 0.5).abs() < 1e-12, "face {f}");
        }
        assert_conforming(&out);
    }

    #[test]
    fn an_edge_with_three_faces_is_split_in_all_of_them() {
        // Three fins on edge 0-1; fin 0 red: the other two are bisected at the same
        // midpoint, so both halves of the edge keep three faces and nothing cracks.
        let m = Mesh::new(
            vec![
                DVec3::ZERO,
                DVec3::X,
                DVec3::Y,
                DVec3::Z,
                DVec3::new(0.5, -1.0, -1.0),
            ],
            vec![[0, 1, 2], [1, 0, 3], [1, 0, 4]],
        );
        let (out, counts, _) = split_once(&m, &[true, false, false]).unwrap();
        assert_eq!((counts.red, counts.green), (1, [2, 0, 0]));
        let topo = Topology::build(&out);
        let mid = topo
            .vertex_neighbors(0)
            .iter()
            .copied()
            .find(|&v| out.positions[v as usize] == DVec3::new(0.5, 0.0, 0.0))
            .unwrap();
        for end in [0, 1] {
            let e = topo.find_edge(end, mid).unwrap();
            assert_eq!(topo.edge_faces(e).len(), 3);
        }
        assert!(topo.find_edge(0, 1).is_none());
    }

    #[test]
    fn a_red_triangle_next_to_a_sliver_is_refused_rather_than_making_degenerate_faces() {
        // [0, 1, 2] is a unit right triangle; [2, 1, 3] a sliver of area 5e-12 on its
        // hypotenuse, above the degenerate threshold (2e-12 here) but too small to halve.
        let m = Mesh::new(
            vec![
                DVec3::ZERO,
                DVec3::X,
                DVec3::Y,
                DVec3::new(0.5, 0.5 + 1e-11, 0.0),
            ],
            vec![[0, 1, 2], [2, 1, 3]],
        );
        sanity_check_with(&m, &SanityOptions::strict()).unwrap();
        let (out, counts, _) = split_once(&m, &[true, false]).unwrap();
        assert_eq!((counts.red, counts.refused), (0, 1));
        assert_eq!(out, m);
    }

    #[test]
    fn passes_stop_as_soon_as_lambda_reaches_beta() {
        // A field concentrated around one interior point of a 16 × 16 grid; β = 5 takes
        // several passes (one pass gives λ ≈ 3.2 here).
        let grid = with_field(plane_grid(16, 16, 1.0).unwrap(), |p| {
            (-(p - DVec3::new(0.2, 0.1, 0.0)).length_squared() / 0.01).exp()
        });
        let params = RefineParams {
            beta: 5.0,
            ..RefineParams::default()
        };
        let (out, report) = run(&grid, params);
        let out = out.unwrap();
        assert_eq!(report.get("stop"), Some(&"reached".into()));
        let l = lambdas(&report);
        assert!(l.len() >= 2, "takes more than one pass: {l:?}");
        assert!(l[..l.len() - 1].iter().all(|&x| x < 5.0), "{l:?}");
        assert!(*l.last().unwrap() >= 5.0, "{l:?}");
        assert_eq!(report.get("lambda").unwrap().as_f64(), l.last().copied());
        let lambda_in = report.get("lambda_in").unwrap().as_f64().unwrap();
        assert!(lambda_in < 1.2, "the input grid is uniform: {lambda_in}");
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        assert_conforming(&out);
        assert!((out.area() - grid.area()).abs() < 1e-12);
        // τ(A₁) grew more than τ(A₂).
        let tau = |n: &str| report.get(n).unwrap().as_f64().unwrap();
        assert!(tau("tau_a1") / tau("tau_a1_in") > 2.0 * tau("tau_a2") / tau("tau_a2_in"));
    }

    #[test]
    fn max_passes_stops_the_run_and_says_so() {
        let grid = with_field(plane_grid(8, 8, 1.0).unwrap(), |p| p.x * p.x);
        let params = RefineParams {
            beta: 1000.0,
            max_passes: 2,
            ..RefineParams::default()
        };
        let (out, report) = run(&grid, params);
        assert!(out.is_ok());
        assert_eq!(report.get("passes"), Some(&2.into()));
        assert_eq!(report.get("stop"), Some(&"max_passes".into()));
        assert!(
            report.warnings[0].contains("max_passes = 2"),
            "{:?}",
            report.warnings
        );
    }

    #[test]
    fn max_faces_is_checked_before_a_pass_and_says_so() {
        let grid = with_field(plane_grid(8, 8, 1.0).unwrap(), |p| p.x * p.x);
        let one_pass = RefineParams {
            beta: 1000.0,
            max_passes: 1,
            ..RefineParams::default()
        };
        let (first, _) = run(&grid, one_pass);
        let after_one = first.unwrap().n_faces() as u64;
        let params = RefineParams {
            beta: 1000.0,
            max_faces: after_one + 1,
            ..RefineParams::default()
        };
        let (out, report) = run(&grid, params);
        assert_eq!(out.unwrap().n_faces() as u64, after_one);
        assert_eq!(report.get("passes"), Some(&1.into()));
        assert_eq!(report.get("stop"), Some(&"max_faces".into()));
        assert!(
            report.warnings[0].contains("above max_faces"),
            "{:?}",
            report.warnings
        );
    }

    #[test]
    fn a_red_region_on_the_border_keeps_one_boundary_loop_on_the_border_lines() {
        // Field high along the left side x = −0.5 of a 12 × 12 grid.
        let grid = with_field(plane_grid(12, 12, 1.0).unwrap(), |p| {
            (-(p.x + 0.5).powi(2) / 0.005).exp()
        });
        let (out, report) = run(&grid, RefineParams::default());
        let out = out.unwrap();
        assert!(report.get("passes").unwrap().as_u64().unwrap() >= 1);
        assert_conforming(&out);
        let (before, after) = (Topology::build(&grid), Topology::build(&out));
        assert_eq!(after.n_boundary_loops(), 1);
        assert!(after.boundary_loop(0).len() > before.boundary_loop(0).len());
        for &v in after.boundary_loop(0) {
            let p = out.positions[v as usize];
            assert!(
                (p.x.abs() - 0.5).abs() < 1e-15 || (p.y.abs() - 0.5).abs() < 1e-15,
                "boundary vertex {v} at {p} is off the border"
            );
        }
    }

    #[test]
    fn a_torus_keeps_its_genus_and_orientation() {
        // F = |K|, the analytic Gaussian curvature of the torus (R = 1, r = 0.4).
        let (big, small) = (1.0, 0.4);
        let t = with_field(torus(big, small, 32, 12).unwrap(), |p| {
            let cos_w = ((p.x * p.x + p.y * p.y).sqrt() - big) / small;
            (cos_w / (small * (big + small * cos_w))).abs()
        });
        let (out, report) = run(&t, RefineParams::default());
        let out = out.unwrap();
        assert!(report.get("passes").unwrap().as_u64().unwrap() >= 1);
        assert_conforming(&out);
        let s = Topology::build(&out).summary(&out);
        assert_eq!((s.genus_total, s.n_boundary_loops), (Some(1), 0));
        assert!(s.consistently_oriented && s.manifold);
        assert!(out.signed_volume() > 0.0);
    }

    #[test]
    fn attributes_are_carried_midpoints_take_the_mean() {
        // A vertex scalar linear in the position is its own mean at every midpoint; a
        // face label is inherited, so each label keeps its parent's area.
        let mut grid = with_field(plane_grid(6, 6, 1.0).unwrap(), |p| p.x.abs());
        let k = grid.positions.iter().map(|p| p.x + 2.0 * p.y).collect();
        grid.vertex_attrs.insert("k", AttrValues::Scalar(k));
        let labels = (0..grid.n_faces() as u32).collect();
        grid.face_attrs.insert("part", AttrValues::Label(labels));
        let (out, report) = run(&grid, RefineParams::default());
        let out = out.unwrap();
        assert!(out.n_vertices() > grid.n_vertices());
        let k = out.vertex_attrs.scalar("k").unwrap();
        for (v, p) in out.positions.iter().enumerate() {
            assert!((k[v] - (p.x + 2.0 * p.y)).abs() < 1e-15, "vertex {v}");
        }
        let part = out.face_attrs.label("part").unwrap();
        let mut area = vec![0.0; grid.n_faces()];
        for f in 0..out.n_faces() {
            area[part[f] as usize] += out.face_area(f);
        }
        for (f, a) in area.iter().enumerate() {
            assert!((a - grid.face_area(f)).abs() < 1e-15, "face {f}");
        }
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    }

    #[test]
    fn a_constant_field_refines_nothing_and_warns() {
        let grid = with_field(plane_grid(4, 4, 1.0).unwrap(), |_| 3.0);
        let (out, report) = run(&grid, RefineParams::default());
        assert_eq!(out.unwrap(), grid);
        assert_eq!(report.get("stop"), Some(&"constant".into()));
        assert!(
            report.warnings[0].contains("constant"),
            "{:?}",
            report.warnings
        );
    }

    #[test]
    fn color_writes_the_field_on_viridis_over_the_truncation_range() {
        let grid = with_field(plane_grid(4, 4, 1.0).unwrap(), |p| p.x);
        let params = RefineParams {
            color: true,
            ..RefineParams::default()
        };
        let stage = RefineRedGreen::new(params.clone());
        assert_eq!(
            stage.contract().writes,
            vec![AttrRef::vertex("color", AttrKind::Color)]
        );
        let (out, report) = run(&grid, params);
        let out = out.unwrap();
        let range = report.get("truncation").unwrap();
        let (lo, hi) = (range[0].as_f64().unwrap(), range[1].as_f64().unwrap());
        let f = out.vertex_attrs.scalar("hybrid_curvature").unwrap();
        let expect = color::colorize(f, lo, hi);
        assert_eq!(
            out.vertex_attrs.get("color"),
            Some(&AttrValues::Color(expect))
        );
        // The lowest x is darkest, the highest brightest.
        let colors = color::colorize(&[-0.5, 0.5], lo, hi);
        assert!(colors[0][1] < colors[1][1]);
    }

    #[test]
    fn recompute_curvature_rewrites_the_three_columns_from_the_refined_mesh() {
        let t = torus(1.0, 0.4, 24, 10).unwrap();
        let e = coarsen_stage_curvature::estimate(&t, &CurvatureParams::default()).unwrap();
        let mut t = t;
        t.vertex_attrs.insert(HYBRID, AttrValues::Scalar(e.hybrid));
        let params = RefineParams {
            recompute_curvature: true,
            max_passes: 1,
            beta: 1000.0,
            ..RefineParams::default()
        };
        let stage = RefineRedGreen::new(params.clone());
        let written: Vec<_> = stage
            .contract()
            .writes
            .iter()
            .map(|a| a.name.clone())
            .collect();
        assert_eq!(written, CURVATURE_COLUMNS);
        let (out, outcome) = refine(t.clone(), &params).unwrap();
        assert_eq!(outcome.passes.len(), 1);
        let again = coarsen_stage_curvature::estimate(&out, &CurvatureParams::default()).unwrap();
        assert_eq!(out.vertex_attrs.scalar(HYBRID), Some(&again.hybrid[..]));
        assert_eq!(out.vertex_attrs.scalar(GAUSSIAN), Some(&again.gaussian[..]));
        assert_eq!(out.vertex_attrs.scalar(MEAN), Some(&again.mean[..]));
        // Carried instead, a midpoint's F is the mean of its edge's ends: not the estimate.
        let carried = RefineParams {
            recompute_curvature: false,
            ..params
        };
        let (plain, _) = refine(t, &carried).unwrap();
        assert_eq!(plain.faces, out.faces);
        assert_ne!(plain.vertex_attrs.scalar(HYBRID), Some(&again.hybrid[..]));

        let other = RefineParams {
            recompute_curvature: true,
            field: "density".into(),
            ..RefineParams::default()
        };
        let issues = other.validate();
        assert_eq!(issues.len(), 1);
        assert!(issues[0].message.contains("hybrid_curvature"), "{issues:?}");
    }

    #[test]
    fn bad_inputs_are_named() {
        let grid = plane_grid(2, 2, 1.0).unwrap();
        let (out, _) = run(&grid, RefineParams::default());
        let e = out.unwrap_err().to_string();
        assert!(
            e.contains("`hybrid_curvature` is missing") && e.contains("no vertex attribute"),
            "{e}"
        );

        let mut nan = with_field(grid.clone(), |p| p.x);
        if let Some(AttrValues::Scalar(v)) = nan.vertex_attrs.get_mut("hybrid_curvature") {
            v[4] = f64::NAN;
        }
        let e = refine(nan, &RefineParams::default()).unwrap_err();
        assert_eq!(
            e,
            RefineError::NonFiniteField {
                name: "hybrid_curvature".into(),
                vertex: 4
            }
        );

        let mut repeated = with_field(grid.clone(), |p| p.x);
        repeated.faces[3] = [2, 5, 5];
        let e = refine(repeated, &RefineParams::default()).unwrap_err();
        assert_eq!(e, RefineError::RepeatedIndex { face: 3, vertex: 5 });

        let mut labels = grid.clone();
        labels
            .vertex_attrs
            .insert("hybrid_curvature", AttrValues::Label(vec![0; 9]));
        let e = refine(labels, &RefineParams::default()).unwrap_err();
        assert!(e.to_string().contains("holds label values"), "{e}");

        assert!(matches!(
            split_once(&grid, &[true]),
            Err(RefineError::RedLength { len: 1, faces: 8 })
        ));
    }

    #[test]
    fn parameters_out_of_range_are_named() {
        let bad = RefineParams {
            field: String::new(),
            alpha: f64::NAN,
            beta: -1.0,
            max_passes: 100,
            max_faces: 0,
            truncated_statistics: false,
            recompute_curvature: false,
            color: false,
        };
        let fields: Vec<_> = bad.validate().iter().map(|i| i.field).collect();
        assert_eq!(
            fields,
            ["field", "alpha", "beta", "max_passes", "max_faces"]
        );
        assert!(RefineParams::default().validate().is_empty());
    }

    #[test]
    fn example_table_builds_through_the_registry_and_reads_the_field() {
        let d = descriptor();
        let mut table: toml::Table =
            toml::from_str(&d.example_toml().replace("[[stage]]\n", "")).unwrap();
        assert_eq!(table.remove("kind"), Some("refine.red-green".into()));
        table.insert("field".into(), "mean_curvature".into());
        let stage = (d.build)(&table).ok().unwrap();
        assert_eq!(stage.kind(), "refine.red-green");
        assert_eq!(
            stage.contract().reads,
            vec![AttrRef::vertex("mean_curvature", AttrKind::Scalar)]
        );
        assert!(stage.contract().writes.is_empty());
    }
}
