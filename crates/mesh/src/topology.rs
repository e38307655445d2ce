//! Adjacency of a triangle mesh, built from the face array into flat CSR tables.
//!
//! [`Topology::build`] makes two passes over the faces, one over the vertices, and one
//! over the edges:
//!
//! 1. **Classify faces.** A face that repeats a vertex index (or names a vertex out of
//!    range) is *skipped*: it takes part in no adjacency, has no edges and no component,
//!    and is counted.
//! 2. **Vertex → corners** by counting sort (counts, prefix sum, fill). Each entry carries
//!    the corner's two neighbours around its face, so the vertex pass reads in order.
//! 3. **One pass over the vertices.** Around vertex `v`, matching the faces' `next` and
//!    `prev` corners groups the faces of every edge `(v, x)` and links the faces into
//!    *fans*. An edge is created by its smaller endpoint, in order of the larger one, so
//!    edges come out sorted by `(a, b)` and need no hash map; `vertex_faces` is rewritten
//!    in fan order. Vertices of at most 16 faces that meet like a consistently oriented
//!    manifold take a quick path of pairwise comparisons in fixed arrays; every other
//!    vertex (high valence, boundary on a non-manifold edge, flips) takes the general path,
//!    which sorts `(other vertex, face)` pairs. Both give identical tables (tested).
//!    Big meshes run the pass over fixed ranges of vertices in parallel; a range needs
//!    nothing from the others (a boundary edge made by another range is named by its
//!    half-edge until all ids are known), and the ranges' tables are appended in vertex
//!    order with their local edge ids shifted.
//! 4. **Boundary loops** follow boundary edges from edge to edge within each fan's ends
//!    (see [`Topology::boundary_loop`]).
//! 5. **Components** over faces by union-find across edges (any edge, whatever its face
//!    count); vertices alone never connect two components, so a bow-tie vertex joining
//!    two otherwise separate parts leaves them two components. Orientability is searched
//!    only when some edge is flipped.
//!
//! Definitions used throughout:
//!
//! * a *boundary edge* has exactly one face; a *non-manifold edge* has three or more
//!   faces, or two faces that use it in the same direction (an *orientation flip*);
//! * a *fan* of vertex `v` is a maximal sequence of faces around `v` in which consecutive
//!   faces share an edge `(v, x)` that has exactly two faces (flipped or not);
//!   a vertex with more than one fan is a *non-manifold vertex* (a bow-tie, or a vertex on
//!   an edge with three or more faces);
//! * an *isolated* vertex is referenced by no face that takes part in adjacency.
//!
//! Every table is a flat array indexed by `u32`; nothing is allocated per element, and
//! the result depends only on the input arrays: every table is bit-identical for any
//! thread count (no hashing; the parallel parts either own disjoint slices or are
//! appended in a fixed order; tested against the one-range build).
//!
//! The adjacency of a uniform 1-to-4 split need not be built from its faces:
//! [`Topology::of_split`] derives it from the adjacency of the mesh split (the same tables,
//! tested against the build; 0.30 s instead of 0.53 s for the 3.8 M faces of the
//! post-process's finest level at 4.4 M input faces).
//!
//! Cost: linear in the mesh size. Meshes of fewer than 32 768 vertices (one range), or
//! one rayon thread, take the serial path (one range, whose tables are moved, not copied).
//! On a 2-core VM shared with other jobs, the 4.4 M-face subdivided bunny builds in
//! about 0.85 s serially; see `examples/build_timing.rs` to measure.

use crate::{Index, Mesh, sanity};
use coarsen_geom::triangle;
use rayon::prelude::*;
use serde::Serialize;
use std::sync::atomic::{AtomicU32, Ordering};

mod split;

pub use split::split_children;

/// The "no such element" value of `u32` tables (a skipped face's edges and component).
pub const NONE: u32 = u32::MAX;

/// The most faces [`Topology`] accepts: every CSR table then fits `u32` offsets.
pub const MAX_FACES: usize = (u32::MAX / 6) as usize;

const E_BOUNDARY: u8 = 1;
const E_MULTI: u8 = 2;
const E_FLIPPED: u8 = 4;

const V_ISOLATED: u8 = 1;
const V_BOUNDARY: u8 = 2;
const V_NON_MANIFOLD: u8 = 4;

/// A mesh too large for 32-bit adjacency tables.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TopologyError {
    /// More faces than [`MAX_FACES`].
    #[error("{n_faces} faces exceed the {max} that the topology tables support")]
    TooManyFaces {
        /// How many faces the mesh has.
        n_faces: usize,
        /// The limit.
        max: usize,
    },
    /// More vertices than 32-bit indices address.
    #[error("{n_vertices} vertices do not fit 32-bit indices")]
    TooManyVertices {
        /// How many vertices the mesh has.
        n_vertices: usize,
    },
}

/// Adjacency of one mesh: edges, vertex fans and one-rings, boundary loops, components.
///
/// Built once from a [`Mesh`] by [`Topology::build`]; it does not borrow the mesh and
/// goes stale when the mesh's faces change.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Topology {
    n_vertices: usize,
    /// Per face: edge of corner `i → i+1`, or [`NONE`] for skipped faces.
    face_edges: Vec<[u32; 3]>,
    /// Per face: its component, or [`NONE`] for skipped faces.
    face_component: Vec<u32>,
    n_repeated_index_faces: usize,
    n_out_of_range_faces: usize,

    /// Undirected edges `[a, b]`, `a < b`, sorted.
    edges: Vec<[u32; 2]>,
    edge_flags: Vec<u8>,
    edge_face_offsets: Vec<u32>,
    edge_faces: Vec<u32>,

    /// Per vertex: first edge whose smaller endpoint it is (edges are sorted).
    vertex_edge_offsets: Vec<u32>,
    vertex_face_offsets: Vec<u32>,
    vertex_faces: Vec<u32>,
    vertex_neighbor_offsets: Vec<u32>,
    vertex_neighbors: Vec<u32>,
    /// Per vertex: its first fan in `fan_offsets`.
    vertex_fan_offsets: Vec<u32>,
    /// Fan `i` is `vertex_faces[fan_offsets[i]..fan_offsets[i + 1]]`.
    fan_offsets: Vec<u32>,
    vertex_flags: Vec<u8>,

    loop_offsets: Vec<u32>,
    loop_vertices: Vec<u32>,
    loop_component: Vec<u32>,
    n_open_boundary_chains: usize,

    component_orientable: Vec<bool>,
    component_manifold: Vec<bool>,

    /// What the faces alone decide, worked out on the first [`Topology::summary`] or
    /// [`Topology::component_euler`].
    counts: Memo<Counts>,
}

/// The counts behind [`Topology::summary`] and [`Topology::component_euler`].
#[derive(Clone, Debug)]
struct Counts {
    /// The summary's figures, degenerate faces by area not counted.
    summary: TopologySummary,
    /// Per component: V − E + F.
    euler: Vec<i64>,
}

/// A value worked out once, on demand; not part of what makes two topologies equal.
#[derive(Clone, Debug)]
struct Memo<T>(std::sync::OnceLock<T>);

impl<T> Default for Memo<T> {
    fn default() -> Self {
        Memo(std::sync::OnceLock::new())
    }
}

impl<T> PartialEq for Memo<T> {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// What the adjacency pass keeps about one face around the current vertex.
#[derive(Clone, Copy)]
struct Slot {
    face: u32,
    /// Corner of the current vertex in the face.
    corner: u8,
    /// The next corner's vertex (the face has half-edge `v → next`).
    next: u32,
    /// The previous corner's vertex (the face has half-edge `prev → v`).
    prev: u32,
    /// The other slot sharing edge `(v, next)` when that edge has exactly two faces.
    link_next: u32,
    /// The other slot sharing edge `(v, prev)` when that edge has exactly two faces.
    link_prev: u32,
    /// Edge `(v, next)` when it is a boundary edge, else [`NONE`].
    edge_next: u32,
    /// Edge `(v, prev)` when it is a boundary edge, else [`NONE`].
    edge_prev: u32,
    /// Local number of the edge `(v, next)` among v's edges.
    group_next: u32,
    /// Local number of the edge `(v, prev)` among v's edges.
    group_prev: u32,
    visited: bool,
}

impl Slot {
    /// The face's corner other than `v` and `x` (one of `next`, `prev`).
    #[inline]
    fn other(&self, x: u32) -> u32 {
        if self.next == x { self.prev } else { self.next }
    }

    /// The slot linked through edge `(v, x)`.
    #[inline]
    fn link(&self, x: u32) -> u32 {
        if self.next == x {
            self.link_next
        } else {
            self.link_prev
        }
    }

    /// The local number of edge `(v, x)`.
    #[inline]
    fn group(&self, x: u32) -> u32 {
        if self.next == x {
            self.group_next
        } else {
            self.group_prev
        }
    }

    /// Edge `(v, x)` if it is a boundary edge, else [`NONE`].
    #[inline]
    fn edge(&self, x: u32) -> u32 {
        if self.next == x {
            self.edge_next
        } else {
            self.edge_prev
        }
    }

    /// Corner index of the half-edge this face has on edge `(v, x)`.
    #[inline]
    fn corner_of_edge(&self, x: u32) -> usize {
        if self.next == x {
            self.corner as usize
        } else {
            (self.corner as usize + 2) % 3
        }
    }
}
/// Vertex → incident corners of the faces with `valid[f]`, in ascending face order, by
/// counting sort in a few parallel pieces: the offsets (`nv + 1`) and the entries.
///
/// Each entry is `[face << 2 | corner, next, prev]`: the corner and its two neighbours
/// around the face (faces number below 2³⁰, see [`MAX_FACES`]), so that a pass over the
/// vertices reads its input in order instead of looking faces up all over memory. Every
/// index of a valid face must be below `nv`.
pub(crate) fn vertex_corners(
    faces: &[[Index; 3]],
    valid: &[bool],
    nv: usize,
) -> (Vec<u32>, Vec<[u32; 3]>) {
    // A counting sort in a few parallel pieces of faces, each with counts of its own:
    // piece k's corners of vertex v go after those of pieces before it, so each
    // vertex's corners come in face order, as one piece would put them.
    let pieces = if faces.len() >= BUCKET_PARALLEL_MIN {
        rayon::current_num_threads().clamp(1, BUCKET_PIECES)
    } else {
        1
    };
    let per = faces.len().div_ceil(pieces).max(1);
    let mut counts: Vec<Vec<u32>> = (0..pieces)
        .into_par_iter()
        .map(|k| {
            let mut c = vec![0u32; nv];
            let lo = (k * per).min(faces.len());
            let hi = ((k + 1) * per).min(faces.len());
            for (f, ok) in faces[lo..hi].iter().zip(&valid[lo..hi]) {
                if *ok {
                    for &v in f {
                        c[v as usize] += 1;
                    }
                }
            }
            c
        })
        .collect();
    // Offsets; each piece's counts become its first slot per vertex.
    let mut offsets = vec![0u32; nv + 1];
    let mut at = 0u32;
    for v in 0..nv {
        offsets[v] = at;
        for c in counts.iter_mut() {
            let n = c[v];
            c[v] = at;
            at += n;
        }
    }
    offsets[nv] = at;
    // Zeroed memory, taken over in place.
    let corners: Vec<[AtomicU32; 3]> = vec![[0u32; 3]; at as usize]
        .into_iter()
        .map(|c| c.map(AtomicU32::new))
        .collect();
    counts
        .into_par_iter()
        .enumerate()
        .for_each(|(k, mut cursor)| {
            let lo = (k * per).min(faces.len());
            let hi = ((k + 1) * per).min(faces.len());
            for (f, (face, ok)) in faces[lo..hi].iter().zip(&valid[lo..hi]).enumerate() {
                if *ok {
                    let f = (lo + f) as u32;
                    for c in 0..3 {
                        let slot = &mut cursor[face[c] as usize];
                        let dst = &corners[*slot as usize];
                        dst[0].store((f << 2) | c as u32, Ordering::Relaxed);
                        dst[1].store(face[(c + 1) % 3], Ordering::Relaxed);
                        dst[2].store(face[(c + 2) % 3], Ordering::Relaxed);
                        *slot += 1;
                    }
                }
            }
        });
    // In place again.
    let corners = corners
        .into_iter()
        .map(|c| c.map(AtomicU32::into_inner))
        .collect();
    (offsets, corners)
}

/// Root of `x` in a union-find forest, halving the path on the way.
#[inline]
pub(crate) fn find_root(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let up = parent[parent[x as usize] as usize];
        parent[x as usize] = up;
        x = up;
    }
    x
}

/// Records that boundary edges `a` and `b` follow each other at their shared vertex `v`.
fn link_boundary(link: &mut Vec<[u32; 2]>, edges: &[[u32; 2]], v: u32, a: u32, b: u32) {
    let needed = a.max(b) as usize + 1;
    if link.len() < needed {
        link.resize(edges.len().max(needed), [NONE; 2]);
    }
    link[a as usize][usize::from(edges[a as usize][1] == v)] = b;
    link[b as usize][usize::from(edges[b as usize][1] == v)] = a;
}

/// Vertices per range of the vertex pass; a mesh with more runs its ranges in parallel.
/// Fixed, and the ranges' tables are appended in order: the result is the same for any
/// thread count.
const CHUNK_VERTICES: usize = 1 << 15;
/// Meshes with fewer vertices run the vertex pass as one range on any thread count:
/// copying the ranges' tables together costs more than the second thread saves (two
/// threads against one: a 70K-face torus 4.2 against 3.7 ms, 140K faces 8.5 against
/// 7.7 ms, 280K faces 14.3 against 16.0 ms).
const ONE_RANGE_MAX_VERTICES: usize = 1 << 17;

/// Vertices with more faces than this always take the general path of the vertex pass
/// (the quick path compares every pair of faces, in fixed-size arrays).
const QUICK_MAX_FACES: usize = 16;

/// Meshes of at least this many faces bucket their corners by vertex in parallel pieces.
const BUCKET_PARALLEL_MIN: usize = 1 << 16;

/// At most this many pieces (each keeps a count per vertex).
const BUCKET_PIECES: usize = 4;

/// Elements per chunk of the summary's parallel counts.
const SUMMARY_CHUNK: usize = 1 << 15;

/// The summary counts per component in parallel up to this many components (each chunk
/// keeps a count per component).
const SUMMARY_PARALLEL_COMPONENTS: usize = 1 << 10;

/// Buffers reused from vertex to vertex by the vertex pass.
#[derive(Default)]
struct Scratch {
    slots: Vec<Slot>,
    pairs: Vec<u64>,
    listed: Vec<bool>,
    /// Boundary ends no fan pairs: `x << 32 | half-edge` of edge `(v, x)`.
    loose_in: Vec<u64>,
    loose_out: Vec<u64>,
}

/// "No slot" in [`Around`]'s links.
const NO_SLOT: u8 = u8::MAX;

/// The faces around one vertex for the quick path of the vertex pass, in fixed-size
/// arrays: slots in face order and their links.
struct Around {
    k: usize,
    face: [u32; QUICK_MAX_FACES],
    corner: [u8; QUICK_MAX_FACES],
    next: [u32; QUICK_MAX_FACES],
    prev: [u32; QUICK_MAX_FACES],
    /// The slot following each slot counter-clockwise (its `next` is this one's `prev`).
    succ: [u8; QUICK_MAX_FACES],
    /// The slot preceding each slot (its `prev` is this one's `next`).
    pred: [u8; QUICK_MAX_FACES],
}

/// Sorts a few keys in place (insertion sort: the fastest for a handful).
#[inline]
fn sort_small(keys: &mut [u64]) {
    for i in 1..keys.len() {
        let key = keys[i];
        let mut m = i;
        while m > 0 && keys[m - 1] > key {
            keys[m] = keys[m - 1];
            m -= 1;
        }
        keys[m] = key;
    }
}

impl Around {
    /// An empty scratch.
    fn new() -> Around {
        Around {
            k: 0,
            face: [0; QUICK_MAX_FACES],
            corner: [0; QUICK_MAX_FACES],
            next: [0; QUICK_MAX_FACES],
            prev: [0; QUICK_MAX_FACES],
            succ: [NO_SLOT; QUICK_MAX_FACES],
            pred: [NO_SLOT; QUICK_MAX_FACES],
        }
    }

    /// Loads and links the faces `ring` (entries `[face << 2 | corner, next, prev]`) when
    /// they meet like a consistently oriented manifold: no two share their `next` corner
    /// and no two share their `prev` corner, so every edge `(v, x)` has one face or two
    /// opposite ones. False when that fails or there are too many faces (the contents are
    /// then unusable).
    fn link(&mut self, ring: &[[u32; 3]]) -> bool {
        let k = ring.len();
        if k > QUICK_MAX_FACES {
            return false;
        }
        let a = self;
        a.k = k;
        for (j, &[packed, next, prev]) in ring.iter().enumerate() {
            a.face[j] = packed >> 2;
            a.corner[j] = (packed & 3) as u8;
            a.next[j] = next;
            a.prev[j] = prev;
            a.succ[j] = NO_SLOT;
            a.pred[j] = NO_SLOT;
        }
        for j in 0..k {
            let (nj, pj) = (a.next[j], a.prev[j]);
            for i in j + 1..k {
                let (ni, pi) = (a.next[i], a.prev[i]);
                if ni == nj || pi == pj {
                    return false;
                }
                if ni == pj {
                    a.succ[j] = i as u8;
                    a.pred[i] = j as u8;
                }
                if pi == nj {
                    a.succ[i] = j as u8;
                    a.pred[j] = i as u8;
                }
            }
        }
        true
    }
}

/// Plain-data figures of a mesh's topology, for reports and tests.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TopologySummary {
    /// Vertices referenced by at least one non-skipped face.
    pub n_vertices: usize,
    /// Vertices referenced by no non-skipped face.
    pub n_isolated_vertices: usize,
    /// All faces of the mesh, skipped ones included.
    pub n_faces: usize,
    /// Undirected edges.
    pub n_edges: usize,
    /// Edges with exactly one face.
    pub n_boundary_edges: usize,
    /// Boundary loops (closed cycles plus open chains, see [`Topology::boundary_loops`]).
    pub n_boundary_loops: usize,
    /// Boundary sequences that could not be closed (non-manifold boundaries only).
    pub n_open_boundary_chains: usize,
    /// Connected components of faces across edges.
    pub n_components: usize,
    /// Edges with three or more faces, or two faces using them in the same direction.
    pub n_non_manifold_edges: usize,
    /// The part of `n_non_manifold_edges` with exactly two faces in the same direction.
    pub n_flipped_edges: usize,
    /// Vertices whose faces form more than one fan.
    pub n_non_manifold_vertices: usize,
    /// Non-manifold vertices on no non-manifold edge (pure bow-ties).
    pub n_bowtie_vertices: usize,
    /// Faces with a repeated index, or of area below `1e-12 · (bbox diagonal)²`.
    pub n_degenerate_faces: usize,
    /// Faces with a repeated vertex index (skipped by the adjacency).
    pub n_repeated_index_faces: usize,
    /// Faces naming a vertex out of range (skipped by the adjacency).
    pub n_out_of_range_faces: usize,
    /// Every edge with exactly two faces is used once in each direction.
    pub consistently_oriented: bool,
    /// Every edge has one or two faces and every vertex's faces form one fan
    /// (orientation flips do not count here; see `consistently_oriented`).
    pub manifold: bool,
    /// Euler characteristic `V − E + F` over referenced vertices, edges and non-skipped faces.
    pub euler: i64,
    /// Genus of each component, `g = (2 − χ − b) / 2`; `None` for a component that is not
    /// a manifold or not orientable.
    pub genus: Vec<Option<i64>>,
    /// Sum of `genus`, when every component has one.
    pub genus_total: Option<i64>,
}

impl Topology {
    /// Builds the adjacency of `mesh`.
    ///
    /// Faces naming a vertex out of range or repeating an index are skipped and counted.
    ///
    /// # Panics
    /// Only when the mesh exceeds [`MAX_FACES`] faces or `u32` vertices; use
    /// [`Topology::try_build`] to get an error instead.
    pub fn build(mesh: &Mesh) -> Topology {
        match Self::try_build(mesh) {
            Ok(t) => t,
            Err(e) => panic!("{e}"),
        }
    }

    /// Builds the adjacency of `mesh`, or says why the mesh is too large for it.
    pub fn try_build(mesh: &Mesh) -> Result<Topology, TopologyError> {
        // One thread, or a mesh too small to gain from more: one range, whose tables need
        // no copying (the same tables).
        let one_range =
            rayon::current_num_threads() == 1 || mesh.positions.len() < ONE_RANGE_MAX_VERTICES;
        let chunk = if one_range {
            usize::MAX
        } else {
            CHUNK_VERTICES
        };
        Self::build_with(mesh, true, chunk)
    }

    /// [`Topology::try_build`], with the quick path of the vertex pass on or off and
    /// `chunk` vertices per range of the vertex pass (tests check that every choice gives
    /// the same tables).
    fn build_with(mesh: &Mesh, quick: bool, chunk: usize) -> Result<Topology, TopologyError> {
        let nv = mesh.positions.len();
        let nf = mesh.faces.len();
        if nf > MAX_FACES {
            return Err(TopologyError::TooManyFaces {
                n_faces: nf,
                max: MAX_FACES,
            });
        }
        if nv >= NONE as usize {
            return Err(TopologyError::TooManyVertices { n_vertices: nv });
        }
        let mut t = Topology {
            n_vertices: nv,
            ..Default::default()
        };
        let valid = t.classify_faces(&mesh.faces);
        let corners = t.bucket_vertex_faces(&mesh.faces, &valid);
        let boundary_link = t.link_edges_and_fans(corners, &mesh.faces, &valid, quick, chunk);
        t.trace_boundary_loops(&mesh.faces, &boundary_link);
        t.label_components(&mesh.faces, &valid);
        Ok(t)
    }

    /// Marks faces that take part in adjacency; counts the skipped ones.
    fn classify_faces(&mut self, faces: &[[Index; 3]]) -> Vec<bool> {
        let nv = self.n_vertices;
        let mut valid = vec![false; faces.len()];
        for (ok, &[a, b, c]) in valid.iter_mut().zip(faces) {
            if a as usize >= nv || b as usize >= nv || c as usize >= nv {
                self.n_out_of_range_faces += 1;
            } else if a == b || b == c || a == c {
                self.n_repeated_index_faces += 1;
            } else {
                *ok = true;
            }
        }
        valid
    }

    /// Vertex → incident corners (ascending face order), by counting sort (see
    /// [`vertex_corners`]); sizes `vertex_faces` to match.
    fn bucket_vertex_faces(&mut self, faces: &[[Index; 3]], valid: &[bool]) -> Vec<[u32; 3]> {
        let (offsets, corners) = vertex_corners(faces, valid, self.n_vertices);
        self.vertex_faces = vec![0u32; corners.len()];
        self.vertex_face_offsets = offsets;
        corners
    }

    /// The vertex pass: creates edges, fills `face_edges`, orders each vertex's faces into
    /// fans, lists one-rings, and links boundary edges at each vertex for loop tracing.
    ///
    /// The vertices are cut into ranges of `chunk` vertices (see [`VertexPass`]), run in
    /// parallel a wave at a time into reused buffers; each range's tables are appended in
    /// vertex order while the next wave runs, and the range-local edge ids in `face_edges`
    /// are shifted at the end, so the result is the same for any chunk size and thread
    /// count. `corners` is freed as soon as the ranges are done.
    fn link_edges_and_fans(
        &mut self,
        corners: Vec<[u32; 3]>,
        faces: &[[Index; 3]],
        valid: &[bool],
        quick: bool,
        chunk: usize,
    ) -> Vec<[u32; 2]> {
        let nv = self.n_vertices;
        let chunk = chunk.max(1);
        let n_chunks = nv.div_ceil(chunk);
        let offsets = std::mem::take(&mut self.vertex_face_offsets);
        let mut vertex_faces = vec![0u32; corners.len()];
        let mut vertex_flags = vec![0u8; nv];
        // Zeroed memory, taken over in place (skipped faces get `NONE` at the end).
        let local_face_edges: Vec<[AtomicU32; 3]> = vec![[0u32; 3]; faces.len()]
            .into_iter()
            .map(|fe| fe.map(AtomicU32::new))
            .collect();
        // Each range owns the slices of `vertex_faces` and `vertex_flags` of its vertices.
        let mut passes = Vec::with_capacity(n_chunks);
        let mut rest_faces = vertex_faces.as_mut_slice();
        for (k, flags) in vertex_flags.chunks_mut(chunk).enumerate() {
            let v0 = k * chunk;
            let (lo, hi) = (offsets[v0] as usize, offsets[v0 + flags.len()] as usize);
            let (mine, rest) = std::mem::take(&mut rest_faces).split_at_mut(hi - lo);
            rest_faces = rest;
            passes.push(VertexPass {
                out: ChunkOut::default(),
                faces: mine,
                face_base: lo,
                flags,
                v0: v0 as u32,
                face_edges: &local_face_edges,
            });
        }
        let mut tables = Tables::with_capacity(if n_chunks > 1 { nv } else { 0 }, corners.len());
        let run = |pass: &mut VertexPass<'_>, out: &mut ChunkOut| {
            std::mem::swap(&mut pass.out, out);
            pass.run(&corners, &offsets, quick);
            std::mem::swap(&mut pass.out, out);
        };
        if let [pass] = passes.as_mut_slice() {
            // One range: its tables are the result, moved rather than copied.
            let mut out = ChunkOut::default();
            run(pass, &mut out);
            tables = Tables::from_single(out);
        } else {
            // Double buffering: one wave's buffers are appended while the next wave fills
            // the other set.
            let wave = 2 * rayon::current_num_threads().max(1);
            let mut filled: Vec<ChunkOut> = (0..wave).map(|_| ChunkOut::default()).collect();
            let mut fresh: Vec<ChunkOut> = (0..wave).map(|_| ChunkOut::default()).collect();
            let mut n_filled = 0;
            for w in passes.chunks_mut(wave) {
                let (done, todo) = (&filled[..n_filled], &mut fresh[..w.len()]);
                rayon::join(
                    || done.iter().for_each(|out| tables.append(out)),
                    || {
                        w.par_iter_mut()
                            .zip(todo.par_iter_mut())
                            .for_each(|(pass, out)| run(pass, out))
                    },
                );
                std::mem::swap(&mut filled, &mut fresh);
                n_filled = w.len();
            }
            filled[..n_filled].iter().for_each(|out| tables.append(out));
        }
        drop(passes);
        drop(corners);
        self.vertex_face_offsets = offsets;
        self.vertex_faces = vertex_faces;
        self.vertex_flags = vertex_flags;
        let Tables {
            edge_bases, links, ..
        } = tables.finish(self);

        let skipped = self.n_out_of_range_faces + self.n_repeated_index_faces > 0;
        let ranges = (n_chunks, chunk);
        self.face_edges = globalize(local_face_edges, faces, valid, ranges, &edge_bases, skipped);
        self.boundary_links(&links)
    }

    /// The boundary links of the edges (see `link_boundary`), from the pairs of half-edges
    /// the ranges found at each vertex, in vertex order, now that every edge has its id.
    fn boundary_links(&self, links: &[[u32; 3]]) -> Vec<[u32; 2]> {
        let mut boundary_link = Vec::new();
        if !links.is_empty() {
            boundary_link = vec![[NONE; 2]; self.edges.len()];
            let edge_of = |h: u32| {
                self.face_edges
                    .get((h >> 2) as usize)
                    .and_then(|e| e.get((h & 3) as usize))
                    .copied()
                    .unwrap_or(NONE)
            };
            for &[v, a, b] in links {
                let (a, b) = (edge_of(a), edge_of(b));
                // Both are edges of v by construction; the test only guards the invariant.
                if a != NONE && b != NONE {
                    link_boundary(&mut boundary_link, &self.edges, v, a, b);
                }
            }
        }
        boundary_link
    }
}

/// The faces' edges with global ids: the range-local ids of `local` shifted by their
/// range's first edge (`edge_bases`; the range of an edge is its smaller endpoint's, of
/// `chunk` vertices each, `n_chunks` of them), `NONE` for the faces not `valid` (some are
/// not when `skipped`). The same layout: collected in place.
fn globalize(
    mut local: Vec<[AtomicU32; 3]>,
    faces: &[[Index; 3]],
    valid: &[bool],
    (n_chunks, chunk): (usize, usize),
    edge_bases: &[u32],
    skipped: bool,
) -> Vec<[u32; 3]> {
    let shift = |(fe, (face, &ok)): (&mut [AtomicU32; 3], (&[Index; 3], &bool))| {
        for (c, e) in fe.iter_mut().enumerate() {
            let e = e.get_mut();
            *e = if ok {
                let owner = face[c].min(face[(c + 1) % 3]) as usize / chunk;
                e.wrapping_add(edge_bases.get(owner).copied().unwrap_or(0))
            } else {
                NONE
            };
        }
    };
    if n_chunks > 1 {
        local
            .par_iter_mut()
            .zip(faces.par_iter().zip(valid))
            .for_each(shift);
    } else if skipped {
        for (fe, &ok) in local.iter_mut().zip(valid) {
            if !ok {
                *fe = [NONE; 3].map(AtomicU32::new);
            }
        }
    }
    local
        .into_iter()
        .map(|fe| fe.map(AtomicU32::into_inner))
        .collect()
}

/// The tables of the vertex pass being assembled from its ranges, in vertex order.
struct Tables {
    edges: Vec<[u32; 2]>,
    edge_flags: Vec<u8>,
    edge_face_offsets: Vec<u32>,
    edge_faces: Vec<u32>,
    vertex_edge_offsets: Vec<u32>,
    vertex_neighbor_offsets: Vec<u32>,
    vertex_neighbors: Vec<u32>,
    vertex_fan_offsets: Vec<u32>,
    fan_offsets: Vec<u32>,
    /// The id of each range's first edge.
    edge_bases: Vec<u32>,
    /// Every range's [`ChunkOut::links`].
    links: Vec<[u32; 3]>,
}

/// `local` with `by` added to every entry.
fn shifted(local: &[u32], by: u32) -> impl Iterator<Item = u32> + '_ {
    local.iter().map(move |&s| s + by)
}

impl Tables {
    /// Empty tables with room for a mesh of `nv` vertices and `n_corners` corners.
    fn with_capacity(nv: usize, n_corners: usize) -> Tables {
        let n_corners = if nv == 0 { 0 } else { n_corners };
        // Euler: E ≈ F · 3/2 for closed meshes, plus half the boundary edges (up to 3F
        // for soups), and a boundary vertex has one neighbour more than faces. Room for
        // boundary edges up to an eighth of the corners: a table that outgrows its room is
        // copied whole (the bunny subdivided three times has 1,784 and overflowed the
        // room of a closed mesh); room never used is never touched.
        let open = n_corners / 16 + 1024;
        let mut t = Tables {
            edges: Vec::with_capacity(n_corners / 2 + open),
            edge_flags: Vec::with_capacity(n_corners / 2 + open),
            edge_face_offsets: Vec::with_capacity(n_corners / 2 + open + 1),
            edge_faces: Vec::with_capacity(n_corners),
            vertex_edge_offsets: Vec::with_capacity(nv + 1),
            vertex_neighbor_offsets: Vec::with_capacity(nv + 1),
            vertex_neighbors: Vec::with_capacity(n_corners + open),
            vertex_fan_offsets: Vec::with_capacity(nv + 1),
            fan_offsets: Vec::with_capacity(nv + 1),
            edge_bases: Vec::new(),
            links: Vec::new(),
        };
        t.edge_face_offsets.push(0);
        t.vertex_neighbor_offsets.push(0);
        t
    }

    /// The tables of a single range over every vertex.
    fn from_single(c: ChunkOut) -> Tables {
        Tables {
            edges: c.edges,
            edge_flags: c.edge_flags,
            edge_face_offsets: c.edge_face_offsets,
            edge_faces: c.edge_faces,
            vertex_edge_offsets: c.vertex_edge_starts,
            vertex_neighbor_offsets: c.vertex_neighbor_offsets,
            vertex_neighbors: c.vertex_neighbors,
            vertex_fan_offsets: c.vertex_fan_starts,
            fan_offsets: c.fan_offsets,
            edge_bases: vec![0],
            links: c.links,
        }
    }

    /// Appends the next range's tables, shifting its local offsets.
    fn append(&mut self, c: &ChunkOut) {
        let (e0, f0) = (self.edges.len() as u32, self.edge_faces.len() as u32);
        let (n0, fan0) = (
            self.vertex_neighbors.len() as u32,
            self.fan_offsets.len() as u32,
        );
        self.edge_bases.push(e0);
        self.vertex_edge_offsets
            .extend(shifted(&c.vertex_edge_starts, e0));
        self.vertex_fan_offsets
            .extend(shifted(&c.vertex_fan_starts, fan0));
        self.vertex_neighbor_offsets
            .extend(shifted(&c.vertex_neighbor_offsets[1..], n0));
        self.edge_face_offsets
            .extend(shifted(&c.edge_face_offsets[1..], f0));
        self.edges.extend_from_slice(&c.edges);
        self.edge_flags.extend_from_slice(&c.edge_flags);
        self.edge_faces.extend_from_slice(&c.edge_faces);
        self.vertex_neighbors.extend_from_slice(&c.vertex_neighbors);
        self.fan_offsets.extend_from_slice(&c.fan_offsets);
        self.links.extend_from_slice(&c.links);
    }

    /// Closes the per-vertex offset tables and moves the tables into `t`; returns what
    /// is left (edge bases and links).
    fn finish(mut self, t: &mut Topology) -> Tables {
        self.vertex_edge_offsets.push(self.edges.len() as u32);
        self.vertex_fan_offsets.push(self.fan_offsets.len() as u32);
        self.fan_offsets.push(t.vertex_faces.len() as u32);
        use std::mem::take;
        t.edges = take(&mut self.edges);
        t.edge_flags = take(&mut self.edge_flags);
        t.edge_face_offsets = take(&mut self.edge_face_offsets);
        t.edge_faces = take(&mut self.edge_faces);
        t.vertex_edge_offsets = take(&mut self.vertex_edge_offsets);
        t.vertex_neighbor_offsets = take(&mut self.vertex_neighbor_offsets);
        t.vertex_neighbors = take(&mut self.vertex_neighbors);
        t.vertex_fan_offsets = take(&mut self.vertex_fan_offsets);
        t.fan_offsets = take(&mut self.fan_offsets);
        self
    }
}

/// What the vertex pass produces for one range of vertices, with offsets local to it.
#[derive(Default)]
struct ChunkOut {
    /// Edges created by the range's vertices (their smaller endpoint), sorted.
    edges: Vec<[u32; 2]>,
    edge_flags: Vec<u8>,
    /// Edge `i`'s faces are `edge_faces[edge_face_offsets[i]..edge_face_offsets[i + 1]]`.
    edge_face_offsets: Vec<u32>,
    edge_faces: Vec<u32>,
    /// Per vertex: its first edge in `edges`.
    vertex_edge_starts: Vec<u32>,
    /// Per vertex: its first fan in `fan_offsets`.
    vertex_fan_starts: Vec<u32>,
    /// Vertex `v0 + i`'s one-ring is `vertex_neighbors[vertex_neighbor_offsets[i]..[i + 1]]`.
    vertex_neighbor_offsets: Vec<u32>,
    vertex_neighbors: Vec<u32>,
    /// The start of each fan in the whole `vertex_faces` table.
    fan_offsets: Vec<u32>,
    /// `[v, a, b]`: boundary edges `a` and `b`, named by their half-edges
    /// (`face << 2 | corner`), follow each other at vertex `v`.
    links: Vec<[u32; 3]>,
}

impl ChunkOut {
    /// Empties every table, keeping the memory.
    fn clear(&mut self) {
        self.edges.clear();
        self.edge_flags.clear();
        self.edge_face_offsets.clear();
        self.edge_face_offsets.push(0);
        self.edge_faces.clear();
        self.vertex_edge_starts.clear();
        self.vertex_fan_starts.clear();
        self.vertex_neighbor_offsets.clear();
        self.vertex_neighbor_offsets.push(0);
        self.vertex_neighbors.clear();
        self.fan_offsets.clear();
        self.links.clear();
    }
}

/// The vertex pass over one range of vertices: what it produces and the parts of the
/// per-vertex tables it owns.
///
/// A range needs nothing from the others: edges are created by their smaller endpoint
/// (no id is needed while the pass runs), and a boundary edge is named by the half-edge
/// its one face has on it, resolved to its id once all ranges are appended.
struct VertexPass<'a> {
    out: ChunkOut,
    /// `vertex_faces` of the range's vertices: entry `i` is `vertex_faces[face_base + i]`.
    faces: &'a mut [u32],
    face_base: usize,
    /// `vertex_flags` of the range: entry `i` is vertex `v0 + i`'s.
    flags: &'a mut [u8],
    v0: u32,
    /// `face_edges` of every face, flat (`3 · face + corner`): the range writes the
    /// range-local ids of the edges it creates.
    face_edges: &'a [[AtomicU32; 3]],
}

/// The half-edge starting at corner `c` of face `f`, as [`ChunkOut::links`] names it.
#[inline]
fn half_edge(f: u32, c: usize) -> u32 {
    (f << 2) | c as u32
}

impl VertexPass<'_> {
    /// Runs the pass over the range's vertices, given the vertex → corners table.
    ///
    /// Everything it needs about a vertex's surroundings is gathered into small local
    /// buffers first. Vertices of low valence whose faces meet like a manifold,
    /// consistently oriented surface take a quick path ([`Self::regular_vertex`]); all
    /// others, and every vertex when `quick` is off, the general one
    /// ([`Self::general_vertex`]); both give identical tables.
    fn run(&mut self, corners: &[[u32; 3]], offsets: &[u32], quick: bool) {
        let nv = self.flags.len();
        let (lo, hi) = (
            offsets[self.v0 as usize] as usize,
            offsets[self.v0 as usize + nv] as usize,
        );
        self.out.clear();
        let o = &mut self.out;
        o.edges.reserve((hi - lo) / 2 + 16);
        o.edge_flags.reserve((hi - lo) / 2 + 16);
        o.edge_face_offsets.reserve((hi - lo) / 2 + 17);
        o.edge_faces.reserve(hi - lo + 16);
        o.vertex_edge_starts.reserve(nv);
        o.vertex_fan_starts.reserve(nv);
        o.vertex_neighbor_offsets.reserve(nv + 1);
        o.vertex_neighbors.reserve(hi - lo + 16);
        o.fan_offsets.reserve(nv + 1);
        let mut sc = Scratch::default();
        let mut around = Around::new();
        for i in 0..nv {
            let v = self.v0 + i as u32;
            let vi = v as usize;
            self.out
                .vertex_edge_starts
                .push(self.out.edges.len() as u32);
            self.out
                .vertex_fan_starts
                .push(self.out.fan_offsets.len() as u32);
            let start = offsets[vi] as usize;
            let end = offsets[vi + 1] as usize;
            if start == end {
                self.flags[i] |= V_ISOLATED;
            } else {
                let ring = &corners[start..end];
                let n_fans = match quick && around.link(ring) {
                    true => self.regular_vertex(v, start, &around),
                    false => {
                        sc.slots.clear();
                        sc.slots
                            .extend(ring.iter().map(|&[packed, next, prev]| Slot {
                                face: packed >> 2,
                                corner: (packed & 3) as u8,
                                next,
                                prev,
                                link_next: NONE,
                                link_prev: NONE,
                                edge_next: NONE,
                                edge_prev: NONE,
                                group_next: 0,
                                group_prev: 0,
                                visited: false,
                            }));
                        self.general_vertex(v, start, &mut sc)
                    }
                };
                if n_fans > 1 {
                    self.flags[i] |= V_NON_MANIFOLD;
                }
            }
            self.out
                .vertex_neighbor_offsets
                .push(self.out.vertex_neighbors.len() as u32);
        }
    }

    /// Appends edge `[v, x]` with its faces (ascending), given as `(face, corner of the
    /// face's half-edge on it)`, writing its range-local id into their `face_edges`.
    #[inline]
    fn push_edge(
        &mut self,
        v: u32,
        x: u32,
        flags: u8,
        on_edge: impl IntoIterator<Item = (u32, usize)>,
    ) {
        let o = &mut self.out;
        let e = o.edges.len() as u32;
        for (f, c) in on_edge {
            o.edge_faces.push(f);
            // Each entry has one writer: the range of the edge's smaller endpoint.
            if let Some(slot) = self.face_edges.get(f as usize).and_then(|fe| fe.get(c)) {
                slot.store(e, Ordering::Relaxed);
            }
        }
        o.edges.push([v, x]);
        o.edge_flags.push(flags);
        o.edge_face_offsets.push(o.edge_faces.len() as u32);
    }

    /// Writes face `f` at position `out` of the whole `vertex_faces` table.
    #[inline]
    fn put_face(&mut self, out: usize, f: u32) {
        self.faces[out - self.face_base] = f;
    }

    /// Sets flag bits of vertex `v` of the range.
    #[inline]
    fn flag(&mut self, v: u32, bits: u8) {
        self.flags[(v - self.v0) as usize] |= bits;
    }

    /// The quick path, for a vertex whose faces [`Around::link`] could link: every edge
    /// `(v, x)` has one face or two opposite ones. Returns the number of fans.
    fn regular_vertex(&mut self, v: u32, start: usize, a: &Around) -> usize {
        let k = a.k;
        // Boundary half-edge of each slot's `next` side (no pred) and `prev` side (no succ).
        let mut b_next = [NONE; QUICK_MAX_FACES];
        let mut b_prev = [NONE; QUICK_MAX_FACES];
        // Edges created here, by the smaller endpoint, in order of the other one: key
        // `x << 8 | slot << 1 | side`, side 0 for edge (v, next), 1 for boundary (v, prev).
        let mut keys = [0u64; 2 * QUICK_MAX_FACES];
        let mut n_keys = 0;
        for j in 0..k {
            let (f, c) = (a.face[j], a.corner[j] as usize);
            if a.next[j] > v {
                keys[n_keys] = (u64::from(a.next[j]) << 8) | (j as u64) << 1;
                n_keys += 1;
            }
            if a.pred[j] == NO_SLOT {
                b_next[j] = half_edge(f, c);
            }
            if a.succ[j] == NO_SLOT {
                if a.prev[j] > v {
                    keys[n_keys] = (u64::from(a.prev[j]) << 8) | (j as u64) << 1 | 1;
                    n_keys += 1;
                }
                b_prev[j] = half_edge(f, (c + 2) % 3);
            }
        }
        let keys = &mut keys[..n_keys];
        sort_small(keys);
        for &key in keys.iter() {
            let (x, j) = ((key >> 8) as u32, ((key & 0xff) >> 1) as usize);
            let (f, c) = (a.face[j], a.corner[j] as usize);
            if key & 1 == 1 {
                self.push_edge(v, x, E_BOUNDARY, [(f, (c + 2) % 3)]);
            } else if a.pred[j] == NO_SLOT {
                self.push_edge(v, x, E_BOUNDARY, [(f, c)]);
            } else {
                // Slots are in face order: the lower slot has the lower face.
                let i = a.pred[j] as usize;
                let other = (a.face[i], (a.corner[i] as usize + 2) % 3);
                let on_edge = if i < j {
                    [other, (f, c)]
                } else {
                    [(f, c), other]
                };
                self.push_edge(v, x, 0, on_edge);
            }
        }

        // Fans: open ones from the face whose `next` edge is on the boundary, following
        // `succ` (counter-clockwise), in slot order; then closed ones from their lowest slot.
        let mut out = start;
        let mut n_fans = 0;
        let mut visited = 0u32;
        for j0 in (0..k).filter(|&j| a.pred[j] == NO_SLOT) {
            n_fans += 1;
            self.out.fan_offsets.push(out as u32);
            self.out.vertex_neighbors.push(a.next[j0]);
            let mut j = j0;
            loop {
                visited |= 1 << j;
                self.put_face(out, a.face[j]);
                out += 1;
                self.out.vertex_neighbors.push(a.prev[j]);
                match a.succ[j] {
                    NO_SLOT => break,
                    s => j = s as usize,
                }
            }
            self.flag(v, V_BOUNDARY);
            self.out.links.push([v, b_next[j0], b_prev[j]]);
        }
        let all = (1u32 << k) - 1;
        while visited != all {
            let j0 = (!visited & all).trailing_zeros() as usize;
            n_fans += 1;
            self.out.fan_offsets.push(out as u32);
            self.out.vertex_neighbors.push(a.next[j0]);
            let mut j = j0;
            loop {
                visited |= 1 << j;
                self.put_face(out, a.face[j]);
                out += 1;
                let s = a.succ[j] as usize;
                // `succ` is a permutation of the slots left at this point; the second
                // test only guards against a broken invariant.
                if s == j0 || s >= k {
                    break;
                }
                self.out.vertex_neighbors.push(a.prev[j]);
                j = s;
            }
        }
        n_fans
    }

    /// The general path: groups the faces of each edge `(v, x)` by sorting, links faces
    /// through edges of exactly two faces (flipped or not), walks the fans and pairs the
    /// boundary edges at their ends. Returns the number of fans.
    fn general_vertex(&mut self, v: u32, start: usize, sc: &mut Scratch) -> usize {
        let n_groups = self.group_edges(v, sc);
        let n_fans = self.walk_fans(v, start, n_groups, sc);
        self.pair_loose_ends(v, sc);
        n_fans
    }

    /// Groups the slots of `v` by the edge `(v, x)` each side lies on (sorting), records
    /// each edge whose other end is larger, and links the faces of every edge of exactly
    /// two faces. Returns the number of groups (edges at `v`).
    fn group_edges(&mut self, v: u32, sc: &mut Scratch) -> u32 {
        let slots = &mut sc.slots;
        let pairs = &mut sc.pairs;
        pairs.clear();
        for (j, s) in slots.iter_mut().enumerate() {
            // An attempt at the quick path may have linked some faces already.
            (s.link_next, s.link_prev) = (NONE, NONE);
            pairs.push(((s.next as u64) << 32) | j as u64);
            pairs.push(((s.prev as u64) << 32) | j as u64);
        }
        pairs.sort_unstable();

        // Each run of equal `x` is the set of faces on edge (v, x): group `n_groups`.
        let mut n_groups = 0u32;
        let mut i = 0;
        while i < pairs.len() {
            let x = (pairs[i] >> 32) as u32;
            let mut k = i + 1;
            while k < pairs.len() && (pairs[k] >> 32) as u32 == x {
                k += 1;
            }
            let run = &pairs[i..k];
            let slot_of = |p: u64| (p & 0xffff_ffff) as usize;
            if x > v {
                let flags = match run.len() {
                    1 => E_BOUNDARY,
                    2 => {
                        let (s0, s1) = (&slots[slot_of(run[0])], &slots[slot_of(run[1])]);
                        if (s0.next == x) == (s1.next == x) {
                            E_FLIPPED
                        } else {
                            0
                        }
                    }
                    _ => E_MULTI,
                };
                let on_edge = run.iter().map(|&p| {
                    let s = &slots[slot_of(p)];
                    (s.face, s.corner_of_edge(x))
                });
                self.push_edge(v, x, flags, on_edge);
            }
            // Boundary edges are named by their one half-edge (ids are not known yet).
            let mut e = NONE;
            if run.len() == 1 {
                let s = &slots[slot_of(run[0])];
                e = half_edge(s.face, s.corner_of_edge(x));
                self.flag(v, V_BOUNDARY);
            }
            for &p in run {
                let s = &mut slots[slot_of(p)];
                if s.next == x {
                    s.edge_next = e;
                    s.group_next = n_groups;
                } else {
                    s.edge_prev = e;
                    s.group_prev = n_groups;
                }
            }
            if run.len() == 2 {
                let (j0, j1) = (slot_of(run[0]), slot_of(run[1]));
                for (a, b) in [(j0, j1), (j1, j0)] {
                    let s = &mut slots[a];
                    if s.next == x {
                        s.link_next = b as u32;
                    } else {
                        s.link_prev = b as u32;
                    }
                }
            }
            n_groups += 1;
            i = k;
        }

        n_groups
    }

    /// Walks the fans of `v` from the linked slots, laying their faces out from `start`
    /// and its neighbours once each, and links the boundary edges at the two open ends of
    /// each chain (those no fan pairs are kept in `sc.loose_in` and `sc.loose_out`).
    /// Returns the number of fans.
    fn walk_fans(&mut self, v: u32, start: usize, n_groups: u32, sc: &mut Scratch) -> usize {
        let slots = &mut sc.slots;
        // Walk the fans: open chains starting where the `next` side is open (so the
        // walk runs counter-clockwise), then open chains starting where the `prev`
        // side is open (only reachable through orientation flips), then closed fans.
        let listed = &mut sc.listed;
        listed.clear();
        listed.resize(n_groups as usize, false);
        let mut out = start;
        let mut n_fans = 0;
        sc.loose_in.clear();
        sc.loose_out.clear();
        for pass in 0..3 {
            for j0 in 0..slots.len() {
                let s0 = &slots[j0];
                if s0.visited {
                    continue;
                }
                let entry0 = match pass {
                    0 if s0.link_next == NONE => s0.next,
                    1 if s0.link_prev == NONE => s0.prev,
                    2 => s0.next,
                    _ => continue,
                };
                n_fans += 1;
                self.out.fan_offsets.push(out as u32);
                let g = s0.group(entry0) as usize;
                if !listed[g] {
                    listed[g] = true;
                    self.out.vertex_neighbors.push(entry0);
                }
                let (mut j, mut entry) = (j0, entry0);
                let (last, exit, closed) = loop {
                    let s = &mut slots[j];
                    s.visited = true;
                    let face = s.face;
                    let exit = s.other(entry);
                    let g = s.group(exit) as usize;
                    let nj = s.link(exit);
                    self.put_face(out, face);
                    out += 1;
                    if !listed[g] {
                        listed[g] = true;
                        self.out.vertex_neighbors.push(exit);
                    }
                    if nj == NONE {
                        break (j, exit, false);
                    }
                    if slots[nj as usize].visited {
                        break (j, exit, true);
                    }
                    j = nj as usize;
                    entry = exit;
                };
                if closed {
                    continue;
                }
                // Boundary edges at the two open ends of the chain are consecutive
                // along the boundary through v, whatever their directions. Each is kept
                // with its other endpoint, the order of the edge ids around v.
                let mut fan_ends = [(NONE, NONE, false); 2];
                for (end, (js, x)) in fan_ends.iter_mut().zip([(j0, entry0), (last, exit)]) {
                    let e = slots[js].edge(x);
                    if e != NONE {
                        // The face has half-edge `v → x` when x is its next corner.
                        *end = (x, e, slots[js].next == x);
                    }
                }
                match fan_ends {
                    [(_, NONE, _), (_, NONE, _)] => {}
                    [(x, e, leaves), (_, NONE, _)] | [(_, NONE, _), (x, e, leaves)] => {
                        let key = (u64::from(x) << 32) | u64::from(e);
                        if leaves {
                            sc.loose_out.push(key);
                        } else {
                            sc.loose_in.push(key);
                        }
                    }
                    [(_, a, _), (_, b, _)] => self.out.links.push([v, a, b]),
                }
            }
        }
        n_fans
    }

    /// Pairs the boundary ends at `v` that no fan paired.
    fn pair_loose_ends(&mut self, v: u32, sc: &mut Scratch) {
        // Boundary ends that no fan pairs (chains ending at an edge of three or more
        // faces): entering edges paired with leaving ones in edge order (the order of
        // their other endpoints), then any rest among themselves, so every boundary edge
        // meets at most one other at v.
        let (loose_in, loose_out) = (&mut sc.loose_in, &mut sc.loose_out);
        loose_in.sort_unstable();
        loose_out.sort_unstable();
        let paired = loose_in.len().min(loose_out.len());
        let half = |key: u64| (key & 0xffff_ffff) as u32;
        for (&a, &b) in loose_in.iter().zip(loose_out.iter()) {
            self.out.links.push([v, half(a), half(b)]);
        }
        let rest = if loose_in.len() > paired {
            &loose_in[paired..]
        } else {
            &loose_out[paired..]
        };
        for pair in rest.chunks_exact(2) {
            self.out.links.push([v, half(pair[0]), half(pair[1])]);
        }
    }
}

impl Topology {
    /// The tail and head of boundary edge `e` as its one face orients it.
    fn boundary_half_edge(&self, faces: &[[Index; 3]], e: u32) -> (u32, u32) {
        let f = self.edge_faces[self.edge_face_offsets[e as usize] as usize] as usize;
        let c = self.face_edges[f].iter().position(|&x| x == e).unwrap_or(0);
        (faces[f][c], faces[f][(c + 1) % 3])
    }

    /// Walks the boundary edges along their links: first the open chains (from an edge
    /// with an unlinked end), then the closed cycles, each from the tail of its lowest edge.
    fn trace_boundary_loops(&mut self, faces: &[[Index; 3]], link: &[[u32; 2]]) {
        self.loop_offsets.push(0);
        if link.is_empty() && !self.edge_flags.iter().any(|f| f & E_BOUNDARY != 0) {
            return; // closed: nothing to trace
        }
        let ne = self.edges.len();
        let mut visited = vec![false; ne];
        for pass in 0..2 {
            for e0 in 0..ne {
                if self.edge_flags[e0] & E_BOUNDARY == 0 || visited[e0] {
                    continue;
                }
                let (tail, head) = self.boundary_half_edge(faces, e0 as u32);
                let side = |e: usize, v: u32| usize::from(self.edges[e][1] == v);
                let link_at = |e: usize, v: u32| link.get(e).map_or(NONE, |l| l[side(e, v)]);
                let start = if pass == 1 || link_at(e0, tail) == NONE {
                    tail
                } else if link_at(e0, head) == NONE {
                    head
                } else {
                    continue;
                };
                let (mut e, mut at) = (e0, start);
                self.loop_vertices.push(start);
                loop {
                    visited[e] = true;
                    let [a, b] = self.edges[e];
                    let far = if a == at { b } else { a };
                    let next = link_at(e, far);
                    if next == NONE {
                        self.loop_vertices.push(far);
                        self.n_open_boundary_chains += 1;
                        break;
                    }
                    if visited[next as usize] {
                        break;
                    }
                    self.loop_vertices.push(far);
                    (e, at) = (next as usize, far);
                }
                self.loop_offsets.push(self.loop_vertices.len() as u32);
                // The first edge for now; turned into its component by `label_components`.
                self.loop_component.push(e0 as u32);
            }
        }
    }

    /// Marks the components where no choice of face orientations makes every edge of
    /// two faces used once in each direction (a search over flip bits per face).
    fn find_non_orientable(&self, valid: &[bool], comp: &[u32], orientable: &mut [bool]) {
        const UNSET: u8 = 2;
        let nf = valid.len();
        let mut flip = vec![UNSET; nf];
        let mut stack: Vec<u32> = Vec::new();
        for f0 in 0..nf {
            if !valid[f0] || flip[f0] != UNSET {
                continue;
            }
            flip[f0] = 0;
            stack.push(f0 as u32);
            while let Some(f) = stack.pop() {
                for e in self.face_edges[f as usize] {
                    let ef = self.edge_faces(e);
                    if ef.len() != 2 {
                        continue;
                    }
                    let g = if ef[0] == f { ef[1] } else { ef[0] } as usize;
                    let flipped = self.edge_flags[e as usize] & E_FLIPPED != 0;
                    let want = flip[f as usize] ^ u8::from(flipped);
                    if flip[g] == UNSET {
                        flip[g] = want;
                        stack.push(g as u32);
                    } else if flip[g] != want {
                        orientable[comp[f as usize] as usize] = false;
                    }
                }
            }
        }
    }

    /// Components across edges, their orientability and manifoldness.
    fn label_components(&mut self, faces: &[[Index; 3]], valid: &[bool]) {
        let nf = faces.len();
        // Union-find over faces, edge by edge; a root is always the lowest face of its set,
        // so numbering roots in face order numbers components by their lowest face.
        let mut parent: Vec<u32> = (0..nf as u32).collect();
        for e in 0..self.edges.len() {
            let ef = &self.edge_faces
                [self.edge_face_offsets[e] as usize..self.edge_face_offsets[e + 1] as usize];
            let mut a = find_root(&mut parent, ef[0]);
            for &g in &ef[1..] {
                let b = find_root(&mut parent, g);
                if a < b {
                    parent[b as usize] = a;
                } else if b < a {
                    parent[a as usize] = b;
                    a = b;
                }
            }
        }
        // Every parent is at most its child, so one forward pass points each face at its
        // root, and a second turns roots into component numbers, in place.
        for f in 0..nf {
            parent[f] = parent[parent[f] as usize];
        }
        let mut n = 0u32;
        for f in 0..nf {
            let r = parent[f] as usize;
            parent[f] = if !valid[f] {
                NONE
            } else if r == f {
                n += 1;
                n - 1
            } else {
                parent[r]
            };
        }
        let comp = parent;
        let nc = n as usize;

        // Orientability: propagate a flip bit across edges of exactly two faces; a
        // contradiction means no choice of face orientations is consistent. Without any
        // flipped edge, "no face flipped" is a consistent choice: nothing to search.
        let mut orientable = vec![true; nc];
        if self.edge_flags.iter().any(|f| f & E_FLIPPED != 0) {
            self.find_non_orientable(valid, &comp, &mut orientable);
        }

        // A component is a manifold unless it holds an edge of three or more faces or a
        // vertex with two fans inside it (fans in different components do not count).
        let mut manifold = vec![true; nc];
        for e in 0..self.edges.len() {
            if self.edge_flags[e] & E_MULTI != 0 {
                let f = self.edge_faces[self.edge_face_offsets[e] as usize];
                manifold[comp[f as usize] as usize] = false;
            }
        }
        let mut fan_comps: Vec<u32> = Vec::new();
        for v in 0..self.n_vertices {
            if self.vertex_flags[v] & V_NON_MANIFOLD == 0 {
                continue;
            }
            fan_comps.clear();
            fan_comps.extend(self.vertex_fans(v as u32).map(|fan| comp[fan[0] as usize]));
            fan_comps.sort_unstable();
            for w in fan_comps.windows(2) {
                if w[0] == w[1] {
                    manifold[w[0] as usize] = false;
                }
            }
        }
        for c in &mut self.loop_component {
            let f = self.edge_faces[self.edge_face_offsets[*c as usize] as usize];
            *c = comp[f as usize];
        }
        self.face_component = comp;
        self.component_orientable = orientable;
        self.component_manifold = manifold;
    }

    /// Number of vertices of the mesh (isolated ones included).
    pub fn n_vertices(&self) -> usize {
        self.n_vertices
    }

    /// Number of faces of the mesh (skipped ones included).
    pub fn n_faces(&self) -> usize {
        self.face_edges.len()
    }

    /// Number of undirected edges.
    pub fn n_edges(&self) -> usize {
        self.edges.len()
    }

    /// Endpoints `[a, b]` of edge `e`, with `a < b`.
    #[inline]
    pub fn edge(&self, e: u32) -> [u32; 2] {
        self.edges[e as usize]
    }

    /// All edges, sorted by `(a, b)`.
    pub fn edges(&self) -> &[[u32; 2]] {
        &self.edges
    }

    /// Faces using edge `e`, in ascending order.
    #[inline]
    pub fn edge_faces(&self, e: u32) -> &[u32] {
        let e = e as usize;
        match self.edge_face_offsets.get(e..e + 2) {
            Some(&[a, b]) => &self.edge_faces[a as usize..b as usize],
            _ => &[],
        }
    }

    /// Edges of face `f`: entry `i` is the edge from corner `i` to corner `i + 1`;
    /// all [`NONE`] for a skipped face.
    #[inline]
    pub fn face_edges(&self, f: u32) -> [u32; 3] {
        self.face_edges[f as usize]
    }

    /// Per face: its edges, entry `i` from corner `i` to corner `i + 1` ([`NONE`] for
    /// skipped faces).
    pub fn face_edge_table(&self) -> &[[u32; 3]] {
        &self.face_edges
    }

    /// The edge joining `a` and `b`, if any.
    pub fn find_edge(&self, a: u32, b: u32) -> Option<u32> {
        let (lo, hi) = if a < b { (a, b) } else { (b, a) };
        let range = self.vertex_edge_offsets.get(lo as usize..lo as usize + 2)?;
        let (s, t) = (range[0] as usize, range[1] as usize);
        self.edges[s..t]
            .binary_search_by_key(&hi, |e| e[1])
            .ok()
            .map(|i| (s + i) as u32)
    }

    /// True when edge `e` has exactly one face.
    #[inline]
    pub fn is_boundary_edge(&self, e: u32) -> bool {
        self.edge_flags[e as usize] & E_BOUNDARY != 0
    }

    /// True when edge `e` has three or more faces, or two using it in the same direction.
    #[inline]
    pub fn is_non_manifold_edge(&self, e: u32) -> bool {
        self.edge_flags[e as usize] & (E_MULTI | E_FLIPPED) != 0
    }

    /// True when edge `e` has exactly two faces that use it in the same direction.
    #[inline]
    pub fn is_flipped_edge(&self, e: u32) -> bool {
        self.edge_flags[e as usize] & E_FLIPPED != 0
    }

    /// Edges with three or more faces or with an orientation flip, ascending.
    pub fn non_manifold_edges(&self) -> Vec<u32> {
        (0..self.edges.len() as u32)
            .filter(|&e| self.is_non_manifold_edge(e))
            .collect()
    }

    /// Faces around vertex `v`, fan after fan.
    ///
    /// For a manifold vertex of a consistently oriented mesh this is its one fan in
    /// counter-clockwise order seen from outside (along the face normals); a boundary
    /// vertex's fan starts at the face whose edge `v → next` is on the boundary.
    #[inline]
    pub fn vertex_faces(&self, v: u32) -> &[u32] {
        let v = v as usize;
        let (a, b) = (
            self.vertex_face_offsets[v] as usize,
            self.vertex_face_offsets[v + 1] as usize,
        );
        &self.vertex_faces[a..b]
    }

    /// Number of faces around vertex `v`.
    #[inline]
    pub fn n_vertex_faces(&self, v: u32) -> usize {
        let v = v as usize;
        (self.vertex_face_offsets[v + 1] - self.vertex_face_offsets[v]) as usize
    }

    /// The fans of vertex `v` (slices of [`Topology::vertex_faces`]); one for a manifold vertex.
    pub fn vertex_fans(&self, v: u32) -> impl Iterator<Item = &[u32]> + '_ {
        let v = v as usize;
        let (a, b) = (
            self.vertex_fan_offsets[v] as usize,
            self.vertex_fan_offsets[v + 1] as usize,
        );
        (a..b).map(move |i| {
            &self.vertex_faces[self.fan_offsets[i] as usize..self.fan_offsets[i + 1] as usize]
        })
    }

    /// Every vertex's faces as one table: `faces[offsets[v]..offsets[v + 1]]` is
    /// [`Topology::vertex_faces`]`(v)`; returns `(offsets, faces)`.
    pub fn vertex_face_table(&self) -> (&[u32], &[u32]) {
        (&self.vertex_face_offsets, &self.vertex_faces)
    }

    /// Number of fans of vertex `v` (0 when isolated, 1 when manifold).
    #[inline]
    pub fn n_vertex_fans(&self, v: u32) -> usize {
        let v = v as usize;
        (self.vertex_fan_offsets[v + 1] - self.vertex_fan_offsets[v]) as usize
    }

    /// The one-ring of vertex `v`: distinct neighbours in the order met along
    /// [`Topology::vertex_faces`]; for a manifold vertex counter-clockwise, from the
    /// boundary neighbour `next` of the first face when `v` is on the boundary.
    ///
    /// Panics on an adjacency made without them ([`Topology::of_split_lean`]).
    #[inline]
    pub fn vertex_neighbors(&self, v: u32) -> &[u32] {
        let v = v as usize;
        let (a, b) = (
            self.vertex_neighbor_offsets[v] as usize,
            self.vertex_neighbor_offsets[v + 1] as usize,
        );
        &self.vertex_neighbors[a..b]
    }

    /// True when [`Topology::vertex_neighbors`] may be asked: every adjacency but a lean
    /// one ([`Topology::of_split_lean`]).
    #[inline]
    pub fn has_vertex_neighbors(&self) -> bool {
        !self.vertex_neighbor_offsets.is_empty()
    }

    /// True when vertex `v` lies on an edge with exactly one face.
    #[inline]
    pub fn is_boundary_vertex(&self, v: u32) -> bool {
        self.vertex_flags[v as usize] & V_BOUNDARY != 0
    }

    /// True when no non-skipped face references vertex `v`.
    #[inline]
    pub fn is_isolated_vertex(&self, v: u32) -> bool {
        self.vertex_flags[v as usize] & V_ISOLATED != 0
    }

    /// True when the faces around vertex `v` form more than one fan.
    #[inline]
    pub fn is_non_manifold_vertex(&self, v: u32) -> bool {
        self.vertex_flags[v as usize] & V_NON_MANIFOLD != 0
    }

    /// Vertices whose faces form more than one fan, ascending.
    pub fn non_manifold_vertices(&self) -> Vec<u32> {
        (0..self.n_vertices as u32)
            .into_par_iter()
            .filter(|&v| self.is_non_manifold_vertex(v))
            .collect()
    }

    /// Vertices referenced by no non-skipped face, ascending.
    pub fn isolated_vertices(&self) -> Vec<u32> {
        (0..self.n_vertices as u32)
            .filter(|&v| self.is_isolated_vertex(v))
            .collect()
    }

    /// Faces skipped by the adjacency because they repeat a vertex index.
    pub fn n_repeated_index_faces(&self) -> usize {
        self.n_repeated_index_faces
    }

    /// Faces skipped by the adjacency because they name a vertex out of range.
    pub fn n_out_of_range_faces(&self) -> usize {
        self.n_out_of_range_faces
    }

    /// True when face `f` takes no part in the adjacency (repeated or out-of-range index).
    #[inline]
    pub fn is_skipped_face(&self, f: u32) -> bool {
        self.face_edges[f as usize][0] == NONE
    }

    /// Number of boundary loops (closed cycles and open chains).
    pub fn n_boundary_loops(&self) -> usize {
        self.loop_component.len()
    }

    /// Boundary loop `i` as a vertex sequence.
    ///
    /// A closed loop starts at the tail of its lowest-numbered edge and first follows that
    /// edge in its face's direction (on a consistently oriented manifold the surface then
    /// lies to the left, seen from outside); each vertex is listed once per pass. At each
    /// vertex, the two boundary edges that end the same fan are consecutive, so a boundary
    /// that touches itself at a bow-tie vertex gives one loop per fan. Boundary edges that
    /// end at an edge of three or more faces are paired at that vertex in edge order,
    /// entering with leaving edges first. An edge left unpaired ends an *open chain*, which
    /// lists both end vertices; open chains come first, each from its open end.
    pub fn boundary_loop(&self, i: usize) -> &[u32] {
        &self.loop_vertices[self.loop_offsets[i] as usize..self.loop_offsets[i + 1] as usize]
    }

    /// The faces along boundary loop `i` (the face of each of its edges), ascending, each
    /// once.
    pub fn faces_along_loop(&self, i: usize) -> Vec<u32> {
        let lp = self.boundary_loop(i);
        let mut faces: Vec<u32> = (0..lp.len())
            .filter_map(|j| self.find_edge(lp[j], lp[(j + 1) % lp.len()]))
            .filter_map(|e| self.edge_faces(e).first().copied())
            .collect();
        faces.sort_unstable();
        faces.dedup();
        faces
    }

    /// All boundary loops as vertex sequences (see [`Topology::boundary_loop`]).
    pub fn boundary_loops(&self) -> Vec<Vec<u32>> {
        (0..self.n_boundary_loops())
            .map(|i| self.boundary_loop(i).to_vec())
            .collect()
    }

    /// Boundary sequences that could not be closed into loops (non-manifold boundaries).
    pub fn n_open_boundary_chains(&self) -> usize {
        self.n_open_boundary_chains
    }

    /// Component of each face (across edges; [`NONE`] for skipped faces). Components are
    /// numbered in order of their lowest face.
    pub fn face_components(&self) -> &[u32] {
        &self.face_component
    }

    /// Number of connected components of faces.
    pub fn n_components(&self) -> usize {
        self.component_orientable.len()
    }

    /// True when component `c`'s faces can be oriented consistently (flipping some of them).
    pub fn component_is_orientable(&self, c: u32) -> bool {
        self.component_orientable[c as usize]
    }

    /// True when component `c` has no edge of three or more faces and no vertex with two
    /// fans inside it.
    pub fn component_is_manifold(&self, c: u32) -> bool {
        self.component_manifold[c as usize]
    }

    /// True when every edge with exactly two faces is used once in each direction.
    pub fn is_consistently_oriented(&self) -> bool {
        self.edge_flags.par_iter().all(|f| f & E_FLIPPED == 0)
    }

    /// True when every edge has one or two faces and every vertex has at most one fan.
    pub fn is_manifold(&self) -> bool {
        self.edge_flags.par_iter().all(|f| f & E_MULTI == 0)
            && self
                .vertex_flags
                .par_iter()
                .all(|f| f & V_NON_MANIFOLD == 0)
    }

    /// Per component, the sum of what `count(i, counts)` adds for every `i` below `len`:
    /// in parallel chunks, each with counts of its own, when there are few components.
    fn component_counts(&self, len: usize, count: impl Fn(usize, &mut [i64]) + Sync) -> Vec<i64> {
        let nc = self.n_components();
        if nc > SUMMARY_PARALLEL_COMPONENTS {
            let mut counts = vec![0i64; nc];
            (0..len).for_each(|i| count(i, &mut counts));
            return counts;
        }
        (0..len.div_ceil(SUMMARY_CHUNK))
            .into_par_iter()
            .map(|k| {
                let mut counts = vec![0i64; nc];
                (k * SUMMARY_CHUNK..((k + 1) * SUMMARY_CHUNK).min(len))
                    .for_each(|i| count(i, &mut counts));
                counts
            })
            .reduce(
                || vec![0i64; nc],
                |mut a, b| {
                    a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                    a
                },
            )
    }

    /// The figures of [`TopologySummary`]; `mesh` must be the mesh this was built from
    /// (its positions give the degenerate-face test).
    pub fn summary(&self, mesh: &Mesh) -> TopologySummary {
        let tiny = sanity::area_threshold(mesh, sanity::DEGENERATE_AREA_REL);
        // A count: the same whatever the chunks and threads.
        let n_tiny: usize = mesh
            .faces
            .par_chunks(1 << 14)
            .enumerate()
            .map(|(k, chunk)| {
                let first = k << 14;
                (first..first + chunk.len())
                    .zip(chunk)
                    .filter(|&(f, face)| {
                        if self.face_edges.get(f).is_none_or(|e| e[0] == NONE) {
                            return false;
                        }
                        let p = face.map(|i| mesh.positions.get(i as usize).copied());
                        matches!(p, [Some(a), Some(b), Some(c)]
                            if sanity::is_degenerate_area(triangle::area(a, b, c), tiny))
                    })
                    .count()
            })
            .sum();
        let mut summary = self.counts.0.get_or_init(|| self.count()).summary.clone();
        summary.n_degenerate_faces += n_tiny;
        summary
    }

    /// Per component: its Euler characteristic V − E + F, a vertex counted in every
    /// component it touches (worked out once, with the summary's counts).
    pub fn component_euler(&self) -> &[i64] {
        &self.counts.0.get_or_init(|| self.count()).euler
    }

    /// The counts of [`Topology::summary`] (without the degenerate faces found by their
    /// area) and of [`Topology::component_euler`].
    fn count(&self) -> Counts {
        let nc = self.n_components();
        let fc = self.component_counts(self.face_component.len(), |f, counts| {
            let c = self.face_component[f];
            if c != NONE {
                counts[c as usize] += 1;
            }
        });
        let ec = self.component_counts(self.edges.len(), |e, counts| {
            let f = self.edge_faces[self.edge_face_offsets[e] as usize];
            counts[self.face_component[f as usize] as usize] += 1;
        });
        let vc = self.component_counts(self.n_vertices, |v, counts| {
            let v = v as u32;
            if self.n_vertex_fans(v) == 1
                && let Some(fan) = self.vertex_fans(v).next()
            {
                // One fan: one component (the common case, without the sort).
                counts[self.face_component[fan[0] as usize] as usize] += 1;
                return;
            }
            let mut comps: Vec<u32> = self
                .vertex_fans(v)
                .map(|fan| self.face_component[fan[0] as usize])
                .collect();
            comps.sort_unstable();
            comps.dedup();
            for c in comps {
                counts[c as usize] += 1;
            }
        });
        let mut bc = vec![0i64; nc];
        for &c in &self.loop_component {
            bc[c as usize] += 1;
        }
        let genus: Vec<Option<i64>> = (0..nc)
            .map(|c| {
                if !(self.component_manifold[c] && self.component_orientable[c]) {
                    return None;
                }
                let twice = 2 - (vc[c] - ec[c] + fc[c]) - bc[c];
                (twice >= 0 && twice % 2 == 0).then_some(twice / 2)
            })
            .collect();
        let genus_total = genus.iter().copied().sum::<Option<i64>>();

        // Counts: the same whatever the chunks and threads.
        let [n_boundary_edges, n_non_manifold_edges, n_flipped_edges] = self
            .edge_flags
            .par_chunks(SUMMARY_CHUNK)
            .map(|chunk| {
                chunk.iter().fold([0usize; 3], |[b, m, f], &flags| {
                    [
                        b + usize::from(flags & E_BOUNDARY != 0),
                        m + usize::from(flags & (E_MULTI | E_FLIPPED) != 0),
                        f + usize::from(flags & E_FLIPPED != 0),
                    ]
                })
            })
            .reduce(|| [0; 3], |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2]]);
        // The ends of edges of three or more faces (rare): a non-manifold vertex on none
        // of them is a bow-tie.
        let mut on_multi: Vec<u32> = self
            .edge_flags
            .par_iter()
            .enumerate()
            .filter(|(_, f)| **f & E_MULTI != 0)
            .flat_map_iter(|(e, _)| self.edges[e])
            .collect();
        on_multi.sort_unstable();
        let n_isolated = self
            .vertex_flags
            .par_iter()
            .filter(|&&f| f & V_ISOLATED != 0)
            .count();
        let nm_vertices = self.non_manifold_vertices();
        let n_bowtie = nm_vertices
            .iter()
            .filter(|v| on_multi.binary_search(v).is_err())
            .count();
        let n_used_faces = self
            .face_component
            .par_iter()
            .filter(|&&c| c != NONE)
            .count();
        let n_ref = self.n_vertices - n_isolated;
        let summary = TopologySummary {
            n_vertices: n_ref,
            n_isolated_vertices: n_isolated,
            n_faces: self.n_faces(),
            n_edges: self.edges.len(),
            n_boundary_edges,
            n_boundary_loops: self.n_boundary_loops(),
            n_open_boundary_chains: self.n_open_boundary_chains,
            n_components: nc,
            n_non_manifold_edges,
            n_flipped_edges,
            n_non_manifold_vertices: nm_vertices.len(),
            n_bowtie_vertices: n_bowtie,
            n_degenerate_faces: self.n_repeated_index_faces,
            n_repeated_index_faces: self.n_repeated_index_faces,
            n_out_of_range_faces: self.n_out_of_range_faces,
            consistently_oriented: self.is_consistently_oriented(),
            manifold: self.is_manifold(),
            euler: n_ref as i64 - self.edges.len() as i64 + n_used_faces as i64,
            genus,
            genus_total,
        };
        let euler = (0..nc).map(|c| vc[c] - ec[c] + fc[c]).collect();
        Counts { summary, euler }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::DVec3;
    use crate::fixtures::{bowtie, tetrahedron};
    use std::collections::BTreeMap;
    use std::path::PathBuf;

    /// `../shared/data` beside the project, if present.
    pub(crate) fn shared_data() -> Option<PathBuf> {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
        if dir.is_dir() {
            Some(dir)
        } else {
            println!("skipped: ../shared/data not found");
            None
        }
    }

    /// A minimal OBJ reader for these tests only: `v` and `f` lines, polygons as fans,
    /// `a/b/c` corners, negative indices. Unreferenced vertices are kept.
    pub(crate) fn read_obj(path: &std::path::Path) -> Mesh {
        let text = std::fs::read_to_string(path).expect("readable test mesh");
        let mut positions = Vec::new();
        let mut faces = Vec::new();
        for line in text.lines() {
            let mut it = line.split_whitespace();
            match it.next() {
                Some("v") => {
                    let c: Vec<f64> = it.take(3).map(|t| t.parse().expect("number")).collect();
                    positions.push(DVec3::new(c[0], c[1], c[2]));
                }
                Some("f") => {
                    let n = positions.len() as i64;
                    let idx: Vec<u32> = it
                        .map(|t| {
                            let i: i64 = t.split('/').next().unwrap().parse().expect("index");
                            (if i < 0 { n + i } else { i - 1 }) as u32
                        })
                        .collect();
                    for k in 1..idx.len() - 1 {
                        faces.push([idx[0], idx[k], idx[k + 1]]);
                    }
                }
                _ => {}
            }
        }
        Mesh::new(positions, faces)
    }

    /// An `n × m` grid of quads on a torus, each split into two triangles.
    fn torus_grid(n: u32, m: u32) -> Mesh {
        let id = |i: u32, j: u32| (i % n) * m + (j % m);
        let mut positions = Vec::new();
        for i in 0..n {
            for j in 0..m {
                let (u, w) = (
                    i as f64 / n as f64 * std::f64::consts::TAU,
                    j as f64 / m as f64 * std::f64::consts::TAU,
                );
                let r = 2.0 + 0.5 * w.cos();
                positions.push(DVec3::new(r * u.cos(), r * u.sin(), 0.5 * w.sin()));
            }
        }
        let mut faces = Vec::new();
        for i in 0..n {
            for j in 0..m {
                faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        Mesh::new(positions, faces)
    }

    /// Checks the tables against each other and against a slow map-based oracle, and the
    /// quick path of the vertex pass against the general one.
    fn check_consistency(mesh: &Mesh, t: &Topology) {
        assert_eq!(
            &Topology::build_with(mesh, false, CHUNK_VERTICES).unwrap(),
            t,
            "quick ≠ general"
        );
        for chunk in [1, 3, 64] {
            assert_eq!(
                &Topology::build_with(mesh, true, chunk).unwrap(),
                t,
                "ranges of {chunk} vertices ≠ one range"
            );
        }
        let mut oracle: BTreeMap<[u32; 2], Vec<u32>> = BTreeMap::new();
        for (f, &[a, b, c]) in mesh.faces.iter().enumerate() {
            let n = mesh.n_vertices() as u32;
            if a >= n || b >= n || c >= n || a == b || b == c || a == c {
                assert!(t.is_skipped_face(f as u32));
                continue;
            }
            for (x, y) in [(a, b), (b, c), (c, a)] {
                oracle
                    .entry([x.min(y), x.max(y)])
                    .or_default()
                    .push(f as u32);
            }
        }
        assert_eq!(t.n_edges(), oracle.len());
        for (e, (key, faces)) in oracle.iter().enumerate() {
            assert_eq!(t.edge(e as u32), *key);
            assert_eq!(t.edge_faces(e as u32), &faces[..]);
            assert_eq!(t.find_edge(key[1], key[0]), Some(e as u32));
            assert_eq!(t.is_boundary_edge(e as u32), faces.len() == 1);
        }
        for (f, face) in mesh.faces.iter().enumerate() {
            if t.is_skipped_face(f as u32) {
                continue;
            }
            for (i, e) in t.face_edges(f as u32).into_iter().enumerate() {
                let (x, y) = (face[i], face[(i + 1) % 3]);
                assert_eq!(t.edge(e), [x.min(y), x.max(y)]);
            }
        }
        for v in 0..mesh.n_vertices() as u32 {
            let mut got = t.vertex_faces(v).to_vec();
            got.sort_unstable();
            let want: Vec<u32> = (0..mesh.n_faces() as u32)
                .filter(|&f| !t.is_skipped_face(f) && mesh.faces[f as usize].contains(&v))
                .collect();
            assert_eq!(got, want, "faces of vertex {v}");
            let mut ring = t.vertex_neighbors(v).to_vec();
            ring.sort_unstable();
            let mut want_ring: Vec<u32> = oracle
                .keys()
                .filter_map(|&[a, b]| (a == v).then_some(b).or((b == v).then_some(a)))
                .collect();
            want_ring.sort_unstable();
            assert_eq!(ring, want_ring, "one-ring of vertex {v}");
            assert_eq!(
                t.vertex_fans(v).map(<[u32]>::len).sum::<usize>(),
                want.len()
            );
        }
    }

    /// Consecutive faces of every fan share an edge, and a consistently oriented fan runs
    /// counter-clockwise: the `prev` corner of one face is the `next` corner of the following.
    fn check_fans_ccw(mesh: &Mesh, t: &Topology) {
        let around = |f: u32, v: u32| {
            let face = mesh.faces[f as usize];
            let c = face.iter().position(|&x| x == v).unwrap();
            (face[(c + 1) % 3], face[(c + 2) % 3])
        };
        for v in 0..mesh.n_vertices() as u32 {
            for fan in t.vertex_fans(v) {
                for w in fan.windows(2) {
                    assert_eq!(around(w[0], v).1, around(w[1], v).0, "fan of {v}");
                }
            }
        }
    }

    #[test]
    fn tetrahedron_is_a_closed_sphere() {
        let m = tetrahedron();
        let t = Topology::build(&m);
        check_consistency(&m, &t);
        check_fans_ccw(&m, &t);
        let s = t.summary(&m);
        assert_eq!((s.n_vertices, s.n_edges, s.n_faces, s.euler), (4, 6, 4, 2));
        assert_eq!(s.n_boundary_loops, 0);
        assert_eq!(s.genus, vec![Some(0)]);
        assert!(s.manifold && s.consistently_oriented);
        for v in 0..4 {
            assert_eq!(t.vertex_neighbors(v).len(), 3);
            assert_eq!(t.n_vertex_fans(v), 1);
            assert!(!t.is_boundary_vertex(v));
        }
    }

    #[test]
    fn euler_characteristics_are_counted_per_component() {
        // A torus, then a tetrahedron, then a single triangle (χ 0, 2 and 1).
        let torus = torus_grid(5, 4);
        let tet = crate::fixtures::tetrahedron();
        let mut positions = torus.positions.clone();
        let mut faces = torus.faces.clone();
        let shift = positions.len() as u32;
        positions.extend(&tet.positions);
        faces.extend(tet.faces.iter().map(|f| f.map(|v| v + shift)));
        let shift = positions.len() as u32;
        positions.extend([
            DVec3::new(9.0, 0.0, 0.0),
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(9.0, 1.0, 0.0),
        ]);
        faces.push([shift, shift + 1, shift + 2]);
        let t = Topology::build(&Mesh::new(positions, faces));
        assert_eq!(t.component_euler(), &[0, 2, 1]);
    }

    #[test]
    fn torus_grid_has_genus_one() {
        let m = torus_grid(8, 5);
        assert!(crate::ring::one_fan_everywhere(&m));
        let t = Topology::build(&m);
        check_consistency(&m, &t);
        check_fans_ccw(&m, &t);
        let s = t.summary(&m);
        assert_eq!(s.euler, 0);
        assert_eq!(s.genus, vec![Some(1)]);
        assert_eq!(s.genus_total, Some(1));
        assert!(s.manifold && s.consistently_oriented);
    }

    #[test]
    fn square_has_one_boundary_loop_in_face_order_and_fans_start_at_the_boundary() {
        // 3---2
        // | / |
        // 0---1      faces 0-1-2 and 0-2-3, counter-clockwise
        let m = Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let t = Topology::build(&m);
        check_consistency(&m, &t);
        assert_eq!(t.boundary_loops(), vec![vec![0, 1, 2, 3]]);
        assert_eq!(t.n_open_boundary_chains(), 0);
        // Around 0, counter-clockwise from the boundary edge 0→1: face 0, then face 1.
        assert_eq!(t.vertex_faces(0), &[0, 1]);
        assert_eq!(t.vertex_neighbors(0), &[1, 2, 3]);
        assert_eq!(t.vertex_neighbors(2), &[3, 0, 1]);
        assert!((0..4).all(|v| t.is_boundary_vertex(v)));
        let s = t.summary(&m);
        assert_eq!(s.genus, vec![Some(0)]);
        assert_eq!(s.n_boundary_edges, 4);
        assert_eq!(s.euler, 1);
    }

    #[test]
    fn interior_vertex_neighbours_run_counter_clockwise() {
        //   3---2
        //   | \ | \
        //   4---0---1      a hexagon-like fan around 0 (6 faces)
        //     \ | \ |
        //       5---6
        let m = Mesh::new(
            vec![
                DVec3::ZERO,
                DVec3::X,
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(-1.0, 1.0, 0.0),
                DVec3::new(-1.0, 0.0, 0.0),
                DVec3::new(0.0, -1.0, 0.0),
                DVec3::new(1.0, -1.0, 0.0),
            ],
            vec![
                [0, 2, 3],
                [0, 6, 1],
                [0, 3, 4],
                [0, 1, 2],
                [0, 4, 5],
                [0, 5, 6],
            ],
        );
        let t = Topology::build(&m);
        check_fans_ccw(&m, &t);
        assert!(!t.is_boundary_vertex(0));
        // Closed fan: starts at the lowest face, walking counter-clockwise.
        assert_eq!(t.vertex_faces(0), &[0, 2, 4, 5, 1, 3]);
        assert_eq!(t.vertex_neighbors(0), &[2, 3, 4, 5, 6, 1]);
    }

    #[test]
    fn bowtie_vertex_is_non_manifold_and_loops_stay_per_fan() {
        let m = bowtie();
        let t = Topology::build(&m);
        check_consistency(&m, &t);
        assert_eq!(t.non_manifold_vertices(), vec![0]);
        assert_eq!(t.n_vertex_fans(0), 2);
        assert!(t.non_manifold_edges().is_empty());
        assert_eq!(t.n_components(), 2, "a vertex alone does not connect");
        // Each loop starts at the tail of its lowest edge: 1→0 (of 0-1) and 0→3.
        assert_eq!(t.boundary_loops(), vec![vec![1, 0, 2], vec![0, 3, 4]]);
        let s = t.summary(&m);
        assert!(!s.manifold);
        assert_eq!((s.n_non_manifold_vertices, s.n_bowtie_vertices), (1, 1));
        // Each part on its own is a disc.
        assert_eq!(s.genus, vec![Some(0), Some(0)]);
    }

    #[test]
    fn fin_edge_with_three_faces_is_non_manifold() {
        //      2
        //     /|\          three triangles on edge 0-1: apexes 2, 3 and 4
        //  3-0-+-1-4
        let m = Mesh::new(
            vec![
                DVec3::ZERO,
                DVec3::X,
                DVec3::new(0.5, 1.0, 0.0),
                DVec3::new(0.5, -1.0, 0.0),
                DVec3::new(0.5, 0.0, 1.0),
            ],
            vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
        );
        let t = Topology::build(&m);
        check_consistency(&m, &t);
        let e = t.find_edge(0, 1).unwrap();
        assert_eq!(t.non_manifold_edges(), vec![e]);
        assert_eq!(t.edge_faces(e), &[0, 1, 2]);
        assert_eq!(t.non_manifold_vertices(), vec![0, 1]);
        let s = t.summary(&m);
        assert_eq!(s.n_components, 1);
        assert_eq!(s.n_bowtie_vertices, 0);
        assert!(!s.manifold);
        assert_eq!(s.genus, vec![None]);
        // 6 boundary edges, every one reached exactly once by the loops or chains.
        let listed: usize =
            t.boundary_loops().iter().map(|l| l.len()).sum::<usize>() - t.n_open_boundary_chains();
        assert_eq!(listed, s.n_boundary_edges);
    }

    #[test]
    fn flipped_face_is_reported_but_component_stays_orientable() {
        // 3---2
        // | / |
        // 0---1      second face listed clockwise: 0-3-2
        let m = Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            vec![[0, 1, 2], [0, 3, 2]],
        );
        let t = Topology::build(&m);
        check_consistency(&m, &t);
        let e = t.find_edge(0, 2).unwrap();
        assert!(t.is_flipped_edge(e));
        assert_eq!(t.non_manifold_edges(), vec![e]);
        assert!(
            t.non_manifold_vertices().is_empty(),
            "still one fan per vertex"
        );
        let s = t.summary(&m);
        assert!(!s.consistently_oriented);
        assert!(s.manifold);
        assert_eq!(s.n_flipped_edges, 1);
        assert!(t.component_is_orientable(0));
        assert_eq!(s.genus, vec![Some(0)]);
    }

    #[test]
    fn summary_counts_degenerate_faces_from_the_positions_given() {
        // The figures the faces decide are kept after the first summary; the degenerate
        // faces follow the positions (stages move vertices and keep the adjacency).
        let m = tetrahedron();
        let t = Topology::build(&m);
        let first = t.summary(&m);
        assert_eq!(first.n_degenerate_faces, 0);
        assert_eq!(t.summary(&m), first);
        let mut flat = m.clone();
        // Vertex 0 onto the midpoint of edge 1–2: face [0, 2, 1] becomes a segment, the
        // other three stay proper triangles.
        let [_, b, c, _] = [0, 1, 2, 3].map(|i| m.positions[i]);
        flat.positions[0] = (b + c) / 2.0;
        let moved = t.summary(&flat);
        assert_eq!(
            moved.n_degenerate_faces,
            1 + t.summary(&m).n_degenerate_faces
        );
        assert_eq!(
            TopologySummary {
                n_degenerate_faces: 0,
                ..moved
            },
            first
        );
        // A fresh adjacency of the moved mesh agrees.
        assert_eq!(Topology::build(&flat).summary(&flat), t.summary(&flat));
    }

    #[test]
    fn mobius_strip_is_not_orientable_and_has_no_genus() {
        // A strip of 5 quads whose ends are glued with a half twist.
        let n = 5u32;
        let mut positions = Vec::new();
        for i in 0..n {
            let u = i as f64 / n as f64 * std::f64::consts::TAU;
            for s in [-0.3, 0.3] {
                let r = 1.0 + s * (u / 2.0).cos();
                positions.push(DVec3::new(r * u.cos(), r * u.sin(), s * (u / 2.0).sin()));
            }
        }
        let mut faces = Vec::new();
        for i in 0..n {
            let (a, b) = (2 * i, 2 * i + 1);
            let (c, d) = if i + 1 < n {
                (2 * i + 2, 2 * i + 3)
            } else {
                (1, 0) // the twist: top meets bottom
            };
            faces.push([a, c, d]);
            faces.push([a, d, b]);
        }
        let m = Mesh::new(positions, faces);
        let t = Topology::build(&m);
        check_consistency(&m, &t);
        assert!(!t.component_is_orientable(0));
        let s = t.summary(&m);
        assert_eq!(s.genus, vec![None]);
        assert_eq!(s.genus_total, None);
        assert_eq!(s.n_boundary_loops, 1, "a Möbius strip has one boundary");
        assert_eq!(t.boundary_loop(0).len(), 10, "it runs around twice");
        assert_eq!(s.n_open_boundary_chains, 0);
    }

    #[test]
    fn repeated_and_out_of_range_faces_are_skipped_and_counted() {
        let mut m = tetrahedron();
        m.faces.push([1, 1, 2]);
        m.faces.push([0, 7, 2]);
        m.positions.push(DVec3::ONE); // vertex 4: isolated
        let t = Topology::build(&m);
        check_consistency(&m, &t);
        assert!(t.is_skipped_face(4) && t.is_skipped_face(5));
        assert_eq!(t.face_edges(4), [NONE; 3]);
        assert_eq!(t.face_components()[5], NONE);
        assert_eq!(t.isolated_vertices(), vec![4]);
        let s = t.summary(&m);
        assert_eq!(s.n_repeated_index_faces, 1);
        assert_eq!(s.n_out_of_range_faces, 1);
        assert_eq!(s.n_degenerate_faces, 1);
        assert_eq!((s.n_vertices, s.n_isolated_vertices), (4, 1));
        assert_eq!(s.genus, vec![Some(0)]);
    }

    #[test]
    fn zero_area_faces_count_as_degenerate() {
        let m = Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0, DVec3::Y],
            vec![[0, 1, 2], [0, 1, 3]],
        );
        let s = Topology::build(&m).summary(&m);
        assert_eq!(s.n_degenerate_faces, 1);
    }

    #[test]
    fn empty_mesh_has_empty_topology() {
        let m = Mesh::default();
        let t = Topology::build(&m);
        let s = t.summary(&m);
        assert_eq!((s.n_edges, s.n_components, s.euler), (0, 0, 0));
        assert_eq!(s.genus_total, Some(0));
        assert_eq!(t.find_edge(0, 1), None);
    }

    #[test]
    fn build_is_deterministic() {
        let m = torus_grid(7, 4);
        assert_eq!(Topology::build(&m), Topology::build(&m));
    }

    #[test]
    fn high_valence_vertex_gets_the_same_fan_as_a_low_valence_one() {
        // A disc of 24 triangles around vertex 0 (more than the quick path takes), faces
        // listed in a scrambled order.
        let n = 24u32;
        let mut positions = vec![DVec3::ZERO];
        positions.extend((0..n).map(|i| {
            let t = f64::from(i) / f64::from(n) * std::f64::consts::TAU;
            DVec3::new(t.cos(), t.sin(), 0.0)
        }));
        let faces: Vec<[u32; 3]> = (0..n)
            .map(|i| (i * 7) % n)
            .map(|i| [0, 1 + i, 1 + (i + 1) % n])
            .collect();
        let m = Mesh::new(positions, faces);
        let t = Topology::build(&m);
        check_consistency(&m, &t);
        check_fans_ccw(&m, &t);
        assert_eq!(t.n_vertex_fans(0), 1);
        assert!(!t.is_boundary_vertex(0));
        assert_eq!(t.vertex_neighbors(0).len(), 24);
        assert_eq!(t.boundary_loops().len(), 1);
        assert_eq!(t.boundary_loop(0).len(), 24);
        assert_eq!(t.summary(&m).genus, vec![Some(0)]);
    }

    /// A torus grid damaged in every way the vertex pass distinguishes: holes (boundary
    /// loops), faces listed backwards (flipped edges), doubled faces (edges of three or
    /// more faces), merged vertices (bow-ties and high valence), faces repeating an index
    /// or naming a vertex out of range (skipped), and isolated vertices.
    fn damaged_torus(n: u32, m: u32) -> Mesh {
        let mut mesh = torus_grid(n, m);
        let nv = mesh.n_vertices() as u32;
        let mut faces = Vec::with_capacity(mesh.faces.len() + mesh.faces.len() / 50);
        for (f, &face) in mesh.faces.iter().enumerate() {
            match f % 211 {
                0 | 1 | 2 | 7 => {} // a hole
                _ if f % 131 == 5 => faces.push([face[0], face[2], face[1]]),
                _ if f % 173 == 9 => {
                    faces.push(face);
                    faces.push(face);
                }
                _ if f % 389 == 11 => faces.push([face[0], face[1], face[0]]),
                _ if f % 397 == 13 => faces.push([face[0], nv + 5, face[2]]),
                _ => faces.push(face),
            }
        }
        // Merge some vertices into others far away: bow-ties and crowded fans.
        for k in 0..(nv / 997) {
            let (from, to) = (k * 997 + 3, (k * 997 + nv / 2) % nv);
            for face in &mut faces {
                face.iter_mut()
                    .filter(|x| **x == from)
                    .for_each(|x| *x = to);
            }
        }
        mesh.faces = faces;
        mesh.positions.push(DVec3::splat(9.0)); // isolated
        mesh
    }

    #[test]
    fn any_range_size_gives_the_same_tables() {
        let m = damaged_torus(40, 31);
        let t = Topology::build_with(&m, true, usize::MAX).unwrap();
        check_consistency(&m, &t);
        let s = t.summary(&m);
        assert!(s.n_boundary_loops > 0 && s.n_non_manifold_edges > 0);
        assert!(s.n_flipped_edges > 0 && s.n_non_manifold_vertices > 0);
        assert!(s.n_repeated_index_faces > 0 && s.n_out_of_range_faces > 0);
        assert!(s.n_isolated_vertices > 0);
        for chunk in [2, 5, 17, 100, 1000] {
            for quick in [true, false] {
                assert_eq!(
                    Topology::build_with(&m, quick, chunk).unwrap(),
                    t,
                    "ranges of {chunk}, quick {quick}"
                );
            }
        }
    }

    #[test]
    fn parallel_build_equals_the_serial_one_for_any_thread_count() {
        // More vertices than one range holds and more faces than one bucketing piece, so
        // `build` takes the parallel paths (the one-thread pool buckets in one piece).
        let clean = torus_grid(300, 240);
        let damaged = damaged_torus(290, 240);
        for m in [&clean, &damaged] {
            assert!(m.n_vertices() > 2 * CHUNK_VERTICES);
            assert!(m.n_faces() >= BUCKET_PARALLEL_MIN);
            let serial = Topology::build_with(m, true, usize::MAX).unwrap();
            assert_eq!(
                Topology::build_with(m, false, usize::MAX).unwrap(),
                serial,
                "quick ≠ general"
            );
            for threads in [1, 2, 3, 4] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let built = pool.install(|| Topology::try_build(m)).unwrap();
                assert_eq!(built, serial, "{threads} threads");
                let ranged = pool.install(|| Topology::build_with(m, true, CHUNK_VERTICES));
                assert_eq!(ranged.unwrap(), serial, "{threads} threads, ranges");
            }
        }
        let s = serial_summary(&damaged);
        assert!(s.n_boundary_loops > 0 && s.n_non_manifold_edges > 0);
        assert!(s.n_flipped_edges > 0 && s.n_bowtie_vertices > 0);
        assert!(s.n_repeated_index_faces > 0 && s.n_out_of_range_faces > 0);
        assert_eq!(serial_summary(&clean).genus, vec![Some(1)]);
    }

    /// The summary of the one-range build.
    fn serial_summary(m: &Mesh) -> TopologySummary {
        Topology::build_with(m, true, usize::MAX)
            .unwrap()
            .summary(m)
    }

    proptest::proptest! {
        #![proptest_config(crate::fixtures::fixed_seed(0x7090_0001))]

        #[test]
        fn random_soups_never_panic_and_tables_agree(
            n in 1usize..9,
            faces in proptest::collection::vec(proptest::array::uniform3(0u32..10), 0..24),
        ) {
            let m = Mesh::new(
                (0..n).map(|i| DVec3::new(i as f64, (i * i) as f64, 1.0)).collect(),
                faces,
            );
            let t = Topology::build(&m);
            check_consistency(&m, &t);
            let s = t.summary(&m);
            // Every boundary edge lies in exactly one loop or chain.
            let listed = t.boundary_loops().iter().map(Vec::len).sum::<usize>()
                - t.n_open_boundary_chains();
            proptest::prop_assert_eq!(listed, s.n_boundary_edges);
            proptest::prop_assert_eq!(s.genus.len(), s.n_components);
            if crate::ring::one_fan_everywhere(&m) {
                proptest::prop_assert_eq!(s.n_non_manifold_vertices + s.n_non_manifold_edges, 0);
            }
        }

        #[test]
        fn damaged_tori_agree_with_the_oracle(
            ops in proptest::collection::vec((0u8..4, 0usize..60, 0u32..30), 0..12),
        ) {
            // A clean torus, then faces removed, flipped or doubled and vertices merged:
            // the mix of regular and irregular vertices both vertex paths must agree on.
            let mut m = torus_grid(6, 5);
            for (kind, f, v) in ops {
                let f = f % m.faces.len().max(1);
                match kind {
                    0 if !m.faces.is_empty() => {
                        m.faces.remove(f);
                    }
                    1 if !m.faces.is_empty() => m.faces[f].swap(1, 2),
                    2 if !m.faces.is_empty() => m.faces.push(m.faces[f]),
                    _ => {
                        let target = (v + 1) % 30;
                        for face in &mut m.faces {
                            face.iter_mut().filter(|x| **x == v).for_each(|x| *x = target);
                        }
                    }
                }
            }
            let t = Topology::build(&m);
            check_consistency(&m, &t);
            let s = t.summary(&m);
            let listed = t.boundary_loops().iter().map(Vec::len).sum::<usize>()
                - t.n_open_boundary_chains();
            proptest::prop_assert_eq!(listed, s.n_boundary_edges);
            if s.manifold && s.consistently_oriented {
                check_fans_ccw(&m, &t);
            }
            if crate::ring::one_fan_everywhere(&m) {
                proptest::prop_assert_eq!(s.n_non_manifold_vertices + s.n_non_manifold_edges, 0);
            }
        }
    }

    /// Union-find root with path halving (test helper).
    fn root(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }

    /// Components when faces sharing only a vertex also count as connected.
    fn parts_joined_at_vertices(t: &Topology) -> usize {
        let mut parent: Vec<usize> = (0..t.n_components()).collect();
        for v in 0..t.n_vertices() as u32 {
            let mut fans = t.vertex_fans(v);
            if let Some(first) = fans.next() {
                let a = root(&mut parent, t.face_components()[first[0] as usize] as usize);
                for fan in fans {
                    let b = root(&mut parent, t.face_components()[fan[0] as usize] as usize);
                    parent[b] = a;
                }
            }
        }
        (0..parent.len())
            .filter(|&c| root(&mut parent, c) == c)
            .count()
    }

    /// Connected pieces of the graph of boundary edges (loops touching at a vertex merge).
    fn boundary_edge_graph_pieces(t: &Topology) -> usize {
        let mut parent: Vec<usize> = (0..t.n_vertices()).collect();
        let mut on = vec![false; t.n_vertices()];
        for e in (0..t.n_edges() as u32).filter(|&e| t.is_boundary_edge(e)) {
            let [a, b] = t.edge(e).map(|v| v as usize);
            on[a] = true;
            on[b] = true;
            let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
            parent[rb] = ra;
        }
        (0..parent.len())
            .filter(|&v| on[v] && root(&mut parent, v) == v)
            .count()
    }

    #[test]
    fn shared_meshes_match_their_documented_topology() {
        let Some(dir) = shared_data() else {
            return;
        };
        let load = |name: &str| {
            let m = read_obj(&dir.join(format!("{name}.obj")));
            let t = Topology::build(&m);
            assert_eq!(
                Topology::build_with(&m, false, CHUNK_VERTICES).unwrap(),
                t,
                "quick ≠ general"
            );
            assert_eq!(
                Topology::build_with(&m, true, 500).unwrap(),
                t,
                "ranges ≠ one range"
            );
            let s = t.summary(&m);
            (t, s)
        };
        let (_, bunny) = load("stanford-bunny");
        assert_eq!(bunny.n_boundary_loops, 5);
        assert_eq!(bunny.n_isolated_vertices, 1113);
        assert_eq!(bunny.genus, vec![Some(0)]);
        assert!(bunny.manifold && bunny.consistently_oriented);

        let (_, rocker) = load("rocker-arm");
        assert_eq!((rocker.n_boundary_edges, rocker.n_components), (0, 1));
        assert_eq!(rocker.genus, vec![Some(1)]);
        assert!(rocker.manifold);

        for name in ["fandisk", "spot"] {
            let (_, s) = load(name);
            assert_eq!((s.n_boundary_edges, s.genus_total), (0, Some(0)), "{name}");
            assert!(s.manifold && s.consistently_oriented, "{name}");
        }

        let (_, cow) = load("cow");
        assert_eq!(cow.n_non_manifold_vertices, 1);
        assert_eq!(cow.n_bowtie_vertices, 1);
        assert_eq!((cow.n_boundary_edges, cow.n_components), (0, 1));

        let (_, beetle) = load("beetle");
        assert_eq!(beetle.n_components, 2);
        assert_eq!(beetle.n_boundary_loops, 23);
        assert_eq!(beetle.n_non_manifold_edges, 47);

        let (_, suzanne) = load("suzanne");
        assert_eq!(suzanne.n_faces, 968);
        assert_eq!(suzanne.n_components, 3);
        assert_eq!(suzanne.n_boundary_loops, 4);
        assert_eq!(suzanne.n_non_manifold_edges, 1);

        // The teapot's 38 bow-tie vertices join parts that share no edge. Our definitions
        // (components across edges, loops split where a boundary passes a bow-tie) give
        // 19 components and 25 loops; the README's figures (4 parts, 10 loops) count
        // parts joined at vertices and pieces of the boundary-edge graph.
        let (teapot_t, teapot) = load("teapot");
        assert_eq!(teapot.n_non_manifold_vertices, 38);
        assert_eq!(teapot.n_bowtie_vertices, 38);
        assert_eq!((teapot.n_components, teapot.n_boundary_loops), (19, 25));
        assert_eq!(parts_joined_at_vertices(&teapot_t), 4);
        assert_eq!(boundary_edge_graph_pieces(&teapot_t), 10);
    }
}
