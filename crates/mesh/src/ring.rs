//! The shape of a vertex's ring: is the set of faces around a vertex one fan?
//!
//! Each face `(v, x, y)` around vertex `v` (counter-clockwise) contributes the ring edge
//! `x → y`. The faces form one closed fan exactly when these edges form one directed
//! cycle, and one open fan exactly when they form one directed path; anything else (a
//! vertex repeated as a source or a target, several cycles or paths) is a non-manifold
//! neighbourhood. The collapse engine classifies its input vertices and checks every
//! collapse with it; [`one_fan_everywhere`] tells the runner cheaply that a mesh has no
//! non-manifold vertex or edge to split.

use crate::{Index, Mesh};
use rayon::prelude::*;

/// What the ring edges around a vertex form.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RingShape {
    /// One directed cycle of at least 3 edges: an interior vertex.
    Cycle,
    /// One directed path: a boundary vertex.
    Path,
    /// Anything else: no faces, two fans, a repeated neighbour, a 2-cycle (duplicated face).
    Invalid,
}

/// Rings up to this many edges are classified by scanning them, without sorting.
const SMALL: usize = 12;

/// Classifies the ring edges `edges` (reordered in place; `targets` is scratch space).
pub fn ring_shape(edges: &mut [(Index, Index)], targets: &mut Vec<Index>) -> RingShape {
    let n = edges.len();
    if n == 0 {
        return RingShape::Invalid;
    }
    if n <= SMALL {
        small_ring_shape(edges)
    } else {
        sorted_ring_shape(edges, targets)
    }
}

/// A vertex that two of the ring edges `edges` leave, or two enter, if any: it makes the
/// ring [`RingShape::Invalid`] whatever else the ring holds (`scratch` is scratch space).
pub fn repeated_end(edges: &[(Index, Index)], scratch: &mut Vec<Index>) -> Option<Index> {
    if edges.len() <= SMALL {
        return edges.iter().enumerate().find_map(|(i, e)| {
            edges[..i].iter().find_map(|d| {
                if d.0 == e.0 {
                    Some(e.0)
                } else if d.1 == e.1 {
                    Some(e.1)
                } else {
                    None
                }
            })
        });
    }
    let mut repeated = |end: fn(&(Index, Index)) -> Index| {
        scratch.clear();
        scratch.extend(edges.iter().map(end));
        scratch.sort_unstable();
        scratch.windows(2).find(|w| w[0] == w[1]).map(|w| w[0])
    };
    repeated(|e| e.0).or_else(|| repeated(|e| e.1))
}

/// [`ring_shape`] of a non-empty ring by sorting its edges and targets.
fn sorted_ring_shape(edges: &mut [(Index, Index)], targets: &mut Vec<Index>) -> RingShape {
    edges.sort_unstable();
    if edges.windows(2).any(|w| w[0].0 == w[1].0) {
        return RingShape::Invalid;
    }
    targets.clear();
    targets.extend(edges.iter().map(|e| e.1));
    targets.sort_unstable();
    if targets.windows(2).any(|w| w[0] == w[1]) {
        return RingShape::Invalid;
    }
    let edges = &*edges;
    follow(
        edges,
        |v| targets.binary_search(&v).is_ok(),
        |v| {
            edges
                .binary_search_by_key(&v, |e| e.0)
                .ok()
                .map(|i| edges[i].1)
        },
    )
}

/// [`ring_shape`] of a few edges, by scanning: the same verdicts without sorting.
fn small_ring_shape(edges: &[(Index, Index)]) -> RingShape {
    for (i, e) in edges.iter().enumerate() {
        if edges[..i].iter().any(|d| d.0 == e.0 || d.1 == e.1) {
            return RingShape::Invalid;
        }
    }
    follow(
        edges,
        |v| edges.iter().any(|d| d.1 == v),
        |v| edges.iter().find(|e| e.0 == v).map(|e| e.1),
    )
}

/// The shape of the non-empty ring `edges`, whose sources are distinct and whose targets
/// are distinct (so each vertex has at most one successor), given which vertices are
/// targets and each vertex's successor: one cycle, one path, or anything else.
#[inline]
fn follow(
    edges: &[(Index, Index)],
    is_target: impl Fn(Index) -> bool,
    successor: impl Fn(Index) -> Option<Index>,
) -> RingShape {
    let n = edges.len();
    let mut starts = edges.iter().filter(|e| !is_target(e.0)).map(|e| e.0);
    let first = starts.next();
    if starts.next().is_some() {
        return RingShape::Invalid;
    }
    let origin = first.unwrap_or(edges[0].0);
    // Follow the unique successor from `origin`, counting edges.
    let mut at = origin;
    let mut steps = 0;
    while let Some(next) = successor(at) {
        at = next;
        steps += 1;
        if at == origin || steps > n {
            break;
        }
    }
    match first {
        None if steps == n && at == origin && n >= 3 => RingShape::Cycle,
        Some(_) if steps == n => RingShape::Path,
        _ => RingShape::Invalid,
    }
}

/// True when every face has three distinct corners in range and the faces around every
/// vertex form one consistently oriented fan, closed or open: such a mesh has no
/// non-manifold vertex and no edge of three or more faces. False only says that one may be
/// there (a fan whose faces disagree in orientation fails too); [`crate::Topology`] tells.
pub fn one_fan_everywhere(mesh: &Mesh) -> bool {
    let n = mesh.n_vertices();
    let faces = &mesh.faces;
    let proper = |&[a, b, c]: &[Index; 3]| {
        a != b && b != c && a != c && (a as usize) < n && (b as usize) < n && (c as usize) < n
    };
    if faces.len() > crate::topology::MAX_FACES
        || !faces.par_iter().with_min_len(1 << 14).all(proper)
    {
        return false;
    }
    // Every vertex's corners, each with its ring edge (the corner's next and previous).
    let (start, corners) = crate::topology::vertex_corners(faces, &vec![true; faces.len()], n);
    (0..n)
        .into_par_iter()
        .with_min_len(1 << 12)
        .try_for_each_init(
            || (Vec::new(), Vec::new()),
            |(edges, targets), v| {
                let around = &corners[start[v] as usize..start[v + 1] as usize];
                if around.is_empty() {
                    return Ok(());
                }
                edges.clear();
                edges.extend(around.iter().map(|&[_, next, prev]| (next, prev)));
                match ring_shape(edges, targets) {
                    RingShape::Invalid => Err(()),
                    RingShape::Cycle | RingShape::Path => Ok(()),
                }
            },
        )
        .is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape(edges: &[(Index, Index)]) -> RingShape {
        ring_shape(&mut edges.to_vec(), &mut Vec::new())
    }

    #[test]
    fn one_cycle_is_interior_and_one_path_is_boundary() {
        assert_eq!(shape(&[(3, 4), (4, 5), (5, 3)]), RingShape::Cycle);
        assert_eq!(shape(&[(5, 6), (3, 4), (4, 5)]), RingShape::Path);
        assert_eq!(shape(&[(1, 2)]), RingShape::Path);
    }

    #[test]
    fn two_fans_repeats_and_short_cycles_are_invalid() {
        assert_eq!(shape(&[]), RingShape::Invalid);
        // Bow-tie: two separate paths.
        assert_eq!(shape(&[(1, 2), (3, 4)]), RingShape::Invalid);
        // Two cycles.
        assert_eq!(
            shape(&[(1, 2), (2, 3), (3, 1), (4, 5), (5, 6), (6, 4)]),
            RingShape::Invalid
        );
        // A path plus a cycle.
        assert_eq!(
            shape(&[(1, 2), (2, 3), (4, 5), (5, 6), (6, 4)]),
            RingShape::Invalid
        );
        // Vertex 2 twice as a source (an edge with two faces in the same direction).
        assert_eq!(shape(&[(1, 2), (2, 3), (2, 4)]), RingShape::Invalid);
        // The two faces of a collapsed tetrahedron: a 2-cycle.
        assert_eq!(shape(&[(1, 2), (2, 1)]), RingShape::Invalid);
    }

    #[test]
    fn one_fan_everywhere_passes_manifold_oriented_meshes_only() {
        use crate::fixtures::{bowtie, tetrahedron};
        let closed = tetrahedron();
        assert!(one_fan_everywhere(&closed));
        let mut open = closed.clone();
        open.faces.pop();
        assert!(one_fan_everywhere(&open), "a boundary fan is one fan");
        let mut isolated = closed.clone();
        isolated.positions.push(crate::DVec3::ONE);
        assert!(one_fan_everywhere(&isolated));
        assert!(one_fan_everywhere(&Mesh::default()));

        assert!(!one_fan_everywhere(&bowtie()), "two fans at one vertex");
        let mut flipped = closed.clone();
        flipped.faces[0].swap(1, 2);
        assert!(!one_fan_everywhere(&flipped));
        let mut fin = open.clone();
        fin.positions.push(crate::DVec3::NEG_ONE);
        fin.faces.push([0, 1, 4]);
        assert!(!one_fan_everywhere(&fin), "an edge of three faces");
        let mut repeated = closed.clone();
        repeated.faces[0] = [0, 0, 1];
        assert!(!one_fan_everywhere(&repeated));
        let mut out_of_range = closed;
        out_of_range.faces[0][2] = 9;
        assert!(!one_fan_everywhere(&out_of_range));
    }

    /// The sorting classifier, whatever the ring's size.
    fn sorted_shape(edges: &[(Index, Index)]) -> RingShape {
        if edges.is_empty() {
            return RingShape::Invalid;
        }
        sorted_ring_shape(&mut edges.to_vec(), &mut Vec::new())
    }

    proptest::proptest! {
        #![proptest_config(crate::fixtures::fixed_seed(0x4149_0001))]

        #[test]
        fn scanning_and_sorting_agree(
            edges in proptest::collection::vec((0u32..8, 0u32..8), 0..=SMALL),
            cycle in 3usize..=SMALL,
            open in proptest::bool::ANY,
            shift in 0usize..SMALL,
        ) {
            proptest::prop_assert_eq!(shape(&edges), sorted_shape(&edges));
            // Valid rings too, which random edges seldom are: a cycle or path, rotated.
            let mut ring: Vec<(Index, Index)> =
                (0..cycle as Index).map(|i| (i, (i + 1) % cycle as Index)).collect();
            if open {
                ring.pop();
            }
            let k = shift % ring.len();
            ring.rotate_left(k);
            let want = if open { RingShape::Path } else { RingShape::Cycle };
            proptest::prop_assert_eq!(shape(&ring), want);
            proptest::prop_assert_eq!(sorted_shape(&ring), want);
        }

        #[test]
        fn a_repeated_end_is_found_exactly_when_an_end_repeats(
            edges in proptest::collection::vec((0u32..40, 0u32..40), 0..30),
        ) {
            let end = repeated_end(&edges, &mut Vec::new());
            let count = |v: Index, side: fn(&(Index, Index)) -> Index| {
                edges.iter().filter(|e| side(e) == v).count()
            };
            let right = match end {
                Some(v) => count(v, |e| e.0) >= 2 || count(v, |e| e.1) >= 2,
                None => edges
                    .iter()
                    .all(|e| count(e.0, |d| d.0) == 1 && count(e.1, |d| d.1) == 1),
            };
            proptest::prop_assert!(right, "{:?} for {:?}", end, edges);
            if end.is_some() {
                proptest::prop_assert_eq!(shape(&edges), RingShape::Invalid);
            }
        }
    }
}
