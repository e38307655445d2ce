//! The estimators: per-face corner terms, per-vertex sums, then the special vertices.
//!
//! The work runs in three phases, each a flat loop:
//!
//! 1. **`normalise_positions`**: positions moved to the bounding-box centre and scaled so
//!    the box's longest side is 1, so areas neither overflow nor underflow and the
//!    degenerate-area cut-off is relative to the mesh's size.
//! 2. **`vertex_sums`** (parallel over vertices): each vertex adds the terms of its corner
//!    of each face over [`Topology::vertex_faces`] in fan order (a fixed order: the same
//!    bits with any thread count) — the corner's angle, its share of the vertex area (mixed
//!    Voronoi, a third, or all of the face), the gradient of the face's area with respect
//!    to it, and the face's twice-area normal — classifies itself, and regular vertices get
//!    their curvature. The terms are worked out where they are summed, not stored per face
//!    first (at 4.4M faces that table was 640 MB).
//! 3. **`fill_special_vertices`**: boundary (by default), non-manifold and zero-area vertices
//!    take the mean of their already resolved neighbours, ring after ring outwards from
//!    the regular vertices.
//!
//! The mean-curvature normal uses the identity
//! `½ Σⱼ (cot αᵢⱼ + cot βᵢⱼ)(xᵢ − xⱼ) = ∇ₓᵢ area(one-ring)`, summing per face
//! `∇ₓᵢ area(ijk) = ½ n̂ × (xₖ − xⱼ)` (corners counter-clockwise about `n̂`). It equals the
//! cotangent Laplacian on every proper triangle, and unlike the cotangents it stays bounded
//! (by half the opposite edge) on needles and caps, where the cotangents blow up and their
//! large terms no longer cancel; a zero-area face contributes nothing.

use crate::{BoundaryMode, CurvatureParams, DeficitArea, GaussianMode, Method};
use coarsen_geom::DVec3;
use coarsen_mesh::topology::TopologyError;
use coarsen_mesh::{IndexError, Mesh, Topology};
use rayon::prelude::*;
use std::f64::consts::{PI, TAU};

/// Vertices with a mixed (or barycentric) area at or below this fraction of the squared
/// longest bounding-box side have no usable area of their own (the relative cut-off of
/// the mesh sanity check's degenerate faces).
pub const DEGENERATE_AREA_REL: f64 = coarsen_mesh::sanity::DEGENERATE_AREA_REL;

/// Parallel loops hand each thread at least this many elements: below it, splitting the
/// work costs more than it saves.
const MIN_CHUNK: usize = 2048;

/// A mesh the estimators cannot read.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CurvatureError {
    /// A vertex with a NaN or infinite coordinate.
    #[error("vertex {vertex} has a non-finite coordinate ({x}, {y}, {z})")]
    NonFinitePosition {
        /// The vertex.
        vertex: usize,
        /// Its x coordinate.
        x: f64,
        /// Its y coordinate.
        y: f64,
        /// Its z coordinate.
        z: f64,
    },
    /// A face index out of range or an attribute column of the wrong length.
    #[error(transparent)]
    Index(#[from] IndexError),
    /// A mesh too large for the adjacency tables.
    #[error(transparent)]
    Topology(#[from] TopologyError),
}

/// What kind of vertex the estimator saw.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum VertexClass {
    /// Interior, one closed fan, positive area: the estimator applies as written.
    Regular,
    /// On a boundary edge, one fan.
    Boundary,
    /// More than one fan (a bow-tie, or on an edge of three or more faces).
    NonManifold,
    /// Not boundary nor non-manifold, but with an area at or below the cut-off.
    DegenerateArea,
    /// Used by no face.
    Isolated,
}

/// Per-vertex curvature and what it took to get there.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Estimate {
    /// Gaussian curvature K per vertex.
    pub gaussian: Vec<f64>,
    /// Signed mean curvature H per vertex (positive on a convex surface with outward normals).
    pub mean: Vec<f64>,
    /// Hybrid curvature F = 0.5·K + 0.5·H² (0.5·|K| + 0.5·H² with `gaussian = "absolute"`).
    pub hybrid: Vec<f64>,
    /// What kind of vertex each one is.
    pub class: Vec<VertexClass>,
    /// Counts of the vertices handled apart from the regular ones.
    pub counts: Counts,
}

/// How many vertices were handled in each special way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counts {
    /// Interior manifold vertices with a usable area: the estimator applied as written.
    pub regular: usize,
    /// Vertices on a boundary edge (one fan).
    pub boundary: usize,
    /// Vertices whose faces form more than one fan.
    pub non_manifold: usize,
    /// Interior manifold vertices whose area is at or below the cut-off.
    pub degenerate_area: usize,
    /// Vertices used by no face: K = H = F = 0.
    pub isolated: usize,
    /// Special vertices given the mean of their resolved neighbours.
    pub from_neighbors: usize,
    /// Boundary vertices given their own one-sided estimate (`boundary = "geodesic"`, or
    /// no resolved vertex reaches them).
    pub one_sided: usize,
    /// Special vertices that nothing could resolve (no area, no resolved vertex reachable):
    /// K = H = F = 0.
    pub unresolved: usize,
    /// Values that overflowed `f64` and were clamped to ±`f64::MAX`.
    pub clamped: usize,
}

/// The terms of one corner of a face.
#[derive(Clone, Copy, Debug, Default)]
struct CornerTerms {
    /// Interior angle at the corner.
    angle: f64,
    /// The corner's share of its vertex's area.
    area: f64,
    /// Gradient of the face's area with respect to the corner.
    grad: DVec3,
    /// The face's twice-area normal `(b − a) × (c − a)`, in its own orientation.
    normal: DVec3,
}

/// What one vertex gathers from its faces.
#[derive(Clone, Copy, Debug)]
struct VertexSums {
    class: VertexClass,
    angle: f64,
    area: f64,
    grad: DVec3,
    normal: DVec3,
}

/// Estimates K, H and F at every vertex of `mesh` with the method and options of `params`.
///
/// Values are in the mesh's units (K in 1/length², H in 1/length). Every value is finite.
pub fn estimate(mesh: &Mesh, params: &CurvatureParams) -> Result<Estimate, CurvatureError> {
    estimate_with(mesh, params, &Topology::try_build(mesh)?)
}

/// [`estimate`] with the adjacency of `mesh` at hand.
pub fn estimate_with(
    mesh: &Mesh,
    params: &CurvatureParams,
    topo: &Topology,
) -> Result<Estimate, CurvatureError> {
    mesh.validate_indices()?;
    let (positions, half_side) = normalise_positions(&mesh.positions)?;
    let sums = vertex_sums(&mesh.faces, &positions, params, topo);

    let mut counts = Counts::default();
    for s in &sums {
        match s.class {
            VertexClass::Regular => counts.regular += 1,
            VertexClass::Boundary => counts.boundary += 1,
            VertexClass::NonManifold => counts.non_manifold += 1,
            VertexClass::DegenerateArea => counts.degenerate_area += 1,
            VertexClass::Isolated => counts.isolated += 1,
        }
    }

    // Regular vertices, and boundary ones when asked for their one-sided estimate.
    let geodesic = params.boundary == BoundaryMode::Geodesic;
    let mut resolved = vec![false; sums.len()];
    let mut k = vec![0.0; sums.len()];
    let mut h = vec![0.0; sums.len()];
    for (v, s) in sums.iter().enumerate() {
        let own = match s.class {
            VertexClass::Regular => Some(interior(s)),
            VertexClass::Boundary if geodesic => one_sided(s),
            _ => None,
        };
        if let Some((kv, hv)) = own {
            (k[v], h[v], resolved[v]) = (kv, hv, true);
            counts.one_sided += usize::from(s.class == VertexClass::Boundary);
        }
    }
    let special = |v: usize| {
        matches!(
            sums[v].class,
            VertexClass::Boundary | VertexClass::NonManifold | VertexClass::DegenerateArea
        )
    };
    counts.from_neighbors = fill_special_vertices(topo, &special, &mut resolved, &mut k, &mut h);
    // What no ring reached: a boundary vertex keeps its one-sided estimate, the rest 0.
    for (v, s) in sums.iter().enumerate() {
        if resolved[v] || !special(v) {
            continue;
        }
        match (s.class, one_sided(s)) {
            (VertexClass::Boundary, Some((kv, hv))) => {
                (k[v], h[v]) = (kv, hv);
                counts.one_sided += 1;
            }
            _ => counts.unresolved += 1,
        }
    }

    // Back to the mesh's units; clamp what overflows there.
    let mut clamp = |x: f64| {
        if x.is_finite() {
            x
        } else {
            counts.clamped += 1;
            if x.is_nan() {
                0.0
            } else {
                f64::MAX.copysign(x)
            }
        }
    };
    // A unit length after normalising is 2·half_side in the mesh: K ∝ 1/length², H ∝ 1/length.
    let gaussian: Vec<f64> = k
        .iter()
        .map(|&x| clamp(x * 0.25 / half_side / half_side))
        .collect();
    let mean: Vec<f64> = h.iter().map(|&x| clamp(x * 0.5 / half_side)).collect();
    let hybrid: Vec<f64> = gaussian
        .iter()
        .zip(&mean)
        .map(|(&kv, &hv)| {
            let kv = match params.gaussian {
                GaussianMode::Signed => kv,
                GaussianMode::Absolute => kv.abs(),
            };
            clamp(0.5 * kv + 0.5 * hv * hv)
        })
        .collect();
    Ok(Estimate {
        gaussian,
        mean,
        hybrid,
        class: sums.iter().map(|s| s.class).collect(),
        counts,
    })
}

/// Positions relative to the bounding-box centre, divided by the box's longest side; and
/// half that side (1 for a box of zero size, so that a point-like mesh stays as it is).
///
/// Everything is halved before it is subtracted, so boxes spanning ±`f64::MAX` stay finite.
fn normalise_positions(positions: &[DVec3]) -> Result<(Vec<DVec3>, f64), CurvatureError> {
    if let Some(vertex) = positions.iter().position(|p| !p.is_finite()) {
        let p = positions[vertex];
        return Err(CurvatureError::NonFinitePosition {
            vertex,
            x: p.x,
            y: p.y,
            z: p.z,
        });
    }
    let bbox = coarsen_geom::Aabb::from_points(positions);
    if bbox.is_empty() {
        return Ok((Vec::new(), 1.0));
    }
    let half_extent = bbox.max * 0.5 - bbox.min * 0.5;
    let centre = bbox.min * 0.5 + bbox.max * 0.5;
    let half_side = match half_extent.max_element() {
        m if m > 0.0 => m,
        _ => 1.0,
    };
    let normalised = positions
        .iter()
        .map(|&p| (p * 0.5 - centre * 0.5) / half_side)
        .collect();
    Ok((normalised, half_side))
}

/// The terms of corner `corner` (0 for `a`, 1 for `b`, 2 for `c`) of triangle `abc`.
fn corner_terms(
    a: DVec3,
    b: DVec3,
    c: DVec3,
    corner: usize,
    params: &CurvatureParams,
) -> CornerTerms {
    let normal = (b - a).cross(c - a);
    // |u × v| is twice the area at every corner, so one cross product serves all three.
    let n2 = normal.length();
    let area = 0.5 * n2;
    let dots = [(b - a).dot(c - a), (c - b).dot(a - b), (a - c).dot(b - c)];
    // atan2(0, 0) = 0: a corner on a zero-length edge has angle 0, as in `coarsen_geom`.
    let angle = n2.atan2(dots[corner]);
    let area_share = match params.method {
        Method::Meyer => mixed_areas(a, b, c, dots, n2)[corner],
        Method::AngleDeficit => match params.deficit_area {
            DeficitArea::Barycentric => area / 3.0,
            DeficitArea::IncidentSum => area,
        },
    };
    let grad = if n2 > 0.0 {
        let u = normal / n2;
        0.5 * u.cross([c - b, a - c, b - a][corner])
    } else {
        DVec3::ZERO
    };
    CornerTerms {
        angle,
        area: area_share,
        grad,
        normal,
    }
}

/// Meyer et al.'s mixed area of each corner: the Voronoi area for a non-obtuse triangle,
/// else half the area at the obtuse corner and a quarter at the two others. A right angle
/// counts as non-obtuse (both rules agree there). `dots` are the corners' edge dot products,
/// `n2` twice the area.
fn mixed_areas(a: DVec3, b: DVec3, c: DVec3, dots: [f64; 3], n2: f64) -> [f64; 3] {
    let area = 0.5 * n2;
    if n2 <= 0.0 {
        return [0.0; 3];
    }
    match dots.iter().position(|&d| d < 0.0) {
        Some(obtuse) => {
            let mut s = [0.25 * area; 3];
            s[obtuse] = 0.5 * area;
            s
        }
        None => {
            // cot of the corner angle = dot / |cross|, finite and ≥ 0 here.
            let [cot_a, cot_b, cot_c] = dots.map(|d| d / n2);
            let (ab, bc, ca) = (
                (b - a).length_squared(),
                (c - b).length_squared(),
                (a - c).length_squared(),
            );
            [
                0.125 * (ab * cot_c + ca * cot_b),
                0.125 * (ab * cot_c + bc * cot_a),
                0.125 * (ca * cot_b + bc * cot_a),
            ]
        }
    }
}

/// Every vertex's corner sums and class.
fn vertex_sums(
    faces: &[[u32; 3]],
    positions: &[DVec3],
    params: &CurvatureParams,
    topo: &Topology,
) -> Vec<VertexSums> {
    (0..topo.n_vertices() as u32)
        .into_par_iter()
        .with_min_len(MIN_CHUNK)
        .map(|v| {
            let mut s = VertexSums {
                class: VertexClass::Regular,
                angle: 0.0,
                area: 0.0,
                grad: DVec3::ZERO,
                normal: DVec3::ZERO,
            };
            for &f in topo.vertex_faces(v) {
                let Some(corner) = faces[f as usize].iter().position(|&x| x == v) else {
                    continue;
                };
                let [a, b, c] = faces[f as usize].map(|i| positions[i as usize]);
                let t = corner_terms(a, b, c, corner, params);
                s.angle += t.angle;
                s.area += t.area;
                s.grad += t.grad;
                s.normal += t.normal;
            }
            s.class = if topo.is_isolated_vertex(v) {
                VertexClass::Isolated
            } else if topo.n_vertex_fans(v) > 1 {
                VertexClass::NonManifold
            } else if topo.is_boundary_vertex(v) {
                VertexClass::Boundary
            } else if s.area <= DEGENERATE_AREA_REL {
                VertexClass::DegenerateArea
            } else {
                VertexClass::Regular
            };
            s
        })
        .collect()
}

/// K and H of an interior vertex: K = (2π − Σθ)/A, H = ±|∇A|/(2A) signed by the normal.
fn interior(s: &VertexSums) -> (f64, f64) {
    let k = (TAU - s.angle) / s.area;
    let magnitude = s.grad.length() / (2.0 * s.area);
    let h = if s.grad.dot(s.normal) < 0.0 {
        -magnitude
    } else {
        magnitude
    };
    (k, h)
}

/// K and H of a boundary vertex from its own faces: the geodesic form K = (π − Σθ)/A and
/// the normal part of the one-sided gradient, H = (∇A · n̂)/(2A) (the in-plane part is the
/// boundary curve's own bending, not the surface's). `None` when the area is unusable.
fn one_sided(s: &VertexSums) -> Option<(f64, f64)> {
    if s.area <= DEGENERATE_AREA_REL {
        return None;
    }
    let k = (PI - s.angle) / s.area;
    let h = s.grad.dot(s.normal.normalize_or_zero()) / (2.0 * s.area);
    Some((k, h))
}

/// Gives each special vertex the mean K and H of its resolved neighbours, ring by ring
/// outwards from the resolved vertices; returns how many were filled.
///
/// A ring is computed from the values of the rings before it only, then written, so the
/// result does not depend on the order within a ring nor on the thread count.
fn fill_special_vertices(
    topo: &Topology,
    special: &(dyn Fn(usize) -> bool + Sync),
    resolved: &mut [bool],
    k: &mut [f64],
    h: &mut [f64],
) -> usize {
    let n = resolved.len();
    let mut queued = vec![false; n];
    let mut ring: Vec<u32> = (0..n as u32)
        .filter(|&v| {
            special(v as usize)
                && !resolved[v as usize]
                && topo
                    .vertex_neighbors(v)
                    .iter()
                    .any(|&w| resolved[w as usize])
        })
        .collect();
    ring.iter().for_each(|&v| queued[v as usize] = true);
    let mut filled = 0;
    while !ring.is_empty() {
        let values: Vec<(f64, f64)> = {
            let (resolved, k, h) = (&*resolved, &*k, &*h);
            ring.par_iter()
                .with_min_len(MIN_CHUNK)
                .map(|&v| {
                    let (mut sk, mut sh, mut count) = (0.0, 0.0, 0usize);
                    for &w in topo.vertex_neighbors(v) {
                        if resolved[w as usize] {
                            sk += k[w as usize];
                            sh += h[w as usize];
                            count += 1;
                        }
                    }
                    let count = count.max(1) as f64;
                    (sk / count, sh / count)
                })
                .collect()
        };
        for (&v, (kv, hv)) in ring.iter().zip(values) {
            (k[v as usize], h[v as usize], resolved[v as usize]) = (kv, hv, true);
        }
        filled += ring.len();
        let mut next = Vec::new();
        for &v in &ring {
            for &w in topo.vertex_neighbors(v) {
                let wi = w as usize;
                if special(wi) && !resolved[wi] && !queued[wi] {
                    queued[wi] = true;
                    next.push(w);
                }
            }
        }
        next.sort_unstable();
        ring = next;
    }
    filled
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Per-vertex area as the estimators sum it.
    fn vertex_areas(mesh: &Mesh, params: &CurvatureParams) -> Vec<f64> {
        let topo = Topology::build(mesh);
        vertex_sums(&mesh.faces, &mesh.positions, params, &topo)
            .iter()
            .map(|s| s.area)
            .collect()
    }

    /// The corner terms of triangle `abc`, corner by corner.
    struct FaceTerms {
        angle: [f64; 3],
        area: [f64; 3],
        grad: [DVec3; 3],
    }

    fn one_face(a: DVec3, b: DVec3, c: DVec3, params: &CurvatureParams) -> FaceTerms {
        let t = [0, 1, 2].map(|k| corner_terms(a, b, c, k, params));
        FaceTerms {
            angle: t.map(|x| x.angle),
            area: t.map(|x| x.area),
            grad: t.map(|x| x.grad),
        }
    }

    #[test]
    fn mixed_areas_partition_the_surface_also_with_obtuse_triangles() {
        //   3           a fan whose triangles are obtuse at vertex 0 (two of them)
        //  / \          and at the rim (the flat one).
        // 1---0---2
        //  \ /
        //   4
        let m = Mesh::new(
            vec![
                DVec3::ZERO,
                DVec3::new(-3.0, 0.0, 0.1),
                DVec3::new(3.0, 0.0, -0.2),
                DVec3::new(-0.5, 0.4, 0.0),
                DVec3::new(0.2, -2.0, 0.3),
            ],
            vec![[0, 3, 1], [0, 2, 3], [0, 1, 4], [0, 4, 2]],
        );
        let areas = vertex_areas(&m, &CurvatureParams::default());
        let total: f64 = areas.iter().sum();
        assert!(
            (total - m.area()).abs() < 1e-12 * m.area(),
            "{total} vs {}",
            m.area()
        );
        assert!(areas.iter().all(|&a| a > 0.0));
        // One obtuse triangle: 1/2 at the obtuse corner, 1/4 elsewhere.
        let t = Mesh::new(
            vec![
                DVec3::ZERO,
                DVec3::new(4.0, 0.0, 0.0),
                DVec3::new(1.0, 0.5, 0.0),
            ],
            vec![[0, 1, 2]],
        );
        let a = vertex_areas(&t, &CurvatureParams::default());
        let area = t.area();
        assert_eq!(a, vec![0.25 * area, 0.25 * area, 0.5 * area]);
    }

    #[test]
    fn voronoi_areas_of_an_equilateral_triangle_are_thirds() {
        let t = Mesh::new(
            vec![
                DVec3::ZERO,
                DVec3::X,
                DVec3::new(0.5, 3f64.sqrt() / 2.0, 0.0),
            ],
            vec![[0, 1, 2]],
        );
        let area = t.area();
        for a in vertex_areas(&t, &CurvatureParams::default()) {
            assert!((a - area / 3.0).abs() < 1e-15);
        }
    }

    #[test]
    fn area_gradient_matches_the_cotangent_formula() {
        let (a, b, c) = (
            DVec3::new(0.1, 0.2, 0.3),
            DVec3::new(1.3, -0.2, 0.5),
            DVec3::new(0.4, 1.1, -0.2),
        );
        let t = one_face(a, b, c, &CurvatureParams::default());
        let cot = |u: DVec3, v: DVec3| u.dot(v) / u.cross(v).length();
        let (cot_b, cot_c) = (cot(a - b, c - b), cot(a - c, b - c));
        // ½ (cot c · (a − b) + cot b · (a − c)) at corner a.
        let expect = 0.5 * (cot_c * (a - b) + cot_b * (a - c));
        assert!(
            (t.grad[0] - expect).length() < 1e-14,
            "{:?} vs {expect:?}",
            t.grad[0]
        );
        let total = t.angle.iter().sum::<f64>();
        assert!((total - PI).abs() < 1e-14);
    }

    #[test]
    fn zero_area_face_has_no_gradient_and_angles_zero_or_pi() {
        let t = one_face(
            DVec3::ZERO,
            DVec3::X,
            DVec3::X * 2.0,
            &CurvatureParams::default(),
        );
        assert_eq!(t.grad, [DVec3::ZERO; 3]);
        assert_eq!(t.area, [0.0; 3]);
        assert_eq!(t.angle, [0.0, PI, 0.0]);
        let t = one_face(
            DVec3::ZERO,
            DVec3::ZERO,
            DVec3::X,
            &CurvatureParams::default(),
        );
        assert!(t.angle.iter().all(|a| a.is_finite()));
    }

    #[test]
    fn huge_and_point_like_coordinates_normalise_to_a_unit_box() {
        let big = [DVec3::splat(-f64::MAX), DVec3::new(f64::MAX, 0.0, 1.0)];
        let (p, half_side) = normalise_positions(&big).unwrap();
        assert_eq!(half_side, f64::MAX);
        assert_eq!(p[1] - p[0], DVec3::new(1.0, 0.5, 0.5));
        let (p, half_side) = normalise_positions(&[DVec3::ONE; 3]).unwrap();
        assert_eq!((half_side, p[0]), (1.0, DVec3::ZERO));
        let err = normalise_positions(&[DVec3::ZERO, DVec3::new(0.0, f64::NAN, 0.0)]);
        assert!(matches!(
            err,
            Err(CurvatureError::NonFinitePosition { vertex: 1, .. })
        ));
    }
}
