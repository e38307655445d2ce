//! Sharp features of a triangle mesh: the edges a coarsening must keep, the curves they
//! chain into, and the corners where curves meet.
//!
//! * A **feature edge** is an edge of two faces whose normals differ by more than
//!   [`FeatureOptions::angle_deg`] (the supplement of the dihedral angle: 0° on a flat
//!   region, 90° on a cube's edge) — [`FeatureKind::Sharp`] —, an edge of one face
//!   ([`FeatureKind::Boundary`], with [`FeatureOptions::boundary`]), an edge of three or
//!   more faces ([`FeatureKind::Junction`]), or an edge the input marks
//!   ([`FeatureKind::Marked`]: one of [`Mesh::marked_edges`], e.g. an OBJ `l` or a PLY
//!   `edge` element, whatever its angle; a marked edge that is also sharp, boundary or
//!   junction is of this kind; a marked pair of vertices that is no edge of the topology
//!   is ignored).
//! * A **corner** is a vertex where a feature curve cannot go on through: where one, or
//!   three or more, feature edges meet, or where two meet at a turn sharper than
//!   [`FeatureOptions::corner_angle_deg`].
//! * A **feature curve** is a maximal chain of feature edges between corners: open (from
//!   corner to corner) or closed (a loop without a corner, e.g. the rim of a cylinder).
//!
//! The detection reads the mesh and its [`Topology`] only; it is sequential and in index
//! order, so the same mesh gives the same features. Later stages read the result as
//! constraints (a corner stays, a curve vertex moves only along its curve).

use coarsen_geom::{DVec3, triangle};
use coarsen_mesh::{Mesh, Topology};
use serde::{Deserialize, Serialize};

/// Settings of [`Features::detect`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FeatureOptions {
    /// An edge is sharp when its two faces' normals differ by more than this (degrees).
    pub angle_deg: f64,
    /// A vertex of two feature edges is a corner when the curve turns there by more than
    /// this (degrees; 0° is straight on).
    pub corner_angle_deg: f64,
    /// Whether boundary edges are feature edges.
    pub boundary: bool,
}

impl Default for FeatureOptions {
    fn default() -> Self {
        FeatureOptions {
            angle_deg: 40.0,
            corner_angle_deg: 45.0,
            boundary: true,
        }
    }
}

/// Why an edge is a feature.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FeatureKind {
    /// Its two faces turn by more than the angle.
    Sharp,
    /// It has one face.
    Boundary,
    /// It has three or more faces.
    Junction,
    /// The input marks it.
    Marked,
}

/// What a vertex is to the features.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum VertexRole {
    /// On no feature edge.
    Free,
    /// Inside feature curve `0` (not at its ends).
    Curve(u32),
    /// A corner.
    Corner,
}

/// The features of one mesh (see the crate docs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Features {
    /// Feature edges of the topology, ascending, with their kind.
    pub edges: Vec<(u32, FeatureKind)>,
    /// Corners, ascending.
    pub corners: Vec<u32>,
    /// Where each curve's vertices start in `curve_vertices` (one more entry than curves).
    pub curve_offsets: Vec<u32>,
    /// The curves' vertices, curve by curve, in order along each; an open curve starts
    /// and ends at corners, a closed one lists each vertex once (its last joins its first).
    pub curve_vertices: Vec<u32>,
    /// Per curve: whether it is closed.
    pub curve_closed: Vec<bool>,
    /// Per vertex: its role.
    pub roles: Vec<VertexRole>,
}

/// Counts of [`Features`], for reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct FeatureCounts {
    /// Sharp edges.
    pub sharp_edges: usize,
    /// Boundary edges taken as features.
    pub boundary_edges: usize,
    /// Edges of three or more faces.
    pub junction_edges: usize,
    /// Edges the input marks (counted here only, whatever else they are).
    #[serde(default)]
    pub marked_edges: usize,
    /// Feature curves.
    pub curves: usize,
    /// Of which closed.
    pub closed_curves: usize,
    /// Corners.
    pub corners: usize,
}

/// The edges of `topo` (the adjacency of `mesh`) whose two faces' normals differ by more
/// than `angle_deg`, ascending. An edge with a degenerate face is never sharp.
pub fn sharp_edges(mesh: &Mesh, topo: &Topology, angle_deg: f64) -> Vec<u32> {
    let cos_limit = angle_deg.to_radians().cos();
    let normal = |f: u32| {
        let [a, b, c] = mesh.corners(f as usize);
        triangle::cross(a, b, c)
    };
    (0..topo.n_edges() as u32)
        .filter(|&e| match topo.edge_faces(e) {
            &[f, g] => {
                let (n, m) = (normal(f), normal(g));
                let lengths = n.length() * m.length();
                lengths > 0.0 && n.dot(m) < cos_limit * lengths
            }
            _ => false,
        })
        .collect()
}

impl Features {
    /// The features of `mesh`, whose adjacency is `topo`.
    pub fn detect(mesh: &Mesh, topo: &Topology, opts: &FeatureOptions) -> Features {
        let edges = feature_edges(mesh, topo, opts);
        let nv = topo.n_vertices();
        let (off, incident) = incident_edges(topo, nv, &edges);
        let corners = find_corners(mesh, topo, opts, &off, &incident);
        let mut roles = vec![VertexRole::Free; nv];
        corners
            .iter()
            .for_each(|&v| roles[v as usize] = VertexRole::Corner);
        let mut f = Features {
            edges,
            corners,
            curve_offsets: vec![0],
            curve_vertices: Vec::new(),
            curve_closed: Vec::new(),
            roles,
        };
        f.chain_curves(topo, &off, &incident);
        f
    }

    /// Number of feature curves.
    pub fn n_curves(&self) -> usize {
        self.curve_closed.len()
    }

    /// The vertices of curve `c`, in order along it.
    pub fn curve(&self, c: usize) -> &[u32] {
        let (a, b) = (self.curve_offsets[c], self.curve_offsets[c + 1]);
        &self.curve_vertices[a as usize..b as usize]
    }

    /// The counts of each kind of feature.
    pub fn counts(&self) -> FeatureCounts {
        let of = |k| self.edges.iter().filter(|e| e.1 == k).count();
        FeatureCounts {
            sharp_edges: of(FeatureKind::Sharp),
            boundary_edges: of(FeatureKind::Boundary),
            junction_edges: of(FeatureKind::Junction),
            marked_edges: of(FeatureKind::Marked),
            curves: self.n_curves(),
            closed_curves: self.curve_closed.iter().filter(|&&c| c).count(),
            corners: self.corners.len(),
        }
    }

    /// Walks the feature edges into curves: from every corner along each of its feature
    /// edges not walked yet, to the next corner; then the loops that no corner cuts, each
    /// from its smallest vertex.
    fn chain_curves(&mut self, topo: &Topology, off: &[u32], incident: &[u32]) {
        let mut walked = vec![false; topo.n_edges()];
        let starts: Vec<u32> = self.corners.clone();
        for v in starts {
            for i in off[v as usize]..off[v as usize + 1] {
                let e = incident[i as usize];
                if !walked[e as usize] {
                    self.walk(topo, off, incident, &mut walked, v, e, false);
                }
            }
        }
        // Loops without a corner: every vertex on them has two feature edges.
        for v in 0..topo.n_vertices() as u32 {
            if self.roles[v as usize] != VertexRole::Free {
                continue;
            }
            let Some(&e) = incident[off[v as usize] as usize..off[v as usize + 1] as usize]
                .iter()
                .find(|&&e| !walked[e as usize])
            else {
                continue;
            };
            self.walk(topo, off, incident, &mut walked, v, e, true);
        }
    }

    /// Walks one curve from `start` along edge `first`, marking its edges in `walked`,
    /// until a corner (open) or back at `start` (closed), and records it.
    #[allow(clippy::too_many_arguments)]
    fn walk(
        &mut self,
        topo: &Topology,
        off: &[u32],
        incident: &[u32],
        walked: &mut [bool],
        start: u32,
        first: u32,
        closed: bool,
    ) {
        let id = self.n_curves() as u32;
        let (mut v, mut e) = (start, first);
        self.curve_vertices.push(start);
        if closed {
            self.roles[start as usize] = VertexRole::Curve(id);
        }
        loop {
            walked[e as usize] = true;
            let [a, b] = topo.edge(e);
            v = if a == v { b } else { a };
            if v == start || self.roles[v as usize] == VertexRole::Corner {
                if !closed {
                    self.curve_vertices.push(v);
                }
                break;
            }
            self.curve_vertices.push(v);
            self.roles[v as usize] = VertexRole::Curve(id);
            // Not a corner: exactly two feature edges, one of them `e`.
            let next = incident[off[v as usize] as usize..off[v as usize + 1] as usize]
                .iter()
                .copied()
                .find(|&g| g != e && !walked[g as usize]);
            match next {
                Some(g) => e = g,
                None => break,
            }
        }
        self.curve_offsets.push(self.curve_vertices.len() as u32);
        self.curve_closed.push(closed);
    }
}

/// The position of edge `e` in the sorted feature edges, if it is one.
#[cfg(test)]
fn self_edge_index(edges: &[(u32, FeatureKind)], e: u32) -> Option<usize> {
    edges.binary_search_by_key(&e, |x| x.0).ok()
}

/// The edges of `topo` that `mesh` marks ([`Mesh::marked_edges`]), ascending, each once;
/// marked pairs that are no edge of `topo` are left out.
fn marked_edges(mesh: &Mesh, topo: &Topology) -> Vec<u32> {
    let mut marked: Vec<u32> = mesh
        .marked_edges
        .iter()
        .filter_map(|&[a, b]| topo.find_edge(a, b))
        .collect();
    marked.sort_unstable();
    marked.dedup();
    marked
}

/// Every feature edge of `topo`, ascending, with its kind.
fn feature_edges(mesh: &Mesh, topo: &Topology, opts: &FeatureOptions) -> Vec<(u32, FeatureKind)> {
    let sharp = sharp_edges(mesh, topo, opts.angle_deg);
    let marked = marked_edges(mesh, topo);
    let mut out: Vec<(u32, FeatureKind)> = Vec::with_capacity(sharp.len() + marked.len());
    let mut s = sharp.iter().peekable();
    let mut m = marked.iter().peekable();
    for e in 0..topo.n_edges() as u32 {
        let kind = match topo.edge_faces(e).len() {
            _ if m.peek() == Some(&&e) => Some(FeatureKind::Marked),
            1 if opts.boundary => Some(FeatureKind::Boundary),
            n if n >= 3 => Some(FeatureKind::Junction),
            _ if s.peek() == Some(&&e) => Some(FeatureKind::Sharp),
            _ => None,
        };
        if s.peek() == Some(&&e) {
            s.next();
        }
        if m.peek() == Some(&&e) {
            m.next();
        }
        if let Some(k) = kind {
            out.push((e, k));
        }
    }
    out
}

/// The feature edges at each vertex, as a table: vertex `v`'s are
/// `incident[off[v]..off[v + 1]]`, ascending.
fn incident_edges(
    topo: &Topology,
    nv: usize,
    edges: &[(u32, FeatureKind)],
) -> (Vec<u32>, Vec<u32>) {
    let mut off = vec![0u32; nv + 1];
    for &(e, _) in edges {
        for v in topo.edge(e) {
            off[v as usize + 1] += 1;
        }
    }
    for i in 0..nv {
        off[i + 1] += off[i];
    }
    let mut fill = off.clone();
    let mut incident = vec![0u32; off[nv] as usize];
    for &(e, _) in edges {
        for v in topo.edge(e) {
            incident[fill[v as usize] as usize] = e;
            fill[v as usize] += 1;
        }
    }
    (off, incident)
}

/// The corners: vertices of one, or three or more, feature edges, and those of two where
/// the curve turns by more than the corner angle (or either edge has no length).
fn find_corners(
    mesh: &Mesh,
    topo: &Topology,
    opts: &FeatureOptions,
    off: &[u32],
    incident: &[u32],
) -> Vec<u32> {
    let cos_corner = opts.corner_angle_deg.to_radians().cos();
    let other = |e: u32, v: u32| {
        let [a, b] = topo.edge(e);
        if a == v { b } else { a }
    };
    (0..topo.n_vertices() as u32)
        .filter(|&v| {
            let mine = &incident[off[v as usize] as usize..off[v as usize + 1] as usize];
            match mine {
                [] => false,
                &[e, g] => {
                    let p = mesh.positions[v as usize];
                    let into: DVec3 = p - mesh.positions[other(e, v) as usize];
                    let out: DVec3 = mesh.positions[other(g, v) as usize] - p;
                    let lengths = into.length() * out.length();
                    !(lengths > 0.0 && into.dot(out) >= cos_corner * lengths)
                }
                _ => true,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests;
