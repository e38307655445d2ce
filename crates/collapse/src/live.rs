//! The mesh being collapsed: flat arrays plus incremental vertex → faces lists.

use crate::progressive::{ChangedFace, DeletedFace, Progressive, Step, fingerprint};
use crate::queue::{Entry, Fate, Queue};
use crate::{
    CollapseError, CollapseRecord, CostModel, FaceGuard, Goal, Index, Merge, NONE, NoGuard,
    Options, Outcome, Plan, Reach, Refusals, Reshape, StopReason, Unit, VertexKind, keep_in_order,
};
use coarsen_edit::FaceLists;
use coarsen_geom::{Aabb, DVec3, is_finite, triangle};
use coarsen_mesh::ring::{RingShape, repeated_end, ring_shape};
use coarsen_mesh::{CarryReport, FaceOrigins, Mesh, VertexOrigins};
use rayon::prelude::*;

mod parts;
mod seams;
mod surface;

pub use surface::Settled;

pub use parts::{PartOptions, Parted};

/// Face states.
const LIVE: u8 = 0;
const DEAD: u8 = 1;
/// A face that repeats a vertex: kept as it is, outside the adjacency (its vertices are locked).
const PASSIVE: u8 = 2;

/// A face is degenerate below this area, relative to the squared bounding-box diagonal
/// (metrics.md's `n_degenerate`).
const DEGENERATE_AREA: f64 = 1e-12;

/// Cosine of the largest turn (60°) a face may make away from its input normal.
const DRIFT_COS: f64 = 0.5;

/// A vertex's merged input region counts for the flip test while the length of its summed
/// area-weighted normal is at least this fraction of its area (the region's normals agree:
/// it does not wrap around a thin part).
const REGION_COHERENCE: f64 = 0.5;

/// The most faces a [`LiveMesh`] takes: its vertex → faces arena (three corners per
/// face, with room to grow) then fits `u32` offsets.
pub const MAX_FACES: usize = (u32::MAX / 8) as usize;

/// How often (in collapses) the progress callback is told.
const PROGRESS_EVERY: usize = 4096;

/// Why a candidate was not collapsed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Refusal {
    Link,
    Flip,
    Degenerate,
    Quality,
    Facing,
    Boundary,
    Locked,
    Seam,
    Model,
}

impl Refusals {
    /// Adds `other`'s counts to these.
    pub(crate) fn add(&mut self, other: &Refusals) {
        self.link += other.link;
        self.flip += other.flip;
        self.degenerate += other.degenerate;
        self.quality += other.quality;
        self.facing += other.facing;
        self.boundary += other.boundary;
        self.locked += other.locked;
        self.seam += other.seam;
        self.model += other.model;
    }

    fn count(&mut self, r: Refusal) {
        *match r {
            Refusal::Link => &mut self.link,
            Refusal::Flip => &mut self.flip,
            Refusal::Degenerate => &mut self.degenerate,
            Refusal::Quality => &mut self.quality,
            Refusal::Facing => &mut self.facing,
            Refusal::Boundary => &mut self.boundary,
            Refusal::Locked => &mut self.locked,
            Refusal::Seam => &mut self.seam,
            Refusal::Model => &mut self.model,
        } += 1;
    }
}

/// A candidate of the initial ranking, costed: queue it, or count why not.
#[derive(Clone, Copy, Debug)]
enum Ranked {
    Queue {
        cost: f64,
        vertices: [Index; 3],
        stamp: u32,
    },
    Refused(Refusal),
}

/// Figures of a live mesh's current state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Summary {
    /// Vertices used by faces.
    pub vertices: usize,
    /// Faces (passive ones, which repeat a vertex, included).
    pub faces: usize,
    /// Vertices used by no face (dropped from the output).
    pub isolated_vertices: usize,
    /// Vertices whose faces form one open fan.
    pub boundary_vertices: usize,
    /// Non-manifold vertices, and vertices of faces that repeat a vertex.
    pub locked_vertices: usize,
    /// Edges with exactly one face.
    pub boundary_edges: usize,
    /// Closed chains of boundary edges (exact when no vertex is locked).
    pub boundary_loops: usize,
    /// Euler characteristic V − E + F (exact when no vertex is locked).
    pub euler: i64,
}

/// `mesh`'s attribute columns alone, its positions and faces freed (see
/// [`LiveMesh::to_mesh_with_attributes`]).
pub fn attributes_only(mesh: Mesh) -> Mesh {
    let Mesh {
        positions,
        faces,
        vertex_attrs,
        face_attrs,
        wedges,
        materials,
        marked_edges,
    } = mesh;
    drop((positions, faces, marked_edges));
    Mesh {
        vertex_attrs,
        face_attrs,
        wedges,
        materials,
        ..Mesh::default()
    }
}

/// A mesh under collapse: positions, faces, vertex kinds and vertex → faces lists, all
/// updated in place by each collapse.
#[derive(Clone, Debug)]
pub struct LiveMesh {
    pos: Vec<DVec3>,
    faces: Vec<[Index; 3]>,
    face_state: Vec<u8>,
    lists: FaceLists,
    kind: Vec<VertexKind>,
    alive: Vec<bool>,
    stamp: Vec<u32>,
    /// The input vertices merged into each vertex, as linked lists (`cluster_next`, over
    /// the vertices' first numbering, see `base_vertex`), with the last one of each list
    /// in `cluster_tail` (per vertex).
    cluster_next: Vec<Index>,
    cluster_tail: Vec<Index>,
    /// Once the arrays were closed up: each vertex's index before the first time (what
    /// `cluster_next` and `original_of` speak), and each face's index in the input.
    base_vertex: Option<Vec<Index>>,
    base_face: Option<Vec<Index>>,
    /// Vertex and face counts of the input (the arrays' lengths until closed up).
    input_vertices: usize,
    input_faces: usize,
    n_vertices: usize,
    n_faces: usize,
    diagonal: f64,
    /// Twice the degenerate area: a face whose cross product is this short is degenerate.
    min_cross: f64,
    /// Each input face's unit normal (zero when degenerate): no collapse may turn a face
    /// 60° or more away from it, so that faces cannot drift over many collapses.
    input_normal: Vec<DVec3>,
    /// Per vertex, the sum of the input faces' cross products (area-weighted normals)
    /// around every input vertex merged into it: no kept face may face away from the
    /// input surface its corners stand for.
    region_normal: Vec<DVec3>,
    /// Per vertex, the sum of the lengths of the cross products summed in `region_normal`:
    /// a region whose normals disagree (it wraps around a thin part) is not tested.
    region_area: Vec<f64>,
    /// The progressive record, when asked for ([`LiveMesh::record_progressive`]).
    history: Option<Progressive>,
    /// The input's index of each vertex (in its first numbering), when
    /// [`LiveMesh::new_renumbered`] renumbered them.
    original_of: Option<Vec<Index>>,
    /// The faces the last collapse deleted (their corners as they were).
    last_deleted: Vec<Index>,
    /// The per-corner attributes tracked through the collapses, when asked for
    /// ([`LiveMesh::track_seams`]).
    seams: Option<seams::SeamState>,
    /// Every edge collapse keeps one of its two vertices where it is
    /// ([`LiveMesh::keep_input_positions`]).
    subset: bool,
    /// The input's positions and faces, when the output takes anything from them
    /// (the seams' values, settling).
    input: Option<Box<surface::InputSurface>>,
    /// Whether the output's moved vertices go onto the input surface
    /// ([`LiveMesh::settle_on_input`]).
    settle: bool,
    /// What settling did, once the output was made.
    settled: std::sync::OnceLock<Settled>,
}

/// What [`LiveMesh::build`] derives from its mesh: per vertex its kind and the sums of
/// the input's area-weighted normals around it, per face its input normal, and the scale.
struct Derived {
    kind: Vec<VertexKind>,
    diagonal: f64,
    min_cross: f64,
    input_normal: Vec<DVec3>,
    region_normal: Vec<DVec3>,
    region_area: Vec<f64>,
}

/// How [`LiveMesh::keep_live`] renumbered: the new vertex `i` is the old
/// `old_vertex[i]`; `new_vertex` and `new_face` map old indices to new ones (or `NONE`).
struct Renaming {
    old_vertex: Vec<Index>,
    new_vertex: Vec<Index>,
    new_face: Vec<Index>,
}

/// A collapse run between calls of [`LiveMesh::resume`]: its queue, work buffers and what
/// it did so far.
struct Run {
    q: Queue,
    s: Scratch,
    out: Outcome,
    /// The candidate that stopped the last call at its error limit, first in line.
    held: Option<Entry>,
    /// Whether the arrays may still be closed up (never while a progressive record is kept).
    may_close_up: bool,
}

impl Run {
    /// The costs of the current candidates in the queue (the held one included), added to
    /// `costs`.
    fn queued_costs(&self, mesh: &LiveMesh, costs: &mut Vec<f64>) {
        let held = self.held.iter();
        costs.extend(
            self.q
                .entries()
                .chain(held)
                .filter(|e| mesh.is_current(e))
                .map(|e| e.cost),
        );
    }
}

/// What [`LiveMesh::vet`] decided for a candidate.
enum Vetted {
    /// Collapse it now, at `plan`, keeping `pinned` when the rules pin a vertex.
    Go { plan: Plan, pinned: Option<Index> },
    /// Not now (stale, refused, or dearer than queued).
    Skip,
    /// The run ends here.
    Stop(StopReason),
}

/// The last face of a face goal: an interior edge collapse takes two faces and would end
/// one below the goal, a boundary one exactly one. While one face is left, the candidates
/// that take two and pass every check are set aside (in queue order) and a boundary edge
/// is looked for; only when none can be collapsed is the first of them made (a closed
/// mesh keeps an even face count: an odd goal is missed by one).
#[derive(Default)]
struct LastFace {
    aside: Vec<Entry>,
    /// Whether the candidate being tried came from `aside`.
    settling: bool,
    /// Whether the mesh has a boundary vertex, once asked.
    has_boundary: Option<bool>,
}

impl LastFace {
    /// The next candidate: the held one, the queue's next, or the first set aside.
    #[inline]
    fn next(&mut self, run: &mut Run) -> Option<Entry> {
        let popped = run.held.take().or_else(|| run.q.pop());
        popped.or_else(|| {
            (!self.aside.is_empty()).then(|| {
                self.settling = true;
                self.aside.remove(0)
            })
        })
    }

    /// Sets `e` aside when it would take the last face's goal one face too far and a
    /// boundary edge may still do.
    #[inline]
    fn holds_back(&mut self, mesh: &LiveMesh, e: Entry, unit: Unit, opts: &Options) -> bool {
        let verts = e.vertices();
        let hold = !self.settling
            && unit == Unit::Edge
            && matches!(opts.goal, Goal::Faces(n) if mesh.n_faces == n + 1)
            && !mesh.is_boundary_edge(verts[0], verts[1])
            && *self
                .has_boundary
                .get_or_insert_with(|| mesh.kind.par_iter().any(|&k| k == VertexKind::Boundary));
        if hold {
            self.aside.push(e);
        }
        hold
    }

    /// Puts what was set aside back in the queue (after a collapse, or at the end).
    fn release(&mut self, q: &mut Queue) {
        self.settling = false;
        for e in self.aside.drain(..) {
            q.put_back(e);
        }
    }
}

/// Work buffers of one run, reused by every collapse.
struct Scratch {
    ring: Vec<(Index, Index)>,
    targets: Vec<Index>,
    /// After a refusal by the link condition: a vertex of the ring that two ring edges
    /// leave or enter ([`NONE`] when the ring fails otherwise).
    witness: Index,
    kept_faces: Vec<(Index, usize)>,
    /// Per kept face: its cross product before and after the merge, and whether it was
    /// degenerate before.
    crosses: Vec<(DVec3, DVec3, bool)>,
    list: Vec<Index>,
    around: Vec<Index>,
    touched: Vec<Index>,
    in_touched: Marks,
    seen: Marks,
}

impl Scratch {
    /// Empty buffers, with marks for `n` vertices or faces.
    fn new(n: usize) -> Self {
        Scratch {
            ring: Vec::new(),
            targets: Vec::new(),
            witness: NONE,
            kept_faces: Vec::new(),
            crosses: Vec::new(),
            list: Vec::new(),
            around: Vec::new(),
            touched: Vec::new(),
            in_touched: Marks::new(n),
            seen: Marks::new(n),
        }
    }
}

/// A set of indices cleared in O(1) by bumping a generation.
struct Marks {
    gen_of: Vec<u32>,
    generation: u32,
}

impl Marks {
    fn new(n: usize) -> Self {
        Marks {
            gen_of: vec![0; n],
            generation: 0,
        }
    }

    fn clear(&mut self) {
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.gen_of.iter_mut().for_each(|g| *g = 0);
            self.generation = 1;
        }
    }

    /// Adds `i`; true when it was not in the set.
    #[inline]
    fn insert(&mut self, i: Index) -> bool {
        let g = &mut self.gen_of[i as usize];
        let fresh = *g != self.generation;
        *g = self.generation;
        fresh
    }

    #[inline]
    fn contains(&self, i: Index) -> bool {
        self.gen_of[i as usize] == self.generation
    }
}

/// The ring edge `x → y` of face `face` around its corner `c`.
#[inline]
fn ring_edge(face: [Index; 3], c: usize) -> (Index, Index) {
    (face[(c + 1) % 3], face[(c + 2) % 3])
}

#[inline]
fn corner_of(face: [Index; 3], v: Index) -> usize {
    if face[0] == v {
        0
    } else if face[1] == v {
        1
    } else {
        2
    }
}

impl LiveMesh {
    /// Takes `mesh` apart for collapsing and classifies its vertices (see the crate docs).
    ///
    /// Fails on indices out of range and on non-finite positions; any other input,
    /// manifold or not, is accepted.
    pub fn new(mesh: &Mesh) -> Result<LiveMesh, CollapseError> {
        Self::check_input(mesh)?;
        Ok(Self::build(
            mesh.positions.clone(),
            mesh.faces.clone(),
            None,
        ))
    }

    /// [`LiveMesh::new`] with the vertices numbered internally in the order the faces first
    /// use them (vertices no face uses last, in input order), so that the vertices of a
    /// face, and of neighbouring faces, sit close together in memory: on a large mesh whose
    /// vertex order wanders (a subdivided one, say) collapsing then takes about a fifth less
    /// time. Vertex indices seen through this live mesh — [`LiveMesh::position`],
    /// [`LiveMesh::face`], [`LiveMesh::faces_around`] and the like, hence a [`CostModel`]'s —
    /// are the internal ones; [`LiveMesh::to_mesh`], [`Outcome::log`] and the progressive
    /// record speak the input's, and the output is the one [`LiveMesh::new`] would give for
    /// the same collapses. When the input already is in that order this is
    /// [`LiveMesh::new`].
    pub fn new_renumbered(mesh: &Mesh) -> Result<LiveMesh, CollapseError> {
        Self::check_input(mesh)?;
        let n = mesh.n_vertices();
        let mut internal = vec![NONE; n];
        let mut original_of: Vec<Index> = Vec::with_capacity(n);
        for face in &mesh.faces {
            for &v in face {
                let slot = &mut internal[v as usize];
                if *slot == NONE {
                    *slot = original_of.len() as Index;
                    original_of.push(v);
                }
            }
        }
        for (v, slot) in internal.iter_mut().enumerate() {
            if *slot == NONE {
                *slot = original_of.len() as Index;
                original_of.push(v as Index);
            }
        }
        if original_of
            .iter()
            .enumerate()
            .all(|(i, &v)| i as Index == v)
        {
            return Ok(Self::build(
                mesh.positions.clone(),
                mesh.faces.clone(),
                None,
            ));
        }
        let positions = original_of
            .iter()
            .map(|&v| mesh.positions[v as usize])
            .collect();
        let faces = mesh
            .faces
            .iter()
            .map(|f| f.map(|v| internal[v as usize]))
            .collect();
        Ok(Self::build(positions, faces, Some(original_of)))
    }

    /// The index of vertex `v` in the input (for a part of a live mesh, see
    /// [`LiveMesh::collapse_in_parts`], in that live mesh), whatever the numbering inside.
    pub fn input_index(&self, v: Index) -> Index {
        self.original(v)
    }

    /// Makes every edge collapse keep one of its two vertices where it is (the cheaper by
    /// the model; "subset placement"), so that the output's vertices are input vertices at
    /// their input positions. Triangle collapses still place their vertex where the model
    /// likes. Call before any collapse.
    pub fn keep_input_positions(&mut self) {
        self.subset = true;
    }

    /// Locks the vertices of the input (its indices) listed in `input`, before any
    /// collapse: like a non-manifold vertex, a locked vertex never moves and no collapse
    /// merges it (a sharp corner to keep). Returns how many were newly locked (indices out
    /// of range, vertices no face uses and those locked already are skipped).
    pub fn lock(&mut self, input: &[Index]) -> usize {
        let mut internal = vec![NONE; self.input_vertices];
        for v in 0..self.pos.len() as Index {
            if let Some(slot) = internal.get_mut(self.original(v) as usize) {
                *slot = v;
            }
        }
        let mut n = 0;
        for &w in input {
            let Some(&v) = internal
                .get(w as usize)
                .filter(|&&v| v != NONE && self.alive[v as usize])
            else {
                continue;
            };
            let kind = &mut self.kind[v as usize];
            if matches!(kind, VertexKind::Interior | VertexKind::Boundary) {
                *kind = VertexKind::Locked;
                n += 1;
            }
        }
        n
    }

    /// The input's index of internal vertex `v` (see [`LiveMesh::new_renumbered`]).
    #[inline]
    fn original(&self, v: Index) -> Index {
        self.original_of_base(self.base(v))
    }

    /// The input's index of the vertex first numbered `b` (see `base_vertex`).
    #[inline]
    fn original_of_base(&self, b: Index) -> Index {
        match &self.original_of {
            Some(o) if b != NONE => o[b as usize],
            _ => b,
        }
    }

    /// The first index of vertex `v` (before the arrays were closed up).
    #[inline]
    fn base(&self, v: Index) -> Index {
        match &self.base_vertex {
            Some(b) if v != NONE => b[v as usize],
            _ => v,
        }
    }

    /// The errors of [`LiveMesh::new`], named in the input's indices.
    fn check_input(mesh: &Mesh) -> Result<(), CollapseError> {
        mesh.validate_indices()?;
        if mesh.n_faces() > MAX_FACES {
            return Err(CollapseError::TooLarge {
                faces: mesh.n_faces(),
                max: MAX_FACES,
            });
        }
        if let Some((vertex, p)) = mesh
            .positions
            .iter()
            .enumerate()
            .find(|(_, p)| !is_finite(**p))
        {
            return Err(CollapseError::NonFinite {
                vertex,
                x: p.x,
                y: p.y,
                z: p.z,
            });
        }
        Ok(())
    }

    /// The live mesh of `positions` and `faces` (checked), with the input's index of each
    /// vertex when they were renumbered.
    fn build(
        positions: Vec<DVec3>,
        faces: Vec<[Index; 3]>,
        original_of: Option<Vec<Index>>,
    ) -> LiveMesh {
        Self::build_with(positions, faces, original_of, None)
    }

    /// [`LiveMesh::build`] with the vertex kinds, scale and input normals `given` instead
    /// of derived from the mesh (a part of a live mesh takes them from the whole).
    fn build_with(
        positions: Vec<DVec3>,
        faces: Vec<[Index; 3]>,
        original_of: Option<Vec<Index>>,
        given: Option<Derived>,
    ) -> LiveMesh {
        let mesh = Mesh::new(positions, faces);
        let n = mesh.n_vertices();
        let face_state: Vec<u8> = mesh
            .faces
            .iter()
            .map(|&[a, b, c]| {
                if a == b || b == c || a == c {
                    PASSIVE
                } else {
                    LIVE
                }
            })
            .collect();
        let use_face: Vec<bool> = face_state.iter().map(|&s| s == LIVE).collect();
        let lists = FaceLists::build(n, &mesh.faces, &use_face);
        let Derived {
            kind,
            diagonal,
            min_cross,
            input_normal,
            region_normal,
            region_area,
        } = match given {
            Some(d) => d,
            None => Self::derive(&mesh, &face_state, &lists),
        };
        let n_faces = mesh.n_faces();
        let n_faces_all = mesh.faces.len();
        let Mesh {
            positions, faces, ..
        } = mesh;
        LiveMesh {
            pos: positions,
            faces,
            face_state,
            lists,
            n_vertices: kind.iter().filter(|k| **k != VertexKind::Isolated).count(),
            n_faces,
            kind,
            alive: vec![true; n],
            stamp: vec![0; n],
            cluster_next: vec![NONE; n],
            cluster_tail: (0..n as Index).collect(),
            diagonal,
            min_cross,
            input_normal,
            region_normal,
            region_area,
            history: None,
            last_deleted: Vec::new(),
            seams: None,
            subset: false,
            input: None,
            settle: false,
            settled: std::sync::OnceLock::new(),
            original_of,
            base_vertex: None,
            base_face: None,
            input_vertices: n,
            input_faces: n_faces_all,
        }
    }

    /// The vertex kinds, the scale, the input face normals and the per-vertex sums of the
    /// input's area-weighted normals of `mesh`.
    fn derive(mesh: &Mesh, face_state: &[u8], lists: &FaceLists) -> Derived {
        let n = mesh.n_vertices();
        let cross_of = |f: usize| {
            let [a, b, c] = mesh.faces[f].map(|v| mesh.positions[v as usize]);
            triangle::cross(a, b, c)
        };
        // The vertex kinds and face normals in parallel, beside the per-vertex sums of the
        // live faces' cross products and their lengths (added in face order).
        let ((kind, diagonal, min_cross, input_normal), (region_normal, region_area)) = rayon::join(
            || {
                let mut kind: Vec<VertexKind> = (0..n)
                    .into_par_iter()
                    .map_init(
                        || (Vec::new(), Vec::new()),
                        |(ring, targets), v| {
                            let around = lists.get(v as Index);
                            if around.is_empty() {
                                return VertexKind::Isolated;
                            }
                            ring.clear();
                            ring.extend(around.iter().map(|&f| {
                                let face = mesh.faces[f as usize];
                                ring_edge(face, corner_of(face, v as Index))
                            }));
                            match ring_shape(ring, targets) {
                                RingShape::Cycle => VertexKind::Interior,
                                RingShape::Path => VertexKind::Boundary,
                                RingShape::Invalid => VertexKind::Locked,
                            }
                        },
                    )
                    .collect();
                for (face, _) in mesh
                    .faces
                    .iter()
                    .zip(face_state)
                    .filter(|(_, s)| **s == PASSIVE)
                {
                    for &v in face {
                        kind[v as usize] = VertexKind::Locked;
                    }
                }
                let bbox = Aabb::from_points(
                    mesh.positions
                        .iter()
                        .zip(&kind)
                        .filter(|(_, k)| **k != VertexKind::Isolated)
                        .map(|(p, _)| p),
                );
                let diagonal = bbox.diagonal();
                let min_cross = 2.0 * DEGENERATE_AREA * diagonal * diagonal;
                let input_normal: Vec<DVec3> = (0..mesh.n_faces())
                    .into_par_iter()
                    .map(|f| {
                        let n = cross_of(f);
                        if n.length() > min_cross {
                            n.normalize()
                        } else {
                            DVec3::ZERO
                        }
                    })
                    .collect();
                (kind, diagonal, min_cross, input_normal)
            },
            || {
                let mut region_normal = vec![DVec3::ZERO; n];
                let mut region_area = vec![0.0; n];
                for (f, face) in mesh.faces.iter().enumerate() {
                    if face_state[f] == LIVE {
                        let cross = cross_of(f);
                        for &v in face {
                            region_normal[v as usize] += cross;
                            region_area[v as usize] += cross.length();
                        }
                    }
                }
                (region_normal, region_area)
            },
        );
        Derived {
            kind,
            diagonal,
            min_cross,
            input_normal,
            region_normal,
            region_area,
        }
    }

    /// Records from now on what undoing each collapse needs (see [`Progressive`]); off by
    /// default. Calling it again keeps what was recorded.
    pub fn record_progressive(&mut self) {
        if self.history.is_none() {
            self.history = Some(Progressive::new(
                self.pos.len() as u32,
                self.faces.len() as u32,
            ));
        }
    }

    /// The progressive record of every collapse since [`LiveMesh::record_progressive`]
    /// (recording stops), with `coarse`'s [`fingerprint`]; `coarse` should be what
    /// [`LiveMesh::to_mesh`] returned. `None` when nothing was recorded.
    pub fn take_progressive(&mut self, coarse: &Mesh) -> Option<Progressive> {
        let mut h = self.history.take()?;
        // Renumbered vertices that no face uses come last, in input order: the list stays
        // in ascending input order.
        h.isolated = (0..self.pos.len())
            .filter(|&v| self.kind[v] == VertexKind::Isolated)
            .map(|v| (self.original(v as Index), self.pos[v]))
            .collect();
        if self.original_of.is_some() {
            for s in &mut h.steps {
                s.kept = self.original(s.kept);
                s.removed = s.removed.map(|v| self.original(v));
            }
            for d in &mut h.deleted {
                d.corners = d.corners.map(|v| self.original(v));
            }
            for c in &mut h.changed {
                c.vertex = self.original(c.vertex);
            }
        }
        h.coarse = fingerprint(coarse);
        Some(h)
    }

    /// Number of vertex indices (the input's vertex count, merged vertices included, until
    /// a run closes up the arrays): the length for per-vertex arrays of a cost model.
    pub fn vertex_slots(&self) -> usize {
        self.pos.len()
    }

    /// Vertices used by faces (locked ones included).
    pub fn n_vertices(&self) -> usize {
        self.n_vertices
    }

    /// Faces (passive ones, which repeat a vertex, included).
    pub fn n_faces(&self) -> usize {
        self.n_faces
    }

    /// Length of the input's bounding-box diagonal (over vertices used by faces).
    pub fn diagonal(&self) -> f64 {
        self.diagonal
    }

    /// Current position of vertex `v`.
    #[inline]
    pub fn position(&self, v: Index) -> DVec3 {
        self.pos[v as usize]
    }

    /// The vertices of face `f` (current, i.e. after renaming by collapses).
    #[inline]
    pub fn face(&self, f: Index) -> [Index; 3] {
        self.faces[f as usize]
    }

    /// The faces around vertex `v` that take part in collapsing (not passive, not dead).
    #[inline]
    pub fn faces_around(&self, v: Index) -> &[Index] {
        self.lists.get(v)
    }

    /// The faces the last collapse deleted; [`LiveMesh::face`] still gives their corners
    /// as they were before it (for cost models that track data around deleted faces).
    pub fn last_deleted(&self) -> &[Index] {
        &self.last_deleted
    }

    /// The kind of vertex `v`.
    #[inline]
    pub fn kind(&self, v: Index) -> VertexKind {
        self.kind[v as usize]
    }

    /// True until vertex `v` is merged into another.
    #[inline]
    pub fn is_alive(&self, v: Index) -> bool {
        self.alive[v as usize]
    }

    /// The faces taking part in collapsing that are still alive, in input order.
    pub fn live_faces(&self) -> impl Iterator<Item = Index> + '_ {
        (0..self.faces.len() as Index).filter(|&f| self.face_state[f as usize] == LIVE)
    }

    /// True when exactly one face has both `a` and `b`.
    pub fn is_boundary_edge(&self, a: Index, b: Index) -> bool {
        // Every edge at an interior vertex has two faces (its ring is one cycle).
        if self.kind[a as usize] == VertexKind::Interior
            || self.kind[b as usize] == VertexKind::Interior
        {
            return false;
        }
        self.lists.with_corner(a, b, &self.faces).count() == 1
    }

    /// Figures of the current state.
    pub fn summary(&self) -> Summary {
        let mut s = Summary {
            vertices: self.n_vertices,
            faces: self.n_faces,
            ..Default::default()
        };
        for (k, _) in self.kind.iter().zip(&self.alive).filter(|(_, a)| **a) {
            match k {
                VertexKind::Isolated => s.isolated_vertices += 1,
                VertexKind::Boundary => s.boundary_vertices += 1,
                VertexKind::Locked => s.locked_vertices += 1,
                VertexKind::Interior => {}
            }
        }
        let mut boundary: Vec<(Index, Index)> = Vec::new();
        let mut n_edges = 0i64;
        let mut n_live = 0i64;
        for f in self.live_faces() {
            n_live += 1;
            let face = self.faces[f as usize];
            for c in 0..3 {
                let (a, b) = (face[c], face[(c + 1) % 3]);
                let is_boundary = self.is_boundary_edge(a, b);
                if is_boundary {
                    boundary.push((a, b));
                }
                if a < b || is_boundary {
                    n_edges += 1;
                }
            }
        }
        s.boundary_edges = boundary.len();
        s.boundary_loops = count_loops(&mut boundary);
        let used = self
            .kind
            .iter()
            .zip(&self.alive)
            .filter(|(k, a)| **a && **k != VertexKind::Isolated && **k != VertexKind::Locked)
            .count() as i64;
        // Locked vertices count when a live face uses them.
        let locked_used = (0..self.pos.len() as Index)
            .filter(|&v| {
                self.alive[v as usize]
                    && self.kind[v as usize] == VertexKind::Locked
                    && !self.lists.get(v).is_empty()
            })
            .count() as i64;
        s.euler = used + locked_used - n_edges + n_live;
        s
    }

    /// Checks every invariant of the adjacency (lists match faces, kinds match rings,
    /// counts match); for tests and debugging. Says what is broken.
    pub fn check_invariants(&self) -> Result<(), String> {
        let mut ring = Vec::new();
        let mut targets = Vec::new();
        for v in 0..self.pos.len() as Index {
            let around = self.lists.get(v);
            if !self.alive[v as usize] {
                if !around.is_empty() {
                    return Err(format!("dead vertex {v} still has faces {around:?}"));
                }
                continue;
            }
            if !is_finite(self.pos[v as usize]) {
                return Err(format!("vertex {v} is at {}", self.pos[v as usize]));
            }
            for (i, &f) in around.iter().enumerate() {
                if self.face_state[f as usize] != LIVE {
                    return Err(format!("vertex {v} lists face {f}, which is not live"));
                }
                if !self.faces[f as usize].contains(&v) {
                    return Err(format!("vertex {v} lists face {f}, which does not use it"));
                }
                if around[..i].contains(&f) {
                    return Err(format!("vertex {v} lists face {f} twice"));
                }
            }
            let expect = match self.kind[v as usize] {
                VertexKind::Interior => RingShape::Cycle,
                VertexKind::Boundary => RingShape::Path,
                VertexKind::Locked => continue,
                VertexKind::Isolated if around.is_empty() => continue,
                VertexKind::Isolated => return Err(format!("isolated vertex {v} has faces")),
            };
            ring.clear();
            ring.extend(around.iter().map(|&f| {
                let face = self.faces[f as usize];
                ring_edge(face, corner_of(face, v))
            }));
            let got = ring_shape(&mut ring, &mut targets);
            if got != expect {
                return Err(format!(
                    "vertex {v} is {:?} but its faces {around:?} form {got:?}",
                    self.kind[v as usize]
                ));
            }
        }
        let mut n_faces = 0;
        for (f, face) in self.faces.iter().enumerate() {
            match self.face_state[f] {
                DEAD => continue,
                PASSIVE => {
                    if face.iter().any(|&v| !self.alive[v as usize]) {
                        return Err(format!("passive face {f} {face:?} uses a dead vertex"));
                    }
                }
                _ => {
                    let [a, b, c] = *face;
                    if a == b || b == c || a == c {
                        return Err(format!("live face {f} repeats a vertex: {face:?}"));
                    }
                    for &v in face {
                        if !self.alive[v as usize] || !self.lists.get(v).contains(&(f as Index)) {
                            return Err(format!("face {f} {face:?} is not listed by vertex {v}"));
                        }
                    }
                }
            }
            n_faces += 1;
        }
        let n_vertices = (0..self.pos.len())
            .filter(|&v| self.alive[v] && self.kind[v] != VertexKind::Isolated)
            .count();
        if (n_vertices, n_faces) != (self.n_vertices, self.n_faces) {
            return Err(format!(
                "counts say {} vertices and {} faces, arrays hold {n_vertices} and {n_faces}",
                self.n_vertices, self.n_faces
            ));
        }
        Ok(())
    }

    /// The collapsed mesh, compacted, with every attribute of `original` carried.
    ///
    /// `original` must be the mesh this live mesh was built from. Surviving vertices and
    /// faces keep their input order; vertices used by no face are dropped.
    pub fn to_mesh(&self, original: &Mesh) -> Result<(Mesh, CarryReport), CollapseError> {
        if original.n_vertices() != self.input_vertices || original.n_faces() != self.input_faces {
            return Err(CollapseError::MeshMismatch {
                vertices: original.n_vertices(),
                faces: original.n_faces(),
                expected_vertices: self.input_vertices,
                expected_faces: self.input_faces,
            });
        }
        original.validate_indices()?;
        Ok(self.compact(original))
    }

    /// [`LiveMesh::to_mesh`] from the attributes of the mesh this live mesh was built from
    /// alone: `attributes` is that mesh with its positions and faces dropped
    /// ([`attributes_only`]), so that a caller need not hold a second copy of a big input
    /// while collapsing.
    pub fn to_mesh_with_attributes(
        &self,
        attributes: &Mesh,
    ) -> Result<(Mesh, CarryReport), CollapseError> {
        // The first column whose length does not fit, if any.
        let bad_vertices = (attributes.vertex_attrs.iter())
            .map(|(_, a)| a.len())
            .find(|&n| n != self.input_vertices);
        let bad_faces = (attributes.face_attrs.iter())
            .map(|(_, a)| a.len())
            .find(|&n| n != self.input_faces);
        if bad_vertices.is_some() || bad_faces.is_some() {
            return Err(CollapseError::MeshMismatch {
                vertices: bad_vertices.unwrap_or(self.input_vertices),
                faces: bad_faces.unwrap_or(self.input_faces),
                expected_vertices: self.input_vertices,
                expected_faces: self.input_faces,
            });
        }
        Ok(self.compact(attributes))
    }

    /// The vertices the output keeps, in its order (the input's order of the vertices
    /// they were).
    fn survivors(&self) -> Vec<Index> {
        let mut survivors: Vec<Index> = (0..self.pos.len() as Index)
            .filter(|&v| self.alive[v as usize] && self.kind[v as usize] != VertexKind::Isolated)
            .collect();
        if self.original_of.is_some() {
            survivors.sort_unstable_by_key(|&v| self.original(v));
        }
        survivors
    }

    /// The input vertices merged into `v` (itself first), in `members`.
    fn members_into(&self, v: Index, members: &mut Vec<Index>) {
        members.clear();
        let mut m = self.base(v);
        while m != NONE {
            members.push(self.original_of_base(m));
            m = self.cluster_next[m as usize];
        }
    }

    /// The compacted mesh with the attributes of `attributes` (fitting the input) carried.
    fn compact(&self, attributes: &Mesh) -> (Mesh, CarryReport) {
        let survivors = self.survivors();
        let mut new_index = vec![NONE; self.pos.len()];
        let mut positions = Vec::with_capacity(survivors.len());
        // Every input vertex is a source of the survivor it went to.
        let mut vo = VertexOrigins::with_capacities(survivors.len(), self.cluster_next.len());
        let mut members = Vec::new();
        // Each survivor's merged input vertices, kept for the wedges when tracked.
        let mut clusters: Vec<Vec<Index>> = Vec::new();
        for &v in &survivors {
            new_index[v as usize] = positions.len() as Index;
            positions.push(self.pos[v as usize]);
            self.members_into(v, &mut members);
            if members.len() == 1 {
                vo.push_copy(members[0]);
            } else {
                vo.push_blend(members.iter().map(|&m| (m, 1.0)));
            }
            if self.seams.is_some() || self.settle {
                clusters.push(members.clone());
            }
        }
        let mut faces = Vec::with_capacity(self.n_faces);
        let mut slots = Vec::new();
        let mut fo = FaceOrigins::with_capacity(self.n_faces);
        for (f, face) in self.faces.iter().enumerate() {
            if self.face_state[f] != DEAD {
                faces.push(face.map(|v| new_index[v as usize]));
                fo.push_parent(self.base_face.as_ref().map_or(f as Index, |b| b[f]));
                if self.seams.is_some() || self.settle {
                    slots.push(f as Index);
                }
            }
        }
        // Where each moved vertex's values come from, and where it settles.
        let nearest = self.nearest_points(&positions, &clusters);
        if self.settle {
            let settled = self.settle(&mut positions, &faces, &slots, &nearest);
            let _ = self.settled.set(settled);
        }
        match self.output_wedges(&slots, &faces, &positions, &clusters, &nearest) {
            // The wedges are this engine's: the rest is carried as always.
            Some(wedges) => {
                let plain = Mesh {
                    vertex_attrs: attributes.vertex_attrs.clone(),
                    face_attrs: attributes.face_attrs.clone(),
                    materials: attributes.materials.clone(),
                    ..Mesh::default()
                };
                let (mut out, carry) = plain.rebuilt(positions, faces, &vo, &fo);
                out.wedges = wedges;
                (out, carry)
            }
            None => attributes.rebuilt(positions, faces, &vo, &fo),
        }
    }

    /// Collapses until `opts.goal` is met, the next collapse would cost more than
    /// `opts.max_error`, or no candidate is left; `progress` hears the number of collapses
    /// done every few thousand. Vertex and face indices taken before may name other
    /// elements after it (see [`Options::compact_min_faces`]); the log and
    /// [`LiveMesh::to_mesh`] speak the input's.
    pub fn collapse<M: CostModel>(
        &mut self,
        model: &mut M,
        opts: &Options,
        progress: &mut dyn FnMut(usize),
    ) -> Outcome {
        self.collapse_guarded(model, &mut NoGuard, opts, progress)
    }

    /// [`LiveMesh::collapse`] with `guard` as one more check: a collapse is refused (as
    /// `facing`) when a face it reshapes fails the guard. The guard runs last, only on
    /// collapses every other check allows.
    pub fn collapse_guarded<M: CostModel, G: FaceGuard>(
        &mut self,
        model: &mut M,
        guard: &mut G,
        opts: &Options,
        progress: &mut dyn FnMut(usize),
    ) -> Outcome {
        if self.reached(opts.goal) {
            return Outcome::none();
        }
        let mut run = self.start(model, opts);
        run.out.stop = self.resume(&mut run, model, guard, opts, progress);
        run.out
    }

    /// The queue of every candidate, ranked, for [`LiveMesh::resume`].
    fn start<M: CostModel>(&mut self, model: &mut M, opts: &Options) -> Run {
        let unit = model.unit();
        let mut out = Outcome::none();
        let s = Scratch::new(self.pos.len().max(self.faces.len()));
        let per_face = if unit == Unit::Edge { 3 } else { 2 };
        // Room for every candidate: each face's edges count half, a boundary edge whole
        // (and a boundary loop has as many edges as vertices).
        let open = match unit {
            Unit::Edge => self
                .kind
                .par_iter()
                .filter(|&&k| matches!(k, VertexKind::Boundary | VertexKind::Locked))
                .count(),
            Unit::Triangle => 0,
        };
        let mut q = Queue::new(self.pos.len(), self.n_faces * per_face / 2 + open + 16);
        model.prepare(self);
        self.rank_all(model, unit, &mut q, &mut out.refused);
        q.sort_initial();
        if opts.keep_log {
            out.log.reserve(self.remaining(opts.goal));
        }
        Run {
            q,
            s,
            out,
            held: None,
            // A progressive record speaks the numbering of each collapse's time.
            may_close_up: self.history.is_none(),
        }
    }

    /// Collapses in `run`'s queue order until `opts.goal`, `opts.max_error` or the end of
    /// the queue; the candidate that passed the error limit is held for the next call (with
    /// a higher limit, the run goes on as if it had never stopped).
    fn resume<M: CostModel, G: FaceGuard>(
        &mut self,
        run: &mut Run,
        model: &mut M,
        guard: &mut G,
        opts: &Options,
        progress: &mut dyn FnMut(usize),
    ) -> StopReason {
        let mut last = LastFace::default();
        let stop = loop {
            if self.reached(opts.goal) {
                break StopReason::Reached;
            }
            let Some(e) = last.next(run) else {
                break StopReason::Exhausted;
            };
            let (plan, pinned) = match self.vet(e, run, model, guard, opts) {
                Vetted::Skip => continue,
                Vetted::Stop(reason) => break reason,
                Vetted::Go { plan, pinned } => (plan, pinned),
            };
            if last.holds_back(self, e, model.unit(), opts) {
                continue;
            }
            let kept = self.make(&e, &plan, pinned, run, model, opts);
            self.after_collapse(&e, kept, run, model, opts, progress);
            last.release(&mut run.q);
        };
        last.release(&mut run.q);
        stop
    }

    /// Whether the candidate `e` is to be collapsed now and how (its plan, and the vertex
    /// the rules pin), or skipped (stale, refused, dearer than queued: counted, parked or
    /// queued again as each case asks), or ends the run (past the error limit: held).
    #[inline]
    fn vet<M: CostModel, G: FaceGuard>(
        &self,
        e: Entry,
        run: &mut Run,
        model: &M,
        guard: &mut G,
        opts: &Options,
    ) -> Vetted {
        let Run {
            q, s, out, held, ..
        } = run;
        // Stale: a vertex changed or went since the entry was queued; a fresh entry
        // for the same candidate was queued then, if it is still a candidate.
        if !self.is_current(&e) {
            return Vetted::Skip;
        }
        let verts = &e.vertices[..e.vertices().len()];
        let pin = match self.rule(verts) {
            Ok(p) => p,
            Err(r) => {
                out.refused.count(r);
                return Vetted::Skip;
            }
        };
        // Recomputed rather than stored: the same inputs give the same plan, and a
        // queue entry stays small.
        let Some((plan, pinned)) = self.plan_pinned(model, verts, pin) else {
            out.refused.count(Refusal::Model);
            q.park(e, NONE);
            return Vetted::Skip;
        };
        // A candidate outside the model's reach keeps its queued cost when its
        // neighbourhood changes; if it has grown dearer since, it goes back in line
        // at its current cost.
        if plan.cost > e.cost {
            q.push(plan.cost, e.vertices, e.stamp);
            return Vetted::Skip;
        }
        // The queue is ordered by cost: nothing cheaper is left.
        if let Some(max) = opts.max_error
            && plan.cost > max
        {
            *held = Some(e);
            return Vetted::Stop(StopReason::MaxError { cost: plan.cost });
        }
        // Refused candidates wait until a collapse touches one of their vertices (one
        // refused by the link condition, until a collapse merges its witness).
        if let Err(r) = self.check(verts, plan.position, opts.min_quality, s) {
            out.refused.count(r);
            let witness = if r == Refusal::Link { s.witness } else { NONE };
            q.park(e, witness);
            return Vetted::Skip;
        }
        if let Err(r) = self.guard(guard, verts, plan.position, s) {
            out.refused.count(r);
            q.park(e, NONE);
            return Vetted::Skip;
        }
        if self.seams.is_some() && self.folds_uvs(verts, self.kept_of(verts, pinned), plan.position)
        {
            out.refused.count(Refusal::Seam);
            q.park(e, NONE);
            return Vetted::Skip;
        }
        Vetted::Go { plan, pinned }
    }

    /// Makes the collapse of `e` at `plan` and records it (the squared volume error, the
    /// log, the run's figures); returns the vertex kept.
    #[inline]
    fn make<M: CostModel>(
        &mut self,
        e: &Entry,
        plan: &Plan,
        pinned: Option<Index>,
        run: &mut Run,
        model: &mut M,
        opts: &Options,
    ) -> Index {
        let out = &mut run.out;
        let verts = &e.vertices[..e.vertices().len()];
        let sve = self.sve(verts, plan.position);
        if opts.weighted_sve {
            out.sve_weighted += crate::weighted_sve(self, verts, plan.position);
        }
        let kept = self.kept_of(verts, pinned);
        let moved = self.moved_uv(verts, kept, plan.position);
        self.merge(verts, kept, plan.position, &mut run.s);
        self.carry_wedges(verts, kept, moved);
        model.merged(self, kept, verts);
        let mut removed = [NONE; 2];
        for (slot, &v) in removed.iter_mut().zip(verts.iter().filter(|&&v| v != kept)) {
            *slot = v;
        }
        if opts.keep_log {
            out.log.push(CollapseRecord {
                kept: self.original(kept),
                removed: removed.map(|v| self.original(v)),
                position: plan.position,
                cost: plan.cost,
                sve,
            });
        }
        out.collapses += 1;
        out.sve += sve;
        out.sve_max = out.sve_max.max(sve);
        out.max_cost = out.max_cost.max(plan.cost);
        out.costs.push(plan.cost);
        kept
    }

    /// After the collapse of `e` into `kept`: the candidates around it queued again, stale
    /// entries swept, the arrays closed up when half the faces are gone, progress told.
    #[inline]
    fn after_collapse<M: CostModel>(
        &mut self,
        e: &Entry,
        kept: Index,
        run: &mut Run,
        model: &mut M,
        opts: &Options,
        progress: &mut dyn FnMut(usize),
    ) {
        let verts = &e.vertices[..e.vertices().len()];
        let unit = model.unit();
        let per_face = if unit == Unit::Edge { 3 } else { 2 };
        let Run {
            q,
            s,
            out,
            may_close_up,
            ..
        } = run;
        self.requeue(
            model,
            unit,
            model.reach(),
            kept,
            verts,
            q,
            s,
            &mut out.refused,
        );
        let live_estimate = self.n_faces * per_face / 2;
        q.sweep_if_stale(live_estimate, |e| self.is_current(e));
        if *may_close_up
            && self.faces.len() >= opts.compact_min_faces
            && 2 * self.n_faces < self.faces.len()
            && !self.reached(opts.goal)
        {
            *may_close_up = self.close_up(model, q);
        }
        if out.collapses.is_multiple_of(PROGRESS_EVERY) {
            progress(out.collapses);
        }
    }

    /// Renumbers the live vertices and faces densely, in their order, with the queue and
    /// `model` (crate docs, *Memory order*); false, changing nothing, when the model
    /// cannot follow.
    fn close_up<M: CostModel>(&mut self, model: &mut M, q: &mut Queue) -> bool {
        let Some(r) = self.keep_live(model) else {
            return false;
        };
        self.lists = self.lists.renumbered(&r.old_vertex, &r.new_face);
        q.renumber(&r.new_vertex, |e| self.is_current(e));
        true
    }

    /// After the parts' results were written in (see `collapse_in_parts`): closes up the
    /// arrays when `model` can follow, and builds the vertex → faces lists afresh.
    fn rebuild_closed_up<M: CostModel>(&mut self, model: &mut M) {
        let _ = self.keep_live(model);
        let use_face: Vec<bool> = self.face_state.iter().map(|&s| s == LIVE).collect();
        self.lists = FaceLists::build(self.pos.len(), &self.faces, &use_face);
    }

    /// Keeps the live vertices and faces, renumbered densely in their order, with `model`
    /// (the vertex → faces lists excepted); `None`, changing nothing, when the model cannot
    /// follow.
    fn keep_live<M: CostModel>(&mut self, model: &mut M) -> Option<Renaming> {
        let mut new_vertex = vec![NONE; self.pos.len()];
        let mut old_vertex: Vec<Index> = Vec::with_capacity(self.n_vertices + 1);
        for (v, &alive) in self.alive.iter().enumerate() {
            if alive {
                new_vertex[v] = old_vertex.len() as Index;
                old_vertex.push(v as Index);
            }
        }
        let mut new_face = vec![NONE; self.faces.len()];
        let mut old_face: Vec<Index> = Vec::with_capacity(self.n_faces + 1);
        for (f, &state) in self.face_state.iter().enumerate() {
            if state != DEAD {
                new_face[f] = old_face.len() as Index;
                old_face.push(f as Index);
            }
        }
        if !model.renumber(&old_vertex, &old_face) {
            return None;
        }
        match &mut self.base_vertex {
            Some(b) => keep_in_order(b, &old_vertex),
            None => self.base_vertex = Some(old_vertex.clone()),
        }
        match &mut self.base_face {
            Some(b) => keep_in_order(b, &old_face),
            None => self.base_face = Some(old_face.clone()),
        }
        // In place: the arrays are already resident, and nothing new is allocated.
        keep_in_order(&mut self.pos, &old_vertex);
        keep_in_order(&mut self.kind, &old_vertex);
        keep_in_order(&mut self.alive, &old_vertex);
        keep_in_order(&mut self.stamp, &old_vertex);
        keep_in_order(&mut self.cluster_tail, &old_vertex);
        keep_in_order(&mut self.region_normal, &old_vertex);
        keep_in_order(&mut self.region_area, &old_vertex);
        keep_in_order(&mut self.faces, &old_face);
        for face in &mut self.faces {
            *face = face.map(|v| new_vertex[v as usize]);
        }
        keep_in_order(&mut self.face_state, &old_face);
        keep_in_order(&mut self.input_normal, &old_face);
        if let Some(seams) = &mut self.seams {
            keep_in_order(&mut seams.class, &old_vertex);
            keep_in_order(&mut seams.wedge, &old_face);
        }
        self.last_deleted.clear();
        Some(Renaming {
            old_vertex,
            new_vertex,
            new_face,
        })
    }

    fn reached(&self, goal: Goal) -> bool {
        match goal {
            Goal::Vertices(n) => self.n_vertices <= n,
            Goal::Faces(n) => self.n_faces <= n,
        }
    }

    /// About how many collapses are left before the goal.
    fn remaining(&self, goal: Goal) -> usize {
        match goal {
            Goal::Vertices(n) => self.n_vertices.saturating_sub(n),
            Goal::Faces(n) => self.n_faces.saturating_sub(n) / 2,
        }
    }

    #[inline]
    fn stamp_sum(&self, verts: &[Index]) -> u32 {
        verts
            .iter()
            .fold(0u32, |s, &v| s.wrapping_add(self.stamp[v as usize]))
    }

    /// True while every vertex of `e` is alive and unchanged since `e` was queued (a
    /// vertex's stamp also grows when it is merged away, so the stamps alone tell).
    #[inline]
    fn is_current(&self, e: &Entry) -> bool {
        self.stamp_sum(e.vertices()) == e.stamp
    }

    /// The vertex a merge of `verts` keeps: the pinned one, else a boundary vertex when
    /// there is one (so that kinds stay true), else the first.
    #[inline]
    fn kept_of(&self, verts: &[Index], pinned: Option<Index>) -> Index {
        pinned
            .or_else(|| {
                verts
                    .iter()
                    .copied()
                    .find(|&v| self.kind[v as usize] == VertexKind::Boundary)
            })
            .unwrap_or(verts[0])
    }

    /// The rules of the vertex kinds (crate docs' table) and of the seams (when tracked,
    /// `seams.rs`): where the result is pinned, or why the merge is not allowed.
    fn rule(&self, verts: &[Index]) -> Result<seams::Pin, Refusal> {
        let pinned = self.boundary_rule(verts)?;
        let pin = self.seam_rule(verts, pinned)?;
        Ok(match (pin, verts) {
            (seams::Pin::Free, &[a, b]) if self.subset => seams::Pin::Either(a, b),
            (pin, _) => pin,
        })
    }

    /// The model's plan under `pin`, and the vertex it keeps in place (of two allowed,
    /// the cheaper; the first on a tie).
    fn plan_pinned<M: CostModel>(
        &self,
        model: &M,
        verts: &[Index],
        pin: seams::Pin,
    ) -> Option<(Plan, Option<Index>)> {
        match pin {
            seams::Pin::Free => Some((self.plan(model, verts, None)?, None)),
            seams::Pin::At(v) => Some((self.plan(model, verts, Some(v))?, Some(v))),
            seams::Pin::Either(a, b) => {
                let at_a = self.plan(model, verts, Some(a)).map(|p| (p, Some(a)));
                let at_b = self.plan(model, verts, Some(b)).map(|p| (p, Some(b)));
                match (at_a, at_b) {
                    (Some(x), Some(y)) => Some(if y.0.cost < x.0.cost { y } else { x }),
                    (x, y) => x.or(y),
                }
            }
        }
    }

    /// The rules of the vertex kinds (crate docs' table): the vertex the result is pinned
    /// to, if any, or why the merge is not allowed.
    fn boundary_rule(&self, verts: &[Index]) -> Result<Option<Index>, Refusal> {
        let mut boundary = [NONE; 3];
        let mut nb = 0;
        for &v in verts {
            match self.kind[v as usize] {
                VertexKind::Interior => {}
                VertexKind::Boundary => {
                    boundary[nb] = v;
                    nb += 1;
                }
                VertexKind::Locked | VertexKind::Isolated => return Err(Refusal::Locked),
            }
        }
        match nb {
            0 => Ok(None),
            1 => Ok(Some(boundary[0])),
            2 if self.is_boundary_edge(boundary[0], boundary[1]) => Ok(None),
            _ => Err(Refusal::Boundary),
        }
    }

    /// The model's plan, with non-finite answers refused and costs of zero or less made +0.
    fn plan<M: CostModel>(
        &self,
        model: &M,
        verts: &[Index],
        pinned: Option<Index>,
    ) -> Option<Plan> {
        let mut plan = model.plan(
            self,
            &Merge {
                vertices: verts,
                pinned,
            },
        )?;
        if !is_finite(plan.position) || !plan.cost.is_finite() {
            return None;
        }
        if plan.cost <= 0.0 {
            plan.cost = 0.0;
        }
        Some(plan)
    }

    /// Costs one candidate and queues it, or counts why it cannot be.
    fn propose<M: CostModel>(
        &self,
        model: &M,
        verts: &[Index],
        q: &mut Queue,
        refused: &mut Refusals,
    ) {
        match self.rank(model, verts) {
            Ranked::Queue {
                cost,
                vertices,
                stamp,
            } => q.push(cost, vertices, stamp),
            Ranked::Refused(r) => refused.count(r),
        }
    }

    /// Queues every candidate: each edge once (from the face using it as `a → b` with
    /// `a < b`, or from its only face), or each face.
    ///
    /// The candidates are costed on rayon's threads, a piece of faces at a time, each
    /// piece's entries gathered on its thread and appended in piece order (a round of
    /// pieces while the next round is costed). A candidate's
    /// sequence number is its slot (face, then edge of the face) in a range taken for the
    /// whole ranking, so the numbers keep the order a single thread would queue them in:
    /// the queue does not depend on the thread count.
    fn rank_all<M: CostModel>(&self, model: &M, unit: Unit, q: &mut Queue, refused: &mut Refusals) {
        /// Faces per piece.
        const PIECE: usize = 1 << 12;
        /// Pieces per round: bounds the memory the gathered entries take.
        const ROUND: usize = 16;
        let n = self.faces.len();
        let slots = match unit {
            Unit::Edge => 3,
            Unit::Triangle => 1,
        };
        let base = q.take_seqs((n * slots) as u64);
        let pieces = n.div_ceil(PIECE);
        // A round's entries go into the queue, in piece order, while the next round ranks.
        let mut ranked: Vec<(Vec<Entry>, Refusals)> = Vec::new();
        let mut queue_them = |ranked: &[(Vec<Entry>, Refusals)]| {
            for (entries, counts) in ranked {
                q.extend_initial(entries);
                refused.add(counts);
            }
        };
        for first in (0..pieces).step_by(ROUND) {
            let rank_round = || -> Vec<(Vec<Entry>, Refusals)> {
                (first..(first + ROUND).min(pieces))
                    .into_par_iter()
                    .map(|k| {
                        let (mut entries, mut counts) = (Vec::new(), Refusals::default());
                        for f in k * PIECE..((k + 1) * PIECE).min(n) {
                            if self.face_state[f] != LIVE {
                                continue;
                            }
                            let face = self.faces[f];
                            let mut rank =
                                |slot: usize, verts: &[Index]| match self.rank(model, verts) {
                                    Ranked::Queue {
                                        cost,
                                        vertices,
                                        stamp,
                                    } => entries.push(Entry {
                                        cost,
                                        seq: base + (f * slots + slot) as u64,
                                        vertices,
                                        stamp,
                                    }),
                                    Ranked::Refused(r) => counts.count(r),
                                };
                            match unit {
                                Unit::Edge => {
                                    for c in 0..3 {
                                        let (a, b) = (face[c], face[(c + 1) % 3]);
                                        if a < b || self.is_boundary_edge(a, b) {
                                            rank(c, &[a.min(b), a.max(b)]);
                                        }
                                    }
                                }
                                Unit::Triangle => rank(0, &face),
                            }
                        }
                        (entries, counts)
                    })
                    .collect()
            };
            ranked = rayon::join(|| queue_them(&ranked), rank_round).1;
        }
        queue_them(&ranked);
    }

    /// What to do with a candidate: queue it at its cost, or count why not.
    fn rank<M: CostModel>(&self, model: &M, verts: &[Index]) -> Ranked {
        let pin = match self.rule(verts) {
            Ok(p) => p,
            Err(r) => return Ranked::Refused(r),
        };
        match self.plan_pinned(model, verts, pin) {
            Some((plan, _)) => {
                let mut v = [NONE; 3];
                v[..verts.len()].copy_from_slice(verts);
                Ranked::Queue {
                    cost: plan.cost,
                    vertices: v,
                    stamp: self.stamp_sum(verts),
                }
            }
            None => Ranked::Refused(Refusal::Model),
        }
    }

    /// Validity checks of merging `verts` at `p` (crate docs, "Checks").
    fn check(
        &self,
        verts: &[Index],
        p: DVec3,
        min_quality: f64,
        s: &mut Scratch,
    ) -> Result<(), Refusal> {
        self.gather_ring(verts, s);
        // Degenerate faces first: the commonest refusal, and cheaper than the link test
        // (the verdict is the same in any order; only the reason counted can differ).
        s.crosses.clear();
        for &(f, c) in &s.kept_faces {
            let old = self.faces[f as usize].map(|v| self.pos[v as usize]);
            let mut new = old;
            new[c] = p;
            let n_old = triangle::cross(old[0], old[1], old[2]);
            let n_new = triangle::cross(new[0], new[1], new[2]);
            let was_degenerate = n_old.length() <= self.min_cross;
            if !was_degenerate && n_new.length() <= self.min_cross {
                return Err(Refusal::Degenerate);
            }
            s.crosses.push((n_old, n_new, was_degenerate));
        }
        if let Err(witness) = self.link(verts, s) {
            s.witness = witness;
            return Err(Refusal::Link);
        }
        let merged_normal: DVec3 = verts.iter().map(|&v| self.region_normal[v as usize]).sum();
        let merged_area: f64 = verts.iter().map(|&v| self.region_area[v as usize]).sum();
        for (&(f, c), &(n_old, n_new, was_degenerate)) in s.kept_faces.iter().zip(&s.crosses) {
            if !was_degenerate {
                // The normal turns by 90° or more from now, or 60° or more from the input
                // face's (so that faces cannot drift over many collapses).
                if n_old.dot(n_new) <= 0.0
                    || self.input_normal[f as usize].dot(n_new) <= DRIFT_COS * n_new.length()
                {
                    return Err(Refusal::Flip);
                }
                // Nor may it turn to face away from the input surface merged into any
                // corner (a face of a noisy input that already did is left alone).
                let face = self.faces[f as usize];
                for (k, &v) in face.iter().enumerate() {
                    let own = self.region_normal[v as usize];
                    let (region, area) = if k == c {
                        (merged_normal, merged_area)
                    } else {
                        (own, self.region_area[v as usize])
                    };
                    if region.dot(n_new) < 0.0
                        && own.dot(n_old) >= 0.0
                        && region.length() >= REGION_COHERENCE * area
                    {
                        return Err(Refusal::Flip);
                    }
                }
            }
            if min_quality > 0.0 {
                let old = self.faces[f as usize].map(|v| self.pos[v as usize]);
                let mut new = old;
                new[c] = p;
                let q_new = triangle::quality(new[0], new[1], new[2]);
                if q_new < min_quality && q_new < triangle::quality(old[0], old[1], old[2]) {
                    return Err(Refusal::Quality);
                }
            }
        }
        Ok(())
    }

    /// The faces around `verts` that survive merging them (`s.kept_faces`, with the corner
    /// that moves) and their ring edges (`s.ring`).
    fn gather_ring(&self, verts: &[Index], s: &mut Scratch) {
        s.ring.clear();
        s.kept_faces.clear();
        for &v in verts {
            for &f in self.lists.get(v) {
                let face = self.faces[f as usize];
                if face.iter().filter(|u| verts.contains(u)).count() >= 2 {
                    continue;
                }
                let c = corner_of(face, v);
                s.ring.push(ring_edge(face, c));
                s.kept_faces.push((f, c));
            }
        }
    }

    /// The link condition on the ring [`LiveMesh::gather_ring`] gathered for `verts`: one
    /// cycle (one path on the boundary), else the witness, a ring vertex that two ring
    /// edges leave or enter ([`NONE`] when the ring fails otherwise).
    ///
    /// A collapse that merges none of `verts` and not the witness leaves the witness's
    /// ring edges as they were (it renames other ring vertices and removes only edges
    /// between two merged ones), so the refusal stands until one does.
    fn link(&self, verts: &[Index], s: &mut Scratch) -> Result<(), Index> {
        let on_boundary = verts
            .iter()
            .any(|&v| self.kind[v as usize] == VertexKind::Boundary);
        match (ring_shape(&mut s.ring, &mut s.targets), on_boundary) {
            (RingShape::Cycle, false) | (RingShape::Path, true) => Ok(()),
            _ => Err(repeated_end(&s.ring, &mut s.targets).unwrap_or(NONE)),
        }
    }

    /// The guard's verdict on the faces [`LiveMesh::check`] just passed (in `s.kept_faces`)
    /// with their moved corner at `p`; faces that were degenerate are not asked.
    fn guard<G: FaceGuard>(
        &self,
        guard: &mut G,
        verts: &[Index],
        p: DVec3,
        s: &Scratch,
    ) -> Result<(), Refusal> {
        let coherence = |normal: DVec3, area: f64| {
            if area > 0.0 {
                normal.length() / area
            } else {
                1.0
            }
        };
        let merged_normal: DVec3 = verts.iter().map(|&v| self.region_normal[v as usize]).sum();
        let merged_area: f64 = verts.iter().map(|&v| self.region_area[v as usize]).sum();
        let merged = coherence(merged_normal, merged_area);
        for &(f, c) in &s.kept_faces {
            let face = self.faces[f as usize];
            let old = face.map(|v| self.pos[v as usize]);
            if triangle::cross(old[0], old[1], old[2]).length() <= self.min_cross {
                continue;
            }
            let mut new = old;
            new[c] = p;
            let mut least = merged;
            let (mut normal, mut area) = (merged_normal, merged_area);
            for (k, &v) in face.iter().enumerate() {
                if k != c {
                    let v = v as usize;
                    least = least.min(coherence(self.region_normal[v], self.region_area[v]));
                    normal += self.region_normal[v];
                    area += self.region_area[v];
                }
            }
            least = least.min(coherence(normal, area));
            let r = Reshape {
                old,
                new,
                coherence: least,
            };
            if !guard.allows(&r) {
                return Err(Refusal::Facing);
            }
        }
        Ok(())
    }

    /// Paper 2's squared-volume error of moving the faces around `verts` to `p`:
    /// Σ (Sᵢ/3 · (nᵢ·p + dᵢ))² over those faces, each counted once.
    fn sve(&self, verts: &[Index], p: DVec3) -> f64 {
        let mut sum = 0.0;
        for (i, &v) in verts.iter().enumerate() {
            for &f in self.lists.get(v) {
                let face = self.faces[f as usize];
                if verts[..i].iter().any(|u| face.contains(u)) {
                    continue;
                }
                let [a, b, c] = face.map(|u| self.pos[u as usize]);
                let cross = triangle::cross(a, b, c);
                // (S/3)·(n·(p − a)) with n = cross/|cross| and S = |cross|/2.
                let volume = cross.dot(p - a) / 6.0;
                sum += volume * volume;
            }
        }
        sum
    }

    /// Merges `verts` into `kept` at `p`: faces with two or more of them die, the others
    /// are renamed; lists, counts, stamps and clusters follow.
    fn merge(&mut self, verts: &[Index], kept: Index, p: DVec3, s: &mut Scratch) {
        s.list.clear();
        self.last_deleted.clear();
        let mut step = Step {
            kept,
            removed: [NONE; 2],
            deleted: 0,
            changed: 0,
        };
        if let Some(h) = &mut self.history {
            h.positions.push(self.pos[kept as usize]);
            for (slot, &v) in step
                .removed
                .iter_mut()
                .zip(verts.iter().filter(|&&v| v != kept))
            {
                *slot = v;
                h.positions.push(self.pos[v as usize]);
            }
        }
        for &v in verts {
            s.around.clear();
            s.around.extend_from_slice(self.lists.get(v));
            for &f in &s.around {
                let fi = f as usize;
                if self.face_state[fi] != LIVE {
                    continue;
                }
                let face = self.faces[fi];
                if face.iter().filter(|u| verts.contains(u)).count() >= 2 {
                    if let Some(h) = &mut self.history {
                        h.deleted.push(DeletedFace {
                            face: f,
                            corners: face,
                        });
                        step.deleted += 1;
                    }
                    self.face_state[fi] = DEAD;
                    self.last_deleted.push(f);
                    self.n_faces -= 1;
                    for &u in face.iter().filter(|u| !verts.contains(u)) {
                        self.lists.remove(u, f);
                    }
                    continue;
                }
                if v != kept
                    && let Some(h) = &mut self.history
                {
                    h.changed.push(ChangedFace { face: f, vertex: v });
                    step.changed += 1;
                }
                self.faces[fi][corner_of(face, v)] = kept;
                s.list.push(f);
            }
        }
        if let Some(h) = &mut self.history {
            h.steps.push(step);
        }
        for &v in verts.iter().filter(|&&v| v != kept) {
            self.lists.clear(v);
            self.alive[v as usize] = false;
            self.stamp[v as usize] = self.stamp[v as usize].wrapping_add(1);
            self.n_vertices -= 1;
            let tail = self.cluster_tail[kept as usize] as usize;
            self.cluster_next[tail] = self.base(v);
            self.cluster_tail[kept as usize] = self.cluster_tail[v as usize];
        }
        debug_assert!(
            self.kind[kept as usize] == VertexKind::Boundary
                || verts
                    .iter()
                    .all(|&v| self.kind[v as usize] == VertexKind::Interior)
        );
        let region: DVec3 = verts.iter().map(|&v| self.region_normal[v as usize]).sum();
        self.region_normal[kept as usize] = region;
        self.region_area[kept as usize] = verts.iter().map(|&v| self.region_area[v as usize]).sum();
        self.lists.set(kept, &s.list);
        self.pos[kept as usize] = p;
        self.stamp[kept as usize] = self.stamp[kept as usize].wrapping_add(1);
    }

    /// After a collapse of `merged` into `kept`: re-costs the candidates it made stale and
    /// re-queues the refused candidates around it that it may have made valid.
    #[allow(clippy::too_many_arguments)]
    fn requeue<M: CostModel>(
        &mut self,
        model: &M,
        unit: Unit,
        reach: Reach,
        kept: Index,
        merged: &[Index],
        q: &mut Queue,
        s: &mut Scratch,
        refused: &mut Refusals,
    ) {
        // `kept` and its neighbours: every vertex whose faces changed.
        s.touched.clear();
        s.in_touched.clear();
        s.in_touched.insert(kept);
        s.touched.push(kept);
        for &f in self.lists.get(kept) {
            for &u in &self.faces[f as usize] {
                if s.in_touched.insert(u) {
                    s.touched.push(u);
                }
            }
        }
        if reach == Reach::TwoRings {
            // The neighbours' neighbours too.
            let ring = s.touched.len();
            for i in 1..ring {
                let u = s.touched[i];
                for &f in self.lists.get(u) {
                    for &w in &self.faces[f as usize] {
                        if s.in_touched.insert(w) {
                            s.touched.push(w);
                        }
                    }
                }
            }
        }
        if reach != Reach::Kept {
            for &u in &s.touched[1..] {
                self.stamp[u as usize] = self.stamp[u as usize].wrapping_add(1);
            }
        }
        let centres = match reach {
            Reach::Kept => 1,
            Reach::Ring | Reach::TwoRings => s.touched.len(),
        };
        s.seen.clear();
        for i in 0..centres {
            let v = s.touched[i];
            match unit {
                Unit::Edge => {
                    // Each neighbour of each centre once; an edge joining two centres
                    // from its smaller end only.
                    s.seen.clear();
                    for &f in self.lists.get(v) {
                        for &u in &self.faces[f as usize] {
                            if u == v || !s.seen.insert(u) {
                                continue;
                            }
                            if reach != Reach::Kept && s.in_touched.contains(u) && u < v {
                                continue;
                            }
                            self.propose(model, &[v.min(u), v.max(u)], q, refused);
                        }
                    }
                }
                Unit::Triangle => {
                    for &f in self.lists.get(v) {
                        if s.seen.insert(f) {
                            self.propose(model, &self.faces[f as usize], q, refused);
                        }
                    }
                }
            }
        }
        // By index: the decision borrows the scratch (its debug check gathers rings in it).
        for i in 0..s.touched.len() {
            q.release(s.touched[i], |e, witness| {
                if !self.is_current(e) {
                    Fate::Drop
                } else if witness != NONE && !merged.contains(&witness) {
                    // Still refused (see `link`): checked in debug builds.
                    debug_assert!({
                        self.gather_ring(e.vertices(), s);
                        self.link(e.vertices(), s).is_err()
                    });
                    #[cfg(test)]
                    tests::KEPT_PARKED.with(|k| k.set(k.get() + 1));
                    Fate::Keep
                } else {
                    Fate::Requeue
                }
            });
        }
    }
}

/// Counts the closed chains of the boundary half-edges `edges` (sorted in place).
fn count_loops(edges: &mut [(Index, Index)]) -> usize {
    edges.sort_unstable();
    let mut used = vec![false; edges.len()];
    let mut loops = 0;
    for i in 0..edges.len() {
        if used[i] {
            continue;
        }
        loops += 1;
        let mut at = i;
        loop {
            used[at] = true;
            let next = edges[at].1;
            let from = edges.partition_point(|e| e.0 < next);
            match (from..edges.len())
                .take_while(|&j| edges[j].0 == next)
                .find(|&j| !used[j])
            {
                Some(j) => at = j,
                None => break,
            }
        }
    }
    loops
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::*;
    use crate::{QemOptions, QuadricModel};
    use coarsen_mesh::{AttrValues, Mesh};

    /// The unit octahedron's corners: +x, +y, −x, −y, +z, −z.
    const OCTAHEDRON: [DVec3; 6] = [
        DVec3::X,
        DVec3::Y,
        DVec3::NEG_X,
        DVec3::NEG_Y,
        DVec3::Z,
        DVec3::NEG_Z,
    ];

    /// An octahedron's faces, outward, given the indices of its +x, +y, −x, −y, +z and −z
    /// corners.
    fn octahedron_faces(
        x: Index,
        y: Index,
        mx: Index,
        my: Index,
        z: Index,
        mz: Index,
    ) -> Vec<[Index; 3]> {
        vec![
            [x, y, z],
            [y, mx, z],
            [mx, my, z],
            [my, x, z],
            [y, x, mz],
            [mx, y, mz],
            [my, mx, mz],
            [x, my, mz],
        ]
    }

    fn run<M: CostModel>(mesh: &Mesh, model: &mut M, goal: Goal) -> (Mesh, Outcome, LiveMesh) {
        let mut live = LiveMesh::new(mesh).unwrap();
        let outcome = live.collapse(model, &Options::new(goal), &mut |_| {});
        live.check_invariants().unwrap();
        let (out, carry) = live.to_mesh(mesh).unwrap();
        assert!(carry.dropped.is_empty());
        (out, outcome, live)
    }

    fn qem(mesh: &Mesh, goal: Goal) -> (Mesh, Outcome) {
        let live = LiveMesh::new(mesh).unwrap();
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let (out, outcome, _) = run(mesh, &mut model, goal);
        (out, outcome)
    }

    fn bump(x: f64, y: f64) -> f64 {
        0.2 * (std::f64::consts::PI * x).sin() * (std::f64::consts::PI * y).sin()
    }

    /// Locked vertices (as a stage keeps sharp corners) survive a collapse to a few
    /// vertices where they are, renumbered or not; without the lock the same run merges
    /// some of them away.
    #[test]
    fn locked_vertices_stay_where_they_are() {
        let mesh = grid(12, 12, bump);
        // A few interior vertices and a boundary one, in the input's numbering.
        let keep: Vec<Index> = vec![14, 40, 84, 90, 6];
        let kept = |out: &Mesh| {
            keep.iter()
                .filter(|&&v| out.positions.contains(&mesh.positions[v as usize]))
                .count()
        };
        for renumbered in [false, true] {
            let mut live = match renumbered {
                false => LiveMesh::new(&mesh),
                true => LiveMesh::new_renumbered(&mesh),
            }
            .unwrap();
            assert_eq!(live.lock(&keep), keep.len());
            // Locking again, out of range: nothing new.
            assert_eq!(live.lock(&[14, 1_000_000]), 0);
            let mut model = QuadricModel::new(&live, &QemOptions::default());
            live.collapse(&mut model, &Options::new(Goal::Vertices(20)), &mut |_| {});
            live.check_invariants().unwrap();
            let (out, _) = live.to_mesh(&mesh).unwrap();
            assert_eq!(out.n_vertices(), 20);
            assert_eq!(kept(&out), keep.len(), "renumbered {renumbered}");
        }
        let (free, _) = qem(&mesh, Goal::Vertices(20));
        assert!(kept(&free) < keep.len());
    }

    #[test]
    fn last_deleted_names_the_faces_the_last_collapse_removed() {
        let faces = octahedron_faces(0, 1, 2, 3, 4, 5);
        let mesh = Mesh::new(OCTAHEDRON.to_vec(), faces.clone());
        let mut live = LiveMesh::new(&mesh).unwrap();
        assert!(live.last_deleted().is_empty());
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let out = live.collapse(&mut model, &Options::new(Goal::Vertices(5)), &mut |_| {});
        let r = out.log[0];
        let mut gone = live.last_deleted().to_vec();
        gone.sort_unstable();
        // The two faces of the collapsed edge, with their corners as they were.
        let expected: Vec<Index> = (0..8)
            .filter(|&f| {
                faces[f as usize].contains(&r.kept) && faces[f as usize].contains(&r.removed[0])
            })
            .collect();
        assert_eq!(gone, expected);
        for &f in &gone {
            assert_eq!(live.face(f), faces[f as usize]);
            assert!(!live.live_faces().any(|g| g == f));
        }
    }

    #[test]
    fn link_condition_refuses_to_pinch_a_tetrahedron() {
        // Any edge collapse of a tetrahedron leaves two faces on the same three vertices.
        let mesh = tetrahedron();
        let (out, outcome, _) = run(&mesh, &mut shortest_edge(), Goal::Vertices(3));
        assert_eq!(outcome.stop, StopReason::Exhausted);
        assert_eq!(outcome.collapses, 0);
        assert_eq!(outcome.refused.link, 6);
        assert_eq!(out, mesh);
    }

    #[test]
    fn link_condition_refuses_a_hidden_cycle() {
        //        3 (north)
        //      / | \
        //     0--1--2--0    equator: a cycle of edges that bounds no face
        //      \ | /
        //        4 (south)
        // Collapsing an equator edge (0,1) would merge the two edges to 2 into one edge
        // with four faces; collapsing 3 onto the equator leaves a tetrahedron.
        let h = 3f64.sqrt() / 2.0;
        let mesh = Mesh::new(
            vec![
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(-0.5, h, 0.0),
                DVec3::new(-0.5, -h, 0.0),
                DVec3::Z,
                -DVec3::Z,
            ],
            vec![
                [0, 1, 3],
                [1, 2, 3],
                [2, 0, 3],
                [1, 0, 4],
                [2, 1, 4],
                [0, 2, 4],
            ],
        );
        let equator_first = Scripted {
            unit: Unit::Edge,
            reach: Reach::Kept,
            cost: |_: &LiveMesh, v: &[Index]| if v[1] < 3 { 0.0 } else { 1.0 },
        };
        let mut model = equator_first;
        let (out, outcome, _) = run(&mesh, &mut model, Goal::Vertices(4));
        assert_eq!(outcome.collapses, 1);
        assert!(outcome.refused.link >= 3, "{:?}", outcome.refused);
        let r = outcome.log[0];
        assert_eq!(
            (r.kept, r.removed),
            (1, [3, NONE]),
            "first apex edge in queue order"
        );
        assert_eq!((out.n_vertices(), out.n_faces()), (4, 4));
        assert_eq!(assert_closed_manifold(&out).euler, 2);
    }

    #[test]
    fn flip_check_refuses_moving_a_vertex_across_its_ring() {
        //            3
        //          / | \
        //        /   |  2      0 is interior, 1..5 are on the boundary.
        //      4 --- 0 ---- 1  Moving 0 onto 3 would turn face (0,1,2) over:
        //        \   |   /     its new corner 3 lies beyond the line 1–2.
        //            5
        let mesh = Mesh::new(
            vec![
                DVec3::ZERO,
                DVec3::new(2.0, 0.0, 0.0),
                DVec3::new(0.2, 0.2, 0.0),
                DVec3::new(0.0, 2.0, 0.0),
                DVec3::new(-1.0, 0.0, 0.0),
                DVec3::new(0.0, -1.0, 0.0),
            ],
            vec![[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5], [0, 5, 1]],
        );
        let mut model = Scripted {
            unit: Unit::Edge,
            reach: Reach::Kept,
            cost: |_: &LiveMesh, v: &[Index]| if v == [0, 3] { 0.0 } else { 1.0 },
        };
        let (out, outcome, _) = run(&mesh, &mut model, Goal::Vertices(5));
        // Edge 0–3 comes first and is refused; then, all costs being equal, edge 0–1 (first
        // in queue order), refused too: moving 0 onto 1 turns (0,2,3) over. Then 1–2 goes.
        assert_eq!(outcome.refused.flip, 2);
        assert_eq!(outcome.collapses, 1);
        assert_eq!((outcome.log[0].kept, outcome.log[0].removed[0]), (1, 2));
        for f in 0..out.n_faces() {
            assert!(out.face_normal(f).z > 0.0, "face {f} flipped");
        }
    }

    /// Collapses edge 12–13 of a flat 5 × 5 grid to a point `height` above its middle.
    struct Lift {
        height: f64,
    }

    impl CostModel for Lift {
        fn unit(&self) -> Unit {
            Unit::Edge
        }
        fn reach(&self) -> Reach {
            Reach::Kept
        }
        fn plan(&self, mesh: &LiveMesh, merge: &Merge<'_>) -> Option<Plan> {
            let [a, b] = [merge.vertices[0], merge.vertices[1]];
            let mid = (mesh.position(a) + mesh.position(b)) / 2.0;
            let lifted = [a, b] == [12, 13];
            Some(Plan {
                position: if lifted {
                    mid + DVec3::Z * self.height
                } else {
                    mid
                },
                cost: if lifted { 0.0 } else { 1.0 },
            })
        }
        fn merged(&mut self, _: &LiveMesh, _: Index, _: &[Index]) {}
    }

    #[test]
    fn faces_may_not_turn_sixty_degrees_from_their_input_normal() {
        let mesh = grid(4, 4, |_, _| 0.0);
        // Lifted 0.5 above the middle of an edge 0.25 long: every kept face tilts by
        // 63°–76°, less than the 90° of a flip but more than the 60° of the drift bound.
        let (_, outcome, _) = run(&mesh, &mut Lift { height: 0.5 }, Goal::Vertices(24));
        assert!(outcome.refused.flip >= 1, "{:?}", outcome.refused);
        assert_ne!((outcome.log[0].kept, outcome.log[0].removed[0]), (12, 13));
        // A small lift (well under 60°) is allowed.
        let (_, outcome, _) = run(&mesh, &mut Lift { height: 0.05 }, Goal::Vertices(24));
        assert_eq!(outcome.refused.flip, 0);
        assert_eq!((outcome.log[0].kept, outcome.log[0].removed[0]), (12, 13));
    }

    #[test]
    fn no_face_flips_on_a_folded_strip() {
        //  z                      A strip 4 cells wide, folded at x = ½ through 179°: the
        //  |  _________           second half lies back over the first, 1° apart, so
        //  |  ________/           crossing the fold costs QEM almost nothing. Every
        //  +--------------- x     output face must face the way its input parent faced.
        let mut mesh = grid(32, 4, |_, _| 0.0);
        let fold = 179f64.to_radians();
        for p in &mut mesh.positions {
            if p.x > 0.5 {
                let d = p.x - 0.5;
                *p = DVec3::new(0.5 + d * fold.cos(), p.y, d * fold.sin());
            }
        }
        let normals = (0..mesh.n_faces()).map(|f| mesh.face_normal(f)).collect();
        mesh.face_attrs.insert("n", AttrValues::Vec3(normals));
        for goal in [60, 30, 16] {
            let (out, _) = qem(&mesh, Goal::Vertices(goal));
            let parent_normals = out.face_attrs.vec3("n").unwrap();
            for (f, n) in parent_normals.iter().enumerate() {
                let dot = out.face_normal(f).dot(*n);
                assert!(dot > 0.0, "goal {goal}: face {f} turned over ({dot})");
            }
        }
    }

    #[test]
    fn no_face_turns_against_the_input_near_it_on_sharp_creases() {
        // Strips folded along a wavy crease through 100°–135°: faces at the crease can
        // cut the corner, lean over and end facing away from the input surface beside
        // them (the metrics' flip test), though each stays within 60° of its own input
        // face. Without the region test, the 120° strip at 30 vertices has such a face.
        // (Folds near 180° make two nearly parallel sheets, a thin part: there a face's
        // centroid may lie nearest the other sheet, which no local test sees.)
        let mut flipped = Vec::new();
        for (i, degrees) in [100.0f64, 120.0, 135.0].into_iter().enumerate() {
            let fold = degrees.to_radians();
            let mut mesh = grid(40, 12, |_, _| 0.0);
            for p in &mut mesh.positions {
                let crease = 0.5 + 0.04 * (9.0 * p.y + i as f64).sin();
                if p.x > crease {
                    let d = p.x - crease;
                    *p = DVec3::new(crease + d * fold.cos(), p.y, d * fold.sin());
                }
            }
            for goal in [200, 80, 30] {
                let (out, _) = qem(&mesh, Goal::Vertices(goal));
                let v = coarsen_metrics::validity(Some(&mesh), &out).unwrap();
                flipped.push((degrees, goal, v.n_flipped.unwrap_or(0)));
            }
        }
        assert!(flipped.iter().all(|f| f.2 == 0), "{flipped:?}");
    }

    #[test]
    fn faces_of_a_noisy_input_that_already_face_away_do_not_block_collapses() {
        // A flat grid shaken by up to 0.8 cell in every direction: about a sixth of its
        // faces fold over. They face away from their corners' regions from the start,
        // which the region test must not hold against every collapse around them.
        let mut state = 5u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut mesh = grid(50, 50, |_, _| 0.0);
        for p in &mut mesh.positions {
            *p += DVec3::new(next(), next(), next()) * (1.6 / 50.0);
        }
        let folded = (0..mesh.n_faces())
            .filter(|&f| mesh.face_normal(f).z < 0.0)
            .count();
        assert!(folded * 10 > mesh.n_faces(), "{folded} folded faces");
        let (out, outcome) = qem(&mesh, Goal::Vertices(300));
        assert_eq!(outcome.stop, StopReason::Reached, "{:?}", outcome.refused);
        assert_eq!(out.n_vertices(), 300);
    }

    #[test]
    fn interior_edge_between_boundary_vertices_is_never_collapsed() {
        // 3---2
        // | / |   the diagonal 0–2 is interior, its ends are on the boundary:
        // 0---1   collapsing it would pinch the square into two triangles at a vertex.
        let mesh = Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let mut model = Scripted {
            unit: Unit::Edge,
            reach: Reach::Kept,
            cost: |_: &LiveMesh, v: &[Index]| if v == [0, 2] { 0.0 } else { 1.0 },
        };
        let (out, outcome, _) = run(&mesh, &mut model, Goal::Vertices(2));
        assert_eq!(outcome.refused.boundary, 1);
        // One boundary edge collapses (3 vertices, 1 face); the last triangle stays.
        assert_eq!(outcome.collapses, 1);
        assert_eq!(outcome.stop, StopReason::Exhausted);
        assert_eq!((out.n_vertices(), out.n_faces()), (3, 1));
        assert!(outcome.refused.link >= 3);
    }

    #[test]
    fn grid_boundary_stays_on_its_original_lines() {
        // A bump on the unit square whose border lies on the four lines z = 0,
        // x or y ∈ {0, 1}. Boundary vertices may only slide along them.
        let mesh = grid(16, 16, bump);
        let (out, outcome) = qem(&mesh, Goal::Vertices(30));
        assert_eq!(outcome.stop, StopReason::Reached);
        assert_eq!(out.n_vertices(), 30);
        let live = LiveMesh::new(&out).unwrap();
        let s = live.summary();
        assert_eq!((s.locked_vertices, s.boundary_loops), (0, 1));
        let mut corners = 0;
        for v in 0..out.n_vertices() as Index {
            let p = live.position(v);
            if live.kind(v) != VertexKind::Boundary {
                assert!(p.x > 0.0 && p.x < 1.0 && p.y > 0.0 && p.y < 1.0, "{p}");
                continue;
            }
            let on_x = p.x.abs() < 1e-9 || (p.x - 1.0).abs() < 1e-9;
            let on_y = p.y.abs() < 1e-9 || (p.y - 1.0).abs() < 1e-9;
            assert!(
                (on_x || on_y) && p.z.abs() < 1e-9,
                "boundary vertex {v} left the border: {p}"
            );
            corners += (on_x && on_y) as usize;
        }
        assert_eq!(corners, 4, "the four corners are kept");
    }

    #[test]
    fn sphere_reaches_the_exact_vertex_count_and_stays_closed() {
        let mesh = icosphere(3);
        assert_eq!(mesh.n_vertices(), 642);
        let (out, outcome) = qem(&mesh, Goal::Vertices(100));
        assert_eq!(outcome.stop, StopReason::Reached);
        assert_eq!(outcome.collapses, 542);
        assert_eq!((out.n_vertices(), out.n_faces()), (100, 196));
        assert_eq!(assert_closed_manifold(&out).euler, 2);
        // QEM keeps the sphere round: every vertex stays near the unit sphere.
        for p in &out.positions {
            assert!((p.length() - 1.0).abs() < 0.05, "{p}");
        }
    }

    #[test]
    fn torus_keeps_its_genus() {
        let mesh = torus(3.0, 1.0, 24, 12);
        let (out, outcome) = qem(&mesh, Goal::Vertices(40));
        assert_eq!(outcome.stop, StopReason::Reached);
        assert_eq!(out.n_vertices(), 40);
        // χ = 2 − 2g = 0.
        assert_eq!(assert_closed_manifold(&out).euler, 0);
    }

    #[test]
    fn face_goal_is_met_within_one_face() {
        let mesh = icosphere(3);
        let (out, outcome) = qem(&mesh, Goal::Faces(301));
        assert_eq!(outcome.stop, StopReason::Reached);
        assert_eq!(out.n_faces(), 300);
        let after = LiveMesh::new(&out).unwrap().summary();
        let note = outcome.below_face_goal(Goal::Faces(301), &after).unwrap();
        assert!(
            note.contains("300 faces, 1 below") && note.contains("closed"),
            "{note}"
        );
        assert_eq!(outcome.below_face_goal(Goal::Faces(300), &after), None);
    }

    #[test]
    fn face_goal_is_met_exactly_where_a_boundary_edge_can_take_the_last_face() {
        // 288 faces; the bump makes costs differ, so interior edges are often the cheapest
        // when one face is left.
        let mesh = grid(12, 12, bump);
        for n in 100..=180 {
            let (out, outcome) = qem(&mesh, Goal::Faces(n));
            assert_eq!(outcome.stop, StopReason::Reached);
            assert_eq!(out.n_faces(), n, "goal {n}");
            let after = LiveMesh::new(&out).unwrap().summary();
            assert_eq!(after.boundary_loops, 1);
            assert_eq!(outcome.below_face_goal(Goal::Faces(n), &after), None);
        }
    }

    #[test]
    fn zero_costs_on_a_flat_grid_collapse_in_queue_order() {
        // 8---9---10--11
        // | / | / | / |    every QEM cost is exactly 0 on a flat, axis-aligned grid,
        // 4---5---6---7    so the heap must fall back on the queue order: the first
        // | / | / | / |    candidate queued is edge 0–1 of face (0,1,5).
        // 0---1---2---3
        let mesh = grid(3, 2, |_, _| 0.0);
        let (out, outcome) = qem(&mesh, Goal::Vertices(6));
        assert!(outcome.log.iter().all(|r| r.cost == 0.0));
        let first = outcome.log[0];
        assert_eq!(
            (first.kept, first.removed, first.position),
            (0, [1, NONE], DVec3::ZERO)
        );
        let (again, outcome2) = qem(&mesh, Goal::Vertices(6));
        assert_eq!(out, again);
        assert_eq!(outcome, outcome2);
    }

    /// Refuses every reshape whose moved corner lands above `z`.
    struct Below(f64);

    impl FaceGuard for Below {
        fn allows(&mut self, r: &Reshape) -> bool {
            r.new.iter().all(|p| p.z <= self.0)
        }
    }

    #[test]
    fn a_guard_refuses_collapses_and_is_counted() {
        let sphere = coarsen_shapes::icosphere(1.0, 2).unwrap();
        let goal = Options::new(Goal::Vertices(40));
        // A guard that allows everything changes nothing.
        let (plain, plain_outcome) = qem(&sphere, Goal::Vertices(40));
        let mut live = LiveMesh::new(&sphere).unwrap();
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let outcome = live.collapse_guarded(&mut model, &mut NoGuard, &goal, &mut |_| {});
        assert_eq!(live.to_mesh(&sphere).unwrap().0, plain);
        assert_eq!(outcome, plain_outcome);
        // Faces may not reach above z = 0.5: the cap stays as it was, the rest coarsens.
        let mut live = LiveMesh::new(&sphere).unwrap();
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let outcome = live.collapse_guarded(&mut model, &mut Below(0.5), &goal, &mut |_| {});
        live.check_invariants().unwrap();
        assert!(outcome.refused.facing > 0);
        assert_eq!(
            outcome.refused.by_reason()["facing"],
            outcome.refused.facing
        );
        let (out, _) = live.to_mesh(&sphere).unwrap();
        let top = |m: &Mesh| m.positions.iter().filter(|p| p.z > 0.5).count();
        assert!(top(&out) <= top(&sphere));
        assert!(out.n_vertices() < sphere.n_vertices());
        // The input's faces above z = 0.5 were all refused a reshape: they survive as
        // they were.
        let kept: Vec<[DVec3; 3]> = (0..out.n_faces()).map(|f| out.corners(f)).collect();
        for f in 0..sphere.n_faces() {
            let c = sphere.corners(f);
            if c.iter().any(|p| p.z > 0.5) && c.iter().all(|p| p.z > 0.5) {
                assert!(kept.contains(&c), "input face {f} was reshaped");
            }
        }
    }

    #[test]
    fn same_input_gives_the_same_output() {
        let mesh = grid(20, 20, bump);
        let (a, oa) = qem(&mesh, Goal::Vertices(50));
        let (b, ob) = qem(&mesh, Goal::Vertices(50));
        assert_eq!(a, b);
        assert_eq!(oa, ob);
    }

    thread_local! {
        /// How often a parked candidate stayed parked for its witness, on this thread.
        pub(super) static KEPT_PARKED: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
    }

    #[test]
    fn link_refusals_wait_for_their_witness_to_merge() {
        // Triangle collapses down to a few vertices refuse many candidates for the link
        // condition; those whose witness a collapse did not merge stay parked, each
        // checked (in this debug build) to be refused still.
        let mesh = icosphere(3);
        let mut model = smallest_triangle(Reach::Kept);
        KEPT_PARKED.with(|k| k.set(0));
        let (out, outcome, _) = run(&mesh, &mut model, Goal::Vertices(12));
        let kept = KEPT_PARKED.with(|k| k.get());
        assert!(
            outcome.refused.link > 0 && kept > 0,
            "{kept} kept, {:?}",
            outcome.refused
        );
        assert_eq!(assert_closed_manifold(&out).euler, 2);
    }

    #[test]
    fn triangle_collapses_keep_a_closed_manifold() {
        let mesh = icosphere(2);
        let mut model = smallest_triangle(Reach::Ring);
        let (out, outcome, _) = run(&mesh, &mut model, Goal::Vertices(40));
        assert_eq!(outcome.stop, StopReason::Reached);
        assert!(
            (39..=40).contains(&out.n_vertices()),
            "{}",
            out.n_vertices()
        );
        assert!(
            outcome.log.iter().all(|r| r.removed[1] != NONE),
            "3 → 1 each time"
        );
        assert_eq!(assert_closed_manifold(&out).euler, 2);
    }

    #[test]
    fn two_rings_reach_recosts_every_triangle_within_two_edges_of_the_new_vertex() {
        let mesh = icosphere(2);
        let calls = std::sync::Mutex::new(Vec::new());
        let mut model = Scripted {
            unit: Unit::Triangle,
            reach: Reach::TwoRings,
            cost: |_: &LiveMesh, v: &[Index]| {
                let mut t = [v[0], v[1], v[2]];
                t.sort_unstable();
                calls.lock().unwrap().push(t);
                0.0
            },
        };
        let (_, outcome, live) = run(&mesh, &mut model, Goal::Vertices(mesh.n_vertices() - 2));
        assert_eq!(outcome.collapses, 1);
        let kept = outcome.log[0].kept;
        // Ranking costs every face once, the pop costs the first again; the rest is requeue.
        let requeued: std::collections::BTreeSet<[Index; 3]> = calls.lock().unwrap()
            [mesh.n_faces() + 1..]
            .iter()
            .copied()
            .collect();
        let neighbours = |v: Index| -> Vec<Index> {
            live.faces_around(v)
                .iter()
                .flat_map(|&f| live.face(f))
                .collect()
        };
        let mut near: Vec<Index> = neighbours(kept).into_iter().flat_map(neighbours).collect();
        near.sort_unstable();
        near.dedup();
        let expect: std::collections::BTreeSet<[Index; 3]> = live
            .live_faces()
            .map(|f| live.face(f))
            .filter(|t| t.iter().any(|v| near.contains(v)))
            .map(|mut t| {
                t.sort_unstable();
                t
            })
            .collect();
        assert_eq!(requeued, expect);
        // Some of them do not touch the new vertex's ring: a Ring reach would miss them.
        let ring = neighbours(kept);
        assert!(expect.iter().any(|t| t.iter().all(|v| !ring.contains(v))));
    }

    #[test]
    fn triangle_collapses_on_a_grid_keep_its_one_boundary_loop() {
        let mesh = grid(10, 10, bump);
        let mut model = smallest_triangle(Reach::Ring);
        let (out, _, _) = run(&mesh, &mut model, Goal::Vertices(30));
        let s = LiveMesh::new(&out).unwrap().summary();
        assert_eq!((s.locked_vertices, s.boundary_loops, s.euler), (0, 1, 1));
    }

    #[test]
    fn non_manifold_vertex_is_locked_in_place() {
        // Two octahedra touching at vertex 0 (a bow-tie vertex).
        let mut positions = OCTAHEDRON.to_vec();
        let offset = DVec3::new(2.0, 0.0, 0.0);
        positions.extend([DVec3::X, DVec3::Y, -DVec3::Y, DVec3::Z, -DVec3::Z].map(|p| p + offset));
        let mut faces = octahedron_faces(0, 1, 2, 3, 4, 5);
        faces.extend(octahedron_faces(6, 7, 0, 8, 9, 10));
        let mesh = Mesh::new(positions, faces);
        let live = LiveMesh::new(&mesh).unwrap();
        assert_eq!(live.kind(0), VertexKind::Locked);
        assert_eq!(live.summary().locked_vertices, 1);
        let (out, outcome, _) = run(&mesh, &mut shortest_edge(), Goal::Vertices(8));
        assert_eq!(outcome.stop, StopReason::Reached);
        assert_eq!(out.n_vertices(), 8);
        assert_eq!(
            out.positions[0],
            DVec3::X,
            "the locked vertex neither moves nor goes"
        );
        assert!(outcome.refused.locked > 0);
    }

    #[test]
    fn faces_repeating_a_vertex_pass_through_and_lock_their_vertices() {
        let mut mesh = tetrahedron();
        mesh.faces.push([0, 0, 1]);
        let live = LiveMesh::new(&mesh).unwrap();
        assert_eq!(live.summary().locked_vertices, 2);
        let (out, outcome, _) = run(&mesh, &mut shortest_edge(), Goal::Vertices(2));
        assert_eq!(outcome.collapses, 0);
        assert_eq!(out, mesh);
    }

    #[test]
    fn damaged_meshes_never_panic_and_keep_the_invariants() {
        // Grids and spheres with points snapped to a coarse lattice (coincident points,
        // zero-area faces), faces deleted (holes, bow-ties), flipped, duplicated and added
        // at random (non-manifold edges, repeated indices). Whatever the engine accepts it
        // must leave consistent.
        let mut state = 99u64;
        let mut next = move |n: u32| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) % n as u64) as u32
        };
        let (mut collapses, mut locked, mut closed_up) = (0, 0, 0);
        for round in 0..200 {
            let mut mesh = if round % 2 == 0 {
                grid(5, 4, bump)
            } else {
                icosphere(1)
            };
            let nv = mesh.n_vertices() as u32;
            let lattice = [0.0, 0.5, 4.0, 16.0][next(4) as usize];
            if lattice > 0.0 {
                for p in &mut mesh.positions {
                    *p = (*p * lattice).round() / lattice;
                }
            }
            for _ in 0..next(4) {
                let f = next(mesh.n_faces() as u32) as usize;
                match next(4) {
                    0 => {
                        mesh.faces.remove(f);
                    }
                    1 => mesh.faces[f].swap(0, 1),
                    2 => mesh.faces.push(mesh.faces[f]),
                    _ => mesh.faces.push([next(nv), next(nv), next(nv)]),
                }
            }
            for goal in [Goal::Vertices(next(nv) as usize), Goal::Faces(0)] {
                // Closing up the arrays after every collapse that halves the live faces
                // changes nothing.
                let run = |compact_min_faces| {
                    let mut live = LiveMesh::new(&mesh).unwrap();
                    let mut model = QuadricModel::new(&live, &QemOptions::default());
                    let opts = closing_up_from(compact_min_faces, goal);
                    let outcome = live.collapse(&mut model, &opts, &mut |_| {});
                    live.check_invariants()
                        .unwrap_or_else(|e| panic!("round {round}: {e}\n{mesh:?}"));
                    let out = live.to_mesh(&mesh).unwrap();
                    (live, outcome, out)
                };
                let (live, outcome, (out, carry)) = run(usize::MAX);
                let (closed, closed_outcome, closed_out) = run(0);
                assert_eq!(
                    (&closed_outcome, &closed_out),
                    (&outcome, &(out.clone(), carry)),
                    "round {round}: closing up changed the run"
                );
                closed_up += usize::from(closed.vertex_slots() < live.vertex_slots());
                assert!(out.validate_indices().is_ok());
                assert_eq!(
                    (out.n_faces(), out.n_vertices()),
                    (live.n_faces(), live.n_vertices())
                );
                assert!(
                    outcome
                        .log
                        .iter()
                        .all(|r| r.cost.is_finite() && r.sve.is_finite())
                );
                collapses += outcome.collapses;
                locked += live.summary().locked_vertices;
            }
        }
        assert!(
            collapses > 1000 && locked > 100 && closed_up > 100,
            "{collapses} collapses, {locked} locked, {closed_up} runs closed up"
        );
    }

    #[test]
    fn closing_up_changes_no_collapse_of_renumbered_inputs_nor_their_attributes() {
        // A grid with attributes, its vertices shuffled: renumbered inside, boundary kept.
        let base = grid_with_attributes();
        let mut mesh = relabelled(&base, &shuffled_order(base.n_vertices(), 3));
        mesh.face_attrs = base.face_attrs.clone();
        let run = |compact_min_faces, goal| {
            let mut live = LiveMesh::new_renumbered(&mesh).unwrap();
            let mut model = QuadricModel::new(&live, &QemOptions::default());
            let opts = closing_up_from(compact_min_faces, goal);
            let outcome = live.collapse(&mut model, &opts, &mut |_| {});
            live.check_invariants().unwrap();
            // A second run on the same live mesh (as the stages finish on an exact count).
            let opts = closing_up_from(compact_min_faces, Goal::Vertices(6));
            let more = live.collapse(&mut model, &opts, &mut |_| {});
            live.check_invariants().unwrap();
            let slots = live.vertex_slots();
            (outcome, more, live.to_mesh(&mesh).unwrap(), slots)
        };
        for goal in [Goal::Vertices(20), Goal::Faces(30)] {
            let (outcome, more, out, slots) = run(usize::MAX, goal);
            let (c_outcome, c_more, c_out, c_slots) = run(0, goal);
            assert!(c_slots < slots / 4, "{c_slots} of {slots} slots");
            assert_eq!((c_outcome, c_more, c_out), (outcome, more, out));
        }
    }

    #[test]
    fn bad_input_is_a_typed_error_naming_the_element() {
        let mut mesh = tetrahedron();
        mesh.positions[2].y = f64::NAN;
        let e = LiveMesh::new(&mesh).unwrap_err();
        assert!(
            matches!(e, CollapseError::NonFinite { vertex: 2, .. }),
            "{e}"
        );
        let mut mesh = tetrahedron();
        mesh.faces[1] = [0, 9, 3];
        let e = LiveMesh::new(&mesh).unwrap_err();
        assert!(e.to_string().contains("face 1 names vertex 9"), "{e}");
        let live = LiveMesh::new(&tetrahedron()).unwrap();
        assert!(matches!(
            live.to_mesh(&icosphere(0)),
            Err(CollapseError::MeshMismatch { .. })
        ));
    }

    #[test]
    fn unused_vertices_are_dropped_and_empty_input_is_fine() {
        let mut mesh = tetrahedron();
        mesh.positions.push(DVec3::splat(5.0));
        let live = LiveMesh::new(&mesh).unwrap();
        assert_eq!(live.summary().isolated_vertices, 1);
        let (out, _) = live.to_mesh(&mesh).unwrap();
        assert_eq!(out.n_vertices(), 4);
        let empty = Mesh::default();
        let (out, outcome, _) = run(&empty, &mut shortest_edge(), Goal::Vertices(0));
        assert_eq!((out.n_vertices(), outcome.collapses), (0, 0));
        assert_eq!(outcome.stop, StopReason::Reached);
    }

    /// A bumped grid with a vertex scalar `x` (its x coordinate) and a face label `cell`
    /// (its index).
    fn grid_with_attributes() -> Mesh {
        let mut mesh = grid(8, 8, bump);
        let xs = mesh.positions.iter().map(|p| p.x).collect();
        mesh.vertex_attrs.insert("x", AttrValues::Scalar(xs));
        let labels = (0..mesh.n_faces() as u32).collect();
        mesh.face_attrs.insert("cell", AttrValues::Label(labels));
        mesh
    }

    #[test]
    fn attributes_are_blended_onto_merged_vertices_and_kept_by_faces() {
        let mesh = grid_with_attributes();
        let (out, outcome) = qem(&mesh, Goal::Vertices(20));
        assert!(outcome.collapses > 0);
        let x = out.vertex_attrs.scalar("x").unwrap();
        assert_eq!(x.len(), 20);
        assert!(x.iter().all(|v| (0.0..=1.0).contains(v)));
        let cells = out.face_attrs.label("cell").unwrap();
        assert_eq!(cells.len(), out.n_faces());
        assert!(
            cells.windows(2).all(|w| w[0] < w[1]),
            "faces keep input order"
        );
    }

    #[test]
    fn attributes_alone_give_the_same_mesh_and_misfits_are_refused() {
        let mesh = grid_with_attributes();
        let mut live = LiveMesh::new_renumbered(&mesh).unwrap();
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        live.collapse(&mut model, &Options::new(Goal::Vertices(20)), &mut |_| {});
        let attributes = attributes_only(mesh.clone());
        let (out, _) = live.to_mesh_with_attributes(&attributes).unwrap();
        assert_eq!(out, live.to_mesh(&mesh).unwrap().0);
        assert_eq!(out.vertex_attrs.scalar("x").unwrap().len(), 20);
        // A column that does not fit the input is an error, not a panic.
        let mut short = attributes.clone();
        short
            .face_attrs
            .insert("cell", AttrValues::Label(vec![0; 3]));
        assert!(matches!(
            live.to_mesh_with_attributes(&short),
            Err(CollapseError::MeshMismatch { faces: 3, .. })
        ));
        let mut short = attributes;
        short
            .vertex_attrs
            .insert("x", AttrValues::Scalar(vec![0.0; 5]));
        assert!(matches!(
            live.to_mesh_with_attributes(&short),
            Err(CollapseError::MeshMismatch { vertices: 5, .. })
        ));
    }

    #[test]
    fn a_candidate_dearer_than_queued_goes_back_in_line() {
        // Edge (84, 85) is far from edge (24, 25), so a Kept reach does not re-cost it
        // after (24, 25) collapses; its cost has grown meanwhile, which its pop must see.
        let mesh = grid(10, 10, |_, _| 0.0);
        let n = mesh.n_vertices();
        let cost = |m: &LiveMesh, v: &[Index]| match v {
            [24, 25] => 0.5,
            [84, 85] if m.n_vertices() == n => 0.75,
            [84, 85] => 5.0,
            _ => 1.0,
        };
        let mut model = Scripted {
            unit: Unit::Edge,
            reach: Reach::Kept,
            cost,
        };
        let (out, outcome, _) = run(&mesh, &mut model, Goal::Vertices(n - 2));
        assert_eq!(outcome.collapses, 2);
        assert_eq!((outcome.log[0].kept, outcome.log[0].removed[0]), (24, 25));
        assert_eq!(outcome.log[1].cost, 1.0, "{:?}", outcome.log[1]);
        assert!(
            outcome
                .log
                .iter()
                .all(|r| (r.kept, r.removed[0]) != (84, 85))
        );
        // Without the log, the same run.
        let mut live = LiveMesh::new(&mesh).unwrap();
        let opts = Options {
            keep_log: false,
            ..Options::new(Goal::Vertices(n - 2))
        };
        let quiet = live.collapse(&mut model, &opts, &mut |_| {});
        assert!(quiet.log.is_empty());
        assert_eq!(
            (quiet.collapses, quiet.sve),
            (outcome.collapses, outcome.sve)
        );
        assert_eq!(live.to_mesh(&mesh).unwrap().0, out);
    }

    #[test]
    fn max_error_stops_before_the_first_costlier_collapse() {
        let mesh = grid(12, 12, bump);
        let (_, full) = qem(&mesh, Goal::Vertices(10));
        let limit = full.log[full.log.len() / 2].cost;
        assert!(limit > 0.0);
        let mut live = LiveMesh::new(&mesh).unwrap();
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let opts = Options {
            max_error: Some(limit),
            ..Options::new(Goal::Vertices(10))
        };
        let outcome = live.collapse(&mut model, &opts, &mut |_| {});
        assert!(matches!(outcome.stop, StopReason::MaxError { cost } if cost > limit));
        assert!(outcome.log.iter().all(|r| r.cost <= limit));
        assert!(outcome.collapses < full.collapses);
    }

    #[test]
    fn a_run_stopped_at_an_error_limit_goes_on_as_if_it_had_never_stopped() {
        let mesh = grid(12, 12, bump);
        let (whole, full) = qem(&mesh, Goal::Vertices(10));
        let limit = full.log[full.log.len() / 2].cost;
        let mut live = LiveMesh::new(&mesh).unwrap();
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let opts = Options::new(Goal::Vertices(10));
        let limited = Options {
            max_error: Some(limit),
            ..opts
        };
        let mut run = live.start(&mut model, &limited);
        let stop = live.resume(&mut run, &mut model, &mut NoGuard, &limited, &mut |_| {});
        assert!(matches!(stop, StopReason::MaxError { .. }));
        assert!(run.held.is_some());
        let halfway = run.out.collapses;
        assert!(halfway > 0 && halfway < full.collapses);
        let stop = live.resume(&mut run, &mut model, &mut NoGuard, &opts, &mut |_| {});
        assert_eq!(stop, StopReason::Reached);
        assert_eq!(run.out.log, full.log);
        assert_eq!(live.to_mesh(&mesh).unwrap().0, whole);
    }

    #[test]
    fn quality_guard_refuses_slivers() {
        let mesh = grid(12, 12, bump);
        let (_, plain) = qem(&mesh, Goal::Vertices(20));
        let mut live = LiveMesh::new(&mesh).unwrap();
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let opts = Options {
            min_quality: 0.3,
            ..Options::new(Goal::Vertices(20))
        };
        let outcome = live.collapse(&mut model, &opts, &mut |_| {});
        assert!(outcome.refused.quality > 0);
        assert_eq!(plain.refused.quality, 0);
        live.check_invariants().unwrap();
    }

    #[test]
    fn sve_is_the_squared_volume_swept_by_the_faces_around_the_merge() {
        // Oracle: Σ (1/9)·Sᵢ²·(nᵢ·p + dᵢ)² over the input faces around both merged vertices.
        let mesh = icosphere(1);
        let (_, outcome) = qem(&mesh, Goal::Vertices(mesh.n_vertices() - 1));
        let r = outcome.log[0];
        let expect: f64 = (0..mesh.n_faces())
            .filter(|&f| {
                mesh.faces[f]
                    .iter()
                    .any(|&v| v == r.kept || v == r.removed[0])
            })
            .map(|f| {
                let s = mesh.face_area(f);
                let q = coarsen_geom::Quadric::from_plane(
                    mesh.face_normal(f),
                    mesh.corners(f)[0],
                    s * s / 9.0,
                );
                q.eval(r.position)
            })
            .sum();
        assert!(expect > 0.0);
        assert!(
            (r.sve - expect).abs() <= 1e-12 * expect,
            "{} vs {expect}",
            r.sve
        );
        assert_eq!(outcome.sve, r.sve);
    }

    #[test]
    fn recording_the_progressive_record_changes_nothing_and_matches_the_output() {
        let mesh = torus(3.0, 1.0, 20, 10);
        let (plain, plain_outcome) = qem(&mesh, Goal::Vertices(30));
        let mut live = LiveMesh::new(&mesh).unwrap();
        live.record_progressive();
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let outcome = live.collapse(&mut model, &Options::new(Goal::Vertices(30)), &mut |_| {});
        let (out, _) = live.to_mesh(&mesh).unwrap();
        assert_eq!((&out, &outcome), (&plain, &plain_outcome));
        let p = live.take_progressive(&out).unwrap();
        assert!(live.take_progressive(&out).is_none(), "taken once");
        assert_eq!(p.steps.len(), outcome.collapses);
        assert_eq!(p.coarse, crate::fingerprint(&out));
        assert_eq!(
            (p.coarse_vertices(), p.coarse_faces()),
            (out.n_vertices(), out.n_faces())
        );
        for (s, r) in p.steps.iter().zip(&outcome.log) {
            assert_eq!((s.kept, s.removed), (r.kept, r.removed));
            // An interior edge collapse deletes the edge's two faces.
            assert_eq!(s.deleted, 2);
        }
        // The first step's positions are the input's.
        let s = p.steps[0];
        assert_eq!(p.positions[0], mesh.positions[s.kept as usize]);
        assert_eq!(p.positions[1], mesh.positions[s.removed[0] as usize]);
        // Not asked for: nothing recorded.
        let mut quiet = LiveMesh::new(&mesh).unwrap();
        assert!(quiet.take_progressive(&out).is_none());
    }

    /// `mesh` with vertex `v` renamed `perm[v]` (positions and attributes moved along).
    /// `0..n` shuffled by a generator seeded with `seed`.
    fn shuffled_order(n: usize, seed: u64) -> Vec<Index> {
        let mut perm: Vec<Index> = (0..n as Index).collect();
        let mut state = seed;
        for i in (1..n).rev() {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            perm.swap(i, (state >> 33) as usize % (i + 1));
        }
        perm
    }

    /// Options for `goal` that close up the arrays from `compact_min_faces` faces on.
    fn closing_up_from(compact_min_faces: usize, goal: Goal) -> Options {
        Options {
            compact_min_faces,
            ..Options::new(goal)
        }
    }

    fn relabelled(mesh: &Mesh, perm: &[Index]) -> Mesh {
        let mut positions = vec![DVec3::ZERO; mesh.n_vertices()];
        let mut xs = vec![0.0; mesh.n_vertices()];
        for (v, &p) in perm.iter().enumerate() {
            positions[p as usize] = mesh.positions[v];
            xs[p as usize] = mesh.positions[v].x;
        }
        let faces = mesh
            .faces
            .iter()
            .map(|f| f.map(|v| perm[v as usize]))
            .collect();
        let mut out = Mesh::new(positions, faces);
        out.vertex_attrs.insert("x", AttrValues::Scalar(xs));
        out
    }

    #[test]
    fn renumbered_runs_are_the_runs_of_the_input_in_face_order_relabelled() {
        // `local`: a torus with its vertices in the order its faces first use them, plus an
        // unused vertex. `shuffled`: the same mesh with the vertices renamed at random. The
        // renumbered run of `shuffled` collapses exactly as the plain run of `local`, and
        // speaks `shuffled`'s indices: output, log and progressive record are `local`'s
        // relabelled, and the output vertices keep `shuffled`'s order.
        let mut base = torus(3.0, 1.0, 24, 12);
        base.positions.push(DVec3::splat(9.0));
        let n = base.n_vertices();
        let mut first_use = Vec::new();
        let mut seen = vec![false; n];
        for &v in base.faces.iter().flatten().chain(&[n as Index - 1]) {
            if !std::mem::replace(&mut seen[v as usize], true) {
                first_use.push(v);
            }
        }
        let mut to_local = vec![0; n];
        for (i, &v) in first_use.iter().enumerate() {
            to_local[v as usize] = i as Index;
        }
        let local = relabelled(&base, &to_local);
        let perm = shuffled_order(n, 7);
        let shuffled = relabelled(&local, &perm);
        let goal = Options::new(Goal::Vertices(40));
        let map = |v: Index| if v == NONE { NONE } else { perm[v as usize] };
        let mut plain = LiveMesh::new(&local).unwrap();
        assert!(
            LiveMesh::new_renumbered(&local)
                .unwrap()
                .original_of
                .is_none()
        );
        plain.record_progressive();
        let mut model = QuadricModel::new(&plain, &QemOptions::default());
        let expect = plain.collapse(&mut model, &goal, &mut |_| {});
        let mut live = LiveMesh::new_renumbered(&shuffled).unwrap();
        assert!(live.original_of.is_some());
        live.record_progressive();
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let got = live.collapse(&mut model, &goal, &mut |_| {});
        live.check_invariants().unwrap();
        assert_eq!(got.collapses, expect.collapses);
        assert!(got.collapses > 200);
        assert_eq!(got.sve, expect.sve);
        for (g, e) in got.log.iter().zip(&expect.log) {
            assert_eq!(g.kept, perm[e.kept as usize]);
            assert_eq!(g.removed, e.removed.map(map));
            assert_eq!((g.position, g.cost), (e.position, e.cost));
        }
        let (out_local, _) = plain.to_mesh(&local).unwrap();
        let (out, carry) = live.to_mesh(&shuffled).unwrap();
        assert!(carry.dropped.is_empty());
        assert_eq!(out.faces.len(), out_local.faces.len());
        // Output vertex i of the plain run stands for a local vertex; the renumbered run has
        // it at the rank of that vertex's shuffled index among the survivors.
        let survivors: Vec<Index> = (0..n as Index)
            .filter(|&v| plain.is_alive(v) && plain.kind(v) != VertexKind::Isolated)
            .collect();
        let mut ranked: Vec<Index> = survivors.iter().map(|&v| perm[v as usize]).collect();
        ranked.sort_unstable();
        let at = |v: Index| ranked.binary_search(&perm[v as usize]).unwrap();
        for (i, &v) in survivors.iter().enumerate() {
            assert_eq!(out.positions[at(v)], out_local.positions[i]);
        }
        for (f, g) in out.faces.iter().zip(&out_local.faces) {
            assert_eq!(*f, g.map(|i| at(survivors[i as usize]) as Index));
        }
        // Each merged vertex blends the same input vertices (its x attribute, a mean of
        // theirs, agrees up to the order of summation).
        let (xs, xs_local) = (
            out.vertex_attrs.scalar("x").unwrap(),
            out_local.vertex_attrs.scalar("x").unwrap(),
        );
        for (i, &v) in survivors.iter().enumerate() {
            assert!((xs[at(v)] - xs_local[i]).abs() < 1e-12);
        }
        // The progressive records: the same steps, in shuffled indices.
        let p_local = plain.take_progressive(&out_local).unwrap();
        let p = live.take_progressive(&out).unwrap();
        assert_eq!(p.coarse, crate::fingerprint(&out));
        assert_eq!(
            (p.positions, p.steps.len()),
            (p_local.positions, p_local.steps.len())
        );
        for (s, e) in p.steps.iter().zip(&p_local.steps) {
            assert_eq!(s.kept, perm[e.kept as usize]);
            assert_eq!(s.removed, e.removed.map(map));
            assert_eq!((s.deleted, s.changed), (e.deleted, e.changed));
        }
        for (d, e) in p.deleted.iter().zip(&p_local.deleted) {
            assert_eq!(
                (d.face, d.corners),
                (e.face, e.corners.map(|v| perm[v as usize]))
            );
        }
        for (c, e) in p.changed.iter().zip(&p_local.changed) {
            assert_eq!((c.face, c.vertex), (e.face, perm[e.vertex as usize]));
        }
        assert_eq!(p.isolated, vec![(perm[n - 1], DVec3::splat(9.0))]);
    }

    #[test]
    fn the_run_does_not_depend_on_the_thread_count() {
        // The initial ranking runs on rayon's threads; its queue must not.
        let mesh = icosphere(5);
        let run_on = |threads: usize| {
            coarsen_testdata::on_threads(threads, || {
                let mut live = LiveMesh::new(&mesh).unwrap();
                let mut model = QuadricModel::new(&live, &QemOptions::default());
                let outcome =
                    live.collapse(&mut model, &Options::new(Goal::Vertices(300)), &mut |_| {});
                (live.to_mesh(&mesh).unwrap().0, outcome)
            })
        };
        let one = run_on(1);
        assert_eq!(one.1.collapses, mesh.n_vertices() - 300);
        for threads in [2, 3, 8] {
            assert_eq!(run_on(threads), one, "{threads} threads");
        }
    }

    #[test]
    fn renumbered_input_errors_name_the_input_elements() {
        let mut mesh = tetrahedron();
        mesh.faces.reverse();
        mesh.positions[3].z = f64::INFINITY;
        let e = LiveMesh::new_renumbered(&mesh).unwrap_err();
        assert!(
            matches!(e, CollapseError::NonFinite { vertex: 3, .. }),
            "{e}"
        );
    }

    #[test]
    fn progress_hears_every_few_thousand_collapses() {
        let mesh = icosphere(5);
        let mut live = LiveMesh::new(&mesh).unwrap();
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let mut heard = Vec::new();
        let outcome = live.collapse(&mut model, &Options::new(Goal::Vertices(500)), &mut |n| {
            heard.push(n)
        });
        assert_eq!(outcome.collapses, mesh.n_vertices() - 500);
        assert_eq!(
            heard,
            (1..=outcome.collapses / PROGRESS_EVERY)
                .map(|i| i * PROGRESS_EVERY)
                .collect::<Vec<_>>()
        );
        assert_eq!(live.n_vertices(), 500);
    }
}
