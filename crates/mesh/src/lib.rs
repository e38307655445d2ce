//! The mesh of coarsen: an indexed triangle mesh in `f64` with named attribute columns.
//!
//! * [`Mesh`]: positions (`DVec3`), faces (`[u32; 3]`, consistently oriented),
//!   per-vertex and per-face [`Attributes`], and the edges the input marks as features.
//! * [`wedge`]: per-corner attributes ([`Wedges`]): a vertex's distinct UVs and normals
//!   across seams and hard edges, and which corners use which.
//! * [`material`]: materials and textures a file named, carried for writing back.
//! * [`carry`]: how a stage that changes connectivity says where each new vertex and face
//!   came from ([`VertexOrigins`], [`FaceOrigins`]) so that one routine carries every
//!   attribute.
//! * [`topology`]: adjacency built from the arrays (CSR), boundary loops, components,
//!   manifoldness, genus, orientation.
//! * [`sanity`]: the exhaustive invariant check that tests and debug runs call after
//!   every stage.
//! * [`hygiene`]: the explicit, reported clean-up steps applied after loading a file.
//! * [`repair`]: the repairs that ready a mesh for a step of a run (pinched vertices split,
//!   edges of three or more faces cut, pieces too small for a dual split), by what it needs.
//! * [`ring`]: whether the faces around a vertex form one oriented fan.
//! * [`order`]: vertices and faces renumbered along a Morton curve, for memory locality.
//!
//! The mesh knows no stage, no pipeline file and no file format.
//!
//! ```
//! use coarsen_mesh::{Mesh, DVec3};
//! let mesh = Mesh::new(
//!     vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
//!     vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
//! );
//! assert_eq!(mesh.n_faces(), 4);
//! assert!(mesh.validate_indices().is_ok());
//! ```

pub mod attribute;
pub mod carry;
pub mod hygiene;
pub mod material;
pub mod order;
pub mod repair;
pub mod ring;
pub mod sanity;
pub mod scale;
pub mod topology;
pub mod wedge;

#[cfg(test)]
mod fixtures;

pub use attribute::{AttrKind, AttrValues, Attributes, Domain};
pub use carry::{CarryReport, FaceOrigins, VertexOrigins};
pub use coarsen_geom::{Aabb, DVec2, DVec3};
pub use hygiene::{HygieneError, HygieneOptions, HygieneReport, clean};
pub use material::{Image, Materials};
pub use sanity::{SanityError, SanityOptions, sanity_check, sanity_check_with};
pub use topology::Topology;
pub use topology::{TopologyError, TopologySummary};
pub use wedge::Wedges;

use coarsen_geom::triangle;

/// A vertex or face index.
pub type Index = u32;

/// An indexed triangle mesh with named per-vertex and per-face attributes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<DVec3>,
    /// Triangles as vertex indices, counter-clockwise seen from outside.
    pub faces: Vec<[Index; 3]>,
    /// Per-vertex attribute columns, each `positions.len()` long.
    pub vertex_attrs: Attributes,
    /// Per-face attribute columns, each `faces.len()` long.
    pub face_attrs: Attributes,
    /// Per-corner attributes (UV seams, hard edges) as wedges; empty when there are none.
    pub wedges: Wedges,
    /// Materials and textures the file named, carried unchanged for writing back; the
    /// face label column `material` says which one each face uses.
    pub materials: Materials,
    /// The edges the input marks as features (an OBJ `l`, a PLY `edge` element), as
    /// vertex pairs; empty by default, and not carried by [`Mesh::rebuilt`].
    pub marked_edges: Vec<[Index; 2]>,
}

/// An index out of range, a wrong column length or a repeated index in one face.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum IndexError {
    /// A face names a vertex that does not exist.
    #[error("face {face} names vertex {vertex}, but the mesh has {n_vertices} vertices")]
    OutOfRange {
        /// The face.
        face: usize,
        /// The vertex index it names.
        vertex: Index,
        /// How many vertices there are.
        n_vertices: usize,
    },
    /// An attribute column whose length differs from its domain's element count.
    #[error("{domain} attribute `{name}` has {len} values for {expected} elements")]
    AttributeLength {
        /// Vertex or face.
        domain: Domain,
        /// The attribute.
        name: String,
        /// Its length.
        len: usize,
        /// The element count.
        expected: usize,
    },
    /// A marked edge names a vertex that does not exist.
    #[error("marked edge {edge} names vertex {vertex}, but the mesh has {n_vertices} vertices")]
    EdgeOutOfRange {
        /// The edge's position in [`Mesh::marked_edges`].
        edge: usize,
        /// The vertex index it names.
        vertex: Index,
        /// How many vertices there are.
        n_vertices: usize,
    },
    /// Wedges that do not match the faces.
    #[error("wedges: {detail}")]
    Wedge {
        /// What is wrong.
        detail: String,
    },
    /// More elements than `u32` indices can address.
    #[error("{count} {what} do not fit 32-bit indices")]
    TooMany {
        /// How many.
        count: usize,
        /// Of what.
        what: &'static str,
    },
}

impl Mesh {
    /// A mesh without attributes.
    pub fn new(positions: Vec<DVec3>, faces: Vec<[Index; 3]>) -> Self {
        Mesh {
            positions,
            faces,
            ..Default::default()
        }
    }

    /// Number of vertices.
    #[inline]
    pub fn n_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of faces.
    #[inline]
    pub fn n_faces(&self) -> usize {
        self.faces.len()
    }

    /// The three corner positions of face `f`.
    #[inline]
    pub fn corners(&self, f: usize) -> [DVec3; 3] {
        let [a, b, c] = self.faces[f];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Area of face `f`.
    #[inline]
    pub fn face_area(&self, f: usize) -> f64 {
        let [a, b, c] = self.corners(f);
        triangle::area(a, b, c)
    }

    /// Unit normal of face `f` (zero when degenerate).
    #[inline]
    pub fn face_normal(&self, f: usize) -> DVec3 {
        let [a, b, c] = self.corners(f);
        triangle::normal(a, b, c)
    }

    /// The summed cross products of `faces` (twice their area-weighted normal; the side
    /// they face together).
    pub fn faces_cross(&self, faces: &[u32]) -> DVec3 {
        faces
            .iter()
            .map(|&f| {
                let [a, b, c] = self.corners(f as usize);
                triangle::cross(a, b, c)
            })
            .sum()
    }

    /// Centroid of face `f`.
    #[inline]
    pub fn face_centroid(&self, f: usize) -> DVec3 {
        let [a, b, c] = self.corners(f);
        triangle::centroid(a, b, c)
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        (0..self.n_faces()).map(|f| self.face_area(f)).sum()
    }

    /// Signed enclosed volume (meaningful for closed, consistently oriented meshes).
    pub fn signed_volume(&self) -> f64 {
        (0..self.n_faces())
            .map(|f| {
                let [a, b, c] = self.corners(f);
                a.dot(b.cross(c))
            })
            .sum::<f64>()
            / 6.0
    }

    /// Bounding box of the vertex positions.
    pub fn bbox(&self) -> Aabb {
        Aabb::from_points(&self.positions)
    }

    /// Area-weighted unit vertex normals (zero at isolated or fully degenerate vertices).
    pub fn vertex_normals(&self) -> Vec<DVec3> {
        let mut n = vec![DVec3::ZERO; self.n_vertices()];
        for f in &self.faces {
            let [a, b, c] = f.map(|i| self.positions[i as usize]);
            let w = triangle::cross(a, b, c);
            for &i in f {
                n[i as usize] += w;
            }
        }
        n.iter_mut().for_each(|v| *v = v.normalize_or_zero());
        n
    }

    /// Checks that every face index and marked edge end is in range, that the counts fit
    /// `u32`, and that every attribute column has the right length.
    pub fn validate_indices(&self) -> Result<(), IndexError> {
        if self.positions.len() > Index::MAX as usize {
            return Err(IndexError::TooMany {
                count: self.positions.len(),
                what: "vertices",
            });
        }
        if self.faces.len() > Index::MAX as usize {
            return Err(IndexError::TooMany {
                count: self.faces.len(),
                what: "faces",
            });
        }
        let n = self.positions.len();
        for (face, f) in self.faces.iter().enumerate() {
            if let Some(&vertex) = f.iter().find(|&&v| v as usize >= n) {
                return Err(IndexError::OutOfRange {
                    face,
                    vertex,
                    n_vertices: n,
                });
            }
        }
        for (edge, e) in self.marked_edges.iter().enumerate() {
            if let Some(&vertex) = e.iter().find(|&&v| v as usize >= n) {
                return Err(IndexError::EdgeOutOfRange {
                    edge,
                    vertex,
                    n_vertices: n,
                });
            }
        }
        self.vertex_attrs.check_len(Domain::Vertex, n)?;
        self.face_attrs.check_len(Domain::Face, self.faces.len())?;
        self.wedges.check(&self.faces)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::tetrahedron;

    #[test]
    fn tetrahedron_volume_and_area() {
        let m = tetrahedron();
        assert!((m.signed_volume() - 1.0 / 6.0).abs() < 1e-12);
        let expect = 1.5 + 3f64.sqrt() / 2.0;
        assert!((m.area() - expect).abs() < 1e-12);
        assert!((m.bbox().diagonal() - 3f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn out_of_range_index_is_named() {
        let mut m = tetrahedron();
        m.faces[2] = [1, 2, 9];
        assert_eq!(
            m.validate_indices(),
            Err(IndexError::OutOfRange {
                face: 2,
                vertex: 9,
                n_vertices: 4
            })
        );
    }

    #[test]
    fn out_of_range_marked_edge_is_named() {
        let mut m = tetrahedron();
        m.marked_edges = vec![[0, 1], [3, 4]];
        assert_eq!(
            m.validate_indices(),
            Err(IndexError::EdgeOutOfRange {
                edge: 1,
                vertex: 4,
                n_vertices: 4
            })
        );
        assert_eq!(
            m.validate_indices().unwrap_err().to_string(),
            "marked edge 1 names vertex 4, but the mesh has 4 vertices"
        );
        m.marked_edges.pop();
        assert!(m.validate_indices().is_ok());
    }

    #[test]
    fn faces_cross_sums_twice_the_area_weighted_normals() {
        // The unit square in z = 0 as two triangles, counter-clockwise seen from +z.
        let square = Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        assert_eq!(square.faces_cross(&[0, 1]), DVec3::new(0.0, 0.0, 2.0));
        assert_eq!(square.faces_cross(&[1]), DVec3::new(0.0, 0.0, 1.0));
        assert_eq!(square.faces_cross(&[]), DVec3::ZERO);
        // A closed surface faces no side.
        let t = tetrahedron();
        assert!(t.faces_cross(&[0, 1, 2, 3]).length() < 1e-15);
    }

    #[test]
    fn vertex_normals_point_outward_on_a_closed_mesh() {
        let m = tetrahedron();
        let n = m.vertex_normals();
        let c = m.positions.iter().copied().sum::<DVec3>() / 4.0;
        for (p, n) in m.positions.iter().zip(&n) {
            assert!((*p - c).dot(*n) > 0.0);
        }
    }
}
