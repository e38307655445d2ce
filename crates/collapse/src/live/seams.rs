//! Per-corner attributes through collapses: UV seams and hard edges as constraints, each
//! face corner's wedge kept current, and the output's wedge values.
//!
//! A *seam edge* is an edge whose two faces disagree at either end on a per-corner value
//! other than the normal (a UV seam, a colour edge): a hard edge of normals alone is no
//! seam, as flat-shaded meshes would otherwise not simplify at all; normals are carried
//! across it like any value. Every vertex gets a class when tracking starts
//! ([`LiveMesh::track_seams`]):
//!
//! | class | what | may |
//! | --- | --- | --- |
//! | free | one wedge, no seam edge | move, merge, be merged |
//! | curve | two wedges, two seam edges, not on the boundary | be merged along a seam edge into a curve or corner vertex; take in free vertices; never moves |
//! | corner | anything else on a seam: a seam's end, where seams meet, a seam on the boundary | take in free vertices and curve vertices along a seam edge; never moves nor goes |
//!
//! So seam vertices keep their input positions and their wedges' values exactly; a
//! collapse joins the two sides of a seam only where both were one side already. A merge
//! of two curve vertices along their seam edge keeps the end that costs less (both are
//! planned). A triangle collapse may hold at most one seam vertex.
//!
//! No collapse may turn a face over in UV space or flatten it there (refused as `seam`):
//! the test reads each wedge's UV as the collapses left it — exact at vertices that did not
//! move, along the merged edge (or triangle) at the point nearest the new position for a
//! vertex that did. The parts of the parallel phase do not test it (the whole mesh's
//! serial phase does), and keep those estimates of the vertices they merged at the kept
//! vertex's input UV.
//!
//! After each collapse the corners of the merged vertex take the wedges of the kept one,
//! side by side: the faces the collapse deleted pair up the wedges of the merged vertices.
//! On output, a wedge of an unmoved vertex keeps its input value; a vertex that moved (a
//! free one: its merged input vertices all free) gets, in every per-corner column, the
//! value at its nearest point on the input faces around the vertices it merged, all on one
//! side of any seam.

use super::LiveMesh;
use crate::{Index, NONE, VertexKind};
use coarsen_geom::{DVec2, DVec3};
use coarsen_mesh::{AttrValues, Attributes, Mesh, Wedges};
use coarsen_spatial::closest_point_on_triangle;
use rayon::prelude::*;
use std::sync::Arc;

/// A vertex on no seam.
pub(crate) const FREE: u8 = 0;
/// A vertex inside a seam curve: two wedges, two seam edges.
pub(crate) const CURVE: u8 = 1;
/// Any other vertex on a seam: it stays.
pub(crate) const CORNER: u8 = 2;

/// The live seam state: each vertex's class and each face slot's corner wedges (input
/// wedge indices), renumbered with the live mesh's arrays.
#[derive(Clone, Debug)]
pub(crate) struct SeamState {
    pub(crate) class: Vec<u8>,
    pub(crate) wedge: Vec<[Index; 3]>,
    /// Per input wedge, the first wedge of its vertex that agrees with it on every column
    /// but `normal`: two corners are on one side of a seam when these agree.
    pub(crate) seam_of: Arc<Vec<Index>>,
    /// Each wedge's UV as the collapses left it (a merged free vertex's estimated along
    /// the merged edge or triangle), when the wedges carry a `uv` column: for the fold
    /// test. The whole mesh only: parts test no folds.
    pub(crate) uv: Option<Vec<DVec2>>,
    /// The input the wedge values come from (the whole mesh only; parts have none).
    pub(crate) source: Option<Box<Source>>,
}

/// The input's wedges, in the input's numbering (its geometry is the live mesh's
/// [`InputSurface`]).
#[derive(Clone, Debug)]
pub(crate) struct Source {
    wedges: Wedges,
}

/// The sides of one merge: which wedge each side (a `seam_of` class of a vertex that
/// goes) takes, a few pairs in place.
#[derive(Default)]
pub(crate) struct Sides {
    pairs: [(Index, Index); 16],
    len: usize,
}

impl Sides {
    /// The wedge side `side` takes, if named.
    fn find(&self, side: Index) -> Option<Index> {
        self.pairs[..self.len]
            .iter()
            .find(|p| p.0 == side)
            .map(|p| p.1)
    }

    /// Names the wedge of `side` unless it is named already (or the pairs are full: a
    /// merge touches a handful of faces).
    fn insert(&mut self, side: Index, wedge: Index) {
        if self.len < self.pairs.len() && self.find(side).is_none() {
            self.pairs[self.len] = (side, wedge);
            self.len += 1;
        }
    }
}

/// Where a merge must put its vertex, by the boundary and seam rules.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Pin {
    /// Anywhere the model likes.
    Free,
    /// At this vertex's position (it is kept).
    At(Index),
    /// At one of these two (the cheaper is kept).
    Either(Index, Index),
}

impl LiveMesh {
    /// Tracks `mesh`'s per-corner attributes (its wedges) through the collapses, with its
    /// seams as constraints (module docs); call before any collapse, with the mesh this
    /// live mesh was built from, whose positions, faces and wedges it takes (the output's
    /// wedge values come from them). Returns how many vertices lie on seams (0, tracking
    /// nothing and taking nothing, when the mesh has no wedges).
    pub fn track_seams(&mut self, mesh: &mut Mesh) -> usize {
        if mesh.wedges.is_empty()
            || mesh.n_faces() != self.faces.len()
            || self.base_face.is_some()
            || mesh.wedges.check(&mesh.faces).is_err()
        {
            return 0;
        }
        let wedge: Vec<[Index; 3]> = (0..mesh.n_faces())
            .map(|f| std::array::from_fn(|k| mesh.wedges.corner(f, k)))
            .collect();
        let mut state = SeamState {
            class: Vec::new(),
            wedge,
            seam_of: Arc::new(seam_of(&mesh.wedges)),
            uv: mesh.wedges.attrs().vec2("uv").map(<[DVec2]>::to_vec),
            source: None,
        };
        state.class = (0..self.pos.len() as Index)
            .into_par_iter()
            .map(|v| self.seam_class(&state, v))
            .collect();
        let on_seams = state.class.iter().filter(|&&c| c != FREE).count();
        state.source = Some(Box::new(Source {
            wedges: std::mem::take(&mut mesh.wedges),
        }));
        self.keep_input_surface(mesh);
        self.seams = Some(state);
        on_seams
    }

    /// Whether the collapses track wedges ([`LiveMesh::track_seams`]).
    pub fn tracks_seams(&self) -> bool {
        self.seams.is_some()
    }

    /// The UVs of face `f`'s corners as the collapses left them, when seams and UVs are
    /// tracked (the whole mesh only: parts track none).
    pub fn face_uvs(&self, f: Index) -> Option<[DVec2; 3]> {
        let state = self.seams.as_ref()?;
        let uv = state.uv.as_ref()?;
        Some(state.wedge.get(f as usize)?.map(|w| uv[w as usize]))
    }

    /// The class of vertex `v` by its faces' corner wedges (module docs).
    fn seam_class(&self, state: &SeamState, v: Index) -> u8 {
        match self.kind[v as usize] {
            VertexKind::Isolated => return FREE,
            VertexKind::Locked => return CORNER,
            VertexKind::Interior | VertexKind::Boundary => {}
        }
        // (neighbour, side at v, side at the neighbour) for each face edge at v, in place
        // (a vertex of more faces than that is kept as a corner).
        const MOST: usize = 32;
        let around = self.lists.get(v);
        if around.len() > MOST {
            return CORNER;
        }
        let mut sides = [(NONE, NONE, NONE); 2 * MOST];
        let mut at_v = [NONE; MOST];
        for (i, &f) in around.iter().enumerate() {
            let face = self.faces[f as usize];
            let k = super::corner_of(face, v);
            let w = state.wedge[f as usize].map(|w| state.seam_of[w as usize]);
            at_v[i] = w[k];
            sides[2 * i] = (face[(k + 1) % 3], w[k], w[(k + 1) % 3]);
            sides[2 * i + 1] = (face[(k + 2) % 3], w[k], w[(k + 2) % 3]);
        }
        let at_v = &mut at_v[..around.len()];
        at_v.sort_unstable();
        let distinct = 1 + at_v.windows(2).filter(|p| p[0] != p[1]).count();
        let sides = &mut sides[..2 * around.len()];
        sides.sort_unstable();
        let mut seam_edges = 0;
        for run in sides.chunk_by(|a, b| a.0 == b.0) {
            if run.len() == 2 && run[0] != run[1] {
                seam_edges += 1;
            } else if run.len() > 2 {
                return CORNER;
            }
        }
        match (distinct.min(around.len()), seam_edges) {
            (0 | 1, 0) => FREE,
            (2, 2) if self.kind[v as usize] == VertexKind::Interior => CURVE,
            _ => CORNER,
        }
    }

    /// Whether edge `a`–`b` is a seam edge: its two faces disagree on a wedge at either
    /// end (an edge without exactly two faces counts as one).
    fn is_seam_edge(&self, state: &SeamState, a: Index, b: Index) -> bool {
        let mut found = [(NONE, NONE); 2];
        let mut n = 0;
        for &f in self.lists.get(a) {
            let face = self.faces[f as usize];
            if face.contains(&b) {
                let w = state.wedge[f as usize].map(|w| state.seam_of[w as usize]);
                if n < 2 {
                    found[n] = (w[super::corner_of(face, a)], w[super::corner_of(face, b)]);
                }
                n += 1;
            }
        }
        n != 2 || found[0] != found[1]
    }

    /// The seam rules on top of the boundary rules' `pinned` (module docs).
    pub(super) fn seam_rule(
        &self,
        verts: &[Index],
        pinned: Option<Index>,
    ) -> Result<Pin, super::Refusal> {
        let Some(state) = &self.seams else {
            return Ok(pinned.map_or(Pin::Free, Pin::At));
        };
        let class = |v: Index| state.class[v as usize];
        let mut on = [NONE; 3];
        let mut n = 0;
        for &v in verts {
            if class(v) != FREE {
                on[n] = v;
                n += 1;
            }
        }
        let pin = match n {
            0 => return Ok(pinned.map_or(Pin::Free, Pin::At)),
            1 => Pin::At(on[0]),
            2 if self.is_seam_edge(state, on[0], on[1]) => match (class(on[0]), class(on[1])) {
                (CURVE, CURVE) => Pin::Either(on[0], on[1]),
                (CORNER, CURVE) => Pin::At(on[0]),
                (CURVE, CORNER) => Pin::At(on[1]),
                _ => return Err(super::Refusal::Seam),
            },
            _ => return Err(super::Refusal::Seam),
        };
        match (pinned, pin) {
            (None, pin) => Ok(pin),
            (Some(b), Pin::At(v)) if b == v => Ok(pin),
            (Some(b), Pin::Either(x, y)) if b == x || b == y => Ok(Pin::At(b)),
            _ => Err(super::Refusal::Seam),
        }
    }

    /// Whether merging `verts` into `kept` at `p` would turn a kept face over in UV
    /// space, or flatten it there: the merged corners take `kept`'s wedge on their side,
    /// whose UV is [`Self::merged_uv`]'s.
    pub(super) fn folds_uvs(&self, verts: &[Index], kept: Index, p: DVec3) -> bool {
        let Some(state) = &self.seams else {
            return false;
        };
        let Some(uv) = &state.uv else {
            return false;
        };
        // The faces to be deleted: those holding two merged vertices.
        let deleted = verts
            .iter()
            .flat_map(|&v| self.lists.get(v))
            .copied()
            .filter(|&f| {
                let face = self.faces[f as usize];
                face.iter().filter(|u| verts.contains(u)).count() >= 2
            });
        let group = self.wedge_groups(state, deleted, verts, kept);
        let moved = self.merged_uv(state, uv, verts, kept, p);
        let uv_of = |w: Index, after: bool| match moved {
            Some((mw, m)) if after && w == mw => m,
            _ => uv[w as usize],
        };
        let area = |w: [Index; 3], after: bool| {
            let [a, b, c] = w.map(|w| uv_of(w, after));
            (b - a).perp_dot(c - a)
        };
        for &v in verts {
            for &f in self.lists.get(v) {
                let face = self.faces[f as usize];
                if face.iter().filter(|u| verts.contains(u)).count() >= 2 {
                    continue;
                }
                let before = state.wedge[f as usize];
                let k = super::corner_of(face, v);
                let mut after = before;
                let side = state.seam_of[before[k] as usize];
                if let Some(g) = group.find(side) {
                    after[k] = g;
                }
                let (a0, a1) = (area(before, false), area(after, true));
                if a0 * a1 < 0.0 || (a1 == 0.0 && a0 != 0.0) {
                    return true;
                }
            }
        }
        false
    }

    /// [`Self::merged_uv`] when seams and UVs are tracked: ask before the merge.
    pub(super) fn moved_uv(
        &self,
        verts: &[Index],
        kept: Index,
        p: DVec3,
    ) -> Option<(Index, DVec2)> {
        let state = self.seams.as_ref()?;
        self.merged_uv(state, state.uv.as_ref()?, verts, kept, p)
    }

    /// When the merge of free vertices `verts` into `kept` moves it to `p`: its wedge and
    /// the UV there, estimated from the merged vertices' (their weights of the point of
    /// the merged edge or triangle nearest `p`). `None` when a seam vertex stays.
    fn merged_uv(
        &self,
        state: &SeamState,
        uv: &[DVec2],
        verts: &[Index],
        kept: Index,
        p: DVec3,
    ) -> Option<(Index, DVec2)> {
        if state.class[kept as usize] != FREE {
            return None;
        }
        let wedge_of = |v: Index| -> Option<Index> {
            let &f = self.lists.get(v).first()?;
            let face = self.faces[f as usize];
            Some(state.wedge[f as usize][super::corner_of(face, v)])
        };
        let pos = |i: usize| self.pos[verts[i] as usize];
        let weights: [f64; 3] = match verts.len() {
            2 => {
                let (a, b) = (pos(0), pos(1));
                let ab = b - a;
                let len2 = ab.length_squared();
                let t = if len2 > 0.0 {
                    ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
                } else {
                    0.5
                };
                [1.0 - t, t, 0.0]
            }
            _ => closest_point_on_triangle(p, pos(0), pos(1), pos(2)).1,
        };
        let mut at = DVec2::ZERO;
        for (i, &v) in verts.iter().enumerate() {
            at += weights[i] * uv[wedge_of(v)? as usize];
        }
        Some((wedge_of(kept)?, at))
    }

    /// Pairs (side, wedge) of a merge of `verts` into `kept`: within each of the `deleted`
    /// faces, the corners of the vertices that go are on the side of the kept vertex's
    /// wedge there. A side is a `seam_of` class (a vertex's wedges that differ in the
    /// normal alone are one side), so that every corner of a vertex that goes finds its
    /// side; the kept vertex's own corners keep theirs.
    fn wedge_groups(
        &self,
        state: &SeamState,
        deleted: impl Iterator<Item = Index>,
        verts: &[Index],
        kept: Index,
    ) -> Sides {
        let mut group = Sides::default();
        for f in deleted {
            let face = self.faces[f as usize];
            let w = state.wedge[f as usize];
            let mut members = [NONE; 3];
            let mut keeper = NONE;
            for k in 0..3 {
                if face[k] == kept {
                    keeper = w[k];
                } else if verts.contains(&face[k]) {
                    members[k] = state.seam_of[w[k] as usize];
                }
            }
            let members = members.into_iter().filter(|&m| m != NONE);
            // A face without a corner at `kept` (the outer faces of a triangle collapse)
            // joins the side of a wedge named before.
            if keeper == NONE {
                keeper = members.clone().find_map(|m| group.find(m)).unwrap_or(NONE);
            }
            if keeper == NONE {
                continue;
            }
            for m in members {
                group.insert(m, keeper);
            }
        }
        group
    }

    /// After `verts` merged into `kept`: the corners of the kept faces that were the
    /// merged vertices' take the kept vertex's wedge on their side ([`Self::wedge_groups`]
    /// of the faces the merge deleted).
    /// `moved` is [`Self::moved_uv`]'s answer, asked before the merge.
    pub(super) fn carry_wedges(
        &mut self,
        verts: &[Index],
        kept: Index,
        moved: Option<(Index, DVec2)>,
    ) {
        let Some(state) = &self.seams else {
            return;
        };
        let group = self.wedge_groups(state, self.last_deleted.iter().copied(), verts, kept);
        let Some(state) = &mut self.seams else {
            return;
        };
        for &f in self.lists.get(kept) {
            let k = super::corner_of(self.faces[f as usize], kept);
            let w = &mut state.wedge[f as usize][k];
            let side = state.seam_of[*w as usize];
            if let Some(g) = group.find(side) {
                *w = g;
            }
        }
        if let (Some((w, at)), Some(uv)) = (moved, &mut state.uv) {
            uv[w as usize] = at;
        }
    }

    /// The output's wedges for its `faces` (the live face slots `slots`, in order) and
    /// vertices (`positions`, each standing for the input vertices `members[v]`; the input
    /// points nearest the moved ones found already in `nearest`:
    /// [`LiveMesh::nearest_points`]), or `None` when no seams are tracked.
    pub(super) fn output_wedges(
        &self,
        slots: &[Index],
        faces: &[[Index; 3]],
        positions: &[DVec3],
        members: &[Vec<Index>],
        nearest: &[Option<(Index, [f64; 3])>],
    ) -> Option<Wedges> {
        let state = self.seams.as_ref()?;
        let source = state.source.as_ref()?;
        let surface = self.input.as_deref()?;
        let input = &source.wedges;
        // Each output corner's wedge, keyed by (input wedge, output vertex): a wedge is one
        // vertex's, even should a corner keep a wedge of another vertex.
        let mut keys: Vec<(Index, Index)> = Vec::new();
        let mut corner_key: Vec<Index> = Vec::with_capacity(3 * faces.len());
        let mut index_of = std::collections::HashMap::new();
        for (&slot, face) in slots.iter().zip(faces) {
            for (&w, &v) in state.wedge[slot as usize].iter().zip(face) {
                let key = (w, v);
                let i = *index_of.entry(key).or_insert_with(|| {
                    keys.push(key);
                    keys.len() as Index - 1
                });
                corner_key.push(i);
            }
        }
        let around = surface.around();
        // Per output wedge, where its values come from: an input wedge as it is, or a
        // point in an input face (barycentric weights).
        let from: Vec<From> = keys
            .par_iter()
            .map(|&(w, v)| {
                let p = positions[v as usize];
                let own = input.vertices()[w as usize];
                if surface.positions[own as usize] == p {
                    return From::Wedge(w);
                }
                nearest[v as usize]
                    .or_else(|| surface.nearest_around(around, &members[v as usize], p))
                    .map_or(From::Wedge(w), |(f, bary)| From::Point(f, bary))
            })
            .collect();
        let mut columns = Attributes::default();
        for (name, values) in input.attrs().iter() {
            let per_wedge = interpolate(values, &from, |f, k| input.corner(f as usize, k));
            let per_wedge = match (name, per_wedge) {
                ("normal", AttrValues::Vec3(n)) => {
                    AttrValues::Vec3(n.into_iter().map(|n| n.normalize_or_zero()).collect())
                }
                (_, v) => v,
            };
            columns.insert(name, per_wedge.gather(&corner_key));
        }
        Some(Wedges::from_corners(faces, columns))
    }
}

/// Per wedge of `wedges`, the first wedge of its vertex holding bit for bit the same
/// values in every column but `normal` (a hard edge of normals alone is no seam: the
/// normals are carried across it by interpolation).
fn seam_of(wedges: &Wedges) -> Vec<Index> {
    let columns: Vec<&AttrValues> = wedges
        .attrs()
        .iter()
        .filter(|(name, _)| *name != "normal")
        .map(|(_, v)| v)
        .collect();
    // Each vertex's wedges in order (CSR), then each wedge against the earlier ones.
    let vertex = wedges.vertices();
    let n = vertex.iter().map(|&v| v as usize + 1).max().unwrap_or(0);
    let mut start = vec![0usize; n + 1];
    for &v in vertex {
        start[v as usize + 1] += 1;
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut list = vec![0 as Index; vertex.len()];
    for (w, &v) in vertex.iter().enumerate() {
        list[fill[v as usize]] = w as Index;
        fill[v as usize] += 1;
    }
    let same = |a: Index, b: Index| {
        columns
            .iter()
            .all(|c| bits(c, a as usize) == bits(c, b as usize))
    };
    (0..vertex.len())
        .into_par_iter()
        .map(|w| {
            let v = vertex[w] as usize;
            let w = w as Index;
            list[start[v]..start[v + 1]]
                .iter()
                .copied()
                .find(|&e| e == w || same(e, w))
                .unwrap_or(w)
        })
        .collect()
}

/// The bits of value `i` of a column.
fn bits(values: &AttrValues, i: usize) -> [u64; 3] {
    match values {
        AttrValues::Scalar(v) => [v[i].to_bits(), 0, 0],
        AttrValues::Vec2(v) => [v[i].x.to_bits(), v[i].y.to_bits(), 0],
        AttrValues::Vec3(v) => v[i].to_array().map(f64::to_bits),
        AttrValues::Label(v) => [u64::from(v[i]), 0, 0],
        AttrValues::Color(v) => [v[i].map(u64::from).iter().fold(0, |a, &c| a << 8 | c), 0, 0],
    }
}
/// Where an output wedge's values come from.
enum From {
    /// The input wedge, as it is.
    Wedge(Index),
    /// The point of input face `.0` with barycentric weights `.1`.
    Point(Index, [f64; 3]),
}

/// One value per output wedge of the input wedge column `values`: copied, or blended from
/// the corners (`corner(face, k)`: their input wedges) of a face.
fn interpolate(
    values: &AttrValues,
    from: &[From],
    corner: impl Fn(Index, usize) -> Index,
) -> AttrValues {
    let mixes: Vec<([Index; 3], [f64; 3])> = from
        .iter()
        .map(|i| match *i {
            From::Wedge(w) => ([w; 3], [1.0, 0.0, 0.0]),
            From::Point(f, bary) => (std::array::from_fn(|k| corner(f, k)), bary),
        })
        .collect();
    values.blend(&mixes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::live::PartOptions;
    use crate::{Goal, NoGuard, Options, QemOptions, QuadricModel};
    use coarsen_mesh::{AttrValues, Attributes};
    use std::collections::HashSet;

    /// A bumpy icosphere charted by longitude and latitude: one seam along the meridian
    /// where the longitude wraps, corners where faces at the poles disagree.
    fn charted_sphere(levels: u32) -> Mesh {
        coarsen_shapes::with_spherical_uvs(crate::live::parts::tests::bumpy(levels))
    }

    /// QEM on `mesh` to `goal` with its seams tracked (in parts first with `parts`).
    fn qem(mesh: &Mesh, goal: Goal, parts: &PartOptions) -> (Mesh, usize) {
        let mut live = LiveMesh::new_renumbered(mesh).unwrap();
        let on_seams = live.track_seams(&mut mesh.clone());
        let mut model = QuadricModel::new(&live, &QemOptions::default());
        let opts = Options::new(goal);
        live.collapse_parted(&mut model, || NoGuard, &opts, parts, &mut |_| {});
        live.check_invariants().unwrap();
        (live.to_mesh(mesh).unwrap().0, on_seams)
    }

    /// An output vertex of two wedges or more that sits where no input vertex sat.
    fn moved_seam_vertex(input: &Mesh, out: &Mesh) -> Option<usize> {
        let input_at: HashSet<[u64; 3]> = input
            .positions
            .iter()
            .map(|p| p.to_array().map(f64::to_bits))
            .collect();
        let mut wedges_of = vec![0; out.n_vertices()];
        for &v in out.wedges.vertices() {
            wedges_of[v as usize] += 1;
        }
        (0..out.n_vertices()).find(|&v| {
            wedges_of[v] > 1 && !input_at.contains(&out.positions[v].to_array().map(f64::to_bits))
        })
    }

    /// The output keeps its seams on the input's seam vertices, every wedge valid, no face
    /// turned over in UV space, and each UV where its vertex is.
    fn assert_seams_kept(input: &Mesh, out: &Mesh) {
        out.wedges.check(&out.faces).unwrap();
        assert!(
            out.wedges.split_vertices() > 10,
            "{}",
            out.wedges.split_vertices()
        );
        assert_eq!(moved_seam_vertex(input, out), None);
        let t = coarsen_metrics::texture(input, out, 2.0 * 3f64.sqrt()).unwrap();
        assert_eq!(t.uv_flipped + t.uv_degenerate, 0, "{t:?}");
        assert_eq!(t.uv_outside, 0, "{t:?}");
        // A UV names the input point nearest its vertex: at most the vertex's distance
        // from the surface (the bumps are 5 % high).
        assert!(t.distortion_max_pct < 2.0, "{t:?}");
    }

    #[test]
    fn classes_follow_the_seams() {
        let m = charted_sphere(3);
        let mut live = LiveMesh::new(&m).unwrap();
        let on_seams = live.track_seams(&mut m.clone());
        // Every split vertex, and the ends of seam edges beyond them (around a pole, each
        // face has a wedge of its own: the pole's neighbours end seam edges).
        assert!(on_seams > m.wedges.split_vertices(), "{on_seams}");
        let class = &live.seams.as_ref().unwrap().class;
        let curves = class.iter().filter(|&&c| c == CURVE).count();
        let corners = class.iter().filter(|&&c| c == CORNER).count();
        // The wrap meridian runs pole to pole: curve vertices along it, its ends corners.
        assert!(
            curves > 10 && corners >= 2,
            "{curves} curve, {corners} corner"
        );
        assert_eq!(curves + corners, on_seams);
        // A mesh without wedges tracks nothing.
        let plain = Mesh::new(m.positions.clone(), m.faces.clone());
        let mut live = LiveMesh::new(&plain).unwrap();
        assert_eq!(live.track_seams(&mut plain.clone()), 0);
        assert!(!live.tracks_seams());
    }

    #[test]
    fn qem_keeps_the_seams_and_their_corners() {
        let m = charted_sphere(4);
        let (out, _) = qem(&m, Goal::Vertices(150), &PartOptions::off());
        assert_eq!(out.n_vertices(), 150);
        assert_seams_kept(&m, &out);
        // Every corner of the input's seams is still a vertex.
        let mut live = LiveMesh::new(&m).unwrap();
        live.track_seams(&mut m.clone());
        let state = live.seams.as_ref().unwrap();
        let kept: HashSet<[u64; 3]> = out
            .positions
            .iter()
            .map(|p| p.to_array().map(f64::to_bits))
            .collect();
        for (v, &c) in state.class.iter().enumerate() {
            if c == CORNER {
                let p = m.positions[v].to_array().map(f64::to_bits);
                assert!(kept.contains(&p), "corner {v} gone");
            }
        }
    }

    #[test]
    fn flat_normals_are_carried_without_making_every_edge_a_seam() {
        let m = charted_sphere(4);
        let mut cols = Attributes::default();
        cols.insert("uv", m.corner_column("uv").unwrap());
        let normals = (0..m.n_faces())
            .flat_map(|f| [m.face_normal(f); 3])
            .collect();
        cols.insert("normal", AttrValues::Vec3(normals));
        let flat = Mesh::new(m.positions.clone(), m.faces.clone()).with_corner_attributes(cols);
        assert_eq!(flat.wedges.split_vertices(), flat.n_vertices());
        let (out, on_seams) = qem(&flat, Goal::Vertices(150), &PartOptions::off());
        assert!(on_seams < flat.n_vertices() / 10, "{on_seams}");
        assert_eq!(out.n_vertices(), 150);
        assert_seams_kept(&flat, &out);
        let Some(AttrValues::Vec3(n)) = out.wedges.attrs().get("normal") else {
            panic!("normals carried");
        };
        assert!(n.iter().all(|n| (n.length() - 1.0).abs() < 1e-9));
    }

    #[test]
    fn parts_carry_the_wedges_alike_on_any_thread_count() {
        let m = charted_sphere(5);
        let parts = PartOptions {
            min_faces: 0,
            faces_per_part: 2048,
            ..PartOptions::default()
        };
        let run = |threads| {
            coarsen_testdata::on_threads(threads, || qem(&m, Goal::Vertices(800), &parts).0)
        };
        let one = run(1);
        assert_seams_kept(&m, &one);
        assert_eq!(run(3), one);
    }

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config {
            cases: 24,
            rng_seed: proptest::test_runner::RngSeed::Fixed(0x5EA3_5000_0000_0048),
            ..proptest::test_runner::Config::default()
        })]

        /// Whatever the charts, the target and the phases: the engine stays sound, the
        /// output's wedges are valid, every vertex with two wedges sits where an input
        /// vertex sat, and no face is flat in UV space.
        #[test]
        fn random_seams_keep_the_mesh_and_its_wedges_sound(
            (mesh, goal, parts) in crate::live::parts::properties::charted_cases(),
        ) {
            let (out, _) = qem(&mesh, goal, &parts);
            out.wedges.check(&out.faces).unwrap();
            proptest::prop_assert_eq!(moved_seam_vertex(&mesh, &out), None);
            let t = coarsen_metrics::texture(&mesh, &out, 1.0).unwrap();
            proptest::prop_assert_eq!(t.uv_degenerate, 0);
        }
    }
}
