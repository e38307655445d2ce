//! Explicit, reported clean-up applied after loading a file.
//!
//! [`clean`] runs these steps in order; each one is counted in the [`HygieneReport`], and a
//! step that is switched off or finds nothing is still listed (with 0):
//!
//! 1. **reject** invalid indices and NaN/infinite positions or float attributes (an
//!    error naming the element; nothing is repaired silently);
//! 2. **weld** (optional) vertices at exactly the same position: coordinates compared
//!    bit for bit after turning `-0.0` into `0.0`; the lowest-numbered vertex of each
//!    group survives and keeps its attributes;
//! 3. **drop degenerate faces** (optional): faces repeating a vertex index (also those
//!    that welding creates), and faces of zero area, i.e. area exactly 0 or below
//!    [`HygieneOptions::degenerate_area_rel`]` · (bbox diagonal)²`;
//! 4. **drop duplicate faces** (optional): a face with the same vertex triple as an earlier
//!    face, up to rotation, is dropped; a face on the same vertices in the *opposite*
//!    orientation is kept and only counted (two-sided sheets are real geometry);
//! 5. **drop unreferenced vertices** (optional), compacting the indices;
//! 6. **marked edges** ([`Mesh::marked_edges`]) follow every weld and renumbering; those
//!    whose ends became one vertex, repeats of an earlier one (either way round), and those
//!    that are no edge of a remaining face are dropped and counted. The rest are stored
//!    with the smaller vertex first, sorted. Listed only when the input marks edges.
//!
//! All re-indexing happens once, at the end, through [`Mesh::rebuilt`], so every
//! attribute column travels with its vertices and faces.

use crate::sanity::{
    NonFinite, area_threshold, faces_sharing_vertex_sets, find_non_finite, is_degenerate_area,
};
use crate::{Domain, FaceOrigins, Index, IndexError, Mesh, VertexOrigins};
use coarsen_geom::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Which clean-up steps [`clean`] runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HygieneOptions {
    /// Merge vertices at bit-identical positions. Default `false`: right for indexed
    /// formats (OBJ, PLY) whose duplicated positions may be intended seams; the loader
    /// turns it on for triangle soups (STL).
    pub weld: bool,
    /// Drop faces that repeat an index or have zero area. Default `true`.
    pub drop_degenerate: bool,
    /// Relative area threshold of the degenerate test: a face is dropped when its area is
    /// 0 or below this times the squared bounding-box diagonal. Default `0.0` (only
    /// exactly flat faces; dropping slivers would open holes in the surface).
    pub degenerate_area_rel: f64,
    /// Drop faces repeating an earlier face's vertex triple in the same orientation.
    /// Default `true`.
    pub drop_duplicate_faces: bool,
    /// Drop vertices that no remaining face references. Default `true`.
    pub drop_unreferenced: bool,
}

impl Default for HygieneOptions {
    fn default() -> Self {
        Self {
            weld: false,
            drop_degenerate: true,
            degenerate_area_rel: 0.0,
            drop_duplicate_faces: true,
            drop_unreferenced: true,
        }
    }
}

impl HygieneOptions {
    /// The defaults for triangle soups (every face with its own corners): welding on.
    pub fn soup() -> Self {
        Self {
            weld: true,
            ..Self::default()
        }
    }
}

/// Input that clean-up refuses to repair.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum HygieneError {
    /// A face index out of range, a column of the wrong length, or too many elements.
    #[error(transparent)]
    Index(#[from] IndexError),
    /// A position with a NaN or infinite coordinate.
    #[error("vertex {vertex} has a non-finite position {position:?}")]
    NonFinitePosition {
        /// The vertex.
        vertex: usize,
        /// Its position.
        position: [f64; 3],
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
}

/// What [`clean`] did, step by step.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HygieneReport {
    /// The options the steps ran with.
    pub options: HygieneOptions,
    /// Vertices before clean-up.
    pub vertices_in: usize,
    /// Faces before clean-up.
    pub faces_in: usize,
    /// Vertices merged into an earlier vertex at the same position.
    pub welded_vertices: usize,
    /// Faces dropped for repeating a vertex index.
    pub repeated_index_faces: usize,
    /// Faces dropped for zero area.
    pub zero_area_faces: usize,
    /// Faces dropped for repeating an earlier face (same vertices, same orientation).
    pub duplicate_faces: usize,
    /// Vertex triples present in both orientations (kept).
    pub opposite_duplicate_pairs: usize,
    /// Vertices dropped because no face references them.
    pub unreferenced_vertices: usize,
    /// Vertices after clean-up.
    pub vertices_out: usize,
    /// Faces after clean-up.
    pub faces_out: usize,
    /// Marked edges before clean-up.
    pub marked_edges_in: usize,
    /// Marked edges dropped because both ends are (or were welded into) one vertex.
    pub marked_on_one_vertex: usize,
    /// Marked edges dropped for repeating an earlier one (in either direction).
    pub marked_repeated: usize,
    /// Marked edges dropped because no remaining face has them as an edge.
    pub marked_off_faces: usize,
    /// Marked edges after clean-up.
    pub marked_edges_out: usize,
    /// Attribute columns that could not be carried (`"vertex k"`, `"face cluster"`).
    pub dropped_attributes: Vec<String>,
}

impl HygieneReport {
    /// One line per step, for people.
    pub fn lines(&self) -> Vec<String> {
        let o = &self.options;
        let off = |on: bool| if on { "" } else { " (off)" };
        let mut lines = vec![
            format!(
                "weld coincident positions{}: {} vertices merged",
                off(o.weld),
                self.welded_vertices
            ),
            format!(
                "drop faces with a repeated index{}: {}",
                off(o.drop_degenerate),
                self.repeated_index_faces
            ),
            format!(
                "drop zero-area faces{}: {}",
                off(o.drop_degenerate),
                self.zero_area_faces
            ),
            format!(
                "drop duplicate faces{}: {}",
                off(o.drop_duplicate_faces),
                self.duplicate_faces
            ),
            format!(
                "opposite-orientation face pairs kept: {}",
                self.opposite_duplicate_pairs
            ),
            format!(
                "drop unreferenced vertices{}: {}",
                off(o.drop_unreferenced),
                self.unreferenced_vertices
            ),
        ];
        if self.marked_edges_in > 0 {
            lines.extend([
                format!(
                    "drop marked edges with both ends on one vertex: {}",
                    self.marked_on_one_vertex
                ),
                format!("drop repeated marked edges: {}", self.marked_repeated),
                format!(
                    "drop marked edges that are no edge of a face: {}",
                    self.marked_off_faces
                ),
            ]);
        }
        let marked = match self.marked_edges_in {
            0 => String::new(),
            n => format!(", {n} → {} marked edges", self.marked_edges_out),
        };
        lines.push(format!(
            "result: {} → {} vertices, {} → {} faces{marked}",
            self.vertices_in, self.vertices_out, self.faces_in, self.faces_out
        ));
        lines.extend(
            self.dropped_attributes
                .iter()
                .map(|a| format!("attribute {a} dropped")),
        );
        lines
    }

    /// True when clean-up changed nothing.
    pub fn is_clean(&self) -> bool {
        self.vertices_in == self.vertices_out
            && self.faces_in == self.faces_out
            && self.marked_edges_in == self.marked_edges_out
    }
}

/// Splits every non-manifold vertex (several face fans meeting at one point, as at a
/// bow-tie) into one vertex per fan: the first fan keeps the vertex, each other fan gets a
/// copy at the same position with the same attributes. Returns the mesh and the number of
/// copies made (0: the mesh comes back unchanged). Fans do not cross an edge of three or
/// more faces, so the split also opens such edges (and a surface along a line of them:
/// [`cut_non_manifold_edges`] keeps the surface whole).
pub fn split_non_manifold_vertices(mesh: Mesh) -> (Mesh, usize) {
    let topo = crate::Topology::build(&mesh);
    split_non_manifold_vertices_with(mesh, &topo)
}

/// [`split_non_manifold_vertices`] with `topo`, the adjacency of `mesh`, at hand.
pub fn split_non_manifold_vertices_with(mesh: Mesh, topo: &crate::Topology) -> (Mesh, usize) {
    let bad = topo.non_manifold_vertices();
    if bad.is_empty() {
        return (mesh, 0);
    }
    let mut positions = mesh.positions.clone();
    let mut faces = mesh.faces.clone();
    let mut origins = VertexOrigins::identity(mesh.n_vertices());
    let mut copies = 0;
    for &v in &bad {
        for fan in topo.vertex_fans(v).skip(1) {
            let w = positions.len() as Index;
            positions.push(mesh.positions[v as usize]);
            origins.push_copy(v);
            for &f in fan {
                for c in &mut faces[f as usize] {
                    if *c == v {
                        *c = w;
                    }
                }
            }
            copies += 1;
        }
    }
    let face_origins = FaceOrigins::from_parents((0..mesh.n_faces() as Index).collect());
    let (out, _) = mesh.rebuilt(positions, faces, &origins, &face_origins);
    (out, copies)
}

/// Makes every two-sided face one-sided: of the faces on the same three vertices, only
/// the first (in face order) is kept; its reverses (and repeats) are dropped. Returns the
/// mesh and the number of faces dropped (0: the mesh comes back unchanged). Vertices are
/// kept, also those no face uses any more.
pub fn drop_two_sided_faces(mesh: Mesh) -> (Mesh, usize) {
    let order = faces_sharing_vertex_sets(&mesh.faces, |_| true);
    let mut keep = vec![true; mesh.n_faces()];
    let mut dropped = 0;
    for group in order.chunk_by(|a, b| a.0 == b.0) {
        if group.first().map(|g| g.1) == group.last().map(|g| g.1) {
            continue;
        }
        let first = group.iter().map(|g| g.2).min().unwrap_or(0);
        for g in group.iter().filter(|g| g.2 != first) {
            keep[g.2 as usize] = false;
            dropped += 1;
        }
    }
    if dropped == 0 {
        return (mesh, 0);
    }
    let parents: Vec<Index> = (0..mesh.n_faces() as Index)
        .filter(|&f| keep[f as usize])
        .collect();
    let faces = parents.iter().map(|&f| mesh.faces[f as usize]).collect();
    let origins = VertexOrigins::identity(mesh.n_vertices());
    let (out, _) = mesh.rebuilt(
        mesh.positions.clone(),
        faces,
        &origins,
        &FaceOrigins::from_parents(parents),
    );
    (out, dropped)
}

/// Splits 1-to-4 every face of each component that has a boundary loop along fewer than
/// three faces (a lone triangle, two triangles: what cutting a fin off often leaves), so
/// that every loop runs along three faces or more, as a dual needs. Other components are
/// untouched. `topo` is the adjacency of `mesh`. Returns the mesh and the number of faces
/// split (0: unchanged).
pub fn split_small_pieces(mesh: Mesh, topo: &crate::Topology) -> (Mesh, usize) {
    let component = topo.face_components();
    let small = small_pieces(topo);
    let split: Vec<bool> = component
        .iter()
        .map(|c| *c != crate::topology::NONE && small.binary_search(c).is_ok())
        .collect();
    let n_split = split.iter().filter(|&&s| s).count();
    if n_split == 0 {
        return (mesh, 0);
    }
    let mut positions = mesh.positions.clone();
    let mut origins = VertexOrigins::identity(mesh.n_vertices());
    // The midpoint of each edge of a split face, made once.
    let mut midpoint = vec![Index::MAX; topo.n_edges()];
    let mut faces = Vec::with_capacity(mesh.n_faces() + 3 * n_split);
    let mut parents = Vec::with_capacity(faces.capacity());
    for (f, &[a, b, c]) in mesh.faces.iter().enumerate() {
        if !split[f] {
            faces.push([a, b, c]);
            parents.push(f as Index);
            continue;
        }
        let [m0, m1, m2] = topo.face_edges(f as u32).map(|e| {
            let [u, v] = topo.edge(e);
            let m = &mut midpoint[e as usize];
            if *m == Index::MAX {
                *m = positions.len() as Index;
                positions.push((mesh.positions[u as usize] + mesh.positions[v as usize]) * 0.5);
                origins.push_edge(u, v, 0.5);
            }
            *m
        });
        // Edge k of the face runs from corner k to corner k + 1.
        faces.extend(crate::topology::split_children([a, b, c], [m0, m1, m2]));
        parents.extend([f as Index; 4]);
    }
    let (out, _) = mesh.rebuilt(
        positions,
        faces,
        &origins,
        &FaceOrigins::from_parents(parents),
    );
    (out, n_split)
}

/// The components (sorted) of `topo` with a boundary loop along fewer than three faces:
/// those [`split_small_pieces`] splits.
pub fn small_pieces(topo: &crate::Topology) -> Vec<u32> {
    let component = topo.face_components();
    let mut small: Vec<u32> = Vec::new();
    for i in 0..topo.n_boundary_loops() {
        let along = topo.faces_along_loop(i);
        if along.len() < 3
            && let Some(&f) = along.first()
        {
            small.push(component[f as usize]);
        }
    }
    small.sort_unstable();
    small.dedup();
    small
}

/// What [`cut_non_manifold_edges`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EdgeCut {
    /// Edges of three or more faces cut apart.
    pub edges: usize,
    /// Vertex copies added (at those edges' ends, and at non-manifold vertices elsewhere).
    pub copies: usize,
}

/// Cuts every edge of three or more faces apart, and splits every non-manifold vertex
/// into one vertex per face fan: a manifold mesh with the same faces, in the same order.
///
/// At each such edge the faces that use it in opposite directions are paired, the pair
/// whose normals agree best first (the two sides of a surface, ahead of a fin standing on
/// it); each pair stays joined there and every other face's side becomes boundary. A
/// fin on a surface thus comes off it and the surface stays whole, also along a line of
/// such edges. Around each vertex, faces joined across an edge (of two faces, or a
/// pair) make one fan; the fan of the vertex's first face keeps it and every other fan
/// gets a copy at the same position with the same attributes. Two faces using an edge in
/// the same direction stay joined (as in [`crate::Topology`]'s fans), and faces that
/// repeat a vertex keep theirs.
pub fn cut_non_manifold_edges(mesh: Mesh) -> (Mesh, EdgeCut) {
    let topo = crate::Topology::build(&mesh);
    cut_non_manifold_edges_with(mesh, &topo)
}

/// [`cut_non_manifold_edges`] with `topo`, the adjacency of `mesh`, at hand.
pub fn cut_non_manifold_edges_with(mesh: Mesh, topo: &crate::Topology) -> (Mesh, EdgeCut) {
    let mut fans = CornerFans::new(&mesh.faces);
    let (multi, pairs) = join_plain_edges(&mesh, topo, &mut fans);
    let cut = EdgeCut {
        edges: multi.len() / 2,
        copies: 0,
    };
    pair_faces_on_multi_edges(topo, &mut fans, &multi, pairs);
    let parent = fans.parent;
    give_fans_vertices(mesh, topo, parent, cut)
}

/// The corners of a face array joined into fans (those around one vertex that share a
/// fan), by union-find over all corners.
struct CornerFans<'a> {
    faces: &'a [[Index; 3]],
    parent: Vec<u32>,
}

impl CornerFans<'_> {
    fn new(faces: &[[Index; 3]]) -> CornerFans<'_> {
        CornerFans {
            faces,
            parent: (0..3 * faces.len() as u32).collect(),
        }
    }

    /// The fan of face `f`'s corner at `v`.
    fn root(&mut self, f: u32, v: Index) -> u32 {
        let k = corner_of(self.faces, f, v);
        crate::topology::find_root(&mut self.parent, k)
    }

    /// Joins faces `f` and `g` across their edge `[a, b]`: their corners at both ends.
    fn join(&mut self, f: u32, g: u32, [a, b]: [u32; 2]) {
        for v in [a, b] {
            let (x, y) = (self.root(f, v), self.root(g, v));
            self.parent[x.max(y) as usize] = x.min(y);
        }
    }
}

/// The corner of face `f` of `faces` at vertex `v` (as `3 f + c`).
fn corner_of(faces: &[[Index; 3]], f: u32, v: Index) -> u32 {
    let c = faces[f as usize].iter().position(|&u| u == v);
    3 * f + c.unwrap_or(0) as u32
}

/// A candidate pair of faces on an edge of three or more faces: how well their normals
/// agree, the edge, the two faces.
type FacePair = (f64, u32, u32, u32);

/// Joins the faces across every edge of two faces, and lists the edges of three or more
/// (`(end, edge)` for both ends, sorted) with the pairs of their faces that run along them
/// in opposite directions.
fn join_plain_edges(
    mesh: &Mesh,
    topo: &crate::Topology,
    fans: &mut CornerFans<'_>,
) -> (Vec<(Index, u32)>, Vec<FacePair>) {
    let normal = |f: u32| {
        let [a, b, c] = mesh.faces[f as usize].map(|v| mesh.positions[v as usize]);
        coarsen_geom::triangle::cross(a, b, c).normalize_or_zero()
    };
    let mut multi: Vec<(Index, u32)> = Vec::new();
    let mut pairs: Vec<FacePair> = Vec::new();
    for e in 0..topo.n_edges() as u32 {
        let [a, b] = topo.edge(e);
        match topo.edge_faces(e) {
            &[f, g] => fans.join(f, g, [a, b]),
            faces if faces.len() >= 3 => {
                multi.extend([(a, e), (b, e)]);
                // Which way each face runs along the edge: a → b or not.
                let forward = |f: u32| {
                    let face = mesh.faces[f as usize];
                    (0..3).any(|c| face[c] == a && face[(c + 1) % 3] == b)
                };
                for (i, &f) in faces.iter().enumerate() {
                    for &g in &faces[i + 1..] {
                        if forward(f) != forward(g) {
                            pairs.push((normal(f).dot(normal(g)), e, f, g));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    multi.sort_unstable();
    (multi, pairs)
}

/// Joins pairs of faces on the edges of three or more faces, the best agreeing pairs
/// first, each face in one pair at most. A pair is joined only if, around each of its
/// ends, no fan then holds more than two faces of any edge of three or more (else that
/// edge would stay one edge of them all, as when a surface's two sides would each join a
/// side of a two-sided flap).
fn pair_faces_on_multi_edges(
    topo: &crate::Topology,
    fans: &mut CornerFans<'_>,
    multi: &[(Index, u32)],
    mut pairs: Vec<FacePair>,
) {
    pairs.sort_by(|x, y| {
        y.0.total_cmp(&x.0)
            .then((x.1, x.2, x.3).cmp(&(y.1, y.2, y.3)))
    });
    let mut taken = vec![false; fans.faces.len()];
    for &(_, e, f, g) in &pairs {
        if taken[f as usize] || taken[g as usize] {
            continue;
        }
        let ends = topo.edge(e);
        let fits = ends.iter().all(|&v| {
            let roots = [f, g].map(|h| fans.root(h, v));
            let from = multi.partition_point(|&(u, _)| u < v);
            multi[from..]
                .iter()
                .take_while(|&&(u, _)| u == v)
                .all(|&(_, m)| {
                    let inside = topo
                        .edge_faces(m)
                        .iter()
                        .filter(|&&h| roots.contains(&fans.root(h, v)))
                        .count();
                    inside <= 2
                })
        });
        if fits {
            taken[f as usize] = true;
            taken[g as usize] = true;
            fans.join(f, g, ends);
        }
    }
}

/// One vertex per fan (`parent`: the corners' union-find of [`CornerFans`]): around each
/// vertex, the fan of its first face keeps it and every other fan gets a copy at the same
/// position with the same attributes (counted in `cut`).
fn give_fans_vertices(
    mesh: Mesh,
    topo: &crate::Topology,
    mut parent: Vec<u32>,
    mut cut: EdgeCut,
) -> (Mesh, EdgeCut) {
    let nf = mesh.n_faces();
    let mut positions = mesh.positions.clone();
    let mut faces = mesh.faces.clone();
    let mut origins = VertexOrigins::identity(mesh.n_vertices());
    // Per vertex: the fans met so far (their root) and the vertex each was given.
    let mut met: Vec<(u32, Index)> = Vec::new();
    for v in 0..mesh.n_vertices() as Index {
        met.clear();
        for &f in topo.vertex_faces(v) {
            let k = corner_of(&mesh.faces, f, v);
            let root = crate::topology::find_root(&mut parent, k);
            let w = match met.iter().find(|&&(r, _)| r == root) {
                Some(&(_, w)) => w,
                None => {
                    let w = if met.is_empty() {
                        v
                    } else {
                        positions.push(mesh.positions[v as usize]);
                        origins.push_copy(v);
                        cut.copies += 1;
                        (positions.len() - 1) as Index
                    };
                    met.push((root, w));
                    w
                }
            };
            faces[(k / 3) as usize][(k % 3) as usize] = w;
        }
    }
    if cut.copies == 0 {
        return (mesh, cut);
    }
    let face_origins = FaceOrigins::from_parents((0..nf as Index).collect());
    let (out, _) = mesh.rebuilt(positions, faces, &origins, &face_origins);
    (out, cut)
}

/// Runs the clean-up steps `opts` selects on `mesh` (see the module docs).
pub fn clean(mesh: Mesh, opts: &HygieneOptions) -> Result<(Mesh, HygieneReport), HygieneError> {
    mesh.validate_indices()?;
    reject_non_finite(&mesh)?;
    let mut report = empty_report(&mesh, opts);
    let rep = weld_representatives(&mesh, opts.weld, &mut report);
    let faces = welded_faces(&mesh, &rep, opts.weld);
    let mut keep = vec![true; faces.len()];
    if opts.drop_degenerate {
        drop_degenerate_faces(&mesh, &faces, opts, &mut keep, &mut report);
    }
    let (dups, opposite) = mark_duplicates(&faces, &mut keep, opts.drop_duplicate_faces);
    report.duplicate_faces = dups;
    report.opposite_duplicate_pairs = opposite;
    // In the welded numbering, ends of kept faces only: the renumbering below keeps them.
    let marked = clean_marked_edges(&mesh.marked_edges, &rep, &faces, &keep, &mut report);
    report.marked_edges_out = marked.len();
    let numbering = surviving_vertices(&faces, &keep, &rep, opts, &mut report);
    if numbering.old_of_new.len() == mesh.n_vertices() && keep.iter().all(|&k| k) {
        // Nothing welded, dropped or renumbered: the mesh goes on as it came.
        drop(faces);
        return Ok(unchanged(mesh, marked, report));
    }
    let out = renumbered(&mesh, &faces, &keep, &numbering, marked, &mut report);
    Ok((out, report))
}

/// The report before any step: the options and the input's counts, every step at 0.
fn empty_report(mesh: &Mesh, opts: &HygieneOptions) -> HygieneReport {
    HygieneReport {
        options: opts.clone(),
        vertices_in: mesh.n_vertices(),
        faces_in: mesh.n_faces(),
        welded_vertices: 0,
        repeated_index_faces: 0,
        zero_area_faces: 0,
        duplicate_faces: 0,
        opposite_duplicate_pairs: 0,
        unreferenced_vertices: 0,
        vertices_out: 0,
        faces_out: 0,
        marked_edges_in: mesh.marked_edges.len(),
        marked_on_one_vertex: 0,
        marked_repeated: 0,
        marked_off_faces: 0,
        marked_edges_out: 0,
        dropped_attributes: Vec::new(),
    }
}

/// Each vertex's surviving vertex after welding (with `weld`), the welded ones counted.
fn weld_representatives(mesh: &Mesh, weld: bool, report: &mut HygieneReport) -> Vec<Index> {
    // Every vertex maps to the surviving vertex of its position group (itself without welding).
    let rep = if weld {
        weld_map(&mesh.positions)
    } else {
        (0..mesh.n_vertices() as Index).collect()
    };
    report.welded_vertices = rep
        .iter()
        .enumerate()
        .filter(|&(v, &r)| r as usize != v)
        .count();
    rep
}

/// The faces of `mesh` in the welded numbering `rep` (borrowed as they are without `weld`).
fn welded_faces<'a>(
    mesh: &'a Mesh,
    rep: &[Index],
    weld: bool,
) -> std::borrow::Cow<'a, [[Index; 3]]> {
    match weld {
        true => mesh
            .faces
            .par_iter()
            .map(|f| f.map(|v| rep[v as usize]))
            .collect::<Vec<_>>()
            .into(),
        false => mesh.faces.as_slice().into(),
    }
}

/// Unmarks in `keep` the faces that repeat an index or have zero area, counting each kind.
fn drop_degenerate_faces(
    mesh: &Mesh,
    faces: &[[Index; 3]],
    opts: &HygieneOptions,
    keep: &mut [bool],
    report: &mut HygieneReport,
) {
    let threshold = area_threshold(mesh, opts.degenerate_area_rel);
    // Per face: 0 kept, 1 repeats an index, 2 zero area.
    let verdict: Vec<u8> = faces
        .par_iter()
        .enumerate()
        .map(|(f, &[a, b, c])| {
            if a == b || b == c || a == c {
                1
            } else if is_degenerate_area(mesh.face_area(f), threshold) {
                2
            } else {
                0
            }
        })
        .collect();
    for (k, &v) in keep.iter_mut().zip(&verdict) {
        *k = v == 0;
        report.repeated_index_faces += usize::from(v == 1);
        report.zero_area_faces += usize::from(v == 2);
    }
}

/// Where the surviving vertices go: old → new index and back.
struct Numbering {
    /// Each old vertex's new index (`Index::MAX` for one that does not survive).
    new_index: Vec<Index>,
    /// Each new vertex's old index, ascending.
    old_of_new: Vec<Index>,
}

/// The surviving vertices and their new numbering (dropped unreferenced ones counted).
fn surviving_vertices(
    faces: &[[Index; 3]],
    keep: &[bool],
    rep: &[Index],
    opts: &HygieneOptions,
    report: &mut HygieneReport,
) -> Numbering {
    let nv = rep.len();
    // Surviving vertices: group representatives, referenced ones unless told to keep all.
    let mut referenced = vec![false; nv];
    for (f, face) in faces.iter().enumerate() {
        if keep[f] {
            face.iter().for_each(|&v| referenced[v as usize] = true);
        }
    }
    let mut new_index = vec![Index::MAX; nv];
    let mut old_of_new: Vec<Index> = Vec::with_capacity(nv);
    for v in 0..nv {
        if rep[v] as usize != v {
            continue;
        }
        if referenced[v] || !opts.drop_unreferenced {
            new_index[v] = old_of_new.len() as Index;
            old_of_new.push(v as Index);
        } else {
            report.unreferenced_vertices += 1;
        }
    }
    Numbering {
        new_index,
        old_of_new,
    }
}

/// `mesh` as it came, with its cleaned marked edges and the report's output counts.
fn unchanged(
    mut mesh: Mesh,
    marked: Vec<[Index; 2]>,
    mut report: HygieneReport,
) -> (Mesh, HygieneReport) {
    mesh.marked_edges = marked;
    report.vertices_out = mesh.n_vertices();
    report.faces_out = mesh.n_faces();
    (mesh, report)
}

/// The mesh of the kept faces on the surviving vertices, every column carried along.
fn renumbered(
    mesh: &Mesh,
    faces: &[[Index; 3]],
    keep: &[bool],
    numbering: &Numbering,
    marked: Vec<[Index; 2]>,
    report: &mut HygieneReport,
) -> Mesh {
    let Numbering {
        new_index,
        old_of_new,
    } = numbering;
    let kept_faces: Vec<Index> = (0..faces.len() as Index)
        .filter(|&f| keep[f as usize])
        .collect();
    let new_faces: Vec<[Index; 3]> = kept_faces
        .par_iter()
        .map(|&f| faces[f as usize].map(|v| new_index[v as usize]))
        .collect();
    let positions: Vec<DVec3> = old_of_new
        .iter()
        .map(|&v| mesh.positions[v as usize])
        .collect();
    // Corners keep their order in every kept face, also where welding renamed a vertex.
    let wedges = mesh.wedges.follow_faces(&kept_faces, &new_faces);
    let (mut out, carry) = mesh.rebuilt(
        positions,
        new_faces,
        &VertexOrigins::from_map(old_of_new),
        &FaceOrigins::from_parents(kept_faces),
    );
    out.wedges = wedges;
    // The renumbering keeps the vertices' order: the edges stay normalised and sorted.
    out.marked_edges = marked
        .into_iter()
        .map(|e| e.map(|v| new_index[v as usize]))
        .collect();
    report.dropped_attributes = carry
        .dropped
        .iter()
        .map(|(d, n)| format!("{d} {n}"))
        .collect();
    report.vertices_out = out.n_vertices();
    report.faces_out = out.n_faces();
    out
}

/// Rejects the first NaN or infinite position or float attribute, naming it.
fn reject_non_finite(mesh: &Mesh) -> Result<(), HygieneError> {
    match find_non_finite(mesh) {
        None => Ok(()),
        Some(NonFinite::Position(vertex)) => Err(HygieneError::NonFinitePosition {
            vertex,
            position: mesh.positions[vertex].to_array(),
        }),
        Some(NonFinite::Attribute(domain, name, element)) => {
            Err(HygieneError::NonFiniteAttribute {
                domain,
                name,
                element,
            })
        }
    }
}

/// For each vertex, the lowest-numbered vertex at the bit-identical position
/// (`-0.0` counted as `0.0`). Sorting, not hashing: same result on every run.
fn weld_map(positions: &[DVec3]) -> Vec<Index> {
    // Adding +0.0 turns -0.0 into +0.0 and leaves every other value alone.
    let key = |p: DVec3| {
        [
            (p.x + 0.0).to_bits(),
            (p.y + 0.0).to_bits(),
            (p.z + 0.0).to_bits(),
        ]
    };
    // Every entry holds its vertex index, so the (parallel) unstable sort has one outcome.
    let mut order: Vec<([u64; 3], Index)> = positions
        .par_iter()
        .enumerate()
        .map(|(v, &p)| (key(p), v as Index))
        .collect();
    order.par_sort_unstable();
    let mut rep: Vec<Index> = (0..positions.len() as Index).collect();
    let mut first = 0;
    for i in 1..order.len() {
        if order[i].0 == order[first].0 {
            rep[order[i].1 as usize] = order[first].1;
        } else {
            first = i;
        }
    }
    rep
}

/// The marked edges `marked` in the welded numbering `rep` (each vertex's surviving
/// vertex), smaller end first, sorted, without those on one vertex, repeats and those that
/// no kept face (`faces` where `keep`) has as an edge; each drop counted in `report`.
fn clean_marked_edges(
    marked: &[[Index; 2]],
    rep: &[Index],
    faces: &[[Index; 3]],
    keep: &[bool],
    report: &mut HygieneReport,
) -> Vec<[Index; 2]> {
    if marked.is_empty() {
        return Vec::new();
    }
    let mut edges: Vec<[Index; 2]> = marked
        .iter()
        .map(|e| e.map(|v| rep[v as usize]))
        .filter(|[a, b]| a != b)
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    report.marked_on_one_vertex = marked.len() - edges.len();
    edges.sort_unstable();
    edges.dedup();
    report.marked_repeated = marked.len() - report.marked_on_one_vertex - edges.len();
    // Which of them some kept face has: one search per face edge among the marked ones.
    let found: Vec<usize> = faces
        .par_iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .flat_map_iter(|(&[a, b, c], _)| {
            [[a, b], [b, c], [c, a]]
                .into_iter()
                .filter_map(|[u, v]| edges.binary_search(&[u.min(v), u.max(v)]).ok())
        })
        .collect();
    let mut on_face = vec![false; edges.len()];
    found.into_iter().for_each(|i| on_face[i] = true);
    let n = edges.len();
    let mut i = 0;
    edges.retain(|_| {
        i += 1;
        on_face[i - 1]
    });
    report.marked_off_faces = n - edges.len();
    edges
}

/// Among kept faces, marks same-orientation repeats of an earlier face as dropped (when
/// `drop`) and counts them; also counts vertex triples present in both orientations.
fn mark_duplicates(faces: &[[Index; 3]], keep: &mut [bool], drop: bool) -> (usize, usize) {
    let order = faces_sharing_vertex_sets(faces, |f| keep[f]);
    let (mut dups, mut opposite) = (0, 0);
    for group in order.chunk_by(|a, b| a.0 == b.0) {
        // Within a group: one orientation, then the other, each in face order.
        for w in group.windows(2) {
            if w[0].1 == w[1].1 && drop {
                dups += 1;
                keep[w[1].2 as usize] = false;
            }
        }
        if group.first().map(|g| g.1) != group.last().map(|g| g.1) {
            opposite += 1;
        }
    }
    (dups, opposite)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{AttrValues, DVec2};

    #[test]
    fn a_bow_tie_vertex_is_split_into_one_vertex_per_fan() {
        let mut m = crate::fixtures::bowtie();
        let n = m.n_vertices();
        m.vertex_attrs.insert(
            "h",
            AttrValues::Scalar((0..n).map(|v| v as f64 + 0.5).collect()),
        );
        let (out, copies) = split_non_manifold_vertices(m.clone());
        assert_eq!(copies, 1);
        assert_eq!(out.n_vertices(), n + 1);
        assert_eq!(out.positions[n], m.positions[0]);
        assert_eq!(out.vertex_attrs.scalar("h").unwrap()[n], 0.5);
        let t = Topology::build(&out);
        assert!(t.is_manifold());
        assert_eq!(t.n_components(), 2);
        // A manifold mesh comes back as it was.
        let (same, none) = split_non_manifold_vertices(out.clone());
        assert_eq!((same.faces, none), (out.faces, 0));
    }
    use crate::topology::Topology;
    use crate::topology::tests::{read_obj, shared_data};

    /// A flat grid of 4 × 2 quads (vertices `y * 5 + x`) with a fin of three triangles
    /// standing on the two edges 6-7 and 7-8 between its interior vertices.
    fn finned_grid() -> Mesh {
        let mut positions: Vec<DVec3> = (0..15)
            .map(|i| DVec3::new(f64::from(i % 5), f64::from(i / 5), 0.0))
            .collect();
        positions.extend([DVec3::new(1.5, 1.0, 1.0), DVec3::new(2.5, 1.0, 1.0)]);
        let mut faces = Vec::new();
        for y in 0..2 {
            for x in 0..4 {
                let a = y * 5 + x;
                faces.push([a, a + 1, a + 6]);
                faces.push([a, a + 6, a + 5]);
            }
        }
        faces.extend([[6, 7, 15], [7, 16, 15], [7, 8, 16]]);
        Mesh::new(positions, faces)
    }

    #[test]
    fn a_fin_is_cut_off_a_surface_that_stays_whole() {
        let m = finned_grid();
        let before = Topology::build(&m).summary(&m);
        assert_eq!((before.n_non_manifold_edges, before.n_components), (2, 1));
        let (out, cut) = cut_non_manifold_edges(m.clone());
        assert_eq!(
            cut,
            EdgeCut {
                edges: 2,
                copies: 3
            }
        );
        // The grid keeps its vertices; the fin's feet are copies at the same places.
        assert_eq!(out.faces[..16], m.faces[..16]);
        assert_eq!(out.faces[16..], [[17, 18, 15], [18, 16, 15], [18, 19, 16]]);
        assert_eq!(
            out.positions[17..],
            [m.positions[6], m.positions[7], m.positions[8]]
        );
        let s = Topology::build(&out).summary(&out);
        assert!(s.manifold && s.consistently_oriented);
        assert_eq!((s.n_components, s.n_boundary_loops), (2, 2));
        // Splitting fans alone would open the grid along the fin's foot as well.
        let (slit, _) = split_non_manifold_vertices(m);
        let s = Topology::build(&slit).summary(&slit);
        assert_eq!((s.n_components, s.n_boundary_loops), (2, 3));
        // A manifold mesh comes back as it was.
        let (same, none) = cut_non_manifold_edges(out.clone());
        assert_eq!((same.faces, none), (out.faces, EdgeCut::default()));
    }

    #[test]
    fn a_two_sided_face_keeps_its_first_side() {
        let mut m = finned_grid();
        // The fin's first face again, the other way round, and once more the first way.
        m.faces.extend([[6, 15, 7], [7, 15, 6]]);
        let (out, dropped) = drop_two_sided_faces(m.clone());
        assert_eq!(dropped, 2);
        assert_eq!(out.faces, m.faces[..19]);
        assert_eq!(out.n_vertices(), m.n_vertices());
        // Nothing two-sided: the mesh comes back as it was.
        let (same, none) = drop_two_sided_faces(out.clone());
        assert_eq!((same.faces, none), (out.faces, 0));
    }

    #[test]
    fn pieces_too_small_for_a_dual_are_split_one_to_four() {
        // The grid (its loop along eight faces) beside a lone triangle and a quad of two.
        let mut m = finned_grid();
        m.faces.truncate(16);
        let n = m.positions.len() as Index;
        m.positions
            .extend((0..7).map(|i| DVec3::new(f64::from(i), 5.0, 0.0)));
        m.faces.extend([
            [n, n + 1, n + 2],
            [n + 3, n + 4, n + 5],
            [n + 3, n + 5, n + 6],
        ]);
        let (out, split) = split_small_pieces(m.clone(), &Topology::build(&m));
        assert_eq!(split, 3);
        assert_eq!(out.faces[..16], m.faces[..16]);
        assert_eq!(out.n_faces(), 16 + 12);
        let t = Topology::build(&out);
        assert!(small_pieces(&t).is_empty());
        let s = t.summary(&out);
        assert!(s.manifold && s.consistently_oriented);
        assert_eq!((s.n_components, s.n_boundary_loops), (3, 3));
        // Nothing too small: the mesh comes back as it was.
        let (same, none) = split_small_pieces(out.clone(), &t);
        assert_eq!((same.faces, none), (out.faces, 0));
    }

    #[test]
    fn the_sides_of_a_surface_are_paired_before_a_fold_back() {
        // Four faces on edge 0-1: the two halves of a flat square (normals +z), and a
        // double-sided flap raised a little over one half (one face up, one down).
        let m = Mesh::new(
            vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(0.5, 1.0, 0.0),
                DVec3::new(0.5, -1.0, 0.0),
                DVec3::new(0.5, 0.5, 0.2),
            ],
            // Taken in face order, the square's halves would each pair with a flap side.
            vec![[0, 1, 2], [0, 4, 1], [0, 1, 4], [1, 0, 3]],
        );
        let (out, cut) = cut_non_manifold_edges(m);
        assert_eq!(cut.edges, 1);
        // The square's halves stay joined on 0-1; the flap is a closed pair of its own.
        assert_eq!([out.faces[0], out.faces[3]], [[0, 1, 2], [1, 0, 3]]);
        let s = Topology::build(&out).summary(&out);
        assert!(s.manifold);
        assert_eq!((s.n_components, s.n_boundary_loops), (2, 1));
    }

    /// A unit cube as a soup: each of its 12 triangles with three corners of its own.
    fn cube_soup() -> Mesh {
        let corner = |i: u32| {
            DVec3::new(
                f64::from(i & 1),
                f64::from((i >> 1) & 1),
                f64::from((i >> 2) & 1),
            )
        };
        // Corner i at (x, y, z) = bits of i; outward-facing quads as two triangles.
        let quads = [
            [0, 2, 3, 1], // z = 0
            [4, 5, 7, 6], // z = 1
            [0, 1, 5, 4], // y = 0
            [2, 6, 7, 3], // y = 1
            [0, 4, 6, 2], // x = 0
            [1, 3, 7, 5], // x = 1
        ];
        let mut positions = Vec::new();
        let mut faces = Vec::new();
        for q in quads {
            for tri in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
                let base = positions.len() as u32;
                positions.extend(tri.map(corner));
                faces.push([base, base + 1, base + 2]);
            }
        }
        // -0.0 must weld with 0.0.
        positions[0].x = -0.0;
        let mut m = Mesh::new(positions, faces);
        let ids: Vec<f64> = (0..m.n_vertices()).map(|i| i as f64).collect();
        m.vertex_attrs.insert("id", AttrValues::Scalar(ids));
        m
    }

    #[test]
    fn cube_soup_welds_to_eight_vertices_and_a_closed_surface() {
        let (m, r) = clean(cube_soup(), &HygieneOptions::soup()).unwrap();
        assert_eq!((m.n_vertices(), m.n_faces()), (8, 12));
        assert_eq!(r.welded_vertices, 36 - 8);
        assert_eq!(r.unreferenced_vertices, 0);
        let s = Topology::build(&m).summary(&m);
        assert!(s.manifold && s.consistently_oriented);
        assert_eq!(s.genus, vec![Some(0)]);
        assert!((m.signed_volume() - 1.0).abs() < 1e-12);
        // The first occurrence of each position wins: ids are the lowest of each group.
        let ids = m.vertex_attrs.scalar("id").unwrap();
        assert_eq!(ids[0], 0.0);
        assert!(ids.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn welding_keeps_every_corner_value_as_wedges() {
        // Each cube face a UV chart of its own: the corners of one position disagree.
        let soup = cube_soup();
        let corner_uv: Vec<DVec2> = (0..3 * soup.n_faces())
            .map(|c| {
                let p = soup.positions[soup.faces[c / 3][c % 3] as usize];
                DVec2::new((c / 6) as f64, p.x + 2.0 * p.y + 4.0 * p.z)
            })
            .collect();
        let mut cols = crate::Attributes::default();
        cols.insert("uv", AttrValues::Vec2(corner_uv.clone()));
        // Kept as wedges although each soup vertex has one value (as a glTF reader would).
        let mut m = soup;
        m.wedges = crate::Wedges::from_corners(&m.faces, cols);
        let (m, _) = clean(m, &HygieneOptions::soup()).unwrap();
        assert_eq!(m.n_vertices(), 8);
        assert!(m.validate_indices().is_ok());
        assert_eq!(m.corner_column("uv"), Some(AttrValues::Vec2(corner_uv)));
        // Every cube corner is on three charts.
        assert_eq!(m.wedges.split_vertices(), 8);
        assert_eq!(m.wedges.len(), 24);
    }

    #[test]
    fn without_weld_a_soup_only_loses_nothing() {
        let (m, r) = clean(cube_soup(), &HygieneOptions::default()).unwrap();
        assert_eq!((m.n_vertices(), m.n_faces()), (36, 12));
        assert!(r.is_clean());
        assert_eq!(r.lines().len(), 7);
        assert!(r.lines()[0].contains("(off): 0 vertices merged"));
    }

    #[test]
    fn nan_vertex_is_rejected_with_its_index() {
        let mut m = cube_soup();
        m.positions[7].z = f64::NAN;
        assert!(matches!(
            clean(m, &HygieneOptions::default()),
            Err(HygieneError::NonFinitePosition { vertex: 7, .. })
        ));
    }

    #[test]
    fn infinite_attribute_is_rejected_with_its_element() {
        let mut m = cube_soup();
        let mut ids = vec![0.0; 36];
        ids[30] = f64::NEG_INFINITY;
        m.vertex_attrs.insert("id", AttrValues::Scalar(ids));
        assert_eq!(
            clean(m, &HygieneOptions::default()),
            Err(HygieneError::NonFiniteAttribute {
                domain: Domain::Vertex,
                name: "id".into(),
                element: 30
            })
        );
    }

    /// The unit square's corners (0–3), a point beyond corner 1 on its line (4) and one
    /// above the square (5).
    fn square_and_two() -> Vec<DVec3> {
        vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::Y,
            DVec3::X * 2.0,
            DVec3::Z,
        ]
    }

    #[test]
    fn degenerate_and_duplicate_faces_are_dropped_and_counted_separately() {
        // 3---2
        // | / |      faces: 0-1-2, 0-2-3, then 1-2-0 (rotation of face 0: dropped),
        // 0---1      2-1-0 (opposite of face 0: kept), 1-1-3 (repeated), 0-1-4 (flat),
        //            and vertex 5 unused.
        let positions = square_and_two();
        let faces = vec![
            [0, 1, 2],
            [0, 2, 3],
            [1, 2, 0],
            [2, 1, 0],
            [1, 1, 3],
            [0, 1, 4],
        ];
        let mut m = Mesh::new(positions, faces);
        m.face_attrs
            .insert("tag", AttrValues::Label(vec![10, 11, 12, 13, 14, 15]));
        let (out, r) = clean(m, &HygieneOptions::default()).unwrap();
        assert_eq!(r.repeated_index_faces, 1);
        assert_eq!(r.zero_area_faces, 1);
        assert_eq!(r.duplicate_faces, 1);
        assert_eq!(r.opposite_duplicate_pairs, 1);
        assert_eq!(
            r.unreferenced_vertices, 2,
            "4 (only on the flat face) and 5"
        );
        assert_eq!(out.faces, vec![[0, 1, 2], [0, 2, 3], [2, 1, 0]]);
        assert_eq!(out.face_attrs.label("tag").unwrap(), &[10, 11, 13]);
        assert_eq!(out.n_vertices(), 4);
    }

    #[test]
    fn marked_edges_follow_the_clean_up_and_the_dropped_ones_are_counted() {
        // The mesh of the test above: vertex 4 only on the flat face, vertex 5 unused.
        let positions = square_and_two();
        let faces = vec![[0, 1, 2], [0, 2, 3], [1, 1, 3], [0, 1, 4]];
        let mut m = Mesh::new(positions, faces);
        // 1-0 kept (as 0-1), 0-1 repeats it, 3-3 is one vertex, 1-3 was only on the face
        // with a repeated index, 1-4 only on the flat one, 5-0 on none; 3-2 kept (as 2-3).
        m.marked_edges = vec![[1, 0], [0, 1], [3, 3], [1, 3], [1, 4], [5, 0], [3, 2]];
        let (out, r) = clean(m, &HygieneOptions::default()).unwrap();
        assert_eq!(out.marked_edges, vec![[0, 1], [2, 3]]);
        assert_eq!(
            (
                r.marked_edges_in,
                r.marked_on_one_vertex,
                r.marked_repeated,
                r.marked_off_faces,
                r.marked_edges_out
            ),
            (7, 1, 1, 3, 2)
        );
        let lines = r.lines();
        for line in [
            "drop marked edges with both ends on one vertex: 1",
            "drop repeated marked edges: 1",
            "drop marked edges that are no edge of a face: 3",
            "result: 6 → 4 vertices, 4 → 2 faces, 7 → 2 marked edges",
        ] {
            assert!(lines.iter().any(|l| l == line), "{line}: {lines:?}");
        }
        assert!(!r.is_clean());
    }

    #[test]
    fn marked_edges_are_welded_with_their_vertices() {
        let mut m = cube_soup();
        // The diagonal of the cube's side z = 0 as soup face 0 has it, again (the other
        // way round) as soup face 1 has it, and an edge between two copies of one corner.
        let [a, _, c] = m.faces[0];
        let [d, e, _] = m.faces[1];
        assert_eq!(m.positions[a as usize], m.positions[d as usize]);
        assert_eq!(m.positions[c as usize], m.positions[e as usize]);
        m.marked_edges = vec![[a, c], [e, d], [a, d]];
        let (ends_a, ends_c) = (m.positions[a as usize], m.positions[c as usize]);
        let (out, r) = clean(m, &HygieneOptions::soup()).unwrap();
        assert_eq!((r.marked_on_one_vertex, r.marked_repeated), (1, 1));
        assert_eq!(out.marked_edges.len(), 1);
        let [u, v] = out.marked_edges[0];
        assert!(u < v);
        let mut got = [out.positions[u as usize], out.positions[v as usize]];
        let mut want = [ends_a, ends_c];
        got.sort_by(|p, q| p.to_array().partial_cmp(&q.to_array()).unwrap());
        want.sort_by(|p, q| p.to_array().partial_cmp(&q.to_array()).unwrap());
        assert_eq!(got, want);
        // Without marked edges the report has no line about them.
        let (_, plain) = clean(cube_soup(), &HygieneOptions::soup()).unwrap();
        assert!(plain.lines().iter().all(|l| !l.contains("marked")));
    }

    #[test]
    fn marked_edges_of_a_clean_mesh_are_put_in_order() {
        let mut m = Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        m.marked_edges = vec![[2, 1], [0, 2], [1, 0]];
        let (out, r) = clean(m.clone(), &HygieneOptions::default()).unwrap();
        assert!(r.is_clean());
        assert_eq!(out.marked_edges, vec![[0, 1], [0, 2], [1, 2]]);
        assert_eq!((out.positions, out.faces), (m.positions, m.faces));
    }

    #[test]
    fn an_out_of_range_marked_edge_is_refused() {
        let mut m = cube_soup();
        m.marked_edges = vec![[0, 1], [2, 99]];
        assert_eq!(
            clean(m, &HygieneOptions::default()),
            Err(HygieneError::Index(IndexError::EdgeOutOfRange {
                edge: 1,
                vertex: 99,
                n_vertices: 36
            }))
        );
    }

    #[test]
    fn a_clean_mesh_comes_back_as_it_came() {
        let mut m = Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        m.vertex_attrs
            .insert("k", AttrValues::Scalar(vec![0.5, 1.5, 2.5, 3.5]));
        m.face_attrs.insert("tag", AttrValues::Label(vec![7, 9]));
        let (out, r) = clean(m.clone(), &HygieneOptions::default()).unwrap();
        assert!(r.is_clean());
        assert_eq!((r.vertices_out, r.faces_out), (4, 2));
        assert_eq!(out, m);
    }

    #[test]
    fn switched_off_steps_keep_everything_and_say_so() {
        let m = Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
            vec![[0, 1, 2], [0, 1, 2], [1, 1, 2]],
        );
        let opts = HygieneOptions {
            weld: false,
            drop_degenerate: false,
            degenerate_area_rel: 0.0,
            drop_duplicate_faces: false,
            drop_unreferenced: false,
        };
        let (out, r) = clean(m.clone(), &opts).unwrap();
        assert_eq!(out, m);
        assert!(r.lines().iter().filter(|l| l.contains("(off)")).count() >= 4);
    }

    #[test]
    fn clean_is_deterministic() {
        let a = clean(cube_soup(), &HygieneOptions::soup()).unwrap();
        let b = clean(cube_soup(), &HygieneOptions::soup()).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn bunny_loses_its_unreferenced_vertices() {
        let Some(dir) = shared_data() else {
            return;
        };
        let m = read_obj(&dir.join("stanford-bunny.obj"));
        let (out, r) = clean(m, &HygieneOptions::default()).unwrap();
        assert_eq!(r.unreferenced_vertices, 1113);
        assert_eq!(out.n_vertices(), 35947 - 1113);
        assert_eq!(out.n_faces(), 69451);
        let s = Topology::build(&out).summary(&out);
        assert_eq!(s.n_isolated_vertices, 0);
        assert_eq!(s.n_boundary_loops, 5);
    }

    #[test]
    fn suzanne_keeps_and_reports_its_two_sided_face() {
        let Some(dir) = shared_data() else {
            return;
        };
        let m = read_obj(&dir.join("suzanne.obj"));
        let (out, r) = clean(m, &HygieneOptions::default()).unwrap();
        assert_eq!(r.opposite_duplicate_pairs, 1);
        assert_eq!(r.duplicate_faces, 0);
        assert_eq!(out.n_faces(), 968);
    }

    #[test]
    fn the_shared_meshes_with_edges_of_three_faces_come_out_manifold() {
        let Some(dir) = shared_data() else {
            return;
        };
        // Suzanne's two-sided face stands on an edge of its surface: the surface's two
        // sides pair up there, and the face's two sides close on each other.
        for (name, edges, components) in [("suzanne", 1, 4), ("beetle", 47, 15)] {
            let (m, _) = clean(
                read_obj(&dir.join(format!("{name}.obj"))),
                &Default::default(),
            )
            .unwrap();
            let (out, cut) = cut_non_manifold_edges(m);
            assert_eq!(cut.edges, edges, "{name}");
            let s = Topology::build(&out).summary(&out);
            assert!(s.manifold, "{name}: {s:?}");
            assert_eq!(s.n_components, components, "{name}");
        }
    }

    #[test]
    fn welding_the_teapot_merges_its_403_duplicated_positions() {
        let Some(dir) = shared_data() else {
            return;
        };
        let m = read_obj(&dir.join("teapot.obj"));
        let (out, r) = clean(m, &HygieneOptions::soup()).unwrap();
        assert_eq!(r.welded_vertices, 403);
        assert_eq!(out.n_vertices(), 3644 - 403);
        // Welded, the seams close: the README's 4 parts become 4 components.
        let s = Topology::build(&out).summary(&out);
        assert_eq!(s.n_components, 4);
    }
}
