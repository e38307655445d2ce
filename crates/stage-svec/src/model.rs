//! Paper 2's constriction error as a [`CostModel`] of the collapse engine.

use coarsen_collapse::{
    CostModel, Index, LiveMesh, Merge, Plan, Reach, Unit, VertexKind, edge_plane, keep_in_order,
};
use coarsen_geom::{DVec3, Quadric, triangle};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Relative determinant below which the summed quadric's minimiser is not trusted (§3.4's
/// area-weighted point takes over).
const SOLVE_TOLERANCE: f64 = 1e-10;

/// 1 − |nᵢ·nⱼ| of two unit normals is a multiple of 2⁻⁵³ (the subtraction from 1 is exact
/// on that grid), so the normal factor's sums are kept as integers in these units: terms
/// added and removed in any order give the same sum, and a sum of zeros stays zero.
const NORMAL_UNIT: f64 = (1u64 << 53) as f64;

/// A face with more neighbours than this has its normal factor summed afresh (in 128 bits)
/// whenever it changes: its wrapping 64-bit sum could have overflowed (a term is below
/// 2⁵⁴).
const MAX_INCREMENTAL: u32 = 500;

/// The term of unit normal `n` and (non-zero) normal `m` in a normal-factor sum, in units
/// of 2⁻⁵³: 1 − |n·m| (`abs`) or 1 − n·m; the same number for the same normals whenever
/// it is computed, so that a term removed is the term once added.
#[inline]
fn normal_term(n: DVec3, m: DVec3, abs: bool) -> i64 {
    let d = n.dot(m);
    ((1.0 - if abs { d.abs() } else { d }) * NORMAL_UNIT) as i64
}

/// Whose shape and normal factors weigh the cost (see the crate docs, *Readings*).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Factors {
    /// Wᵢ·Nᵢ inside every face's quadric Qᵢ (Eq. 4 as printed).
    Face,
    /// W_t·N_t of the collapsed triangle times the plain squared volume v̄ᵀ(Σ (1/9)Sᵢ²ppᵀ)v̄
    /// (the abstract's "shape factor and normal constraint factor of triangle").
    Triangle,
}

/// Faces or vertices whose data [`SvecModel::new`] computes in parallel at a time (bounds
/// the memory of the answers).
const SETUP_BLOCK: usize = 1 << 16;

/// The area of a face whose cross product is `len` long, in units of the squared
/// diagonal (`scale`: 1 / diagonal).
#[inline]
fn scaled_area(len: f64, scale: f64) -> f64 {
    0.5 * len * scale * scale
}

/// What [`SvecModel`] derives from the shape of one face.
struct Shape {
    angles: [f64; 3],
    /// Unit normal (zero when degenerate).
    normal: DVec3,
    /// Area, unit-diagonal units.
    area: f64,
    /// Wᵢ · (1/9)Sᵢ², unit-diagonal units.
    shape_plain: f64,
}

impl Shape {
    /// The shape of face `f` from the current positions (`scale`: 1 / diagonal).
    fn of(mesh: &LiveMesh, scale: f64, f: Index) -> Shape {
        let [a, b, c] = mesh.face(f).map(|v| mesh.position(v));
        let cross = triangle::cross(a, b, c);
        let len = cross.length();
        let angles = triangle::angles(a, b, c);
        let normal = if len > 0.0 && len.is_finite() {
            cross / len
        } else {
            DVec3::ZERO
        };
        let s = scaled_area(len, scale);
        let [x, y, z] = angles;
        let shape = 2.0 * (1.0 - x.min(y).min(z).cos()) * s;
        // Distances squared are in world units: scale them to a unit diagonal too.
        let plain = s * s / 9.0 * scale * scale;
        Shape {
            angles,
            normal,
            area: s,
            shape_plain: shape * plain,
        }
    }
}

/// What [`SvecModel`] derives for one face from the normals around it: Nᵢ's exact sum and
/// count, and Qᵢ's plane offset and weight.
struct FaceQuadric {
    normal_sum: i64,
    normal_count: u32,
    offset: f64,
    weight: f64,
}

/// How far from the merged vertices' centroid the minimiser may lie, in units of their
/// largest distance to it; farther, §3.4's area-weighted point takes over.
const MAX_REACH: f64 = 4.0;

/// Settings of [`SvecModel`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SvecOptions {
    /// Triangles whose Gauss-curvature factor K_t exceeds this are strong-feature
    /// triangles; `None` takes mean + `feature_sigma` · σ of K_t over the input.
    pub feature_threshold: Option<f64>,
    /// How many standard deviations above the mean the automatic threshold sits.
    pub feature_sigma: f64,
    /// Weight each face's quadric by φᵢ (see the crate docs) before placing and costing.
    pub volume_constraint: bool,
    /// Weight of a plane through each boundary edge, perpendicular to its face, added to
    /// the summed quadric (relative to the face's Wᵢ·(1/9)Sᵢ², as if its Nᵢ were 1);
    /// 0 leaves the paper's cost (see the crate docs).
    pub boundary_weight: f64,
    /// Whose factors weigh the cost: each face's, or the collapsed triangle's.
    pub factors: Factors,
    /// Nᵢ from 1 − |nᵢ·nⱼ| (the extracted text) or from 1 − nᵢ·nⱼ.
    pub normal_abs: bool,
    /// Queue a strong-feature triangle at the cost of its free placement and move it to
    /// its feature vertex only when it is collapsed (Step 5), instead of costing it there.
    pub feature_on_dequeue: bool,
    /// Re-cost every triangle within two edges of the new vertex after each collapse.
    pub two_rings: bool,
}

impl Default for SvecOptions {
    fn default() -> Self {
        SvecOptions {
            feature_threshold: None,
            feature_sigma: 2.0,
            volume_constraint: false,
            boundary_weight: 0.0,
            factors: Factors::Face,
            normal_abs: true,
            feature_on_dequeue: false,
            two_rings: false,
        }
    }
}

/// Per-face and per-vertex data of paper 2's constriction error, kept current as the
/// engine collapses.
#[derive(Clone, Debug)]
pub struct SvecModel {
    unit: Unit,
    /// Whether the face and vertex data below are there ([`SvecModel::deferred`]).
    built: bool,
    /// Plane, quadric weight and area of each face, side by side (a sum over faces reads
    /// one record per face).
    face: Vec<FaceData>,
    /// Per face, Σ (1 − |nᵢ·nⱼ|) over the faces j sharing a vertex with it, in exact
    /// integer units of 2⁻⁵³ (wrapping; see [`NORMAL_UNIT`]), and how many faces j there
    /// are: Nᵢ is kept up to date by adding and removing terms, exactly.
    normal_sum: Vec<i64>,
    normal_count: Vec<u32>,
    /// Wᵢ · (1/9)Sᵢ² (unit-diagonal units) of each face: Qᵢ's weight is this times Nᵢ.
    shape_plain: Vec<f64>,
    /// Interior angle of each face at each of its corners (computed once per change of
    /// shape, read by the angle deficits and the shape factors).
    angles: Vec<[f64; 3]>,
    /// Σ areas of the faces around each vertex (A_v), unit-diagonal units.
    vertex_area: Vec<f64>,
    /// |angle deficit| of each vertex (2π − Σα inside, π − Σα on the boundary).
    deficit: Vec<f64>,
    threshold: f64,
    /// The settings it was made with.
    opts: SvecOptions,
    /// 1 / diagonal.
    scale: f64,
    volume_constraint: bool,
    feature_collapses: usize,
    /// Work buffers of `merged`.
    touched: Vec<Index>,
    ring2: Vec<Index>,
    face_mark: Vec<u32>,
    vertex_mark: Vec<u32>,
    generation: u32,
}

/// What [`SvecModel`] keeps of one face. Planes and weights (not 10-number quadrics) are
/// kept, to save memory; Qᵢ is rebuilt when summed.
#[derive(Clone, Copy, Debug, Default)]
struct FaceData {
    /// Unit normal n (zero when degenerate).
    normal: DVec3,
    /// Offset d of the plane n·x + d = 0 (zero when degenerate).
    offset: f64,
    /// (1/9)·Wᵢ·Nᵢ·Sᵢ² scaled to a unit diagonal: Qᵢ is this weight times the plane's
    /// quadric. The plain squared volume (for φ) is the same plane with weight (1/9)·Sᵢ².
    weight: f64,
    /// Area, in units of the squared diagonal.
    area: f64,
}

/// |2π − Σα| (interior) or |π − Σα| (boundary) at `v`, and the area around it, from
/// `corner(f, c)`: the angle of face `f` at its corner `c`, and its area.
#[inline]
fn deficit_and_area(
    mesh: &LiveMesh,
    v: Index,
    corner: impl Fn(Index, usize) -> (f64, f64),
) -> (f64, f64) {
    let mut angle_sum = 0.0;
    let mut a = 0.0;
    for &f in mesh.faces_around(v) {
        let face = mesh.face(f);
        let c = face.iter().position(|&u| u == v).unwrap_or(0);
        let (angle, area) = corner(f, c);
        angle_sum += angle;
        a += area;
    }
    let full = if mesh.kind(v) == VertexKind::Boundary {
        PI
    } else {
        2.0 * PI
    };
    ((full - angle_sum).abs(), a)
}

/// Sets the angle deficit and area of every vertex of `mesh` with faces, from
/// `corner` (see [`deficit_and_area`]), on rayon's threads a block at a time.
fn fill_vertices(
    mesh: &LiveMesh,
    corner: impl Fn(Index, usize) -> (f64, f64) + Sync,
    deficit: &mut [f64],
    vertex_area: &mut [f64],
) {
    let verts: Vec<Index> = (0..mesh.vertex_slots() as Index)
        .filter(|&v| mesh.is_alive(v) && !mesh.faces_around(v).is_empty())
        .collect();
    for block in verts.chunks(SETUP_BLOCK) {
        let da: Vec<(f64, f64)> = block
            .par_iter()
            .map(|&v| deficit_and_area(mesh, v, &corner))
            .collect();
        for (&v, (d, a)) in block.iter().zip(da) {
            deficit[v as usize] = d;
            vertex_area[v as usize] = a;
        }
    }
}

/// Calls `visit` once for each face around any of `verts` (faces around several of them
/// once, at the first).
#[inline]
fn for_faces_around(mesh: &LiveMesh, verts: &[Index], mut visit: impl FnMut(Index)) {
    for (i, &v) in verts.iter().enumerate() {
        for &f in mesh.faces_around(v) {
            let face = mesh.face(f);
            if verts[..i].iter().any(|u| face.contains(u)) {
                continue;
            }
            visit(f);
        }
    }
}

impl SvecModel {
    /// The data of `mesh`'s faces and vertices, and the feature threshold of its triangles.
    pub fn new(mesh: &LiveMesh, opts: &SvecOptions) -> Self {
        let n_faces = mesh.live_faces().last().map_or(0, |f| f as usize + 1);
        let mut m = SvecModel::sized(mesh, opts, n_faces, mesh.vertex_slots());
        // Each face's and vertex's data from the mesh and the data before it, on rayon's
        // threads a block at a time (the same values as one by one).
        let faces: Vec<Index> = mesh.live_faces().collect();
        for block in faces.chunks(SETUP_BLOCK) {
            let shapes: Vec<Shape> = block
                .par_iter()
                .map(|&f| Shape::of(mesh, m.scale, f))
                .collect();
            for (&f, s) in block.iter().zip(shapes) {
                m.set_shape(f, s);
            }
        }
        let (angles, face) = (&m.angles, &m.face);
        let corner = |f: Index, c: usize| (angles[f as usize][c], face[f as usize].area);
        fill_vertices(mesh, corner, &mut m.deficit, &mut m.vertex_area);
        for block in faces.chunks(SETUP_BLOCK) {
            let qs: Vec<_> = block.par_iter().map(|&f| m.quadric_of(mesh, f)).collect();
            for (&f, q) in block.iter().zip(qs) {
                m.set_quadric(f, q);
            }
        }
        m.threshold = match opts.feature_threshold {
            Some(t) => t,
            None => m.auto_threshold(mesh),
        };
        m
    }

    /// `mesh`'s feature threshold with none of its face data, which
    /// [`CostModel::prepare`] builds: for a mesh the parallel phase cuts into parts (each
    /// part gets a model of its own, and the joined mesh one afresh), it spares building
    /// and holding the whole mesh's.
    pub fn deferred(mesh: &LiveMesh, opts: &SvecOptions) -> Self {
        let automatic = opts.feature_threshold.is_none();
        let n_vertices = if automatic { mesh.vertex_slots() } else { 0 };
        let mut m = SvecModel::sized(mesh, opts, 0, n_vertices);
        m.built = false;
        m.threshold = match opts.feature_threshold {
            Some(t) => t,
            None => {
                // The vertices' data from the positions, the same numbers as `new`'s.
                let scale = m.scale;
                let corner = |f: Index, c: usize| {
                    let t = mesh.face(f).map(|v| mesh.position(v));
                    let len = triangle::cross(t[0], t[1], t[2]).length();
                    (triangle::angle_at(t, c), scaled_area(len, scale))
                };
                fill_vertices(mesh, corner, &mut m.deficit, &mut m.vertex_area);
                m.auto_threshold(mesh)
            }
        };
        // Only the threshold is kept.
        m.deficit = Vec::new();
        m.vertex_area = Vec::new();
        m.vertex_mark = Vec::new();
        m
    }

    /// A model with room for `n_faces` faces and `n_vertices` vertices, all zero.
    fn sized(mesh: &LiveMesh, opts: &SvecOptions, n_faces: usize, n_vertices: usize) -> Self {
        let d = mesh.diagonal();
        let scale = if d > 0.0 && d.is_finite() {
            1.0 / d
        } else {
            1.0
        };
        SvecModel {
            unit: Unit::Triangle,
            built: true,
            face: vec![FaceData::default(); n_faces],
            normal_sum: vec![0; n_faces],
            normal_count: vec![0; n_faces],
            shape_plain: vec![0.0; n_faces],
            angles: vec![[0.0; 3]; n_faces],
            vertex_area: vec![0.0; n_vertices],
            deficit: vec![0.0; n_vertices],
            threshold: f64::INFINITY,
            opts: *opts,
            scale,
            volume_constraint: opts.volume_constraint,
            feature_collapses: 0,
            touched: Vec::new(),
            ring2: Vec::new(),
            face_mark: vec![0; n_faces],
            vertex_mark: vec![0; n_vertices],
            generation: 0,
        }
    }

    /// Mean + `feature_sigma` · σ of K_t over `mesh`'s triangles, from the vertices' data.
    fn auto_threshold(&self, mesh: &LiveMesh) -> f64 {
        let ks: Vec<f64> = mesh
            .live_faces()
            .map(|f| self.triangle_curvature(&mesh.face(f)))
            .filter(|k| k.is_finite())
            .collect();
        mean_plus_sigma(&ks, self.opts.feature_sigma)
    }

    /// The data of `mesh` with this model's settings, unit and feature threshold.
    fn with_threshold(&self, mesh: &LiveMesh) -> Self {
        let mut m = SvecModel::new(
            mesh,
            &SvecOptions {
                feature_threshold: Some(self.threshold),
                ..self.opts
            },
        );
        m.unit = self.unit;
        m.feature_collapses = self.feature_collapses;
        m
    }

    /// Collapse triangles (the method) or edges (to finish on an exact count).
    pub fn set_unit(&mut self, unit: Unit) {
        self.unit = unit;
    }

    /// The Gauss-curvature threshold above which a triangle is a strong feature.
    pub fn feature_threshold(&self) -> f64 {
        self.threshold
    }

    /// Collapses so far whose new vertex was placed on a strong-feature vertex.
    pub fn feature_collapses(&self) -> usize {
        self.feature_collapses
    }

    /// Paper 2's K_t of the merged vertices: Σ |angle deficit| / Σ A_v.
    pub fn triangle_curvature(&self, verts: &[Index]) -> f64 {
        let (d, a) = verts.iter().fold((0.0, 0.0), |(d, a), &v| {
            (
                d + self.deficit[v as usize],
                a + self.vertex_area[v as usize],
            )
        });
        if a > 0.0 { d / a } else { 0.0 }
    }

    /// |K_v| = |angle deficit| / A_v of vertex `v`.
    pub fn vertex_curvature(&self, v: Index) -> f64 {
        let a = self.vertex_area[v as usize];
        if a > 0.0 {
            self.deficit[v as usize] / a
        } else {
            0.0
        }
    }

    /// The quadric Qᵢ of face `f` (unit-diagonal units).
    #[inline]
    pub fn face_quadric(&self, f: Index) -> Quadric {
        let fi = f as usize;
        Quadric::from_plane_offset(
            self.face[fi].normal,
            self.face[fi].offset,
            self.face[fi].weight,
        )
    }

    /// The plain squared volume (1/9)·Sᵢ²·p pᵀ of face `f` (unit-diagonal units), for φ.
    fn volume_quadric(&self, f: Index) -> Quadric {
        let fi = f as usize;
        let s = self.face[fi].area;
        let plain = s * s / 9.0 * self.scale * self.scale;
        Quadric::from_plane_offset(self.face[fi].normal, self.face[fi].offset, plain)
    }

    /// Normal, area and corner angles of face `f` from the current positions.
    fn update_shape(&mut self, mesh: &LiveMesh, f: Index) {
        self.set_shape(f, Shape::of(mesh, self.scale, f));
    }

    fn set_shape(&mut self, f: Index, s: Shape) {
        let fi = f as usize;
        self.angles[fi] = s.angles;
        self.face[fi].normal = s.normal;
        self.face[fi].area = s.area;
        self.shape_plain[fi] = s.shape_plain;
    }

    /// A_v and the angle deficit of vertex `v`.
    fn update_vertex(&mut self, mesh: &LiveMesh, v: Index) {
        let da = deficit_and_area(mesh, v, |f, c| {
            (self.angles[f as usize][c], self.face[f as usize].area)
        });
        self.set_vertex(v, da);
    }

    fn set_vertex(&mut self, v: Index, (deficit, area): (f64, f64)) {
        self.deficit[v as usize] = deficit;
        self.vertex_area[v as usize] = area;
    }

    /// Nᵢ summed afresh from the normals around face `f`, then Qᵢ.
    fn update_quadric(&mut self, mesh: &LiveMesh, f: Index) {
        self.set_quadric(f, self.quadric_of(mesh, f));
    }

    /// What [`SvecModel::update_quadric`] sets for face `f`; `None` for a degenerate face
    /// (offset and weight 0, sum and count left as they are).
    fn quadric_of(&self, mesh: &LiveMesh, f: Index) -> Option<FaceQuadric> {
        let fi = f as usize;
        let n = self.face[fi].normal;
        if n == DVec3::ZERO {
            return None;
        }
        let face = mesh.face(f);
        let (sum, count) = self.normal_sum_of(mesh, f);
        Some(FaceQuadric {
            normal_sum: sum as i64,
            normal_count: count,
            offset: -n.dot(mesh.position(face[0])),
            weight: self.quadric_weight(fi, sum, count),
        })
    }

    /// Nᵢ's sum (units of 2⁻⁵³) and count of face `f`, summed afresh over the faces
    /// sharing a vertex with it.
    fn normal_sum_of(&self, mesh: &LiveMesh, f: Index) -> (i128, u32) {
        let n = self.face[f as usize].normal;
        let (mut sum, mut count) = (0i128, 0u32);
        for_faces_around(mesh, &mesh.face(f), |g| {
            let m = self.face[g as usize].normal;
            if g != f && m != DVec3::ZERO {
                sum += normal_term(n, m, self.opts.normal_abs) as i128;
                count += 1;
            }
        });
        (sum, count)
    }

    fn set_quadric(&mut self, f: Index, q: Option<FaceQuadric>) {
        let fi = f as usize;
        match q {
            None => {
                self.face[fi].offset = 0.0;
                self.face[fi].weight = 0.0;
            }
            Some(q) => {
                self.normal_sum[fi] = q.normal_sum;
                self.normal_count[fi] = q.normal_count;
                self.face[fi].offset = q.offset;
                self.face[fi].weight = q.weight;
            }
        }
    }

    /// Qᵢ's weight of face `fi` whose normal-factor sum is `sum` over `count` faces:
    /// (1/9)·Wᵢ·Nᵢ·Sᵢ² (face factors) or the plain (1/9)·Sᵢ² (the triangle's factors
    /// weigh the cost instead), unit-diagonal units.
    fn quadric_weight(&self, fi: usize, sum: i128, count: u32) -> f64 {
        match self.opts.factors {
            Factors::Face => self.shape_plain[fi] * normal_factor(sum, count),
            Factors::Triangle => {
                let s = self.face[fi].area;
                s * s / 9.0 * self.scale * self.scale
            }
        }
    }

    /// W_t·N_t of the merge's triangle (for an edge, the mean over the faces holding it)
    /// under [`Factors::Triangle`]; 1 under [`Factors::Face`].
    fn cost_factor(&self, mesh: &LiveMesh, verts: &[Index]) -> f64 {
        if self.opts.factors == Factors::Face {
            return 1.0;
        }
        let (mut sum, mut n) = (0.0, 0usize);
        for &f in mesh.faces_around(verts[0]) {
            let face = mesh.face(f);
            if verts[1..].iter().all(|v| face.contains(v)) {
                sum += self.triangle_factor(mesh, f);
                n += 1;
            }
        }
        if n > 0 { sum / n as f64 } else { 0.0 }
    }

    /// W_t·N_t of face `f`: 2(1 − cos α_min)·S_t (unit-diagonal units) times its Nᵢ.
    fn triangle_factor(&self, mesh: &LiveMesh, f: Index) -> f64 {
        let fi = f as usize;
        if self.face[fi].normal == DVec3::ZERO {
            return 0.0;
        }
        let [x, y, z] = self.angles[fi];
        let w = 2.0 * (1.0 - x.min(y).min(z).cos()) * self.face[fi].area;
        let count = self.normal_count[fi];
        let n = if count > MAX_INCREMENTAL {
            let (sum, count) = self.normal_sum_of(mesh, f);
            normal_factor(sum, count)
        } else {
            normal_factor(self.normal_sum[fi] as i128, count)
        };
        w * n
    }

    /// Qᵢ's weight of face `f` from its kept sum (a face with too many neighbours for the
    /// 64-bit sum is summed afresh).
    fn update_weight(&mut self, mesh: &LiveMesh, f: Index) {
        let fi = f as usize;
        if self.face[fi].normal == DVec3::ZERO {
            return;
        }
        let count = self.normal_count[fi];
        if count > MAX_INCREMENTAL {
            self.update_quadric(mesh, f);
        } else {
            self.face[fi].weight = self.quadric_weight(fi, self.normal_sum[fi] as i128, count);
        }
    }

    /// Replaces the term of normal `old` by that of `new` (a zero normal has no term) in
    /// the sum of every face around `w` that uses neither `kept` nor `skip`, and marks them
    /// for a new weight.
    #[allow(clippy::too_many_arguments)]
    fn adjust_around(
        &mut self,
        mesh: &LiveMesh,
        w: Index,
        kept: Index,
        skip: Index,
        old: DVec3,
        new: DVec3,
        generation: u32,
    ) {
        let (had, has) = (old != DVec3::ZERO, new != DVec3::ZERO);
        let count_change = has as i32 - had as i32;
        for &i in mesh.faces_around(w) {
            let face = mesh.face(i);
            if face.contains(&kept) || face.contains(&skip) {
                continue;
            }
            let ii = i as usize;
            let n = self.face[ii].normal;
            if n == DVec3::ZERO {
                // Its weight is zero whatever its sum; it is summed afresh once reshaped.
                continue;
            }
            let mut delta = 0i64;
            let abs = self.opts.normal_abs;
            if has {
                delta = delta.wrapping_add(normal_term(n, new, abs));
            }
            if had {
                delta = delta.wrapping_sub(normal_term(n, old, abs));
            }
            self.normal_sum[ii] = self.normal_sum[ii].wrapping_add(delta);
            self.normal_count[ii] = self.normal_count[ii].wrapping_add_signed(count_change);
            if Self::mark(&mut self.face_mark, generation, i) {
                self.ring2.push(i);
            }
        }
    }

    /// Σ Qᵢ (each weighted by `phi` when given) over the faces around `verts`, with the
    /// boundary planes of those faces when [`SvecOptions::boundary_weight`] is set.
    fn summed(&self, mesh: &LiveMesh, verts: &[Index], phi: Option<(DVec3, f64)>) -> Quadric {
        let mut q = Quadric::ZERO;
        match phi {
            Some((p, mean)) => for_faces_around(mesh, verts, |f| {
                let w = self.volume_quadric(f).eval(p).max(0.0) / mean;
                q += self.face_quadric(f) * w;
            }),
            None => for_faces_around(mesh, verts, |f| q += self.face_quadric(f)),
        }
        if self.opts.boundary_weight > 0.0
            && verts.iter().any(|&v| mesh.kind(v) != VertexKind::Interior)
        {
            for_faces_around(mesh, verts, |f| q += self.boundary_planes(mesh, f, verts));
        }
        q
    }

    /// The planes through face `f`'s boundary edges at `verts`, perpendicular to it, each
    /// weighted by [`SvecOptions::boundary_weight`] times the face's Wᵢ·(1/9)Sᵢ².
    fn boundary_planes(&self, mesh: &LiveMesh, f: Index, verts: &[Index]) -> Quadric {
        let mut q = Quadric::ZERO;
        let n = self.face[f as usize].normal;
        if n == DVec3::ZERO {
            return q;
        }
        let face = mesh.face(f);
        for i in 0..3 {
            let (u, v) = (face[i], face[(i + 1) % 3]);
            if !(verts.contains(&u) || verts.contains(&v)) || !mesh.is_boundary_edge(u, v) {
                continue;
            }
            let w = self.opts.boundary_weight * self.shape_plain[f as usize];
            if let Some(plane) = edge_plane(mesh.position(u), mesh.position(v), n, w) {
                q += plane;
            }
        }
        q
    }

    /// Mean of the plain squared volumes (1/9)Sᵢ²(p·v̄)² around `verts` at `p`.
    fn mean_volume(&self, mesh: &LiveMesh, verts: &[Index], p: DVec3) -> f64 {
        let (mut sum, mut count) = (0.0, 0usize);
        for_faces_around(mesh, verts, |f| {
            sum += self.volume_quadric(f).eval(p).max(0.0);
            count += 1;
        });
        if count > 0 { sum / count as f64 } else { 0.0 }
    }

    /// §3.4 (Step 3's "Eq. 8"): the A_v-weighted mean of the merged vertices (their plain mean when every
    /// A_v is zero).
    fn area_weighted_mean(&self, mesh: &LiveMesh, verts: &[Index]) -> DVec3 {
        let total: f64 = verts.iter().map(|&v| self.vertex_area[v as usize]).sum();
        if total > 0.0 {
            verts
                .iter()
                .map(|&v| mesh.position(v) * (self.vertex_area[v as usize] / total))
                .sum()
        } else {
            verts.iter().map(|&v| mesh.position(v)).sum::<DVec3>() / verts.len() as f64
        }
    }

    /// Where the merged vertex goes, given the summed quadric `q` (the rules of the crate
    /// docs, the feature rule only when `feature`), and whether the feature rule placed it.
    fn place(
        &self,
        mesh: &LiveMesh,
        merge: &Merge<'_>,
        q: &Quadric,
        feature: bool,
    ) -> (DVec3, bool) {
        let verts = merge.vertices;
        if let Some(v) = merge.pinned {
            return (mesh.position(v), false);
        }
        let mut boundary = verts
            .iter()
            .copied()
            .filter(|&v| mesh.kind(v) == VertexKind::Boundary);
        if let (Some(i), Some(j)) = (boundary.next(), boundary.next()) {
            return (self.on_segment(mesh, q, i, j), false);
        }
        if feature && self.triangle_curvature(verts) > self.threshold {
            // The strong-feature vertex: the largest |K_v|, the first of equals.
            let mut best = verts[0];
            for &v in &verts[1..] {
                if self.vertex_curvature(v) > self.vertex_curvature(best) {
                    best = v;
                }
            }
            return (mesh.position(best), true);
        }
        let n = verts.len() as f64;
        let centroid = verts.iter().map(|&v| mesh.position(v)).sum::<DVec3>() / n;
        let radius = verts
            .iter()
            .map(|&v| (mesh.position(v) - centroid).length())
            .fold(0.0, f64::max);
        match q.minimizer(SOLVE_TOLERANCE) {
            Some(x) if (x - centroid).length() <= MAX_REACH * radius => (x, false),
            _ => (self.area_weighted_mean(mesh, verts), false),
        }
    }

    /// §3.5: v̄ = ω vᵢ + (1 − ω) vⱼ with ω ∈ [0, 1] minimising `q` along the segment; the
    /// A_v-weighted point when `q` is flat along it.
    fn on_segment(&self, mesh: &LiveMesh, q: &Quadric, i: Index, j: Index) -> DVec3 {
        let (pi, pj) = (mesh.position(i), mesh.position(j));
        let d = pi - pj;
        let a = q.matrix();
        // q(pj + ω d) = ω² dᵀAd + 2ω dᵀ(A pj + b) + q(pj).
        let curvature = d.dot(a * d);
        let slope = d.dot(a * pj + q.b);
        let omega = if curvature > 0.0 && curvature.is_finite() {
            (-slope / curvature).clamp(0.0, 1.0)
        } else {
            let (ai, aj) = (self.vertex_area[i as usize], self.vertex_area[j as usize]);
            if ai + aj > 0.0 { ai / (ai + aj) } else { 0.5 }
        };
        pj + d * omega
    }

    /// Marks `i` in `marks` for the current generation; true when it was not yet marked.
    fn mark(marks: &mut [u32], generation: u32, i: Index) -> bool {
        let m = &mut marks[i as usize];
        let fresh = *m != generation;
        *m = generation;
        fresh
    }
}

/// Nᵢ = mean of (1 − |nᵢ·nⱼ|)/2 from a sum in units of 2⁻⁵³ over `count` faces.
#[inline]
fn normal_factor(sum: i128, count: u32) -> f64 {
    if count > 0 {
        0.5 * (sum as f64 / NORMAL_UNIT) / count as f64
    } else {
        0.0
    }
}

/// mean + `sigma` · standard deviation of `values` (∞ when empty).
fn mean_plus_sigma(values: &[f64], sigma: f64) -> f64 {
    if values.is_empty() {
        return f64::INFINITY;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|k| (k - mean) * (k - mean)).sum::<f64>() / n;
    mean + sigma * var.sqrt()
}

impl CostModel for SvecModel {
    fn unit(&self) -> Unit {
        self.unit
    }

    fn reach(&self) -> Reach {
        // The triangles around the new vertex; those farther out are re-costed when
        // they come off the queue (see the crate docs), or all within two edges.
        if self.opts.two_rings {
            Reach::TwoRings
        } else {
            Reach::Kept
        }
    }

    fn plan(&self, mesh: &LiveMesh, merge: &Merge<'_>) -> Option<Plan> {
        let verts = merge.vertices;
        let mut q = self.summed(mesh, verts, None);
        let (mut position, feature) = self.place(mesh, merge, &q, true);
        // Under the dequeue reading a strong-feature triangle is costed at its free
        // placement (the rules other than the feature rule) and moved to its feature
        // vertex when collapsed.
        let dequeue = feature && self.opts.feature_on_dequeue;
        let mut free = if dequeue {
            self.place(mesh, merge, &q, false).0
        } else {
            position
        };
        if self.volume_constraint {
            // φᵢ: each face's plain squared volume at the unconstrained v̄, over their mean.
            let mean = self.mean_volume(mesh, verts, free);
            if mean > 0.0 && mean.is_finite() {
                q = self.summed(mesh, verts, Some((free, mean)));
                if !feature || dequeue {
                    free = self.place(mesh, merge, &q, false).0;
                }
                if !feature {
                    position = free;
                }
            }
        }
        let at = if dequeue { free } else { position };
        Some(Plan {
            position,
            cost: self.cost_factor(mesh, verts) * q.eval(at),
        })
    }

    fn prepare(&mut self, mesh: &LiveMesh) {
        if !self.built {
            *self = self.with_threshold(mesh);
        }
    }

    fn merged(&mut self, mesh: &LiveMesh, kept: Index, merged: &[Index]) {
        debug_assert!(self.built, "collapses on a deferred model");
        // The caches still describe the mesh before the collapse: the plan that was
        // carried out used the feature rule exactly when this says so.
        let interior = merged.iter().all(|&v| mesh.kind(v) == VertexKind::Interior);
        if interior && self.triangle_curvature(merged) > self.threshold {
            self.feature_collapses += 1;
        }
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.face_mark.iter_mut().for_each(|m| *m = 0);
            self.vertex_mark.iter_mut().for_each(|m| *m = 0);
            self.generation = 1;
        }
        let generation = self.generation;
        // The faces around `kept` changed shape; `kept` and its neighbours changed angle
        // sums and areas. Every face sharing a vertex with a changed or deleted face has a
        // new Nᵢ: those around `kept` are summed afresh, the others (which share with them
        // only vertices other than `kept`) get the changed terms replaced and the deleted
        // ones removed from their kept sums.
        let mut touched = std::mem::take(&mut self.touched);
        touched.clear();
        self.ring2.clear();
        touched.push(kept);
        Self::mark(&mut self.vertex_mark, generation, kept);
        // Faces around `kept` are marked first: they are summed afresh below.
        for &f in mesh.faces_around(kept) {
            Self::mark(&mut self.face_mark, generation, f);
        }
        for &f in mesh.faces_around(kept) {
            let old = self.face[f as usize].normal;
            self.update_shape(mesh, f);
            let new = self.face[f as usize].normal;
            let face = mesh.face(f);
            let c = face.iter().position(|&u| u == kept).unwrap_or(0);
            let (w1, w2) = (face[(c + 1) % 3], face[(c + 2) % 3]);
            if old != new {
                for (w, skip) in [(w1, kept), (w2, w1)] {
                    self.adjust_around(mesh, w, kept, skip, old, new, generation);
                }
            }
            for v in face {
                if Self::mark(&mut self.vertex_mark, generation, v) {
                    touched.push(v);
                }
            }
        }
        for &d in mesh.last_deleted() {
            let old = self.face[d as usize].normal;
            for w in mesh.face(d) {
                if !merged.contains(&w) {
                    self.adjust_around(mesh, w, kept, kept, old, DVec3::ZERO, generation);
                }
            }
        }
        for &v in &touched {
            self.update_vertex(mesh, v);
        }
        for &f in mesh.faces_around(kept) {
            self.update_quadric(mesh, f);
        }
        let ring2 = std::mem::take(&mut self.ring2);
        for &f in &ring2 {
            self.update_weight(mesh, f);
        }
        self.ring2 = ring2;
        self.touched = touched;
    }

    fn for_part(&self, part: &LiveMesh) -> Option<Self> {
        let mut m = self.with_threshold(part);
        m.feature_collapses = 0;
        Some(m)
    }

    /// Its data are derived from the mesh alone: rebuilt once the parts are joined.
    fn joined(&mut self, _mesh: &LiveMesh, _kept: Index, _merged: &[Index]) {}

    fn after_join(&mut self, mesh: &LiveMesh) {
        let feature_collapses = self.feature_collapses;
        *self = self.with_threshold(mesh);
        self.feature_collapses = feature_collapses;
    }

    fn tally(&self) -> usize {
        self.feature_collapses
    }

    fn add_tally(&mut self, n: usize) {
        self.feature_collapses += n;
    }

    fn renumber(&mut self, vertices: &[Index], faces: &[Index]) -> bool {
        if !self.built {
            // Nothing to rename yet.
            return true;
        }
        keep_in_order(&mut self.face, faces);
        keep_in_order(&mut self.normal_sum, faces);
        keep_in_order(&mut self.normal_count, faces);
        keep_in_order(&mut self.shape_plain, faces);
        keep_in_order(&mut self.angles, faces);
        keep_in_order(&mut self.face_mark, faces);
        keep_in_order(&mut self.vertex_area, vertices);
        keep_in_order(&mut self.deficit, vertices);
        keep_in_order(&mut self.vertex_mark, vertices);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::Mesh;

    #[test]
    fn a_plane_kept_as_normal_and_offset_gives_from_planes_numbers() {
        let n = DVec3::new(0.3, -0.4, 0.5).normalize();
        let point = DVec3::new(1.7, -2.3, 0.9);
        let w = 0.37;
        let q = Quadric::from_plane_offset(n, -n.dot(point), w);
        assert_eq!(q, Quadric::from_plane(n, point, w));
        assert_ne!(q, Quadric::from_plane_offset(n, -n.dot(point), 2.0 * w));
    }

    /// The model under test, checked against fresh sums after every collapse.
    struct Checked(SvecModel, usize);

    impl CostModel for Checked {
        fn unit(&self) -> Unit {
            self.0.unit()
        }
        fn reach(&self) -> Reach {
            self.0.reach()
        }
        fn plan(&self, mesh: &LiveMesh, merge: &Merge<'_>) -> Option<Plan> {
            self.0.plan(mesh, merge)
        }
        fn merged(&mut self, mesh: &LiveMesh, kept: Index, merged: &[Index]) {
            self.0.merged(mesh, kept, merged);
            let mut fresh = self.0.clone();
            for f in mesh.live_faces() {
                let fi = f as usize;
                if self.0.face[fi].normal == DVec3::ZERO {
                    continue;
                }
                fresh.update_quadric(mesh, f);
                assert_eq!(
                    (self.0.normal_sum[fi], self.0.normal_count[fi]),
                    (fresh.normal_sum[fi], fresh.normal_count[fi]),
                    "face {f} after collapse {} into {kept}",
                    self.1
                );
                assert_eq!(
                    self.0.face[fi].weight, fresh.face[fi].weight,
                    "face {f} after collapse {} into {kept}",
                    self.1
                );
            }
            self.1 += 1;
        }
        fn renumber(&mut self, vertices: &[Index], faces: &[Index]) -> bool {
            self.0.renumber(vertices, faces)
        }
    }

    #[test]
    fn kept_normal_factors_equal_fresh_sums_after_every_collapse() {
        use coarsen_collapse::{Goal, Options};
        let mesh = coarsen_shapes::bumpy_sphere(1.0, 3, 0.15, 3.0).unwrap();
        for unit in [Unit::Triangle, Unit::Edge] {
            // Also with the engine closing up its arrays whenever half the faces are gone
            // (the model renamed with them): the same collapses and output.
            let run = |compact_min_faces| {
                let mut live = LiveMesh::new(&mesh).unwrap();
                let mut model = SvecModel::new(&live, &SvecOptions::default());
                model.set_unit(unit);
                let mut checked = Checked(model, 0);
                let opts = Options {
                    compact_min_faces,
                    ..Options::new(Goal::Faces(200))
                };
                let out = live.collapse(&mut checked, &opts, &mut |_| {});
                assert!(out.collapses > 200, "{out:?}");
                (out, live.to_mesh(&mesh).unwrap().0, live.vertex_slots())
            };
            let (out, mesh_out, slots) = run(usize::MAX);
            let (c_out, c_mesh_out, c_slots) = run(0);
            assert!(c_slots < slots / 2, "{c_slots} of {slots} slots");
            assert_eq!((c_out, c_mesh_out), (out, mesh_out));
        }
    }

    #[test]
    fn omega_minimises_the_quadric_along_the_boundary_segment() {
        // Two triangles; 0 and 1 are the ends of the segment.
        let mesh = Mesh::new(
            vec![
                DVec3::ZERO,
                DVec3::new(4.0, 0.0, 0.0),
                DVec3::new(2.0, 2.0, 0.0),
                DVec3::new(2.0, -2.0, 0.0),
            ],
            vec![[0, 1, 2], [1, 0, 3]],
        );
        let live = LiveMesh::new(&mesh).unwrap();
        let model = SvecModel::new(&live, &SvecOptions::default());
        // The plane x = 1 crosses the segment at ω = 3/4 (from vertex 1's side: 1 − ¼).
        let q = Quadric::from_plane(DVec3::X, DVec3::new(1.0, 0.0, 0.0), 1.0);
        let p = model.on_segment(&live, &q, 0, 1);
        assert!((p - DVec3::new(1.0, 0.0, 0.0)).length() < 1e-12, "{p}");
        // Beyond the segment: clamped to the nearer end.
        let q = Quadric::from_plane(DVec3::X, DVec3::new(9.0, 0.0, 0.0), 1.0);
        assert_eq!(model.on_segment(&live, &q, 0, 1), DVec3::new(4.0, 0.0, 0.0));
        // Flat along the segment: the A_v-weighted point (equal areas: the middle).
        let p = model.on_segment(&live, &Quadric::ZERO, 0, 1);
        assert!((p - DVec3::new(2.0, 0.0, 0.0)).length() < 1e-12, "{p}");
    }

    #[test]
    fn boundary_planes_keep_a_corner_of_the_boundary() {
        // A flat 2 × 2 grid; vertex 0 is a corner, 0–1 a boundary edge, 4 the middle.
        let positions = (0..9)
            .map(|k| DVec3::new((k % 3) as f64, (k / 3) as f64, 0.0))
            .collect();
        let mut faces = Vec::new();
        for j in 0..2 {
            for i in 0..2 {
                let at = |i: u32, j: u32| j * 3 + i;
                faces.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                faces.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        let live = LiveMesh::new(&Mesh::new(positions, faces)).unwrap();
        let merge = Merge {
            vertices: &[0, 1, 4],
            pinned: None,
        };
        let plan = |w: f64| {
            let opts = SvecOptions {
                boundary_weight: w,
                ..SvecOptions::default()
            };
            SvecModel::new(&live, &opts).plan(&live, &merge).unwrap()
        };
        // The paper's cost is 0 on a flat mesh: the A_v-weighted point, off the corner.
        let plain = plan(0.0);
        assert_eq!(plain.cost, 0.0);
        assert!(
            plain.position.x > 0.1 && plain.position.y == 0.0,
            "{}",
            plain.position
        );
        // The plane through the boundary edge 3–0 (x = 0) prices the cut corner.
        let kept = plan(1.0);
        assert_eq!(kept.position, DVec3::ZERO);
        assert_eq!(kept.cost, 0.0);
        // Cutting the corner would have cost something.
        let opts = SvecOptions {
            boundary_weight: 1.0,
            ..SvecOptions::default()
        };
        let model = SvecModel::new(&live, &opts);
        let q = model.summed(&live, &[0, 1, 4], None);
        assert!(q.eval(plain.position) > 0.0);
    }
}
