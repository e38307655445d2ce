//! The `dual` stage: the dual triangulation of a face clustering (paper 1 "Mesh
//! coarsening method", step 4, after Valette & Chassery 2004).
//!
//! Reads the face label `cluster` (`0..n`, every value used) and outputs exactly n
//! vertices, one per cluster, and k − 2 triangles at every input vertex where k ≥ 3
//! clusters meet, fanned in the cyclic order of the clusters around that vertex (the
//! input's fan order), so that they are oriented like the input.
//!
//! # Validity and repairs
//!
//! The dual is a valid manifold with the input's components, boundary loops and genus when
//! every cluster is a disc, no cluster meets itself around a vertex, the clusters meet each
//! other in single arcs, and every boundary loop is met by at least three clusters, each
//! only once. Before emitting anything the stage diagnoses the clustering (cluster
//! connectivity and Euler characteristic, pinches, boundary loops) and then the dual faces
//! themselves (a cluster without a triangle, duplicate triangles, non-manifold edges or
//! vertices, components/loops/genus differing from the input's). Every cluster to blame is
//! **split** in two (double sweep: grown from its two faces farthest apart) and the count is
//! kept exact by **merging** the smallest interior cluster far from every problem into its
//! smallest neighbour; a few constrained minimisation passes (`relax_passes`) then smooth
//! the touched clusters (with `fold_guard`, refusing moves into clusters that face away,
//! as `cluster.cvt` does), and the diagnosis runs again, at most `max_repair_rounds` times.
//! A boundary loop's problem (a cluster meeting it twice, or meeting two loops) first
//! blames every cluster along the loop, which adds clusters along it; if that has not
//! converged after eight rounds (many loops close together), the repair starts again from
//! the first clustering blaming only the clusters met twice.
//! When splitting cannot help — on a strip or ribbon one or two faces wide every compact
//! cluster touches the boundary on both sides, and halves of it do too — the clusters to
//! blame are **rebuilt**: broken into single faces (every cluster, if that is not enough),
//! then merged back, the pair of smallest summed area first, as collapses of the dual's
//! edges that pass the link condition (so the dual stays a manifold of the input's
//! topology) between clusters that meet along one path of input edges and nowhere else
//! (so the merged cluster is a disc), until the count is exact. If no valid merge is left
//! above the count, the stage fails with a parameter error naming the smallest count it
//! reached; if problems remain it fails too: it never emits a broken mesh nor adds a
//! vertex. A mesh with a boundary loop along fewer than three faces (e.g. a component of
//! two triangles) has no valid dual under any clustering and is refused up front, as an
//! input error.
//!
//! # Boundaries
//!
//! Beyond paper 1: at a boundary vertex the fan is open, so its k clusters (in fan order,
//! not merged cyclically) give k − 2 triangles and the two outermost clusters are joined by
//! an output boundary edge. Along each input boundary loop the clusters touching it (at
//! least three, each once) thus become an output boundary loop in the same order. Their
//! vertices are put on the input boundary, at the middle (by arc length) of the cluster's
//! run of boundary edges, so they are spread evenly along it. When the stage's input is not
//! the run's and its boundary has left the run's input's (after a simplifier, whose
//! boundary edges are chords of the input's), the stage then moves them onto the run's
//! input boundary ([`pull_onto_input`], each move undone where it would spoil a face).
//! With `fix_facing`, a boundary vertex of a flat triangle or of one facing away first tries
//! the ends and middles of its cluster's boundary edges, and leaves the boundary only when
//! each of them leaves one of its triangles flat or facing away.
//!
//! # Placement (`placement`)
//!
//! * `closest-vertex` — paper 1: the input vertex of the cluster nearest its centroid;
//! * `centroid` — the area-weighted centroid of the cluster;
//! * `projected` — the nearest point of the run's input surface to that centroid (the
//!   clustered mesh's own surface for callers of [`dual`] that give none);
//! * `quadric` — the minimiser of the cluster's summed, area-weighted face-plane quadrics,
//!   regularised towards the projected centroid (directions whose curvature is below
//!   10⁻³ of the quadric's trace stay at it), and falling back to the projected centroid
//!   when the point leaves the cluster's bounding box enlarged by half its diagonal.
//!
//! Where a part of the input is thinner than a cluster (a cow's ears, a teapot's rim), an
//! output face can lie nearer the opposite sheet and face away from it — the metrics count it
//! as flipped. With `fix_facing` (on by default) each vertex of such a face tries points of its
//! cluster's faces and moves to one where fewer of its faces do so (none flat), keeping the
//! largest smallest angle. Pipelines whose post-process re-triangulates turn it off here: the
//! post-process's own dual always does it, on the mesh that is kept.
//!
//! Vertex attributes are carried to each output vertex as the area-weighted blend of its
//! cluster's vertices; face attributes do not survive.
//!
//! The report gives `vertices`, `faces`, `placement`, `repairs` (clusters split),
//! `repair_rounds`, `problems` (found by the first diagnosis, by kind), `restarted` (the
//! repair started again blaming only the clusters met twice), `rebuilt` (the fallback
//! above ran), `boundary_clusters`, `boundary_pulled` (boundary vertices moved onto the
//! run's input boundary), `boundary_left` (those left off it, where the move would spoil a
//! face), `quadric_fallbacks` and `degenerate_fixes` (vertices of a
//! would-be degenerate or flipped output triangle — e.g. three closest vertices in a row, or
//! a boundary cluster between two others on a straight boundary — moved to their projected
//! centroid, unsnapped).

mod build;
mod pull;

pub use pull::{Pull, Pulled, pull_onto_input};

pub use build::{DualError, DualStats, Problems};

use coarsen_geom::{Aabb, DVec3, Quadric};
use coarsen_mesh::{FaceOrigins, Topology, VertexOrigins};
use coarsen_metrics::{Facing, SurfaceIndex, SurfaceParts};
use coarsen_spatial::{Bvh, closest_point_on_segment};
use coarsen_stage::{
    AttrKind, AttrRef, Context, Contract, Domain, Mesh, Needs, Params, Stage, StageError, params,
};
use coarsen_stage_cvt::{CLUSTER, cluster_centroids, faces_by_cluster};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Where each cluster's output vertex goes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Placement {
    /// The input vertex of the cluster nearest its centroid (paper 1).
    ClosestVertex,
    /// The area-weighted centroid.
    Centroid,
    /// The nearest point of the input surface to the centroid.
    #[default]
    Projected,
    /// The guarded minimiser of the cluster's face-plane quadrics.
    Quadric,
}

params! {
    /// Parameters of `dual`.
    pub struct DualParams {
        /// Vertex placement: "closest-vertex", "centroid", "projected" or "quadric".
        pub placement: Placement = Placement::Projected,
        /// Most diagnose-and-repair rounds before giving up.
        pub max_repair_rounds: u32 = 40,
        /// Minimisation passes after each repair round (0 = none).
        pub relax_passes: u32 = 8,
        /// Move the vertices of faces that face away from the input surface nearest them
        /// (a part thinner than a cluster) to points of their clusters where fewer do
        /// (off where a post-process re-triangulates anyway: it fixes its own).
        pub fix_facing: bool = true,
        /// Keep the clusters the repairs relax off the far side of thin sheets (as `cluster.cvt`'s `fold_guard`).
        pub fold_guard: bool = false,
    }
}

impl Params for DualParams {}

/// How [`dual`] repairs a clustering that has no valid dual.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Repair {
    /// Most diagnose-and-repair rounds before giving up.
    pub max_rounds: u32,
    /// Minimisation passes after each repair round (0 = none).
    pub relax_passes: u32,
    /// Whether those passes refuse moves into clusters facing away (`cluster.cvt`'s `fold_guard`).
    pub fold_guard: bool,
}

/// The dual of a clustering: output mesh and figures.
#[derive(Clone, Debug)]
pub struct Dual {
    /// The output mesh: one vertex per cluster.
    pub mesh: Mesh,
    /// Repairs made.
    pub stats: DualStats,
    /// Clusters whose vertex was put on the input boundary.
    pub boundary_clusters: usize,
    /// Quadric placements that fell back to the projected centroid.
    pub quadric_fallbacks: usize,
    /// Vertices moved to their (unsnapped) projected centroid to undo a degenerate face.
    pub degenerate_fixes: usize,
}

/// The dual triangulation of `mesh` clustered by `labels` (`0..n`): repairs the clustering
/// where needed (the repaired labels are written back), places the vertices (projecting
/// onto the indexed `surface`, or onto `mesh` itself when `None`), carries the vertex
/// attributes. `topo` is `mesh`'s adjacency; with `fix_facing`, faces facing away from
/// the surface get their vertices moved where fewer do (see [`DualParams`]).
pub fn dual(
    mesh: &Mesh,
    topo: &Topology,
    labels: &mut Vec<u32>,
    placement: Placement,
    surface: Option<&Facing<'_>>,
    repair: Repair,
    fix_facing: bool,
) -> Result<Dual, DualError> {
    repaired(mesh, topo, labels, repair)?.finish(mesh, labels, placement, surface, fix_facing)
}

/// A clustering repaired for its dual, with the dual's faces: [`dual`] up to the placement,
/// which needs no more of the adjacency than the boundary kept here (so that a caller can
/// let the adjacency go before it indexes the surface to place on).
pub struct Repaired {
    n: usize,
    faces: Vec<[u32; 3]>,
    stats: DualStats,
    boundary: Boundary,
}

/// What the placement reads of the clustered mesh's adjacency: its boundary.
struct Boundary {
    /// The boundary edges (of one face), in the adjacency's edge order: (face, ends).
    edges: Vec<(u32, [u32; 2])>,
    /// The closed boundary loops of three or more vertices, each with the face along its
    /// edge `j → j + 1` (`None` where the adjacency finds none).
    loops: Vec<(Vec<u32>, Vec<Option<u32>>)>,
}

impl Boundary {
    fn of(topo: &Topology) -> Boundary {
        let edges = (0..topo.n_edges() as u32)
            .filter_map(|e| match topo.edge_faces(e) {
                &[f] => Some((f, topo.edge(e))),
                _ => None,
            })
            .collect();
        let loops = (0..topo.n_boundary_loops())
            .filter_map(|i| {
                let lp = topo.boundary_loop(i);
                let k = lp.len();
                if k < 3 || lp[0] == lp[k - 1] {
                    return None;
                }
                let faces = (0..k)
                    .map(|j| {
                        topo.find_edge(lp[j], lp[(j + 1) % k])
                            .and_then(|e| topo.edge_faces(e).first().copied())
                    })
                    .collect();
                Some((lp.to_vec(), faces))
            })
            .collect();
        Boundary { edges, loops }
    }
}

/// The first part of [`dual`]: the checks and the repairs of the clustering (the repaired
/// labels are written back), with what the rest needs of `topo`.
pub fn repaired(
    mesh: &Mesh,
    topo: &Topology,
    labels: &mut Vec<u32>,
    repair: Repair,
) -> Result<Repaired, DualError> {
    if let Some(f) = (0..mesh.n_faces() as u32).find(|&f| topo.is_skipped_face(f)) {
        return Err(DualError::NotManifold(format!("face {f} repeats a vertex")));
    }
    if let Some(&e) = topo.non_manifold_edges().first() {
        let [a, b] = topo.edge(e);
        return Err(DualError::NotManifold(format!(
            "edge {a}-{b} has {} faces or a flipped orientation",
            topo.edge_faces(e).len()
        )));
    }
    if let Some(&v) = topo.non_manifold_vertices().first() {
        return Err(DualError::NotManifold(format!(
            "vertex {v} has {} fans",
            topo.n_vertex_fans(v)
        )));
    }
    if labels.len() != mesh.n_faces() {
        return Err(DualError::BadLabels(format!(
            "{} labels for {} faces",
            labels.len(),
            mesh.n_faces()
        )));
    }
    let n = labels.iter().max().map_or(0, |&m| m as usize + 1);
    let mut count = vec![0usize; n];
    labels.iter().for_each(|&l| count[l as usize] += 1);
    if let Some(c) = count.iter().position(|&k| k == 0) {
        return Err(DualError::BadLabels(format!(
            "cluster {c} has no face (labels must be 0..n, every value used)"
        )));
    }
    if let Some(why) = short_boundary_loop(topo) {
        return Err(DualError::NoDual(why));
    }
    if let Some(why) = too_few_vertices(topo, n) {
        return Err(DualError::TooFew(why));
    }
    let (faces, stats) = build::repaired_dual(mesh, topo, labels, n, repair)?;
    Ok(Repaired {
        n,
        faces,
        stats,
        boundary: Boundary::of(topo),
    })
}

impl Repaired {
    /// The rest of [`dual`] for the `mesh` and repaired `labels` this came from: the
    /// placement, the fixes of flat triangles and of triangles facing away from the
    /// surface, the output mesh with its vertex origins.
    pub fn finish(
        self,
        mesh: &Mesh,
        labels: &[u32],
        placement: Placement,
        surface: Option<&Facing<'_>>,
        fix_facing: bool,
    ) -> Result<Dual, DualError> {
        let Repaired {
            n,
            faces,
            stats,
            boundary,
        } = self;
        // One index of the surface serves the placement and the flipped-face test.
        let own;
        let facing = match surface {
            Some(f) => f,
            None => {
                own = Facing::new(mesh);
                &own
            }
        };
        // Each cluster's faces, ascending: for the centroids and the vertex origins.
        let (start, members) = faces_by_cluster(labels, n);
        let centroids = cluster_centroids(mesh, &start, &members);
        let (mut positions, on_boundary, quadric_fallbacks) =
            place(mesh, &boundary, labels, &centroids, placement, facing.bvh());
        let boundary_clusters = on_boundary.iter().filter(|&&b| b).count();
        let fixes = Fixes {
            mesh,
            labels,
            faces: &faces,
            facing,
            boundary: &boundary,
            centroids: &centroids,
            on_boundary: &on_boundary,
            fix_facing,
            diag2: mesh.bbox().diagonal().powi(2),
            n,
        };
        let (mut moved, turned) = fixes.to_projected_centroids(&mut positions);
        moved += fixes.to_better_points(&mut positions, &turned);
        if let Some(f) = faces.iter().find(|f| fixes.flat(f, &positions)) {
            return Err(DualError::Unrepaired(format!(
                "the output vertex of cluster {} lies on a degenerate triangle",
                f[0]
            )));
        }
        // Origins serve only to carry vertex attributes: none, none to gather.
        let origins = match mesh.vertex_attrs.is_empty() {
            true => {
                let mut o = VertexOrigins::with_capacity(n);
                (0..n).for_each(|_| o.push_unknown());
                o
            }
            false => vertex_origins(mesh, &start, &members),
        };
        let mut fo = FaceOrigins::with_capacity(faces.len());
        faces.iter().for_each(|_| fo.push_unknown());
        let (out, _) = mesh.rebuilt(positions, faces, &origins, &fo);
        Ok(Dual {
            mesh: out,
            stats,
            boundary_clusters,
            quadric_fallbacks,
            degenerate_fixes: moved,
        })
    }
}

/// What the fixes after the placement read: a degenerate output face (e.g. three closest
/// vertices in a row on a flat part), or one facing away from the input surface nearest
/// its centroid (closest-vertex placement on a curved part), gets its clusters' vertices
/// moved (the report's `degenerate_fixes`).
struct Fixes<'a> {
    mesh: &'a Mesh,
    labels: &'a [u32],
    /// The output faces, over the clusters.
    faces: &'a [[u32; 3]],
    facing: &'a Facing<'a>,
    boundary: &'a Boundary,
    centroids: &'a [DVec3],
    /// Per cluster: placed on the input boundary.
    on_boundary: &'a [bool],
    fix_facing: bool,
    /// The squared diagonal of the mesh's box, the scale of a flat triangle.
    diag2: f64,
    /// Clusters.
    n: usize,
}

/// What the second fix reads around the clusters it tries to move.
struct Around {
    /// Per cluster: its faces of the clustered mesh.
    members: Vec<Vec<u32>>,
    /// Per cluster kept on the boundary: its boundary edges.
    edges_of: Vec<Vec<[DVec3; 2]>>,
    /// Per cluster: the output faces at its vertex.
    faces: Vec<Vec<usize>>,
}

impl Fixes<'_> {
    /// Whether output face `f` is degenerate at `positions`.
    fn flat(&self, f: &[u32; 3], positions: &[DVec3]) -> bool {
        let [a, b, c] = f.map(|i| positions[i as usize]);
        coarsen_geom::triangle::area(a, b, c) <= 1e-10 * self.diag2
    }

    /// Whether output face `f` faces away from the input surface at `positions`.
    fn away(&self, f: &[u32; 3], positions: &[DVec3]) -> bool {
        let [a, b, c] = f.map(|i| positions[i as usize]);
        self.facing.faces_away(a, b, c)
    }

    /// With `fix_facing`, clusters on the input boundary (whose vertices the placement put
    /// on it) stay out of the first move: they try points of their boundary edges first,
    /// and leave the boundary only when none of those will do.
    fn rim(&self, c: usize) -> bool {
        self.fix_facing && self.on_boundary[c]
    }

    /// The clusters (output vertices) of the faces `pick` selects, ascending.
    fn clusters_of(&self, pick: impl Fn(usize) -> bool) -> Vec<u32> {
        let mut v: Vec<u32> = (0..self.faces.len())
            .filter(|&i| pick(i))
            .flat_map(|i| self.faces[i])
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// The first fix: the vertices of flat faces and faces facing away go to their
    /// clusters' projected centroids, the most central choice. Returns how many moved,
    /// and per output face whether it faces away now.
    fn to_projected_centroids(&self, positions: &mut [DVec3]) -> (usize, Vec<bool>) {
        // Per output face: whether it faces away (the costly test, run in parallel, and
        // again only for faces whose vertices move).
        let mut turned: Vec<bool> = self
            .faces
            .par_iter()
            .map(|f| self.away(f, positions))
            .collect();
        let mut bad = self.clusters_of(|i| self.flat(&self.faces[i], positions) || turned[i]);
        bad.retain(|&c| !self.rim(c as usize));
        if !bad.is_empty() {
            // Unsnapped: a boundary cluster between two others on a straight boundary would
            // otherwise give a flat triangle; its vertex then stays just inside the boundary.
            let projected: Vec<DVec3> = bad
                .par_iter()
                .map(|&c| {
                    let g = self.centroids[c as usize];
                    self.facing.bvh().closest_point(g).map_or(g, |h| h.point)
                })
                .collect();
            let mut changed = vec![false; self.n];
            for (&c, p) in bad.iter().zip(projected) {
                positions[c as usize] = p;
                changed[c as usize] = true;
            }
            turned
                .par_iter_mut()
                .zip(self.faces)
                .filter(|(_, f)| f.iter().any(|&c| changed[c as usize]))
                .for_each(|(t, f)| *t = self.away(f, positions));
        }
        (bad.len(), turned)
    }

    /// The second fix, for the triangles still flat (or, with `fix_facing`, facing away:
    /// `turned`). Centroids in a row (e.g. thin clusters along a straight strip), or a face
    /// across a part thinner than a cluster (nearest the opposite sheet): each vertex of
    /// such a triangle tries points of its cluster ([`Fixes::to_better_point`]). Returns
    /// how many moved.
    fn to_better_points(&self, positions: &mut [DVec3], turned: &[bool]) -> usize {
        let still = self.clusters_of(|i| {
            self.flat(&self.faces[i], positions) || (self.fix_facing && turned[i])
        });
        if still.is_empty() {
            return 0;
        }
        let around = self.around(&still);
        still
            .iter()
            .filter(|&&c| self.to_better_point(c, &around, positions))
            .count()
    }

    /// The faces, boundary edges and output faces of the clusters `involved`.
    fn around(&self, involved_clusters: &[u32]) -> Around {
        let n = self.n;
        let mut involved = vec![false; n];
        involved_clusters
            .iter()
            .for_each(|&c| involved[c as usize] = true);
        let mut members: Vec<Vec<u32>> = vec![Vec::new(); n];
        for (f, &c) in self.labels.iter().enumerate() {
            if involved[c as usize] {
                members[c as usize].push(f as u32);
            }
        }
        // The boundary edges of the involved clusters kept on the boundary by the first fix.
        let mut edges_of: Vec<Vec<[DVec3; 2]>> = vec![Vec::new(); n];
        for &(f, ends) in &self.boundary.edges {
            let c = self.labels[f as usize] as usize;
            if involved[c] && self.rim(c) {
                edges_of[c].push(ends.map(|v| self.mesh.positions[v as usize]));
            }
        }
        let mut faces: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (i, f) in self.faces.iter().enumerate() {
            f.iter()
                .filter(|&&c| involved[c as usize])
                .for_each(|&c| faces[c as usize].push(i));
        }
        Around {
            members,
            edges_of,
            faces,
        }
    }

    /// The (flat, facing away) counts of the output triangles around cluster `c`.
    fn score(&self, c: u32, around: &Around, positions: &[DVec3]) -> (usize, usize) {
        around.faces[c as usize]
            .iter()
            .fold((0, 0), |(fl, aw), &i| {
                let f = &self.faces[i];
                (
                    fl + self.flat(f, positions) as usize,
                    aw + self.away(f, positions) as usize,
                )
            })
    }

    /// The smallest angle of the output triangles around cluster `c`.
    fn smallest_angle(&self, c: u32, around: &Around, positions: &[DVec3]) -> f64 {
        around.faces[c as usize]
            .iter()
            .map(|&i| {
                let [a, b, cc] = self.faces[i].map(|k| positions[k as usize]);
                coarsen_geom::triangle::min_angle(a, b, cc)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Moves cluster `c`'s vertex to a better point, if one will do: a cluster kept on the
    /// boundary first tries points of its boundary edges ([`Fixes::rim_point`]), then
    /// every cluster points of its faces and of the surface ([`Fixes::inner_point`]).
    /// Returns whether it moved.
    fn to_better_point(&self, c: u32, around: &Around, positions: &mut [DVec3]) -> bool {
        let now = self.score(c, around, positions);
        if now.0 == 0 && now.1 == 0 {
            return false;
        }
        if let Some(p) = self.rim_point(c, around, positions) {
            positions[c as usize] = p;
            return true;
        }
        match self.inner_point(c, now, around, positions) {
            Some(p) => {
                positions[c as usize] = p;
                true
            }
            None => false,
        }
    }

    /// Of the ends and middles of cluster `c`'s boundary edges (nearest first), those that
    /// leave none of its triangles flat or facing away, the one with the largest smallest
    /// angle. `positions` comes back as it came.
    fn rim_point(&self, c: u32, around: &Around, positions: &mut [DVec3]) -> Option<DVec3> {
        let here = positions[c as usize];
        let mut on_rim: Vec<(f64, u64, DVec3)> = around.edges_of[c as usize]
            .iter()
            .enumerate()
            .flat_map(|(i, &[a, b])| {
                [a, a.lerp(b, 0.5), b]
                    .into_iter()
                    .enumerate()
                    .map(move |(k, p)| (p.distance_squared(here), (i as u64) << 2 | k as u64, p))
            })
            .collect();
        on_rim.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut kept = None;
        for (_, _, p) in on_rim {
            positions[c as usize] = p;
            if self.score(c, around, positions) != (0, 0) {
                continue;
            }
            let shape = self.smallest_angle(c, around, positions);
            if kept.is_none_or(|(_, w)| shape > w) {
                kept = Some((p, shape));
            }
        }
        positions[c as usize] = here;
        kept.map(|(p, _)| p)
    }

    /// Each face's centroid of cluster `c`, and the points halfway from it to the face's
    /// corners (the centroids alone are in a row too under a fan of faces on a straight
    /// line), and against faces facing away the nearest point of the surface's side the
    /// cluster faces (across a part thinner than a cluster, the side its triangles belong
    /// on). Against flat triangles (`now`: the current score) it takes, of those that
    /// leave none of its triangles flat, the one with the fewest facing away (nearest
    /// first); against faces facing away, one that leaves fewer facing away and none flat,
    /// the one whose triangles keep the largest smallest angle. `positions` comes back as
    /// it came.
    fn inner_point(
        &self,
        c: u32,
        now: (usize, usize),
        around: &Around,
        positions: &mut [DVec3],
    ) -> Option<DVec3> {
        let (mesh, here) = (self.mesh, positions[c as usize]);
        let members = &around.members[c as usize];
        let mut cand: Vec<(f64, u64, DVec3)> = members
            .iter()
            .flat_map(|&f| {
                let g = mesh.face_centroid(f as usize);
                let [a, b, cc] = mesh.corners(f as usize);
                [g, g.lerp(a, 0.5), g.lerp(b, 0.5), g.lerp(cc, 0.5)]
                    .into_iter()
                    .enumerate()
                    .map(move |(k, p)| {
                        (p.distance_squared(here), (u64::from(f) << 2) | k as u64, p)
                    })
            })
            .collect();
        if now.1 > 0 {
            let normal = mesh.faces_cross(members);
            if let Some(p) = self
                .facing
                .project_facing(self.centroids[c as usize], normal)
            {
                cand.push((p.distance_squared(here), u64::MAX, p));
            }
        }
        cand.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut best: Option<((usize, usize), DVec3, f64)> = None;
        for (_, _, p) in cand {
            positions[c as usize] = p;
            let sc = self.score(c, around, positions);
            if sc.0 > 0 || (now.0 == 0 && sc.1 >= now.1) {
                continue;
            }
            // Flat triangles: the nearest of the fewest facing away (angles not looked at).
            let shape = match now.0 {
                0 => self.smallest_angle(c, around, positions),
                _ => 0.0,
            };
            if best.is_none_or(|(b, _, w)| sc.1 < b.1 || (sc.1 == b.1 && shape > w)) {
                best = Some((sc, p, shape));
            }
        }
        positions[c as usize] = here;
        best.map(|(_, p, _)| p)
    }
}

/// Why `n` vertices cannot make a valid mesh of `topo`'s topology, if they cannot: every
/// boundary loop needs three vertices of its own, and a closed component of Euler
/// characteristic χ needs at least (7 + √(49 − 24χ))/2 (Heawood: 4 for a sphere, 7 for a
/// torus). Necessary conditions only.
fn too_few_vertices(topo: &Topology, n: usize) -> Option<String> {
    let nc = topo.n_components();
    let mut loops = vec![0usize; nc];
    for i in 0..topo.n_boundary_loops() {
        let comp = topo
            .boundary_loop(i)
            .first()
            .and_then(|&v| topo.vertex_faces(v).first())
            .map(|&f| topo.face_components()[f as usize] as usize);
        if let Some(c) = comp.filter(|&c| c < nc) {
            loops[c] += 1;
        }
    }
    // χ of each component, worked out once by the adjacency (the runner's manifold check
    // has usually asked for it already).
    let chi = topo.component_euler();
    let mut need = 0usize;
    let mut worst = (0usize, 0usize);
    for c in 0..nc {
        let m = if loops[c] > 0 {
            3 * loops[c]
        } else {
            let chi = chi[c] as f64;
            ((7.0 + (49.0 - 24.0 * chi).max(0.0).sqrt()) / 2.0).ceil() as usize
        };
        need += m;
        if m > worst.1 {
            worst = (c, m);
        }
    }
    (n < need).then(|| {
        format!(
            "{n} vertices cannot make a valid mesh of this topology: it needs at least {need} \
             (component {} of {nc} alone needs {}: three per boundary loop, four for a closed \
             sphere, seven for a torus)",
            worst.0, worst.1
        )
    })
}

/// A boundary loop along fewer than three faces, if any: its output loop needs three
/// clusters, each with a face on it, so no clustering has a valid dual (e.g. a component
/// of two triangles).
fn short_boundary_loop(topo: &Topology) -> Option<String> {
    (0..topo.n_boundary_loops()).find_map(|i| {
        let lp = topo.boundary_loop(i);
        let faces = topo.faces_along_loop(i);
        (faces.len() < 3).then(|| {
            format!(
                "the boundary loop through vertex {} runs along only {} faces, and the dual of \
                 a boundary loop needs three (one vertex per face along it); subdividing the \
                 mesh first (the `subdivide` stage, as `uniform-cvt` does) gives it more",
                lp.first().copied().unwrap_or(0),
                faces.len()
            )
        })
    })
}

/// Each cluster's vertex as the area-weighted blend of its faces' corners (the clusters'
/// faces as [`faces_by_cluster`] gives them).
fn vertex_origins(mesh: &Mesh, start: &[usize], order: &[u32]) -> VertexOrigins {
    let n = start.len().saturating_sub(1);
    // Per cluster, in parallel (runs of clusters, each with its own table of where a
    // vertex sits in the blend, a word per vertex of the mesh: at most 16 of them): its
    // faces' corners in order of first appearance, the weights summed per vertex.
    let runs = (4 * rayon::current_num_threads()).clamp(1, 16);
    let run = n.div_ceil(runs).max(1);
    let blends: Vec<Vec<(u32, f64)>> = (0..n.div_ceil(run))
        .into_par_iter()
        .map(|k| {
            let mut slot = vec![u32::MAX; mesh.n_vertices()];
            (k * run..n.min((k + 1) * run))
                .map(|c| {
                    let mut blend: Vec<(u32, f64)> = Vec::new();
                    for &f in &order[start[c]..start[c + 1]] {
                        let w = mesh.face_area(f as usize) / 3.0 + f64::MIN_POSITIVE;
                        for &v in &mesh.faces[f as usize] {
                            match slot[v as usize] {
                                u32::MAX => {
                                    slot[v as usize] = blend.len() as u32;
                                    blend.push((v, w));
                                }
                                i => blend[i as usize].1 += w,
                            }
                        }
                    }
                    for &(v, _) in &blend {
                        slot[v as usize] = u32::MAX;
                    }
                    blend
                })
                .collect::<Vec<_>>()
        })
        .flatten_iter()
        .collect();
    // Each vertex is a source of every cluster around it: of one inside a cluster, of
    // two or three on a border.
    let total = blends.iter().map(Vec::len).sum();
    let mut o = VertexOrigins::with_capacities(n, total);
    blends.into_iter().for_each(|b| o.push_blend(b));
    o
}

/// Output positions from the clusters' `centroids`, projecting through `bvh` (the surface's
/// index), boundary clusters snapped onto their boundary runs: `(positions, per cluster
/// whether it is on the boundary, quadric fall-backs)`.
fn place(
    mesh: &Mesh,
    boundary: &Boundary,
    labels: &[u32],
    centroids: &[DVec3],
    placement: Placement,
    bvh: &Bvh,
) -> (Vec<DVec3>, Vec<bool>, usize) {
    let n = centroids.len();
    let project = |p: DVec3| bvh.closest_point(p).map_or(p, |h| h.point);
    let mut fallbacks = 0;
    let mut pos: Vec<DVec3> = match placement {
        Placement::Centroid => centroids.to_vec(),
        Placement::Projected => centroids.par_iter().map(|&c| project(c)).collect(),
        Placement::ClosestVertex => {
            // Each cluster takes its nearest vertex not taken by a lower-numbered cluster,
            // so that no two output vertices coincide (the centroid when all are taken).
            let mut cand: Vec<(u32, f64, u32)> = Vec::with_capacity(3 * mesh.n_faces());
            for (f, &c) in labels.iter().enumerate() {
                for &v in &mesh.faces[f] {
                    let d = mesh.positions[v as usize].distance_squared(centroids[c as usize]);
                    cand.push((c, d, v));
                }
            }
            cand.sort_unstable_by(|a, b| {
                a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2))
            });
            let mut taken = vec![false; mesh.n_vertices()];
            let mut pos = centroids.to_vec();
            let mut i = 0;
            for (c, p) in pos.iter_mut().enumerate() {
                let mut done = false;
                while i < cand.len() && cand[i].0 == c as u32 {
                    let v = cand[i].2 as usize;
                    if !done && !taken[v] {
                        taken[v] = true;
                        *p = mesh.positions[v];
                        done = true;
                    }
                    i += 1;
                }
            }
            pos
        }
        Placement::Quadric => {
            let mut q = vec![Quadric::ZERO; n];
            let mut boxes = vec![Aabb::EMPTY; n];
            for (f, &c) in labels.iter().enumerate() {
                let [a, b, cc] = mesh.corners(f);
                let normal = mesh.face_normal(f);
                if normal != DVec3::ZERO {
                    q[c as usize] += Quadric::from_plane(normal, a, mesh.face_area(f));
                }
                [a, b, cc].iter().for_each(|p| boxes[c as usize].grow(*p));
            }
            (0..n)
                .map(|c| {
                    let p0 = project(centroids[c]);
                    let m = q[c].matrix();
                    let trace = q[c].a[0] + q[c].a[3] + q[c].a[5];
                    let mu = 1e-3 * trace;
                    let reg = m + coarsen_geom::DMat3::from_diagonal(DVec3::splat(mu));
                    let rhs = -q[c].b + mu * p0;
                    let bx = boxes[c];
                    let margin = 0.5 * bx.diagonal();
                    let inside = |x: DVec3| {
                        (bx.min - DVec3::splat(margin)).cmple(x).all()
                            && x.cmple(bx.max + DVec3::splat(margin)).all()
                    };
                    match coarsen_geom::solve::solve3(reg, rhs, 1e-14) {
                        Some(x) if trace > 0.0 && inside(x) => x,
                        _ => {
                            fallbacks += 1;
                            p0
                        }
                    }
                })
                .collect()
        }
    };
    // Clusters on the boundary: their vertex goes to the middle (by arc length) of their
    // run of boundary edges, so the output boundary vertices are spread evenly along it;
    // the nearest point of their boundary edges where no run is found.
    let mut best: Vec<Option<(f64, DVec3)>> = vec![None; n];
    for &(f, ends) in &boundary.edges {
        let c = labels[f as usize] as usize;
        let [a, b] = ends.map(|v| mesh.positions[v as usize]);
        let p = closest_point_on_segment(pos[c], a, b).0;
        let d = p.distance_squared(pos[c]);
        if best[c].is_none_or(|(bd, _)| d < bd) {
            best[c] = Some((d, p));
        }
    }
    for (c, mid) in boundary_run_middles(mesh, boundary, labels, n)
        .into_iter()
        .enumerate()
    {
        if let Some(p) = mid {
            best[c] = Some((0.0, p));
        }
    }
    let mut on_boundary = vec![false; n];
    for (c, b) in best.iter().enumerate() {
        if let Some((_, p)) = b {
            pos[c] = *p;
            on_boundary[c] = true;
        }
    }
    (pos, on_boundary, fallbacks)
}

/// Per cluster: the arc-length middle of its longest run of consecutive boundary edges
/// along a closed boundary loop (`None` for clusters off the boundary, and for loops met
/// by one cluster only).
fn boundary_run_middles(
    mesh: &Mesh,
    boundary: &Boundary,
    labels: &[u32],
    n: usize,
) -> Vec<Option<DVec3>> {
    let mut out: Vec<Option<(f64, DVec3)>> = vec![None; n];
    for (lp, edge_faces) in &boundary.loops {
        let k = lp.len();
        // The cluster of each edge lp[j] → lp[j + 1].
        let ec: Vec<Option<u32>> = edge_faces
            .iter()
            .map(|f| f.map(|f| labels[f as usize]))
            .collect();
        let Some(start) = (0..k).find(|&j| ec[j] != ec[(j + k - 1) % k]) else {
            continue;
        };
        let mut j = 0;
        while j < k {
            let first = (start + j) % k;
            let c = ec[first];
            let mut len = 0;
            while j + len < k && ec[(start + j + len) % k] == c {
                len += 1;
            }
            if let Some(c) = c {
                let seg = |m: usize| {
                    let a = mesh.positions[lp[(first + m) % k] as usize];
                    let b = mesh.positions[lp[(first + m + 1) % k] as usize];
                    (a, b)
                };
                let total: f64 = (0..len).map(|m| seg(m).0.distance(seg(m).1)).sum();
                let mut left = 0.5 * total;
                let mut mid = seg(0).0;
                for m in 0..len {
                    let (a, b) = seg(m);
                    let l = a.distance(b);
                    if left <= l || m + 1 == len {
                        mid = if l > 0.0 {
                            a.lerp(b, (left / l).min(1.0))
                        } else {
                            a
                        };
                        break;
                    }
                    left -= l;
                }
                let slot = &mut out[c as usize];
                if slot.is_none_or(|(t, _)| total > t) {
                    *slot = Some((total, mid));
                }
            }
            j += len;
        }
    }
    out.into_iter().map(|o| o.map(|(_, p)| p)).collect()
}

/// The dual triangulation of the face clustering `cluster`.
pub struct DualStage(DualParams);

impl Stage for DualStage {
    type Params = DualParams;
    const KIND: &'static str = "dual";
    const SUMMARY: &'static str = "Dual triangulation of the face label `cluster`: one vertex per cluster, repairing the clustering where the dual would not be a valid manifold.";

    fn new(params: DualParams) -> Self {
        DualStage(params)
    }

    fn contract(&self) -> Contract {
        Contract {
            reads: vec![AttrRef::face(CLUSTER, AttrKind::Label)],
            writes: Vec::new(),
            clears: vec![Domain::Face],
            needs: Needs {
                manifold: true,
                ..Needs::default()
            },
            carries_wedges: false,
            restores_wedges: false,
        }
    }

    fn run(&self, mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        let p = &self.0;
        let mut labels = mesh
            .face_attrs
            .label(CLUSTER)
            .ok_or_else(|| {
                StageError::Input(format!("`{}`: no face label `{CLUSTER}`", Self::KIND))
            })?
            .to_vec();
        let topo = cx
            .topology(&mesh)
            .map_err(|e| StageError::Input(format!("`{}`: {e}", Self::KIND)))?;
        let stage_error = |e: DualError| match e {
            DualError::Unrepaired(_) => StageError::Internal(format!("`{}`: {e}", Self::KIND)),
            DualError::TooFew(_) => StageError::Param {
                name: "target",
                message: format!("`{}`: {e}", Self::KIND),
            },
            e => StageError::Input(format!("`{}`: {e}", Self::KIND)),
        };
        let repaired = repaired(
            &mesh,
            &topo,
            &mut labels,
            Repair {
                max_rounds: p.max_repair_rounds,
                relax_passes: p.relax_passes,
                fold_guard: p.fold_guard,
            },
        )
        .map_err(stage_error)?;
        let rim: Vec<DVec3> = (0..mesh.n_vertices() as u32)
            .filter(|&v| topo.is_boundary_vertex(v))
            .map(|v| mesh.positions[v as usize])
            .collect();
        // The input's index takes what it needs of the adjacency (the clustered mesh's, when
        // the clustering ran on the input) before the adjacency goes and the index's face
        // hierarchy is built: at millions of faces the two together set the run's peak.
        let has_input = cx.original.n_faces() > 0;
        let parts = match has_input && cx.input_index_at_hand::<SurfaceIndex>().is_none() {
            false => None,
            true => Some(SurfaceParts::of(
                cx.original,
                &*cx.input_topology()
                    .map_err(|e| StageError::Input(format!("`{}`: the input: {e}", Self::KIND)))?,
            )),
        };
        drop(topo);
        cx.release_topology();
        // Built from those parts unless a stage before built it.
        let facing = has_input.then(|| {
            let index = cx.input_index(|original| match parts {
                Some(parts) => parts.build(original),
                None => SurfaceIndex::new(original),
            });
            Facing::with_index(cx.original, index)
        });
        let d = repaired
            .finish(&mesh, &labels, p.placement, facing.as_ref(), p.fix_facing)
            .map_err(stage_error)?;
        let mut d = d;
        let pulled = match &facing {
            Some(facing) => pull_boundary(&mut d.mesh, &rim, facing, cx)?,
            None => Pulled::default(),
        };
        report(cx.report, p, &d, &pulled);
        Ok(d.mesh)
    }
}

/// Beyond the dual's own input: when its boundary has left the run's input's (after a
/// simplifier, whose boundary edges are chords of the input's), the boundary vertices of
/// `out` go onto the input's own boundary, from the dual input's boundary vertices `rim`.
/// A boundary on the input's (a refinement's or a subdivision's) is left to the dual,
/// which may have kept a vertex inside on purpose (a flat triangle).
fn pull_boundary(
    out: &mut Mesh,
    rim: &[DVec3],
    facing: &Facing<'_>,
    cx: &mut Context<'_>,
) -> Result<Pulled, StageError> {
    let diag = cx.original.bbox().diagonal();
    let tol = 1e-9 * diag;
    let off = rim.par_iter().any(|&p| {
        facing
            .project_boundary(p)
            .is_some_and(|q| q.distance(p) > tol)
    });
    if !off {
        return Ok(Pulled::default());
    }
    let out_topo = Topology::try_build(out)
        .map_err(|e| StageError::Internal(format!("`{}`: {e}", DualStage::KIND)))?;
    let pull = Pull {
        rim,
        interior: false,
        min_move: 1e-12 * diag,
    };
    Ok(
        match pull_onto_input(out, &out_topo, facing, pull, diag * diag) {
            Some(p) => p,
            None => {
                cx.report.warn(
                    "moving the boundary vertices onto the input's boundary would degenerate faces: they stay on the clustered mesh's boundary",
                );
                Pulled::default()
            }
        },
    )
}

/// The stage's figures, and a warning when the clustering was repaired.
fn report(r: &mut coarsen_stage::StageReport, p: &DualParams, d: &Dual, pulled: &Pulled) {
    r.figure("boundary_pulled", pulled.moved);
    r.figure("boundary_left", pulled.boundary_left);
    r.figure("vertices", d.mesh.n_vertices());
    r.figure("faces", d.mesh.n_faces());
    r.figure("placement", p.placement);
    r.figure("repairs", d.stats.repairs);
    r.figure("repair_rounds", d.stats.repair_rounds);
    r.figure("problems", d.stats.first_problems);
    r.figure("boundary_clusters", d.boundary_clusters);
    r.figure("quadric_fallbacks", d.quadric_fallbacks);
    r.figure("degenerate_fixes", d.degenerate_fixes);
    r.figure("restarted", d.stats.restarted);
    r.figure("rebuilt", d.stats.rebuilt);
    if d.stats.rebuilt {
        r.warn(
            "splitting could not repair the clustering (parts too thin for compact clusters): \
             the clusters to blame were rebuilt from single faces merged back to the count"
                .to_string(),
        );
    } else if d.stats.repairs > 0 {
        let restart = if d.stats.restarted {
            ", started again from the clustering as it came after splitting whole boundary \
             loops had not converged (the splits counted since)"
        } else {
            ""
        };
        r.warn(format!(
            "the clustering was repaired: {} clusters split (each paid for by a merge elsewhere) in {} rounds{restart}",
            d.stats.repairs, d.stats.repair_rounds
        ));
    }
}

coarsen_stage::export_stage!(DualStage);

#[cfg(test)]
mod tests;
