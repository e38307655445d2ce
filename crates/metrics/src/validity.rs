//! Validity of the output mesh: counts, topology, degenerate and flipped faces (metrics
//! spec, "Validity of the output").

use crate::error::{MetricsError, Role};
use crate::prepare::{Prepared, map_chunks};
use coarsen_geom::triangle;
use coarsen_mesh::topology::TopologySummary;
use coarsen_mesh::{DVec3, Mesh, Topology};
use coarsen_spatial::{Bvh, closest_point_on_segment};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Output faces per parallel chunk of the flip test.
const CHUNK: usize = 2048;

/// Counts and topology of the output, and its faces that are degenerate or turned over.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Validity {
    /// Vertices of the mesh (all of them, used by a face or not).
    pub n_vertices: usize,
    /// Faces of the mesh.
    pub n_faces: usize,
    /// Every edge has one or two faces and every vertex's faces form one fan.
    pub manifold: bool,
    /// Connected components of faces (joined across edges).
    pub n_components: usize,
    /// Boundary loops.
    pub n_boundary_loops: usize,
    /// Total genus from Euler's formula per component (`g = (2 − χ − b)/2`), `None` when a
    /// component is not an orientable manifold.
    pub genus: Option<i64>,
    /// Faces with a repeated vertex or an area below `1e-12 × (bbox diagonal)²`.
    pub n_degenerate: usize,
    /// Faces whose normal is more than 90° from the input surface's normal at the input
    /// point nearest the face's centroid; `None` when there is no input to compare with.
    /// The input normal at a point inside a face is that face's normal; on an edge, the
    /// area-weighted mean of the edge's faces; at a vertex, the area-weighted vertex
    /// normal (where such a mean vanishes, the nearest face's own normal). Degenerate
    /// output faces have no normal and are never counted.
    pub n_flipped: Option<usize>,
}

/// Checks `output` and, when an `input` is given, counts output faces turned against it.
///
/// Errors when a mesh has a bad index or a bad used vertex (not finite, or beyond
/// ±[`MAX_COORDINATE`](crate::MAX_COORDINATE)), or is too large for the topology tables.
pub fn validity(input: Option<&Mesh>, output: &Mesh) -> Result<Validity, MetricsError> {
    let output = Prepared::new(output, Role::Output)?;
    let out_topology = topology(&output, Role::Output)?;
    let flip = match input {
        Some(input) => {
            let input = Prepared::new(input, Role::Input)?;
            let in_topology = topology(&input, Role::Input)?;
            let bvh = Bvh::build(&input.mesh.positions, &input.mesh.faces);
            Some(count_flipped(&output, &input, &bvh, &in_topology))
        }
        None => None,
    };
    Ok(validity_of(
        &output,
        &out_topology.summary(output.mesh),
        flip,
    ))
}

/// Builds the topology of a checked mesh.
pub(crate) fn topology(p: &Prepared, role: Role) -> Result<Topology, MetricsError> {
    Topology::try_build(p.mesh).map_err(|source| MetricsError::Topology { mesh: role, source })
}

/// True when the mesh is closed (no boundary edge), manifold and consistently oriented,
/// so that its signed volume is the volume it encloses.
pub(crate) fn encloses_volume(t: &Topology) -> bool {
    t.n_edges() > 0
        && t.is_manifold()
        && t.is_consistently_oriented()
        && (0..t.n_edges() as u32).all(|e| !t.is_boundary_edge(e))
}

/// [`validity`] of a checked mesh, from its topology summary and its flipped-face count.
pub(crate) fn validity_of(
    output: &Prepared,
    summary: &TopologySummary,
    n_flipped: Option<usize>,
) -> Validity {
    Validity {
        n_vertices: output.mesh.n_vertices(),
        n_faces: output.mesh.n_faces(),
        manifold: summary.manifold,
        n_components: summary.n_components,
        n_boundary_loops: summary.n_boundary_loops,
        genus: summary.genus_total,
        n_degenerate: summary.n_degenerate_faces,
        n_flipped,
    }
}

/// The input surface's normal at a point of face `face` with barycentric weights `bary`
/// (unnormalised): the face's own inside it, the summed normals of the faces around the
/// edge or vertex it lies on (a weight of exactly 0 puts it on the opposite edge).
fn surface_normal(mesh: &Mesh, topo: &Topology, face: u32, bary: [f64; 3]) -> DVec3 {
    let vertex_normal = |v: u32| -> DVec3 {
        topo.vertex_faces(v)
            .iter()
            .map(|&f| face_cross(mesh, f))
            .sum()
    };
    let edge_normal = |a: u32, b: u32| {
        topo.find_edge(a, b).map_or(DVec3::ZERO, |e| {
            topo.edge_faces(e)
                .iter()
                .map(|&f| face_cross(mesh, f))
                .sum()
        })
    };
    surface_normal_with(mesh, face, bary, vertex_normal, edge_normal)
}

/// Face `f`'s cross product (twice its area along its normal).
pub(crate) fn face_cross(mesh: &Mesh, f: u32) -> DVec3 {
    let [a, b, c] = mesh.corners(f as usize);
    triangle::cross(a, b, c)
}

/// [`surface_normal`] with the summed normals around a vertex and along an edge given.
pub(crate) fn surface_normal_with(
    mesh: &Mesh,
    face: u32,
    bary: [f64; 3],
    vertex_normal: impl Fn(u32) -> DVec3,
    edge_normal: impl Fn(u32, u32) -> DVec3,
) -> DVec3 {
    let face_cross = |f: u32| face_cross(mesh, f);
    let [p, q, r] = mesh.faces[face as usize];
    let n = match bary.map(|w| w != 0.0) {
        [true, false, false] => vertex_normal(p),
        [false, true, false] => vertex_normal(q),
        [false, false, true] => vertex_normal(r),
        [true, true, false] => edge_normal(p, q),
        [false, true, true] => edge_normal(q, r),
        [true, false, true] => edge_normal(r, p),
        _ => DVec3::ZERO,
    };
    if n.length_squared() > 0.0 {
        n
    } else {
        face_cross(face)
    }
}

/// True when triangle `abc` points away (> 90°) from the input normal at the nearest point
/// of the input to its centroid — the test behind [`Validity::n_flipped`]; `normal` gives
/// the input normal at a face and barycentric point ([`surface_normal`]).
fn faces_away(
    bvh: &Bvh,
    normal: impl Fn(u32, [f64; 3]) -> DVec3,
    a: DVec3,
    b: DVec3,
    c: DVec3,
) -> bool {
    let n_out = triangle::cross(a, b, c);
    n_out != DVec3::ZERO
        && bvh
            .closest_point(triangle::centroid(a, b, c))
            .is_some_and(|hit| n_out.dot(normal(hit.face, hit.bary)) < 0.0)
}

/// Output faces whose normal points away (> 90°) from the input normal nearest their
/// centroid (see [`Validity::n_flipped`]).
pub(crate) fn count_flipped(
    output: &Prepared,
    input: &Prepared,
    in_bvh: &Bvh,
    in_topology: &Topology,
) -> usize {
    let (out_mesh, in_mesh) = (output.mesh, input.mesh);
    let normal = |f, bary| surface_normal(in_mesh, in_topology, f, bary);
    map_chunks(out_mesh.n_faces(), CHUNK, |range| {
        range
            .filter(|&f| {
                let [a, b, c] = out_mesh.corners(f);
                faces_away(in_bvh, normal, a, b, c)
            })
            .count()
    })
    .into_iter()
    .sum()
}

/// Which output faces [`count_flipped`] counts, face by face.
pub(crate) fn flipped_faces(
    output: &Prepared,
    input: &Prepared,
    in_bvh: &Bvh,
    in_topology: &Topology,
) -> Vec<bool> {
    let (out_mesh, in_mesh) = (output.mesh, input.mesh);
    let normal = |f, bary| surface_normal(in_mesh, in_topology, f, bary);
    map_chunks(out_mesh.n_faces(), CHUNK, |range| {
        range
            .map(|f| {
                let [a, b, c] = out_mesh.corners(f);
                faces_away(in_bvh, normal, a, b, c)
            })
            .collect::<Vec<bool>>()
    })
    .concat()
}

/// The indexes of an input surface that [`Facing`] reads: its faces around each vertex
/// (for the normals at vertices and edges), its boundary edges and its face hierarchy.
/// Owns no reference to the mesh or its adjacency, so a run can build it once, share it,
/// and let the adjacency go.
pub struct SurfaceIndex {
    /// Vertex `v`'s faces are `vertex_faces[vertex_face_offsets[v]..vertex_face_offsets[v + 1]]`,
    /// in the adjacency's order.
    vertex_face_offsets: Vec<u32>,
    vertex_faces: Vec<u32>,
    /// The boundary edges (edges of one face), in the adjacency's edge order.
    boundary_edges: Vec<[u32; 2]>,
    bvh: Bvh,
    /// The rim the boundary projections follow: the boundary edges and the edges of three
    /// or more faces (where a run's repairs cut the surface apart, making boundary).
    rim_edges: Vec<[u32; 2]>,
    /// The rim edges as degenerate triangles `[a, b, b]` (their nearest point is the
    /// segment's), indexed; `None` without a rim.
    rim_bvh: Option<Bvh>,
    /// `(vertex, rim edge)` for both ends of every rim edge, by vertex.
    rim_ends: Vec<(u32, u32)>,
}

/// What a [`SurfaceIndex`] takes of its input's adjacency, taken before the face
/// hierarchy is built: a caller can then let the adjacency go first (at millions of faces
/// the two together would set the run's peak memory).
pub struct SurfaceParts {
    vertex_face_offsets: Vec<u32>,
    vertex_faces: Vec<u32>,
    boundary_edges: Vec<[u32; 2]>,
    rim_edges: Vec<[u32; 2]>,
}

impl SurfaceParts {
    /// The parts of `input`'s index from its adjacency `topo`.
    pub fn of(input: &Mesh, topo: &Topology) -> Self {
        let n = input.n_vertices();
        let mut vertex_face_offsets = Vec::with_capacity(n + 1);
        let mut vertex_faces = Vec::with_capacity(3 * input.n_faces());
        vertex_face_offsets.push(0);
        for v in 0..n as u32 {
            vertex_faces.extend_from_slice(topo.vertex_faces(v));
            vertex_face_offsets.push(vertex_faces.len() as u32);
        }
        let boundary_edges: Vec<[u32; 2]> = (0..topo.n_edges() as u32)
            .filter(|&e| topo.is_boundary_edge(e))
            .map(|e| topo.edge(e))
            .collect();
        let rim_edges: Vec<[u32; 2]> = (0..topo.n_edges() as u32)
            .filter(|&e| topo.is_boundary_edge(e) || topo.edge_faces(e).len() >= 3)
            .map(|e| topo.edge(e))
            .collect();
        SurfaceParts {
            vertex_face_offsets,
            vertex_faces,
            boundary_edges,
            rim_edges,
        }
    }

    /// The index of `input` (the mesh these parts were taken from).
    pub fn build(self, input: &Mesh) -> SurfaceIndex {
        let SurfaceParts {
            vertex_face_offsets,
            vertex_faces,
            boundary_edges,
            rim_edges,
        } = self;
        let segments: Vec<[u32; 3]> = rim_edges.iter().map(|&[a, b]| [a, b, b]).collect();
        let mut rim_ends: Vec<(u32, u32)> = (0..rim_edges.len() as u32)
            .flat_map(|e| rim_edges[e as usize].map(|v| (v, e)))
            .collect();
        rim_ends.sort_unstable();
        SurfaceIndex {
            rim_ends,
            vertex_face_offsets,
            vertex_faces,
            rim_bvh: (!segments.is_empty()).then(|| Bvh::build(&input.positions, &segments)),
            boundary_edges,
            rim_edges,
            bvh: Bvh::build(&input.positions, &input.faces),
        }
    }
}

impl SurfaceIndex {
    /// Indexes `input` (its faces and adjacency).
    pub fn new(input: &Mesh) -> Self {
        SurfaceIndex::with_topology(input, &Topology::build(input))
    }

    /// Indexes the faces of `input`, whose adjacency `topo` was built earlier.
    pub fn with_topology(input: &Mesh, topo: &Topology) -> Self {
        SurfaceParts::of(input, topo).build(input)
    }

    /// The rim edges at vertex `v`.
    fn rim_edges_at(&self, v: u32) -> impl Iterator<Item = u32> + '_ {
        let from = self.rim_ends.partition_point(|&(w, _)| w < v);
        self.rim_ends[from..]
            .iter()
            .take_while(move |&&(w, _)| w == v)
            .map(|&(_, e)| e)
    }

    /// The faces around vertex `v`.
    fn vertex_faces(&self, v: u32) -> &[u32] {
        let v = v as usize;
        match self.vertex_face_offsets.get(v..v + 2) {
            Some(&[a, b]) => &self.vertex_faces[a as usize..b as usize],
            _ => &[],
        }
    }

    /// The input normal at barycentric point `bary` of face `face` of `mesh` (the mesh
    /// indexed), as [`surface_normal`] gives it from the adjacency.
    fn normal(&self, mesh: &Mesh, face: u32, bary: [f64; 3]) -> DVec3 {
        let vertex_normal = |v: u32| -> DVec3 {
            self.vertex_faces(v)
                .iter()
                .map(|&f| face_cross(mesh, f))
                .sum()
        };
        let edge_normal = |a: u32, b: u32| -> DVec3 {
            // The faces on edge ab, ascending as the adjacency lists an edge's faces (the
            // same sum, bit for bit).
            let mut on_edge: Vec<u32> = self
                .vertex_faces(a)
                .iter()
                .copied()
                .filter(|&f| mesh.faces[f as usize].contains(&b))
                .collect();
            on_edge.sort_unstable();
            on_edge.into_iter().map(|f| face_cross(mesh, f)).sum()
        };
        surface_normal_with(mesh, face, bary, vertex_normal, edge_normal)
    }
}

/// An input surface indexed for the flipped-face test of the metrics, for stages that must
/// not produce a face the metrics would count as flipped.
pub struct Facing<'a> {
    mesh: &'a Mesh,
    index: Arc<SurfaceIndex>,
}

impl<'a> Facing<'a> {
    /// Indexes `input` (its faces and adjacency).
    pub fn new(input: &'a Mesh) -> Self {
        Facing::with_index(input, Arc::new(SurfaceIndex::new(input)))
    }

    /// `input` with its index built earlier by [`SurfaceIndex::new`] from the same mesh.
    pub fn with_index(input: &'a Mesh, index: Arc<SurfaceIndex>) -> Self {
        Facing { mesh: input, index }
    }

    /// The index of the input's faces.
    pub fn bvh(&self) -> &Bvh {
        &self.index.bvh
    }

    /// The input's boundary edges (edges of one face), in the order of its adjacency's edges.
    pub fn boundary_edges(&self) -> &[[u32; 2]] {
        &self.index.boundary_edges
    }

    /// The index of the input's rim: its boundary edges and edges of three or more faces;
    /// `None` when it has none.
    fn rim_bvh(&self) -> Option<&Bvh> {
        self.index.rim_bvh.as_ref()
    }

    /// The nearest point of the input's boundary edges (and edges of three or more faces,
    /// which a run's repairs cut apart) to `p`; `None` without any (or for a point that is
    /// not finite).
    pub fn project_boundary(&self, p: DVec3) -> Option<DVec3> {
        self.rim_bvh()?.closest_point(p).map(|h| h.point)
    }

    /// The nearest point to `target` of the input's boundary (as [`Facing::project_boundary`]
    /// sees it) within `reach` along it (arc length) of the boundary point nearest `from`: a
    /// projection that follows the loop `from` is on, where [`Facing::project_boundary`] may
    /// land on another loop or across a bay of this one. `None` without a boundary (or for
    /// points that are not finite).
    pub fn project_boundary_along(&self, from: DVec3, target: DVec3, reach: f64) -> Option<DVec3> {
        /// Most boundary edges one projection looks at.
        const MOST_EDGES: usize = 4096;
        if !target.is_finite() {
            return None;
        }
        let start = self.rim_bvh()?.closest_point(from)?;
        let index = &self.index;
        let position = |v: u32| self.mesh.positions[v as usize];
        let nearest_on = |e: u32| {
            let [a, b] = index.rim_edges[e as usize].map(position);
            closest_point_on_segment(target, a, b).0
        };
        let mut best = nearest_on(start.face);
        let mut best_d2 = best.distance_squared(target);
        // Walk out from the start's edge through both its ends, each vertex reached with the
        // arc length from the start and the edge it was reached by (a loop shorter than the
        // reach is walked round again: the same points, which change nothing).
        let [a, b] = index.rim_edges[start.face as usize];
        let mut front = vec![
            (a, start.point.distance(position(a)), start.face),
            (b, start.point.distance(position(b)), start.face),
        ];
        let mut looked = 1;
        while let Some((v, arc, by)) = front.pop() {
            if arc > reach {
                continue;
            }
            for e in index.rim_edges_at(v) {
                if e == by || looked >= MOST_EDGES {
                    continue;
                }
                looked += 1;
                let q = nearest_on(e);
                let d2 = q.distance_squared(target);
                if d2 < best_d2 {
                    (best, best_d2) = (q, d2);
                }
                let [x, y] = index.rim_edges[e as usize];
                let w = if x == v { y } else { x };
                front.push((w, arc + position(v).distance(position(w)), e));
            }
        }
        Some(best)
    }

    /// The nearest point to `p` of the input's faces that face the same side as `normal`
    /// (a positive dot product): where a thin part's two sides lie close, the point on the
    /// side a triangle of that normal belongs to. `None` when no face does (or for a point
    /// that is not finite).
    pub fn project_facing(&self, p: DVec3, normal: DVec3) -> Option<DVec3> {
        // No side to face: every face would be refused, after a walk of the whole tree.
        if normal == DVec3::ZERO || !normal.is_finite() {
            return None;
        }
        self.index
            .bvh
            .closest_point_where(p, |f| face_cross(self.mesh, f).dot(normal) > 0.0)
            .map(|h| h.point)
    }

    /// True when triangle `abc` would count as flipped against the input.
    pub fn faces_away(&self, a: DVec3, b: DVec3, c: DVec3) -> bool {
        let normal = |f, bary| self.index.normal(self.mesh, f, bary);
        faces_away(&self.index.bvh, normal, a, b, c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::icosphere;

    /// An equilateral triangle of side ≈ 0.17 centred at `centre`, counter-clockwise about `n`.
    fn small_triangle_facing(centre: DVec3, n: DVec3) -> Mesh {
        let (u, v) = (DVec3::Y, n.cross(DVec3::Y));
        let s = 3f64.sqrt() / 2.0;
        let corners = vec![
            centre + u * 0.1,
            centre + (u * -0.5 + v * s) * 0.1,
            centre + (u * -0.5 - v * s) * 0.1,
        ];
        Mesh::new(corners, vec![[0, 1, 2]])
    }

    #[test]
    fn closed_sphere_is_a_valid_genus_zero_manifold() {
        let m = icosphere(2);
        let v = validity(Some(&m), &m).unwrap();
        assert_eq!(
            v,
            Validity {
                n_vertices: 162,
                n_faces: 320,
                manifold: true,
                n_components: 1,
                n_boundary_loops: 0,
                genus: Some(0),
                n_degenerate: 0,
                n_flipped: Some(0),
            }
        );
        assert_eq!(validity(None, &m).unwrap().n_flipped, None);
    }

    #[test]
    fn turned_over_faces_are_counted_as_flipped() {
        let input = icosphere(3);
        let mut output = icosphere(2);
        for f in [0, 5, 17] {
            output.faces[f].swap(1, 2);
        }
        let v = validity(Some(&input), &output).unwrap();
        assert_eq!(v.n_flipped, Some(3));
        // A face turned over inside a closed surface makes its edges run the same way
        // as the neighbours': still closed, but not oriented.
        assert!(v.manifold);
    }

    /// A steep ridge (two faces meeting at 2·atan(0.1) ≈ 11°) and an output face hanging
    /// above it, tilted towards the left slope: its centroid's nearest input point is on
    /// the ridge edge, where the input normal is the mean of both slopes (straight up).
    /// Judged against the right slope alone it would look turned over; it is not. The
    /// same face turned over is.
    ///
    /// ```text
    ///        out (normal ∝ (−3, 0, 1))
    ///
    ///         /\   ridge along y at x = 0, z = 0
    ///        /  \
    ///   (−1,0,−10) (1,0,−10)
    /// ```
    #[test]
    fn faces_above_a_sharp_ridge_are_judged_against_both_slopes() {
        let input = Mesh::new(
            vec![
                DVec3::new(0.0, -1.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(1.0, 0.0, -10.0),
                DVec3::new(-1.0, 0.0, -10.0),
            ],
            vec![[0, 2, 1], [0, 1, 3]],
        );
        let n = DVec3::new(-3.0, 0.0, 1.0).normalize();
        let mut output = small_triangle_facing(DVec3::new(0.0, 0.0, 1.0), n);
        assert!(output.face_normal(0).dot(n) > 0.999);
        assert_eq!(validity(Some(&input), &output).unwrap().n_flipped, Some(0));
        output.faces[0].swap(1, 2);
        assert_eq!(validity(Some(&input), &output).unwrap().n_flipped, Some(1));
    }

    /// A thin sheet: two unit squares 0.01 apart, the upper facing up, the lower down. A
    /// point just below the upper square's middle is nearer the lower one; projected for a
    /// triangle facing up it lands on the upper square, for one facing down on the lower.
    #[test]
    fn projection_for_a_side_lands_on_the_faces_of_that_side() {
        let square = |z: f64| {
            [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)].map(|(x, y)| DVec3::new(x, y, z))
        };
        let positions: Vec<DVec3> = square(0.01).into_iter().chain(square(0.0)).collect();
        let input = Mesh::new(positions, vec![[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]]);
        assert!(input.face_normal(0).z > 0.99 && input.face_normal(2).z < -0.99);
        let facing = Facing::new(&input);
        let p = DVec3::new(0.5, 0.4, 0.004);
        assert_eq!(facing.bvh().closest_point(p).unwrap().point.z, 0.0);
        let up = facing.project_facing(p, DVec3::Z).unwrap();
        assert_eq!(up, DVec3::new(0.5, 0.4, 0.01));
        let down = facing.project_facing(p, -DVec3::Z).unwrap();
        assert_eq!(down, DVec3::new(0.5, 0.4, 0.0));
        // No face of the sheet faces sideways; no normal faces no side.
        assert!(facing.project_facing(p, DVec3::X).is_none());
        assert!(facing.project_facing(p, DVec3::ZERO).is_none());
        assert!(facing.project_facing(p, DVec3::NAN).is_none());
    }

    /// A steep four-sided peak (apex at height 10 over a 2 × 2 base) and an output face
    /// above it, tilted towards −x: its centroid's nearest input point is the apex, where
    /// the input normal is the area-weighted mean of the four slopes (straight up). Judged
    /// against the +x slope alone it would look turned over; it is not. The same face
    /// turned over is.
    #[test]
    fn faces_above_a_sharp_peak_are_judged_against_the_vertex_normal() {
        let input = Mesh::new(
            vec![
                DVec3::new(0.0, 0.0, 10.0),
                DVec3::new(1.0, -1.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(-1.0, 1.0, 0.0),
                DVec3::new(-1.0, -1.0, 0.0),
            ],
            vec![[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1]],
        );
        assert!(input.face_normal(0).x > 0.99);
        let n = DVec3::new(-3.0, 0.0, 1.0).normalize();
        assert!(n.dot(input.face_normal(0)) < 0.0);
        let mut output = small_triangle_facing(DVec3::new(0.0, 0.0, 11.0), n);
        assert!(output.face_normal(0).dot(n) > 0.999);
        assert_eq!(validity(Some(&input), &output).unwrap().n_flipped, Some(0));
        output.faces[0].swap(1, 2);
        assert_eq!(validity(Some(&input), &output).unwrap().n_flipped, Some(1));
    }

    /// A flat annulus between circles of radius 1 and 2 (32 segments each): a point at
    /// radius 1.4 is nearer the inner loop, but projected along the boundary from the outer
    /// loop it stays on the outer one, within the reach asked for.
    #[test]
    fn projection_along_the_boundary_stays_on_the_loop_it_starts_from() {
        let n = 32u32;
        let at = |r: f64, i: u32| {
            let a = std::f64::consts::TAU * f64::from(i) / f64::from(n);
            DVec3::new(r * a.cos(), r * a.sin(), 0.0)
        };
        let positions: Vec<DVec3> = (0..n)
            .map(|i| at(1.0, i))
            .chain((0..n).map(|i| at(2.0, i)))
            .collect();
        let faces: Vec<[u32; 3]> = (0..n)
            .flat_map(|i| {
                let j = (i + 1) % n;
                [[i, n + i, n + j], [i, n + j, j]]
            })
            .collect();
        let m = Mesh::new(positions, faces);
        let facing = Facing::new(&m);
        let target = 1.4 * DVec3::new(0.3f64.cos(), 0.3f64.sin(), 0.0);
        let inner = facing.project_boundary(target).unwrap();
        assert!(inner.length() < 1.0 + 1e-12, "{inner}");
        let outer = facing
            .project_boundary_along(DVec3::new(2.0, 0.0, 0.0), target, 1.0)
            .unwrap();
        assert!(outer.length() > 1.99, "{outer}");
        assert!((outer.y.atan2(outer.x) - 0.3).abs() < 0.01, "{outer}");
        // Within a reach of 0.1 only the two edges at the start are looked at.
        let near = facing
            .project_boundary_along(DVec3::new(2.0, 0.0, 0.0), target, 0.1)
            .unwrap();
        assert!(
            near.length() > 1.99 && near.y.atan2(near.x) <= std::f64::consts::TAU / 32.0 + 1e-12,
            "{near}"
        );
        assert_eq!(
            facing.project_boundary_along(DVec3::ZERO, DVec3::NAN, 1.0),
            None
        );
        let closed = icosphere(1);
        assert_eq!(
            Facing::new(&closed).project_boundary_along(DVec3::X, DVec3::X, 1.0),
            None
        );
    }

    /// Three triangles on one edge (a fin): a run's repairs cut that edge apart, making
    /// boundary of it, so the boundary projections see it as boundary too.
    #[test]
    fn edges_of_three_faces_count_as_boundary_for_the_projections() {
        let m = Mesh::new(
            vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(4.0, 0.0, 0.0),
                DVec3::new(2.0, 3.0, 0.0),
                DVec3::new(2.0, -3.0, 0.0),
                DVec3::new(2.0, 0.0, 3.0),
            ],
            vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
        );
        let facing = Facing::new(&m);
        let p = DVec3::new(2.0, 0.4, 0.4);
        assert_eq!(facing.project_boundary(p), Some(DVec3::new(2.0, 0.0, 0.0)));
        assert_eq!(
            facing.project_boundary_along(DVec3::ZERO, p, 10.0),
            Some(DVec3::new(2.0, 0.0, 0.0))
        );
    }

    /// The surface index keeps the faces around each vertex and the boundary edges, not
    /// the adjacency: its normals at vertices, on edges and inside faces must be the
    /// adjacency's, bit for bit, and its boundary edges the adjacency's, in order.
    #[test]
    fn the_surface_index_gives_the_adjacency_normals_bit_for_bit() {
        let mut m = icosphere(2);
        // Uneven faces (so that the order of a sum would show) and a hole.
        for (i, p) in m.positions.iter_mut().enumerate() {
            *p *= 1.0 + 0.1 * ((i as f64) * 0.7).sin();
        }
        m.faces.retain(|f| !f.contains(&5));
        let topo = Topology::build(&m);
        let index = SurfaceIndex::with_topology(&m, &topo);
        let third = 1.0 / 3.0;
        let points = [
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.5, 0.5, 0.0],
            [0.0, 0.3, 0.7],
            [0.6, 0.0, 0.4],
            [third, third, third],
        ];
        for f in 0..m.n_faces() as u32 {
            for bary in points {
                let (a, b) = (
                    index.normal(&m, f, bary),
                    surface_normal(&m, &topo, f, bary),
                );
                assert_eq!(
                    a.to_array().map(f64::to_bits),
                    b.to_array().map(f64::to_bits)
                );
            }
        }
        let boundary: Vec<[u32; 2]> = (0..topo.n_edges() as u32)
            .filter(|&e| topo.is_boundary_edge(e))
            .map(|e| topo.edge(e))
            .collect();
        assert_eq!(boundary.len(), 5, "the hole's rim");
        assert_eq!(
            Facing::with_index(&m, Arc::new(index)).boundary_edges(),
            boundary
        );
    }

    #[test]
    fn an_open_disc_with_a_sliver_has_a_boundary_and_a_degenerate_face() {
        let mut m = icosphere(2);
        // Drop the faces around vertex 0: one hole.
        m.faces.retain(|f| !f.contains(&0));
        // A zero-area face joined to nothing else: a second component with its own loop.
        let n = m.positions.len() as u32;
        m.positions
            .extend([DVec3::splat(3.0), DVec3::splat(4.0), DVec3::splat(5.0)]);
        m.faces.push([n, n + 1, n + 2]);
        let v = validity(None, &m).unwrap();
        assert_eq!(v.n_components, 2);
        assert_eq!(v.n_boundary_loops, 2);
        assert_eq!(v.n_degenerate, 1);
        assert_eq!(v.genus, Some(0));
    }

    #[test]
    fn encloses_volume_needs_closed_and_oriented() {
        let m = icosphere(1);
        let t = |m: &Mesh| Topology::try_build(m).unwrap();
        assert!(encloses_volume(&t(&m)));
        let mut open = m.clone();
        open.faces.pop();
        assert!(!encloses_volume(&t(&open)));
        let mut turned = m.clone();
        turned.faces[3].swap(0, 1);
        assert!(!encloses_volume(&t(&turned)));
        assert!(!encloses_volume(&t(&Mesh::default())));
    }
}
