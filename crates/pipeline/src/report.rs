//! The run report: what every stage did, how long it took and what it measured.

use coarsen_stage::Target;
use serde::Serialize;

/// The report of one stage of a run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageRecord {
    /// 1-based position in the pipeline.
    pub index: usize,
    /// The stage kind.
    pub kind: String,
    /// The id the file gave it, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
    /// Effective parameters (defaults filled in, overrides applied).
    pub params: serde_json::Value,
    /// Wall time in seconds.
    pub seconds: f64,
    /// Wall time in seconds the runner spent readying the mesh before the stage (the
    /// adjacency it builds to check the mesh, which the next stage that needs one takes
    /// over; edges cut, vertices split).
    pub ready_seconds: f64,
    /// Vertex count before the stage.
    pub vertices_before: usize,
    /// Face count before the stage.
    pub faces_before: usize,
    /// Vertex count after the stage.
    pub vertices_after: usize,
    /// Face count after the stage.
    pub faces_after: usize,
    /// The stage's own figures, in the order it gave them.
    pub figures: serde_json::Map<String, serde_json::Value>,
    /// Findings that are not failures.
    pub warnings: Vec<String>,
}

/// The report of a whole run (`--report FILE` writes it as JSON).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RunReport {
    /// The pipeline's name.
    pub pipeline: String,
    /// The run target, if any.
    pub target: Option<Target>,
    /// Where the input came from (a file path or `demo`).
    pub input: String,
    /// Notes from loading and cleaning the input.
    pub input_notes: Vec<String>,
    /// Input vertex count (after clean-up).
    pub input_vertices: usize,
    /// Input face count (after clean-up).
    pub input_faces: usize,
    /// Output vertex count.
    pub output_vertices: usize,
    /// Output face count.
    pub output_faces: usize,
    /// Per-stage records, in order.
    pub stages: Vec<StageRecord>,
    /// What the run could not carry from its input to its output (per-corner UVs and
    /// normals the stages cannot carry yet, materials the faces lost), one sentence each.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// Wall time of all stages, in seconds.
    pub seconds: f64,
}

impl RunReport {
    /// The report as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }

    /// A short table for people: one line per stage.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "pipeline `{}`: {} → {} vertices, {} → {} faces in {:.3} s\n",
            self.pipeline,
            self.input_vertices,
            self.output_vertices,
            self.input_faces,
            self.output_faces,
            self.seconds
        );
        for n in &self.notes {
            s.push_str(&format!("  note: {n}\n"));
        }
        for r in &self.stages {
            s.push_str(&format!(
                "  {:>2}. {:<20} {:>9} → {:<9} faces  {:>8.3} s\n",
                r.index, r.kind, r.faces_before, r.faces_after, r.seconds
            ));
            for w in &r.warnings {
                s.push_str(&format!("      warning: {w}\n"));
            }
        }
        s
    }
}
