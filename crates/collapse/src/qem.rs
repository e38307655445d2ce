//! The quadric error metric of Garland & Heckbert (1997), *Surface simplification using
//! quadric error metrics*, as a [`CostModel`] for edge collapses.
//!
//! * **Vertex quadrics.** Each vertex starts with the sum of the plane quadrics `p pᵀ` of
//!   its faces. With `area_weighted` (the default) each plane is weighted by its face's
//!   area, so a quadric measures area × squared distance — the integrated error — and a
//!   dense region does not weigh more than a coarse one of the same size; without it every
//!   face counts 1, as in the paper's first version.
//! * **Boundaries.** Each boundary edge adds, to both its ends, the plane through the edge
//!   perpendicular to its face, weighted by `boundary_weight` (× the squared edge length
//!   when area-weighted, so that it scales like the face terms). Moving a boundary vertex
//!   off its boundary line then costs far more than moving it along.
//! * **Placement.** The merged vertex goes to the minimiser of the summed quadric when
//!   that 3×3 system is well conditioned (relative determinant above `1e-10`) and the
//!   minimiser lies within twice the edge length of the edge's midpoint; otherwise to the
//!   cheapest of the endpoints and the midpoint (the first of equals, in that order). A
//!   merge pinned by the boundary rules (interior onto boundary) goes to its boundary
//!   vertex. A boundary edge collapses onto whichever of its two ends costs less (the
//!   first on a tie), so boundary vertices always sit on input boundary vertices and a
//!   boundary never leaves its own line; the constraint planes make the end that would
//!   cut a corner of the boundary the expensive one, so corners stay.
//! * **Cost.** `v̄ᵀ Q v̄` of the summed quadric, divided by `diagonal⁴` (area-weighted) or
//!   `diagonal²` (not), so that costs — and the `max_error` limit — do not depend on the
//!   model's size: they are those of the same mesh scaled to a unit diagonal.
//! * **Update.** The merged vertex keeps the sum of the merged quadrics.
//! * **Texture coordinates** ([`QemOptions::uv_weight`], off by default): on a mesh whose
//!   seams are tracked with UVs, each face adds Hoppe's (1999) attribute terms: its UV
//!   field is linear over the face, s(x) = g·x + d for each of u and v, and the term
//!   w·(g·x + d − s)² measures how far a value s at point x is from it. Summed per vertex,
//!   the value s that fits the merged faces best is taken for each of u and v (their
//!   minimum over s), and what is left — how far the merged region's UV field is from one
//!   linear map — adds `uv_weight` times itself to the cost. UVs are scaled by the
//!   bounding-box diagonal first, so that a UV error of the texture's width weighs as a
//!   distance of the diagonal; w is the face's area (or 1, as the planes). The placement
//!   stays the geometric one: the output's UVs are taken from the input where each vertex
//!   lands ([`crate::LiveMesh::track_seams`]). A seam vertex, whose faces disagree on
//!   its UV, carries a standing term that makes merges into it dearer.
//! * **Unit.** Edges by default; with [`QemOptions::unit`] = [`Unit::Triangle`] a
//!   candidate is a triangle whose three quadrics are summed and placed the same way (the
//!   triangle-collapse QEM of Zhou, Pan & Shi 1998, paper 2's baseline [8]).

use crate::{CostModel, Index, LiveMesh, Merge, Plan, Reach, Unit, VertexKind};
use coarsen_geom::{DVec2, DVec3, Quadric, triangle};
use rayon::prelude::*;

/// Relative determinant below which the quadric's minimiser is not trusted.
const SOLVE_TOLERANCE: f64 = 1e-10;

/// How far from the merged vertices' centroid the minimiser may lie, in units of their
/// largest distance to it (for an edge: half its length).
const MAX_REACH: f64 = 4.0;

/// Settings of [`QuadricModel`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QemOptions {
    /// Weight each face plane by the face's area. Default `true`.
    pub area_weighted: bool,
    /// Weight of boundary constraint planes relative to face planes. Default `1000`.
    pub boundary_weight: f64,
    /// What a candidate merges: edges (Garland–Heckbert) or triangles. Default edges.
    pub unit: Unit,
    /// Weight of the texture-coordinate terms in the cost (module docs); 0 (the
    /// default) leaves the cost geometric.
    pub uv_weight: f64,
}

impl Default for QemOptions {
    fn default() -> Self {
        QemOptions {
            area_weighted: true,
            boundary_weight: 1000.0,
            unit: Unit::Edge,
            uv_weight: 0.0,
        }
    }
}

/// Garland–Heckbert quadrics, one per vertex.
#[derive(Clone, Debug)]
pub struct QuadricModel {
    quadrics: Vec<Quadric>,
    /// Per vertex, the texture-coordinate terms, with their weight in the cost (module
    /// docs), when asked for and the mesh has UVs.
    uv: Option<(Vec<UvQuadric>, f64)>,
    /// Costs are divided by this (diagonal⁴ or diagonal²).
    cost_unit: f64,
    unit: Unit,
}

/// Σ w·(gⱼ·x + dⱼ − sⱼ)² over faces, for the two UV components j, as a function of the
/// point x and the values s: the x-only part as a quadric, with Σ w·gⱼ, Σ w·dⱼ and Σ w.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UvQuadric {
    /// Σ w·(gⱼ·x + dⱼ)² over both components.
    q: Quadric,
    /// Σ w·gⱼ per component.
    grad: [DVec3; 2],
    /// Σ w·dⱼ per component.
    offset: [f64; 2],
    /// Σ w.
    weight: f64,
}

impl UvQuadric {
    /// The terms of the face with corners `p` and UVs `uv` (scaled), weighted by `w`;
    /// `None` for a degenerate face.
    fn of_face(p: [DVec3; 3], uv: [DVec2; 3], w: f64) -> Option<UvQuadric> {
        let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
        let n = e1.cross(e2);
        let n2 = n.length_squared();
        if n2 == 0.0 || !n2.is_finite() {
            return None;
        }
        // The gradient in the face's plane with g·e1 = s1 − s0 and g·e2 = s2 − s0.
        let (a, b) = (e2.cross(n) / n2, n.cross(e1) / n2);
        let mut out = UvQuadric {
            weight: w,
            ..UvQuadric::default()
        };
        for j in 0..2 {
            let s = uv.map(|t| t[j]);
            let g = a * (s[1] - s[0]) + b * (s[2] - s[0]);
            let d = s[0] - g.dot(p[0]);
            out.q += Quadric::from_plane_offset(g, d, w);
            out.grad[j] = g * w;
            out.offset[j] = d * w;
        }
        Some(out)
    }

    /// The least of the terms over the values s at point `x`: what is left when each UV
    /// component takes the value that fits the faces best.
    fn least(&self, x: DVec3) -> f64 {
        if self.weight <= 0.0 {
            return 0.0;
        }
        let fit: f64 = (0..2)
            .map(|j| {
                let t = self.grad[j].dot(x) + self.offset[j];
                t * t
            })
            .sum();
        (self.q.eval(x) - fit / self.weight).max(0.0)
    }
}

impl std::ops::AddAssign for UvQuadric {
    fn add_assign(&mut self, o: UvQuadric) {
        self.q += o.q;
        for j in 0..2 {
            self.grad[j] += o.grad[j];
            self.offset[j] += o.offset[j];
        }
        self.weight += o.weight;
    }
}

/// Calls `add` with each term `face` gives a vertex's quadric, in order: its plane (to
/// each corner), then each boundary edge's constraint plane (to both its ends).
fn add_face_terms(
    mesh: &LiveMesh,
    opts: &QemOptions,
    face: [Index; 3],
    mut add: impl FnMut(Index, Quadric),
) {
    let [a, b, c] = face.map(|v| mesh.position(v));
    let cross = triangle::cross(a, b, c);
    let twice_area = cross.length();
    if twice_area == 0.0 || !twice_area.is_finite() {
        return;
    }
    let n = cross / twice_area;
    let w = if opts.area_weighted {
        0.5 * twice_area
    } else {
        1.0
    };
    let q = Quadric::from_plane(n, a, w);
    for &v in &face {
        add(v, q);
    }
    if opts.boundary_weight <= 0.0 {
        return;
    }
    for i in 0..3 {
        let (u, v) = (face[i], face[(i + 1) % 3]);
        if !mesh.is_boundary_edge(u, v) {
            continue;
        }
        let (pu, pv) = (mesh.position(u), mesh.position(v));
        let w = opts.boundary_weight
            * if opts.area_weighted {
                (pv - pu).length_squared()
            } else {
                1.0
            };
        if let Some(q) = edge_plane(pu, pv, n, w) {
            add(u, q);
            add(v, q);
        }
    }
}

/// `weight` × the squared distance to the plane through the edge `pu`–`pv` perpendicular to
/// its face (unit normal `n`): the constraint that keeps a boundary on its line. `None`
/// when the edge is degenerate or parallel to `n`.
pub fn edge_plane(pu: DVec3, pv: DVec3, n: DVec3, weight: f64) -> Option<Quadric> {
    let m = (pv - pu).cross(n).normalize_or_zero();
    (m != DVec3::ZERO).then(|| Quadric::from_plane(m, pu, weight))
}

impl QuadricModel {
    /// The initial quadrics of `mesh`'s vertices.
    pub fn new(mesh: &LiveMesh, opts: &QemOptions) -> Self {
        // Each vertex sums its terms in face order, as one pass over the faces would: the
        // vertices are cut into ranges, one per thread, and each range walks every face
        // and keeps the terms of its own vertices (the faces' terms recomputed where they
        // touch two ranges), so the sums are the same bits on any number of threads.
        let mut quadrics = vec![Quadric::ZERO; mesh.vertex_slots()];
        let range = quadrics
            .len()
            .div_ceil(rayon::current_num_threads().max(1))
            .max(1 << 12);
        quadrics
            .par_chunks_mut(range)
            .enumerate()
            .for_each(|(i, own)| {
                let (lo, len) = ((i * range) as Index, own.len());
                let mine = |v: Index| v >= lo && ((v - lo) as usize) < len;
                for f in mesh.live_faces() {
                    let face = mesh.face(f);
                    if face.iter().any(|&v| mine(v)) {
                        add_face_terms(mesh, opts, face, |v, q| {
                            if mine(v) {
                                own[(v - lo) as usize] += q;
                            }
                        });
                    }
                }
            });
        let d = mesh.diagonal();
        let cost_unit = match (d > 0.0, opts.area_weighted) {
            (false, _) => 1.0,
            (true, true) => d.powi(4),
            (true, false) => d * d,
        };
        let uv = (opts.uv_weight > 0.0)
            .then(|| uv_quadrics(mesh, opts, if d > 0.0 { d } else { 1.0 }))
            .flatten()
            .map(|q| (q, opts.uv_weight));
        QuadricModel {
            quadrics,
            uv,
            cost_unit,
            unit: opts.unit,
        }
    }

    /// Collapse edges or triangles from now on (a triangle run finishes on an exact count
    /// with a few edge collapses).
    pub fn set_unit(&mut self, unit: Unit) {
        self.unit = unit;
    }

    /// The current quadric of vertex `v`.
    pub fn quadric(&self, v: Index) -> &Quadric {
        &self.quadrics[v as usize]
    }

    /// Σ of the quadrics of `verts`, added in order from zero.
    #[inline]
    fn sum(&self, verts: &[Index]) -> Quadric {
        let mut q = Quadric::ZERO;
        for &v in verts {
            q += self.quadrics[v as usize];
        }
        q
    }

    /// The weighted texture-coordinate cost of merging `verts` at `x` (0 without them).
    fn uv_cost(&self, verts: &[Index], x: DVec3) -> f64 {
        let Some((uv, weight)) = &self.uv else {
            return 0.0;
        };
        let mut q = UvQuadric::default();
        for &v in verts {
            q += uv[v as usize];
        }
        weight * q.least(x)
    }
}

/// Each vertex's texture-coordinate terms (module docs), summed in face order as the
/// quadrics are; `None` when `mesh` tracks no UVs. UVs are scaled by `scale`.
fn uv_quadrics(mesh: &LiveMesh, opts: &QemOptions, scale: f64) -> Option<Vec<UvQuadric>> {
    mesh.face_uvs(mesh.live_faces().next()?)?;
    let mut out = vec![UvQuadric::default(); mesh.vertex_slots()];
    let range = out
        .len()
        .div_ceil(rayon::current_num_threads().max(1))
        .max(1 << 12);
    out.par_chunks_mut(range).enumerate().for_each(|(i, own)| {
        let (lo, len) = ((i * range) as Index, own.len());
        let mine = |v: Index| v >= lo && ((v - lo) as usize) < len;
        for f in mesh.live_faces() {
            let face = mesh.face(f);
            if !face.iter().any(|&v| mine(v)) {
                continue;
            }
            let Some(uv) = mesh.face_uvs(f) else { continue };
            let p = face.map(|v| mesh.position(v));
            let w = if opts.area_weighted {
                0.5 * triangle::cross(p[0], p[1], p[2]).length()
            } else {
                1.0
            };
            let Some(q) = UvQuadric::of_face(p, uv.map(|t| t * scale), w) else {
                continue;
            };
            for &v in &face {
                if mine(v) {
                    own[(v - lo) as usize] += q;
                }
            }
        }
    });
    Some(out)
}

impl CostModel for QuadricModel {
    fn unit(&self) -> Unit {
        self.unit
    }

    fn reach(&self) -> Reach {
        Reach::Kept
    }

    fn plan(&self, mesh: &LiveMesh, merge: &Merge<'_>) -> Option<Plan> {
        let q = self.sum(merge.vertices);
        let mut boundary = merge
            .vertices
            .iter()
            .copied()
            .filter(|&v| mesh.kind(v) == VertexKind::Boundary);
        let position = match (merge.pinned, boundary.next(), boundary.next()) {
            (Some(v), _, _) => mesh.position(v),
            (None, Some(a), Some(b)) => {
                let (pa, pb) = (mesh.position(a), mesh.position(b));
                if q.eval(pa) <= q.eval(pb) { pa } else { pb }
            }
            _ => {
                let n = merge.vertices.len() as f64;
                let centroid = merge
                    .vertices
                    .iter()
                    .map(|&v| mesh.position(v))
                    .sum::<DVec3>()
                    / n;
                let radius = merge
                    .vertices
                    .iter()
                    .map(|&v| (mesh.position(v) - centroid).length())
                    .fold(0.0, f64::max);
                match q.minimizer(SOLVE_TOLERANCE) {
                    Some(x) if (x - centroid).length() <= MAX_REACH * radius => x,
                    _ => {
                        let mut best = centroid;
                        let mut best_cost = q.eval(centroid);
                        for &v in merge.vertices.iter().rev() {
                            let p = mesh.position(v);
                            let c = q.eval(p);
                            if c <= best_cost {
                                (best, best_cost) = (p, c);
                            }
                        }
                        best
                    }
                }
            }
        };
        let cost = q.eval(position) + self.uv_cost(merge.vertices, position);
        Some(Plan {
            position,
            cost: cost / self.cost_unit,
        })
    }

    fn merged(&mut self, _mesh: &LiveMesh, kept: Index, merged: &[Index]) {
        self.quadrics[kept as usize] = self.sum(merged);
        if let Some((uv, _)) = &mut self.uv {
            let mut q = UvQuadric::default();
            for &v in merged {
                q += uv[v as usize];
            }
            uv[kept as usize] = q;
        }
    }

    fn renumber(&mut self, vertices: &[Index], _faces: &[Index]) -> bool {
        crate::keep_in_order(&mut self.quadrics, vertices);
        if let Some((uv, _)) = &mut self.uv {
            crate::keep_in_order(uv, vertices);
        }
        true
    }

    /// The whole's quadrics of the part's vertices, as the whole's collapses left them.
    fn for_part(&self, part: &LiveMesh) -> Option<Self> {
        let whole = |v: Index| part.input_index(v) as usize;
        Some(QuadricModel {
            quadrics: (0..part.vertex_slots() as Index)
                .map(|v| self.quadrics[whole(v)])
                .collect(),
            uv: self.uv.as_ref().map(|(uv, w)| {
                let part_uv = (0..part.vertex_slots() as Index)
                    .map(|v| uv[whole(v)])
                    .collect();
                (part_uv, *w)
            }),
            cost_unit: self.cost_unit,
            unit: self.unit,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::grid;

    /// The terms of every face around each vertex of `mesh` (UVs per vertex from
    /// `uv_of`), unweighted by area.
    fn vertex_uv_terms(
        mesh: &coarsen_mesh::Mesh,
        uv_of: impl Fn(DVec3) -> DVec2,
    ) -> Vec<UvQuadric> {
        let mut out = vec![UvQuadric::default(); mesh.n_vertices()];
        for face in &mesh.faces {
            let p = face.map(|v| mesh.positions[v as usize]);
            let q = UvQuadric::of_face(p, p.map(&uv_of), 1.0).unwrap();
            for &v in face {
                out[v as usize] += q;
            }
        }
        out
    }

    #[test]
    fn uv_terms_vanish_for_one_linear_map_and_grow_where_it_bends() {
        // A flat grid: its faces' UV fields agree everywhere on it when the UVs are one
        // linear map of the position; with u = x² they agree at the vertex only.
        let mesh = grid(12, 12, |_, _| 0.0);
        let linear = vertex_uv_terms(&mesh, |p| DVec2::new(2.0 * p.x - p.y, p.y + 0.5));
        let bent = vertex_uv_terms(&mesh, |p| DVec2::new(p.x * p.x, p.y));
        // Away from the vertex, where the faces' fields extend beyond their own face.
        let off = DVec3::new(0.03, 0.02, 0.0);
        let (mut most, mut most_bent) = (0.0f64, 0.0f64);
        for (v, &p) in mesh.positions.iter().enumerate() {
            most = most.max(linear[v].least(p)).max(linear[v].least(p + off));
            most_bent = most_bent.max(bent[v].least(p + off));
        }
        assert!(most < 1e-12, "{most}");
        assert!(most_bent > 1e-6, "{most_bent}");
        // The value that fits best is the map's own at the vertex.
        let v = 7 * 13 + 6;
        let (q, p) = (linear[v], mesh.positions[v]);
        let u = (q.grad[0].dot(p) + q.offset[0]) / q.weight;
        assert!((u - (2.0 * p.x - p.y)).abs() < 1e-12, "{u}");
    }

    #[test]
    fn uv_terms_are_one_pass_sums_on_any_thread_count() {
        let mesh = coarsen_shapes::with_planar_uvs(grid(120, 120, |x, y| {
            (7.0 * x).sin() * (5.0 * y).cos() * 0.1
        }));
        let mut live = LiveMesh::new(&mesh).unwrap();
        live.track_seams(&mut mesh.clone());
        let opts = QemOptions {
            uv_weight: 1.0,
            ..QemOptions::default()
        };
        let one = coarsen_testdata::on_threads(1, || QuadricModel::new(&live, &opts));
        let (terms, _) = one.uv.as_ref().expect("the grid has UVs");
        assert!(terms.iter().all(|t| t.weight > 0.0));
        for threads in [2, 3, 8] {
            let model = coarsen_testdata::on_threads(threads, || QuadricModel::new(&live, &opts));
            assert!(model.uv == one.uv, "{threads} threads");
        }
        // Off by default, and off on a mesh without UVs.
        assert!(
            QuadricModel::new(&live, &QemOptions::default())
                .uv
                .is_none()
        );
        let bare = LiveMesh::new(&grid(4, 4, |_, _| 0.0)).unwrap();
        assert!(QuadricModel::new(&bare, &opts).uv.is_none());
    }

    #[test]
    fn initial_quadrics_are_one_pass_sums_on_any_thread_count() {
        // An open, bumpy grid of 14,641 vertices: several vertex ranges, boundary terms.
        let mesh = grid(120, 120, |x, y| (7.0 * x).sin() * (5.0 * y).cos() * 0.1);
        let live = LiveMesh::new(&mesh).unwrap();
        let opts = QemOptions::default();
        // The reference: one pass over the faces, each term added where it goes.
        let mut one_pass = vec![Quadric::ZERO; live.vertex_slots()];
        for f in live.live_faces() {
            add_face_terms(&live, &opts, live.face(f), |v, q| one_pass[v as usize] += q);
        }
        assert!(one_pass.iter().all(|q| *q != Quadric::ZERO));
        for threads in [1, 2, 3, 8] {
            let model = coarsen_testdata::on_threads(threads, || QuadricModel::new(&live, &opts));
            assert!(model.quadrics == one_pass, "{threads} threads");
        }
    }
}
