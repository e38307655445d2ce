//! The input surface a live mesh keeps for its output: the faces a moved vertex's
//! per-corner values come from ([`super::seams`]), and the points the moved vertices
//! settle on ([`LiveMesh::settle_on_input`]).
//!
//! **Settling.** A collapse puts the vertex it keeps where the cost model likes, which for
//! the quadric is off the input surface by up to the error it measures. With
//! [`LiveMesh::settle_on_input`], each output vertex that moved goes, after the last
//! collapse, to the nearest point of the input faces around the input vertices it
//! merged — the very point its per-corner values (UVs, normals, colours) are taken at, so
//! that they are exact at the vertex, as at an input vertex. A move is left out when it
//! would flatten one of the vertex's faces, turn one by 90° or more, or turn one 60° or
//! more away from its input face (the engine's own checks); the vertices are settled one
//! by one in output order, each against its neighbours as settled so far.

use super::{DRIFT_COS, LiveMesh};
use crate::Index;
use coarsen_geom::{DVec3, triangle};
use coarsen_mesh::Mesh;
use coarsen_spatial::closest_point_on_triangle;
use rayon::prelude::*;
use std::sync::OnceLock;

/// The input's positions and faces, in the input's numbering.
#[derive(Clone, Debug)]
pub(crate) struct InputSurface {
    pub(crate) positions: Vec<DVec3>,
    pub(crate) faces: Vec<[Index; 3]>,
    /// Each vertex's faces, once asked for.
    around: OnceLock<Around>,
}

/// What settling did ([`LiveMesh::settled`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Settled {
    /// Vertices moved onto the input surface.
    pub moved: usize,
    /// Vertices off the surface left where they were (the move would spoil a face).
    pub refused: usize,
}

/// Each input vertex's faces (CSR: offsets, then faces) and the longest edge of those
/// faces.
#[derive(Clone, Debug)]
pub(crate) struct Around {
    start: Vec<usize>,
    list: Vec<Index>,
    reach: Vec<f64>,
}

impl InputSurface {
    /// Each input vertex's faces and their longest edge.
    pub(crate) fn around(&self) -> &Around {
        self.around.get_or_init(|| self.build_around())
    }

    fn build_around(&self) -> Around {
        let (positions, faces) = (&self.positions, &self.faces);
        let (start, list) = vertex_face_lists(faces, positions.len());
        let mut reach = vec![0.0f64; positions.len()];
        for face in faces {
            let [a, b, c] = face.map(|v| positions[v as usize]);
            let longest = a.distance(b).max(b.distance(c)).max(c.distance(a));
            for &v in face {
                reach[v as usize] = reach[v as usize].max(longest);
            }
        }
        Around { start, list, reach }
    }

    /// The input face around `members` nearest `p`, with the barycentric weights of the
    /// nearest point (the first face of the least distance).
    ///
    /// A member farther from `p` than the best distance so far and its faces' longest
    /// edge cannot hold a nearer point on its faces (every point of a face lies within its
    /// longest edge of each corner): the nearest member's faces first, then only the
    /// members near enough.
    pub(crate) fn nearest_around(
        &self,
        around: &Around,
        members: &[Index],
        p: DVec3,
    ) -> Option<(Index, [f64; 3])> {
        let Around { start, list, reach } = around;
        let gap = |m: Index| self.positions[m as usize].distance(p);
        let first = members
            .iter()
            .copied()
            .min_by(|&a, &b| gap(a).total_cmp(&gap(b)))?;
        let mut best: Option<(f64, Index, [f64; 3])> = None;
        let order = std::iter::once(first).chain(members.iter().copied().filter(|&m| m != first));
        for m in order {
            if let Some((d2, _, _)) = best
                && gap(m) - reach[m as usize] > d2.sqrt()
            {
                continue;
            }
            let m = m as usize;
            for &f in &list[start[m]..start[m + 1]] {
                let [a, b, c] = self.faces[f as usize].map(|v| self.positions[v as usize]);
                if a == b || b == c || a == c {
                    continue;
                }
                let (q, bary) = closest_point_on_triangle(p, a, b, c);
                let d = q.distance_squared(p);
                if best.is_none_or(|(bd, bf, _)| d < bd || (d == bd && f < bf)) {
                    best = Some((d, f, bary));
                }
            }
        }
        best.map(|(_, f, bary)| (f, bary))
    }

    /// The point of face `f` with barycentric weights `bary`.
    fn point(&self, f: Index, bary: [f64; 3]) -> DVec3 {
        let [a, b, c] = self.faces[f as usize].map(|v| self.positions[v as usize]);
        a * bary[0] + b * bary[1] + c * bary[2]
    }
}

/// Each vertex's faces (CSR: offsets, then faces) of `n` vertices.
pub(crate) fn vertex_face_lists(faces: &[[Index; 3]], n: usize) -> (Vec<usize>, Vec<Index>) {
    let mut start = vec![0usize; n + 1];
    for &v in faces.iter().flatten() {
        start[v as usize + 1] += 1;
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut list = vec![0; start[n]];
    for (f, face) in faces.iter().enumerate() {
        for &v in face {
            list[fill[v as usize]] = f as Index;
            fill[v as usize] += 1;
        }
    }
    (start, list)
}

impl LiveMesh {
    /// Keeps the positions and faces of `mesh`, the mesh this live mesh was built from,
    /// as the input surface (taking them: `mesh` is left without them), unless kept
    /// already or `mesh` is not that mesh.
    pub(crate) fn keep_input_surface(&mut self, mesh: &mut Mesh) {
        if self.input.is_some()
            || mesh.n_vertices() != self.input_vertices
            || mesh.n_faces() != self.input_faces
        {
            return;
        }
        self.input = Some(Box::new(InputSurface {
            positions: std::mem::take(&mut mesh.positions),
            faces: std::mem::take(&mut mesh.faces),
            around: OnceLock::new(),
        }));
    }

    /// Asks for the output's moved vertices on the input surface (module docs) when the
    /// output is made ([`LiveMesh::to_mesh_with_attributes`]; what it did:
    /// [`LiveMesh::settled`]). Call before any collapse, with the mesh this live mesh was
    /// built from, whose positions and faces it takes (after [`LiveMesh::track_seams`],
    /// which takes them too: either keeps them for both).
    pub fn settle_on_input(&mut self, mesh: &mut Mesh) {
        self.keep_input_surface(mesh);
        self.settle = self.input.is_some();
    }

    /// What settling did when the output was made; `None` before, or when not asked for.
    pub fn settled(&self) -> Option<Settled> {
        self.settled.get().copied()
    }

    /// Per output vertex (`positions`, each standing for the input vertices
    /// `members[v]`), the input point nearest a vertex that moved — a face and barycentric
    /// weights — where its values come from and where it settles; `None` for a vertex at
    /// its input position (empty without an input surface).
    pub(super) fn nearest_points(
        &self,
        positions: &[DVec3],
        members: &[Vec<Index>],
    ) -> Vec<Option<(Index, [f64; 3])>> {
        let Some(surface) = self.input.as_deref() else {
            return Vec::new();
        };
        if members.len() != positions.len() {
            return Vec::new();
        }
        let around = surface.around();
        positions
            .par_iter()
            .zip(members)
            .map(|(&p, members)| {
                if let [m] = members[..]
                    && surface.positions[m as usize] == p
                {
                    return None;
                }
                surface.nearest_around(around, members, p)
            })
            .collect()
    }

    /// Moves each output vertex (`positions`, of the output `faces` made from the live
    /// slots `slots`) to its input point in `nearest`, one by one in output order, where
    /// that spoils none of its faces (module docs).
    pub(super) fn settle(
        &self,
        positions: &mut [DVec3],
        faces: &[[Index; 3]],
        slots: &[Index],
        nearest: &[Option<(Index, [f64; 3])>],
    ) -> Settled {
        let mut settled = Settled::default();
        let Some(surface) = self.input.as_deref() else {
            return settled;
        };
        let (start, list) = vertex_face_lists(faces, positions.len());
        for (i, near) in nearest.iter().enumerate() {
            let Some((f, bary)) = *near else { continue };
            let q = surface.point(f, bary);
            if q == positions[i] || !q.is_finite() {
                continue;
            }
            let sound = list[start[i]..start[i + 1]]
                .iter()
                .all(|&g| self.settles_face(positions, faces[g as usize], slots[g as usize], i, q));
            if sound {
                positions[i] = q;
                settled.moved += 1;
            } else {
                settled.refused += 1;
            }
        }
        settled
    }

    /// Whether output face `face` (live slot `slot`) stays sound with its vertex `i` at
    /// `q`: not flattened, not turned by 90° or more, nor 60° or more away from its input
    /// face (unless it was so before).
    fn settles_face(
        &self,
        positions: &[DVec3],
        face: [Index; 3],
        slot: Index,
        i: usize,
        q: DVec3,
    ) -> bool {
        let old = face.map(|v| positions[v as usize]);
        let mut new = old;
        for (k, &v) in face.iter().enumerate() {
            if v as usize == i {
                new[k] = q;
            }
        }
        let n_old = triangle::cross(old[0], old[1], old[2]);
        let n_new = triangle::cross(new[0], new[1], new[2]);
        if n_old.length() <= self.min_cross {
            return true;
        }
        let input = self.input_normal[slot as usize];
        let drifted = |n: DVec3| input.dot(n) <= DRIFT_COS * n.length();
        n_new.length() > self.min_cross
            && n_old.dot(n_new) > 0.0
            && (!drifted(n_new) || drifted(n_old))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::live::PartOptions;
    use crate::{Goal, NoGuard, Options, QemOptions, QuadricModel};
    use coarsen_spatial::Bvh;

    /// QEM on `mesh` to `goal` with `parts`, its seams tracked and its moved vertices
    /// settled or not.
    fn qem_with(mesh: &Mesh, goal: Goal, parts: &PartOptions, settle: bool) -> (Mesh, Settled) {
        let mut live = LiveMesh::new_renumbered(mesh).unwrap();
        let mut input = mesh.clone();
        live.track_seams(&mut input);
        if settle {
            live.settle_on_input(&mut input);
        }
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        live.collapse_parted(
            &mut model,
            || NoGuard,
            &Options::new(goal),
            parts,
            &mut |_| {},
        );
        let out = live.to_mesh(mesh).unwrap().0;
        (out, live.settled().unwrap_or_default())
    }

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config {
            cases: 24,
            rng_seed: proptest::test_runner::RngSeed::Fixed(0x5E77_1E00_0000_0050),
            ..proptest::test_runner::Config::default()
        })]

        /// Settling changes positions only: the same faces, every moved vertex on the
        /// input or left where it was, no face flattened by it.
        #[test]
        fn settling_moves_vertices_onto_the_input_and_nothing_else(
            (mesh, goal, parts) in crate::live::parts::properties::charted_cases(),
        ) {
            let (free, _) = qem_with(&mesh, goal, &parts, false);
            let (settled, did) = qem_with(&mesh, goal, &parts, true);
            proptest::prop_assert_eq!(&settled.faces, &free.faces);
            let diagonal = mesh.bbox().diagonal();
            let bvh = Bvh::build(&mesh.positions, &mesh.faces);
            let (mut moved, mut on_input) = (0, 0);
            for (p, q) in free.positions.iter().zip(&settled.positions) {
                if p != q {
                    moved += 1;
                    let d = bvh.closest_point(*q).map_or(f64::INFINITY, |n| n.distance_squared.sqrt());
                    on_input += usize::from(d <= 1e-9 * diagonal);
                }
            }
            proptest::prop_assert_eq!(moved, did.moved);
            proptest::prop_assert_eq!(on_input, moved);
            let min_cross = 2.0 * 1e-12 * diagonal * diagonal;
            for face in &settled.faces {
                let [a, b, c] = face.map(|v| settled.positions[v as usize]);
                let [x, y, z] = face.map(|v| free.positions[v as usize]);
                let flat = |a: DVec3, b: DVec3, c: DVec3| triangle::cross(a, b, c).length() <= min_cross;
                proptest::prop_assert!(!flat(a, b, c) || flat(x, y, z));
            }
        }
    }

    /// The largest distance from a vertex of `out` to the surface of `input`.
    fn farthest_vertex(input: &Mesh, out: &Mesh) -> f64 {
        let bvh = Bvh::build(&input.positions, &input.faces);
        (out.positions.iter())
            .filter_map(|&p| bvh.closest_point(p))
            .map(|n| n.distance_squared.sqrt())
            .fold(0.0, f64::max)
    }

    #[test]
    fn settled_vertices_lie_on_the_input_with_exact_uvs() {
        let input = coarsen_shapes::with_spherical_uvs(crate::live::parts::tests::bumpy(4));
        let goal = Goal::Vertices(300);
        // In parts first, cut small.
        let parts = PartOptions {
            min_faces: 0,
            faces_per_part: 256,
            ..PartOptions::default()
        };
        let (free, none) = qem_with(&input, goal, &parts, false);
        let (settled, did) = qem_with(&input, goal, &parts, true);
        assert_eq!(none, Settled::default());
        // The same collapses: only the moved vertices' positions (and values) differ.
        assert_eq!(settled.faces, free.faces);
        assert!(did.moved > 200 && did.refused == 0, "{did:?}");
        assert_eq!(did.moved + did.refused, {
            let at_input: std::collections::HashSet<_> = input
                .positions
                .iter()
                .map(|p| p.to_array().map(f64::to_bits))
                .collect();
            (free.positions.iter())
                .filter(|p| !at_input.contains(&p.to_array().map(f64::to_bits)))
                .count()
        });
        let diagonal = 2.0 * 3f64.sqrt();
        assert!(farthest_vertex(&input, &free) > 1e-3 * diagonal);
        assert!(farthest_vertex(&input, &settled) < 1e-12 * diagonal);
        let before = coarsen_metrics::texture(&input, &free, diagonal).unwrap();
        let after = coarsen_metrics::texture(&input, &settled, diagonal).unwrap();
        assert!(before.distortion_max_pct > 0.05, "{before:?}");
        assert!(after.distortion_max_pct < 1e-9, "{after:?}");
        assert_eq!(after.uv_flipped + after.uv_degenerate, 0, "{after:?}");
        let validity = coarsen_metrics::validity(Some(&input), &settled).unwrap();
        assert_eq!(validity.n_flipped, Some(0));
    }
}
