//! One red-green pass on flat arrays: the edge table, the marking with its closure, and the
//! split itself.
//!
//! The pass reads as three phases:
//!
//! 1. [`EdgeTable::build`] numbers the undirected edges (counting sort by the smaller
//!    endpoint, then a small sort per bucket), so that every face corner knows its edge.
//!    (`Topology` numbers the edges the same way but also builds fans, boundary loops and
//!    components, which a pass does not need: about 10 ms on the bunny against 2–3 ms. A
//!    caller that holds the adjacency already reads the table from it instead:
//!    [`EdgeTable::from_topology`], through `split_once_with`.)
//! 2. [`Plan::new`] marks every edge of a red triangle for splitting. The closure is the
//!    paper's: a triangle that is not red is split by the number of its marked edges
//!    (1 → 2 triangles, 2 → 3, 3 → 4) and marks nothing itself, so marking never spreads and
//!    the result is conforming after one step. One guard keeps areas above the degenerate
//!    threshold: a red triangle is demoted when it, or a triangle across one of its edges,
//!    is too small to split (see [`Plan::new`]).
//! 3. [`split`] appends one midpoint per marked edge and replaces every face by its
//!    children, recording where each came from so that `Mesh::rebuilt` carries the
//!    attributes (a midpoint takes the mean of its edge's ends). A uniform split (every
//!    face red) writes its children in parallel, numbered as `coarsen_mesh::topology`'s
//!    uniform split (midpoints in edge order, children by `split_children`), so that its
//!    adjacency can be derived from the coarse one (`Topology::of_split`).
//!
//! ```text
//!  red, or 3 marked      1 marked          2 marked (a-b, b-c)
//!        c                   c                   c
//!       / \                 /|\                 /|\
//!     m2---m1               / | \               / | m1
//!     / \ / \             /  |  \             /  |/ \
//!    a---m0--b           a---m0--b           a---m0--b
//! ```
//!
//! With two marked edges the corner triangle `m0 b m1` is cut off and the quadrilateral
//! `a m0 m1 c` is cut along `m0-c` (drawn) or `a-m1`, whichever leaves the better worst
//! shape.

use coarsen_geom::{DVec3, triangle};
use coarsen_mesh::topology::split_children;
use coarsen_mesh::{FaceOrigins, Index, Mesh, Topology, VertexOrigins};
use rayon::prelude::*;
use std::borrow::Cow;

/// Undirected edges of a face array, numbered in `(smaller, larger)` endpoint order.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct EdgeTable<'a> {
    /// Per face `f`, entry `i`: the edge from corner `i` to corner `i + 1`.
    pub(crate) face_edges: Cow<'a, [[u32; 3]]>,
    /// Endpoints `[a, b]` of each edge, `a < b`, sorted.
    pub(crate) ends: Cow<'a, [[u32; 2]]>,
}

impl<'a> EdgeTable<'a> {
    /// The edge table of `mesh` read from `topo`, its adjacency, which numbers edges the
    /// same way; `None` when `topo` does not fit `mesh` or skips a face.
    pub(crate) fn from_topology(mesh: &Mesh, topo: &'a Topology) -> Option<EdgeTable<'a>> {
        let fits = topo.n_vertices() == mesh.n_vertices()
            && topo.n_faces() == mesh.n_faces()
            && topo.n_repeated_index_faces() + topo.n_out_of_range_faces() == 0;
        fits.then(|| EdgeTable {
            face_edges: Cow::Borrowed(topo.face_edge_table()),
            ends: Cow::Borrowed(topo.edges()),
        })
    }

    /// Numbers the edges of `faces` over `n_vertices` vertices. Faces must index vertices
    /// below `n_vertices` and repeat no index (the caller checks both).
    pub(crate) fn build(n_vertices: usize, faces: &[[Index; 3]]) -> EdgeTable<'static> {
        // Counting sort of the corner slots by their edge's smaller endpoint.
        let mut offsets = vec![0u32; n_vertices + 1];
        for f in faces {
            for i in 0..3 {
                offsets[f[i].min(f[(i + 1) % 3]) as usize + 1] += 1;
            }
        }
        for v in 0..n_vertices {
            offsets[v + 1] += offsets[v];
        }
        let mut fill = offsets.clone();
        // Key: larger endpoint in the high half, corner slot in the low half, so that a
        // bucket sorts by edge and then by slot (deterministic).
        let mut keys = vec![0u64; 3 * faces.len()];
        for (fi, f) in faces.iter().enumerate() {
            for i in 0..3 {
                let (a, b) = (f[i], f[(i + 1) % 3]);
                let lo = a.min(b) as usize;
                keys[fill[lo] as usize] = (u64::from(a.max(b)) << 32) | (3 * fi + i) as u64;
                fill[lo] += 1;
            }
        }
        let mut face_edges = vec![[0u32; 3]; faces.len()];
        // 3F/2 edges on a closed mesh, half as many more as boundary edges (room for
        // those up to an eighth of the corners; outgrowing the room would copy the table).
        let mut ends = Vec::with_capacity(3 * faces.len() / 2 + 3 * faces.len() / 16 + 1024);
        for lo in 0..n_vertices {
            let bucket = &mut keys[offsets[lo] as usize..offsets[lo + 1] as usize];
            bucket.sort_unstable();
            let mut last = u64::MAX;
            for &key in bucket.iter() {
                let hi = key >> 32;
                if hi != last {
                    ends.push([lo as u32, hi as u32]);
                    last = hi;
                }
                let slot = (key & 0xffff_ffff) as usize;
                face_edges[slot / 3][slot % 3] = (ends.len() - 1) as u32;
            }
        }
        EdgeTable {
            face_edges: Cow::Owned(face_edges),
            ends: Cow::Owned(ends),
        }
    }

    /// The three edges of face `f`, edge `i` from corner `i` to corner `i + 1`.
    #[inline]
    pub(crate) fn of_face(&self, f: usize) -> [u32; 3] {
        self.face_edges[f]
    }
}

/// What one pass will do: which edges are split and how many triangles of each kind.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Plan {
    /// Per edge: split at its midpoint.
    pub(crate) marked: Vec<bool>,
    /// Per face: bit `i` set when its edge `i` is marked.
    pub(crate) mask: Vec<u8>,
    /// Per face: split 1-to-4 as a red triangle.
    pub(crate) red: Vec<bool>,
    /// The split counts and the sizes of the result.
    pub(crate) counts: SplitCounts,
}

/// How many triangles of each kind one pass splits, and the size of its result.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SplitCounts {
    /// Red triangles, split 1-to-4.
    pub red: usize,
    /// Red candidates demoted because they, or a triangle across one of their edges, were
    /// too small to split without a child falling below the degenerate-area threshold.
    pub refused: usize,
    /// Green triangles by number of marked edges: `[bisected, into 3, 1-to-4]`.
    pub green: [usize; 3],
    /// Edges split (= vertices added).
    pub split_edges: usize,
    /// Vertices after the pass.
    pub vertices: usize,
    /// Faces after the pass.
    pub faces: usize,
}

impl Plan {
    /// Marks the edges of the `candidates` (red) faces and closes the marking.
    ///
    /// `splittable[f]` says that face `f` may be split: its smallest possible child (a
    /// quarter of its area) stays above the degenerate threshold. A candidate is demoted
    /// when it, or any face sharing one of its edges, is not splittable: the faces that are
    /// too small forbid their edges, and a candidate with a forbidden edge is dropped. One
    /// round suffices — demoting only unmarks edges, and every face left with a marked edge
    /// is a kept red face or shares that edge with one, whose edges were not forbidden.
    pub(crate) fn new(
        table: &EdgeTable,
        n_vertices: usize,
        candidates: &[bool],
        splittable: &[bool],
    ) -> Plan {
        let nf = candidates.len();
        let ne = table.ends.len();
        let mut marked = vec![false; ne];
        for f in (0..nf).filter(|&f| candidates[f]) {
            table
                .of_face(f)
                .iter()
                .for_each(|&e| marked[e as usize] = true);
        }
        let mut forbidden = vec![false; ne];
        let mut any_forbidden = false;
        for f in (0..nf).filter(|&f| !splittable[f]) {
            let edges = table.of_face(f);
            if edges.iter().any(|&e| marked[e as usize]) {
                edges.iter().for_each(|&e| forbidden[e as usize] = true);
                any_forbidden = true;
            }
        }
        let mut red = candidates.to_vec();
        let mut refused = 0;
        if any_forbidden {
            for (f, r) in red.iter_mut().enumerate() {
                if *r && table.of_face(f).iter().any(|&e| forbidden[e as usize]) {
                    *r = false;
                    refused += 1;
                }
            }
            marked.iter_mut().for_each(|m| *m = false);
            for f in (0..nf).filter(|&f| red[f]) {
                table
                    .of_face(f)
                    .iter()
                    .for_each(|&e| marked[e as usize] = true);
            }
        }
        Plan::closed(table, n_vertices, marked, red, refused)
    }

    /// Marks the `marked` edges (one flag per edge of `table`) but those of a face that
    /// is not `splittable` (see [`Plan::new`]), and closes the marking: a face with all
    /// three edges marked counts as red, the others are split by their marked edges.
    pub(crate) fn of_edges(
        table: &EdgeTable,
        n_vertices: usize,
        mut marked: Vec<bool>,
        splittable: &[bool],
    ) -> Plan {
        let nf = splittable.len();
        let mut refused = 0;
        for f in (0..nf).filter(|&f| !splittable[f]) {
            for e in table.of_face(f) {
                refused += usize::from(std::mem::take(&mut marked[e as usize]));
            }
        }
        let red: Vec<bool> = (0..nf)
            .map(|f| table.of_face(f).iter().all(|&e| marked[e as usize]))
            .collect();
        Plan::closed(table, n_vertices, marked, red, refused)
    }

    /// The plan of the `marked` edges, with the `red` faces and the `refused` count.
    fn closed(
        table: &EdgeTable,
        n_vertices: usize,
        marked: Vec<bool>,
        red: Vec<bool>,
        refused: usize,
    ) -> Plan {
        let nf = red.len();
        let mut counts = SplitCounts {
            refused,
            faces: nf,
            ..SplitCounts::default()
        };
        let mask: Vec<u8> = (0..nf)
            .map(|f| {
                let e = table.of_face(f);
                let m = (0..3).fold(0u8, |m, i| m | (u8::from(marked[e[i] as usize]) << i));
                let k = m.count_ones() as usize;
                if red[f] {
                    counts.red += 1;
                } else if k > 0 {
                    counts.green[k - 1] += 1;
                }
                counts.faces += k;
                m
            })
            .collect();
        counts.split_edges = marked.iter().filter(|&&m| m).count();
        counts.vertices = n_vertices + counts.split_edges;
        Plan {
            marked,
            mask,
            red,
            counts,
        }
    }
}

/// The arrays of the refined mesh and where each element came from.
pub(crate) struct Split {
    /// Old positions, then one midpoint per marked edge in edge order.
    pub(crate) positions: Vec<DVec3>,
    /// The children of every old face, face after face.
    pub(crate) faces: Vec<[Index; 3]>,
    /// Old vertices copied, midpoints from their edge at `t = ½`.
    pub(crate) vertex_origins: VertexOrigins,
    /// The parent of every child face.
    pub(crate) face_origins: FaceOrigins,
}

/// Splits `mesh` as `plan` says. Children keep their parent's orientation; a face with two
/// marked edges cuts its remaining quadrilateral along the diagonal giving the better worst
/// Frey–Borouchaki quality (the diagonal from the unsplit corner on a tie).
pub(crate) fn split(mesh: &Mesh, table: &EdgeTable<'_>, plan: &Plan) -> Split {
    let nv = mesh.n_vertices();
    let c = &plan.counts;
    let mut mid = vec![Index::MAX; table.ends.len()];
    let mut next = nv as Index;
    for (m, &marked) in mid.iter_mut().zip(&plan.marked) {
        if marked {
            *m = next;
            next += 1;
        }
    }
    let mut positions = Vec::with_capacity(c.vertices);
    positions.extend_from_slice(&mesh.positions);
    let mut vertex_origins = VertexOrigins::with_capacity(c.vertices);
    (0..nv as Index).for_each(|v| vertex_origins.push_copy(v));
    for (&[a, b], _) in table.ends.iter().zip(&plan.marked).filter(|(_, m)| **m) {
        positions.push((mesh.positions[a as usize] + mesh.positions[b as usize]) * 0.5);
        vertex_origins.push_edge(a, b, 0.5);
    }
    // Each face's children, in face order.
    let children = |f: usize, out: &mut [[Index; 3]]| -> usize {
        let v = mesh.faces[f];
        let m = table.of_face(f).map(|e| mid[e as usize]);
        match plan.mask[f] {
            0 => {
                out[0] = v;
                1
            }
            7 => {
                // The mesh crate's layout: a uniform split (every midpoint `nv + e`, as
                // here when every edge is marked) gets its adjacency derived from the
                // coarse one (`Topology::of_split`), as `postprocess` does.
                out[..4].copy_from_slice(&split_children(v, m));
                4
            }
            1 | 2 | 4 => {
                // Rotate so that the marked edge runs a → b.
                let i = plan.mask[f].trailing_zeros() as usize;
                let (a, b, c) = (v[i], v[(i + 1) % 3], v[(i + 2) % 3]);
                out[..2].copy_from_slice(&[[a, m[i], c], [m[i], b, c]]);
                2
            }
            mask => {
                // Two marked edges: rotate so that they are a → b and b → c; c → a stays.
                let k = (!mask & 7).trailing_zeros() as usize;
                let (i, j) = ((k + 1) % 3, (k + 2) % 3);
                let (a, b, c) = (v[i], v[j], v[k]);
                let (mab, mbc) = (m[i], m[j]);
                out[0] = [mab, b, mbc];
                let p = |x: Index| positions[x as usize];
                let q = |x: [Index; 3]| triangle::quality(p(x[0]), p(x[1]), p(x[2]));
                let from_a = [[a, mab, mbc], [a, mbc, c]];
                let from_mab = [[a, mab, c], [mab, mbc, c]];
                let worst = |t: &[[Index; 3]; 2]| q(t[0]).min(q(t[1]));
                out[1..3].copy_from_slice(if worst(&from_mab) > worst(&from_a) {
                    &from_mab
                } else {
                    &from_a
                });
                3
            }
        }
    };
    let (faces, parents) = if plan.mask.iter().all(|&m| m == 7) {
        // Uniform: four children per face, filled in parallel.
        let mut faces = vec![[0; 3]; 4 * mesh.n_faces()];
        faces.par_chunks_mut(4).enumerate().for_each(|(f, out)| {
            children(f, out);
        });
        let parents = (0..4 * mesh.n_faces())
            .into_par_iter()
            .map(|i| (i / 4) as Index)
            .collect();
        (faces, parents)
    } else {
        let mut faces = Vec::with_capacity(c.faces);
        let mut parents = Vec::with_capacity(c.faces);
        let mut out = [[0; 3]; 4];
        for f in 0..mesh.n_faces() {
            let n = children(f, &mut out);
            faces.extend_from_slice(&out[..n]);
            parents.extend(std::iter::repeat_n(f as Index, n));
        }
        (faces, parents)
    };
    debug_assert_eq!(faces.len(), c.faces);
    debug_assert_eq!(positions.len(), c.vertices);
    Split {
        positions,
        faces,
        vertex_origins,
        face_origins: FaceOrigins::from_parents(parents),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles on a square, sharing the diagonal 1-2:
    ///
    /// ```text
    /// 2---3
    /// | \ |
    /// 0---1
    /// ```
    fn square() -> Mesh {
        Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 0.0)],
            vec![[0, 1, 2], [1, 3, 2]],
        )
    }

    #[test]
    fn edge_table_numbers_shared_edges_once_in_sorted_order() {
        let m = square();
        let t = EdgeTable::build(4, &m.faces);
        assert_eq!(t.ends, vec![[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]]);
        // Face 0: 0→1, 1→2, 2→0. Face 1: 1→3, 3→2, 2→1.
        assert_eq!(t.of_face(0), [0, 2, 1]);
        assert_eq!(t.of_face(1), [3, 4, 2]);
    }

    #[test]
    fn one_red_face_marks_its_edges_and_bisects_its_neighbour() {
        let m = square();
        let t = EdgeTable::build(4, &m.faces);
        let plan = Plan::new(&t, 4, &[true, false], &[true, true]);
        assert_eq!(plan.marked, vec![true, true, true, false, false]);
        assert_eq!(plan.mask, vec![7, 0b100]);
        assert_eq!(plan.counts.red, 1);
        assert_eq!(plan.counts.green, [1, 0, 0]);
        assert_eq!((plan.counts.vertices, plan.counts.faces), (7, 6));
    }

    #[test]
    fn a_candidate_next_to_a_face_too_small_to_split_is_refused() {
        let m = square();
        let t = EdgeTable::build(4, &m.faces);
        let plan = Plan::new(&t, 4, &[true, false], &[true, false]);
        assert!(plan.marked.iter().all(|&x| !x));
        assert_eq!(plan.counts.red, 0);
        assert_eq!(plan.counts.refused, 1);
        assert_eq!(plan.counts.faces, 2);
    }

    /// Splits the one triangle `corners` with its edges 0→1 and 1→2 marked (as two red
    /// neighbours would mark them); midpoints become vertices 3 (of 0-1) and 4 (of 1-2).
    fn split_two_edges(corners: [(f64, f64); 3]) -> Vec<[u32; 3]> {
        let m = Mesh::new(
            corners.map(|(x, y)| DVec3::new(x, y, 0.0)).to_vec(),
            vec![[0, 1, 2]],
        );
        let t = EdgeTable::build(3, &m.faces);
        let mut plan = Plan::new(&t, 3, &[false], &[true]);
        plan.marked = t.ends.iter().map(|&e| e != [0, 2]).collect();
        plan.mask = vec![0b011];
        plan.counts.vertices = 5;
        plan.counts.faces = 3;
        let s = split(&m, &t, &plan);
        let area: f64 = s
            .faces
            .iter()
            .map(|f| f.map(|i| s.positions[i as usize]))
            .map(|[a, b, c]| triangle::area(a, b, c))
            .sum();
        assert!((area - m.area()).abs() < 1e-12);
        s.faces
    }

    #[test]
    fn two_marked_edges_cut_along_the_diagonal_with_the_better_worst_quality() {
        //  2              Marked: 0-1 (midpoint 3) and 1-2 (midpoint 4).
        //  | \            Corner child [3, 1, 4]; the quadrilateral 0-3-4-2 is cut
        //  |   4          along 0-4 (worst quality 0.368) rather than 3-2 (0.323).
        //  |     \
        //  0---3---1
        assert_eq!(
            split_two_edges([(0.0, 0.0), (4.0, 0.0), (0.0, 1.0)]),
            vec![[3, 1, 4], [0, 3, 4], [0, 4, 2]]
        );
        //  1              Marked: 0-1 (midpoint 3) and 1-2 (midpoint 4).
        //  | \            Here 3-2 gives worst quality 0.213, 0-4 only 0.106.
        //  4   3
        //  |     \
        //  2-------0
        assert_eq!(
            split_two_edges([(4.0, 0.0), (0.0, 1.0), (0.0, 0.0)]),
            vec![[3, 1, 4], [0, 3, 2], [3, 4, 2]]
        );
    }
}
