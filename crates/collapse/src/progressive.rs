//! The progressive record of a run: what undoing each collapse (a vertex split) needs.
//!
//! Recording is off unless [`LiveMesh::record_progressive`](crate::LiveMesh::record_progressive)
//! asked for it. The record is flat: one [`Step`] per collapse, and three arenas (old
//! positions, deleted faces, renamed faces) that the steps index by their counts, so no
//! collapse allocates anything of its own.
//!
//! Indices are those of the engine's input mesh. The coarse mesh that
//! [`LiveMesh::to_mesh`](crate::LiveMesh::to_mesh) writes is compacted: its vertices are the
//! input vertices that no step removed and that some face used, in input order; its faces
//! are the input faces that no step deleted, in input order. That is the whole compaction
//! map, so the record does not store it.

use crate::{Index, NONE};
use coarsen_geom::DVec3;
use coarsen_mesh::Mesh;

/// One collapse, as its undo needs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Step {
    /// The vertex that survived the collapse.
    pub kept: Index,
    /// The vertices merged into it ([`NONE`] when unused: an edge collapse removes one).
    pub removed: [Index; 2],
    /// How many faces the collapse deleted (their entries in [`Progressive::deleted`]).
    pub deleted: u32,
    /// How many faces the collapse renamed (their entries in [`Progressive::changed`]).
    pub changed: u32,
}

impl Step {
    /// The removed vertices, without the [`NONE`] padding.
    pub fn removed(&self) -> impl Iterator<Item = Index> + '_ {
        self.removed.iter().copied().filter(|&v| v != NONE)
    }

    /// How many vertices the collapse removed (1 or 2).
    pub fn n_removed(&self) -> usize {
        self.removed().count()
    }

    /// How many positions the step owns in [`Progressive::positions`]: the kept vertex's
    /// and each removed vertex's.
    pub fn n_positions(&self) -> usize {
        1 + self.n_removed()
    }
}

/// A face a collapse deleted, with its corners just before the collapse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeletedFace {
    /// The face (input face index).
    pub face: Index,
    /// Its vertices before the collapse.
    pub corners: [Index; 3],
}

/// A face a collapse renamed: its corner that holds the kept vertex after the collapse held
/// `vertex` (a removed vertex) before; its other corners did not change.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChangedFace {
    /// The face (input face index).
    pub face: Index,
    /// The vertex at the renamed corner before the collapse.
    pub vertex: Index,
}

/// Every collapse of a run in order, with what undoing it needs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Progressive {
    /// Vertices of the engine's input mesh.
    pub input_vertices: u32,
    /// Faces of the engine's input mesh.
    pub input_faces: u32,
    /// Input vertices that no face used (dropped from the coarse mesh), with their positions.
    pub isolated: Vec<(Index, DVec3)>,
    /// The collapses, in the order they were made.
    pub steps: Vec<Step>,
    /// Per step, in step order: the kept vertex's position, then each removed vertex's,
    /// all as they were just before the collapse.
    pub positions: Vec<DVec3>,
    /// Per step, in step order: the faces it deleted.
    pub deleted: Vec<DeletedFace>,
    /// Per step, in step order: the faces it renamed.
    pub changed: Vec<ChangedFace>,
    /// [`fingerprint`] of the coarse mesh the record undoes from.
    pub coarse: u64,
}

impl Progressive {
    /// A record of a mesh with these counts and no collapse yet.
    pub fn new(input_vertices: u32, input_faces: u32) -> Self {
        Progressive {
            input_vertices,
            input_faces,
            ..Default::default()
        }
    }

    /// Vertices of the coarse mesh: the input's, less the isolated and removed ones.
    pub fn coarse_vertices(&self) -> usize {
        let removed: usize = self.steps.iter().map(Step::n_removed).sum();
        (self.input_vertices as usize)
            .saturating_sub(self.isolated.len())
            .saturating_sub(removed)
    }

    /// Faces of the coarse mesh: the input's, less the deleted ones.
    pub fn coarse_faces(&self) -> usize {
        (self.input_faces as usize).saturating_sub(self.deleted.len())
    }

    /// Multiplies every recorded position by `2^k`, exactly as
    /// [`coarsen_mesh::scale::scale_by_power_of_two`] does a mesh's (so that a record taken
    /// on a rescaled mesh speaks the input's units). The coarse fingerprint is left alone.
    pub fn scale_by_power_of_two(&mut self, k: i32) {
        let mut m = Mesh::new(std::mem::take(&mut self.positions), Vec::new());
        coarsen_mesh::scale::scale_by_power_of_two(&mut m, k);
        self.positions = m.positions;
        let mut m = Mesh::new(self.isolated.iter().map(|&(_, p)| p).collect(), Vec::new());
        coarsen_mesh::scale::scale_by_power_of_two(&mut m, k);
        for ((_, p), q) in self.isolated.iter_mut().zip(m.positions) {
            *p = q;
        }
    }
}

/// A 64-bit digest of a mesh's positions (their bits) and faces, to tell whether a coarse
/// mesh is the one a record was taken from (FNV-1a; not cryptographic).
pub fn fingerprint(mesh: &Mesh) -> u64 {
    let mut h = Fnv::default();
    h.write(&(mesh.n_vertices() as u64).to_le_bytes());
    h.write(&(mesh.n_faces() as u64).to_le_bytes());
    for p in &mesh.positions {
        for x in p.to_array() {
            h.write(&x.to_bits().to_le_bytes());
        }
    }
    for f in &mesh.faces {
        for v in f {
            h.write(&v.to_le_bytes());
        }
    }
    h.finish()
}

/// The 64-bit FNV-1a hash.
#[derive(Clone, Copy, Debug)]
pub struct Fnv(u64);

impl Default for Fnv {
    fn default() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    /// Hashes `bytes` in.
    #[inline]
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// The hash so far.
    pub fn finish(&self) -> u64 {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fingerprint_sees_a_moved_bit_and_a_rotated_face() {
        let m = Mesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::Y], vec![[0, 1, 2]]);
        let mut moved = m.clone();
        moved.positions[1].x = f64::from_bits(1.0f64.to_bits() + 1);
        let mut rotated = m.clone();
        rotated.faces[0] = [1, 2, 0];
        let f = fingerprint(&m);
        assert_eq!(f, fingerprint(&m.clone()));
        assert_ne!(f, fingerprint(&moved));
        assert_ne!(f, fingerprint(&rotated));
        // Known FNV-1a value of the empty input.
        assert_eq!(Fnv::default().finish(), 0xcbf2_9ce4_8422_2325);
        let mut h = Fnv::default();
        h.write(b"a");
        assert_eq!(h.finish(), 0xaf63_dc4c_8601_ec8c);
    }

    #[test]
    fn counts_follow_the_steps_and_scaling_is_exact() {
        let mut p = Progressive::new(10, 16);
        p.isolated.push((9, DVec3::splat(3.0)));
        p.steps.push(Step {
            kept: 0,
            removed: [1, NONE],
            deleted: 2,
            changed: 3,
        });
        p.steps.push(Step {
            kept: 2,
            removed: [3, 4],
            deleted: 4,
            changed: 5,
        });
        assert_eq!(p.steps[1].n_positions(), 3);
        assert_eq!(p.coarse_vertices(), 10 - 1 - 3);
        p.deleted = vec![
            DeletedFace {
                face: 0,
                corners: [0, 1, 2]
            };
            6
        ];
        assert_eq!(p.coarse_faces(), 10);
        p.positions = vec![DVec3::new(0.1, -0.3, 7.0); 5];
        let before = p.clone();
        p.scale_by_power_of_two(-700);
        assert_ne!(p.positions, before.positions);
        p.scale_by_power_of_two(700);
        assert_eq!(p, before);
    }
}
