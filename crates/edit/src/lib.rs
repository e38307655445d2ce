//! One editable triangle mesh for the stages that edit a mesh in place: faces with each
//! vertex's faces kept up to date through every edit, the checks an edge collapse must
//! pass to keep a manifold its topology, and the edits themselves.
//!
//! * [`FaceLists`]: each vertex's faces in one arena of `u32` (the collapse engine's
//!   storage, shared by [`Editable`]).
//! * [`Editable`]: faces (alive or dead slots), each vertex's alive faces in ascending
//!   order and, on request ([`Editable::with_edges`]), every edge with its face count.
//!   Geometry stays with the caller: the same structure serves the relaxation's
//!   split/collapse pairs and flips and the subdivision's Delaunay flips on a mesh, and
//!   the dual's merging of clusters on a graph of clusters without positions.
//! * [`Editable::can_collapse`]: the topological checks of an edge collapse as one table
//!   of [`Rules`] (after meshoptimizer's `kCanCollapse`): the link condition, the boundary
//!   rules, and the rules a client adds (both ends one fan, a loop of three boundary
//!   edges, a vertex left with no face). The geometric vetoes (faces turning over,
//!   angles) are the client's, asked after these.
//! * [`Constraints`]: fixed vertices, vertices bound to curves and the curves' edges
//!   (sharp features; empty unless given, [`Editable::with_constraints`]): no collapse
//!   takes a constrained vertex, no flip turns a curve edge, a split of one puts its new
//!   vertex on the curve.
//! * The edits: [`Editable::collapse`], [`Editable::split_edge`], [`Editable::flip`] (with
//!   [`Editable::flip_parts`]), [`Editable::replace_face`], [`Editable::push_face`] and
//!   [`Editable::add_vertex`].
//!
//! Every operation is sequential and in index order: the same edits give the same mesh.

mod constraints;
mod lists;

pub use constraints::{Constraints, Role};
pub use lists::FaceLists;

use std::collections::BTreeMap;

/// Why [`Editable::can_collapse`] refused a collapse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// The two vertices share no face, or more than two.
    NotAnEdge,
    /// An end is not one fan of faces (a non-manifold vertex).
    NotOneFan,
    /// The link condition fails: the ends have a common neighbour that is not opposite
    /// the edge, or two common neighbours joined by an edge that does not lie on the
    /// edge's faces (a face of one end, renamed, would repeat a face of the other): the
    /// collapse would pinch the surface or fold two faces onto each other.
    Link,
    /// An interior edge joining two boundary vertices: the collapse would join two
    /// boundary loops, or pinch one.
    Bridge,
    /// A boundary edge of a loop of three ([`Rules::loops_of_three`]).
    LoopOfThree,
    /// A vertex opposite the edge has no other face ([`Rules::every_vertex_kept`]).
    VertexLeft,
    /// An end is fixed or on a curve ([`Constraints`]).
    Constrained,
}

/// The checks of [`Editable::can_collapse`] beyond those every collapse must pass (one
/// or two faces on the edge, the link condition, no interior edge between two boundary
/// vertices).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Rules {
    /// Both ends must be one fan of faces.
    pub one_fan: bool,
    /// A boundary edge may not be collapsed when its ends have a common boundary
    /// neighbour: the loop would fall below four vertices.
    pub loops_of_three: bool,
    /// No vertex opposite the edge may be left with no face.
    pub every_vertex_kept: bool,
}

/// A triangle mesh's faces and each vertex's faces, edited in place (see the crate docs).
#[derive(Clone, Debug)]
pub struct Editable {
    faces: Vec<[u32; 3]>,
    alive: Vec<bool>,
    /// Each vertex's alive faces, ascending.
    lists: FaceLists,
    /// Every edge (ends ascending) with its count of alive faces, when kept.
    edges: Option<BTreeMap<[u32; 2], u32>>,
    /// What the edits respect (none by default).
    constraints: Constraints,
}

impl Editable {
    /// `faces` over `n_vertices` vertices, every face alive. Panics on a corner out of
    /// range (callers hand it meshes they checked).
    pub fn new(n_vertices: usize, faces: Vec<[u32; 3]>) -> Editable {
        let alive = vec![true; faces.len()];
        let lists = FaceLists::build(n_vertices, &faces, &alive);
        Editable {
            faces,
            alive,
            lists,
            edges: None,
            constraints: Constraints::default(),
        }
    }

    /// The same, its edits respecting `constraints` (see [`Constraints`]).
    pub fn with_constraints(mut self, constraints: Constraints) -> Editable {
        self.constraints = constraints;
        self
    }

    /// The constraints the edits respect, as the edits left them.
    pub fn constraints(&self) -> &Constraints {
        &self.constraints
    }

    /// The same, also keeping every edge with its face count ([`Editable::edges`]).
    pub fn with_edges(mut self) -> Editable {
        let mut edges = BTreeMap::new();
        for (f, face) in self.faces.iter().enumerate() {
            if self.alive[f] {
                count_edges(&mut edges, *face, true);
            }
        }
        self.edges = Some(edges);
        self
    }

    /// The face slots, alive or dead (a dead face keeps the corners it had).
    pub fn faces(&self) -> &[[u32; 3]] {
        &self.faces
    }

    /// The corners of face `f`.
    pub fn face(&self, f: u32) -> [u32; 3] {
        self.faces[f as usize]
    }

    /// Whether face `f` is alive.
    pub fn is_alive(&self, f: u32) -> bool {
        self.alive[f as usize]
    }

    /// The alive faces, in slot order.
    pub fn alive_faces(&self) -> impl Iterator<Item = [u32; 3]> + '_ {
        self.faces
            .iter()
            .zip(&self.alive)
            .filter(|(_, a)| **a)
            .map(|(f, _)| *f)
    }

    /// The alive faces around `v`, ascending.
    pub fn faces_around(&self, v: u32) -> &[u32] {
        self.lists.get(v)
    }

    /// Every edge (ends ascending, in ascending order) with its count of alive faces;
    /// `None` unless built [`Editable::with_edges`].
    pub fn edges(&self) -> Option<&BTreeMap<[u32; 2], u32>> {
        self.edges.as_ref()
    }

    /// The alive faces that have both `a` and `b`, ascending.
    pub fn edge_faces(&self, a: u32, b: u32) -> Vec<u32> {
        self.lists.with_corner(a, b, &self.faces).collect()
    }

    /// True when `a`–`b` is an edge of some alive face.
    pub fn has_edge(&self, a: u32, b: u32) -> bool {
        self.lists.with_corner(a, b, &self.faces).next().is_some()
    }

    /// Every edge (ends ascending, in ascending order) with its count of alive faces,
    /// gathered from the faces now (no tracking needed).
    pub fn edges_now(&self) -> Vec<([u32; 2], u32)> {
        let mut all: Vec<[u32; 2]> = self
            .alive_faces()
            .flat_map(|t| (0..3).map(move |i| [t[i].min(t[(i + 1) % 3]), t[i].max(t[(i + 1) % 3])]))
            .collect();
        all.sort_unstable();
        let mut out: Vec<([u32; 2], u32)> = Vec::with_capacity(all.len() / 2 + 1);
        for e in all {
            match out.last_mut() {
                Some((last, n)) if *last == e => *n += 1,
                _ => out.push((e, 1)),
            }
        }
        out
    }

    /// True when `a`–`b` is an edge of exactly one face.
    pub fn is_boundary_edge(&self, a: u32, b: u32) -> bool {
        self.lists.with_corner(a, b, &self.faces).count() == 1
    }

    /// The vertices joined to `v` by an edge, ascending.
    pub fn neighbors(&self, v: u32) -> Vec<u32> {
        let mut out: Vec<u32> = self
            .lists
            .get(v)
            .iter()
            .flat_map(|&f| self.faces[f as usize])
            .filter(|&w| w != v)
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// The vertices joined to `v` by an edge of one face, ascending.
    pub fn boundary_neighbors(&self, v: u32) -> Vec<u32> {
        let mut n = self.neighbors(v);
        n.retain(|&w| self.is_boundary_edge(v, w));
        n
    }

    /// True when `v` is the end of an edge of one face.
    pub fn is_boundary_vertex(&self, v: u32) -> bool {
        self.neighbors(v)
            .into_iter()
            .any(|w| self.is_boundary_edge(v, w))
    }

    /// The fans the faces around `v` form: faces joined across their edges at `v` (one for
    /// a manifold vertex, none for a vertex without faces).
    pub fn n_fans(&self, v: u32) -> usize {
        let faces = self.lists.get(v);
        let mut root: Vec<usize> = (0..faces.len()).collect();
        fn find(root: &mut [usize], mut i: usize) -> usize {
            while root[i] != i {
                i = root[i];
            }
            i
        }
        for i in 0..faces.len() {
            for j in i + 1..faces.len() {
                let (fi, fj) = (self.faces[faces[i] as usize], self.faces[faces[j] as usize]);
                if fi.iter().any(|&w| w != v && fj.contains(&w)) {
                    let (ri, rj) = (find(&mut root, i), find(&mut root, j));
                    root[ri.max(rj)] = ri.min(rj);
                }
            }
        }
        (0..faces.len())
            .filter(|&i| find(&mut root, i) == i)
            .count()
    }

    /// Whether collapsing edge `a`–`b` (either way) keeps the mesh a manifold of the same
    /// topology, by the checks every collapse passes and those `rules` adds: `Err` names
    /// the first check that fails.
    pub fn can_collapse(&self, a: u32, b: u32, rules: Rules) -> Result<(), Refusal> {
        if self.constraints.locked(a) || self.constraints.locked(b) {
            return Err(Refusal::Constrained);
        }
        let shared = self.edge_faces(a, b);
        if shared.is_empty() || shared.len() > 2 {
            return Err(Refusal::NotAnEdge);
        }
        if rules.one_fan && (self.n_fans(a) != 1 || self.n_fans(b) != 1) {
            return Err(Refusal::NotOneFan);
        }
        // The link condition: the ends' common neighbours are exactly the vertices
        // opposite the edge (each opposite vertex is one, so counting suffices).
        let opposite: Vec<u32> = shared
            .iter()
            .filter_map(|&f| {
                self.faces[f as usize]
                    .into_iter()
                    .find(|&w| w != a && w != b)
            })
            .collect();
        let (na, nb) = (self.neighbors(a), self.neighbors(b));
        let common = na.iter().filter(|w| nb.binary_search(w).is_ok()).count();
        if common != opposite.len() {
            return Err(Refusal::Link);
        }
        if shared.len() == 2 && self.is_boundary_vertex(a) && self.is_boundary_vertex(b) {
            return Err(Refusal::Bridge);
        }
        if shared.len() == 1 && rules.loops_of_three {
            let (ea, eb) = (self.boundary_neighbors(a), self.boundary_neighbors(b));
            if ea.iter().any(|w| eb.binary_search(w).is_ok()) {
                return Err(Refusal::LoopOfThree);
            }
        }
        if rules.every_vertex_kept
            && opposite
                .iter()
                .any(|&c| self.lists.get(c).iter().all(|f| shared.contains(f)))
        {
            return Err(Refusal::VertexLeft);
        }
        // The link condition's part on edges last: it is the costly one, and the checks
        // above refuse most candidates first (the verdict is the same in any order).
        if self.repeats_a_face(a, b, &shared) {
            return Err(Refusal::Link);
        }
        Ok(())
    }

    /// True when a face of `b` off the edge, with `b` renamed `a`, has the corners of a
    /// face of `a` off the edge (`shared`: the edge's faces).
    fn repeats_a_face(&self, a: u32, b: u32, shared: &[u32]) -> bool {
        let key = |mut f: [u32; 3]| {
            f.sort_unstable();
            f
        };
        let mut at_a: Vec<[u32; 3]> = self
            .lists
            .get(a)
            .iter()
            .filter(|f| !shared.contains(f))
            .map(|&f| key(self.faces[f as usize]))
            .collect();
        at_a.sort_unstable();
        self.lists
            .get(b)
            .iter()
            .filter(|f| !shared.contains(f))
            .any(|&f| {
                let renamed = self.faces[f as usize].map(|c| if c == b { a } else { c });
                at_a.binary_search(&key(renamed)).is_ok()
            })
    }

    /// Collapses `gone` into `keep` (checked by [`Editable::can_collapse`]): the faces
    /// with both die, the other faces of `gone` take `keep` in its place. Returns the
    /// faces that died, ascending.
    pub fn collapse(&mut self, keep: u32, gone: u32) -> Vec<u32> {
        let around = self.lists.get(gone).to_vec();
        let mut freed = Vec::new();
        for f in around {
            let face = self.faces[f as usize];
            if face.contains(&keep) {
                self.replace_face(f, None);
                freed.push(f);
            } else {
                self.replace_face(f, Some(face.map(|c| if c == gone { keep } else { c })));
            }
        }
        freed
    }

    /// Face slot `f` becomes `now` (alive; `None`: dead), a dead slot coming back to life;
    /// the vertices' lists and the edge counts follow.
    pub fn replace_face(&mut self, f: u32, now: Option<[u32; 3]>) {
        let fi = f as usize;
        if self.alive[fi] {
            let was = self.faces[fi];
            if let Some(edges) = &mut self.edges {
                count_edges(edges, was, false);
            }
            for v in was {
                self.lists.remove(v, f);
            }
        }
        match now {
            Some(face) => {
                self.faces[fi] = face;
                self.alive[fi] = true;
                if let Some(edges) = &mut self.edges {
                    count_edges(edges, face, true);
                }
                for v in face {
                    self.lists.insert_sorted(v, f);
                }
            }
            None => self.alive[fi] = false,
        }
    }

    /// The two faces of interior edge `a`–`b` and the vertices opposite it, when it has
    /// exactly two faces that hold it in opposite directions and is no curve edge (see
    /// [`Constraints`]): `(g, h, c, d)` with face `g` = a → b → c and face `h` =
    /// b → a → d (in some rotation); `None` otherwise.
    pub fn flip_parts(&self, a: u32, b: u32) -> Option<(u32, u32, u32, u32)> {
        if self.constraints.is_curve_edge(a, b) {
            return None;
        }
        self.edge_parts(a, b)
    }

    /// [`Editable::flip_parts`] whatever the constraints.
    fn edge_parts(&self, a: u32, b: u32) -> Option<(u32, u32, u32, u32)> {
        let mut on_edge = self.lists.with_corner(a, b, &self.faces);
        let (Some(f1), Some(f2), None) = (on_edge.next(), on_edge.next(), on_edge.next()) else {
            return None;
        };
        let third = |f: u32, x: u32, y: u32| {
            let t = self.faces[f as usize];
            (0..3)
                .find(|&i| t[i] == x && t[(i + 1) % 3] == y)
                .map(|i| t[(i + 2) % 3])
        };
        match (third(f1, a, b), third(f2, b, a)) {
            (Some(c), Some(d)) => Some((f1, f2, c, d)),
            _ => match (third(f2, a, b), third(f1, b, a)) {
                (Some(c), Some(d)) => Some((f2, f1, c, d)),
                _ => None,
            },
        }
    }

    /// Flips edge `a`–`b` of faces `g` = a → b → c and `h` = b → a → d (as
    /// [`Editable::flip_parts`] gives them) into `c`–`d`: `g` becomes a → d → c and `h`
    /// d → b → c, in their slots. Returns the two new faces.
    pub fn flip(&mut self, [a, b]: [u32; 2], (g, h, c, d): (u32, u32, u32, u32)) -> [[u32; 3]; 2] {
        let new = [[a, d, c], [d, b, c]];
        self.replace_face(g, Some(new[0]));
        self.replace_face(h, Some(new[1]));
        new
    }

    /// Splits interior edge `c`–`d` at vertex `m`, which has no faces (a vertex a collapse
    /// left, or [`Editable::add_vertex`]'s): of its faces `g` = c → d → x and
    /// `h` = d → c → y, the halves on `x`'s side take their slots (`g` c → m → x, `h`
    /// m → d → x) and those on `y`'s side the dead slots `reuse` (d → m → y, then
    /// m → c → y), each appended in a new slot where `None`. Returns the four slots in that
    /// order; `None` (nothing changed) when the edge does not have exactly two faces that
    /// hold it in opposite directions, `m` has faces or a slot of `reuse` is alive. A
    /// curve edge's new vertex joins its curve ([`Constraints::split_edge`]).
    pub fn split_edge(
        &mut self,
        [c, d]: [u32; 2],
        m: u32,
        reuse: [Option<u32>; 2],
    ) -> Option<[u32; 4]> {
        let (g, h, x, y) = self.edge_parts(c, d)?;
        if !self.lists.get(m).is_empty() || reuse.iter().flatten().any(|&f| self.is_alive(f)) {
            return None;
        }
        self.constraints.split_edge(c, d, m);
        self.replace_face(g, Some([c, m, x]));
        self.replace_face(h, Some([m, d, x]));
        let mut place = |slot: Option<u32>, face: [u32; 3]| match slot {
            Some(f) => {
                self.replace_face(f, Some(face));
                f
            }
            None => self.push_face(face),
        };
        let s3 = place(reuse[0], [d, m, y]);
        let s4 = place(reuse[1], [m, c, y]);
        Some([g, h, s3, s4])
    }

    /// Appends face `face` (alive) in a new slot, whose index it returns. Its corners must
    /// be vertices of the mesh ([`Editable::add_vertex`] makes new ones).
    pub fn push_face(&mut self, face: [u32; 3]) -> u32 {
        let f = self.faces.len() as u32;
        self.faces.push(face);
        self.alive.push(false);
        self.replace_face(f, Some(face));
        f
    }

    /// A new vertex without faces; returns its index.
    pub fn add_vertex(&mut self) -> u32 {
        self.lists.push_vertex()
    }

    /// The vertices the lists hold.
    pub fn n_vertices(&self) -> usize {
        self.lists.n_vertices()
    }
}

/// Counts the edges of `face` once more (`add`) or once less in `edges`.
fn count_edges(edges: &mut BTreeMap<[u32; 2], u32>, face: [u32; 3], add: bool) {
    for i in 0..3 {
        let (a, b) = (face[i], face[(i + 1) % 3]);
        let key = [a.min(b), a.max(b)];
        if add {
            *edges.entry(key).or_insert(0) += 1;
        } else if let Some(n) = edges.get_mut(&key) {
            *n -= 1;
            if *n == 0 {
                edges.remove(&key);
            }
        }
    }
}

#[cfg(test)]
mod tests;
