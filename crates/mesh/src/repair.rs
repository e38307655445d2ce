//! The repairs that ready a mesh for the next step of a run, chosen by what that step
//! needs ([`Needs`]) and reported as notes.
//!
//! Before a step that needs a manifold mesh or asks for it ([`Needs::split_fans`], the
//! collapse stages), non-manifold vertices (several face fans at one point) are split into
//! one vertex per fan. A step that only asks for the split skips the adjacency altogether
//! when every vertex is one oriented fan ([`crate::ring::one_fan_everywhere`]), a far
//! cheaper test (0.16 against 0.8 s on the bunny subdivided three times, 4.4M faces).
//!
//! Edges of three or more faces are cut apart before a step that needs a manifold mesh,
//! and before the first step of a run that has one ([`Needs::cut_ahead`]: so that the steps
//! between, clustering above all, see the surface that step will get): two-sided faces
//! (two faces back to back on the same vertices, which no dual can represent) are first
//! made one-sided ([`crate::hygiene::drop_two_sided_faces`]), then the faces on each such
//! edge are paired, the two sides of a surface first, and the others come off
//! ([`crate::hygiene::cut_non_manifold_edges`]: a fin on a surface leaves the surface
//! whole). With [`Needs::cut_ahead`], the faces of pieces whose boundary runs along fewer
//! than three faces (a lone triangle cut off; no dual exists for them) are then split
//! 1-to-4 ([`crate::hygiene::split_small_pieces`]). A step that only asks for the split
//! gets those edges as they are (their vertices stay in place). Two faces using an edge in
//! the same direction are no matter of manifoldness (the step itself may refuse them);
//! [`RepairError::NotManifold`] guards what is left.
//!
//! The adjacency comes from the caller (`topology`), which may hold the one of the mesh
//! already: nothing is built where a cheap test answers, and a mesh that is manifold
//! needs no summary.

use crate::hygiene;
use crate::{Mesh, Topology, TopologyError, TopologySummary};
use std::sync::Arc;

/// The words of the note when non-manifold vertices were split (one vertex per face fan).
pub const SPLIT_FANS_NOTE: &str = "split into one vertex per face fan";

/// The words of the note when edges of three or more faces were cut apart (after making
/// two-sided faces one-sided).
pub const CUT_EDGES_NOTE: &str = "edges of three or more faces cut apart";

/// What the next step of a run needs from the mesh.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Needs {
    /// An edge- and vertex-manifold mesh: edges of three or more faces are cut, pinched
    /// vertices split, and a mesh still not manifold is refused.
    pub manifold: bool,
    /// Pinched vertices split into one vertex per face fan; edges of three or more faces
    /// left as they are.
    pub split_fans: bool,
    /// A later step needs a manifold mesh: cut edges of three or more faces now, and split
    /// pieces too small for a dual 1-to-4 (before the first step of such a run).
    pub cut_ahead: bool,
}

/// Why a mesh could not be readied.
#[derive(Debug, thiserror::Error)]
pub enum RepairError {
    /// The adjacency could not be built.
    #[error(transparent)]
    Topology(#[from] TopologyError),
    /// The step needs a manifold mesh and the repairs did not make one.
    #[error("{edges} non-manifold edges and {vertices} non-manifold vertices")]
    NotManifold {
        /// Non-manifold edge count.
        edges: usize,
        /// Non-manifold vertex count.
        vertices: usize,
    },
}

/// A mesh readied for a step, and what was done to it (one note per repair, for the
/// step's warnings).
pub struct Readied {
    /// The repaired mesh (the input when nothing was needed).
    pub mesh: Mesh,
    /// One line per repair made.
    pub notes: Vec<String>,
}

/// Readies `mesh` for a step that `needs` so much (see the module docs). `topology` gives
/// the adjacency of a mesh: the caller's, built or kept (it is asked for the input mesh
/// and for each repaired one, never when the cheap tests answer).
pub fn ready(
    mesh: Mesh,
    needs: Needs,
    topology: impl Fn(&Mesh) -> Result<Arc<Topology>, TopologyError>,
) -> Result<Readied, RepairError> {
    let mut notes = Vec::new();
    let cut_ahead = needs.cut_ahead && !topology(&mesh)?.is_manifold();
    let mesh = if may_need_repair(&mesh, needs, cut_ahead) && !topology(&mesh)?.is_manifold() {
        make_workable(mesh, needs, cut_ahead, &topology, &mut notes)?
    } else {
        mesh
    };
    let mesh = if needs.cut_ahead {
        split_small_pieces(mesh, &topology, &mut notes)?
    } else {
        mesh
    };
    Ok(Readied { mesh, notes })
}

/// Whether `mesh` may need a repair for `needs`, by the cheapest test that tells:
/// a step that only asks for the split needs no adjacency when every vertex is one
/// oriented fan (the usual case).
fn may_need_repair(mesh: &Mesh, needs: Needs, cut_ahead: bool) -> bool {
    needs.manifold || cut_ahead || (needs.split_fans && !crate::ring::one_fan_everywhere(mesh))
}

/// Splits the pinched vertices of `mesh` (not manifold), after cutting its edges of three
/// or more faces apart when the step or a later one needs a manifold mesh; refuses a mesh
/// still not manifold for a step that needs one.
fn make_workable(
    mesh: Mesh,
    needs: Needs,
    cut_ahead: bool,
    topology: &impl Fn(&Mesh) -> Result<Arc<Topology>, TopologyError>,
    notes: &mut Vec<String>,
) -> Result<Mesh, RepairError> {
    let mut summary = topology(&mesh)?.summary(&mesh);
    let mut mesh = mesh;
    // Edges of three or more faces are cut only for a step that cannot work with them, or
    // before one: a collapse stage keeps them joined (its vertices there stay).
    let multi_edges = summary.n_non_manifold_edges - summary.n_flipped_edges;
    let cut = (needs.manifold || cut_ahead) && multi_edges > 0;
    let split_only = multi_edges == 0 && (needs.manifold || needs.split_fans);
    if summary.n_non_manifold_vertices > 0 && (split_only || cut) {
        (mesh, summary) = split_fans(mesh, cut, &summary, topology, notes)?;
    }
    if needs.manifold && !summary.manifold {
        return Err(RepairError::NotManifold {
            edges: summary.n_non_manifold_edges,
            vertices: summary.n_non_manifold_vertices,
        });
    }
    Ok(mesh)
}

/// One vertex per face fan of `mesh` (whose summary is `before`), its edges of three or
/// more faces cut apart first when `cut` (two-sided faces made one-sided before): the
/// mesh and its summary after.
fn split_fans(
    mesh: Mesh,
    cut: bool,
    before: &TopologySummary,
    topology: &impl Fn(&Mesh) -> Result<Arc<Topology>, TopologyError>,
    notes: &mut Vec<String>,
) -> Result<(Mesh, TopologySummary), RepairError> {
    let (mesh, cut_edges, copies) = if cut {
        // A two-sided face (two faces back to back) has no dual: one side stays.
        let (m, dropped) = hygiene::drop_two_sided_faces(mesh);
        if dropped > 0 {
            notes.push(format!(
                "{dropped} faces dropped that lay back to back on another face (two-sided faces made one-sided)"
            ));
        }
        let topo = topology(&m)?;
        let (m, c) = hygiene::cut_non_manifold_edges_with(m, &topo);
        (m, c.edges, c.copies)
    } else {
        let topo = topology(&mesh)?;
        let (m, copies) = hygiene::split_non_manifold_vertices_with(mesh, &topo);
        (m, 0, copies)
    };
    let after = topology(&mesh)?.summary(&mesh);
    if copies > 0 {
        let cut_note = if cut_edges > 0 {
            format!("{cut_edges} {CUT_EDGES_NOTE}, ")
        } else {
            String::new()
        };
        notes.push(format!(
            "{cut_note}{} non-manifold vertices {SPLIT_FANS_NOTE} ({copies} copies added)",
            before.n_non_manifold_vertices - after.n_non_manifold_vertices
        ));
    }
    Ok((mesh, after))
}

/// `mesh` with the faces of its pieces too small for a dual (a boundary loop along fewer
/// than three faces, as a lone triangle cut off) split 1-to-4.
fn split_small_pieces(
    mesh: Mesh,
    topology: &impl Fn(&Mesh) -> Result<Arc<Topology>, TopologyError>,
    notes: &mut Vec<String>,
) -> Result<Mesh, RepairError> {
    let topo = topology(&mesh)?;
    if hygiene::small_pieces(&topo).is_empty() {
        return Ok(mesh);
    }
    let (split, n) = hygiene::split_small_pieces(mesh, &topo);
    notes.push(format!(
        "{n} faces split 1-to-4 in pieces whose boundary runs along fewer than three faces (a dual needs three)"
    ));
    Ok(split)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::{bowtie, tetrahedron};
    use std::cell::Cell;

    /// `ready` with an adjacency built on every call, counting the calls.
    fn ready_counting(mesh: Mesh, needs: Needs) -> (Result<Readied, RepairError>, usize) {
        let calls = Cell::new(0);
        let out = ready(mesh, needs, |m| {
            calls.set(calls.get() + 1);
            Topology::try_build(m).map(Arc::new)
        });
        (out, calls.get())
    }

    #[test]
    fn a_step_that_only_asks_for_the_split_builds_nothing_on_one_fan_everywhere() {
        let split_fans = Needs {
            split_fans: true,
            ..Needs::default()
        };
        let (out, calls) = ready_counting(tetrahedron(), split_fans);
        let out = out.unwrap();
        assert_eq!((out.mesh, out.notes.len(), calls), (tetrahedron(), 0, 0));
        // Nothing asked: nothing tested.
        let (out, calls) = ready_counting(bowtie(), Needs::default());
        assert_eq!((out.unwrap().mesh, calls), (bowtie(), 0));
    }

    #[test]
    fn a_bow_tie_is_split_per_fan_and_noted() {
        let split_fans = Needs {
            split_fans: true,
            ..Needs::default()
        };
        let out = ready_counting(bowtie(), split_fans).0.unwrap();
        assert_eq!(out.mesh.n_vertices(), 6);
        assert_eq!(out.notes.len(), 1);
        assert!(out.notes[0].contains(SPLIT_FANS_NOTE), "{:?}", out.notes);
        let manifold = Needs {
            manifold: true,
            ..Needs::default()
        };
        let out = ready_counting(bowtie(), manifold).0.unwrap();
        assert!(Topology::build(&out.mesh).is_manifold());
    }

    #[test]
    fn a_manifold_mesh_is_tested_once_and_given_back() {
        let manifold = Needs {
            manifold: true,
            cut_ahead: true,
            ..Needs::default()
        };
        let (out, calls) = ready_counting(tetrahedron(), manifold);
        let out = out.unwrap();
        assert_eq!((out.mesh, out.notes.len()), (tetrahedron(), 0));
        // Once ahead, once for the step, once for the small pieces: a caller that keeps
        // the adjacency builds it once.
        assert_eq!(calls, 3);
    }
}
