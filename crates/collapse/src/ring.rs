//! The shape of a vertex's ring: is the set of faces around a vertex one fan?
//!
//! Each face `(v, x, y)` around vertex `v` (counter-clockwise) contributes the ring edge
//! `x → y`. The faces form one closed fan exactly when these edges form one directed
//! cycle, and one open fan exactly when they form one directed path; anything else (a
//! vertex repeated as a source or a target, several cycles or paths) is a non-manifold
//! neighbourhood. The same test classifies input vertices and checks every collapse.

use crate::Index;

/// What the ring edges around a vertex form.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum RingShape {
    /// One directed cycle of at least 3 edges: an interior vertex.
    Cycle,
    /// One directed path: a boundary vertex.
    Path,
    /// Anything else: no faces, two fans, a repeated neighbour, a 2-cycle (duplicated face).
    Invalid,
}

/// Classifies the ring edges `edges` (reordered in place; `targets` is scratch space).
pub(crate) fn ring_shape(edges: &mut [(Index, Index)], targets: &mut Vec<Index>) -> RingShape {
    let n = edges.len();
    if n == 0 {
        return RingShape::Invalid;
    }
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
    let mut starts = edges
        .iter()
        .filter(|e| targets.binary_search(&e.0).is_err())
        .map(|e| e.0);
    let first = starts.next();
    if starts.next().is_some() {
        return RingShape::Invalid;
    }
    let origin = first.unwrap_or(edges[0].0);
    // Follow the unique successor from `origin`, counting edges.
    let mut at = origin;
    let mut steps = 0;
    while let Ok(i) = edges.binary_search_by_key(&at, |e| e.0) {
        at = edges[i].1;
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
}
