//! Per-corner attributes kept as wedges: texture coordinates across seams, normals across
//! hard edges.
//!
//! A *wedge* is one of a vertex's distinct attribute values: the corners of the faces
//! around a vertex that agree on every per-corner column share a wedge, and a vertex on a
//! UV seam or a hard edge has one wedge per side. [`Wedges`] holds, for every face corner
//! (`3 · face + k`), the wedge it uses, for every wedge its vertex, and the per-wedge
//! columns. Nothing read from a file is lost: a glTF vertex, an OBJ `v/vt/vn` triple, is
//! a wedge. A `uv` column counts `v` up from the image's bottom row, as OBJ and PLY do
//! (the glTF reader and writer turn glTF's `v`, which counts down from its top).
//!
//! A column whose wedges agree at every vertex is no different from a per-vertex column;
//! [`Mesh::with_corner_attributes`] keeps such columns per vertex (where every stage
//! carries them) and only the others as wedges. Connectivity changes carry wedges through
//! [`Mesh::rebuilt`] when every new corner can be traced to a corner of its parent face,
//! and name them in the [`CarryReport`](crate::CarryReport) otherwise.

use crate::{AttrValues, Attributes, Index, IndexError, Mesh};

/// Per-corner attributes: every face corner names a wedge of its vertex; wedges hold the
/// values.
///
/// Empty (no column, no corner) on a mesh without per-corner attributes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Wedges {
    /// For each face corner `3 · face + k`, the wedge it uses.
    corners: Vec<Index>,
    /// For each wedge, its vertex.
    vertex: Vec<Index>,
    /// Per-wedge columns, each one value per wedge.
    attrs: Attributes,
}

impl Wedges {
    /// Wedges from per-corner columns (each `3 · faces.len()` values, corner `3 · f + k`
    /// being corner `k` of face `f`): corners of one vertex whose values are bit for bit
    /// equal in every column share a wedge; wedges are numbered in the order of their
    /// first corner. No column gives no wedges.
    ///
    /// Panics when a column's length is not three per face (a caller's bug).
    pub fn from_corners(faces: &[[Index; 3]], columns: Attributes) -> Wedges {
        if columns.is_empty() {
            return Wedges::default();
        }
        let n_corners = 3 * faces.len();
        for (name, v) in columns.iter() {
            assert_eq!(
                v.len(),
                n_corners,
                "corner column `{name}`: one value per corner"
            );
        }
        let n_vertices = faces
            .iter()
            .flatten()
            .map(|&v| v as usize + 1)
            .max()
            .unwrap_or(0);
        // The wedges of each vertex as a linked list: head per vertex, next per wedge.
        let mut head = vec![Index::MAX; n_vertices];
        let mut next: Vec<Index> = Vec::new();
        let mut first_corner: Vec<Index> = Vec::new();
        let mut vertex: Vec<Index> = Vec::new();
        let mut corners = Vec::with_capacity(n_corners);
        for (c, &v) in faces.iter().flatten().enumerate() {
            let mut w = head[v as usize];
            while w != Index::MAX && !same_values(&columns, first_corner[w as usize] as usize, c) {
                w = next[w as usize];
            }
            if w == Index::MAX {
                w = vertex.len() as Index;
                vertex.push(v);
                first_corner.push(c as Index);
                next.push(head[v as usize]);
                head[v as usize] = w;
            }
            corners.push(w);
        }
        Wedges {
            corners,
            vertex,
            attrs: columns.gather(&first_corner),
        }
    }

    /// True when there is no per-corner column.
    pub fn is_empty(&self) -> bool {
        self.attrs.is_empty()
    }

    /// Number of wedges.
    pub fn len(&self) -> usize {
        self.vertex.len()
    }

    /// The wedge of each face corner (`3 · face + k`).
    pub fn corners(&self) -> &[Index] {
        &self.corners
    }

    /// The wedge of corner `k` of face `f`.
    pub fn corner(&self, f: usize, k: usize) -> Index {
        self.corners[3 * f + k]
    }

    /// The vertex of each wedge.
    pub fn vertices(&self) -> &[Index] {
        &self.vertex
    }

    /// The per-wedge columns.
    pub fn attrs(&self) -> &Attributes {
        &self.attrs
    }

    /// Every column expanded to one value per face corner.
    pub fn corner_values(&self) -> Attributes {
        self.attrs.gather(&self.corners)
    }

    /// The seam edges of `faces` (smaller vertex first, sorted): edges of two faces whose
    /// corners disagree at either end on a column other than `normal` (UV seams; a hard
    /// edge of normals alone is no seam).
    pub fn seam_edges(&self, faces: &[[Index; 3]]) -> Vec<[Index; 2]> {
        if self.is_empty() || self.corners.len() != 3 * faces.len() {
            return Vec::new();
        }
        let columns: Vec<&AttrValues> = self
            .attrs
            .iter()
            .filter(|(name, _)| *name != "normal")
            .map(|(_, v)| v)
            .collect();
        let same = |a: Index, b: Index| columns.iter().all(|c| equal_at(c, a as usize, b as usize));
        // (edge, corner at its smaller end, corner at its larger end) for every face edge.
        let mut sides: Vec<([Index; 2], Index, Index)> = Vec::with_capacity(3 * faces.len());
        for (f, face) in faces.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (face[k], face[(k + 1) % 3]);
                let (ca, cb) = (3 * f + k, 3 * f + (k + 1) % 3);
                let (wa, wb) = (self.corners[ca], self.corners[cb]);
                sides.push(if a < b {
                    ([a, b], wa, wb)
                } else {
                    ([b, a], wb, wa)
                });
            }
        }
        sides.sort_unstable();
        sides
            .chunk_by(|x, y| x.0 == y.0)
            .filter(|run| run.len() == 2 && !(same(run[0].1, run[1].1) && same(run[0].2, run[1].2)))
            .map(|run| run[0].0)
            .collect()
    }

    /// How many vertices have two wedges or more (seam and hard-edge vertices).
    pub fn split_vertices(&self) -> usize {
        let mut seen: Vec<u8> = Vec::new();
        for &v in &self.vertex {
            let v = v as usize;
            if v >= seen.len() {
                seen.resize(v + 1, 0);
            }
            seen[v] = seen[v].saturating_add(1);
        }
        seen.iter().filter(|&&n| n > 1).count()
    }

    /// The wedges of new faces, each the same corners in the same order as an old face:
    /// new face `i` is old face `parents[i]` (its vertices maybe renumbered or welded
    /// into `new_faces[i]`).
    pub fn follow_faces(&self, parents: &[Index], new_faces: &[[Index; 3]]) -> Wedges {
        if self.is_empty() {
            return Wedges::default();
        }
        let corners: Vec<Index> = parents
            .iter()
            .flat_map(|&p| (0..3).map(move |k| 3 * p + k))
            .collect();
        self.regrouped(&corners, new_faces)
    }

    /// The same wedges on the faces renumbered: new face `i` is old face `faces[i]` (every
    /// old face once), its vertices renamed by `vertex_rank` (old vertex → new). The wedges
    /// keep their numbers and values.
    pub fn permuted(&self, faces: &[Index], vertex_rank: &[Index]) -> Wedges {
        if self.is_empty() {
            return Wedges::default();
        }
        Wedges {
            corners: faces
                .iter()
                .flat_map(|&f| (0..3).map(move |k| self.corners[3 * f as usize + k]))
                .collect(),
            vertex: self
                .vertex
                .iter()
                .map(|&v| vertex_rank[v as usize])
                .collect(),
            attrs: self.attrs.clone(),
        }
    }

    /// Wedges for `new_faces` whose corner `c` takes the values of old corner
    /// `old_corners[c]`, regrouped by the new vertices.
    pub(crate) fn regrouped(&self, old_corners: &[Index], new_faces: &[[Index; 3]]) -> Wedges {
        let old_wedge: Vec<Index> = old_corners
            .iter()
            .map(|&c| self.corners[c as usize])
            .collect();
        Wedges::from_corners(new_faces, self.attrs.gather(&old_wedge))
    }

    /// Removes the columns that are per vertex in disguise (every wedge of each vertex
    /// holding the same value) and returns them as vertex columns of `n_vertices` values;
    /// a vertex without a wedge gets the column's zero. The remaining columns are regrouped.
    pub fn take_per_vertex(&mut self, faces: &[[Index; 3]], n_vertices: usize) -> Attributes {
        let mut per_vertex = Attributes::default();
        if self.is_empty() {
            return per_vertex;
        }
        let mut first = vec![Index::MAX; n_vertices];
        for (w, &v) in self.vertex.iter().enumerate() {
            if first[v as usize] == Index::MAX {
                first[v as usize] = w as Index;
            }
        }
        let mut kept = Attributes::default();
        for (name, values) in self.attrs.iter() {
            let uniform = self
                .vertex
                .iter()
                .enumerate()
                .all(|(w, &v)| equal_at(values, first[v as usize] as usize, w));
            if uniform {
                per_vertex.insert(name, gather_or_zero(values, &first));
            } else {
                kept.insert(name, values.clone());
            }
        }
        if per_vertex.is_empty() {
            return per_vertex;
        }
        let kept_corners = kept.gather(&self.corners);
        *self = Wedges::from_corners(faces, kept_corners);
        per_vertex
    }

    /// Checks the wedges against the mesh's faces: one wedge per corner, in range, of the
    /// corner's vertex, and every column one value per wedge.
    pub fn check(&self, faces: &[[Index; 3]]) -> Result<(), IndexError> {
        if self.is_empty() {
            if self.corners.is_empty() && self.vertex.is_empty() {
                return Ok(());
            }
            return Err(IndexError::Wedge {
                detail: "wedges without a column".into(),
            });
        }
        if self.corners.len() != 3 * faces.len() {
            return Err(IndexError::Wedge {
                detail: format!("{} corners for {} faces", self.corners.len(), faces.len()),
            });
        }
        for (c, (&w, &v)) in self.corners.iter().zip(faces.iter().flatten()).enumerate() {
            match self.vertex.get(w as usize) {
                Some(&owner) if owner == v => {}
                Some(&owner) => {
                    return Err(IndexError::Wedge {
                        detail: format!(
                            "corner {} of face {} (vertex {v}) uses wedge {w} of vertex {owner}",
                            c % 3,
                            c / 3
                        ),
                    });
                }
                None => {
                    return Err(IndexError::Wedge {
                        detail: format!(
                            "corner {} of face {} uses wedge {w}, but there are {} wedges",
                            c % 3,
                            c / 3,
                            self.vertex.len()
                        ),
                    });
                }
            }
        }
        self.attrs
            .check_len(crate::Domain::Vertex, self.vertex.len())
            .map_err(|e| IndexError::Wedge {
                detail: e.to_string().replacen("vertex", "wedge", 1),
            })
    }

    /// The first non-finite value of a column, as `(name, wedge)`.
    pub(crate) fn first_non_finite(&self) -> Option<(&str, usize)> {
        self.attrs
            .iter()
            .find_map(|(n, v)| v.first_non_finite().map(|i| (n, i)))
    }
}

/// Whether corners `a` and `b` hold bit for bit the same value in every column.
fn same_values(columns: &Attributes, a: usize, b: usize) -> bool {
    columns.iter().all(|(_, v)| equal_at(v, a, b))
}

/// Whether `values[a]` and `values[b]` are bit for bit equal.
fn equal_at(values: &AttrValues, a: usize, b: usize) -> bool {
    match values {
        AttrValues::Scalar(v) => v[a].to_bits() == v[b].to_bits(),
        AttrValues::Vec2(v) => {
            v[a].to_array().map(f64::to_bits) == v[b].to_array().map(f64::to_bits)
        }
        AttrValues::Vec3(v) => {
            v[a].to_array().map(f64::to_bits) == v[b].to_array().map(f64::to_bits)
        }
        AttrValues::Label(v) => v[a] == v[b],
        AttrValues::Color(v) => v[a] == v[b],
    }
}

/// `values[i]` for each `i` of `indices`, the zero value where `i` is `Index::MAX`.
fn gather_or_zero(values: &AttrValues, indices: &[Index]) -> AttrValues {
    fn pick<T: Copy + Default>(v: &[T], idx: &[Index]) -> Vec<T> {
        idx.iter()
            .map(|&i| v.get(i as usize).copied().unwrap_or_default())
            .collect()
    }
    match values {
        AttrValues::Scalar(v) => AttrValues::Scalar(pick(v, indices)),
        AttrValues::Vec2(v) => AttrValues::Vec2(pick(v, indices)),
        AttrValues::Vec3(v) => AttrValues::Vec3(pick(v, indices)),
        AttrValues::Label(v) => AttrValues::Label(pick(v, indices)),
        AttrValues::Color(v) => AttrValues::Color(pick(v, indices)),
    }
}

impl Mesh {
    /// `self` with per-corner columns (one value per face corner, `3 · face + k`) added:
    /// a column that holds one value per vertex (every corner of each vertex agreeing bit
    /// for bit) becomes a vertex column, the rest become [`Wedges`]. Replaces any wedges.
    pub fn with_corner_attributes(mut self, columns: Attributes) -> Mesh {
        let mut wedges = Wedges::from_corners(&self.faces, columns);
        let per_vertex = wedges.take_per_vertex(&self.faces, self.n_vertices());
        for (name, values) in per_vertex.iter() {
            self.vertex_attrs.insert(name, values.clone());
        }
        self.wedges = wedges;
        self
    }

    /// The value of wedge column `name` at every face corner: from the wedges when they
    /// hold it, else from the vertex column of that name; `None` when neither does.
    pub fn corner_column(&self, name: &str) -> Option<AttrValues> {
        if let Some(values) = self.wedges.attrs.get(name) {
            return Some(values.gather(&self.wedges.corners));
        }
        let values = self.vertex_attrs.get(name)?;
        let idx: Vec<Index> = self.faces.iter().flatten().copied().collect();
        Some(values.gather(&idx))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DVec2;
    use coarsen_geom::DVec3;

    /// Two triangles sharing the edge 1–2, with a UV seam along it.
    fn seamed() -> (Mesh, Attributes) {
        let m = Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 0.0)],
            vec![[0, 1, 2], [1, 3, 2]],
        );
        let uv = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(0.5, 0.0),
            DVec2::new(0.0, 0.5),
            DVec2::new(0.6, 0.0), // vertex 1 again, other side of the seam
            DVec2::new(1.0, 1.0),
            DVec2::new(0.0, 0.6), // vertex 2 again
        ];
        let mut cols = Attributes::default();
        cols.insert("uv", AttrValues::Vec2(uv));
        cols.insert("normal", AttrValues::Vec3(vec![DVec3::Z; 6]));
        (m, cols)
    }

    #[test]
    fn seam_edges_are_those_whose_faces_disagree_but_not_on_normals_alone() {
        let (m, cols) = seamed();
        let w = Wedges::from_corners(&m.faces, cols.clone());
        assert_eq!(w.seam_edges(&m.faces), vec![[1, 2]]);
        // Normals that differ across the edge (a hard edge) make no seam.
        let mut normals = Attributes::default();
        let n = [DVec3::Z, DVec3::Z, DVec3::Z, DVec3::X, DVec3::X, DVec3::X];
        normals.insert("normal", AttrValues::Vec3(n.to_vec()));
        let hard = Wedges::from_corners(&m.faces, normals);
        assert!(hard.seam_edges(&m.faces).is_empty());
        assert!(Wedges::default().seam_edges(&m.faces).is_empty());
    }

    #[test]
    fn seams_become_wedges_and_uniform_columns_become_vertex_columns() {
        let (m, cols) = seamed();
        let m = m.with_corner_attributes(cols.clone());
        assert_eq!(m.vertex_attrs.vec3("normal").unwrap(), &[DVec3::Z; 4]);
        assert!(m.wedges.attrs().get("normal").is_none());
        assert_eq!(m.wedges.len(), 6);
        assert_eq!(m.wedges.split_vertices(), 2);
        assert_eq!(m.wedges.vertices(), &[0, 1, 2, 1, 3, 2]);
        assert!(m.validate_indices().is_ok());
        assert_eq!(m.corner_column("uv"), cols.get("uv").cloned());
        assert_eq!(m.corner_column("normal"), cols.get("normal").cloned());
    }

    #[test]
    fn equal_values_at_one_vertex_share_a_wedge() {
        let (m, mut cols) = seamed();
        cols.insert(
            "uv",
            AttrValues::Vec2(vec![
                DVec2::ZERO,
                DVec2::X,
                DVec2::Y,
                DVec2::X,
                DVec2::ONE,
                DVec2::Y,
            ]),
        );
        let m = m.with_corner_attributes(cols);
        assert!(m.wedges.is_empty());
        assert_eq!(
            m.vertex_attrs.vec2("uv").unwrap(),
            &[DVec2::ZERO, DVec2::X, DVec2::Y, DVec2::ONE]
        );
    }

    #[test]
    fn a_wedge_of_another_vertex_is_an_error() {
        let (m, cols) = seamed();
        let mut m = m.with_corner_attributes(cols);
        m.wedges.corners.swap(0, 1);
        let e = m.validate_indices().unwrap_err().to_string();
        assert!(
            e.contains("corner 0 of face 0 (vertex 0) uses wedge 1 of vertex 1"),
            "{e}"
        );
        m.wedges.corners.pop();
        assert!(
            m.validate_indices()
                .unwrap_err()
                .to_string()
                .contains("5 corners")
        );
    }

    #[test]
    fn following_faces_keeps_corner_values() {
        let (m, cols) = seamed();
        let m = m.with_corner_attributes(cols.clone());
        // Keep face 1 only, its vertices renumbered 1→0, 3→1, 2→2.
        let w = m.wedges.follow_faces(&[1], &[[0, 1, 2]]);
        assert_eq!(
            w.corner_values().vec2("uv").unwrap(),
            &cols.vec2("uv").unwrap()[3..6]
        );
        assert_eq!(w.vertices(), &[0, 1, 2]);
    }
}
