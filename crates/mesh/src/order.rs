//! A mesh's vertices and faces in the order of a Morton (Z-order) curve through space.
//!
//! Vertices are ordered by the Morton code of their position (21 bits per axis, in the
//! mesh's box; ties by vertex index), faces by the first of their corners on that curve
//! (ties by face index). Vertices and faces that are close in space are then close in
//! memory, which is what a large mesh read in the order a scanner or a subdivision wrote
//! it lacks: the runner renumbers large inputs this way ([`along_curve`]), and the CVT
//! clusterer lays its tables out in this order. The order depends only on the positions
//! and faces, never on the thread count.

use crate::{FaceOrigins, Index, Mesh, VertexOrigins};
use coarsen_geom::DVec3;
use rayon::prelude::*;

/// The Morton order of a mesh's vertices and faces (see the module docs).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CurveOrder {
    /// Position `i` on the curve holds old vertex `vertices[i]`.
    pub vertices: Vec<Index>,
    /// Old vertex `v` sits at position `vertex_rank[v]` on the curve.
    pub vertex_rank: Vec<Index>,
    /// Position `i` in the face order holds old face `faces[i]`.
    pub faces: Vec<Index>,
}

impl CurveOrder {
    /// The curve order of `mesh`; `None` when a face names a vertex out of range.
    pub fn of(mesh: &Mesh) -> Option<CurveOrder> {
        mesh.validate_indices().ok()?;
        let (center, scale) = unit_box(mesh);
        let nv = mesh.n_vertices();
        // Already in order (a mesh the runner renumbered): no sort needed to tell.
        if in_order(mesh, center, scale) {
            let identity = |n: usize| (0..n as Index).collect::<Vec<_>>();
            return Some(CurveOrder {
                vertices: identity(nv),
                vertex_rank: identity(nv),
                faces: identity(mesh.n_faces()),
            });
        }
        let mut keyed: Vec<(u64, Index)> = mesh
            .positions
            .par_iter()
            .enumerate()
            .map(|(v, &p)| (morton((p - center) * scale), v as Index))
            .collect();
        keyed.par_sort_unstable();
        let vertices: Vec<Index> = keyed.into_par_iter().map(|k| k.1).collect();
        let mut vertex_rank = vec![0 as Index; nv];
        for (i, &v) in vertices.iter().enumerate() {
            vertex_rank[v as usize] = i as Index;
        }
        let first: Vec<Index> = mesh
            .faces
            .par_iter()
            .map(|f| min3(f.map(|v| vertex_rank[v as usize])))
            .collect();
        // Counting sort by first corner: ties stay in face order.
        let mut at = vec![0 as Index; nv + 1];
        for &k in &first {
            at[k as usize + 1] += 1;
        }
        for i in 0..nv {
            at[i + 1] += at[i];
        }
        let mut faces = vec![0 as Index; mesh.n_faces()];
        for (f, &k) in first.iter().enumerate() {
            faces[at[k as usize] as usize] = f as Index;
            at[k as usize] += 1;
        }
        Some(CurveOrder {
            vertices,
            vertex_rank,
            faces,
        })
    }

    /// True when the mesh already is in this order.
    pub fn is_identity(&self) -> bool {
        let same = |order: &[Index]| order.iter().enumerate().all(|(i, &x)| i as Index == x);
        same(&self.vertices) && same(&self.faces)
    }
}

/// True when `mesh` is already in its curve order ([`CurveOrder::of`] would give every
/// vertex and face its own index back), told without building the order.
pub fn is_along_curve(mesh: &Mesh) -> bool {
    if mesh.validate_indices().is_err() {
        return false;
    }
    let (center, scale) = unit_box(mesh);
    in_order(mesh, center, scale)
}

/// True when the vertices' Morton codes in the box `center`, `scale` ascend and the faces'
/// first corners do.
fn in_order(mesh: &Mesh, center: DVec3, scale: f64) -> bool {
    let key = |p: DVec3| morton((p - center) * scale);
    mesh.positions
        .par_windows(2)
        .all(|w| key(w[0]) <= key(w[1]))
        && mesh.faces.par_windows(2).all(|w| min3(w[0]) <= min3(w[1]))
}

/// The centre of `mesh`'s box and the scale that gives the box a unit diagonal (1 for a
/// box of one point): the coordinates `(p − centre) · scale` the curve is drawn in.
pub fn unit_box(mesh: &Mesh) -> (DVec3, f64) {
    let bbox = mesh.bbox();
    let diagonal = bbox.diagonal();
    let scale = if diagonal > 0.0 { 1.0 / diagonal } else { 1.0 };
    (bbox.center(), scale)
}

/// The smallest of a face's corners.
fn min3([a, b, c]: [Index; 3]) -> Index {
    a.min(b).min(c)
}

/// `mesh` with its vertices and faces renumbered along the Morton curve, every attribute
/// and marked edge carried; the same surface, faces keeping their corners' cyclic order. A mesh already in
/// that order, or with a face naming a vertex out of range, comes back as it is.
pub fn along_curve(mesh: Mesh) -> Mesh {
    let Some(order) = CurveOrder::of(&mesh) else {
        return mesh;
    };
    if order.is_identity() {
        return mesh;
    }
    let positions = order
        .vertices
        .par_iter()
        .map(|&v| mesh.positions[v as usize])
        .collect();
    let faces = order
        .faces
        .par_iter()
        .map(|&f| mesh.faces[f as usize].map(|v| order.vertex_rank[v as usize]))
        .collect();
    // The marked edges renumbered, smaller end first and sorted again.
    let mut marked_edges: Vec<[Index; 2]> = mesh
        .marked_edges
        .iter()
        .map(|e| e.map(|v| order.vertex_rank[v as usize]))
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    marked_edges.sort_unstable();
    if mesh.vertex_attrs.is_empty()
        && mesh.face_attrs.is_empty()
        && mesh.wedges.is_empty()
        && mesh.materials.is_empty()
    {
        return Mesh {
            marked_edges,
            ..Mesh::new(positions, faces)
        };
    }
    let CurveOrder {
        vertices,
        faces: face_order,
        vertex_rank,
    } = order;
    // The wedges keep their numbers: only their corners and vertices are renamed.
    let mut mesh = mesh;
    let wedges = std::mem::take(&mut mesh.wedges).permuted(&face_order, &vertex_rank);
    // Pure copies: every column carries.
    let mut out = mesh
        .rebuilt(
            positions,
            faces,
            &VertexOrigins::from_map(&vertices),
            &FaceOrigins::from_parents(face_order),
        )
        .0;
    out.wedges = wedges;
    out.marked_edges = marked_edges;
    out
}

/// The Morton code of `p`, a point of the box `[-1, 1]³` (coordinates beyond it are
/// clamped; NaN counts as -1), 21 bits per axis.
pub fn morton(p: DVec3) -> u64 {
    let spread = |x: f64| -> u64 {
        let mut v = (((x.clamp(-1.0, 1.0) + 1.0) * 0.5) * ((1u64 << 21) - 1) as f64) as u64;
        v &= 0x1f_ffff;
        v = (v | v << 32) & 0x1f_0000_0000_ffff;
        v = (v | v << 16) & 0x1f_0000_ff00_00ff;
        v = (v | v << 8) & 0x100f_00f0_0f00_f00f;
        v = (v | v << 4) & 0x10c3_0c30_c30c_30c3;
        v = (v | v << 2) & 0x1249_2492_4924_9249;
        v
    };
    spread(p.x) | spread(p.y) << 1 | spread(p.z) << 2
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{AttrValues, Topology};

    /// A grid of `n × n` quads (two triangles each) with its vertices and faces shuffled
    /// by a fixed stride, and a per-vertex and a per-face column naming the originals.
    fn shuffled_grid(n: u32) -> Mesh {
        let nv = (n + 1) * (n + 1);
        let stride = |len: u32| (0..len).map(move |i| (i * 7919) % len);
        // A permutation: 7919 is prime and divides neither count.
        assert!(!nv.is_multiple_of(7919) && !(2 * n * n).is_multiple_of(7919));
        let vmap: Vec<u32> = stride(nv).collect();
        let mut inverse = vec![0; nv as usize];
        for (i, &v) in vmap.iter().enumerate() {
            inverse[v as usize] = i as u32;
        }
        let positions = vmap
            .iter()
            .map(|&v| DVec3::new((v % (n + 1)) as f64, (v / (n + 1)) as f64, 0.0))
            .collect();
        let mut faces = Vec::new();
        for y in 0..n {
            for x in 0..n {
                let v = |dx: u32, dy: u32| inverse[((y + dy) * (n + 1) + x + dx) as usize];
                faces.push([v(0, 0), v(1, 0), v(1, 1)]);
                faces.push([v(0, 0), v(1, 1), v(0, 1)]);
            }
        }
        let nf = faces.len() as u32;
        let fmap: Vec<u32> = stride(nf).collect();
        let faces: Vec<[u32; 3]> = fmap.iter().map(|&f| faces[f as usize]).collect();
        let mut mesh = Mesh::new(positions, faces);
        mesh.vertex_attrs
            .insert("id", AttrValues::Label((0..nv).collect()));
        mesh.face_attrs
            .insert("id", AttrValues::Label((0..nf).collect()));
        mesh
    }

    #[test]
    fn renumbering_keeps_the_surface_and_carries_attributes() {
        let mesh = shuffled_grid(40);
        let ordered = along_curve(mesh.clone());
        assert_ne!(ordered.faces, mesh.faces);
        let AttrValues::Label(vid) = ordered.vertex_attrs.get("id").unwrap() else {
            panic!("vertex ids")
        };
        let AttrValues::Label(fid) = ordered.face_attrs.get("id").unwrap() else {
            panic!("face ids")
        };
        // Every vertex and face is the one its carried id names, corners in cyclic order.
        for (v, &old) in vid.iter().enumerate() {
            assert_eq!(ordered.positions[v], mesh.positions[old as usize]);
        }
        for (f, &old) in fid.iter().enumerate() {
            let renamed = ordered.faces[f].map(|v| vid[v as usize]);
            assert_eq!(renamed, mesh.faces[old as usize]);
        }
        let (a, b) = (Topology::build(&mesh), Topology::build(&ordered));
        assert_eq!(a.summary(&mesh), b.summary(&ordered));
        // Per-corner values (each corner's own) follow their faces.
        let mut cols = crate::Attributes::default();
        let corner_ids = (0..3 * mesh.n_faces() as u32).collect();
        cols.insert("corner", AttrValues::Label(corner_ids));
        let cornered = mesh.clone().with_corner_attributes(cols);
        let moved = along_curve(cornered.clone());
        moved.wedges.check(&moved.faces).unwrap();
        let Some(AttrValues::Label(c)) = moved.corner_column("corner") else {
            panic!("corner ids")
        };
        for (f, &old) in fid.iter().enumerate() {
            for k in 0..3 {
                assert_eq!(c[3 * f + k], 3 * old + k as u32);
            }
        }
        // In order now: ordering again changes nothing.
        assert!(CurveOrder::of(&ordered).unwrap().is_identity());
        assert_eq!(along_curve(ordered.clone()), ordered);
        // Vertices in order but two faces swapped: the faces are put back.
        let mut swapped = ordered.clone();
        let last = swapped.n_faces() - 1;
        swapped.faces.swap(0, last);
        let order = CurveOrder::of(&swapped).unwrap();
        assert!(!order.is_identity());
        let again = along_curve(swapped);
        assert!(CurveOrder::of(&again).unwrap().is_identity());
        let sorted = |m: &Mesh| {
            let mut f = m.faces.clone();
            f.sort_unstable();
            f
        };
        assert_eq!(sorted(&again), sorted(&ordered));
    }

    #[test]
    fn marked_edges_follow_the_renumbering() {
        // The grid's row y = 3, marked one edge at a time, in both directions.
        let mut mesh = shuffled_grid(40);
        let at = |x: f64, y: f64| {
            let p = DVec3::new(x, y, 0.0);
            mesh.positions.iter().position(|&q| q == p).unwrap() as u32
        };
        let marked: Vec<[u32; 2]> = (0..40)
            .map(|x| [at(f64::from(x + 1), 3.0), at(f64::from(x), 3.0)])
            .collect();
        mesh.marked_edges = marked;
        let ends = |m: &Mesh| {
            let mut pairs: Vec<[[u64; 3]; 2]> = m
                .marked_edges
                .iter()
                .map(|e| {
                    let mut p = e.map(|v| m.positions[v as usize].to_array().map(f64::to_bits));
                    p.sort_unstable();
                    p
                })
                .collect();
            pairs.sort_unstable();
            pairs
        };
        for ordered in [along_curve(mesh.clone()), {
            // Without attributes: the other way out.
            let mut bare = mesh.clone();
            bare.vertex_attrs.clear();
            bare.face_attrs.clear();
            along_curve(bare)
        }] {
            assert_eq!(ends(&ordered), ends(&mesh));
            assert!(ordered.marked_edges.iter().all(|[a, b]| a < b));
            assert!(ordered.marked_edges.is_sorted());
            assert!(ordered.validate_indices().is_ok());
        }
    }

    #[test]
    fn the_order_follows_the_curve_and_brings_neighbours_together() {
        let mesh = shuffled_grid(64);
        let order = CurveOrder::of(&mesh).unwrap();
        let code = |v: u32| {
            let b = mesh.bbox();
            morton((mesh.positions[v as usize] - b.center()) / b.diagonal())
        };
        assert!(order.vertices.windows(2).all(|w| code(w[0]) <= code(w[1])));
        // The mean index gap across a face's corners shrinks by an order of magnitude.
        let spread = |m: &Mesh| {
            m.faces
                .iter()
                .map(|f| (f.iter().max().unwrap() - f.iter().min().unwrap()) as f64)
                .sum::<f64>()
                / m.n_faces() as f64
        };
        let ordered = along_curve(mesh.clone());
        assert!(
            spread(&ordered) * 10.0 < spread(&mesh),
            "{} vs {}",
            spread(&ordered),
            spread(&mesh)
        );
    }

    #[test]
    fn out_of_range_faces_and_empty_meshes_are_left_alone() {
        let broken = Mesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::Y], vec![[0, 1, 7]]);
        assert!(CurveOrder::of(&broken).is_none());
        assert_eq!(along_curve(broken.clone()), broken);
        assert!(!is_along_curve(&broken));
        let empty = Mesh::default();
        assert!(CurveOrder::of(&empty).unwrap().is_identity());
        assert!(is_along_curve(&empty));
        assert_eq!(along_curve(empty.clone()), empty);
    }

    #[test]
    fn a_mesh_is_along_the_curve_exactly_when_its_order_is_the_identity() {
        let shuffled = shuffled_grid(32);
        assert!(!is_along_curve(&shuffled));
        assert!(!CurveOrder::of(&shuffled).unwrap().is_identity());
        let ordered = along_curve(shuffled);
        assert!(is_along_curve(&ordered));
        assert!(CurveOrder::of(&ordered).unwrap().is_identity());
        // Vertices in order but two faces swapped out of it.
        let mut faces_out = ordered.clone();
        let last = faces_out.faces.len() - 1;
        faces_out.faces.swap(0, last);
        assert!(!is_along_curve(&faces_out));
        assert!(!CurveOrder::of(&faces_out).unwrap().is_identity());
    }
}
