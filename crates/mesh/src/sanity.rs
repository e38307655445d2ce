//! The exhaustive invariant check that tests and debug runs call after every stage.
//!
//! [`sanity_check`] tests, in this order, and reports the first violation found (the
//! lowest element index within each test):
//!
//! 1. counts fit `u32`, face indices are in range, attribute columns have the right length;
//! 2. positions are finite, then float attribute values (vertex columns, then face columns);
//! 3. no face repeats a vertex index;
//! 4. no face has zero area: area exactly 0, or below
//!    [`SanityOptions::degenerate_area_rel`]` · (bbox diagonal)²`;
//! 5. no two faces have the same vertex set (in either orientation);
//! 6. when [`SanityOptions::require_manifold`]: no edge with three or more faces, no vertex
//!    whose faces form more than one fan;
//! 7. when [`SanityOptions::require_oriented`]: every edge with two faces is used once in
//!    each direction.

use crate::topology::{Topology, TopologyError};
use crate::{Domain, Index, IndexError, Mesh};
use coarsen_geom::is_finite;
use rayon::prelude::*;

/// The metrics' degenerate-face threshold: area below `1e-12 · (bbox diagonal)²`.
pub const DEGENERATE_AREA_REL: f64 = 1e-12;

/// Which optional invariants [`sanity_check_with`] enforces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SanityOptions {
    /// Reject edges with three or more faces and vertices with more than one fan.
    /// Default `false`.
    pub require_manifold: bool,
    /// Reject edges whose two faces use them in the same direction. Default `false`.
    pub require_oriented: bool,
    /// A face is degenerate when its area is zero or below this times the squared
    /// bounding-box diagonal. Default [`DEGENERATE_AREA_REL`].
    pub degenerate_area_rel: f64,
}

impl Default for SanityOptions {
    fn default() -> Self {
        Self {
            require_manifold: false,
            require_oriented: false,
            degenerate_area_rel: DEGENERATE_AREA_REL,
        }
    }
}

impl SanityOptions {
    /// Every invariant on: a closed or bordered, consistently oriented 2-manifold.
    pub fn strict() -> Self {
        Self {
            require_manifold: true,
            require_oriented: true,
            ..Self::default()
        }
    }
}

/// The first invariant a mesh breaks, with the offending elements.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SanityError {
    /// A face index out of range, a column of the wrong length, or too many elements.
    #[error(transparent)]
    Index(#[from] IndexError),
    /// The mesh is too large for the topology tables.
    #[error(transparent)]
    Topology(#[from] TopologyError),
    /// A position with a NaN or infinite coordinate.
    #[error("vertex {vertex} has a non-finite position")]
    NonFinitePosition {
        /// The vertex.
        vertex: usize,
    },
    /// A float attribute value that is NaN or infinite.
    #[error("{domain} attribute `{name}` is not finite at element {element}")]
    NonFiniteAttribute {
        /// Vertex or face column.
        domain: Domain,
        /// The column.
        name: String,
        /// The element.
        element: usize,
    },
    /// A face naming the same vertex twice.
    #[error("face {face} repeats vertex {vertex}")]
    RepeatedIndex {
        /// The face.
        face: usize,
        /// The repeated vertex.
        vertex: Index,
    },
    /// A face of (near) zero area.
    #[error("face {face} has area {area:e}, not above the degenerate threshold {threshold:e}")]
    ZeroArea {
        /// The face.
        face: usize,
        /// Its area.
        area: f64,
        /// The threshold it fails.
        threshold: f64,
    },
    /// Two faces on the same three vertices.
    #[error("face {face} has the same vertices as face {first}")]
    DuplicateFace {
        /// The later face.
        face: usize,
        /// The earlier face it duplicates.
        first: usize,
    },
    /// An edge with three or more faces.
    #[error("edge {a}-{b} has {} faces: {faces:?}", faces.len())]
    NonManifoldEdge {
        /// Smaller endpoint.
        a: Index,
        /// Larger endpoint.
        b: Index,
        /// Its faces.
        faces: Vec<Index>,
    },
    /// A vertex whose faces form several fans (a bow-tie or a vertex on a fin).
    #[error("vertex {vertex} has {n_fans} separate fans of faces")]
    NonManifoldVertex {
        /// The vertex.
        vertex: Index,
        /// How many fans.
        n_fans: usize,
    },
    /// Two faces using their shared edge in the same direction.
    #[error("faces {faces:?} both use edge {a}-{b} in the same direction")]
    OrientationFlip {
        /// Smaller endpoint.
        a: Index,
        /// Larger endpoint.
        b: Index,
        /// The two faces.
        faces: [Index; 2],
    },
}

/// Checks every default invariant of `mesh` (see the module docs); manifoldness and
/// orientation are not required.
pub fn sanity_check(mesh: &Mesh) -> Result<(), SanityError> {
    sanity_check_with(mesh, &SanityOptions::default())
}

/// Checks the invariants of `mesh` that `opts` selects, in the order of the module docs.
pub fn sanity_check_with(mesh: &Mesh, opts: &SanityOptions) -> Result<(), SanityError> {
    mesh.validate_indices()?;
    check_finite(mesh)?;
    check_faces(mesh, opts.degenerate_area_rel)?;
    check_duplicates(mesh, opts.require_manifold)?;
    if opts.require_manifold || opts.require_oriented {
        let topo = Topology::try_build(mesh)?;
        if opts.require_manifold {
            check_manifold(&topo)?;
        }
        if opts.require_oriented {
            check_oriented(&topo)?;
        }
    }
    Ok(())
}

/// The first non-finite value of a mesh: a position, or a float attribute value.
pub(crate) enum NonFinite {
    /// Vertex with a NaN or infinite coordinate.
    Position(usize),
    /// `(domain, column, element)` of a NaN or infinite attribute value.
    Attribute(Domain, String, usize),
}

/// Finds the first NaN or infinite position, else the first such float attribute value
/// (vertex columns, then face columns, in column order).
pub(crate) fn find_non_finite(mesh: &Mesh) -> Option<NonFinite> {
    if let Some(vertex) = mesh.positions.iter().position(|&p| !is_finite(p)) {
        return Some(NonFinite::Position(vertex));
    }
    [
        (Domain::Vertex, &mesh.vertex_attrs),
        (Domain::Face, &mesh.face_attrs),
    ]
    .into_iter()
    .flat_map(|(domain, attrs)| attrs.iter().map(move |(name, v)| (domain, name, v)))
    .find_map(|(domain, name, values)| {
        let element = values.first_non_finite()?;
        Some(NonFinite::Attribute(domain, name.to_string(), element))
    })
    .or_else(|| {
        // A per-corner value is named by its wedge's vertex.
        let (name, wedge) = mesh.wedges.first_non_finite()?;
        let vertex = mesh.wedges.vertices()[wedge] as usize;
        Some(NonFinite::Attribute(
            Domain::Vertex,
            name.to_string(),
            vertex,
        ))
    })
}

/// The area threshold of the degenerate-face test: `rel · (bbox diagonal)²`.
pub(crate) fn area_threshold(mesh: &Mesh, rel: f64) -> f64 {
    let diag = mesh.bbox().diagonal();
    rel * diag * diag
}

/// True when a face of `area` is degenerate: area exactly zero or below `threshold`.
#[inline]
pub(crate) fn is_degenerate_area(area: f64, threshold: f64) -> bool {
    area == 0.0 || area < threshold
}

/// Kept faces that share their vertex set with another kept face, as `(sorted vertex
/// triple, reversed, face)`, sorted: faces on the same vertices are adjacent, same
/// orientation together, lowest face first. `reversed` tells whether the face runs against
/// the increasing order of its sorted triple. Faces with a vertex set of their own (nearly
/// all of them) are left out.
pub(crate) fn faces_sharing_vertex_sets(
    faces: &[[Index; 3]],
    keep: impl Fn(usize) -> bool + Sync,
) -> Vec<([Index; 3], bool, Index)> {
    let entry = |f: usize| {
        let face = faces[f];
        let mut s = face;
        s.sort_unstable();
        let m = face.iter().position(|&v| v == s[0]).unwrap_or(0);
        (s, face[(m + 1) % 3] != s[1], f as Index)
    };
    let least = |f: usize| faces[f].iter().copied().min().unwrap_or(0) as usize;
    // Faces on the same vertices share their least vertex: bucket the kept faces by it (a
    // counting sort, in face order), then sort and group each bucket on its own.
    let nv = faces
        .iter()
        .flatten()
        .copied()
        .max()
        .map_or(0, |m| m as usize + 1);
    let mut offsets = vec![0u32; nv + 1];
    for f in 0..faces.len() {
        if keep(f) {
            offsets[least(f) + 1] += 1;
        }
    }
    for v in 0..nv {
        offsets[v + 1] += offsets[v];
    }
    let mut bucketed = vec![0 as Index; offsets[nv] as usize];
    let mut fill = offsets.clone();
    for f in 0..faces.len() {
        if keep(f) {
            let v = least(f);
            bucketed[fill[v] as usize] = f as Index;
            fill[v] += 1;
        }
    }
    drop(fill);
    // Buckets by ranges of vertices, in parallel; the ranges' results join in order.
    const RANGE: usize = 1 << 14;
    (0..nv.div_ceil(RANGE))
        .into_par_iter()
        .flat_map_iter(|r| {
            let mut out = Vec::new();
            let mut bucket = Vec::new();
            for v in r * RANGE..nv.min((r + 1) * RANGE) {
                let members = &bucketed[offsets[v] as usize..offsets[v + 1] as usize];
                if members.len() < 2 {
                    continue;
                }
                bucket.clear();
                bucket.extend(members.iter().map(|&f| entry(f as usize)));
                bucket.sort_unstable();
                for set in bucket.chunk_by(|a, b| a.0 == b.0) {
                    if set.len() > 1 {
                        out.extend_from_slice(set);
                    }
                }
            }
            out
        })
        .collect()
}

fn check_finite(mesh: &Mesh) -> Result<(), SanityError> {
    match find_non_finite(mesh) {
        None => Ok(()),
        Some(NonFinite::Position(vertex)) => Err(SanityError::NonFinitePosition { vertex }),
        Some(NonFinite::Attribute(domain, name, element)) => Err(SanityError::NonFiniteAttribute {
            domain,
            name,
            element,
        }),
    }
}

fn check_faces(mesh: &Mesh, area_rel: f64) -> Result<(), SanityError> {
    for (face, &[a, b, c]) in mesh.faces.iter().enumerate() {
        if a == b || a == c {
            return Err(SanityError::RepeatedIndex { face, vertex: a });
        }
        if b == c {
            return Err(SanityError::RepeatedIndex { face, vertex: b });
        }
    }
    let threshold = area_threshold(mesh, area_rel);
    for face in 0..mesh.n_faces() {
        let area = mesh.face_area(face);
        if is_degenerate_area(area, threshold) {
            return Err(SanityError::ZeroArea {
                face,
                area,
                threshold,
            });
        }
    }
    Ok(())
}

/// Faces grouped by vertex set; of all faces that repeat a lower face's set, the lowest
/// is reported with the lowest face of its set. A face and its opposite-orientation twin
/// (a two-sided sheet, which load-time hygiene keeps) count as duplicates only when
/// `opposite_too` (manifold meshes have none).
fn check_duplicates(mesh: &Mesh, opposite_too: bool) -> Result<(), SanityError> {
    let order = faces_sharing_vertex_sets(&mesh.faces, |_| true);
    let mut found: Option<(Index, Index)> = None;
    for set in order.chunk_by(|a, b| a.0 == b.0) {
        // Same orientation always duplicates; opposite only when asked.
        let groups: Vec<&[([Index; 3], bool, Index)]> = if opposite_too {
            vec![set]
        } else {
            set.chunk_by(|a, b| a.1 == b.1).collect()
        };
        for group in groups {
            let first = group.iter().map(|g| g.2).min().unwrap_or(0);
            let later = group.iter().map(|g| g.2).filter(|&f| f != first).min();
            if let Some(face) = later
                && found.is_none_or(|(f, _)| face < f)
            {
                found = Some((face, first));
            }
        }
    }
    match found {
        Some((face, first)) => Err(SanityError::DuplicateFace {
            face: face as usize,
            first: first as usize,
        }),
        None => Ok(()),
    }
}

fn check_manifold(topo: &Topology) -> Result<(), SanityError> {
    for e in 0..topo.n_edges() as u32 {
        if topo.edge_faces(e).len() > 2 {
            let [a, b] = topo.edge(e);
            return Err(SanityError::NonManifoldEdge {
                a,
                b,
                faces: topo.edge_faces(e).to_vec(),
            });
        }
    }
    if let Some(&vertex) = topo.non_manifold_vertices().first() {
        return Err(SanityError::NonManifoldVertex {
            vertex,
            n_fans: topo.n_vertex_fans(vertex),
        });
    }
    Ok(())
}

fn check_oriented(topo: &Topology) -> Result<(), SanityError> {
    for e in 0..topo.n_edges() as u32 {
        if topo.is_flipped_edge(e) {
            let [a, b] = topo.edge(e);
            let f = topo.edge_faces(e);
            return Err(SanityError::OrientationFlip {
                a,
                b,
                faces: [f[0], f[1]],
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::{bowtie, tetrahedron};
    use crate::{AttrValues, DVec3};

    proptest::proptest! {
        #![proptest_config(crate::fixtures::fixed_seed(0x5a17_0001))]

        /// The bucketed grouping keeps exactly the groups of two or more that sorting
        /// every kept face gives, in the same order; few vertices make many repeats and
        /// large buckets.
        #[test]
        fn shared_vertex_sets_match_sorting_every_face(
            faces in proptest::collection::vec(proptest::array::uniform3(0u32..7), 0..200),
            mask in proptest::collection::vec(proptest::bool::weighted(0.8), 200),
        ) {
            let keep = |f: usize| mask[f];
            let mut all: Vec<([Index; 3], bool, Index)> = (0..faces.len())
                .filter(|&f| keep(f))
                .map(|f| {
                    let face = faces[f];
                    let mut s = face;
                    s.sort_unstable();
                    let m = face.iter().position(|&v| v == s[0]).unwrap();
                    (s, face[(m + 1) % 3] != s[1], f as Index)
                })
                .collect();
            all.sort_unstable();
            let want: Vec<_> = all
                .chunk_by(|a, b| a.0 == b.0)
                .filter(|g| g.len() > 1)
                .flatten()
                .copied()
                .collect();
            proptest::prop_assert_eq!(faces_sharing_vertex_sets(&faces, keep), want);
        }
    }

    #[test]
    fn clean_tetrahedron_passes_every_check() {
        assert_eq!(
            sanity_check_with(&tetrahedron(), &SanityOptions::strict()),
            Ok(())
        );
    }

    #[test]
    fn out_of_range_index_is_named() {
        let mut m = tetrahedron();
        m.faces[1] = [0, 1, 4];
        assert!(matches!(
            sanity_check(&m),
            Err(SanityError::Index(IndexError::OutOfRange {
                face: 1,
                vertex: 4,
                ..
            }))
        ));
    }

    #[test]
    fn short_attribute_column_is_named() {
        let mut m = tetrahedron();
        m.vertex_attrs.insert("k", AttrValues::Scalar(vec![0.0; 3]));
        assert!(matches!(
            sanity_check(&m),
            Err(SanityError::Index(IndexError::AttributeLength {
                len: 3,
                expected: 4,
                ..
            }))
        ));
    }

    #[test]
    fn nan_position_is_named() {
        let mut m = tetrahedron();
        m.positions[2].y = f64::NAN;
        assert_eq!(
            sanity_check(&m),
            Err(SanityError::NonFinitePosition { vertex: 2 })
        );
    }

    #[test]
    fn infinite_face_attribute_is_named() {
        let mut m = tetrahedron();
        m.face_attrs.insert(
            "err",
            AttrValues::Scalar(vec![0.0, 1.0, f64::INFINITY, 2.0]),
        );
        assert_eq!(
            sanity_check(&m),
            Err(SanityError::NonFiniteAttribute {
                domain: Domain::Face,
                name: "err".into(),
                element: 2
            })
        );
    }

    #[test]
    fn repeated_index_is_named() {
        // 0---1, face 4 = 1-1-3: a "triangle" on an edge
        let mut m = tetrahedron();
        m.faces.push([1, 3, 1]);
        assert_eq!(
            sanity_check(&m),
            Err(SanityError::RepeatedIndex { face: 4, vertex: 1 })
        );
    }

    #[test]
    fn collinear_face_has_zero_area() {
        // 0---1---4 on one line: face 0-1-4 has no area
        let mut m = tetrahedron();
        m.positions.push(DVec3::X * 2.0);
        m.faces.push([0, 1, 4]);
        let err = sanity_check(&m).unwrap_err();
        assert!(matches!(err, SanityError::ZeroArea { face: 4, area, .. } if area == 0.0));
    }

    #[test]
    fn sliver_below_relative_threshold_is_degenerate() {
        // 0---1 with 4 a hair above the midpoint: area 5e-14 in a unit box
        let mut m = tetrahedron();
        m.positions.push(DVec3::new(0.5, 1e-13, 0.0));
        m.faces.push([0, 1, 4]);
        assert!(m.face_area(4) > 0.0);
        assert!(matches!(
            sanity_check(&m),
            Err(SanityError::ZeroArea { face: 4, .. })
        ));
        let lax = SanityOptions {
            degenerate_area_rel: 0.0,
            ..SanityOptions::default()
        };
        assert_eq!(sanity_check_with(&m, &lax), Ok(()));
    }

    #[test]
    fn duplicates_are_named_and_opposite_twins_only_when_manifold_is_required() {
        let mut m = tetrahedron();
        m.faces.push([3, 1, 2]); // face 2 = 1-2-3, same orientation
        assert_eq!(
            sanity_check(&m),
            Err(SanityError::DuplicateFace { face: 4, first: 2 })
        );
        m.faces[4] = [1, 3, 2]; // opposite orientation: a two-sided sheet, kept by hygiene
        assert_eq!(sanity_check(&m), Ok(()));
        assert_eq!(
            sanity_check_with(&m, &SanityOptions::strict()),
            Err(SanityError::DuplicateFace { face: 4, first: 2 })
        );
        // The later face sorts first within its set (0-1-2 runs forwards, face 0 = 0-2-1
        // backwards): still named as the later one.
        m.faces[4] = [0, 1, 2];
        assert_eq!(
            sanity_check_with(&m, &SanityOptions::strict()),
            Err(SanityError::DuplicateFace { face: 4, first: 0 })
        );
    }

    #[test]
    fn fin_edge_fails_only_when_manifold_is_required() {
        //      3   4
        //      |  /        tetrahedron plus face 0-1-4 on edge 0-1
        //  0---+-1
        let mut m = tetrahedron();
        m.positions.push(DVec3::new(0.5, -1.0, 0.5));
        m.faces.push([0, 1, 4]);
        assert_eq!(sanity_check(&m), Ok(()));
        assert_eq!(
            sanity_check_with(&m, &SanityOptions::strict()),
            Err(SanityError::NonManifoldEdge {
                a: 0,
                b: 1,
                faces: vec![0, 1, 4]
            })
        );
    }

    #[test]
    fn bowtie_vertex_fails_when_manifold_is_required() {
        let m = bowtie();
        assert_eq!(sanity_check(&m), Ok(()));
        let opts = SanityOptions {
            require_manifold: true,
            ..SanityOptions::default()
        };
        assert_eq!(
            sanity_check_with(&m, &opts),
            Err(SanityError::NonManifoldVertex {
                vertex: 0,
                n_fans: 2
            })
        );
    }

    #[test]
    fn flipped_face_fails_when_orientation_is_required() {
        // tetrahedron with face 1 listed clockwise: 0-3-1 instead of 0-1-3
        let mut m = tetrahedron();
        m.faces[1] = [0, 3, 1];
        let opts = SanityOptions {
            require_oriented: true,
            ..SanityOptions::default()
        };
        assert_eq!(
            sanity_check_with(&m, &opts),
            Err(SanityError::OrientationFlip {
                a: 0,
                b: 1,
                faces: [0, 1]
            })
        );
        assert_eq!(sanity_check(&m), Ok(()));
    }

    #[test]
    fn errors_read_as_sentences() {
        let e = SanityError::DuplicateFace { face: 9, first: 3 };
        assert_eq!(e.to_string(), "face 9 has the same vertices as face 3");
    }
}
