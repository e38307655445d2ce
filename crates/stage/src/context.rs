//! What a running stage sees besides the mesh: the original input, the run target, its
//! report and a progress sink.

use coarsen_mesh::Mesh;
use serde::{Deserialize, Serialize};
use std::fmt;

/// The size a coarsening run aims for.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase", deny_unknown_fields)]
pub enum Target {
    /// Exactly this many output vertices.
    Vertices(u64),
    /// This many output faces (exactly where the method allows, else as near as it can).
    Faces(u64),
    /// This fraction of the run input's faces removed, in `[0, 1)` (paper 2's 70 % is `0.7`).
    Ratio(f64),
}

impl fmt::Display for Target {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Target::Vertices(n) => write!(f, "{n} vertices"),
            Target::Faces(n) => write!(f, "{n} faces"),
            Target::Ratio(r) => write!(f, "{:.4}% of faces removed", r * 100.0),
        }
    }
}

impl Target {
    /// The target as a vertex count for `mesh` (stages pass the run's input,
    /// [`Context::original`], so that a ratio means the same wherever the stage stands).
    ///
    /// Face counts and ratios convert with the mesh's own vertex/face proportion, which
    /// for triangle meshes is close to ½ (exactly so, up to the Euler characteristic and
    /// the boundary, for closed meshes).
    pub fn vertices_for(&self, mesh: &Mesh) -> u64 {
        let (v, f) = (mesh.n_vertices() as f64, mesh.n_faces().max(1) as f64);
        match *self {
            Target::Vertices(n) => n,
            Target::Faces(n) => (n as f64 * v / f).round() as u64,
            Target::Ratio(r) => (v * (1.0 - r)).round() as u64,
        }
    }

    /// The target as a face count for `mesh`.
    pub fn faces_for(&self, mesh: &Mesh) -> u64 {
        let (v, f) = (mesh.n_vertices().max(1) as f64, mesh.n_faces() as f64);
        match *self {
            Target::Vertices(n) => (n as f64 * f / v).round() as u64,
            Target::Faces(n) => n,
            Target::Ratio(r) => (f * (1.0 - r)).round() as u64,
        }
    }

    /// A problem with the target's value itself, if any.
    pub fn check(&self) -> Result<(), String> {
        match *self {
            Target::Ratio(r) if !(0.0..1.0).contains(&r) => Err(format!(
                "ratio is the fraction of faces removed and must be in [0, 1), got {r}"
            )),
            _ => Ok(()),
        }
    }
}

/// A run target as a count: exact vertices, or faces (face targets and ratios).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetCount {
    /// Exactly this many vertices.
    Vertices(u64),
    /// This many faces.
    Faces(u64),
}

/// Where a long-running stage reports progress; the CLI draws it, tests ignore it.
pub trait Progress: Send + Sync {
    /// A step of `total` units begins (0 when the total is unknown).
    fn begin(&self, label: &str, total: u64);
    /// `done` units of the current step are finished; `message` says e.g. the energy.
    fn advance(&self, done: u64, message: &str);
    /// The current step ended.
    fn end(&self);
}

/// A progress sink that shows nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoProgress;

impl Progress for NoProgress {
    fn begin(&self, _: &str, _: u64) {}
    fn advance(&self, _: u64, _: &str) {}
    fn end(&self) {}
}

/// What a stage tells the run report: named figures and warnings.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct StageReport {
    /// Named figures (numbers, tables as arrays of objects), in the order they were given.
    pub figures: Vec<(String, serde_json::Value)>,
    /// Findings that are not failures (repairs made, attributes dropped, targets missed).
    pub warnings: Vec<String>,
}

impl StageReport {
    /// Records a figure; a second figure of the same name replaces the first.
    pub fn figure(&mut self, name: &str, value: impl Serialize) {
        let v = serde_json::to_value(value)
            .unwrap_or_else(|e| serde_json::Value::String(e.to_string()));
        match self.figures.iter_mut().find(|(n, _)| n == name) {
            Some((_, old)) => *old = v,
            None => self.figures.push((name.to_string(), v)),
        }
    }

    /// The figure called `name`.
    pub fn get(&self, name: &str) -> Option<&serde_json::Value> {
        self.figures.iter().find(|(n, _)| n == name).map(|(_, v)| v)
    }

    /// Records a warning.
    pub fn warn(&mut self, message: impl Into<String>) {
        self.warnings.push(message.into());
    }
}

/// What a collapse stage hands back through [`Context::progressive`]: its progressive
/// record, type-erased so that this API names no engine (the built-in simplifiers hand back
/// a `coarsen_collapse::Progressive`).
pub type Handback = Box<dyn std::any::Any + Send>;

/// The run as a stage sees it.
pub struct Context<'a> {
    /// The mesh the run started from (after load-time clean-up); always available.
    pub original: &'a Mesh,
    /// The run target, if the pipeline or the command line gave one.
    pub target: Option<Target>,
    /// This stage's part of the run report.
    pub report: &'a mut StageReport,
    /// Progress sink for long loops.
    pub progress: &'a dyn Progress,
    /// When the run asks for a progressive record (`coarsen run --progressive`), where a
    /// stage that records its collapses ([`crate::Stage::RECORDS_COLLAPSES`]) puts it,
    /// replacing an earlier stage's; `None` otherwise (then nothing is recorded).
    pub progressive: Option<&'a mut Option<Handback>>,
    /// What the run's stages share (indexes of the input, the current adjacency); `None`
    /// builds afresh on every request.
    pub shared: Option<&'a crate::Shared>,
}

impl<'a> Context<'a> {
    /// A context with no target, no progress display and a fresh report.
    pub fn new(original: &'a Mesh, report: &'a mut StageReport) -> Self {
        Context {
            original,
            target: None,
            report,
            progress: &NoProgress,
            progressive: None,
            shared: None,
        }
    }

    /// The value of type `T` derived from the run input ([`Context::original`]) by
    /// `build`, built once per run and shared by every stage that asks for it.
    pub fn input_index<T: std::any::Any + Send + Sync>(
        &self,
        build: impl FnOnce(&Mesh) -> T,
    ) -> std::sync::Arc<T> {
        let original = self.original;
        match self.shared {
            Some(s) => s.input_index(|| build(original)),
            None => std::sync::Arc::new(build(original)),
        }
    }

    /// The value of type `T` derived from the run input ([`Context::input_index`]) when a
    /// stage before built it; nothing is built.
    pub fn input_index_at_hand<T: std::any::Any + Send + Sync>(&self) -> Option<std::sync::Arc<T>> {
        self.shared.and_then(|s| s.input_index_at_hand())
    }

    /// Lets go of the adjacency kept for the stages after (see [`Context::topology`]): for
    /// a stage done with it before it builds something big, so that the two do not add up
    /// to the run's peak memory. The next stage that asks builds it again.
    pub fn release_topology(&self) {
        if let Some(s) = self.shared {
            s.forget_topology();
        }
    }

    /// The adjacency of `mesh`, shared with the stages before and after while the faces
    /// stay the same.
    pub fn topology(
        &self,
        mesh: &Mesh,
    ) -> Result<std::sync::Arc<coarsen_mesh::Topology>, coarsen_mesh::TopologyError> {
        match self.shared {
            Some(s) => s.topology(mesh),
            None => coarsen_mesh::Topology::try_build(mesh).map(std::sync::Arc::new),
        }
    }

    /// The adjacency of `mesh` when a stage before left it (see [`Context::topology`]);
    /// nothing is built.
    pub fn topology_at_hand(&self, mesh: &Mesh) -> Option<std::sync::Arc<coarsen_mesh::Topology>> {
        self.shared.and_then(|s| s.topology_at_hand(mesh))
    }

    /// Like [`Context::input_index`], for a value built from the run input and its
    /// adjacency ([`Context::input_topology`]); the adjacency is only looked for when the
    /// value is not built yet.
    pub fn input_index_with_topology<T: std::any::Any + Send + Sync>(
        &self,
        build: impl FnOnce(&Mesh, &coarsen_mesh::Topology) -> T,
    ) -> Result<std::sync::Arc<T>, coarsen_mesh::TopologyError> {
        let original = self.original;
        let build = || self.input_topology().map(|topo| build(original, &topo));
        match self.shared {
            Some(s) => s.try_input_index(build),
            None => build().map(std::sync::Arc::new),
        }
    }

    /// The adjacency of the run input ([`Context::original`]): the one a stage still holds
    /// or the one kept between stages when that is the input's, else built anew.
    pub fn input_topology(
        &self,
    ) -> Result<std::sync::Arc<coarsen_mesh::Topology>, coarsen_mesh::TopologyError> {
        match self.shared {
            Some(s) => s.input_topology(self.original),
            None => coarsen_mesh::Topology::try_build(self.original).map(std::sync::Arc::new),
        }
    }

    /// The run target, checked, and as a count: vertex targets stay vertex counts; face
    /// targets and ratios become face counts (a ratio counts the run input's faces,
    /// wherever the stage stands). Errors name the stage.
    pub fn target_count(&self, kind: &str) -> Result<(Target, TargetCount), crate::StageError> {
        let t = self.require_target(kind)?;
        t.check()
            .map_err(|m| crate::StageError::Input(format!("`{kind}`: {m}")))?;
        let count = match t {
            Target::Vertices(n) => TargetCount::Vertices(n),
            Target::Faces(_) | Target::Ratio(_) => TargetCount::Faces(t.faces_for(self.original)),
        };
        Ok((t, count))
    }

    /// The run target, or an error naming the stage that needs one.
    pub fn require_target(&self, kind: &str) -> Result<Target, crate::StageError> {
        self.target.ok_or_else(|| {
            crate::StageError::Input(format!(
                "`{kind}` needs a target: give the pipeline a target or pass --vertices, --faces or --ratio"
            ))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::DVec3;

    #[test]
    fn targets_convert_with_the_mesh_proportions() {
        let m = Mesh::new(vec![DVec3::ZERO; 100], vec![[0, 1, 2]; 200]);
        assert_eq!(Target::Vertices(10).faces_for(&m), 20);
        assert_eq!(Target::Faces(50).vertices_for(&m), 25);
        assert_eq!(Target::Ratio(0.7).faces_for(&m), 60);
        assert_eq!(Target::Ratio(0.7).vertices_for(&m), 30);
        assert!(Target::Ratio(1.0).check().is_err());
        assert!(Target::Ratio(f64::NAN).check().is_err());
    }

    #[test]
    fn report_figures_replace_by_name() {
        let mut r = StageReport::default();
        r.figure("passes", 3);
        r.figure("lambda", [1.5, 2.1]);
        r.figure("passes", 4);
        assert_eq!(r.figures.len(), 2);
        assert_eq!(r.get("passes"), Some(&serde_json::json!(4)));
    }
}
