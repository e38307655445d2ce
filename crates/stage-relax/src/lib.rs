//! The `relax` stage (beyond the papers): a few sweeps of tangential relaxation that lift
//! the worst triangles of a coarse mesh without changing its connectivity.
//!
//! In each sweep every vertex, in index order, is offered a few moves: an interior vertex
//! towards the area-weighted centroid of its ring of faces, within its tangent plane
//! (`step`, half and a quarter of the way), then onto the nearest point of the run's input
//! surface when `project` is on; a boundary vertex towards the middle (or the thirds) of
//! the segment between its two boundary neighbours, then onto the nearest point of the
//! input's boundary edges. The best move is kept only when the smallest angle of the vertex's faces grows,
//! none of them turns by more than `max_turn_deg`, and (when projecting) none faces away
//! from the input normal nearest its centroid — so the mesh's minimum angle never drops, no
//! face flips, and every vertex stays on the input surface. Deterministic (one thread,
//! fixed order).
//!
//! With `flips`, each sweep first flips the interior edges whose two faces get a larger
//! smallest angle that way (same guards: no new edge duplicating one, no face turned by
//! more than `max_turn_deg`, none facing away from the input); the vertex count and the
//! topology stay.
//!
//! The report gives `moved` (moves kept, per sweep), `flipped` (edges flipped, per sweep) and `min_angle_before` /
//! `min_angle_after` in degrees.

use coarsen_geom::{DVec3, triangle};
use coarsen_mesh::Topology;
use coarsen_metrics::{Facing, SurfaceIndex};
use coarsen_spatial::closest_point_on_segment;
use coarsen_stage::{
    Context, Contract, Mesh, Needs, ParamIssue, Params, Stage, StageError, params,
};
use std::sync::Arc;

params! {
    /// Parameters of `relax`.
    pub struct RelaxParams {
        /// Sweeps over the vertices.
        pub sweeps: u32 = 4,
        /// Fraction of the way to the ring centroid tried in each move.
        pub step: f64 = 1.0,
        /// Pull each moved vertex onto the nearest point of the run's input surface.
        pub project: bool = true,
        /// A move is refused if it turns a face normal by more than this many degrees.
        pub max_turn_deg: f64 = 30.0,
        /// Also flip interior edges where that raises the smallest angle of their two faces.
        pub flips: bool = true,
    }
}

impl Params for RelaxParams {
    fn validate(&self) -> Vec<ParamIssue> {
        let mut v = Vec::new();
        coarsen_stage::params::check_range(&mut v, "sweeps", self.sweeps, 0, 1000);
        coarsen_stage::params::check_range(&mut v, "step", self.step, 0.0, 1.0);
        coarsen_stage::params::check_range(&mut v, "max_turn_deg", self.max_turn_deg, 0.0, 90.0);
        v
    }
}

/// What [`relax`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Relaxed {
    /// Moves kept in each sweep.
    pub moved: Vec<usize>,
    /// Edges flipped in each sweep.
    pub flipped: Vec<usize>,
    /// Smallest angle of the mesh before, in degrees.
    pub min_angle_before: f64,
    /// Smallest angle of the mesh after, in degrees.
    pub min_angle_after: f64,
}

/// Smallest angle of the faces `fan` of `mesh`, with vertex `v` at `p`, in radians; and
/// whether every face normal stays within `cos_turn` of `normals`.
fn fan_min_angle(
    mesh: &Mesh,
    fan: &[u32],
    v: u32,
    p: DVec3,
    normals: &[DVec3],
    cos_turn: f64,
) -> Option<f64> {
    let mut worst = f64::INFINITY;
    for (i, &f) in fan.iter().enumerate() {
        let [a, b, c] = mesh.faces[f as usize].map(|w| {
            if w == v {
                p
            } else {
                mesh.positions[w as usize]
            }
        });
        let n = triangle::normal(a, b, c);
        if n.dot(normals[i]) < cos_turn {
            return None;
        }
        worst = worst.min(triangle::min_angle(a, b, c));
    }
    Some(worst)
}

/// The surface vertices are kept on: the input mesh, its face index and its boundary edges.
pub struct Surface<'a> {
    facing: Facing<'a>,
    boundary: Vec<[DVec3; 2]>,
}

impl<'a> Surface<'a> {
    /// Indexes `mesh` (its faces and boundary edges).
    pub fn new(mesh: &'a Mesh) -> Self {
        Surface::with_index(mesh, Arc::new(SurfaceIndex::new(mesh)))
    }

    /// `mesh` with its index built earlier by [`SurfaceIndex::new`] from the same mesh.
    pub fn with_index(mesh: &'a Mesh, index: Arc<SurfaceIndex>) -> Self {
        let facing = Facing::with_index(mesh, index);
        let t = facing.topology();
        let boundary = (0..t.n_edges() as u32)
            .filter(|&e| t.is_boundary_edge(e))
            .map(|e| t.edge(e).map(|v| mesh.positions[v as usize]))
            .collect();
        Surface { facing, boundary }
    }

    /// The nearest point of the surface.
    fn project(&self, p: DVec3) -> Option<DVec3> {
        self.facing.bvh().closest_point(p).map(|h| h.point)
    }

    /// The nearest point of the boundary edges.
    fn project_boundary(&self, p: DVec3) -> Option<DVec3> {
        self.boundary
            .iter()
            .map(|[a, b]| {
                let q = closest_point_on_segment(p, *a, *b).0;
                (q, q.distance_squared(p))
            })
            .min_by(|x, y| x.1.total_cmp(&y.1))
            .map(|(q, _)| q)
    }

    /// True when the triangle `abc` does not face away from the input (the metrics'
    /// flipped-face test).
    fn agrees(&self, a: DVec3, b: DVec3, c: DVec3) -> bool {
        !self.facing.faces_away(a, b, c)
    }
}

/// One sweep of edge flips over `mesh` (in edge order, each face flipped at most once):
/// the interior edge a–b of faces abc and bad becomes c–d when the smallest angle of the
/// two faces grows, c–d is not an edge yet, neither new face turns by more than `cos_turn`
/// from the face it replaces, and both agree with `surface`. `topo` is `mesh`'s adjacency
/// before the sweep. Returns the flips made.
fn flip_sweep(
    mesh: &mut Mesh,
    topo: &Topology,
    surface: Option<&Surface<'_>>,
    cos_turn: f64,
) -> usize {
    let mut touched = vec![false; mesh.n_faces()];
    let mut added: std::collections::HashSet<[u32; 2]> = std::collections::HashSet::new();
    let key = |a: u32, b: u32| if a < b { [a, b] } else { [b, a] };
    let mut flips = 0;
    for e in 0..topo.n_edges() as u32 {
        let ef = topo.edge_faces(e);
        if ef.len() != 2 || touched[ef[0] as usize] || touched[ef[1] as usize] {
            continue;
        }
        let [a, b] = topo.edge(e);
        // f1 holds a → b, f2 holds b → a.
        let rot = |f: u32, x: u32, y: u32| -> Option<u32> {
            let t = mesh.faces[f as usize];
            (0..3)
                .find(|&i| t[i] == x && t[(i + 1) % 3] == y)
                .map(|i| t[(i + 2) % 3])
        };
        let (c, d) = match (rot(ef[0], a, b), rot(ef[1], b, a)) {
            (Some(c), Some(d)) => (c, d),
            _ => match (rot(ef[1], a, b), rot(ef[0], b, a)) {
                (Some(c), Some(d)) => (c, d),
                _ => continue,
            },
        };
        if c == d || topo.find_edge(c, d).is_some() || added.contains(&key(c, d)) {
            continue;
        }
        let p = |v: u32| mesh.positions[v as usize];
        let old = [[a, b, c], [b, a, d]];
        let new = [[a, d, c], [d, b, c]];
        let worst = |fs: &[[u32; 3]; 2]| {
            fs.iter()
                .map(|f| triangle::min_angle(p(f[0]), p(f[1]), p(f[2])))
                .fold(f64::INFINITY, f64::min)
        };
        if worst(&new) <= worst(&old) {
            continue;
        }
        let n_old = [0, 1].map(|i| triangle::normal(p(old[i][0]), p(old[i][1]), p(old[i][2])));
        let ok = new.iter().all(|f| {
            let n = triangle::normal(p(f[0]), p(f[1]), p(f[2]));
            n_old.iter().all(|o| n.dot(*o) >= cos_turn)
                && surface.is_none_or(|s| s.agrees(p(f[0]), p(f[1]), p(f[2])))
        });
        if !ok {
            continue;
        }
        let (f1, f2) = (ef[0] as usize, ef[1] as usize);
        let (g1, g2) = if rot(ef[0], a, b) == Some(c) {
            (f1, f2)
        } else {
            (f2, f1)
        };
        mesh.faces[g1] = new[0];
        mesh.faces[g2] = new[1];
        touched[f1] = true;
        touched[f2] = true;
        added.insert(key(c, d));
        flips += 1;
    }
    flips
}

/// Relaxes the vertices of `mesh` in place (see the crate docs), keeping them on `surface`
/// when given.
pub fn relax(mesh: &mut Mesh, surface: Option<&Surface<'_>>, params: &RelaxParams) -> Relaxed {
    let min_angle = |m: &Mesh| {
        (0..m.n_faces())
            .map(|f| {
                let [a, b, c] = m.corners(f);
                triangle::min_angle(a, b, c).to_degrees()
            })
            .fold(f64::INFINITY, f64::min)
    };
    let mut out = Relaxed {
        min_angle_before: min_angle(mesh),
        ..Relaxed::default()
    };
    let Ok(topo) = Topology::try_build(mesh) else {
        out.min_angle_after = out.min_angle_before;
        return out;
    };
    // The two boundary neighbours of each boundary vertex.
    let mut ends: Vec<Vec<u32>> = vec![Vec::new(); mesh.n_vertices()];
    for e in 0..topo.n_edges() as u32 {
        if topo.is_boundary_edge(e) {
            let [a, b] = topo.edge(e);
            ends[a as usize].push(b);
            ends[b as usize].push(a);
        }
    }
    let cos_turn = params.max_turn_deg.to_radians().cos();
    let mut normals = Vec::new();
    let mut topo = topo;
    for _ in 0..params.sweeps {
        if params.flips {
            let flipped = flip_sweep(mesh, &topo, surface, cos_turn);
            out.flipped.push(flipped);
            if flipped > 0 {
                match Topology::try_build(mesh) {
                    Ok(t) => topo = t,
                    Err(_) => break,
                }
            }
        }
        let mut moved = 0;
        for v in 0..mesh.n_vertices() as u32 {
            let fan = topo.vertex_faces(v);
            if fan.is_empty() || topo.n_vertex_fans(v) != 1 {
                continue;
            }
            let p = mesh.positions[v as usize];
            normals.clear();
            let (mut sum, mut area, mut normal) = (DVec3::ZERO, 0.0, DVec3::ZERO);
            for &f in fan {
                let [a, b, c] = mesh.corners(f as usize);
                let w = triangle::area(a, b, c);
                sum += w * triangle::centroid(a, b, c);
                area += w;
                normal += triangle::cross(a, b, c);
                normals.push(triangle::normal(a, b, c));
            }
            // Candidate positions, best first: the full move, then partial ones (on the
            // boundary: a third and two thirds of the way between the two neighbours).
            let mut cands = [DVec3::NAN; 3];
            if topo.is_boundary_vertex(v) {
                let [u, w] = match ends[v as usize][..] {
                    [u, w] => [u, w].map(|i| mesh.positions[i as usize]),
                    _ => continue,
                };
                for (c, s) in cands.iter_mut().zip([0.5, 1.0 / 3.0, 2.0 / 3.0]) {
                    let target = p + params.step * (u.lerp(w, s) - p);
                    *c = match surface.filter(|_| params.project) {
                        Some(sf) => sf.project_boundary(target).unwrap_or(DVec3::NAN),
                        None => target,
                    };
                }
            } else {
                let normal = normal.normalize_or_zero();
                if area <= 0.0 || normal == DVec3::ZERO {
                    continue;
                }
                let d = sum / area - p;
                let d = d - d.dot(normal) * normal;
                for (c, s) in cands.iter_mut().zip([1.0, 0.5, 0.25]) {
                    let q = p + s * params.step * d;
                    *c = match surface.filter(|_| params.project) {
                        Some(sf) => sf.project(q).unwrap_or(q),
                        None => q,
                    };
                }
            }
            let Some(before) = fan_min_angle(mesh, fan, v, p, &normals, -1.0) else {
                continue;
            };
            let agrees = |q: DVec3| {
                surface.is_none_or(|s| {
                    fan.iter().all(|&f| {
                        let [a, b, c] = mesh.faces[f as usize].map(|w| {
                            if w == v {
                                q
                            } else {
                                mesh.positions[w as usize]
                            }
                        });
                        s.agrees(a, b, c)
                    })
                })
            };
            // Rank the improving candidates; the (costlier) input-normal test goes in order.
            let mut ranked: Vec<(f64, DVec3)> = cands
                .iter()
                .filter(|q| q.is_finite() && **q != p)
                .filter_map(|&q| {
                    fan_min_angle(mesh, fan, v, q, &normals, cos_turn)
                        .filter(|&after| after > before)
                        .map(|after| (after, q))
                })
                .collect();
            ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
            if let Some(&(_, q)) = ranked.iter().find(|(_, q)| agrees(*q)) {
                mesh.positions[v as usize] = q;
                moved += 1;
            }
        }
        out.moved.push(moved);
        if moved == 0 && out.flipped.last().is_none_or(|&f| f == 0) {
            break;
        }
    }
    out.min_angle_after = min_angle(mesh);
    out
}

/// The `relax` stage.
pub struct Relax(RelaxParams);

impl Stage for Relax {
    type Params = RelaxParams;
    const KIND: &'static str = "relax";
    const SUMMARY: &'static str = "Tangential relaxation on the input surface: vertex moves that raise the smallest angle around them, no face flipped.";

    fn new(params: RelaxParams) -> Self {
        Relax(params)
    }

    fn contract(&self) -> Contract {
        Contract {
            needs: Needs {
                manifold: true,
                ..Needs::default()
            },
            ..Contract::default()
        }
    }

    fn run(&self, mut mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        let surface = (self.0.project && cx.original.n_faces() > 0)
            .then(|| Surface::with_index(cx.original, cx.input_index(SurfaceIndex::new)));
        let r = relax(&mut mesh, surface.as_ref(), &self.0);
        cx.report.figure("moved", &r.moved);
        cx.report.figure("flipped", &r.flipped);
        cx.report.figure("min_angle_before", r.min_angle_before);
        cx.report.figure("min_angle_after", r.min_angle_after);
        Ok(mesh)
    }
}

coarsen_stage::export_stage!(Relax);

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_stage::StageReport;

    /// A sphere whose vertices were pushed around on its surface: relaxing lifts its
    /// smallest angle, keeps every vertex on the sphere and flips nothing.
    #[test]
    fn relaxing_a_jittered_sphere_raises_its_smallest_angle_and_stays_on_it() {
        let original = coarsen_shapes::icosphere(1.0, 4).unwrap();
        let mut m = coarsen_shapes::icosphere(1.0, 3).unwrap();
        let mut s = 7u64;
        for p in &mut m.positions {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let t = DVec3::new(
                ((s >> 11) % 1000) as f64 / 1000.0 - 0.5,
                ((s >> 23) % 1000) as f64 / 1000.0 - 0.5,
                ((s >> 37) % 1000) as f64 / 1000.0 - 0.5,
            );
            *p = (*p + 0.08 * t).normalize();
        }
        let before = m.clone();
        let mut report = StageReport::default();
        // Moves only, so the faces stay comparable one by one.
        let params = RelaxParams {
            flips: false,
            ..RelaxParams::default()
        };
        let out = Relax::new(params)
            .run(m, &mut Context::new(&original, &mut report))
            .unwrap();
        let a0 = report.get("min_angle_before").unwrap().as_f64().unwrap();
        let a1 = report.get("min_angle_after").unwrap().as_f64().unwrap();
        assert!(a1 > a0 + 1.0, "{a0} → {a1}");
        assert!(out.faces == before.faces, "faces changed");
        for p in &out.positions {
            // On the input polyhedron: within its chord error of the unit sphere.
            assert!((p.length() - 1.0).abs() < 0.01, "{p}");
        }
        for f in 0..out.n_faces() {
            assert!(
                out.face_normal(f).dot(before.face_normal(f)) > 0.5,
                "face {f}"
            );
        }
    }

    /// A flat rhombus split along its long diagonal gets the short one.
    #[test]
    fn a_long_diagonal_is_flipped_to_the_short_one() {
        let positions = vec![
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 0.3, 0.0),
            DVec3::new(0.0, -0.3, 0.0),
        ];
        let mut m = Mesh::new(positions, vec![[0, 1, 2], [1, 0, 3]]);
        let params = RelaxParams {
            step: 0.0,
            sweeps: 1,
            ..RelaxParams::default()
        };
        let r = relax(&mut m, None, &params);
        assert_eq!(r.flipped, vec![1]);
        assert!(r.min_angle_after > r.min_angle_before + 10.0, "{r:?}");
        let t = Topology::build(&m);
        assert!(t.find_edge(2, 3).is_some() && t.find_edge(0, 1).is_none());
        assert!(t.is_consistently_oriented());
        for f in 0..2 {
            assert!(m.face_normal(f).z > 0.0);
        }
    }

    /// On a disc with holes, boundary vertices only slide along the input's boundary edges.
    #[test]
    fn boundary_vertices_stay_on_the_input_boundary() {
        let original = coarsen_shapes::disk_with_holes(2, 24, 1.0).unwrap();
        let surface = Surface::new(&original);
        let topo = Topology::build(&original);
        let mut m = original.clone();
        // Jitter the interior within the plane; the boundary starts where it is.
        for (v, p) in m.positions.iter_mut().enumerate() {
            if !topo.is_boundary_vertex(v as u32) {
                let t = (v as f64 * 12.9898).sin() * 0.01;
                *p += DVec3::new(t, -t, 0.0);
            }
        }
        let mean_min_angle = |m: &Mesh| {
            (0..m.n_faces())
                .map(|f| {
                    let [a, b, c] = m.corners(f);
                    triangle::min_angle(a, b, c)
                })
                .sum::<f64>()
                / m.n_faces() as f64
        };
        let before = mean_min_angle(&m);
        let r = relax(&mut m, Some(&surface), &RelaxParams::default());
        assert!(r.min_angle_after >= r.min_angle_before, "{r:?}");
        assert!(mean_min_angle(&m) > before, "{r:?}");
        let mut slid = 0;
        for v in 0..m.n_vertices() as u32 {
            let p = m.positions[v as usize];
            if topo.is_boundary_vertex(v) {
                let d = surface.project_boundary(p).unwrap().distance(p);
                assert!(d < 1e-12, "vertex {v} left the boundary by {d}");
                slid += usize::from(p != original.positions[v as usize]);
            }
            assert_eq!(p.z, 0.0);
        }
        assert!(slid > 0);
    }
}
