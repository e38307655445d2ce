//! The `texture` stage: lays the run input's per-corner attributes (UVs across seams,
//! normals, colours) onto the current mesh, for pipelines whose stages rebuild the surface
//! and so cannot carry them (clustering, the dual, relaxation). The runner keeps them on
//! the run's input for it (`Contract::restores_wedges`).
//!
//! Each output face takes one *side* of the input: an input face and the faces reached
//! from it without crossing a seam (an edge whose faces disagree on a UV or other
//! per-corner value but the normal). Each of its corners takes the values at the point of
//! that side nearest the corner's vertex, found by a best-first walk from that face (the
//! faces nearer the vertex than the best point so far, at most [`MAX_WALK`] of them): a
//! face straddling a seam the output does not follow has its far corners held to the
//! seam, on its own side, rather than reaching into another chart. The side is the one of
//! the input face nearest the face's centroid; when that turns the face over in UV space
//! (against that input face's winding), the first side of the input faces nearest each
//! corner that does not is taken instead.
//! The values are those of the input face's corners, weighted barycentrically (normals made
//! unit again); a vertex's corners whose UVs agree to within 10⁻⁷ of the UV extent share one
//! wedge.
//!
//! When the run's input says which material each face uses (the face label column
//! `material`, of more than one value) and the mesh lost that column, each face takes the
//! material of the input face nearest its centroid. Without per-corner attributes or
//! materials on the run's input, the mesh passes unchanged.
//!
//! A coarse face over a stretch where the input's UVs bend faster than the face is wide
//! can still be laid turned over in UV space (judged as the texture figures judge it,
//! `coarsen_metrics::UvJudge`). With `mend` (the default) such faces are mended: a corner
//! moved along the input, else one of the face's edges flipped, when that lays every face
//! it touches right and keeps their shape (module `mend`); the figures say how many of
//! each, and how many faces are left turned over.

use coarsen_geom::{DVec2, DVec3};
use coarsen_mesh::material::MATERIAL;
use coarsen_mesh::{AttrValues, Attributes, Index, Mesh, Wedges};
use coarsen_spatial::{Bvh, closest_point_on_triangle};
use coarsen_stage::{Context, Contract, Params, Stage, StageError, params};
use rayon::prelude::*;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

mod mend;

params! {
    /// Parameters of `texture`.
    pub struct TextureParams {
        /// Flip an edge of each face laid turned over in UV space when that lays both of
        /// its faces right and keeps their shape (`mend` module).
        pub mend: bool = true,
    }
}

impl Params for TextureParams {}

/// The most input faces one corner's walk visits.
pub const MAX_WALK: usize = 4096;

/// The `texture` stage.
pub struct TextureStage {
    params: TextureParams,
}

impl Stage for TextureStage {
    type Params = TextureParams;
    const KIND: &'static str = "texture";
    const SUMMARY: &'static str = "The run input's UVs, normals, colours and face materials laid onto the current mesh, each face on one side of the input's UV seams; faces laid turned over in UV space mended by a vertex move or an edge flip.";

    fn new(params: TextureParams) -> Self {
        TextureStage { params }
    }

    fn contract(&self) -> Contract {
        Contract {
            carries_wedges: true,
            restores_wedges: true,
            ..Contract::default()
        }
    }

    fn run(&self, mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        let input = cx.original;
        let materials = input
            .face_attrs
            .label(MATERIAL)
            .filter(|m| m.iter().any(|&x| x != m[0]) && mesh.face_attrs.get(MATERIAL).is_none());
        if (input.wedges.is_empty() && materials.is_none()) || mesh.faces.is_empty() {
            cx.report.figure("textured", false);
            return Ok(mesh);
        }
        let bvh = Bvh::build(&input.positions, &input.faces);
        let mut mesh = mesh;
        if let Some(labels) = materials {
            let of_face = lay_materials(&mesh, &bvh, labels);
            mesh.face_attrs.insert(MATERIAL, AttrValues::Label(of_face));
            cx.report.figure("materials_laid", true);
        }
        if input.wedges.is_empty() {
            cx.report.figure("textured", false);
            return Ok(mesh);
        }
        let sides = Sides::of(input);
        let uv = input.wedges.attrs().vec2("uv");
        let layer = Layer {
            input,
            sides: &sides,
            bvh: &bvh,
            uv,
        };
        let laid: Vec<(Index, [Option<Found>; 3])> = mesh
            .faces
            .par_iter()
            .map_init(
                || Walk::new(input.n_faces()),
                |walk, face| layer.lay(walk, face.map(|v| mesh.positions[v as usize])),
            )
            .collect();
        let judge = uv.map(|uv| {
            let corner_uv = (0..3 * input.n_faces())
                .map(|c| uv[input.wedges.corners()[c] as usize])
                .collect();
            coarsen_metrics::UvJudge::with_index(input, corner_uv, &bvh)
        });
        let (mut start, mut found): (Vec<Index>, Vec<[Option<Found>; 3]>) =
            laid.into_iter().unzip();
        let mended = match (uv, &judge) {
            (Some(uv), Some(judge)) => {
                let side_of = sides.labels();
                let laid = mend::Laid {
                    input,
                    uv,
                    sides: &sides,
                    side_of: &side_of,
                    mend: self.params.mend,
                    judge,
                };
                mend::mend(
                    &laid,
                    &mut mesh.positions,
                    &mut mesh.faces,
                    &mut found,
                    &mut start,
                )
            }
            _ => mend::Mended::default(),
        };
        // A corner held to a seam: its side's nearest point is farther than the input's.
        let held = mesh
            .faces
            .par_iter()
            .zip(&found)
            .map(|(face, found)| {
                face.iter()
                    .zip(found)
                    .filter(|(v, f)| {
                        let p = mesh.positions[**v as usize];
                        let all = bvh.closest_point(p).map_or(0.0, |n| n.distance_squared);
                        f.is_some_and(|f| f.d2 > all * (1.0 + 1e-9) + 1e-300)
                    })
                    .count()
            })
            .sum::<usize>();
        let mut columns = Attributes::default();
        for (name, values) in input.wedges.attrs().iter() {
            columns.insert(name, interpolate(input, values, name, &found));
        }
        let columns = share_wedges(&mesh, columns);
        let mut out = mesh;
        out.wedges = Wedges::default();
        let out = out.with_corner_attributes(columns);
        cx.report.figure("textured", true);
        cx.report
            .figure("seam_vertices", out.wedges.split_vertices());
        cx.report.figure("corners_held_to_a_seam", held);
        cx.report.figure("uv_flips_mended", mended.flips);
        cx.report.figure("uv_moves_mended", mended.moves);
        cx.report.figure("uv_turned_over", mended.turned);
        Ok(out)
    }
}

/// What laying a face on the input needs.
struct Layer<'a> {
    input: &'a Mesh,
    sides: &'a Sides,
    bvh: &'a Bvh,
    uv: Option<&'a [DVec2]>,
}

impl Layer<'_> {
    /// A face with corners `corners` laid on the input (module docs): the input face whose
    /// side it takes, and each corner's point of that side.
    fn lay(&self, walk: &mut Walk, corners: [DVec3; 3]) -> (Index, [Option<Found>; 3]) {
        let (input, uv) = (self.input, self.uv);
        let on_side = |walk: &mut Walk, start: Index| {
            corners.map(|p| walk.nearest(input, self.sides, start, p))
        };
        let centroid = (corners[0] + corners[1] + corners[2]) / 3.0;
        let Some(first) = self.bvh.closest_point(centroid).map(|n| n.face) else {
            return (NONE, [None; 3]);
        };
        let mut best = (first, on_side(walk, first));
        if !turns_over(input, uv, first, &best.1) {
            return best;
        }
        let mut tried = vec![first];
        for p in corners {
            let Some(start) = self.bvh.closest_point(p).map(|n| n.face) else {
                continue;
            };
            if tried.contains(&start) {
                continue;
            }
            tried.push(start);
            let other = on_side(walk, start);
            if !turns_over(input, uv, start, &other) {
                best = (start, other);
                break;
            }
        }
        best
    }
}

/// Each face's material: that of the input face nearest its centroid.
fn lay_materials(mesh: &Mesh, bvh: &Bvh, labels: &[u32]) -> Vec<u32> {
    mesh.faces
        .par_iter()
        .map(|face| {
            let c = face
                .iter()
                .map(|&v| mesh.positions[v as usize])
                .sum::<DVec3>()
                / 3.0;
            bvh.closest_point(c)
                .map_or(labels[0], |n| labels[n.face as usize])
        })
        .collect()
}

/// Whether a face's corners `found` on the side of input face `start` turn it over in UV
/// space against `start`'s own winding.
fn turns_over(
    input: &Mesh,
    uv: Option<&[DVec2]>,
    start: Index,
    found: &[Option<Found>; 3],
) -> bool {
    let Some(uv) = uv else {
        return false;
    };
    let at = |f: &Found| uv_at(input, uv, f);
    let wind = |t: [DVec2; 3]| (t[1] - t[0]).perp_dot(t[2] - t[0]);
    let [Some(a), Some(b), Some(c)] = found else {
        return false;
    };
    let own = wind(std::array::from_fn(|k| {
        uv[input.wedges.corner(start as usize, k) as usize]
    }));
    wind([at(a), at(b), at(c)]) * own < 0.0
}

/// The UV of the input at a found point.
fn uv_at(input: &Mesh, uv: &[DVec2], f: &Found) -> DVec2 {
    (0..3)
        .map(|k| f.bary[k] * uv[input.wedges.corner(f.face as usize, k) as usize])
        .sum()
}

/// The input's faces joined across the edges that are no seam.
struct Sides {
    /// Per face, the faces across its edges `k → k + 1` on the same side (or `NONE`).
    next: Vec<[Index; 3]>,
}

const NONE: Index = Index::MAX;

impl Sides {
    fn of(input: &Mesh) -> Sides {
        let seams = input.wedges.seam_edges(&input.faces);
        let mut edges: Vec<([Index; 2], Index, u8)> = Vec::with_capacity(3 * input.n_faces());
        for (f, face) in input.faces.iter().enumerate() {
            for k in 0..3u8 {
                let (a, b) = (face[k as usize], face[(k as usize + 1) % 3]);
                edges.push(([a.min(b), a.max(b)], f as Index, k));
            }
        }
        edges.sort_unstable();
        let mut next = vec![[NONE; 3]; input.n_faces()];
        for run in edges.chunk_by(|x, y| x.0 == y.0) {
            if let [(e, f, k), (_, g, j)] = run
                && seams.binary_search(e).is_err()
            {
                next[*f as usize][*k as usize] = *g;
                next[*g as usize][*j as usize] = *f;
            }
        }
        Sides { next }
    }

    /// Each face's side: the smallest face index of the faces it reaches without crossing
    /// a seam.
    fn labels(&self) -> Vec<Index> {
        let mut label = vec![NONE; self.next.len()];
        let mut stack = Vec::new();
        for f in 0..self.next.len() {
            if label[f] != NONE {
                continue;
            }
            label[f] = f as Index;
            stack.push(f as Index);
            while let Some(g) = stack.pop() {
                for &h in &self.next[g as usize] {
                    if h != NONE && label[h as usize] == NONE {
                        label[h as usize] = f as Index;
                        stack.push(h);
                    }
                }
            }
        }
        label
    }
}

/// Where a corner's values come from: an input face and the weights of its corners.
#[derive(Clone, Copy, Debug)]
struct Found {
    face: Index,
    bary: [f64; 3],
    /// Squared distance from the corner's vertex.
    d2: f64,
}

/// A face in the walk's queue, nearest first (ties: the smaller face).
#[derive(PartialEq)]
struct Queued(f64, Index);

impl Eq for Queued {}

impl Ord for Queued {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

impl PartialOrd for Queued {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// One thread's walk: the faces seen, marked by generation.
struct Walk {
    seen: Vec<u32>,
    generation: u32,
    queue: BinaryHeap<Queued>,
}

impl Walk {
    fn new(n_faces: usize) -> Walk {
        Walk {
            seen: vec![0; n_faces],
            generation: 0,
            queue: BinaryHeap::new(),
        }
    }

    /// The point of `start`'s side nearest `p` (module docs).
    fn nearest(&mut self, input: &Mesh, sides: &Sides, start: Index, p: DVec3) -> Option<Found> {
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.seen.fill(0);
            self.generation = 1;
        }
        self.queue.clear();
        let near = |f: Index| {
            let [a, b, c] = input.faces[f as usize].map(|v| input.positions[v as usize]);
            let (q, bary) = closest_point_on_triangle(p, a, b, c);
            (q.distance_squared(p), bary)
        };
        let mut best: Option<(f64, Found)> = None;
        self.seen[start as usize] = self.generation;
        self.queue.push(Queued(near(start).0, start));
        let mut visited = 0;
        while let Some(Queued(d, f)) = self.queue.pop() {
            if best.is_some_and(|(bd, _)| d > bd) || visited >= MAX_WALK {
                break;
            }
            visited += 1;
            let (d, bary) = near(f);
            for &g in &sides.next[f as usize] {
                if g == NONE {
                    continue;
                }
                if self.seen[g as usize] != self.generation {
                    self.seen[g as usize] = self.generation;
                    self.queue.push(Queued(near(g).0, g));
                }
            }
            if best.is_none_or(|(bd, b)| d < bd || (d == bd && f < b.face)) {
                best = Some((
                    d,
                    Found {
                        face: f,
                        bary,
                        d2: d,
                    },
                ));
            }
        }
        best.map(|(_, f)| f)
    }
}

/// The values of input wedge column `values` at each output corner's point (zero where
/// none was found; normals made unit again).
fn interpolate(
    input: &Mesh,
    values: &AttrValues,
    name: &str,
    found: &[[Option<Found>; 3]],
) -> AttrValues {
    let mixes: Vec<([Index; 3], [f64; 3])> = found
        .iter()
        .flatten()
        .map(|c| match c {
            Some(c) => (
                std::array::from_fn(|k| input.wedges.corner(c.face as usize, k)),
                c.bary,
            ),
            None => ([0; 3], [0.0; 3]),
        })
        .collect();
    match (name, values.blend(&mixes)) {
        ("normal", AttrValues::Vec3(n)) => {
            AttrValues::Vec3(n.into_iter().map(DVec3::normalize_or_zero).collect())
        }
        (_, v) => v,
    }
}

/// `columns` (per output corner) with the corners of each vertex whose UVs agree to within
/// 10⁻⁷ of the UV extent given the first such corner's values in every column.
fn share_wedges(mesh: &Mesh, columns: Attributes) -> Attributes {
    let Some(AttrValues::Vec2(uv)) = columns.get("uv") else {
        return columns;
    };
    let (lo, hi) = uv.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), t| (lo.min(*t), hi.max(*t)),
    );
    let tolerance = 1e-7 * (hi - lo).length().max(f64::MIN_POSITIVE);
    // Each vertex's corners, in corner order.
    let mut by_vertex: Vec<(Index, Index)> = mesh
        .faces
        .iter()
        .flatten()
        .enumerate()
        .map(|(c, &v)| (v, c as Index))
        .collect();
    by_vertex.sort_unstable();
    let mut source: Vec<Index> = (0..uv.len() as Index).collect();
    for run in by_vertex.chunk_by(|a, b| a.0 == b.0) {
        for (i, &(_, c)) in run.iter().enumerate() {
            if let Some(&(_, first)) = run[..i].iter().find(|&&(_, d)| {
                source[d as usize] == d && uv[d as usize].distance(uv[c as usize]) <= tolerance
            }) {
                source[c as usize] = first;
            }
        }
    }
    columns.gather(&source)
}

coarsen_stage::export_stage!(TextureStage);

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_stage::StageReport;

    /// Runs the stage on `mesh` with `input` as the run's input.
    fn run(input: &Mesh, mesh: Mesh) -> (Mesh, StageReport) {
        let mut report = StageReport::default();
        let mut cx = Context::new(input, &mut report);
        let out = TextureStage::new(TextureParams::default())
            .run(mesh, &mut cx)
            .unwrap();
        (out, report)
    }

    /// `m` turned about z by `turn` radians.
    fn turned(mut m: Mesh, turn: f64) -> Mesh {
        let (s, c) = turn.sin_cos();
        for p in &mut m.positions {
            *p = DVec3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z);
        }
        m
    }

    /// A latitude–longitude sphere turned about z by `turn` radians, so that its own
    /// meridians miss the input's seam.
    fn turned_sphere(turn: f64) -> Mesh {
        turned(coarsen_shapes::uv_sphere(1.0, 16, 24).unwrap(), turn)
    }

    #[test]
    fn a_remeshed_sphere_takes_the_input_uvs_on_each_side_of_the_seam() {
        let input = coarsen_shapes::with_spherical_uvs(coarsen_shapes::icosphere(1.0, 4).unwrap());
        // The input's seam zigzags along its edges near the meridian; the output's faces
        // across it (more of them when the output is turned by 0.1 radians) have their far
        // corners held to the seam on the face's side, as far off as an edge is long.
        for (turn, mean_pct, max_pct) in [(0.0, 0.1, 2.0), (0.1, 0.25, 8.0)] {
            let (out, report) = run(&input, turned_sphere(turn));
            out.wedges.check(&out.faces).unwrap();
            assert_eq!(report.get("textured"), Some(&true.into()));
            let held = report
                .get("corners_held_to_a_seam")
                .and_then(|h| h.as_u64());
            assert!(held.is_some_and(|h| h > 0), "{held:?}");
            let t = coarsen_metrics::texture(&input, &out, 2.0 * 3f64.sqrt()).unwrap();
            // The seam is kept (a meridian of split vertices), nothing turns over, and the
            // UVs name points near their vertices (the spheres' faces are flat; the most
            // at the poles, where the longitude is no coordinate).
            assert!(t.seam_vertices >= 15, "turn {turn}: {t:?}");
            assert_eq!(t.uv_flipped + t.uv_degenerate, 0, "turn {turn}: {t:?}");
            assert!(t.distortion_mean_pct < mean_pct, "turn {turn}: {t:?}");
            assert!(t.distortion_max_pct < max_pct, "turn {turn}: {t:?}");
        }
    }

    /// A plane grid with UVs swirled about its middle: each point's (x, y) turned by
    /// `twist` radians per unit of its distance from the middle.
    fn swirled(n: u32, twist: f64) -> Mesh {
        let m = coarsen_shapes::plane_grid(n, n, 2.0).unwrap();
        let mid = m.positions.iter().sum::<DVec3>() / m.n_vertices() as f64;
        let uv = m
            .faces
            .iter()
            .flatten()
            .map(|&v| {
                let p = m.positions[v as usize] - mid;
                let (s, c) = (twist * p.truncate().length()).sin_cos();
                DVec2::new(c * p.x - s * p.y, s * p.x + c * p.y)
            })
            .collect();
        let mut cols = coarsen_mesh::Attributes::default();
        cols.insert("uv", AttrValues::Vec2(uv));
        let wedges = Wedges::from_corners(&m.faces, cols);
        Mesh { wedges, ..m }
    }

    #[test]
    fn faces_laid_turned_over_where_the_uvs_swirl_are_mended() {
        // Coarse faces over UVs that turn faster than the faces are wide: laid as they
        // fall, some are turned over in UV space.
        let input = swirled(80, 2.0);
        let mesh = coarsen_shapes::plane_grid(8, 8, 2.0).unwrap();
        let stage = |mend| {
            let mut report = StageReport::default();
            let mut cx = Context::new(&input, &mut report);
            let out = TextureStage::new(TextureParams { mend })
                .run(mesh.clone(), &mut cx)
                .unwrap();
            (out, report)
        };
        let count = |r: &StageReport, k: &str| r.get(k).and_then(|x| x.as_u64()).unwrap();
        let texture = |m: &Mesh| {
            let t = coarsen_metrics::texture(&input, m, 2.0 * 2f64.sqrt()).unwrap();
            (t.uv_flipped + t.uv_degenerate) as u64
        };
        let (plain, before) = stage(false);
        let turned = count(&before, "uv_turned_over");
        assert!(turned > 0, "nothing to mend");
        assert_eq!(texture(&plain), turned);
        assert_eq!(plain.faces, mesh.faces);
        let (out, after) = stage(true);
        assert_eq!(count(&after, "uv_turned_over"), 0);
        assert_eq!(texture(&out), 0);
        assert!(count(&after, "uv_flips_mended") > 0 && count(&after, "uv_moves_mended") > 0);
        // Still a manifold sheet with its boundary, its vertices on the input, facing up,
        // no angle under the floor that was not there.
        out.wedges.check(&out.faces).unwrap();
        let v = coarsen_metrics::validity(Some(&mesh), &out).unwrap();
        assert!(
            v.manifold && v.n_boundary_loops == 1 && v.n_components == 1,
            "{v:?}"
        );
        assert!(out.positions.iter().all(|p| p.z == 0.0));
        assert!((0..out.n_faces()).all(|f| out.face_normal(f).z > 0.99));
        let q = |m: &Mesh| coarsen_metrics::quality(m).unwrap().alpha_min_deg;
        assert!(
            q(&out) >= q(&plain).min(30.0) - 1e-9,
            "{} {}",
            q(&out),
            q(&plain)
        );
    }

    #[test]
    fn each_face_takes_the_material_under_it() {
        // Two materials by hemisphere, no UVs; the remeshed sphere lost the column.
        let band = |z: f64| u32::from(z > 0.0);
        let mut input = coarsen_shapes::icosphere(1.0, 4).unwrap();
        let material = (0..input.n_faces())
            .map(|f| {
                band(
                    input.faces[f]
                        .iter()
                        .map(|&v| input.positions[v as usize].z)
                        .sum(),
                )
            })
            .collect();
        input
            .face_attrs
            .insert(MATERIAL, AttrValues::Label(material));
        let mesh = turned_sphere(0.1);
        let (out, report) = run(&input, mesh.clone());
        assert_eq!(report.get("materials_laid"), Some(&true.into()));
        assert_eq!(report.get("textured"), Some(&false.into()));
        assert_eq!((&out.positions, &out.faces), (&mesh.positions, &mesh.faces));
        let laid = out.face_attrs.label(MATERIAL).expect("materials laid");
        let right = (0..out.n_faces())
            .filter(|&f| {
                let z: f64 = out.faces[f]
                    .iter()
                    .map(|&v| out.positions[v as usize].z)
                    .sum();
                laid[f] == band(z)
            })
            .count();
        assert_eq!(right, out.n_faces());
        // A mesh that kept its own column keeps it.
        let mut own = mesh.clone();
        own.face_attrs
            .insert(MATERIAL, AttrValues::Label(vec![7; own.n_faces()]));
        let (kept, _) = run(&input, own.clone());
        assert_eq!(kept, own);
    }

    #[test]
    fn without_per_corner_attributes_the_mesh_passes_unchanged() {
        let input = coarsen_shapes::icosphere(1.0, 2).unwrap();
        let mesh = turned_sphere(0.1);
        let (out, report) = run(&input, mesh.clone());
        assert_eq!(out, mesh);
        assert_eq!(report.get("textured"), Some(&false.into()));
    }

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config {
            cases: 24,
            rng_seed: proptest::test_runner::RngSeed::Fixed(0x7E47_0000_0000_0048),
            ..proptest::test_runner::Config::default()
        })]

        /// Any charts on the input, any surface to lay them on: every corner gets a value
        /// and the wedges are valid.
        #[test]
        fn any_charts_on_any_surface_give_valid_wedges(
            charts in 1u32..30,
            stride in 1u32..97,
            turn in 0.0f64..6.3,
            levels in 1u32..4,
        ) {
            let input = coarsen_shapes::with_uv_islands(
                coarsen_shapes::icosphere(1.0, 3).unwrap(),
                charts,
                stride,
            );
            let mesh = turned(coarsen_shapes::icosphere(1.1, levels).unwrap(), turn);
            let (out, _) = run(&input, mesh.clone());
            let uv = out.corner_column("uv");
            proptest::prop_assert!(uv.is_some());
            out.wedges.check(&out.faces).unwrap();
            // Mending keeps the surface: the same vertices, still a closed sphere.
            proptest::prop_assert_eq!(out.n_vertices(), mesh.n_vertices());
            proptest::prop_assert_eq!(out.n_faces(), mesh.n_faces());
            let v = coarsen_metrics::validity(None, &out).unwrap();
            proptest::prop_assert!(v.manifold && v.genus == Some(0) && v.n_degenerate == 0);
        }

        /// Swirled UVs of any strength under a grid of any size: whatever mending does
        /// leaves a manifold sheet facing up, and no more turned faces than it found.
        #[test]
        fn mending_keeps_the_sheet_and_never_adds_turned_faces(
            twist in 0.0f64..16.0,
            n in 2u32..14,
            turn in 0.0f64..0.8,
        ) {
            let input = swirled(40, twist);
            let mesh = turned(coarsen_shapes::plane_grid(n, n, 1.8).unwrap(), turn);
            let mut report = StageReport::default();
            let mut cx = Context::new(&input, &mut report);
            let plain = TextureStage::new(TextureParams { mend: false })
                .run(mesh.clone(), &mut cx)
                .unwrap();
            let before = report.get("uv_turned_over").and_then(|x| x.as_u64()).unwrap();
            let (out, after) = run(&input, mesh.clone());
            let left = after.get("uv_turned_over").and_then(|x| x.as_u64()).unwrap();
            proptest::prop_assert!(left <= before, "{} > {}", left, before);
            proptest::prop_assert_eq!(plain.faces.len(), out.faces.len());
            out.wedges.check(&out.faces).unwrap();
            let v = coarsen_metrics::validity(Some(&mesh), &out).unwrap();
            proptest::prop_assert!(v.manifold && v.n_boundary_loops == 1 && v.n_degenerate == 0);
            proptest::prop_assert!((0..out.n_faces()).all(|f| out.face_normal(f).z > 0.0));
        }
    }
}
