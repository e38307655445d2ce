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
//! * **Unit.** Edges by default; with [`QemOptions::unit`] = [`Unit::Triangle`] a
//!   candidate is a triangle whose three quadrics are summed and placed the same way (the
//!   triangle-collapse QEM of Zhou, Pan & Shi 1998, paper 2's baseline [8]).

use crate::{CostModel, Index, LiveMesh, Merge, Plan, Reach, Unit, VertexKind};
use coarsen_geom::{DVec3, Quadric, triangle};
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
}

impl Default for QemOptions {
    fn default() -> Self {
        QemOptions {
            area_weighted: true,
            boundary_weight: 1000.0,
            unit: Unit::Edge,
        }
    }
}

/// Garland–Heckbert quadrics, one per vertex.
#[derive(Clone, Debug)]
pub struct QuadricModel {
    quadrics: Vec<Quadric>,
    /// Costs are divided by this (diagonal⁴ or diagonal²).
    cost_unit: f64,
    unit: Unit,
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
        QuadricModel {
            quadrics,
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
        Some(Plan {
            position,
            cost: q.eval(position) / self.cost_unit,
        })
    }

    fn merged(&mut self, _mesh: &LiveMesh, kept: Index, merged: &[Index]) {
        self.quadrics[kept as usize] = self.sum(merged);
    }

    fn renumber(&mut self, vertices: &[Index], _faces: &[Index]) -> bool {
        crate::keep_in_order(&mut self.quadrics, vertices);
        true
    }

    /// The whole's quadrics of the part's vertices, as the whole's collapses left them.
    fn for_part(&self, part: &LiveMesh) -> Option<Self> {
        Some(QuadricModel {
            quadrics: (0..part.vertex_slots() as Index)
                .map(|v| self.quadrics[part.input_index(v) as usize])
                .collect(),
            cost_unit: self.cost_unit,
            unit: self.unit,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::grid;

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
