//! What a stage reads, writes and needs: checked for a whole pipeline before it runs.

use coarsen_mesh::{AttrKind, Domain};
use serde::{Deserialize, Serialize};
use std::fmt;

/// A named attribute of one domain and kind.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AttrRef {
    /// Vertex or face.
    pub domain: Domain,
    /// Column name.
    pub name: String,
    /// Value type.
    pub kind: AttrKind,
}

impl AttrRef {
    /// A vertex attribute.
    pub fn vertex(name: impl Into<String>, kind: AttrKind) -> Self {
        AttrRef {
            domain: Domain::Vertex,
            name: name.into(),
            kind,
        }
    }

    /// A face attribute.
    pub fn face(name: impl Into<String>, kind: AttrKind) -> Self {
        AttrRef {
            domain: Domain::Face,
            name: name.into(),
            kind,
        }
    }
}

impl fmt::Display for AttrRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {} `{}`", self.domain, self.kind, self.name)
    }
}

/// What a stage needs from the mesh and the run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Needs {
    /// The input must be an edge- and vertex-manifold mesh.
    pub manifold: bool,
    /// The stage needs a run target (`--vertices`, `--faces`, `--ratio` or the pipeline's).
    pub target: bool,
    /// Vertices where several face fans meet are split into one vertex per fan before the
    /// stage; edges of three or more faces are left as they are (implied by `manifold`,
    /// which has them cut apart too).
    pub split_fans: bool,
}

/// A stage's declared data flow.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Contract {
    /// Attributes that must exist when the stage starts.
    pub reads: Vec<AttrRef>,
    /// Attributes present when the stage ends.
    pub writes: Vec<AttrRef>,
    /// Domains whose attributes do not survive the stage (other than those it writes),
    /// e.g. a dual triangulation drops every face attribute.
    pub clears: Vec<Domain>,
    /// Requirements on the input and the run.
    pub needs: Needs,
    /// Whether the stage carries per-corner attributes (`Mesh::wedges`: UVs across seams,
    /// normals across hard edges) to its output; the runner keeps them only through a
    /// pipeline whose every stage does (or that restores them after the last that does
    /// not).
    pub carries_wedges: bool,
    /// Whether the stage writes the run input's per-corner attributes onto the mesh it
    /// returns (from `Context::original`, which keeps them when the stages before could
    /// not carry them).
    pub restores_wedges: bool,
}
