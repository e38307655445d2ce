//! The clustering engine: seeding, region growing and the ACVD minimisation loop.
//!
//! Faces are adjacent across an edge of exactly two faces (edges of three or more faces
//! separate, like boundary edges). Clusters keep running [`Sums`], so a move test is O(1)
//! in the energy plus a look at the fans of the moved face's three corners.

use crate::energy::{Derived, Energy, FaceData, FacePoint, Sums, WithEnergy};
use crate::sweep;
use coarsen_geom::{DVec3, SplitMix64, triangle};
use coarsen_mesh::order::{CurveOrder, is_along_curve, morton, unit_box};
use coarsen_mesh::topology::NONE;
use coarsen_mesh::{Mesh, Topology};
use rayon::prelude::*;
use std::borrow::Cow;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering::Relaxed};

/// Meshes with fewer faces keep their own face order inside the clusterer; bigger ones
/// are renumbered along a Morton curve (see [`Clusterer`]).
const LAYOUT_MIN_FACES: usize = 1 << 20;

/// A warm start over more faces than this works each face's mass and centroid out from its
/// corners when asked ([`Derived`]); up to it they are kept in a table (32 bytes a face, 64
/// MB at the bound), which the passes read about a quarter faster: on the post-process's
/// finest level of the bunny at 5000 vertices (634K faces, 15 passes) the passes' CPU time
/// fell from 0.27–0.29 s to 0.20–0.21 s for 0.02–0.04 s more setting up. Above it (the
/// 4.4M-face bunny's 3.8M-face finest level) the table would set the run's peak memory.
const DERIVE_MIN_FACES: usize = 2_000_000;

/// Parts the clusters are split into for the parallel sweep (fixed: the result must not
/// depend on the thread count).
const PARTS: usize = 8;
/// Faces may fall asleep in a pass after one that changed fewer than this share of the
/// clusters (see `sweep::Part::sleepers`): on the 4.4M-face bunny into 30,000 clusters with
/// r = 2, passes 100 to 200 (a few hundred clusters changed per pass) take 0.55 s instead
/// of 1.6 s; earlier, most sleepers would be woken again at once.
pub(crate) const SLEEP_SHARE: f64 = 0.125;

/// Meshes with fewer faces are swept as one part.
const PARALLEL_MIN_FACES: usize = 20_000;

/// Why a clustering could not be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ClusterError {
    /// More clusters asked for than there are faces.
    #[error("{clusters} clusters asked for, but the mesh has only {faces} faces")]
    TooManyClusters {
        /// Clusters asked for.
        clusters: usize,
        /// Faces of the mesh.
        faces: usize,
    },
    /// Fewer clusters than connected components (each needs one).
    #[error(
        "{clusters} clusters asked for, but the mesh has {components} connected components (each needs at least one)"
    )]
    TooFewClusters {
        /// Clusters asked for.
        clusters: usize,
        /// Components of the mesh.
        components: usize,
    },
    /// A face that takes no part in the adjacency (it repeats a vertex).
    #[error("face {face} repeats a vertex index; clean the mesh first")]
    SkippedFace {
        /// The face.
        face: usize,
    },
    /// A density value that is not a positive finite number.
    #[error("density at vertex {vertex} is {value}; it must be positive and finite")]
    BadDensity {
        /// The vertex.
        vertex: usize,
        /// Its value.
        value: f64,
    },
    /// A label column whose length or values do not fit the mesh.
    #[error("cluster label of face {face} is {label}, not below the cluster count {clusters}")]
    BadLabel {
        /// The face.
        face: usize,
        /// Its label.
        label: u32,
        /// The cluster count.
        clusters: usize,
    },
    /// A label column whose length is not the mesh's face count.
    #[error("{labels} cluster labels given for a mesh of {faces} faces")]
    LabelCount {
        /// Labels given.
        labels: usize,
        /// Faces of the mesh.
        faces: usize,
    },
}

/// The figures of one minimisation.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PassLog {
    /// Faces moved in each pass.
    pub moves: Vec<u64>,
    /// Total energy at the end of each pass.
    pub energy: Vec<f64>,
    /// Energy before the first pass.
    pub initial_energy: f64,
    /// Improving moves refused because they would empty, split or pinch a cluster.
    pub refused: u64,
    /// Faces that fell asleep: left out of the passes, with nothing around them changed,
    /// until a cluster next to them changes (the result is the same as visiting them).
    pub slept: u64,
}

/// The clusterer's layout of a mesh: vertices along a Morton curve of their positions,
/// faces by their first corner on that curve (`coarsen_mesh::order`), or the mesh's own
/// order.
struct Layout<'a> {
    /// Laid out along the curve (also when the mesh was in that order already).
    curve: bool,
    /// The mesh's own order, its tables borrowed.
    own_tables: bool,
    /// Layout position → vertex; empty in the mesh's own order.
    vorder: Vec<u32>,
    perm: FacePerm,
    /// Each face's corners (layout positions) by layout position.
    corners: Cow<'a, [[u32; 3]]>,
}

impl<'a> Layout<'a> {
    /// The layout of `mesh`: along the curve when `curve`, where a mesh already in that
    /// order (the runner renumbers large inputs so) is laid out as it is.
    fn of(mesh: &'a Mesh, curve: bool) -> Layout<'a> {
        let nf = mesh.n_faces();
        let along = curve && is_along_curve(mesh);
        let layout = match curve && !along {
            true => CurveOrder::of(mesh),
            false => None,
        };
        let curve = along || layout.is_some();
        let own_tables = layout.is_none();
        // Layout position → vertex, vertex → layout position, layout position → face;
        // empty when the layout is the mesh's own order.
        let (vorder, vmap, order) = match layout {
            Some(o) => (o.vertices, o.vertex_rank, o.faces),
            None => (Vec::new(), Vec::new(), Vec::new()),
        };
        let perm = match own_tables {
            true => FacePerm::Identity(nf),
            false => {
                let mut rank = vec![0u32; nf];
                for (i, &f) in order.iter().enumerate() {
                    rank[f as usize] = i as u32;
                }
                FacePerm::Map { order, rank }
            }
        };
        let corners: Cow<'a, [[u32; 3]]> = match own_tables {
            true => Cow::Borrowed(&mesh.faces),
            false => Cow::Owned(
                (0..nf)
                    .into_par_iter()
                    .map(|i| mesh.faces[perm.order(i) as usize].map(|v| vmap[v as usize]))
                    .collect(),
            ),
        };
        drop(vmap);
        Layout {
            curve,
            own_tables,
            vorder,
            perm,
            corners,
        }
    }
}

/// [`ClusterError::SkippedFace`] for a face of the `nf` that `topo` skips,
/// [`ClusterError::BadDensity`] for a density that is not finite and positive.
fn check_input(nf: usize, topo: &Topology, density: Option<&[f64]>) -> Result<(), ClusterError> {
    if let Some(face) = (0..nf).find(|&f| topo.is_skipped_face(f as u32)) {
        return Err(ClusterError::SkippedFace { face });
    }
    if let Some(d) = density
        && let Some((vertex, &value)) = d
            .iter()
            .enumerate()
            .find(|(_, x)| !(x.is_finite() && **x > 0.0))
    {
        return Err(ClusterError::BadDensity { vertex, value });
    }
    Ok(())
}

/// Per face in layout order: the faces across its three edges (layout ranks), `NONE`
/// across a boundary edge or an edge of three or more faces.
fn face_neighbours(topo: &Topology, perm: &FacePerm) -> Vec<[u32; 3]> {
    (0..perm.len())
        .into_par_iter()
        .map(|i| {
            let f = perm.order(i);
            topo.face_edges(f)
                .map(|e| match (e != NONE).then(|| topo.edge_faces(e)) {
                    Some(&[a, b]) => perm.rank(if a == f { b } else { a } as usize),
                    _ => NONE,
                })
        })
        .collect()
}

/// A bit per face of `nf`, all clear.
fn bits(nf: usize) -> Vec<AtomicU64> {
    (0..nf.div_ceil(64)).map(|_| AtomicU64::new(0)).collect()
}

/// The clusterer's face layout against the mesh's face numbering; the identity (a mesh
/// laid out in its own order, or one the runner renumbered along the curve already) is
/// kept as its length alone (two arrays of a face each fewer: 36 MB at 4.4M faces).
enum FacePerm {
    Identity(usize),
    Map {
        /// Layout position → mesh face.
        order: Vec<u32>,
        /// Mesh face → layout position.
        rank: Vec<u32>,
    },
}

impl FacePerm {
    /// The number of faces.
    fn len(&self) -> usize {
        match self {
            FacePerm::Identity(n) => *n,
            FacePerm::Map { order, .. } => order.len(),
        }
    }

    /// The mesh face at layout position `i`.
    #[inline]
    fn order(&self, i: usize) -> u32 {
        match self {
            FacePerm::Identity(_) => i as u32,
            FacePerm::Map { order, .. } => order[i],
        }
    }

    /// The layout position of mesh face `f`.
    #[inline]
    fn rank(&self, f: usize) -> u32 {
        match self {
            FacePerm::Identity(_) => f as u32,
            FacePerm::Map { rank, .. } => rank[f],
        }
    }
}

/// A face clustering in progress over one mesh.
///
/// Generic over the energy so that the move tests call it directly; `dyn Energy` works too.
///
/// Inside, on meshes of 2²⁰ faces or more, vertices are renumbered along a Morton curve of
/// their positions and faces by their first corner on it (the *layout*; smaller meshes keep
/// their order), so that the neighbours a move test reads lie close in memory; the public
/// methods take and give faces in the mesh's own numbering.
pub struct Clusterer<'a, E: Energy + ?Sized = dyn Energy> {
    energy: &'a E,
    /// Layout position ↔ mesh face.
    perm: FacePerm,
    /// Per layout face: the layout face across each edge (corner i → i+1), or `NONE`.
    nbr: Vec<[u32; 3]>,
    /// Per layout face: its corners as layout vertices (when the layout is the mesh's own
    /// order, the mesh's faces themselves).
    pub(crate) corners: Cow<'a, [[u32; 3]]>,
    /// Per layout vertex: its faces (layout numbering, in the adjacency's fan order) are
    /// `fan[fan_off[v]..fan_off[v + 1]]` (in the mesh's own order, the adjacency's table).
    fan_off: Cow<'a, [u32]>,
    fan: Cow<'a, [u32]>,
    /// Per layout vertex: its faces form one closed fan.
    closed: Vec<bool>,
    /// Whether the passes' move test may walk fans across edges ([`walk_fan`]): the mesh
    /// is manifold and consistently oriented.
    walk_fans: bool,
    /// Per layout face: its mass and centroid.
    face_sums: FaceData<'a>,
    /// Per layout vertex: its position (the mesh's own when the layout is its order, else
    /// normalised), for the fold guard's face normals.
    pos: Cow<'a, [DVec3]>,
    /// The layout runs along the Morton curve (else it is the mesh's own order).
    curve: bool,
    /// The cluster of every mesh face (mesh numbering).
    labels: Vec<u32>,
    sums: Vec<Sums>,
    /// Per cluster: its energy term, kept in step with `sums`.
    terms: Vec<f64>,
    /// Stop when a pass lowers the energy by less than this fraction of it.
    tolerance: f64,
    /// See [`SLEEP_SHARE`].
    sleep_share: f64,
    /// See [`Clusterer::set_fold_guard`].
    fold_guard: bool,
    /// The mesh's adjacency.
    topo: &'a Topology,
}

impl<'a, E: Energy + ?Sized> Clusterer<'a, E> {
    /// A clusterer over `mesh` (whose adjacency is `topo`) with `energy`, face masses from
    /// the energy and the optional per-vertex `density`. No face is labelled yet.
    pub fn new(
        mesh: &'a Mesh,
        topo: &'a Topology,
        energy: &'a E,
        density: Option<&[f64]>,
    ) -> Result<Self, ClusterError> {
        let curve = mesh.n_faces() >= LAYOUT_MIN_FACES;
        Self::with_layout(mesh, topo, energy, density, curve, false)
    }

    /// [`Clusterer::new`] in the mesh's own order at every size: for a few passes from a
    /// clustering at hand (a warm start, a local repair), where the curve layout would
    /// cost about what it saves. Without a density and above `DERIVE_MIN_FACES` faces,
    /// each face's mass and centroid are worked out from its corners when asked instead of
    /// kept in a table (32 bytes a face, read only by the few faces a pass prices).
    pub fn for_few_passes(
        mesh: &'a Mesh,
        topo: &'a Topology,
        energy: &'a E,
        density: Option<&[f64]>,
    ) -> Result<Self, ClusterError> {
        let derive = mesh.n_faces() > DERIVE_MIN_FACES;
        Self::with_layout(mesh, topo, energy, density, false, derive)
    }

    /// [`Clusterer::new`] with the layout along the Morton curve (`curve`) or in the
    /// mesh's own order; with `derive`, face masses and centroids worked out when asked
    /// where the layout is the mesh's order and there is no density.
    pub(crate) fn with_layout(
        mesh: &'a Mesh,
        topo: &'a Topology,
        energy: &'a E,
        density: Option<&[f64]>,
        curve: bool,
        derive: bool,
    ) -> Result<Self, ClusterError> {
        let nf = mesh.n_faces();
        check_input(nf, topo, density)?;
        // Normalised coordinates: centred, unit diagonal, so the sums keep their digits
        // (and the curve order below is drawn in the same ones).
        let (center, scale) = unit_box(mesh);
        let nv = mesh.n_vertices();
        let pos_of = |v: u32| (mesh.positions[v as usize] - center) * scale;
        let Layout {
            curve,
            own_tables,
            vorder,
            perm,
            corners,
        } = Layout::of(mesh, curve);
        let vertex_at = |i: usize| if own_tables { i as u32 } else { vorder[i] };
        let face_point = |i: usize, [a, b, c]: [DVec3; 3]| {
            let rho = density.map_or(1.0, |d| {
                mesh.faces[perm.order(i) as usize]
                    .iter()
                    .map(|&v| d[v as usize])
                    .sum::<f64>()
                    / 3.0
            });
            FacePoint {
                mass: energy.face_mass(triangle::area(a, b, c), rho),
                centroid: triangle::centroid(a, b, c),
            }
        };
        // The fold guard's normals need only directions: the mesh's own positions serve
        // when the layout is its order.
        let (face_sums, pos) = match own_tables {
            true if derive && density.is_none() => (
                FaceData::Derived(Derived {
                    corners: &mesh.faces,
                    positions: &mesh.positions,
                    center,
                    scale,
                }),
                Cow::Borrowed(&mesh.positions[..]),
            ),
            true => (
                FaceData::Kept(
                    corners
                        .par_iter()
                        .enumerate()
                        .map(|(i, c)| face_point(i, c.map(pos_of)))
                        .collect(),
                ),
                Cow::Borrowed(&mesh.positions[..]),
            ),
            false => {
                // Face sums from the vertices in layout order (reads close in memory).
                let pos: Vec<DVec3> = vorder.par_iter().map(|&v| pos_of(v)).collect();
                let sums = corners
                    .par_iter()
                    .enumerate()
                    .map(|(i, c)| face_point(i, c.map(|v| pos[v as usize])))
                    .collect();
                (FaceData::Kept(sums), Cow::Owned(pos))
            }
        };
        let (fan_off, fan) = match own_tables {
            true => {
                let (off, fan) = topo.vertex_face_table();
                (Cow::Borrowed(off), Cow::Borrowed(fan))
            }
            false => {
                let (off, fan) = csr(&vorder, |v| topo.vertex_faces(v), |g| perm.rank(g as usize));
                (Cow::Owned(off), Cow::Owned(fan))
            }
        };
        let closed = (0..nv)
            .into_par_iter()
            .map(|i| {
                let v = vertex_at(i);
                topo.n_vertex_fans(v) == 1 && !topo.is_boundary_vertex(v)
            })
            .collect();
        let nbr = face_neighbours(topo, &perm);
        Ok(Clusterer {
            energy,
            perm,
            nbr,
            corners,
            fan_off,
            fan,
            closed,
            walk_fans: topo.is_manifold() && topo.is_consistently_oriented(),
            face_sums,
            pos,
            curve,
            labels: vec![NONE; nf],
            sums: Vec::new(),
            terms: Vec::new(),
            tolerance: 0.0,
            sleep_share: SLEEP_SHARE,
            fold_guard: false,
            topo,
        })
    }

    /// Whether face masses and centroids are worked out when asked (no table).
    #[cfg(test)]
    pub(crate) fn derives_face_data(&self) -> bool {
        matches!(self.face_sums, FaceData::Derived(_))
    }

    /// Makes [`Clusterer::minimize`] stop after a pass that lowers the energy by less than
    /// `tolerance` times its value (0, the default, stops only when nothing moves).
    pub fn set_tolerance(&mut self, tolerance: f64) {
        self.tolerance = tolerance;
    }

    /// Makes [`Clusterer::minimize`] refuse moves into clusters facing away from the face.
    pub fn set_fold_guard(&mut self, on: bool) {
        self.fold_guard = on;
    }

    /// Lets faces fall asleep after passes that changed fewer than `share` of the
    /// clusters (0: never; above 1: from the first pass).
    #[cfg(test)]
    pub(crate) fn set_sleep_share(&mut self, share: f64) {
        self.sleep_share = share;
    }

    /// The cluster of every face.
    pub fn labels(&self) -> &[u32] {
        &self.labels
    }

    /// Hands the labels over, consuming the clusterer.
    pub fn into_labels(self) -> Vec<u32> {
        self.labels
    }

    /// The number of clusters.
    pub fn n_clusters(&self) -> usize {
        self.sums.len()
    }

    /// The running sums of every cluster.
    pub fn cluster_sums(&self) -> &[Sums] {
        &self.sums
    }

    /// The total energy of the current clustering.
    pub fn total_energy(&self) -> f64 {
        self.terms.iter().sum()
    }

    /// Connected components of faces over the adjacency: `(component per face, count)`.
    pub fn components(&self) -> (Vec<u32>, usize) {
        let (comp, n) = self.layout_components();
        let mut out = vec![0u32; comp.len()];
        for (i, &c) in comp.iter().enumerate() {
            out[self.perm.order(i) as usize] = c;
        }
        (out, n)
    }

    /// [`Clusterer::components`] in the layout's numbering (of faces and components).
    fn layout_components(&self) -> (Vec<u32>, usize) {
        let nf = self.nbr.len();
        // One component across edges, none of more than two faces: one across the edges
        // of two faces too, with no search.
        let topo = self.topo;
        if topo.n_components() == 1
            && (0..topo.n_edges() as u32)
                .into_par_iter()
                .all(|e| !topo.is_non_manifold_edge(e))
        {
            return (vec![0; nf], 1);
        }
        let mut comp = vec![NONE; nf];
        let mut n = 0u32;
        let mut stack = Vec::new();
        for s in 0..nf {
            if comp[s] != NONE {
                continue;
            }
            comp[s] = n;
            stack.push(s as u32);
            while let Some(f) = stack.pop() {
                for g in self.nbr[f as usize] {
                    if g != NONE && comp[g as usize] == NONE {
                        comp[g as usize] = n;
                        stack.push(g);
                    }
                }
            }
            n += 1;
        }
        (comp, n as usize)
    }

    /// Picks `n` seed faces (at least one per component, the rest in proportion to each
    /// component's mass) and grows them breadth-first until every face belongs to a
    /// cluster. Within a component the faces are ordered along a Morton (Z-order) curve
    /// (the layout's order: by their first corner along the curve of the vertices) and the
    /// seeds are stratified by mass along it — one in each of the
    /// component's equal-mass stretches, at a point jittered by a [`SplitMix64`] from
    /// `seed` — so the seeds start evenly spread and the minimisation has little to move.
    /// A mesh laid out along the curve (big) grows in blocks of the layout at once
    /// (`grow_in_blocks`).
    pub fn seed(&mut self, n: usize, seed: u64) -> Result<(), ClusterError> {
        let nf = self.nbr.len();
        if n > nf {
            return Err(ClusterError::TooManyClusters {
                clusters: n,
                faces: nf,
            });
        }
        let (comp, nc) = self.layout_components();
        if n < nc {
            return Err(ClusterError::TooFewClusters {
                clusters: n,
                components: nc,
            });
        }
        // Faces of each component along the Morton curve, as a CSR by component.
        let mut off = vec![0usize; nc + 1];
        comp.iter().for_each(|&c| off[c as usize + 1] += 1);
        for i in 0..nc {
            off[i + 1] += off[i];
        }
        let members: Vec<u32> = if !self.curve {
            // The mesh's own order: sort along the curve of the face centroids. Keys are
            // distinct (the face is one), so the parallel sort is deterministic.
            let mut keyed: Vec<(u32, u64, u32)> = (0..nf)
                .into_par_iter()
                .map(|f| {
                    let y = self
                        .face_sums
                        .point(f, self.energy)
                        .sums()
                        .centroid_or_zero();
                    (comp[f], morton(y), f as u32)
                })
                .collect();
            keyed.par_sort_unstable();
            keyed.into_iter().map(|k| k.2).collect()
        } else if nc == 1 {
            (0..nf as u32).collect()
        } else {
            let mut fill = off.clone();
            let mut members = vec![0u32; nf];
            for (f, &c) in comp.iter().enumerate() {
                members[fill[c as usize]] = f as u32;
                fill[c as usize] += 1;
            }
            members
        };
        drop(comp);
        let mass_of = |f: u32| self.face_sums.point(f as usize, self.energy).mass.max(0.0);
        let mass: Vec<f64> = (0..nc)
            .map(|c| {
                members[off[c]..off[c + 1]]
                    .iter()
                    .map(|&f| mass_of(f))
                    .sum()
            })
            .collect();
        let quota = allocate(n, &mass, |c| off[c + 1] - off[c]);
        let mut rng = SplitMix64::new(seed);
        let mut labels = vec![NONE; nf];
        let mut seeds = Vec::with_capacity(n);
        let mut next = 0u32;
        for c in 0..nc {
            stratified(
                &members[off[c]..off[c + 1]],
                quota[c],
                mass[c],
                mass_of,
                &mut rng,
                |f| {
                    labels[f as usize] = next;
                    seeds.push(f);
                    next += 1;
                },
            );
        }
        // A big mesh (laid out along the curve) grows in blocks of the layout at once.
        match self.curve {
            true => grow_in_blocks(&self.nbr, &mut labels, seeds, BLOCK),
            false => grow(&self.nbr, &mut labels, 0, seeds),
        }
        self.set_layout_labels(labels, n);
        Ok(())
    }

    /// Takes over an existing clustering of `n` clusters (labels `0..n`).
    pub fn set_labels(&mut self, labels: Vec<u32>, n: usize) -> Result<(), ClusterError> {
        if labels.len() != self.perm.len() {
            return Err(ClusterError::LabelCount {
                labels: labels.len(),
                faces: self.perm.len(),
            });
        }
        if let Some((face, &label)) = labels.iter().enumerate().find(|(_, l)| **l as usize >= n) {
            return Err(ClusterError::BadLabel {
                face,
                label,
                clusters: n,
            });
        }
        let layout: Cow<'_, [u32]> = match &self.perm {
            FacePerm::Identity(_) => Cow::Borrowed(&labels),
            FacePerm::Map { order, .. } => {
                Cow::Owned(order.par_iter().map(|&f| labels[f as usize]).collect())
            }
        };
        let sums = self.sums_by_cluster(&layout, n);
        drop(layout);
        self.labels = labels;
        self.terms = sums.iter().map(|s| self.energy.cluster(s)).collect();
        self.sums = sums;
        Ok(())
    }

    /// Each cluster's sums from labels in the layout's numbering (all below `n`), each
    /// summed in layout order; big meshes sum the clusters in parallel, to the same bits.
    fn sums_by_cluster(&self, labels: &[u32], n: usize) -> Vec<Sums> {
        let point = |i: usize| self.face_sums.point(i, self.energy).sums();
        if labels.len() < PARALLEL_MIN_FACES {
            let mut sums = vec![Sums::default(); n];
            for (i, &l) in labels.iter().enumerate() {
                sums[l as usize] = sums[l as usize].plus(point(i));
            }
            return sums;
        }
        let (start, members) = faces_by_cluster(labels, n);
        (0..n)
            .into_par_iter()
            .map(|c| {
                members[start[c]..start[c + 1]]
                    .iter()
                    .fold(Sums::default(), |s, &i| s.plus(point(i as usize)))
            })
            .collect()
    }

    /// [`Clusterer::set_labels`] from labels in the layout's numbering (all below `n`).
    fn set_layout_labels(&mut self, labels: Vec<u32>, n: usize) {
        let sums = self.sums_by_cluster(&labels, n);
        self.labels = match &self.perm {
            FacePerm::Identity(_) => labels,
            FacePerm::Map { rank, .. } => rank.par_iter().map(|&i| labels[i as usize]).collect(),
        };
        self.terms = sums.iter().map(|s| self.energy.cluster(s)).collect();
        self.sums = sums;
    }

    /// Where the move test finds the faces round a corner (layout numbering).
    fn fans(&self) -> Fans<'_> {
        Fans {
            corners: &self.corners,
            nbr: &self.nbr,
            fan_off: &self.fan_off,
            fan: &self.fan,
            closed: &self.closed,
            walk: self.walk_fans,
        }
    }

    /// True when face `t` may leave its cluster for cluster `to`: its cluster keeps a face
    /// and stays connected without a pinch at `t`'s corners (paper 1's boundary test: the
    /// donor's faces form one arc around each corner), and `to` gains `t` without closing
    /// a loop or touching itself at a corner.
    pub fn may_move(&self, t: u32, to: u32) -> bool {
        let from = self.labels[t as usize];
        if from == to || self.sums[from as usize].count < 1.5 {
            return false;
        }
        let tl = self.perm.rank(t as usize);
        let (fans, mut buf) = (self.fans(), [0u32; FAN_WALK]);
        (0..3).all(|i| {
            let (fan, closed) = fans.around(tl, i, &mut buf);
            fan_runs(fan, closed, [from, to, tl], |g| {
                self.labels[self.perm.order(g as usize) as usize]
            })
            .iter()
            .all(|&r| r <= 1)
        })
    }

    /// Moves face `t` to cluster `to` (no checks).
    pub fn apply_move(&mut self, t: u32, to: u32) {
        let from = self.labels[t as usize] as usize;
        let ft = self
            .face_sums
            .point(self.perm.rank(t as usize) as usize, self.energy)
            .sums();
        self.sums[from] = self.sums[from].minus(ft);
        self.sums[to as usize] = self.sums[to as usize].plus(ft);
        self.terms[from] = self.energy.cluster(&self.sums[from]);
        self.terms[to as usize] = self.energy.cluster(&self.sums[to as usize]);
        self.labels[t as usize] = to;
    }

    /// The ACVD loop, over faces: each pass sweeps the *active* faces in layout order (at
    /// first the faces of `start`, or every face when `None`). A face with no neighbour in
    /// another cluster drops out; one on a cluster border stays active, and is tested only
    /// when its cluster or a neighbouring one changed in this pass or the previous one
    /// (ACVD's trick): it moves to the neighbouring cluster that lowers the energy most, if
    /// the move is allowed. A move activates the face's neighbours — in this pass when
    /// they come later in the sweep. Stops after a pass without moves, after `max_passes`
    /// passes, or when a pass lowers the energy by less than the tolerance.
    pub fn minimize(
        &mut self,
        max_passes: u32,
        start: Option<&[u32]>,
        mut on_pass: impl FnMut(u32, u64, f64),
    ) -> PassLog {
        let nf = self.perm.len();
        let n = self.sums.len();
        if n == 0 {
            // Nothing labelled yet: nothing to minimise.
            return PassLog::default();
        }
        let bitset = || bits(nf);
        let (mut cur, mut next) = (self.first_active(start), bitset());
        let mut log = PassLog {
            initial_energy: self.total_energy(),
            ..PassLog::default()
        };
        let (order, starts) = self.parts();
        let mut new_of = vec![0u32; n];
        for (i, &c) in order.iter().enumerate() {
            new_of[c as usize] = i as u32;
        }
        // Labels by layout face, in the parts' cluster numbering.
        let labels: Vec<AtomicU32> = (0..nf)
            .into_par_iter()
            .map(|i| AtomicU32::new(new_of[self.labels[self.perm.order(i) as usize] as usize]))
            .collect();
        let mut sums: Vec<Sums> = order.iter().map(|&c| self.sums[c as usize]).collect();
        let mut terms: Vec<f64> = order.iter().map(|&c| self.terms[c as usize]).collect();
        let guard = self.fold_guard;
        let mut normals = self.cluster_normals(&labels, n);
        let mut last_mod = vec![0u32; n];
        let mut sleepers = vec![Vec::new(); n];
        let asleep = bitset();
        let mut own = sweep::owners(&labels, &starts);
        let mut previous = log.initial_energy;
        let mut changed = n;
        let mut sleeping = false;
        for pass in 1..=max_passes {
            let may_sleep = (changed as f64) < self.sleep_share * n as f64;
            sleeping |= may_sleep;
            // One sweep per way of reading the face data, each compiled for its own.
            macro_rules! pass_over {
                ($faces:expr) => {
                    sweep::pass(
                        &sweep::View {
                            corners: &self.corners,
                            nbr: &self.nbr,
                            fans: self.fans(),
                            face_sums: $faces,
                            pos: guard.then_some(&self.pos[..]),
                            energy: self.energy,
                            labels: &labels,
                            cur: &cur,
                            next: &next,
                            asleep: &asleep,
                            may_sleep,
                            sleeping,
                        },
                        &starts,
                        &mut own,
                        sweep::State {
                            sums: &mut sums,
                            terms: &mut terms,
                            normals: &mut normals,
                            last_mod: &mut last_mod,
                            sleepers: &mut sleepers,
                        },
                        pass,
                    )
                };
            }
            let (moves, refused, slept) = match &self.face_sums {
                FaceData::Kept(table) => pass_over!(&table[..]),
                FaceData::Derived(d) => pass_over!(&WithEnergy(d, self.energy)),
            };
            log.refused += refused;
            log.slept += slept;
            changed = last_mod.iter().filter(|&&m| m == pass).count();
            std::mem::swap(&mut cur, &mut next);
            next.iter_mut().for_each(|w| *w.get_mut() = 0);
            let energy: f64 = terms.iter().sum();
            log.moves.push(moves);
            log.energy.push(energy);
            on_pass(pass, moves, energy);
            let settled = previous - energy <= self.tolerance * energy.abs();
            previous = energy;
            if moves == 0 || settled {
                break;
            }
        }
        for (i, l) in labels.into_iter().enumerate() {
            self.labels[self.perm.order(i) as usize] = order[l.into_inner() as usize];
        }
        for (i, &c) in order.iter().enumerate() {
            self.sums[c as usize] = sums[i];
            self.terms[c as usize] = terms[i];
        }
        log
    }

    /// The faces [`Clusterer::minimize`]'s first pass tests (by layout rank): those of
    /// `start`, or every face.
    fn first_active(&self, start: Option<&[u32]>) -> Vec<AtomicU64> {
        let nf = self.perm.len();
        let mut cur = bits(nf);
        match start {
            // Every face: whole words at once.
            None => cur.iter_mut().enumerate().for_each(|(w, word)| {
                *word.get_mut() = match nf - 64 * w {
                    64.. => u64::MAX,
                    left => (1 << left) - 1,
                }
            }),
            Some(faces) => faces.iter().filter(|&&f| (f as usize) < nf).for_each(|&f| {
                let f = self.perm.rank(f as usize);
                cur[f as usize / 64].fetch_or(1 << (f % 64), Relaxed);
            }),
        }
        cur
    }

    /// The parts the passes sweep side by side: the clusters in Morton order of their
    /// centroids (in their own order when one part does), and where each part starts in
    /// that order (ranges of about equal face counts), the total last.
    fn parts(&self) -> (Vec<u32>, Vec<u32>) {
        let (nf, n) = (self.perm.len(), self.sums.len());
        let n_parts = if nf >= PARALLEL_MIN_FACES && n >= 64 * PARTS {
            PARTS
        } else {
            1
        };
        let order: Vec<u32> = if n_parts == 1 {
            (0..n as u32).collect()
        } else {
            let mut keyed: Vec<(u64, u32)> = (0..n)
                .map(|c| (morton(self.sums[c].centroid_or_zero()), c as u32))
                .collect();
            keyed.sort_unstable();
            keyed.into_iter().map(|(_, c)| c).collect()
        };
        let mut starts = vec![0u32];
        let mut run = 0.0;
        let total: f64 = self.sums.iter().map(|s| s.count).sum();
        for (i, &c) in order.iter().enumerate() {
            run += self.sums[c as usize].count;
            if starts.len() < n_parts && run >= total * starts.len() as f64 / n_parts as f64 {
                starts.push(i as u32 + 1);
            }
        }
        starts.push(n as u32);
        starts.dedup();
        (order, starts)
    }

    /// Per cluster of `labels` (by layout face; `n` clusters): its faces' area vectors
    /// summed, for the fold guard (zeros without it).
    fn cluster_normals(&self, labels: &[AtomicU32], n: usize) -> Vec<DVec3> {
        let mut normals = vec![DVec3::ZERO; n];
        if self.fold_guard {
            for (corners, l) in self.corners.iter().zip(labels) {
                let [a, b, c] = corners.map(|v| self.pos[v as usize]);
                normals[l.load(Relaxed) as usize] += (b - a).cross(c - a);
            }
        }
        normals
    }

    /// Per cluster: whether its faces are connected across edges (a check for tests and
    /// the dual's repairs).
    pub fn connected_clusters(&self) -> Vec<bool> {
        let n = self.sums.len();
        let labels: Vec<u32> = (0..self.perm.len())
            .into_par_iter()
            .map(|i| self.labels[self.perm.order(i) as usize])
            .collect();
        // The faces (layout slots) of each cluster.
        let (start, members) = faces_by_cluster(&labels, n);
        // Per cluster, in parallel: a flood fill from its first face reaches all of them.
        // Every face is marked by its own cluster's fill only.
        let seen: Vec<AtomicU32> = (0..labels.len()).map(|_| AtomicU32::new(0)).collect();
        (0..n)
            .into_par_iter()
            .map_init(Vec::new, |stack, c| {
                let faces = &members[start[c]..start[c + 1]];
                let Some(&s) = faces.first() else {
                    return false;
                };
                seen[s as usize].store(1, Relaxed);
                stack.clear();
                stack.push(s);
                let mut reached = 1;
                while let Some(f) = stack.pop() {
                    for g in self.nbr[f as usize] {
                        if g != NONE
                            && labels[g as usize] == c as u32
                            && seen[g as usize].swap(1, Relaxed) == 0
                        {
                            reached += 1;
                            stack.push(g);
                        }
                    }
                }
                reached == faces.len()
            })
            .collect()
    }
}

/// Per face of `topo` (which has `n_faces` faces), the face across each edge (corner
/// i → i+1) when the edge has exactly two faces, else `NONE`.
pub fn face_neighbors(topo: &Topology, n_faces: usize) -> Vec<[u32; 3]> {
    (0..n_faces as u32)
        .into_par_iter()
        .map(|f| {
            topo.face_edges(f)
                .map(|e| match (e != NONE).then(|| topo.edge_faces(e)) {
                    Some(&[a, b]) => {
                        if a == f {
                            b
                        } else {
                            a
                        }
                    }
                    _ => NONE,
                })
        })
        .collect()
}

/// Picks `q` of the items `part` (in curve order, of total mass `total`), one in each
/// equal-mass stretch at a point jittered by `rng`: item k is the one where the running
/// mass passes (k + u)·total/q, or the next free one when a heavy item spans stretches.
pub(crate) fn stratified(
    part: &[u32],
    q: usize,
    total: f64,
    mass_of: impl Fn(u32) -> f64,
    rng: &mut SplitMix64,
    mut pick: impl FnMut(u32),
) {
    let mut run = 0.0;
    let mut k = 0usize;
    let goal = |k: usize, rng: &mut SplitMix64| {
        let u = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        (k as f64 + u) * total / q as f64
    };
    let mut at = goal(0, rng);
    for (i, &f) in part.iter().enumerate() {
        run += mass_of(f);
        // Items left must still cover the picks left.
        let must = part.len() - i <= q - k;
        if k < q && (run > at || must || total <= 0.0) {
            pick(f);
            k += 1;
            if k < q {
                at = goal(k, rng);
            }
        }
    }
}

/// The CSR `(offsets, values)` of the lists `list(k)` for the keys `keys`, each value
/// mapped by `map`; filled in parallel by blocks of keys.
fn csr<'l>(
    keys: &[u32],
    list: impl Fn(u32) -> &'l [u32] + Sync,
    map: impl Fn(u32) -> u32 + Sync,
) -> (Vec<u32>, Vec<u32>) {
    const BLOCK: usize = 4096;
    let mut off = Vec::with_capacity(keys.len() + 1);
    off.push(0u32);
    let mut at = 0u32;
    for &k in keys {
        at += list(k).len() as u32;
        off.push(at);
    }
    let mut values = vec![0u32; at as usize];
    let mut blocks = Vec::with_capacity(keys.len().div_ceil(BLOCK));
    let mut rest = values.as_mut_slice();
    for (b, chunk) in keys.chunks(BLOCK).enumerate() {
        let len = (off[b * BLOCK + chunk.len()] - off[b * BLOCK]) as usize;
        let (head, tail) = std::mem::take(&mut rest).split_at_mut(len);
        blocks.push((chunk, head));
        rest = tail;
    }
    blocks.into_par_iter().for_each(|(chunk, out)| {
        let mut i = 0;
        for &k in chunk {
            for &x in list(k) {
                out[i] = map(x);
                i += 1;
            }
        }
    });
    (off, values)
}

/// Faces in each block of the layout that [`grow_in_blocks`] grows on its own: at 4.4M
/// faces, the growing 0.13–0.18 s → 0.042–0.045 s (2¹⁷ and 2¹⁸ as fast, 2²⁰ slower).
const BLOCK: usize = 1 << 19;

/// Grows the labelled faces of `queue` breadth-first (in queue order) over `nbr` into every
/// face of `labels` (faces `lo..lo + labels.len()`) they reach that has no label yet,
/// never stepping outside those faces.
fn grow(nbr: &[[u32; 3]], labels: &mut [u32], lo: u32, mut queue: Vec<u32>) {
    // Each face joins the queue at most once.
    queue.reserve(labels.len().saturating_sub(queue.len()));
    let mut head = 0;
    while let Some(&f) = queue.get(head) {
        head += 1;
        let l = labels[(f - lo) as usize];
        for g in nbr[f as usize] {
            if g != NONE
                && let Some(slot) = labels.get_mut(g.wrapping_sub(lo) as usize)
                && *slot == NONE
            {
                *slot = l;
                queue.push(g);
            }
        }
    }
}

/// Like [`grow`] from the seed faces `seeds` (in order), but each block of `block` faces
/// in parallel, from its own seeds and within itself (along the Morton layout a block is
/// a compact piece of the surface, and its tables fit in cache); then the faces no seed
/// of their block reached are grown into from the labelled faces next to them (in face
/// order). The blocks depend on the face count alone, never on the thread count.
pub(crate) fn grow_in_blocks(nbr: &[[u32; 3]], labels: &mut [u32], seeds: Vec<u32>, block: usize) {
    let nf = labels.len();
    let mut by_block = vec![Vec::new(); nf.div_ceil(block)];
    for &f in &seeds {
        by_block[f as usize / block].push(f);
    }
    labels
        .par_chunks_mut(block)
        .zip(by_block)
        .enumerate()
        .for_each(|(k, (mine, queue))| grow(nbr, mine, (k * block) as u32, queue));
    let labels_ro: &[u32] = labels;
    let rim: Vec<u32> = (0..nf as u32)
        .into_par_iter()
        .filter(|&f| {
            labels_ro[f as usize] != NONE
                && nbr[f as usize]
                    .iter()
                    .any(|&g| g != NONE && labels_ro[g as usize] == NONE)
        })
        .collect();
    grow(nbr, labels, 0, rim);
}

/// Most faces [`walk_fan`] lists around a vertex (more: it gives up).
pub(crate) const FAN_WALK: usize = 48;

/// Where the move test finds the faces round a corner (a clusterer's layout tables).
#[derive(Clone, Copy)]
pub(crate) struct Fans<'f> {
    /// Per face: its corners.
    pub corners: &'f [[u32; 3]],
    /// Per face: the face across each edge (corner i → i + 1), or [`NONE`].
    pub nbr: &'f [[u32; 3]],
    /// Per vertex `v`: its faces in fan order, `fan[fan_off[v]..fan_off[v + 1]]`.
    pub fan_off: &'f [u32],
    pub fan: &'f [u32],
    /// Per vertex: its faces form one closed fan.
    pub closed: &'f [bool],
    /// Whether corners may be walked round across `nbr` ([`walk_fan`]; the mesh is
    /// manifold and consistently oriented): the same fans as the table's, from memory a
    /// sweep has just read.
    pub walk: bool,
}

impl<'f> Fans<'f> {
    /// The faces round corner `i` of face `t` in fan order, and whether they close
    /// round it: walked (into `buf`) when allowed and short enough, else the table's row.
    #[inline]
    pub(crate) fn around<'b>(
        &self,
        t: u32,
        i: usize,
        buf: &'b mut [u32; FAN_WALK],
    ) -> (&'b [u32], bool)
    where
        'f: 'b,
    {
        if self.walk
            && let Some((n, closed)) = walk_fan(self.nbr, t, i, buf)
        {
            return (&buf[..n], closed);
        }
        let v = self.corners[t as usize][i] as usize;
        let (a, b) = (self.fan_off[v] as usize, self.fan_off[v + 1] as usize);
        (&self.fan[a..b], self.closed[v])
    }
}

/// The faces around corner `i` of face `t`, found by stepping across the faces' edges
/// (`nbr`, [`NONE`] across a boundary) and written to `buf` in fan order: `Some((len,
/// closed))`, or `None` when the fan has more than [`FAN_WALK`] faces or the adjacency is
/// not that of a manifold vertex. For a manifold mesh this is the vertex's one fan, as
/// the vertex's row of the fan table gives it up to rotation and direction (which
/// [`fan_runs`] does not see), read from the faces near `t` that the sweep has just read.
#[inline]
pub(crate) fn walk_fan(
    nbr: &[[u32; 3]],
    t: u32,
    i: usize,
    buf: &mut [u32; FAN_WALK],
) -> Option<(usize, bool)> {
    // The edge of face `g` back to `f`, when there is exactly one.
    let back = |g: u32, f: u32| -> Option<usize> {
        let n = nbr[g as usize];
        let k = n.iter().position(|&x| x == f)?;
        (n.iter().filter(|&&x| x == f).count() == 1).then_some(k)
    };
    buf[0] = t;
    let mut n = 1;
    // One way round: out across each face's edge that ends at the vertex.
    let (mut f, mut e) = (t, (i + 2) % 3);
    loop {
        let g = nbr[f as usize][e];
        if g == NONE {
            break;
        }
        if g == t {
            return Some((n, true));
        }
        if n == FAN_WALK {
            return None;
        }
        buf[n] = g;
        n += 1;
        e = (back(g, f)? + 2) % 3;
        f = g;
    }
    // Open: the other way round from t (out across the edge that starts at the vertex),
    // put in front, reversed.
    let first = n;
    let (mut f, mut e) = (t, i);
    loop {
        let g = nbr[f as usize][e];
        if g == NONE {
            break;
        }
        if g == t || n == FAN_WALK {
            return None;
        }
        buf[n] = g;
        n += 1;
        e = (back(g, f)? + 1) % 3;
        f = g;
    }
    // buf = [t, a1..ak, b1..bm]: rotate to [b1..bm, t, a1..ak], then reverse the b's.
    buf[..n].rotate_left(first);
    buf[..n - first].reverse();
    Some((n, false))
}

/// Around a vertex whose faces are `fan` (in fan order; `closed` when they form one closed
/// fan), the number of runs (maximal arcs) of faces of cluster `from` without face `t`, of
/// cluster `to` without `t`, and of `to` with `t` — in one walk of the fan, `label` giving
/// each face's cluster. A cluster covering the whole closed fan counts as one run.
#[inline]
pub(crate) fn fan_runs(
    fan: &[u32],
    closed: bool,
    [from, to, t]: [u32; 3],
    label: impl Fn(u32) -> u32,
) -> [u32; 3] {
    // Membership bits of a face: from without t, to without t, to with t.
    let member = |g: u32| -> u32 {
        if g == t {
            0b100
        } else {
            let l = label(g);
            if l == from {
                0b001
            } else if l == to {
                0b110
            } else {
                0
            }
        }
    };
    let mut prev = match fan.last() {
        Some(&g) if closed => member(g),
        _ => 0,
    };
    let (mut runs, mut all) = ([0u32; 3], 0b111u32);
    for &g in fan {
        let m = member(g);
        let starts = m & !prev;
        for (i, r) in runs.iter_mut().enumerate() {
            *r += (starts >> i) & 1;
        }
        all &= m;
        prev = m;
    }
    if !fan.is_empty() {
        for (i, r) in runs.iter_mut().enumerate() {
            if *r == 0 && (all >> i) & 1 == 1 {
                *r = 1;
            }
        }
    }
    runs
}

/// Splits `n` among components: one each, the rest in proportion to `mass` (largest
/// remainder, ties to the lower index), never more than a component's `size`.
fn allocate(n: usize, mass: &[f64], size: impl Fn(usize) -> usize) -> Vec<usize> {
    let nc = mass.len();
    let mut q = vec![1usize; nc];
    let mut left = n - nc;
    while left > 0 {
        let open: Vec<usize> = (0..nc).filter(|&c| q[c] < size(c)).collect();
        let total: f64 = open.iter().map(|&c| mass[c]).sum();
        let mut rem: Vec<(f64, usize)> = Vec::with_capacity(open.len());
        let mut given = 0;
        for &c in &open {
            let share = if total > 0.0 {
                left as f64 * mass[c] / total
            } else {
                left as f64 / open.len() as f64
            };
            let whole = (share.floor() as usize).min(size(c) - q[c]);
            q[c] += whole;
            given += whole;
            rem.push((share - share.floor(), c));
        }
        left -= given;
        rem.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        for &(_, c) in &rem {
            if left == 0 {
                break;
            }
            if q[c] < size(c) {
                q[c] += 1;
                left -= 1;
            }
        }
    }
    q
}

/// The faces of each of `n` clusters given each face's label: cluster `c` has
/// `members[start[c]..start[c + 1]]`, ascending.
pub fn faces_by_cluster(labels: &[u32], n: usize) -> (Vec<usize>, Vec<u32>) {
    let mut start = vec![0usize; n + 1];
    labels.iter().for_each(|&c| start[c as usize + 1] += 1);
    for c in 0..n {
        start[c + 1] += start[c];
    }
    let mut at = start.clone();
    let mut members = vec![0u32; labels.len()];
    for (f, &c) in labels.iter().enumerate() {
        members[at[c as usize]] = f as u32;
        at[c as usize] += 1;
    }
    (start, members)
}

/// The mass centroid of each cluster in the mesh's own coordinates (area-weighted face
/// centroids), for callers that place a point per cluster; the clusters' faces as
/// [`faces_by_cluster`] gives them.
pub fn cluster_centroids(mesh: &Mesh, start: &[usize], members: &[u32]) -> Vec<DVec3> {
    // The clusters in parallel, each summed in face order: the same sums as one pass
    // over the faces.
    (0..start.len().saturating_sub(1))
        .into_par_iter()
        .map(|c| {
            let (mut s, mut w, mut p, mut k) = (DVec3::ZERO, 0.0f64, DVec3::ZERO, 0.0f64);
            for &f in &members[start[c]..start[c + 1]] {
                let a = mesh.face_area(f as usize);
                let g = mesh.face_centroid(f as usize);
                s += a * g;
                w += a;
                p += g;
                k += 1.0;
            }
            if w > 0.0 { s / w } else { p / k.max(1.0) }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn allocation_gives_every_component_one_and_the_rest_by_mass() {
        let q = allocate(10, &[1.0, 3.0, 0.0], |_| 100);
        assert_eq!(q.iter().sum::<usize>(), 10);
        assert_eq!(q[2], 1);
        assert!(q[1] > q[0]);
        // Capacities are respected.
        let q = allocate(6, &[100.0, 1.0], |c| [2, 10][c]);
        assert_eq!(q, vec![2, 4]);
    }
}
