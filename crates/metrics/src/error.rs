//! What can make a figure impossible to compute, naming the mesh and the element.

use coarsen_mesh::topology::TopologyError;
use coarsen_mesh::{DVec3, IndexError};
use std::fmt;

/// The largest coordinate magnitude measured: squared areas and distances of coordinates
/// this large still fit `f64`, so no figure overflows.
pub const MAX_COORDINATE: f64 = 1e75;

/// Which of the two meshes an error is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Role {
    /// The mesh given to the run (the reference surface).
    Input,
    /// The mesh the run produced (the one being measured).
    Output,
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Role::Input => "input",
            Role::Output => "output",
        })
    }
}

/// Bad input to a measurement: every variant names the mesh and, where there is one, the
/// offending element.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MetricsError {
    /// A face index out of range, a count beyond `u32`, or a wrong attribute column length.
    #[error("{mesh} mesh: {source}")]
    Indices {
        /// Which mesh.
        mesh: Role,
        /// What is wrong.
        source: IndexError,
    },
    /// A vertex used by a face has a NaN or infinite coordinate, or one beyond
    /// ±[`MAX_COORDINATE`].
    #[error(
        "{mesh} mesh: vertex {vertex} is used by a face but has position {position}; coordinates must be finite and within ±1e75"
    )]
    BadCoordinate {
        /// Which mesh.
        mesh: Role,
        /// The vertex.
        vertex: usize,
        /// Its position.
        position: DVec3,
    },
    /// Fidelity needs a surface on both sides.
    #[error("{mesh} mesh has no faces, so its distance to the other surface is undefined")]
    NoFaces {
        /// Which mesh.
        mesh: Role,
    },
    /// Distances are percents of the input's bounding-box diagonal, which must be positive
    /// and finite.
    #[error(
        "input mesh's bounding-box diagonal is {diagonal}: distances cannot be given as a percent of it"
    )]
    BadExtent {
        /// The diagonal (of the vertices used by faces).
        diagonal: f64,
    },
    /// More elements than the topology tables hold.
    #[error("{mesh} mesh: {source}")]
    Topology {
        /// Which mesh.
        mesh: Role,
        /// The limit exceeded.
        source: TopologyError,
    },
}
