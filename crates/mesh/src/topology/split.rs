//! The adjacency of a uniform 1-to-4 split, derived from the adjacency of the mesh split
//! instead of built from the split's faces.
//!
//! The uniform split is numbered this way (this module's convention; a caller whose split
//! numbers its elements so, laying out the children with [`split_children`], gets its
//! adjacency from [`Topology::of_split`]): the vertices keep their numbers, the midpoint of
//! edge `e` (this adjacency's edge numbering) is vertex `n_vertices + e`, and face
//! `f = [v0, v1, v2]`, whose edge `i` runs from corner `i` to corner `i + 1` and has
//! midpoint `mi`, becomes the four faces `4f .. 4f + 3`: `[v0, m0, m2]`, `[m0, v1, m1]`,
//! `[m2, m1, v2]`, `[m0, m1, m2]`. Corner child `c` has the half-edges `vc → mc` (its
//! corner `c`), `mc → m(c+2)` (corner `c + 1`) and `m(c+2) → vc` (corner `c + 2`); the
//! centre child has `mi → m(i+1)` at corner `i`.
//!
//! Every table comes out exactly as [`Topology::build`] would make it (tested against it):
//! edges sorted, each edge's faces ascending, fans starting where the build starts them,
//! loops traced from the same edge in the same direction, components numbered by their
//! lowest face.

use super::*;

/// Vertices per range of the parallel fill.
const RANGE: usize = 1 << 14;

/// One face around a midpoint: the fine face and its corners after and before the
/// midpoint.
#[derive(Clone, Copy)]
struct Around {
    face: u32,
    next: u32,
    prev: u32,
}

/// An interior edge from a midpoint to a larger one: the other midpoint and the two fine
/// faces on it with the corner of the edge in each (the corner child first).
type Partner = (u32, [(u32, usize); 2]);

/// Per fine vertex: how many entries it has in each table.
#[derive(Clone, Copy, Default)]
struct Entries {
    faces: u32,
    neighbors: u32,
    edges: u32,
    edge_faces: u32,
}

/// The slices of the output tables that one range of fine vertices fills.
struct Piece<'a> {
    v0: usize,
    v1: usize,
    faces: &'a mut [u32],
    neighbors: &'a mut [u32],
    edges: &'a mut [[u32; 2]],
    edge_flags: &'a mut [u8],
    /// Ends of the range's edges' face lists (`edge_face_offsets[1 + e]`).
    edge_face_ends: &'a mut [u32],
    edge_faces: &'a mut [u32],
    flags: &'a mut [u8],
}

/// Cuts `s` into consecutive pieces of the given lengths.
fn cut<T>(mut s: &mut [T], lengths: impl Iterator<Item = usize>) -> Vec<&mut [T]> {
    let mut out = Vec::new();
    for n in lengths {
        let (head, tail) = std::mem::take(&mut s).split_at_mut(n);
        out.push(head);
        s = tail;
    }
    out
}

/// Exclusive prefix sums of `count` over `n` items, with the total appended.
fn offsets(n: usize, count: impl Fn(usize) -> u32) -> Vec<u32> {
    let mut out = Vec::with_capacity(n + 1);
    let mut at = 0u32;
    for i in 0..n {
        out.push(at);
        at += count(i);
    }
    out.push(at);
    out
}

/// The four children of face `corners` in the uniform 1-to-4 split, given the midpoints
/// of its edges (`mids[i]` on the edge from corner `i` to corner `i + 1`): the three corner
/// children, then the centre one, as the module docs number them.
#[inline]
pub fn split_children(corners: [u32; 3], mids: [u32; 3]) -> [[u32; 3]; 4] {
    let ([v0, v1, v2], [m0, m1, m2]) = (corners, mids);
    [[v0, m0, m2], [m0, v1, m1], [m2, m1, v2], [m0, m1, m2]]
}

impl Topology {
    /// The uniform 1-to-4 split of `mesh` (whose adjacency this is) in the numbering the
    /// module docs give, each midpoint halfway along its edge; attributes are not carried.
    pub fn uniform_split(&self, mesh: &Mesh) -> Mesh {
        let nv = mesh.n_vertices() as u32;
        let mut positions = mesh.positions.clone();
        positions.extend(
            self.edges
                .iter()
                .map(|&[a, b]| (mesh.positions[a as usize] + mesh.positions[b as usize]) * 0.5),
        );
        let faces = mesh
            .faces
            .iter()
            .zip(&self.face_edges)
            .flat_map(|(&corners, e)| split_children(corners, e.map(|e| nv + e)))
            .collect();
        Mesh::new(positions, faces)
    }

    /// The adjacency of `fine` when `fine` is the uniform 1-to-4 split of `coarse` (whose
    /// adjacency this is), numbered as the module docs say; `None` when it is not, or when
    /// `coarse` is not a consistently oriented manifold without isolated vertices (then
    /// build it). The same tables as [`Topology::build`] of `fine`, made from these ones.
    pub fn of_split(&self, coarse: &Mesh, fine: &Mesh) -> Option<Topology> {
        self.split_tables(coarse, fine, true)
    }

    /// [`Topology::of_split`] without the vertex neighbours (see
    /// [`Topology::has_vertex_neighbors`]), for readers that never ask for them: at 3.8M
    /// faces 53 MB less. `None` also when this adjacency has none.
    pub fn of_split_lean(&self, coarse: &Mesh, fine: &Mesh) -> Option<Topology> {
        self.split_tables(coarse, fine, false)
    }

    /// [`Topology::of_split`], the vertex neighbours laid out when `neighbors` is true.
    fn split_tables(&self, coarse: &Mesh, fine: &Mesh, neighbors: bool) -> Option<Topology> {
        if !self.is_split_into(coarse, fine) {
            return None;
        }
        let c = Coarse {
            topo: self,
            faces: &coarse.faces,
            face_edges: &self.face_edges,
            nv: self.n_vertices,
        };
        let off = c.offsets(neighbors)?;
        let mut fine = FineTables::new(&off, 4 * self.n_faces());
        c.fill(&mut fine, &off, neighbors);
        let (loop_offsets, loop_vertices) = c.loops()?;
        Some(fine.into_topology(self, off, loop_offsets, loop_vertices))
    }

    /// Whether `fine` is the uniform split of `coarse`, whose adjacency this is, in the
    /// module's numbering, and `coarse` a consistently oriented manifold without isolated
    /// vertices whose split fits the tables.
    fn is_split_into(&self, coarse: &Mesh, fine: &Mesh) -> bool {
        let (nv, nf, ne) = (self.n_vertices, self.n_faces(), self.edges.len());
        let (nv2, nf2) = (nv + ne, 4 * nf);
        let manifold = self.has_vertex_neighbors()
            && coarse.n_vertices() == nv
            && coarse.n_faces() == nf
            && self.n_repeated_index_faces + self.n_out_of_range_faces == 0
            && self.n_open_boundary_chains == 0
            && self
                .edge_flags
                .par_iter()
                .all(|f| f & (E_MULTI | E_FLIPPED) == 0)
            && self
                .vertex_flags
                .par_iter()
                .all(|f| f & (V_ISOLATED | V_NON_MANIFOLD) == 0);
        if !manifold
            || fine.n_vertices() != nv2
            || fine.n_faces() != nf2
            || nf2 > MAX_FACES
            || nv2 >= NONE as usize
        {
            return false;
        }
        let (cf, fe) = (&coarse.faces, &self.face_edges);
        let children = |f: usize| split_children(cf[f], fe[f].map(|e| nv as u32 + e));
        fine.faces
            .par_chunks(4)
            .enumerate()
            .all(|(f, four)| four == children(f))
    }
}

/// The coarse mesh and its adjacency, as the derivation of its split's adjacency reads
/// them.
struct Coarse<'a> {
    topo: &'a Topology,
    faces: &'a [[u32; 3]],
    face_edges: &'a [[u32; 3]],
    /// Coarse vertices: the fine vertex of edge `e`'s midpoint is `nv + e`.
    nv: usize,
}

/// Where each fine vertex's entries start in each table (with the totals appended).
struct Offsets {
    faces: Vec<u32>,
    /// Empty without the vertex neighbours.
    neighbors: Vec<u32>,
    edges: Vec<u32>,
    edge_faces: Vec<u32>,
}

/// The tables of the fine adjacency, filled range by range.
struct FineTables {
    vertex_faces: Vec<u32>,
    vertex_neighbors: Vec<u32>,
    edges: Vec<[u32; 2]>,
    edge_flags: Vec<u8>,
    edge_face_offsets: Vec<u32>,
    edge_faces: Vec<u32>,
    vertex_flags: Vec<u8>,
    face_edges: Vec<[AtomicU32; 3]>,
}

impl Coarse<'_> {
    /// The fine vertex at the midpoint of coarse edge `e`.
    #[inline]
    fn mid(&self, e: u32) -> u32 {
        self.nv as u32 + e
    }

    /// The corner of coarse face `f` at vertex `v`.
    #[inline]
    fn corner(&self, v: u32, f: u32) -> usize {
        self.faces[f as usize]
            .iter()
            .position(|&x| x == v)
            .unwrap_or(0)
    }

    /// The slot of edge `e` among coarse face `f`'s edges.
    #[inline]
    fn slot(&self, e: u32, f: u32) -> usize {
        self.face_edges[f as usize]
            .iter()
            .position(|&x| x == e)
            .unwrap_or(0)
    }

    /// The fine faces around midpoint `e` in one coarse face `f`, counter-clockwise.
    fn around_in(&self, e: u32, f: u32) -> [Around; 3] {
        let k = self.slot(e, f);
        let (c1, c2) = ((k + 1) % 3, (k + 2) % 3);
        let (v, m) = (
            self.faces[f as usize],
            self.face_edges[f as usize].map(|e| self.mid(e)),
        );
        let f4 = 4 * f;
        [
            Around {
                face: f4 + c1 as u32,
                next: v[c1],
                prev: m[c1],
            },
            Around {
                face: f4 + 3,
                next: m[c1],
                prev: m[c2],
            },
            Around {
                face: f4 + k as u32,
                next: m[c2],
                prev: v[k],
            },
        ]
    }

    /// The other edges of the coarse faces of edge `e`, two per face, and how many.
    fn partner_ids(&self, e: u32) -> ([u32; 4], usize) {
        let mut ids = [NONE; 4];
        let ef = self.topo.edge_faces(e);
        for (i, &f) in ef.iter().take(2).enumerate() {
            let k = self.slot(e, f);
            ids[2 * i] = self.face_edges[f as usize][(k + 2) % 3];
            ids[2 * i + 1] = self.face_edges[f as usize][(k + 1) % 3];
        }
        (ids, 2 * ef.len().min(2))
    }

    /// The interior fine edges from midpoint `e` to larger midpoints, sorted, into `out`.
    fn partners(&self, e: u32, out: &mut Vec<Partner>) {
        out.clear();
        for &f in self.topo.edge_faces(e) {
            let k = self.slot(e, f);
            let (c1, c2) = ((k + 1) % 3, (k + 2) % 3);
            let f4 = 4 * f;
            let (p2, p1) = (
                self.face_edges[f as usize][c2],
                self.face_edges[f as usize][c1],
            );
            if p2 > e {
                out.push((self.mid(p2), [(f4 + k as u32, c1), (f4 + 3, c2)]));
            }
            if p1 > e {
                out.push((self.mid(p1), [(f4 + c1 as u32, c2), (f4 + 3, k)]));
            }
        }
        out.sort_unstable_by_key(|p| p.0);
    }

    /// How many entries fine vertex `v` has in each table; `None` when two coarse faces
    /// share two edges (the split would not be a manifold).
    fn entries(&self, v: usize) -> Option<Entries> {
        let t = self.topo;
        if v < self.nv {
            let k = t.n_vertex_faces(v as u32) as u32;
            let n = t.vertex_neighbors(v as u32).len() as u32;
            return Some(Entries {
                faces: k,
                neighbors: n,
                edges: n,
                edge_faces: 2 * k,
            });
        }
        let e = (v - self.nv) as u32;
        let (ids, n) = self.partner_ids(e);
        let ids = &ids[..n];
        if (0..n).any(|i| ids[i + 1..].contains(&ids[i])) {
            return None;
        }
        let larger = ids.iter().filter(|&&p| p > e).count() as u32;
        Some(Entries {
            faces: 3 * n as u32 / 2,
            neighbors: n as u32 + 2,
            edges: larger,
            edge_faces: 2 * larger,
        })
    }

    /// Where each fine vertex's entries start; `None` when the split would not be a
    /// manifold.
    fn offsets(&self, neighbors: bool) -> Option<Offsets> {
        let (ne, nf) = (self.topo.edges.len(), self.topo.n_faces());
        let nv2 = self.nv + ne;
        let counts: Vec<Entries> = (0..nv2)
            .into_par_iter()
            .map(|v| self.entries(v))
            .collect::<Option<_>>()?;
        let off = Offsets {
            faces: offsets(nv2, |v| counts[v].faces),
            // Without neighbours no offsets either (asking for them then fails loudly).
            neighbors: match neighbors {
                true => offsets(nv2, |v| counts[v].neighbors),
                false => Vec::new(),
            },
            edges: offsets(nv2, |v| counts[v].edges),
            edge_faces: offsets(nv2, |v| counts[v].edge_faces),
        };
        (off.edges[nv2] as usize == 2 * ne + 3 * nf).then_some(off)
    }

    /// Fills `t` range by range in parallel: each range of fine vertices owns its slices
    /// of the tables.
    fn fill(&self, t: &mut FineTables, off: &Offsets, neighbors: bool) {
        let nv2 = self.nv + self.topo.edges.len();
        let bounds: Vec<(usize, usize)> = (0..nv2.div_ceil(RANGE))
            .map(|r| (r * RANGE, nv2.min((r + 1) * RANGE)))
            .collect();
        let (pieces, face_edges) = t.pieces(&bounds, off, neighbors);
        pieces
            .into_par_iter()
            .for_each(|p| self.fill_piece(p, off, face_edges, neighbors));
    }

    /// Fills one range's slices: each coarse vertex's entries, then each midpoint's.
    fn fill_piece(
        &self,
        mut p: Piece<'_>,
        off: &Offsets,
        face_edges: &[[AtomicU32; 3]],
        neighbors: bool,
    ) {
        let mut at = At {
            // Where the piece's edge faces start in the whole table.
            ef0: off.edge_faces[p.v0],
            ..At::default()
        };
        let mut scratch = Scratch::default();
        for (v, &e_base) in (p.v0..p.v1).zip(&off.edges[p.v0..p.v1]) {
            let put = |f: u32, c: usize, j: usize| {
                face_edges[f as usize][c].store((e_base as usize + j) as u32, Ordering::Relaxed)
            };
            if v < self.nv {
                self.fill_vertex(v, &mut p, &mut at, &mut scratch, neighbors, put);
            } else {
                self.fill_midpoint(v, &mut p, &mut at, &mut scratch, neighbors, put);
            }
        }
    }

    /// Coarse vertex `v`'s entries: its children turn like the coarse faces around it;
    /// each has the edges to two midpoints at `v` (corner `c` and `c + 2` of the child).
    fn fill_vertex(
        &self,
        v: usize,
        p: &mut Piece<'_>,
        at: &mut At,
        s: &mut Scratch,
        neighbors: bool,
        put: impl Fn(u32, usize, usize),
    ) {
        let t = self.topo;
        let vv = v as u32;
        let fan = t.vertex_faces(vv);
        let open = t.vertex_flags[v] & V_BOUNDARY != 0;
        p.flags[v - p.v0] = t.vertex_flags[v];
        s.mids.clear();
        s.sides.clear();
        for (j, &f) in fan.iter().enumerate() {
            let c = self.corner(vv, f);
            let child = 4 * f + c as u32;
            p.faces[at.faces] = child;
            at.faces += 1;
            let fe = self.face_edges[f as usize];
            let (next, prev) = (self.mid(fe[c]), self.mid(fe[(c + 2) % 3]));
            if j == 0 {
                s.mids.push(next);
            }
            if open || j + 1 < fan.len() {
                s.mids.push(prev);
            }
            s.sides.push((next, child, c));
            s.sides.push((prev, child, (c + 2) % 3));
        }
        if neighbors {
            p.neighbors[at.neighbors..at.neighbors + s.mids.len()].copy_from_slice(&s.mids);
            at.neighbors += s.mids.len();
        }
        // Edges to the midpoints around v, in order of the midpoints, each with the
        // children on it (ascending).
        s.sides.sort_unstable();
        for (j, group) in s.sides.chunk_by(|a, b| a.0 == b.0).enumerate() {
            p.edges[at.edges] = [vv, group[0].0];
            p.edge_flags[at.edges] = if group.len() == 1 { E_BOUNDARY } else { 0 };
            for &(_, child, corner) in group {
                p.edge_faces[at.edge_faces] = child;
                at.edge_faces += 1;
                put(child, corner, j);
            }
            p.edge_face_ends[at.edges] = at.ef0 + at.edge_faces as u32;
            at.edges += 1;
        }
    }

    /// Midpoint `v`'s entries: the fine faces around it (from the lowest face, in the
    /// lower coarse face, when the edge is closed) and its edges to larger midpoints.
    fn fill_midpoint(
        &self,
        v: usize,
        p: &mut Piece<'_>,
        at: &mut At,
        s: &mut Scratch,
        neighbors: bool,
        put: impl Fn(u32, usize, usize),
    ) {
        let e = (v - self.nv) as u32;
        let ef = self.topo.edge_faces(e);
        s.ring.clear();
        for &f in ef {
            s.ring.extend(self.around_in(e, f));
        }
        let start = match ef.len() {
            // Closed: from the lowest face, in the lower coarse face.
            2 if self.slot(e, ef[0]) != 2 => 2,
            _ => 0,
        };
        s.ring.rotate_left(start);
        let boundary = ef.len() == 1;
        p.flags[v - p.v0] = if boundary { V_BOUNDARY } else { 0 };
        if neighbors {
            p.neighbors[at.neighbors] = s.ring[0].next;
            at.neighbors += 1;
            let shown = if boundary {
                s.ring.len()
            } else {
                s.ring.len() - 1
            };
            for a in &s.ring[..shown] {
                p.neighbors[at.neighbors] = a.prev;
                at.neighbors += 1;
            }
        }
        for a in &s.ring {
            p.faces[at.faces] = a.face;
            at.faces += 1;
        }
        self.partners(e, &mut s.pairs);
        for (j, &(m, on)) in s.pairs.iter().enumerate() {
            p.edges[at.edges] = [v as u32, m];
            for (g, c) in on {
                p.edge_faces[at.edge_faces] = g;
                at.edge_faces += 1;
                put(g, c, j);
            }
            p.edge_face_ends[at.edges] = at.ef0 + at.edge_faces as u32;
            at.edges += 1;
        }
    }

    /// The fine boundary loops: each coarse loop with its midpoints between its vertices,
    /// from the tail of its lowest edge (which lies at its lowest vertex), the same way
    /// round; `None` for a loop of fewer than three edges.
    fn loops(&self) -> Option<(Vec<u32>, Vec<u32>)> {
        let t = self.topo;
        let mut loop_offsets = Vec::with_capacity(t.loop_offsets.len());
        let mut loop_vertices = Vec::with_capacity(2 * t.loop_vertices.len());
        loop_offsets.push(0);
        for i in 0..t.n_boundary_loops() {
            let l = t.boundary_loop(i);
            let n = l.len();
            let low = (0..n).min_by_key(|&j| l[j])?;
            let at = |j: usize| l[(low + j) % n];
            let first = loop_vertices.len();
            for j in 0..n {
                loop_vertices.push(at(j));
                loop_vertices.push(self.mid(t.find_edge(at(j), at(j + 1))?));
            }
            // The edge into the lowest vertex is the lower one: its midpoint comes first.
            let into = t.find_edge(at(n - 1), at(0))?;
            if n < 3 || into < t.find_edge(at(0), at(1))? {
                loop_vertices[first..].rotate_right(1);
            }
            if n < 3 {
                return None;
            }
            loop_offsets.push(loop_vertices.len() as u32);
        }
        Some((loop_offsets, loop_vertices))
    }
}

/// Where a range's filling stands in each of its slices.
#[derive(Default)]
struct At {
    faces: usize,
    neighbors: usize,
    edges: usize,
    edge_faces: usize,
    /// Where the range's edge faces start in the whole table.
    ef0: u32,
}

/// A range's reused lists.
#[derive(Default)]
struct Scratch {
    mids: Vec<u32>,
    ring: Vec<Around>,
    pairs: Vec<Partner>,
    sides: Vec<(u32, u32, usize)>,
}

impl FineTables {
    /// The tables, zeroed, at the sizes `off` gives, for `nf2` fine faces.
    fn new(off: &Offsets, nf2: usize) -> FineTables {
        let nv2 = off.faces.len() - 1;
        let ne2 = off.edges[nv2] as usize;
        FineTables {
            vertex_faces: vec![0u32; off.faces[nv2] as usize],
            vertex_neighbors: vec![0u32; off.neighbors.get(nv2).map_or(0, |&n| n as usize)],
            edges: vec![[0u32; 2]; ne2],
            edge_flags: vec![0u8; ne2],
            edge_face_offsets: vec![0u32; ne2 + 1],
            edge_faces: vec![0u32; off.edge_faces[nv2] as usize],
            vertex_flags: vec![0u8; nv2],
            face_edges: (0..nf2)
                .into_par_iter()
                .map(|_| [0, 0, 0].map(AtomicU32::new))
                .collect(),
        }
    }

    /// The tables cut into the slices each range of fine vertices (`bounds`) fills, and
    /// the faces' edges, which every range writes to (each entry once).
    fn pieces(
        &mut self,
        bounds: &[(usize, usize)],
        off: &Offsets,
        neighbors: bool,
    ) -> (Vec<Piece<'_>>, &[[AtomicU32; 3]]) {
        let len = |off: &[u32]| -> std::vec::IntoIter<usize> {
            let n: Vec<usize> = bounds
                .iter()
                .map(|&(v0, v1)| (off[v1] - off[v0]) as usize)
                .collect();
            n.into_iter()
        };
        let mut f = cut(&mut self.vertex_faces, len(&off.faces)).into_iter();
        let mut n = match neighbors {
            true => cut(&mut self.vertex_neighbors, len(&off.neighbors)),
            false => Vec::new(),
        }
        .into_iter();
        let mut e = cut(&mut self.edges, len(&off.edges)).into_iter();
        let mut ef = cut(&mut self.edge_flags, len(&off.edges)).into_iter();
        let mut ee = cut(&mut self.edge_face_offsets[1..], len(&off.edges)).into_iter();
        let mut efs = cut(&mut self.edge_faces, len(&off.edge_faces)).into_iter();
        let mut fl = cut(&mut self.vertex_flags, bounds.iter().map(|b| b.1 - b.0)).into_iter();
        let pieces = bounds
            .iter()
            .map(|&(v0, v1)| Piece {
                v0,
                v1,
                faces: f.next().unwrap_or_default(),
                neighbors: n.next().unwrap_or_default(),
                edges: e.next().unwrap_or_default(),
                edge_flags: ef.next().unwrap_or_default(),
                edge_face_ends: ee.next().unwrap_or_default(),
                edge_faces: efs.next().unwrap_or_default(),
                flags: fl.next().unwrap_or_default(),
            })
            .collect();
        (pieces, &self.face_edges)
    }

    /// The fine adjacency: these tables, the offsets, the loops, and what carries over
    /// from `coarse` (components, orientability, manifoldness).
    fn into_topology(
        self,
        coarse: &Topology,
        off: Offsets,
        loop_offsets: Vec<u32>,
        loop_vertices: Vec<u32>,
    ) -> Topology {
        let nv2 = off.faces.len() - 1;
        let nf2 = self.face_edges.len();
        Topology {
            n_vertices: nv2,
            face_edges: self
                .face_edges
                .into_iter()
                .map(|fe| fe.map(AtomicU32::into_inner))
                .collect(),
            face_component: (0..nf2)
                .into_par_iter()
                .map(|f| coarse.face_component[f / 4])
                .collect(),
            n_repeated_index_faces: 0,
            n_out_of_range_faces: 0,
            edges: self.edges,
            edge_flags: self.edge_flags,
            edge_face_offsets: self.edge_face_offsets,
            edge_faces: self.edge_faces,
            vertex_edge_offsets: off.edges,
            vertex_face_offsets: off.faces.clone(),
            vertex_faces: self.vertex_faces,
            vertex_neighbor_offsets: off.neighbors,
            vertex_neighbors: self.vertex_neighbors,
            vertex_fan_offsets: (0..=nv2 as u32).collect(),
            fan_offsets: off.faces,
            vertex_flags: self.vertex_flags,
            loop_offsets,
            loop_vertices,
            loop_component: coarse.loop_component.clone(),
            n_open_boundary_chains: 0,
            component_orientable: coarse.component_orientable.clone(),
            component_manifold: coarse.component_manifold.clone(),
            counts: Memo::default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_geom::DVec3;

    /// A grid of `nx × ny` squares cut into triangles (diagonals alternating), wrapped into a
    /// torus when `wrap`; faces for which `drop` says so are left out, faces are listed in
    /// the order `face_order` gives and vertices renumbered by `vertex_of`.
    fn grid(
        nx: u32,
        ny: u32,
        wrap: bool,
        drop: impl Fn(u32) -> bool,
        mut face_order: impl FnMut(&mut Vec<[u32; 3]>),
        vertex_of: impl Fn(u32) -> u32,
    ) -> Mesh {
        let (cols, rows) = if wrap { (nx, ny) } else { (nx + 1, ny + 1) };
        let id = |i: u32, j: u32| vertex_of((j % rows) * cols + (i % cols));
        let mut faces = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let [a, b, c, d] = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
                let two = if (i + j) % 2 == 0 {
                    [[a, b, c], [a, c, d]]
                } else {
                    [[a, b, d], [b, c, d]]
                };
                for (k, f) in two.into_iter().enumerate() {
                    if !drop(2 * (j * nx + i) + k as u32) {
                        faces.push(f);
                    }
                }
            }
        }
        face_order(&mut faces);
        let n = cols * rows;
        let mut positions = vec![DVec3::ZERO; n as usize];
        for j in 0..rows {
            for i in 0..cols {
                let (u, w) = (i as f64, j as f64);
                positions[vertex_of(j * cols + i) as usize] =
                    DVec3::new(u, w, (u * 0.7).sin() * (w * 0.3).cos());
            }
        }
        Mesh::new(positions, faces)
    }

    /// `of_split` gives exactly the built tables, or `None` (then says so).
    fn derived_is_built(m: &Mesh) -> bool {
        let t = Topology::build(m);
        let fine = t.uniform_split(m);
        match t.of_split(m, &fine) {
            Some(d) => {
                assert_eq!(d, Topology::build(&fine));
                true
            }
            None => false,
        }
    }

    /// The lean split is the full one without its vertex neighbours, and cannot be split
    /// again from.
    #[test]
    fn the_lean_split_is_the_split_without_neighbours() {
        let m = grid(8, 8, false, |f| (36..40).contains(&f), |_| {}, |v| v);
        let t = Topology::build(&m);
        let fine = t.uniform_split(&m);
        let (Some(full), Some(lean)) = (t.of_split(&m, &fine), t.of_split_lean(&m, &fine)) else {
            panic!("the grid's split is derived");
        };
        assert!(full.has_vertex_neighbors() && !lean.has_vertex_neighbors());
        assert_ne!(full, lean);
        let mut stripped = full.clone();
        stripped.vertex_neighbor_offsets.clear();
        stripped.vertex_neighbors.clear();
        assert_eq!(stripped, lean);
        assert_eq!(lean.of_split(&fine, &lean.uniform_split(&fine)), None);
    }

    fn keep_all(_: u32) -> bool {
        false
    }

    #[test]
    fn the_split_of_closed_meshes_matches_the_build() {
        assert!(derived_is_built(&crate::fixtures::tetrahedron()));
        assert!(derived_is_built(&grid(6, 5, true, keep_all, |_| {}, |v| v)));
        // Reversed face order and vertex numbering: other fan starts and edge orders.
        let n = 6 * 5;
        assert!(derived_is_built(&grid(
            6,
            5,
            true,
            keep_all,
            |f| f.reverse(),
            |v| n - 1 - v
        )));
    }

    #[test]
    fn the_split_of_meshes_with_holes_and_parts_matches_the_build() {
        // A hole in the middle, and a triangle cut away at a corner.
        let holed = grid(
            8,
            8,
            false,
            |f| (36..40).contains(&f) || f == 0,
            |_| {},
            |v| v,
        );
        assert_eq!(Topology::build(&holed).n_boundary_loops(), 2);
        assert!(derived_is_built(&holed));
        // Two components: a torus and an open grid side by side, faces interleaved.
        let a = grid(5, 4, true, keep_all, |_| {}, |v| v);
        let b = grid(3, 3, false, keep_all, |_| {}, |v| v);
        let shift = a.n_vertices() as u32;
        let mut positions = a.positions.clone();
        positions.extend(b.positions.iter().map(|p| *p + DVec3::X * 20.0));
        let mut faces = Vec::new();
        for i in 0..a.n_faces().max(b.n_faces()) {
            faces.extend(a.faces.get(i).copied());
            faces.extend(b.faces.get(i).map(|f| f.map(|v| v + shift)));
        }
        let both = Mesh::new(positions, faces);
        assert_eq!(Topology::build(&both).n_components(), 2);
        assert!(derived_is_built(&both));
    }

    #[test]
    fn a_vertex_of_many_faces_splits_like_the_build() {
        // A cone of 24 faces round an apex (the build's general path), closed by a fan.
        let k = 24u32;
        let mut positions = vec![DVec3::Z, DVec3::ZERO];
        positions.extend((0..k).map(|i| {
            let a = std::f64::consts::TAU * f64::from(i) / f64::from(k);
            DVec3::new(a.cos(), a.sin(), 0.0)
        }));
        let rim = |i: u32| 2 + i % k;
        let mut faces: Vec<[u32; 3]> = (0..k).map(|i| [0, rim(i), rim(i + 1)]).collect();
        faces.extend((0..k).map(|i| [1, rim(i + 1), rim(i)]));
        assert!(derived_is_built(&Mesh::new(positions, faces)));
    }

    #[test]
    fn random_holes_and_orders_match_the_build_or_are_declined() {
        let mut rng = coarsen_geom::SplitMix64::new(1);
        let mut next = move || rng.next_u64();
        let mut derived = 0;
        for round in 0..80 {
            let (nx, ny) = (3 + (next() % 6) as u32, 3 + (next() % 6) as u32);
            let wrap = round % 3 == 0;
            let holes: Vec<u32> = (0..(next() % 5))
                .map(|_| (next() % (2 * nx * ny) as u64) as u32)
                .collect();
            let n = if wrap { nx * ny } else { (nx + 1) * (ny + 1) };
            let shift = (next() % u64::from(n)) as u32;
            let swap = next();
            let m = grid(
                nx,
                ny,
                wrap,
                |f| holes.contains(&f),
                |faces| {
                    let len = faces.len();
                    for i in 0..len {
                        let j = ((swap >> (i % 60)) as usize ^ i) % len;
                        faces.swap(i, j);
                    }
                },
                |v| (v + shift) % n,
            );
            // Holes can leave unused vertices or bow-ties: those are declined.
            derived += usize::from(derived_is_built(&m));
        }
        assert!(derived > 30, "only {derived} of 80 meshes derived");
    }

    #[test]
    fn a_mesh_that_is_not_the_split_is_declined() {
        let m = grid(4, 4, true, keep_all, |_| {}, |v| v);
        let t = Topology::build(&m);
        let mut fine = t.uniform_split(&m);
        fine.faces.swap(0, 1);
        assert_eq!(t.of_split(&m, &fine), None);
        // A bow-tie: not a manifold, left to the build.
        let b = crate::fixtures::bowtie();
        let tb = Topology::build(&b);
        assert_eq!(tb.of_split(&b, &tb.uniform_split(&b)), None);
    }
}
