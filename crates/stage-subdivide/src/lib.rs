//! The `subdivide` stage: uniform 1-to-4 subdivision (every edge split at its midpoint),
//! `times` times. Clustering a subdivided mesh gives the CVT finer faces to work with —
//! paper 1's post-process subdivides the coarse mesh three times, and pyacvd recommends
//! subdividing before clustering. Midpoints take the mean of their edge's attributes, child
//! faces inherit their parent's (the red-green refiner's split does the work, with every
//! face red).
//!
//! With `faces_per_target_vertex`, a mesh that already has that many faces per vertex of
//! the run target is fine enough and is left as it is (ACVD subdivides only below a
//! threshold of the same kind): a 1.1M-face scan coarsened to 5000 vertices gains nothing
//! from 4.4M faces but the time to cluster them.
//!
//! With `max_edge` (and a run target), before the subdivisions, every edge longer than
//! `max_edge` target edges is split at its midpoint (red-green closed, pass after pass
//! until none is), and after each pass the edges between coplanar faces (within
//! 10⁻³ rad) that are not locally Delaunay are flipped (`flip.rs`; not on a mesh with face
//! attributes, whose labels a flip would move): a CAD export's fans of slivers spanning
//! whole faces become faces no longer than a target edge, which the clustering needs
//! (`coarsen_shapes::cad`'s plate at 1500 vertices with `uniform-cvt`: Hausdorff 7.2 % →
//! 1.7 %, flipped faces 12 → 0). Off in the shipped pipelines: on the teapot at 1200 it
//! costs `uniform-cvt` its smallest angle (16° → 0.7°).

use coarsen_stage::{Context, Contract, Mesh, ParamIssue, Params, Stage, StageError, params};

mod flip;

params! {
    /// Parameters of `subdivide`.
    pub struct SubdivideParams {
        /// How many 1-to-4 subdivisions (each multiplies the face count by 4).
        pub times: u32 = 1,
        /// Stop subdividing before the face count would pass this guard.
        pub max_faces: u64 = 8_000_000,
        /// Stop subdividing once the mesh has this many faces per vertex of the run target
        /// (0: subdivide `times` times whatever the target; without a target the same).
        pub faces_per_target_vertex: f64 = 0.0,
        /// Before the subdivisions, split every edge longer than this many edge lengths of
        /// the run target (the mean edge of a regular mesh with the target's vertex count
        /// over the input's area), pass after pass, until none is (a CAD export's slivers
        /// span whole faces: the clusters need short faces everywhere). 0: none; without a
        /// target, none.
        pub max_edge: f64 = 0.0,
    }
}

impl Params for SubdivideParams {
    fn validate(&self) -> Vec<ParamIssue> {
        let mut v = Vec::new();
        coarsen_stage::params::check_range(&mut v, "times", self.times, 0, 8);
        coarsen_stage::params::check_range(&mut v, "max_faces", self.max_faces, 1, 1 << 31);
        coarsen_stage::params::check_range(
            &mut v,
            "faces_per_target_vertex",
            self.faces_per_target_vertex,
            0.0,
            1e6,
        );
        coarsen_stage::params::check_range(&mut v, "max_edge", self.max_edge, 0.0, 1e6);
        if self.max_edge > 0.0 && self.max_edge < 0.05 {
            v.push(ParamIssue {
                field: "max_edge",
                message: format!("{} is below 0.05 (or 0 for none)", self.max_edge),
            });
        }
        v
    }
}

/// The `subdivide` stage.
pub struct Subdivide(SubdivideParams);

impl Stage for Subdivide {
    type Params = SubdivideParams;
    const KIND: &'static str = "subdivide";
    const SUMMARY: &'static str =
        "Uniform 1-to-4 subdivision, repeated; attributes carried to midpoints and child faces.";

    fn new(params: SubdivideParams) -> Self {
        Subdivide(params)
    }

    fn contract(&self) -> Contract {
        Contract::default()
    }

    fn run(&self, mut mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        // Enough faces: this many or more (a target the later stages will refuse counts
        // as none here).
        let enough = match (self.0.faces_per_target_vertex, cx.target) {
            (k, Some(t)) if k > 0.0 && t.check().is_ok() => {
                Some(k * t.vertices_for(cx.original) as f64)
            }
            _ => None,
        };
        if let (k, Some(t)) = (self.0.max_edge, cx.target)
            && k > 0.0
            && t.check().is_ok()
        {
            mesh = self.split_long(mesh, k * target_edge(cx.original, t), cx)?;
        }
        let mut done = 0;
        for _ in 0..self.0.times {
            if let Some(enough) = enough
                && mesh.n_faces() as f64 >= enough
            {
                cx.report.figure("fine_enough", true);
                break;
            }
            if (mesh.n_faces() as u64).saturating_mul(4) > self.0.max_faces {
                cx.report.warn(format!(
                    "stopped after {done} of {} subdivisions: another would pass max_faces = {}",
                    self.0.times, self.0.max_faces
                ));
                break;
            }
            let all = vec![true; mesh.n_faces()];
            let (next, _counts, carry) = coarsen_stage_refine::split_once(&mesh, &all)
                .map_err(|e| StageError::Input(e.to_string()))?;
            for w in carry.warnings() {
                cx.report.warn(w);
            }
            mesh = next;
            done += 1;
        }
        cx.report.figure("subdivisions", done);
        cx.report.figure("faces", mesh.n_faces());
        Ok(mesh)
    }
}

impl Subdivide {
    /// Splits the edges of `mesh` longer than `max_len`, pass after pass, until none is,
    /// the face count would pass `max_faces`, or [`MAX_LONG_PASSES`] passes.
    fn split_long(
        &self,
        mut mesh: Mesh,
        max_len: f64,
        cx: &mut Context<'_>,
    ) -> Result<Mesh, StageError> {
        let (mut passes, mut split, mut flips) = (0, 0, 0);
        while passes < MAX_LONG_PASSES {
            // At most every face 1-to-4.
            if (mesh.n_faces() as u64).saturating_mul(4) > self.0.max_faces {
                cx.report.warn(format!(
                    "stopped splitting long edges after {passes} passes: another could pass \
                     max_faces = {}",
                    self.0.max_faces
                ));
                break;
            }
            let (next, counts, carry) = coarsen_stage_refine::split_long_edges(&mesh, max_len)
                .map_err(|e| StageError::Input(e.to_string()))?;
            for w in carry.warnings() {
                cx.report.warn(w);
            }
            if counts.split_edges == 0 {
                break;
            }
            split += counts.split_edges;
            mesh = next;
            if mesh.face_attrs.is_empty() {
                flips += flip::flip_to_delaunay(&mut mesh);
            }
            passes += 1;
        }
        cx.report.figure("long_edge_passes", passes);
        cx.report.figure("long_edges_split", split);
        cx.report.figure("flat_flips", flips);
        Ok(mesh)
    }
}

/// Most passes of long-edge splitting (each halves the longest edges).
const MAX_LONG_PASSES: u32 = 24;

/// The mean edge length of a regular triangle mesh with the vertex count of target `t`
/// over the area of `input` (2 faces per vertex, equilateral).
fn target_edge(input: &Mesh, t: coarsen_stage::Target) -> f64 {
    let n = t.vertices_for(input).max(1) as f64;
    (4.0 * input.area() / (2.0 * n) / 3f64.sqrt()).sqrt()
}

coarsen_stage::export_stage!(Subdivide);

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::{AttrValues, DVec3, Topology};
    use coarsen_stage::{StageReport, Target};

    #[test]
    fn each_pass_quadruples_faces_and_keeps_topology_and_attributes() {
        let mut torus = coarsen_shapes::torus(2.0, 0.5, 12, 8).unwrap();
        let n = torus.n_vertices();
        torus
            .vertex_attrs
            .insert("s", AttrValues::Scalar((0..n).map(|i| i as f64).collect()));
        let mut report = StageReport::default();
        let out = Subdivide::new(SubdivideParams {
            times: 2,
            ..Default::default()
        })
        .run(torus.clone(), &mut Context::new(&torus, &mut report))
        .unwrap();
        assert_eq!(out.n_faces(), torus.n_faces() * 16);
        let t = Topology::build(&out).summary(&out);
        assert!(t.manifold && t.consistently_oriented);
        assert_eq!(t.genus_total, Some(1));
        let s = out.vertex_attrs.scalar("s").unwrap();
        assert_eq!(&s[..n], &(0..n).map(|i| i as f64).collect::<Vec<_>>()[..]);
        assert!(s.iter().all(|&x| (0.0..n as f64).contains(&x)));
    }

    #[test]
    fn the_face_guard_stops_early_and_says_so() {
        let sphere = coarsen_shapes::icosphere(1.0, 1).unwrap();
        let mut report = StageReport::default();
        let out = Subdivide::new(SubdivideParams {
            times: 3,
            max_faces: 1000,
            ..Default::default()
        })
        .run(sphere.clone(), &mut Context::new(&sphere, &mut report))
        .unwrap();
        assert_eq!(out.n_faces(), 80 * 4);
        assert_eq!(report.warnings.len(), 1);
    }

    #[test]
    fn a_mesh_with_enough_faces_per_target_vertex_is_left_as_it_is() {
        // 80 faces; at 20 faces per target vertex, 10 target vertices want 200 faces.
        let sphere = coarsen_shapes::icosphere(1.0, 1).unwrap();
        let run = |target: Option<Target>| {
            let mut report = StageReport::default();
            let mut cx = Context::new(&sphere, &mut report);
            cx.target = target;
            let out = Subdivide::new(SubdivideParams {
                times: 3,
                faces_per_target_vertex: 20.0,
                ..Default::default()
            })
            .run(sphere.clone(), &mut cx)
            .unwrap();
            (out.n_faces(), report.get("fine_enough").is_some())
        };
        assert_eq!(run(Some(Target::Vertices(10))), (320, true));
        assert_eq!(run(Some(Target::Vertices(2))), (80, true));
        assert_eq!(run(Some(Target::Vertices(1000))), (80 * 64, false));
        // Faces and ratios count through the input's vertices per face (42 / 80).
        assert_eq!(run(Some(Target::Faces(20))), (320, true));
        // No target, or one the later stages will refuse: `times` times.
        assert_eq!(run(None), (80 * 64, false));
        assert_eq!(run(Some(Target::Ratio(1.5))), (80 * 64, false));
    }

    /// A square of two triangles with its sides sampled densely (a CAD export's fan of
    /// slivers from one corner), to 100 target vertices: every edge ends no longer than
    /// the target edge, the square's area and boundary stay, and the flips leave no face
    /// thinner than the fan's.
    #[test]
    fn long_edges_split_and_flat_slivers_flip_to_the_target_edge() {
        let n = 40;
        let mut positions = vec![DVec3::ZERO];
        positions.extend((0..=n).map(|i| DVec3::new(10.0, 10.0 * i as f64 / n as f64, 0.0)));
        positions.extend(
            (0..n)
                .rev()
                .map(|i| DVec3::new(10.0 * i as f64 / n as f64, 10.0, 0.0)),
        );
        let faces: Vec<[u32; 3]> = (1..positions.len() as u32 - 1)
            .map(|i| [0, i, i + 1])
            .collect();
        let fan = Mesh::new(positions, faces);
        let smallest = |m: &Mesh| {
            (0..m.n_faces())
                .map(|f| {
                    let [a, b, c] = m.corners(f);
                    coarsen_geom::triangle::min_angle(a, b, c)
                })
                .fold(f64::INFINITY, f64::min)
        };
        let mut report = StageReport::default();
        let mut cx = Context::new(&fan, &mut report);
        cx.target = Some(Target::Vertices(100));
        let out = Subdivide::new(SubdivideParams {
            times: 0,
            max_edge: 1.0,
            ..Default::default()
        })
        .run(fan.clone(), &mut cx)
        .unwrap();
        let h = target_edge(&fan, Target::Vertices(100));
        let t = Topology::build(&out);
        let longest = (0..t.n_edges() as u32)
            .map(|e| {
                let [a, b] = t.edge(e);
                out.positions[a as usize].distance(out.positions[b as usize])
            })
            .fold(0.0, f64::max);
        assert!(longest <= h, "{longest} > {h}");
        assert!((out.area() - 100.0).abs() < 1e-9);
        let summary = t.summary(&out);
        assert!(summary.manifold && summary.consistently_oriented);
        assert_eq!(summary.n_boundary_loops, 1);
        assert!(smallest(&out) > smallest(&fan));
        assert!(report.get("flat_flips").unwrap().as_u64().unwrap() > 0);
        // Without a target nothing is split.
        let mut report = StageReport::default();
        let same = Subdivide::new(SubdivideParams {
            times: 0,
            max_edge: 1.0,
            ..Default::default()
        })
        .run(fan.clone(), &mut Context::new(&fan, &mut report))
        .unwrap();
        assert_eq!(same, fan);
    }
}
