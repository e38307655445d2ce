//! The `postprocess` stage (paper 1, "Post-process"): the coarse mesh M_c is uniformly
//! subdivided 1-to-4 `times` times, clustered again into n = |V(M_c)| regions with the CVT
//! clusterer, triangulated with the dual again, and — with `project` — every vertex is pulled
//! onto the nearest point of the run's input surface (a vertex of the output's boundary
//! onto the input's boundary, along the loop of the nearest coarse boundary vertex), so the
//! resampling does not drift from the original. It reuses the `subdivide`/refine split,
//! `cluster.cvt` and `dual` crates; it copies none of them. With `fold_guard` the
//! re-clustering and the dual's repairs keep clusters off the far side of thin sheets (see
//! `cluster.cvt`).
//!
//! When the finest clustering has no valid dual that its repairs can reach, the coarse mesh
//! is returned as it came, with a warning and the report figure `kept_coarse`. The report's
//! `projected_vertices` counts the vertices the projection moved and `boundary_left` the
//! boundary vertices it left off the input's boundary (where the move would spoil a face;
//! a later `relax` may still move them onto it).

use coarsen_mesh::{DVec3, Topology};
use coarsen_stage::{
    AttrValues, Context, Contract, Domain, Mesh, Needs, ParamIssue, Params, Stage, StageError,
    params,
};
use coarsen_stage_cvt::{CvtParams, EnergyKind, Start};
use coarsen_stage_dual::{Placement, Pull, pull_onto_input};
use rayon::prelude::*;

params! {
    /// Parameters of `postprocess`.
    pub struct PostprocessParams {
        /// Uniform 1-to-4 subdivisions of the coarse mesh before re-clustering (paper 1: 3).
        pub times: u32 = 3,
        /// Energy of the re-clustering: "shu2009" or "valette2004".
        pub energy: EnergyKind = EnergyKind::Shu2009,
        /// Exponent r of "shu2009" (paper 1 uses the main clustering's r).
        pub r: f64 = 2.0,
        /// Seed of the re-clustering's initial regions.
        pub seed: u64 = 1,
        /// At most this many clustering passes.
        pub max_passes: u32 = 200,
        /// Where each cluster's vertex goes: "closest-vertex", "centroid", "projected" or "quadric".
        pub placement: Placement = Placement::Projected,
        /// Pull every output vertex onto the nearest point of the run's input surface (its
        /// boundary for boundary vertices).
        pub project: bool = true,
        /// Stop the finest level's re-clustering after a pass that lowers the energy by less
        /// than this fraction (coarser levels: a tenth of it).
        pub tolerance: f64 = 1e-3,
        /// Subdivide fewer times rather than pass this many faces.
        pub max_faces: u64 = 8_000_000,
        /// Keep the re-clustering's clusters from wrapping round thin sheets (as `cluster.cvt`'s `fold_guard`).
        pub fold_guard: bool = false,
    }
}

impl Params for PostprocessParams {
    fn validate(&self) -> Vec<ParamIssue> {
        let mut v = Vec::new();
        coarsen_stage::params::check_range(&mut v, "times", self.times, 0, 6);
        coarsen_stage::params::check_range(&mut v, "r", self.r, 0.0, 16.0);
        coarsen_stage::params::check_range(&mut v, "max_passes", self.max_passes, 1, 100_000);
        coarsen_stage::params::check_range(&mut v, "tolerance", self.tolerance, 0.0, 1.0);
        coarsen_stage::params::check_range(&mut v, "max_faces", self.max_faces, 1, 1 << 31);
        v
    }
}

/// The `postprocess` stage.
pub struct Postprocess(PostprocessParams);

impl Stage for Postprocess {
    type Params = PostprocessParams;
    const KIND: &'static str = "postprocess";
    const SUMMARY: &'static str = "Paper 1's post-process: subdivide, re-cluster into as many regions as vertices, dual again, project onto the input.";

    fn new(params: PostprocessParams) -> Self {
        Postprocess(params)
    }

    fn contract(&self) -> Contract {
        Contract {
            clears: vec![Domain::Face],
            needs: Needs {
                manifold: true,
                ..Default::default()
            },
            ..Default::default()
        }
    }

    fn run(&self, mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        let coarse = mesh.clone();
        // The coarse mesh's adjacency, which the runner's manifold check built.
        let coarse_topo = cx.topology(&coarse).ok();
        let coarse_rim = boundary_points(&coarse, coarse_topo.as_deref());
        // 1–2. Subdivide and re-cluster into n regions, level by level.
        let mut levels = self.recluster(mesh, &coarse, coarse_topo.as_deref(), cx)?;
        // 3. Dual again, placed on the input when projecting onto it.
        let facing = self.input_facing(cx)?;
        let Some(dual) = self.dual_again(&mut levels, facing.as_ref(), cx)? else {
            return Ok(coarse);
        };
        let mut out = dual.mesh;
        // 4. Pull onto the input surface.
        let projected = match &facing {
            Some(facing) => project(&mut out, &coarse_rim, facing, cx)?,
            None => coarsen_stage_dual::Pulled::default(),
        };
        report(cx, &levels, &dual.stats, &projected);
        Ok(out)
    }
}

/// The finest level's clustering and how the levels went.
struct Levels {
    /// The finest subdivision.
    fine: Mesh,
    /// Its faces' clusters.
    labels: Vec<u32>,
    /// Its adjacency, when the last level kept it.
    topo: Option<Topology>,
    /// Subdivisions made.
    done: u32,
    /// Clustering passes per level.
    passes: Vec<usize>,
    /// The finest level's clustering log.
    log: coarsen_stage_cvt::PassLog,
    /// Every level's energy after each pass, coarsest first (for the report's plots).
    energy_per_level: Vec<Vec<f64>>,
    /// Every level's moved faces in each pass, coarsest first.
    moves_per_level: Vec<Vec<u64>>,
}

impl Postprocess {
    /// Subdivides `mesh` (the coarse mesh, with adjacency `coarse_topo`) and re-clusters
    /// it into as many regions as it has vertices, level by level: the first level starts
    /// from the dual cells of the coarse vertices, each finer one from the clustering of
    /// the level before carried to the child faces, so the global arrangement settles
    /// where faces are few and the fine levels only polish borders.
    fn recluster(
        &self,
        mesh: Mesh,
        coarse: &Mesh,
        coarse_topo: Option<&Topology>,
        cx: &mut Context<'_>,
    ) -> Result<Levels, StageError> {
        let p = &self.0;
        let n = mesh.n_vertices();
        let mut fine = mesh;
        fine.face_attrs.insert(
            COARSE_FACE,
            AttrValues::Label((0..coarse.n_faces() as u32).collect()),
        );
        let mut cvt = CvtParams {
            energy: p.energy,
            r: p.r,
            seed: p.seed,
            max_passes: p.max_passes,
            fold_guard: p.fold_guard,
            ..Default::default()
        };
        let mut done = 0;
        let mut passes = Vec::new();
        let (mut energy_per_level, mut moves_per_level) = (Vec::new(), Vec::new());
        let mut log = None;
        // Each level's adjacency, derived from the one before where the split is uniform
        // (the first from the coarse mesh's).
        let mut level_topo: Option<Topology> = None;
        let mut derived = None;
        for _ in 0..p.times.max(1) {
            if done < p.times {
                if (fine.n_faces() as u64).saturating_mul(4) > p.max_faces {
                    cx.report.warn(format!(
                        "subdivided {done} of {} times: another would pass max_faces = {}",
                        p.times, p.max_faces
                    ));
                    if done > 0 {
                        break;
                    }
                } else {
                    let before = level_topo.take();
                    let topo = before.as_ref().or(coarse_topo);
                    // The finest level's readers (the clusterer, the dual) never ask for
                    // the vertex neighbours.
                    let (next, topo) = subdivide(&fine, topo, done + 1 == p.times)?;
                    derived = topo;
                    fine = next;
                    done += 1;
                }
            }
            // A finer level starts from the level before's clustering, carried to the
            // child faces by the split; the first from the dual cells.
            let start = match (fine.face_attrs.remove(CLUSTER), log.is_some()) {
                (Some(AttrValues::Label(l)), true) => Start::Carried(l),
                (Some(AttrValues::Label(l)), false) => Start::Labels(l),
                _ => Start::Labels(dual_cells(coarse, &fine, done)),
            };
            // The coarse faces are only needed for the dual cells of the first level: the
            // finer levels need not carry them.
            fine.face_attrs.remove(COARSE_FACE);
            let topo = match derived.take() {
                Some(t) => t,
                None => Topology::try_build(&fine).map_err(|e| StageError::Input(e.to_string()))?,
            };
            // Coarse levels settle the arrangement (ten times tighter; they are cheap); the
            // finest only polishes, and stops at `tolerance`.
            cvt.tolerance = if done >= p.times {
                p.tolerance
            } else {
                0.1 * p.tolerance
            };
            let clustering = cluster_level(&fine, &topo, start, n, &cvt, done, cx)?;
            passes.push(clustering.log.moves.len());
            energy_per_level.push(clustering.log.energy.clone());
            moves_per_level.push(clustering.log.moves.clone());
            fine.face_attrs
                .insert(CLUSTER, AttrValues::Label(clustering.labels));
            log = Some(clustering.log);
            level_topo = Some(topo);
            if done == p.times || done == 0 {
                break;
            }
        }
        fine.face_attrs.remove(COARSE_FACE);
        let Some(AttrValues::Label(labels)) = fine.face_attrs.remove(CLUSTER) else {
            return Err(StageError::Internal(format!(
                "`{}`: the clustering was lost",
                Self::KIND
            )));
        };
        Ok(Levels {
            fine,
            labels,
            topo: level_topo,
            done,
            passes,
            log: log.unwrap_or_default(),
            energy_per_level,
            moves_per_level,
        })
    }

    /// The flipped-face test on the run's input, whose index the dual's placement and the
    /// projection share; `None` without projection.
    fn input_facing<'a>(
        &self,
        cx: &Context<'a>,
    ) -> Result<Option<coarsen_metrics::Facing<'a>>, StageError> {
        if !(self.0.project && cx.original.n_faces() > 0) {
            return Ok(None);
        }
        let index = cx
            .input_index_with_topology(coarsen_metrics::SurfaceIndex::with_topology)
            .map_err(|e| StageError::Input(format!("`{}`: the input: {e}", Self::KIND)))?;
        Ok(Some(coarsen_metrics::Facing::with_index(
            cx.original,
            index,
        )))
    }

    /// The dual of the finest clustering; `None` (said in a warning and the figure
    /// `kept_coarse`) when it has no valid dual that the repairs can reach: the coarse
    /// mesh is a valid result already, and a fine clustering without a dual (e.g.
    /// clusters of a few tiny faces whose vertices fall in a row) leaves it as it came
    /// rather than failing the run.
    fn dual_again(
        &self,
        levels: &mut Levels,
        facing: Option<&coarsen_metrics::Facing<'_>>,
        cx: &mut Context<'_>,
    ) -> Result<Option<coarsen_stage_dual::Dual>, StageError> {
        let p = &self.0;
        let topo = match levels.topo.take() {
            Some(t) => t,
            None => {
                Topology::try_build(&levels.fine).map_err(|e| StageError::Input(e.to_string()))?
            }
        };
        let repair = coarsen_stage_dual::Repair {
            max_rounds: 40,
            relax_passes: 8,
            fold_guard: p.fold_guard,
        };
        let fine = &levels.fine;
        let labels = &mut levels.labels;
        match coarsen_stage_dual::dual(fine, &topo, labels, p.placement, facing, repair, true) {
            Ok(d) => Ok(Some(d)),
            Err(e @ coarsen_stage_dual::DualError::Unrepaired(_)) => {
                cx.report.warn(format!(
                    "the re-clustered mesh has no valid dual ({e}): the coarse mesh is kept as it came"
                ));
                cx.report.figure("kept_coarse", true);
                Ok(None)
            }
            Err(e @ coarsen_stage_dual::DualError::TooFew(_)) => Err(StageError::Param {
                name: "target",
                message: format!("`{}`: {e}", Self::KIND),
            }),
            Err(e) => Err(StageError::Input(format!("`{}`: {e}", Self::KIND))),
        }
    }
}

/// The positions of `coarse`'s boundary vertices (`topo`: its adjacency, if at hand). They
/// lie on the input's boundary (the dual before put them there): the projection of the
/// output's boundary starts from them.
fn boundary_points(coarse: &Mesh, topo: Option<&Topology>) -> Vec<DVec3> {
    match topo {
        Some(t) => (0..coarse.n_vertices() as u32)
            .filter(|&v| t.is_boundary_vertex(v))
            .map(|v| coarse.positions[v as usize])
            .collect(),
        None => Vec::new(),
    }
}

/// `fine` split uniformly once more (reading the adjacency `topo` when at hand), and the
/// split's adjacency derived from it when it can be (`lean`: without the vertex
/// neighbours).
fn subdivide(
    fine: &Mesh,
    topo: Option<&Topology>,
    lean: bool,
) -> Result<(Mesh, Option<Topology>), StageError> {
    let all = vec![true; fine.n_faces()];
    let next = coarsen_stage_refine::split_once_with(fine, &all, topo)
        .map_err(|e| StageError::Input(e.to_string()))?
        .0;
    let derived = topo.and_then(|t| match lean {
        true => t.of_split_lean(fine, &next),
        false => t.of_split(fine, &next),
    });
    Ok((next, derived))
}

/// One level's clustering of `fine` (adjacency `topo`) into `n` regions from `start`, its
/// passes told to the run's progress.
fn cluster_level(
    fine: &Mesh,
    topo: &Topology,
    start: Start,
    n: usize,
    cvt: &CvtParams,
    done: u32,
    cx: &Context<'_>,
) -> Result<coarsen_stage_cvt::Clustering, StageError> {
    let progress = cx.progress;
    progress.begin(Postprocess::KIND, u64::from(cvt.max_passes));
    let clustering =
        coarsen_stage_cvt::cluster_from(fine, topo, start, n, cvt, None, |pass, moves, energy| {
            progress.advance(
                u64::from(pass),
                &format!("level {done}: {moves} moves, energy {energy:.4e}"),
            );
        })
        .map_err(|e| StageError::Input(format!("`{}`: {e}", Postprocess::KIND)))?;
    progress.end();
    Ok(clustering)
}

/// Pulls `out` onto the input surface, the vertices of its boundary onto the input's
/// boundary from the coarse boundary vertices `rim`, which lie on it (the dual put them on
/// the subdivided coarse boundary, whose edges cut across the input's bays); moves that
/// would spoil a face are undone, and all of them (with a warning) when the projection
/// would degenerate faces.
fn project(
    out: &mut Mesh,
    rim: &[DVec3],
    facing: &coarsen_metrics::Facing<'_>,
    cx: &mut Context<'_>,
) -> Result<coarsen_stage_dual::Pulled, StageError> {
    let topo = Topology::try_build(out)
        .map_err(|e| StageError::Internal(format!("`{}`: {e}", Postprocess::KIND)))?;
    let pull = Pull {
        rim,
        interior: true,
        min_move: 0.0,
    };
    let diag2 = cx.original.bbox().diagonal().powi(2);
    Ok(match pull_onto_input(out, &topo, facing, pull, diag2) {
        Some(p) => p,
        None => {
            cx.report.warn(
                "projection onto the input would degenerate faces: vertices left where the dual put them",
            );
            coarsen_stage_dual::Pulled::default()
        }
    })
}

/// The stage's figures.
fn report(
    cx: &mut Context<'_>,
    levels: &Levels,
    stats: &coarsen_stage_dual::DualStats,
    projected: &coarsen_stage_dual::Pulled,
) {
    let (r, log) = (&mut *cx.report, &levels.log);
    r.figure("subdivisions", levels.done);
    r.figure("fine_faces", levels.fine.n_faces());
    r.figure("passes_per_level", &levels.passes);
    r.figure("passes", log.moves.len());
    r.figure("initial_energy", log.initial_energy);
    r.figure("moves_per_pass", &log.moves);
    r.figure("energy_per_pass", &log.energy);
    r.figure("energy_per_pass_per_level", &levels.energy_per_level);
    r.figure("moves_per_pass_per_level", &levels.moves_per_level);
    r.figure("repairs", stats.repairs);
    r.figure("restarted", stats.restarted);
    r.figure("projected_vertices", projected.moved);
    r.figure("boundary_left", projected.boundary_left);
}

/// Face label naming each fine face's coarse face while the stage runs.
const COARSE_FACE: &str = "postprocess.coarse_face";

/// Face label carrying the clustering of one level to the next while the stage runs.
const CLUSTER: &str = "postprocess.cluster";

/// The clustering of `fine` (a 1-to-4 subdivision of `coarse`, `times` deep, whose faces
/// carry [`COARSE_FACE`]) into the dual cells of the coarse vertices: each fine face goes to
/// the corner of its coarse face nearest in barycentric terms (ties to the lower index).
/// Without subdivision every coarse vertex would not get a face: then it returns nothing,
/// and the clusterer seeds afresh.
fn dual_cells(coarse: &Mesh, fine: &Mesh, times: u32) -> Vec<u32> {
    let Some(parent) = fine.face_attrs.label(COARSE_FACE) else {
        return Vec::new();
    };
    if times == 0 {
        return Vec::new();
    }
    (0..fine.n_faces())
        .into_par_iter()
        .map(|t| {
            let f = coarse.faces[parent[t] as usize];
            let [a, b, c] = f.map(|v| coarse.positions[v as usize]);
            let w = coarsen_geom::triangle::barycentric(fine.face_centroid(t), a, b, c);
            let mut best = 0;
            for i in 1..3 {
                if w[i] > w[best] || (w[i] == w[best] && f[i] < f[best]) {
                    best = i;
                }
            }
            f[best]
        })
        .collect()
}

coarsen_stage::export_stage!(Postprocess);

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_stage::StageReport;

    /// Runs the stage on `coarse` against `original`; checks that the output keeps the
    /// vertex count and is an oriented manifold, and gives its summary and the report.
    fn run_checked(
        original: &Mesh,
        coarse: &Mesh,
        p: PostprocessParams,
    ) -> (Mesh, coarsen_mesh::TopologySummary, StageReport) {
        let mut report = StageReport::default();
        let out = Postprocess::new(p)
            .run(coarse.clone(), &mut Context::new(original, &mut report))
            .unwrap();
        assert_eq!(out.n_vertices(), coarse.n_vertices());
        let t = Topology::build(&out).summary(&out);
        assert!(t.manifold && t.consistently_oriented, "{t:?}");
        (out, t, report)
    }

    /// `fold_guard` reaches the re-clustering: on a sheet thinner than a cluster it changes
    /// the result, which stays a closed manifold of the coarse mesh's vertex count.
    #[test]
    fn the_fold_guard_reaches_the_reclustering() {
        let flat = |subdivisions| {
            let mut m = coarsen_shapes::icosphere(1.0, subdivisions).unwrap();
            m.positions.iter_mut().for_each(|p| p.z *= 0.02);
            m
        };
        let (original, coarse) = (flat(4), flat(2));
        let run = |fold_guard| {
            let p = PostprocessParams {
                times: 2,
                energy: EnergyKind::Valette2004,
                r: 0.0,
                fold_guard,
                ..Default::default()
            };
            let (out, t, _) = run_checked(&original, &coarse, p);
            assert_eq!((t.n_boundary_loops, t.genus_total), (0, Some(0)));
            out
        };
        assert_ne!(run(false).positions, run(true).positions);
    }

    #[test]
    fn postprocess_keeps_the_vertex_count_and_topology_and_improves_shapes() {
        let original = coarsen_shapes::torus(2.0, 0.6, 60, 30).unwrap();
        // A poor coarse mesh: long thin triangles (many segments around, few across).
        let coarse = coarsen_shapes::torus(2.0, 0.6, 90, 6).unwrap();
        let p = PostprocessParams {
            times: 2,
            ..Default::default()
        };
        let (out, t, report) = run_checked(&original, &coarse, p);
        assert_eq!(t.genus_total, Some(1));
        let min_angle = |m: &Mesh| {
            (0..m.n_faces())
                .map(|f| {
                    let [a, b, c] = m.corners(f);
                    coarsen_geom_min_angle(a, b, c)
                })
                .fold(f64::INFINITY, f64::min)
        };
        assert!(
            min_angle(&out) > min_angle(&coarse),
            "{} vs {}",
            min_angle(&out),
            min_angle(&coarse)
        );
        assert!(report.get("projected_vertices").is_some());
    }

    /// A flat unit disk: a centre and `rings` rings of `segments` vertices each.
    fn disk(rings: u32, segments: u32) -> Mesh {
        let mut positions = vec![coarsen_mesh::DVec3::ZERO];
        for k in 1..=rings {
            let r = f64::from(k) / f64::from(rings);
            for i in 0..segments {
                let a = std::f64::consts::TAU * f64::from(i) / f64::from(segments);
                positions.push(coarsen_mesh::DVec3::new(r * a.cos(), r * a.sin(), 0.0));
            }
        }
        let id = |k: u32, i: u32| {
            if k == 0 {
                0
            } else {
                1 + (k - 1) * segments + i % segments
            }
        };
        let mut faces = Vec::new();
        for i in 0..segments {
            faces.push([0, id(1, i), id(1, i + 1)]);
        }
        for k in 1..rings {
            for i in 0..segments {
                faces.push([id(k, i), id(k + 1, i), id(k + 1, i + 1)]);
                faces.push([id(k, i), id(k + 1, i + 1), id(k, i + 1)]);
            }
        }
        Mesh::new(positions, faces)
    }

    #[test]
    fn boundary_vertices_end_on_the_input_boundary() {
        // The coarse disk's rim is a 12-gon whose edges cut inside the input's 120-gon:
        // the dual puts the rim's vertices on the subdivided 12-gon, where the nearest
        // point of the (flat) input surface is the point itself.
        let original = disk(20, 120);
        let coarse = disk(4, 12);
        let mut report = StageReport::default();
        let out = Postprocess::new(PostprocessParams::default())
            .run(coarse.clone(), &mut Context::new(&original, &mut report))
            .unwrap();
        assert_eq!(out.n_vertices(), coarse.n_vertices());
        let topo = Topology::build(&out);
        let rim: Vec<u32> = (0..out.n_vertices() as u32)
            .filter(|&v| topo.is_boundary_vertex(v))
            .collect();
        assert!(rim.len() >= 3, "{} boundary vertices", rim.len());
        let segments: Vec<[coarsen_mesh::DVec3; 2]> = (0..120)
            .map(|i| {
                [
                    original.positions[2281 + i],
                    original.positions[2281 + (i + 1) % 120],
                ]
            })
            .collect();
        for v in rim {
            let p = out.positions[v as usize];
            let d = segments
                .iter()
                .map(|&[a, b]| {
                    coarsen_spatial::closest_point_on_segment(p, a, b)
                        .0
                        .distance(p)
                })
                .fold(f64::INFINITY, f64::min);
            assert!(
                d < 1e-12,
                "boundary vertex {v} at {p} is {d} from the input boundary"
            );
        }
    }

    fn coarsen_geom_min_angle(
        a: coarsen_mesh::DVec3,
        b: coarsen_mesh::DVec3,
        c: coarsen_mesh::DVec3,
    ) -> f64 {
        let ang = |u: coarsen_mesh::DVec3, v: coarsen_mesh::DVec3| u.angle_between(v);
        ang(b - a, c - a)
            .min(ang(c - b, a - b))
            .min(ang(a - c, b - c))
    }
}
