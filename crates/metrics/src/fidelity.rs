//! Fidelity of one surface to another: sampled two-sided distances (metrics spec,
//! "Fidelity to the input").
//!
//! # Sampling rule
//!
//! Each direction is sampled on its own mesh: the input's samples are measured against
//! the output (the forward direction), the output's against the input (the backward
//! direction). A mesh of `F` faces carries
//!
//! - every vertex used by a face;
//! - points along every edge: an edge of length `L` gets `max(1, ⌈L/h⌉ − 1)` points
//!   evenly spaced between its ends, `h = √(A/S)` being the spacing of the face samples
//!   (`A` the mesh's area, `S` below), so that edges are sampled as densely as faces;
//!   then a golden-section search of [`REFINE_STEPS`] points between the neighbours of
//!   each edge's farthest point looks for the edge's largest distance, which is often a
//!   kink (the edge crossing a crease of the other surface) that even spacing misses by up
//!   to half a spacing's rise. Those points count for the maximum only: the mean and RMS
//!   are of the evenly spread samples;
//! - `S = max(`[`FidelityOptions::min_face_samples`]`, `[`FidelityOptions::samples_per_face`]`·F)`
//!   points on its faces (defaults 1,000,000 and 100).
//!
//! [`Fidelity::forward_samples`] and [`Fidelity::backward_samples`] count them (the
//! searches' points apart). A coarse output needs this many: with about 10 points per face
//! in all, the output → input maximum of a 5000-vertex bunny read 0.33 % where this finds
//! 0.41 %; without the edge searches it read 1.3 % lower than with ten times the samples.
//!
//! Face samples are spread over one mesh's faces in proportion to area: with `Cᵢ` the
//! area of faces `0..i`, face `i` gets `⌊S·Cᵢ₊₁/A⌋ − ⌊S·Cᵢ/A⌋` of the `S` samples (so
//! exactly `S` in all; zero-area faces get none). Within a face, sample `j` sits at
//! barycentric `(u, v)` of the additive recurrence `u = frac(1/3 + j/g)`,
//! `v = frac(1/3 + j/g²)` (`g` the plastic number), folded into the triangle: a
//! low-discrepancy sequence whose first point is the centroid and whose first `k` points
//! leave no part of the face of area above a small multiple of `1/k` unsampled. Each vertex
//! and each edge is sampled with the first face (in face order) that uses it. The samples
//! are thus a pure function of the mesh: no random state, the same every run.
//!
//! # Distances
//!
//! Each sample's distance is to the nearest point of the other surface (point to
//! triangle, through a [`Bvh`]). The samples of one face lie within one small ball, so
//! they are answered together: the other surface's triangles that can be nearest to some
//! point of the ball are gathered once ([`Bvh::gather_near`]) and each sample looks at
//! those alone; the ball is [`NEAR_GROW`] times the face's own, so that it serves the
//! following faces too while it covers them. The distances are exactly those of one
//! query per sample. Distances that are rounding noise — at most [`ROUNDING_FLOOR`] times
//! the larger of the input's diagonal and its largest coordinate magnitude — count as
//! exactly 0, so a mesh measured against itself scores 0.
//!
//! The faces are split into fixed chunks, measured in parallel and summed in chunk order:
//! the figures are bit-for-bit the same on any number of threads.

use crate::error::{MetricsError, Role};
use crate::prepare::{Prepared, map_chunks};
use crate::validity::{encloses_volume, topology};
use coarsen_mesh::{DVec3, Mesh};
use coarsen_spatial::{Bvh, NearSet};
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// Distances up to this fraction of the input's scale (see the module docs) count as 0.
pub const ROUNDING_FLOOR: f64 = 1e-12;

/// Most triangles gathered for the samples of one face (see [`Bvh::gather_near`]);
/// beyond that each sample walks the tree on its own.
pub const NEAR_LIMIT: usize = 32;

/// The ball of a gathering is this many times the face's own (centred on its centroid,
/// through its farthest corner), so that one gathering serves the next faces too while
/// they lie inside it. Measured on a 4M-face input: 1.5 saves a sixth of the time
/// against 1; larger balls cost more on 70K-face inputs than they save.
pub const NEAR_GROW: f64 = 1.5;

/// Faces per parallel chunk.
const CHUNK: usize = 1024;

/// The plastic number `g`, root of `g³ = g + 1`; `1/g` and `1/g²` drive the in-face
/// sample sequence.
const PLASTIC: f64 = 1.324_717_957_244_746;

/// How fidelity is sampled (see the module docs for the rule).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FidelityOptions {
    /// Face samples per face of each mesh. Default 100.
    pub samples_per_face: u32,
    /// At least this many face samples on each mesh. Default 1,000,000.
    pub min_face_samples: u64,
}

/// The default of [`FidelityOptions::samples_per_face`].
pub const SAMPLES_PER_FACE: u32 = 100;

/// The default of [`FidelityOptions::min_face_samples`].
pub const MIN_FACE_SAMPLES: u64 = 1_000_000;

impl Default for FidelityOptions {
    fn default() -> Self {
        FidelityOptions {
            samples_per_face: SAMPLES_PER_FACE,
            min_face_samples: MIN_FACE_SAMPLES,
        }
    }
}

impl FidelityOptions {
    /// The face samples of a mesh of `faces` faces: `max(min_face_samples,
    /// samples_per_face · faces)`.
    pub fn face_samples(&self, faces: usize) -> u64 {
        (u64::from(self.samples_per_face) * faces as u64).max(self.min_face_samples)
    }
}

/// How far the output surface is from the input surface, as percents of the input's
/// bounding-box diagonal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fidelity {
    /// Symmetric Hausdorff distance: the larger of `forward_max_pct` and `backward_max_pct`.
    pub hausdorff_pct: f64,
    /// Mean of all sampled distances, both directions pooled.
    pub mean_dist_pct: f64,
    /// Root mean square of all sampled distances, both directions pooled.
    pub rms_dist_pct: f64,
    /// Largest distance from a sample of the input to the output surface.
    pub forward_max_pct: f64,
    /// Largest distance from a sample of the output to the input surface.
    pub backward_max_pct: f64,
    /// Number of samples, both directions (see the module docs for the rule).
    pub n_samples: u64,
    /// Samples of the input (vertices, edge points, face points), measured against the
    /// output.
    pub forward_samples: u64,
    /// Samples of the output, measured against the input.
    pub backward_samples: u64,
    /// The input's bounding-box diagonal (of the vertices used by faces), in model units.
    pub bbox_diagonal: f64,
    /// `|V_out − V_in| / |V_in| · 100` with signed volumes, when both meshes are closed and
    /// consistently oriented and the input encloses a non-zero volume; else `None`.
    pub volume_change_pct: Option<f64>,
}

/// Measures how far `output` lies from `input` (see the module docs for the sampling).
///
/// Errors when either mesh has a bad index or a bad used vertex (not finite, or beyond
/// ±[`MAX_COORDINATE`](crate::MAX_COORDINATE)), when either has no faces, or when the
/// input's diagonal is zero.
pub fn fidelity(
    input: &Mesh,
    output: &Mesh,
    opts: &FidelityOptions,
) -> Result<Fidelity, MetricsError> {
    let (input, output) = rayon::join(
        || Prepared::new(input, Role::Input),
        || Prepared::new(output, Role::Output),
    );
    let (input, output) = (input?, output?);
    let floor = rounding_floor(&input, &output)?;
    let closed = |p: &Prepared, role| topology(p, role).is_ok_and(|t| encloses_volume(&t));
    let sampled = sample_both(&input, &output, opts, floor, false, || {
        closed(&input, Role::Input)
    });
    let both_closed = sampled.alongside && closed(&output, Role::Output);
    Ok(figures(&input, &output, &sampled, both_closed))
}

/// Checks that both meshes have faces and the input a usable diagonal; returns the
/// distance below which a sampled distance counts as 0 (see the module docs).
pub(crate) fn rounding_floor(input: &Prepared, output: &Prepared) -> Result<f64, MetricsError> {
    for (p, role) in [(input, Role::Input), (output, Role::Output)] {
        if p.mesh.faces.is_empty() {
            return Err(MetricsError::NoFaces { mesh: role });
        }
    }
    let diagonal = input.bbox.diagonal();
    if !(diagonal.is_finite() && diagonal > 0.0) {
        return Err(MetricsError::BadExtent { diagonal });
    }
    let scale = diagonal.max(input.bbox.min.abs().max(input.bbox.max.abs()).max_element());
    Ok(ROUNDING_FLOOR * scale)
}

/// The sampled distances of both directions, the input's tree (which the flip test needs
/// too) and what was computed alongside.
pub(crate) struct Sampled<T> {
    /// From the input's samples to the output surface.
    forward: Stats,
    /// From the output's samples to the input surface.
    backward: Stats,
    /// Per-element distances of the input to the output, when asked for.
    pub forward_field: Option<DistanceField>,
    /// Per-element distances of the output to the input, when asked for.
    pub backward_field: Option<DistanceField>,
    /// The tree over the input's faces.
    pub input_bvh: Bvh,
    /// The result of the `alongside` task given to [`sample_both`].
    pub alongside: T,
}

/// Samples both directions of checked meshes (`floor` from [`rounding_floor`]) and runs
/// `alongside` (e.g. the input's topology) on the same threads; with `record`, keeps each
/// mesh's per-element distances too ([`DistanceField`]).
///
/// The larger mesh's many samples need only the smaller mesh's tree, which is quick to
/// build, so they are measured while the larger mesh's tree is being built; its fewer
/// samples go last. Either way each direction's figures depend only on the two meshes.
pub(crate) fn sample_both<T: Send>(
    input: &Prepared,
    output: &Prepared,
    opts: &FidelityOptions,
    floor: f64,
    record: bool,
    alongside: impl FnOnce() -> T + Send,
) -> Sampled<T> {
    let build = |p: &Prepared| Bvh::build(&p.mesh.positions, &p.mesh.faces);
    if input.mesh.n_faces() >= output.mesh.n_faces() {
        let output_bvh = build(output);
        let (forward, (input_bvh, alongside)) = rayon::join(
            || one_side(input, &output_bvh, opts, floor, record),
            || rayon::join(|| build(input), alongside),
        );
        let backward = one_side(output, &input_bvh, opts, floor, record);
        Sampled {
            forward: forward.0,
            backward: backward.0,
            forward_field: forward.1,
            backward_field: backward.1,
            input_bvh,
            alongside,
        }
    } else {
        let (input_bvh, alongside) = rayon::join(|| build(input), alongside);
        let (backward, output_bvh) = rayon::join(
            || one_side(output, &input_bvh, opts, floor, record),
            || build(output),
        );
        let forward = one_side(input, &output_bvh, opts, floor, record);
        Sampled {
            forward: forward.0,
            backward: backward.0,
            forward_field: forward.1,
            backward_field: backward.1,
            input_bvh,
            alongside,
        }
    }
}

/// The figures of [`fidelity`] from the sampled distances.
pub(crate) fn figures<T>(
    input: &Prepared,
    output: &Prepared,
    sampled: &Sampled<T>,
    both_closed: bool,
) -> Fidelity {
    let (forward, backward) = (sampled.forward, sampled.backward);
    let mut pooled = forward;
    pooled.merge(&backward);
    let n = pooled.count.max(1) as f64;
    let diagonal = input.bbox.diagonal();
    let pct = |d: f64| 100.0 * d / diagonal;
    let volume_change_pct = both_closed
        .then(|| volume_change(input.mesh, output.mesh))
        .flatten();
    Fidelity {
        hausdorff_pct: pct(forward.max.max(backward.max)),
        mean_dist_pct: pct(pooled.sum / n),
        rms_dist_pct: pct((pooled.sum_sq / n).sqrt()),
        forward_max_pct: pct(forward.max),
        backward_max_pct: pct(backward.max),
        n_samples: pooled.count,
        forward_samples: forward.count,
        backward_samples: backward.count,
        bbox_diagonal: diagonal,
        volume_change_pct,
    }
}

/// Relative change of signed volume, in percent; `None` when the input's is zero.
fn volume_change(input: &Mesh, output: &Mesh) -> Option<f64> {
    let (v_in, v_out) = (input.signed_volume(), output.signed_volume());
    let change = 100.0 * (v_out - v_in).abs() / v_in.abs();
    change.is_finite().then_some(change)
}

/// Running figures of a set of sampled distances.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Stats {
    count: u64,
    max: f64,
    sum: f64,
    sum_sq: f64,
}

impl Stats {
    #[inline]
    fn add(&mut self, d: f64) {
        self.count += 1;
        self.max = self.max.max(d);
        self.sum += d;
        self.sum_sq += d * d;
    }

    fn merge(&mut self, o: &Stats) {
        self.count += o.count;
        self.max = self.max.max(o.max);
        self.sum += o.sum;
        self.sum_sq += o.sum_sq;
    }
}

/// The distances of one mesh's elements to the other surface, in model units: what the
/// fields of [`crate::fields`] are made of.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct DistanceField {
    /// Each vertex's distance (0 for a vertex no face uses).
    pub vertex: Vec<f64>,
    /// Each face's largest distance over its samples: those it owns (module docs), the
    /// edge searches' points and its corners.
    pub face: Vec<f64>,
}

/// Distances from the samples of `from` (see the module docs) to the surface in `to`,
/// gathered face by face: a face's samples are the vertices and edges it is the first face
/// to use, then its share of the face samples. All the samples of a face are answered
/// from the triangles of `to` gathered once for that face ([`Bvh::gather_near`]). With
/// `record`, the per-element distances too.
fn one_side(
    from: &Prepared,
    to: &Bvh,
    opts: &FidelityOptions,
    floor: f64,
    record: bool,
) -> (Stats, Option<DistanceField>) {
    one_side_with(from, to, opts, floor, true, record)
}

/// What one chunk of faces gives: its figures and, when recorded, each face's largest
/// distance and the distances of the vertices it sampled.
type ChunkResult = (Stats, Vec<f64>, Vec<(u32, f64)>);

/// [`one_side`], or with `batched` false one walk of the tree per sample: the reference
/// that the batched queries must match bit for bit.
fn one_side_with(
    from: &Prepared,
    to: &Bvh,
    opts: &FidelityOptions,
    floor: f64,
    batched: bool,
    record: bool,
) -> (Stats, Option<DistanceField>) {
    let side = Side::new(from.mesh, to, opts, floor, batched, record);
    let parts = map_chunks(side.mesh.n_faces(), CHUNK, |range| {
        side.measure_chunk(range)
    });
    let total = sum_in_chunk_order(&parts);
    (total, record.then(|| assemble_field(side.mesh, parts)))
}

/// The figures of all chunks, merged in chunk order.
fn sum_in_chunk_order(parts: &[ChunkResult]) -> Stats {
    let mut total = Stats::default();
    for part in parts {
        total.merge(&part.0);
    }
    total
}

/// The area of faces `0..i` of `mesh` for each `i` up to the face count, and the total.
fn cumulative_areas(mesh: &Mesh) -> (Vec<f64>, f64) {
    let n_faces = mesh.n_faces();
    let mut cumulative = Vec::with_capacity(n_faces + 1);
    let mut area = 0.0;
    cumulative.push(0.0);
    for f in 0..n_faces {
        area += mesh.face_area(f);
        cumulative.push(area);
    }
    (cumulative, area)
}

/// What every chunk of one direction reads: the two surfaces, the options and the way the
/// samples are shared out.
struct Side<'a> {
    /// The mesh whose samples are measured.
    mesh: &'a Mesh,
    /// The surface they are measured against.
    to: &'a Bvh,
    /// Distances up to this count as 0.
    floor: f64,
    /// Whether a face's samples are answered from triangles gathered once for the face.
    batched: bool,
    /// Whether the per-element distances are kept.
    record: bool,
    /// The face samples in all.
    samples: u64,
    /// Which face samples each vertex and each edge.
    first: FirstUse,
    /// The area of faces `0..i`, for each `i` up to the face count.
    cumulative: Vec<f64>,
    /// The mesh's area.
    area: f64,
    /// Whether the face samples are spread by area (a positive, finite area).
    spread: bool,
    /// The spacing of the face samples, which the edge samples keep too.
    spacing: f64,
}

impl<'a> Side<'a> {
    /// The shared reads for measuring the samples of `mesh` against `to`.
    fn new(
        mesh: &'a Mesh,
        to: &'a Bvh,
        opts: &FidelityOptions,
        floor: f64,
        batched: bool,
        record: bool,
    ) -> Self {
        let samples = opts.face_samples(mesh.n_faces());
        let first = FirstUse::of(mesh);
        // Cumulative areas give each face its share of the samples.
        let (cumulative, area) = cumulative_areas(mesh);
        let spread = area > 0.0 && area.is_finite();
        // The spacing of the face samples, which the edge samples keep too.
        let spacing = if spread {
            (area / samples as f64).sqrt()
        } else {
            f64::INFINITY
        };
        Side {
            mesh,
            to,
            floor,
            batched,
            record,
            samples,
            first,
            cumulative,
            area,
            spread,
            spacing,
        }
    }

    /// How many face samples the faces before face `f` hold.
    fn before(&self, f: usize) -> u64 {
        if !self.spread {
            0
        } else if f == self.mesh.n_faces() {
            self.samples
        } else {
            // The cast truncates, i.e. floors the non-negative quotient.
            ((self.samples as f64 * self.cumulative[f] / self.area) as u64).min(self.samples)
        }
    }

    /// The distance from `p` to the other surface (rounding noise as 0).
    fn distance(&self, p: DVec3, near: &NearSet) -> f64 {
        // `to` holds every face of a checked, non-empty mesh: a nearest point exists.
        let d = self
            .to
            .closest_point_near(near, p)
            .map_or(0.0, |h| h.distance());
        if d <= self.floor { 0.0 } else { d }
    }

    /// The samples face `f` owns.
    fn face_samples(&self, f: usize) -> FaceSamples {
        let (mesh, first) = (self.mesh, &self.first);
        let corners = mesh.corners(f);
        let owned_vertices = first.vertices_of(mesh, f);
        let edge_points: [u64; 3] = std::array::from_fn(|k| {
            if first.owns_edge(mesh, f, k) {
                edge_points(corners[k].distance(corners[(k + 1) % 3]), self.spacing)
            } else {
                0
            }
        });
        let n_face = self.before(f + 1) - self.before(f);
        FaceSamples {
            f,
            corners,
            owned_vertices,
            edge_points,
            n_face,
        }
    }

    /// The figures and, when recorded, the distances of the faces in `range`.
    fn measure_chunk(&self, range: Range<usize>) -> ChunkResult {
        let mut chunk = Chunk::new(self);
        for f in range {
            chunk.measure_face(f);
        }
        chunk.finish()
    }
}

/// The samples one face owns (see the module docs).
struct FaceSamples {
    /// The face.
    f: usize,
    /// Its corners' positions.
    corners: [DVec3; 3],
    /// Which corners it samples.
    owned_vertices: [bool; 3],
    /// How many points it samples on its edge from corner `k` to corner `k + 1`.
    edge_points: [u64; 3],
    /// How many of the face samples it holds.
    n_face: u64,
}

impl FaceSamples {
    /// How many samples in all (the edge searches' points apart).
    fn count(&self) -> u64 {
        self.n_face
            + self.owned_vertices.iter().filter(|&&o| o).count() as u64
            + self.edge_points.iter().sum::<u64>()
    }
}

/// The running state of one chunk of faces.
struct Chunk<'s> {
    /// What every chunk reads.
    side: &'s Side<'s>,
    /// The figures of the samples so far.
    stats: Stats,
    /// The largest distance the edge searches found (it counts for the maximum only).
    refined: f64,
    /// Each face's largest distance, when recorded.
    face_max: Vec<f64>,
    /// The sampled vertices' distances, when recorded.
    vertex_at: Vec<(u32, f64)>,
    /// The triangles of the other surface gathered for a face so far.
    near: NearSet,
}

impl<'s> Chunk<'s> {
    /// A chunk with nothing measured yet.
    fn new(side: &'s Side<'s>) -> Self {
        Chunk {
            side,
            stats: Stats::default(),
            refined: 0.0f64,
            face_max: Vec::new(),
            vertex_at: Vec::new(),
            near: NearSet::new(),
        }
    }

    /// The distance at `p`, added to the figures.
    fn measure(&mut self, p: DVec3) -> f64 {
        let d = self.side.distance(p, &self.near);
        self.stats.add(d);
        d
    }

    /// Measures the samples face `f` owns and, when recording, keeps their largest distance.
    fn measure_face(&mut self, f: usize) {
        let mut largest = 0.0f64;
        let face = self.side.face_samples(f);
        self.gather_near(&face);
        self.measure_vertices(&face, &mut largest);
        let peaks = self.measure_edges(&face, &mut largest);
        self.search_edge_peaks(&face, &peaks, &mut largest);
        self.measure_face_points(&face, &mut largest);
        if self.side.record {
            self.face_max.push(largest);
        }
    }

    /// Gathers the triangles near `face` unless those gathered already serve.
    fn gather_near(&mut self, face: &FaceSamples) {
        let corners = face.corners;
        let [a, b, c] = corners;
        // The set gathered for an earlier face serves while it covers this one.
        if self.side.batched && face.count() >= 2 && !corners.iter().all(|&x| self.near.covers(x)) {
            let centre = (a + b + c) / 3.0;
            let radius = corners
                .iter()
                .map(|&x| (x - centre).length())
                .fold(0.0, f64::max);
            self.side
                .to
                .gather_near(centre, NEAR_GROW * radius, NEAR_LIMIT, &mut self.near);
        }
    }

    /// Measures the corners `face` owns.
    fn measure_vertices(&mut self, face: &FaceSamples, largest: &mut f64) {
        for (k, _) in face.owned_vertices.iter().enumerate().filter(|(_, o)| **o) {
            let d = self.measure(face.corners[k]);
            *largest = largest.max(d);
            if self.side.record {
                self.vertex_at.push((self.side.mesh.faces[face.f][k], d));
            }
        }
    }

    /// Measures the even points on the edges `face` owns; gives each one's farthest's bracket.
    fn measure_edges(&mut self, face: &FaceSamples, largest: &mut f64) -> [(f64, f64); 3] {
        let corners = face.corners;
        let mut peaks = [(0.0, 0.0); 3];
        for (k, &count) in face.edge_points.iter().enumerate() {
            let (p, q) = (corners[k], corners[(k + 1) % 3]);
            let step = 1.0 / (count + 1) as f64;
            let mut best = (f64::NEG_INFINITY, 0.0);
            for i in 1..=count {
                let t = i as f64 * step;
                let d = self.measure(p + (q - p) * t);
                *largest = largest.max(d);
                if d > best.0 {
                    best = (d, t);
                }
            }
            peaks[k] = (best.1 - step, best.1 + step);
        }
        peaks
    }

    /// Searches each owned edge's bracket `peaks` for the edge's largest distance.
    fn search_edge_peaks(
        &mut self,
        face: &FaceSamples,
        peaks: &[(f64, f64); 3],
        largest: &mut f64,
    ) {
        let corners = face.corners;
        // The largest distance along an edge is often a kink (the edge passing over a
        // crease of the other surface), which evenly spaced points miss by up to half
        // a spacing's rise: a search between the largest point's neighbours finds it.
        for (k, &(lo, hi)) in peaks.iter().enumerate() {
            if face.edge_points[k] > 0 {
                let (p, q) = (corners[k], corners[(k + 1) % 3]);
                let peak = golden_max(lo, hi, |t| self.side.distance(p + (q - p) * t, &self.near));
                self.refined = self.refined.max(peak);
                *largest = largest.max(peak);
            }
        }
    }

    /// Measures the face samples `face` holds.
    fn measure_face_points(&mut self, face: &FaceSamples, largest: &mut f64) {
        let [a, b, c] = face.corners;
        for j in 0..face.n_face {
            let (u, v) = face_sample(j);
            *largest = largest.max(self.measure(a + (b - a) * u + (c - a) * v));
        }
    }

    /// The chunk's figures (the edge searches' maximum included) and its records.
    fn finish(mut self) -> ChunkResult {
        self.stats.max = self.stats.max.max(self.refined);
        (self.stats, self.face_max, self.vertex_at)
    }
}

/// The per-element distances from the chunks' records: each face's largest distance
/// raised to its corners' (a face too small for samples of its own still shows the
/// distance at its corners).
fn assemble_field(mesh: &Mesh, parts: Vec<ChunkResult>) -> DistanceField {
    let mut vertex = vec![0.0; mesh.n_vertices()];
    let mut face = Vec::with_capacity(mesh.n_faces());
    for (_, faces, vertices) in parts {
        face.extend(faces);
        for (v, d) in vertices {
            vertex[v as usize] = d;
        }
    }
    for (largest, corners) in face.iter_mut().zip(&mesh.faces) {
        for &v in corners {
            *largest = largest.max(vertex[v as usize]);
        }
    }
    DistanceField { vertex, face }
}

/// The largest value `f` takes at the points a golden-section search for its maximum on
/// `[lo, hi]` visits ([`REFINE_STEPS`] of them).
fn golden_max(lo: f64, hi: f64, f: impl Fn(f64) -> f64) -> f64 {
    const INV_PHI: f64 = 0.618_033_988_749_894_9;
    let (mut a, mut b) = (lo.max(0.0), hi.min(1.0));
    let mut x1 = b - INV_PHI * (b - a);
    let mut x2 = a + INV_PHI * (b - a);
    let (mut f1, mut f2) = (f(x1), f(x2));
    let mut best = f1.max(f2);
    for _ in 2..REFINE_STEPS {
        if f1 >= f2 {
            b = x2;
            (x2, f2) = (x1, f1);
            x1 = b - INV_PHI * (b - a);
            f1 = f(x1);
            best = best.max(f1);
        } else {
            a = x1;
            (x1, f1) = (x2, f2);
            x2 = a + INV_PHI * (b - a);
            f2 = f(x2);
            best = best.max(f2);
        }
    }
    best
}

/// Points of the golden-section search around each edge's largest sample: the bracket of
/// two spacings shrinks to 0.618¹⁰ ≈ 1/120 of itself.
pub const REFINE_STEPS: usize = 12;

/// The points sampled inside an edge of length `length` at sample spacing `spacing`:
/// `max(1, ⌈length/spacing⌉ − 1)`, so that neighbouring points are at most `spacing`
/// apart.
fn edge_points(length: f64, spacing: f64) -> u64 {
    let gaps = (length / spacing).ceil();
    // A NaN (zero over zero) or an infinite spacing leaves the midpoint alone; the cap
    // keeps a sliver's long edge from asking for more points than a face has samples.
    if gaps.is_nan() || gaps <= 2.0 {
        1
    } else {
        (gaps.min(1e9) as u64) - 1
    }
}

/// Which face samples each vertex and each edge: the first face, in face order, that uses
/// it (a vertex → faces table in face order answers both).
struct FirstUse {
    /// `start[v]..start[v + 1]` indexes `faces` for vertex `v`.
    start: Vec<u32>,
    /// The faces of each vertex, ascending.
    faces: Vec<u32>,
}

impl FirstUse {
    fn of(mesh: &Mesh) -> FirstUse {
        let n = mesh.n_vertices();
        let mut start = vec![0u32; n + 1];
        for face in &mesh.faces {
            for &v in face {
                start[v as usize + 1] += 1;
            }
        }
        for v in 0..n {
            start[v + 1] += start[v];
        }
        let mut fill = start.clone();
        let mut faces = vec![0u32; start[n] as usize];
        for (f, face) in mesh.faces.iter().enumerate() {
            for &v in face {
                let at = &mut fill[v as usize];
                faces[*at as usize] = f as u32;
                *at += 1;
            }
        }
        FirstUse { start, faces }
    }

    fn faces_of(&self, v: u32) -> &[u32] {
        let v = v as usize;
        &self.faces[self.start[v] as usize..self.start[v + 1] as usize]
    }

    /// Which corners of face `f` it samples: those whose vertex it is the first to use
    /// (once, should the face repeat a vertex).
    fn vertices_of(&self, mesh: &Mesh, f: usize) -> [bool; 3] {
        let face = mesh.faces[f];
        std::array::from_fn(|k| {
            self.faces_of(face[k]).first() == Some(&(f as u32)) && !face[..k].contains(&face[k])
        })
    }

    /// True when face `f` samples its edge from corner `k` to corner `k + 1`: it is the
    /// first face holding both ends (an edge whose ends coincide is no edge).
    fn owns_edge(&self, mesh: &Mesh, f: usize, k: usize) -> bool {
        let face = mesh.faces[f];
        let (a, b) = (face[k], face[(k + 1) % 3]);
        a != b
            && self
                .faces_of(a)
                .iter()
                .find(|&&g| mesh.faces[g as usize].contains(&b))
                == Some(&(f as u32))
    }
}

/// Barycentric `(u, v)` of the `j`-th sample in a face (weights of corners b and c).
#[inline]
fn face_sample(j: u64) -> (f64, f64) {
    // `x − trunc(x)` as `f64::fract` computes it, with the truncation done by a cast (the
    // arguments are non-negative and far below 2⁶³), which needs no call into libm.
    let fract = |x: f64| x - (x as u64) as f64;
    let j = j as f64;
    let u = fract(1.0 / 3.0 + j / PLASTIC);
    let v = fract(1.0 / 3.0 + j / (PLASTIC * PLASTIC));
    if u + v > 1.0 {
        (1.0 - u, 1.0 - v)
    } else {
        (u, v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::icosphere;

    /// Sparse sampling, for the tests whose point is not the density.
    const LIGHT: FidelityOptions = FidelityOptions {
        samples_per_face: 10,
        min_face_samples: 0,
    };

    fn scaled(m: &Mesh, s: f64) -> Mesh {
        Mesh::new(
            m.positions.iter().map(|p| *p * s).collect(),
            m.faces.clone(),
        )
    }

    #[test]
    fn identical_meshes_are_exactly_zero_apart() {
        let m = icosphere(3);
        let f = fidelity(&m, &m, &LIGHT).unwrap();
        assert_eq!(f.hausdorff_pct, 0.0);
        assert_eq!(f.mean_dist_pct, 0.0);
        assert_eq!(f.rms_dist_pct, 0.0);
        assert_eq!(f.volume_change_pct, Some(0.0));
    }

    /// Inner polyhedron P (vertices on the unit sphere) against (1+d)·P. Every point x of
    /// P is d·|x| ≤ d from (1+d)·x, and every vertex of (1+d)·P is at least d from P
    /// (P lies in the unit ball): the Hausdorff distance is exactly d. The forward
    /// direction is smaller: a vertex of P is d·h from (1+d)·P, h the distance of its
    /// faces' planes from the centre.
    #[test]
    fn sphere_against_its_scaled_copy_is_d_apart() {
        let m = icosphere(3);
        let d = 0.01;
        let f = fidelity(&m, &scaled(&m, 1.0 + d), &LIGHT).unwrap();
        let diag = m.bbox().diagonal();
        let expect = 100.0 * d / diag;
        assert!(
            (f.hausdorff_pct - expect).abs() < 1e-9 * expect,
            "{} vs {expect}",
            f.hausdorff_pct
        );
        assert_eq!(f.backward_max_pct, f.hausdorff_pct);
        let h_min = (0..m.n_faces())
            .map(|i| m.face_normal(i).dot(m.corners(i)[0]))
            .fold(f64::INFINITY, f64::min);
        assert!(f.forward_max_pct >= expect * h_min * (1.0 - 1e-9));
        assert!(f.forward_max_pct <= expect);
        assert!(f.mean_dist_pct > expect * h_min * 0.9 && f.mean_dist_pct <= expect);
        // Volume scales by (1+d)³.
        let dv = 100.0 * ((1.0 + d).powi(3) - 1.0);
        assert!((f.volume_change_pct.unwrap() - dv).abs() < 1e-9);
    }

    /// The rule of the module docs, counted independently: used vertices, the points
    /// of each distinct edge, the face samples.
    fn expected_samples(m: &Mesh, opts: &FidelityOptions) -> u64 {
        let faces = opts.face_samples(m.n_faces());
        let area: f64 = (0..m.n_faces()).map(|f| m.face_area(f)).sum();
        let spacing = (area / faces as f64).sqrt();
        let mut edges = std::collections::BTreeSet::new();
        let mut used = std::collections::BTreeSet::new();
        for f in &m.faces {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                edges.insert((a.min(b), a.max(b)));
                used.insert(a);
            }
        }
        let edge_points: u64 = edges
            .iter()
            .map(|&(a, b)| {
                let l = m.positions[a as usize].distance(m.positions[b as usize]);
                ((l / spacing).ceil() as u64).saturating_sub(1).max(1)
            })
            .sum();
        used.len() as u64 + edge_points + faces
    }

    #[test]
    fn sample_count_follows_the_stated_rule() {
        let fine = icosphere(3);
        let coarse = icosphere(1);
        for opts in [
            FidelityOptions {
                samples_per_face: 7,
                min_face_samples: 0,
            },
            FidelityOptions {
                samples_per_face: 7,
                min_face_samples: 5000,
            },
            FidelityOptions::default(),
        ] {
            // Either way round: each mesh carries its own samples.
            for (input, output) in [(&fine, &coarse), (&coarse, &fine)] {
                let f = fidelity(input, output, &opts).unwrap();
                assert_eq!(
                    f.forward_samples,
                    expected_samples(input, &opts),
                    "{opts:?}"
                );
                assert_eq!(
                    f.backward_samples,
                    expected_samples(output, &opts),
                    "{opts:?}"
                );
                assert_eq!(f.n_samples, f.forward_samples + f.backward_samples);
            }
        }
        // At least the minimum on the faces of the small mesh, 100 per face on the large.
        let f = fidelity(&fine, &coarse, &FidelityOptions::default()).unwrap();
        assert!(f.backward_samples > 1_000_000);
        assert!(f.forward_samples > 1_000_000.max(100 * fine.n_faces() as u64));
    }

    #[test]
    fn the_edge_search_finds_a_kink_between_two_samples() {
        // A roof over [0, 1] with its ridge at 0.37, sampled at 0.25 and 0.5.
        let roof = |t: f64| 1.0 - (t - 0.37).abs();
        let peak = golden_max(0.0, 0.5, roof);
        assert!(peak > 1.0 - 0.005 && peak <= 1.0, "{peak}");
        // Never below what it evaluates; the bracket is clipped to the edge.
        assert_eq!(golden_max(-1.0, 2.0, |t| t), golden_max(0.0, 1.0, |t| t));
        assert!(golden_max(0.0, 1.0, |t| t) > 0.99);
    }

    #[test]
    fn edges_get_points_at_the_face_samples_spacing() {
        assert_eq!(edge_points(1.0, 0.3), 3); // 4 gaps of 0.25
        assert_eq!(edge_points(1.0, 0.5), 1); // the midpoint
        assert_eq!(edge_points(1.0, 2.0), 1);
        assert_eq!(edge_points(0.0, 0.0), 1);
        assert_eq!(edge_points(1.0, f64::INFINITY), 1);
        assert_eq!(edge_points(1e300, 1e-300), 999_999_999);
    }

    /// The output → input maximum of a coarse polyhedron inscribed in a fine one lies
    /// inside its faces; the dense default finds it at least as far as sparse sampling,
    /// within a hair of the value a very dense sampling gives.
    #[test]
    fn dense_sampling_finds_the_largest_distance_of_a_coarse_output() {
        let (fine, coarse) = (icosphere(4), icosphere(1));
        let sparse = FidelityOptions {
            samples_per_face: 10,
            min_face_samples: 0,
        };
        let denser = FidelityOptions {
            samples_per_face: 1000,
            min_face_samples: 4_000_000,
        };
        let at = |o: &FidelityOptions| fidelity(&fine, &coarse, o).unwrap().backward_max_pct;
        let (s, d, reference) = (at(&sparse), at(&FidelityOptions::default()), at(&denser));
        assert!(d >= s, "{d} < {s}");
        assert!(
            d >= reference * 0.995 && d <= reference,
            "{d} against {reference}"
        );
    }

    /// A bumpy sphere: `m`'s vertices pushed in and out by a smooth pattern.
    fn bumpy(m: &Mesh, amplitude: f64) -> Mesh {
        let positions = m
            .positions
            .iter()
            .map(|p| *p * (1.0 + amplitude * (5.0 * p.x).sin() * (3.0 * p.y + p.z).cos()))
            .collect();
        Mesh::new(positions, m.faces.clone())
    }

    #[test]
    fn batched_queries_give_exactly_the_distances_of_one_query_per_sample() {
        // Fine against coarse (small balls, sets reused), coarse against fine (large
        // balls, many over the limit) and a mesh against itself (distance 0 everywhere).
        let (fine, coarse) = (bumpy(&icosphere(4), 0.05), scaled(&icosphere(2), 1.01));
        for (from, to) in [(&fine, &coarse), (&coarse, &fine), (&fine, &fine)] {
            let (from, to) = (
                Prepared::new(from, Role::Input).unwrap(),
                Prepared::new(to, Role::Output).unwrap(),
            );
            let bvh = Bvh::build(&to.mesh.positions, &to.mesh.faces);
            let floor = rounding_floor(&from, &to).unwrap();
            let opts = FidelityOptions {
                samples_per_face: 10,
                min_face_samples: 0,
            };
            let (batched, field) = one_side_with(&from, &bvh, &opts, floor, true, true);
            let (reference, _) = one_side_with(&from, &bvh, &opts, floor, false, false);
            let (unrecorded, none) = one_side_with(&from, &bvh, &opts, floor, true, false);
            assert_eq!((unrecorded, none), (batched, None));
            let field = field.unwrap();
            let largest = field.face.iter().copied().fold(0.0, f64::max);
            assert_eq!(largest.to_bits(), batched.max.to_bits());
            assert_eq!(batched.count, reference.count);
            assert_eq!(batched.max.to_bits(), reference.max.to_bits());
            assert_eq!(batched.sum.to_bits(), reference.sum.to_bits());
            assert_eq!(batched.sum_sq.to_bits(), reference.sum_sq.to_bits());
        }
    }

    #[test]
    fn input_smaller_than_output_gives_the_same_figures_on_one_thread() {
        let (small, large) = (icosphere(2), bumpy(&icosphere(4), 0.02));
        let opts = LIGHT;
        let f = fidelity(&small, &large, &opts).unwrap();
        assert_eq!(
            coarsen_testdata::on_threads(1, || fidelity(&small, &large, &opts).unwrap()),
            f
        );
        assert!(f.backward_max_pct > 0.0 && f.forward_max_pct > 0.0);
        // The same pair the other way round swaps the directions' maxima.
        let g = fidelity(&large, &small, &opts).unwrap();
        assert_eq!(g.n_samples, f.n_samples);
        let diag = |m: &Mesh| m.bbox().diagonal();
        let back_to_model = |pct: f64, m: &Mesh| pct * diag(m);
        assert!(
            (back_to_model(g.forward_max_pct, &large) - back_to_model(f.backward_max_pct, &small))
                .abs()
                < 1e-12
        );
    }

    #[test]
    fn face_samples_start_at_the_centroid_and_stay_inside() {
        assert_eq!(face_sample(0), (1.0 / 3.0, 1.0 / 3.0));
        for j in (0..1000).chain([123_456_789, 1 << 40]) {
            let (u, v) = face_sample(j);
            // The cast-based fraction is `f64::fract`, bit for bit.
            let (x, y) = (
                1.0 / 3.0 + j as f64 / PLASTIC,
                1.0 / 3.0 + j as f64 / (PLASTIC * PLASTIC),
            );
            let fold = if x.fract() + y.fract() > 1.0 {
                (1.0 - x.fract(), 1.0 - y.fract())
            } else {
                (x.fract(), y.fract())
            };
            assert_eq!((u, v), fold);
            assert!(u >= 0.0 && v >= 0.0 && u + v <= 1.0, "{j}: {u} {v}");
        }
    }

    #[test]
    fn same_figures_twice_and_on_one_thread() {
        let a = icosphere(4);
        let b = scaled(&icosphere(2), 1.02);
        let opts = LIGHT;
        let first = fidelity(&a, &b, &opts).unwrap();
        assert_eq!(first, fidelity(&a, &b, &opts).unwrap());
        let single = coarsen_testdata::on_threads(1, || fidelity(&a, &b, &opts).unwrap());
        assert_eq!(first, single);
        assert_eq!(
            first.hausdorff_pct.to_bits(),
            single.hausdorff_pct.to_bits()
        );
    }

    #[test]
    fn open_meshes_have_no_volume_change() {
        let a = icosphere(2);
        let mut b = a.clone();
        b.faces.pop();
        let f = fidelity(&a, &b, &LIGHT).unwrap();
        assert_eq!(f.volume_change_pct, None);
    }

    #[test]
    fn empty_and_pointlike_meshes_are_named_errors() {
        let a = icosphere(1);
        let empty = Mesh::new(a.positions.clone(), Vec::new());
        let opts = LIGHT;
        assert_eq!(
            fidelity(&a, &empty, &opts),
            Err(MetricsError::NoFaces { mesh: Role::Output })
        );
        let point = Mesh::new(vec![DVec3::ONE; 3], vec![[0, 1, 2]]);
        assert_eq!(
            fidelity(&point, &a, &opts),
            Err(MetricsError::BadExtent { diagonal: 0.0 })
        );
    }

    #[test]
    fn degenerate_faces_and_loose_vertices_do_not_break_the_figures() {
        let mut a = icosphere(2);
        let n = a.positions.len() as u32;
        a.positions.push(DVec3::splat(50.0)); // unused: neither sampled nor in the box
        a.faces.push([0, 0, 1]); // zero area
        a.faces.push([0, 1, n - 1]);
        let f = fidelity(&a, &icosphere(2), &LIGHT).unwrap();
        for x in [f.hausdorff_pct, f.mean_dist_pct, f.rms_dist_pct] {
            assert!(x.is_finite());
        }
        assert!((f.bbox_diagonal - icosphere(2).bbox().diagonal()).abs() < 1e-12);
    }
}
