//! The `cluster.cvt` stage: centroidal Voronoi face clustering (paper 1 "Our face
//! clustering method", after Valette & Chassery 2004), the first half of CVT coarsening.
//!
//! The faces are partitioned into n connected clusters minimising an [`Energy`]:
//!
//! * `energy = "shu2009"` — paper 1's Eq.(7), E⁽³⁾ = Σᵢ mᵢʳ (Σ‖yₜ‖² − ‖Σyₜ‖²/mᵢ), with
//!   mᵢ the face count of cluster i and exponent `r` (r = 0 is the uniform case);
//! * `energy = "valette2004"` — Eq.(1) on faces, masses wₜ = ρ(yₜ)·sₜ (area times the
//!   mean of the vertex scalar `density` over the face's corners, 1 when none is named).
//!
//! | parameter | default | meaning |
//! | --- | --- | --- |
//! | `clusters` | `0` | cluster count; 0 takes the run's target as a vertex count (the dual has one vertex per cluster) |
//! | `energy` | `"shu2009"` | `"shu2009"` or `"valette2004"` |
//! | `r` | `2` | exponent of `shu2009` |
//! | `density` | `""` | vertex scalar used as density ρ by `valette2004` (none when empty) |
//! | `seed` | `1` | seed of the SplitMix64 that picks the seed faces |
//! | `max_passes` | `200` | most passes of the minimisation |
//! | `tolerance` | `0` | stop after a pass lowering the energy by less than this fraction |
//! | `fold_guard` | `false` | refuse moves into a cluster whose summed area vector points more than 90° away from the face's normal |
//!
//! 1. **Seeds**: every connected component gets one seed face, the rest are shared in
//!    proportion to the components' masses; within a component the faces are ordered along
//!    a Morton curve of their centroids (on meshes of 2²⁰ faces or more: vertices along the
//!    curve of their positions, faces by their first corner on it) and one seed is drawn
//!    in each equal-mass stretch (jittered by SplitMix64 from `seed`), then grown
//!    breadth-first until every face belongs to a cluster (on meshes of 2²⁰ faces or more
//!    each block of 2¹⁹ faces along the curve from its own seeds, in parallel, then the
//!    faces left from the regions next to them).
//! 2. **Minimisation** (the ACVD loop, over faces): each pass sweeps the faces on cluster
//!    borders in index order (on meshes of 2²⁰ faces or more the clusterer renumbers faces
//!    and vertices along that curve, so the faces a test reads lie close in memory, and
//!    sweeps in that order; labels come back in the mesh's numbering); a face is tested
//!    only when its cluster or a neighbouring one
//!    changed in the current or previous pass. Its move to each neighbouring cluster is
//!    priced in O(1) from the clusters' running sums and the best improving one kept. A
//!    move is refused when it would empty the donor cluster, split it or pinch it (paper
//!    1's "cluster separation detection": the donor's faces must form at most one arc
//!    around each corner of the moved face), or when the receiving cluster would close a
//!    loop or touch itself at a corner. With `fold_guard` (beyond both papers), a move is
//!    also refused when the face's normal points more than 90° away from the receiving
//!    cluster's summed area vector: a cluster then cannot grow round the rim of a sheet
//!    thinner than itself (an ear) onto the far side, where its dual vertex would sit
//!    between the two sides. A move activates the face's neighbours.
//!    On meshes of 20,000 faces or more the clusters are split into 8 parts along the
//!    Morton curve, swept in parallel, and the faces on the borders between parts after
//!    them in one thread: the same result on any number of threads (see `sweep.rs`).
//! 3. Stops after a pass without moves, after `max_passes`, or after a pass that lowers the
//!    energy by less than `tolerance` times its value.
//!
//! Output: the face label `cluster` (`0..n`); every cluster is non-empty and connected.
//! The report gives `clusters`, `passes`, `moves`, `moves_per_pass`, `energy_per_pass`
//! (normalised coordinates: centred, unit bounding-box diagonal), `initial_energy` and
//! `refused`.
//!
//! ```
//! use coarsen_stage::{Context, Stage, StageReport};
//! use coarsen_stage_cvt::{ClusterCvt, CvtParams};
//! let sphere = coarsen_shapes::icosphere(1.0, 3).unwrap();
//! let mut report = StageReport::default();
//! let mut cx = Context::new(&sphere, &mut report);
//! let params = CvtParams { clusters: 50, ..CvtParams::default() };
//! let out = ClusterCvt::new(params).run(sphere.clone(), &mut cx)?;
//! let labels = out.face_attrs.label("cluster").unwrap();
//! assert_eq!(labels.iter().max(), Some(&49));
//! # Ok::<(), coarsen_stage::StageError>(())
//! ```

pub mod energy;
pub mod engine;
mod sweep;

pub use energy::{Energy, FacePoint, Shu2009, Sums, Valette2004};
pub use engine::{
    ClusterError, Clusterer, PassLog, cluster_centroids, face_neighbors, faces_by_cluster,
};

use coarsen_mesh::Topology;
use coarsen_stage::params::check_range;
use coarsen_stage::{
    AttrKind, AttrValues, Context, Contract, Mesh, Needs, ParamIssue, Params, Stage, StageError,
    params,
};
use coarsen_stage::{AttrRef, StageReport};
use serde::{Deserialize, Serialize};

/// Name of the face label the stage writes.
pub const CLUSTER: &str = "cluster";

/// Which energy the clustering minimises.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum EnergyKind {
    /// Paper 1's E⁽³⁾ with exponent `r`.
    #[default]
    Shu2009,
    /// Valette & Chassery 2004, area-weighted (times an optional density).
    Valette2004,
}

params! {
    /// Parameters of `cluster.cvt`.
    pub struct CvtParams {
        /// Number of clusters; 0 takes the run's target, as a vertex count.
        pub clusters: u64 = 0,
        /// Energy: "shu2009" (paper 1's E⁽³⁾ with exponent r) or "valette2004" (area-weighted).
        pub energy: EnergyKind = EnergyKind::Shu2009,
        /// Exponent r of "shu2009" on the cluster's face count (0 = uniform).
        pub r: f64 = 2.0,
        /// Vertex scalar used as density by "valette2004"; empty for none.
        pub density: String = String::new(),
        /// Seed of the generator that picks the seed faces.
        pub seed: u64 = 1,
        /// Most passes of the minimisation.
        pub max_passes: u32 = 200,
        /// Stop after a pass that lowers the energy by less than this fraction (0: only when nothing moves).
        pub tolerance: f64 = 0.0,
        /// Refuse moves of a face into a cluster whose faces, summed, face more than 90° away from it (keeps clusters from wrapping round thin sheets).
        pub fold_guard: bool = false,
    }
}

impl Params for CvtParams {
    fn validate(&self) -> Vec<ParamIssue> {
        let mut issues = Vec::new();
        check_range(&mut issues, "r", self.r, 0.0, 16.0);
        check_range(&mut issues, "clusters", self.clusters, 0, u32::MAX as u64);
        check_range(&mut issues, "tolerance", self.tolerance, 0.0, 1.0);
        if !self.density.is_empty() && self.energy != EnergyKind::Valette2004 {
            issues.push(ParamIssue::new(
                "density",
                "only energy = \"valette2004\" uses a density",
            ));
        }
        issues
    }
}

/// Result of [`cluster`]: the labels and the minimisation's figures.
#[derive(Clone, Debug, PartialEq)]
pub struct Clustering {
    /// The cluster of every face, `0..n`.
    pub labels: Vec<u32>,
    /// Number of clusters.
    pub n: usize,
    /// Passes, moves and energies.
    pub log: PassLog,
}

/// Clusters the faces of `mesh` into `n` connected clusters (seeding and minimisation);
/// `density` is the per-vertex density of `valette2004`. `on_pass(pass, moves, energy)`
/// is called after each pass.
pub fn cluster(
    mesh: &Mesh,
    topo: &Topology,
    n: usize,
    params: &CvtParams,
    density: Option<&[f64]>,
    on_pass: impl FnMut(u32, u64, f64),
) -> Result<Clustering, ClusterError> {
    cluster_from(mesh, topo, Start::Seeds, n, params, density, on_pass)
}

/// Where [`cluster_from`] starts.
#[derive(Clone, Debug, PartialEq)]
pub enum Start {
    /// Fresh seeds, grown into regions.
    Seeds,
    /// A clustering of the mesh (`0..n` per face): taken when every cluster is non-empty
    /// and connected, else fresh seeds.
    Labels(Vec<u32>),
    /// A clustering of the mesh this one is the uniform 1-to-4 split of, carried to the
    /// child faces: connected wherever the coarse one was, so only the labels and the
    /// cluster sizes are checked (the post-process's finer levels).
    Carried(Vec<u32>),
}

/// Like [`cluster`], but starting from `start` (a warm start runs the minimisation from
/// a clustering at hand, e.g. a previous one carried to a finer mesh).
pub fn cluster_from(
    mesh: &Mesh,
    topo: &Topology,
    start: Start,
    n: usize,
    params: &CvtParams,
    density: Option<&[f64]>,
    on_pass: impl FnMut(u32, u64, f64),
) -> Result<Clustering, ClusterError> {
    match params.energy {
        EnergyKind::Shu2009 => {
            let energy = Shu2009 { r: params.r };
            run_from(mesh, topo, start, n, params, &energy, density, on_pass)
        }
        EnergyKind::Valette2004 => {
            run_from(mesh, topo, start, n, params, &Valette2004, density, on_pass)
        }
    }
}

/// [`cluster_from`] with the energy chosen.
#[allow(clippy::too_many_arguments)]
fn run_from<E: Energy>(
    mesh: &Mesh,
    topo: &Topology,
    start: Start,
    n: usize,
    params: &CvtParams,
    energy: &E,
    density: Option<&[f64]>,
    on_pass: impl FnMut(u32, u64, f64),
) -> Result<Clustering, ClusterError> {
    // A warm start (the post-process's levels) runs few passes: no curve layout (see
    // `Clusterer::for_few_passes`), whose copies would also add to the peak memory.
    let (labels, carried) = match start {
        Start::Seeds => (Vec::new(), false),
        Start::Labels(l) => (l, false),
        Start::Carried(l) => (l, true),
    };
    let warm = labels.len() == mesh.n_faces();
    let mut c = match warm {
        true => Clusterer::for_few_passes(mesh, topo, energy, density)?,
        false => Clusterer::new(mesh, topo, energy, density)?,
    };
    let usable = warm
        && c.set_labels(labels, n).is_ok()
        && c.cluster_sums().iter().all(|s| s.count > 0.5)
        && (carried || c.connected_clusters().iter().all(|&k| k));
    debug_assert!(
        !(usable && carried) || c.connected_clusters().iter().all(|&k| k),
        "a carried clustering came out disconnected"
    );
    if !usable {
        c.seed(n, params.seed)?;
    }
    c.set_tolerance(params.tolerance);
    c.set_fold_guard(params.fold_guard);
    let log = c.minimize(params.max_passes, None, on_pass);
    Ok(Clustering {
        labels: c.into_labels(),
        n,
        log,
    })
}

/// Centroidal Voronoi face clustering into the run target's vertex count.
pub struct ClusterCvt(CvtParams);

impl Stage for ClusterCvt {
    type Params = CvtParams;
    const KIND: &'static str = "cluster.cvt";
    const SUMMARY: &'static str = "Centroidal Voronoi face clustering (paper 1, Valette–Chassery 2004): writes face label `cluster`.";

    fn new(params: CvtParams) -> Self {
        ClusterCvt(params)
    }

    fn contract(&self) -> Contract {
        let p = &self.0;
        Contract {
            reads: if p.density.is_empty() {
                Vec::new()
            } else {
                vec![AttrRef::vertex(p.density.clone(), AttrKind::Scalar)]
            },
            writes: vec![AttrRef::face(CLUSTER, AttrKind::Label)],
            clears: Vec::new(),
            needs: Needs {
                target: p.clusters == 0,
                ..Needs::default()
            },
            carries_wedges: false,
            restores_wedges: false,
        }
    }

    fn run(&self, mut mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        let p = &self.0;
        let n = if p.clusters > 0 {
            p.clusters
        } else {
            let t = cx.require_target(Self::KIND)?;
            t.check()
                .map_err(|m| StageError::Input(format!("`{}`: {m}", Self::KIND)))?;
            t.vertices_for(cx.original)
        };
        let n = usize::try_from(n).unwrap_or(usize::MAX);
        let density = if p.density.is_empty() {
            None
        } else {
            Some(mesh.vertex_attrs.scalar(&p.density).ok_or_else(|| {
                StageError::Input(format!(
                    "`{}`: no vertex scalar `{}` for the density",
                    Self::KIND,
                    p.density
                ))
            })?)
        };
        let topo = cx
            .topology(&mesh)
            .map_err(|e| StageError::Input(format!("`{}`: {e}", Self::KIND)))?;
        let progress = cx.progress;
        progress.begin(Self::KIND, u64::from(p.max_passes));
        let result = cluster(&mesh, &topo, n, p, density, |pass, moves, energy| {
            progress.advance(
                u64::from(pass),
                &format!("{moves} moves, energy {energy:.6e}"),
            )
        });
        progress.end();
        let c = result.map_err(|e| match e {
            ClusterError::TooManyClusters { .. } | ClusterError::TooFewClusters { .. } => {
                StageError::Param {
                    name: "clusters",
                    message: e.to_string(),
                }
            }
            e => StageError::Input(format!("`{}`: {e}", Self::KIND)),
        })?;
        report(cx.report, &c, p);
        mesh.face_attrs.insert(CLUSTER, AttrValues::Label(c.labels));
        Ok(mesh)
    }
}

/// Fills the stage report.
fn report(r: &mut StageReport, c: &Clustering, p: &CvtParams) {
    r.figure("energy", p.energy);
    r.figure("clusters", c.n);
    r.figure("passes", c.log.moves.len());
    r.figure("moves", c.log.moves.iter().sum::<u64>());
    r.figure("moves_per_pass", &c.log.moves);
    r.figure("initial_energy", c.log.initial_energy);
    r.figure("energy_per_pass", &c.log.energy);
    r.figure("refused", c.log.refused);
    if c.log.moves.len() as u32 >= p.max_passes && c.log.moves.last().is_some_and(|&m| m > 0) {
        r.warn(format!(
            "the minimisation stopped at max_passes = {} while faces were still moving",
            p.max_passes
        ));
    }
}

coarsen_stage::export_stage!(ClusterCvt);

#[cfg(test)]
mod tests;
