//! The `curvature` stage: per-vertex Gaussian curvature K, signed mean curvature H and the
//! hybrid curvature F of paper 1 ("Adaptive refinement"), written as vertex attributes
//! for the refinement and feature stages that follow.
//!
//! # Estimators (`method`)
//!
//! * **`meyer`** (default; Meyer, Desbrun, Schröder & Barr 2002, as paper 1 uses it). Per
//!   vertex the *mixed area* A: per incident triangle its Voronoi part
//!   `(|PQ|² cot R + |PR|² cot Q)/8` when the triangle has no obtuse angle, else half the
//!   triangle's area at the obtuse corner and a quarter at the others (the shares
//!   partition the surface). Then `K = (2π − Σθ)/A` and the mean-curvature normal
//!   `K(x) = (1/2A) Σⱼ (cot αⱼ + cot βⱼ)(x − xⱼ)`; `H = |K(x)|/2`, negative when `K(x)`
//!   points against the vertex normal (the sum of the incident faces' area-weighted
//!   normals). H is positive on a convex surface with outward normals: 1/R on a sphere of
//!   radius R, `(R + 2r cos v)/(2r(R + r cos v))` on a torus at tube angle v.
//!   The cotangent sum is evaluated as the gradient of the one-ring's area (per face
//!   `½ n̂ × (opposite edge)`), the same vector on proper triangles but bounded on needles
//!   and caps (see [`estimate`](mod@estimate)).
//! * **`angle-deficit`**: paper 2's estimator for its Gauss-curvature feature filter (§3.3),
//!   `K = (2π − Σα)/A_v`. Paper 2 writes A_v as "the area summation of the adjacent
//!   triangles of v", with no factor, but takes the estimator from Meyer et al. (its
//!   reference 15), where each triangle gives a third of its area to each corner (the
//!   barycentric area): only then is K a curvature (1/R² on a sphere of radius R; with the
//!   whole sum it is a third of that). So `deficit_area = "barycentric"` (default) divides by
//!   a third of the sum, and `deficit_area = "incident-sum"` by the whole sum, the paper's
//!   formula as printed. H uses the same cotangent normal as `meyer`, divided by the
//!   same area A_v.
//!
//! Hybrid curvature (`gaussian`): `F = 0.5·K + 0.5·H²` (paper 1; `signed`, the default) or
//! `F = 0.5·|K| + 0.5·H²` (`absolute`: saddles count as curved too).
//!
//! # Vertices that are not interior manifold vertices
//!
//! * **Boundary** vertices (on an edge of one face): by default (`boundary = "neighbors"`)
//!   they take the mean K and H of their neighbours, filled ring by ring from the interior,
//!   because the one-sided estimate measures the boundary curve as much as the surface (a
//!   grid's corner has `π − Σθ = π/2`). With `boundary = "geodesic"` they keep their own
//!   estimate: `K = (π − Σθ)/A` and `H = (∇A · n̂)/(2A)`, the normal component of the
//!   one-sided cotangent normal (its in-plane part is the boundary's own bending).
//! * **Non-manifold** vertices (more than one fan: bow-ties, vertices of edges with three or
//!   more faces) and interior vertices whose area is at or below `1e-12 ·` (longest box
//!   side)² (all their faces degenerate): always the mean of their neighbours, as above.
//! * What no ring reaches (a component without a regular vertex, e.g. a lone triangle):
//!   a boundary vertex keeps its one-sided estimate when it has an area, anything else gets
//!   K = H = F = 0; **isolated** vertices (no face) get 0.
//!
//! Every value is finite: angles come from `atan2`, areas and divisions are guarded, and a
//! value that still overflows `f64` in the mesh's units is clamped to ±`f64::MAX` (counted).
//! A mesh with a NaN or infinite coordinate is refused with [`StageError::Input`] naming the
//! vertex. Faces with an orientation flip keep their angles and areas, but the vertex
//! normal that signs H is unreliable next to them.
//!
//! Accuracy, as the tests pin it (every vertex, relative error): on icospheres of radius
//! 0.5, 1 and 3 with 3–5 subdivisions `meyer` gives K within 0.55 % of 1/R² and H within
//! 0.004 % of 1/R; on a 400 × 100 torus (R = 2, r = 0.5) K within 0.03 % of the largest |K|
//! and H within 0.02 %. `angle-deficit` (barycentric) has a mean K within 0.6 % but a
//! largest error of 15 % that does not shrink with subdivision: a third of the area is not
//! the vertex's share where neighbouring triangles differ in shape.
//!
//! The stage reports `method`, `gaussian`, `boundary`, the `min`/`max`/`mean` of K, H and F
//! over the vertices that have faces (`gaussian_curvature`, `mean_curvature`,
//! `hybrid_curvature`), and the `vertices` counts of [`Counts`].
//!
//! ```
//! use coarsen_stage::{Context, Stage, StageReport};
//! use coarsen_stage_curvature::{Curvature, CurvatureParams, HYBRID, MEAN};
//! let sphere = coarsen_shapes::icosphere(2.0, 4).unwrap();
//! let mut report = StageReport::default();
//! let mut cx = Context::new(&sphere, &mut report);
//! let out = Curvature::new(CurvatureParams::default()).run(sphere.clone(), &mut cx)?;
//! let h = out.vertex_attrs.scalar(MEAN).unwrap();
//! assert!(h.iter().all(|&h| (h - 0.5).abs() < 0.01 * 0.5));
//! assert!(out.vertex_attrs.scalar(HYBRID).is_some());
//! # Ok::<(), coarsen_stage::StageError>(())
//! ```

pub mod estimate;

pub use estimate::{Counts, CurvatureError, Estimate, VertexClass, estimate, estimate_with};

use coarsen_stage::{
    AttrKind, AttrRef, AttrValues, Context, Contract, Mesh, Params, Stage, StageError, StageReport,
    params,
};
use serde::{Deserialize, Serialize};

/// Name of the vertex attribute holding the Gaussian curvature K.
pub const GAUSSIAN: &str = "gaussian_curvature";
/// Name of the vertex attribute holding the signed mean curvature H.
pub const MEAN: &str = "mean_curvature";
/// Name of the vertex attribute holding the hybrid curvature F.
pub const HYBRID: &str = "hybrid_curvature";

/// Which estimator computes K and H.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Meyer et al. 2002: mixed Voronoi area, angle deficit, cotangent mean-curvature normal.
    #[default]
    Meyer,
    /// Paper 2's angle deficit over the incident triangles' area (see `deficit_area`).
    AngleDeficit,
}

/// How the Gaussian curvature enters the hybrid F.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GaussianMode {
    /// F = 0.5·K + 0.5·H² (paper 1).
    #[default]
    Signed,
    /// F = 0.5·|K| + 0.5·H².
    Absolute,
}

/// What boundary vertices get.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BoundaryMode {
    /// The mean of their neighbours' values, filled ring by ring from the interior.
    #[default]
    Neighbors,
    /// Their own one-sided estimate: K = (π − Σθ)/A, H from the normal part of the
    /// one-sided cotangent normal.
    Geodesic,
}

/// The area that divides the angle deficit of `method = "angle-deficit"`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DeficitArea {
    /// A third of the incident triangles' area (Meyer et al.'s barycentric area): K → 1/R².
    #[default]
    Barycentric,
    /// The whole incident area, as paper 2 prints it: K → 1/(3R²) on a sphere.
    IncidentSum,
}

params! {
    /// Parameters of `curvature`.
    pub struct CurvatureParams {
        /// Estimator: "meyer" (mixed Voronoi area, cotangent mean-curvature normal) or
        /// "angle-deficit" (paper 2's estimator). Default "meyer".
        pub method: Method = Method::Meyer,
        /// Gaussian term of F: "signed" (F = 0.5·K + 0.5·H², paper 1) or "absolute"
        /// (F = 0.5·|K| + 0.5·H²). Default "signed".
        pub gaussian: GaussianMode = GaussianMode::Signed,
        /// Boundary vertices: "neighbors" (mean of the neighbours' values) or "geodesic"
        /// (own one-sided estimate, K = (π − Σθ)/A). Default "neighbors".
        pub boundary: BoundaryMode = BoundaryMode::Neighbors,
        /// Area of `method = "angle-deficit"`: "barycentric" (a third of the incident
        /// triangles' area) or "incident-sum" (all of it, as paper 2 prints it).
        /// Default "barycentric".
        pub deficit_area: DeficitArea = DeficitArea::Barycentric,
    }
}

impl Params for CurvatureParams {}

/// Estimates per-vertex Gaussian, mean and hybrid curvature.
pub struct Curvature(CurvatureParams);

impl Stage for Curvature {
    type Params = CurvatureParams;
    const KIND: &'static str = "curvature";
    const SUMMARY: &'static str = "Per-vertex Gaussian, mean and hybrid curvature (Meyer et al. 2002, or paper 2's angle deficit).";

    fn new(params: CurvatureParams) -> Self {
        Curvature(params)
    }

    fn contract(&self) -> Contract {
        Contract {
            writes: [GAUSSIAN, MEAN, HYBRID]
                .map(|name| AttrRef::vertex(name, AttrKind::Scalar))
                .to_vec(),
            carries_wedges: true,
            ..Contract::default()
        }
    }

    fn run(&self, mut mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        // The adjacency stays for the stages after (refinement numbers its first edges
        // with it).
        let input_error = |e: String| StageError::Input(format!("`{}`: {e}", Self::KIND));
        let topo = cx.topology(&mesh).map_err(|e| input_error(e.to_string()))?;
        let e = estimate_with(&mesh, &self.0, &topo).map_err(|e| input_error(e.to_string()))?;
        report(cx.report, &self.0, &e);
        let Estimate {
            gaussian,
            mean,
            hybrid,
            ..
        } = e;
        mesh.vertex_attrs
            .insert(GAUSSIAN, AttrValues::Scalar(gaussian));
        mesh.vertex_attrs.insert(MEAN, AttrValues::Scalar(mean));
        mesh.vertex_attrs.insert(HYBRID, AttrValues::Scalar(hybrid));
        Ok(mesh)
    }
}

/// Minimum, maximum and mean of a column over the vertices that have faces.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
struct Range {
    min: f64,
    max: f64,
    mean: f64,
}

/// The [`Range`] of `values` where `used`; `None` when no value is used.
fn range(values: &[f64], used: &[bool]) -> Option<Range> {
    let n = used.iter().filter(|&&u| u).count();
    if n == 0 {
        return None;
    }
    let mut r = Range {
        min: f64::INFINITY,
        max: f64::NEG_INFINITY,
        mean: 0.0,
    };
    // Sequential on purpose: the sum's order, hence its bits, is fixed. Each term is divided
    // first so that values near ±f64::MAX do not overflow the sum.
    for (&x, _) in values.iter().zip(used).filter(|(_, u)| **u) {
        r.min = r.min.min(x);
        r.max = r.max.max(x);
        r.mean += x / n as f64;
    }
    Some(r)
}

/// Fills the stage report: settings, value ranges, vertex counts, then warnings.
fn report(r: &mut StageReport, p: &CurvatureParams, e: &Estimate) {
    r.figure("method", p.method);
    r.figure("gaussian", p.gaussian);
    r.figure("boundary", p.boundary);
    if p.method == Method::AngleDeficit {
        r.figure("deficit_area", p.deficit_area);
    }
    let used: Vec<bool> = e
        .class
        .iter()
        .map(|&c| c != VertexClass::Isolated)
        .collect();
    r.figure(GAUSSIAN, range(&e.gaussian, &used));
    r.figure(MEAN, range(&e.mean, &used));
    r.figure(HYBRID, range(&e.hybrid, &used));
    let c = &e.counts;
    r.figure("vertices", c);
    if c.non_manifold > 0 {
        r.warn(format!(
            "{} non-manifold vertices took the mean curvature of their neighbours",
            c.non_manifold
        ));
    }
    if c.degenerate_area > 0 {
        r.warn(format!(
            "{} vertices surrounded by degenerate faces (no area) took the mean curvature of their neighbours",
            c.degenerate_area
        ));
    }
    if c.unresolved > 0 {
        r.warn(format!(
            "{} vertices have neither an area nor a neighbour with a curvature (parts without an interior vertex): K = H = F = 0 there",
            c.unresolved
        ));
    }
    if c.clamped > 0 {
        r.warn(format!(
            "{} curvature values overflowed and were clamped to ±{:e}",
            c.clamped,
            f64::MAX
        ));
    }
}

coarsen_stage::export_stage!(Curvature);

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::DVec3;
    use coarsen_shapes::{bumpy_sphere, icosphere, plane_grid, torus};

    fn run_with(mesh: &Mesh, params: CurvatureParams) -> (Mesh, StageReport) {
        let mut report = StageReport::default();
        let mut cx = Context::new(mesh, &mut report);
        let out = Curvature::new(params).run(mesh.clone(), &mut cx).unwrap();
        (out, report)
    }

    fn meyer(mesh: &Mesh) -> Estimate {
        estimate(mesh, &CurvatureParams::default()).unwrap()
    }

    fn all_finite(e: &Estimate) -> bool {
        [&e.gaussian, &e.mean, &e.hybrid]
            .iter()
            .all(|c| c.iter().all(|x| x.is_finite()))
    }

    /// Mean and largest relative error of `values` against `exact`.
    fn errors(values: &[f64], exact: f64) -> (f64, f64) {
        let rel: Vec<f64> = values.iter().map(|v| (v / exact - 1.0).abs()).collect();
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        (
            (mean / exact - 1.0).abs(),
            rel.iter().copied().fold(0.0, f64::max),
        )
    }

    #[test]
    fn spheres_of_any_radius_converge_to_one_over_r_squared_and_one_over_r() {
        for radius in [0.5, 1.0, 3.0] {
            for k in 3..=5 {
                let e = meyer(&icosphere(radius, k).unwrap());
                let (k_mean, k_max) = errors(&e.gaussian, 1.0 / (radius * radius));
                let (h_mean, h_max) = errors(&e.mean, 1.0 / radius);
                eprintln!(
                    "R={radius} k={k}: K mean {k_mean:.2e} max {k_max:.2e}; H mean {h_mean:.2e} max {h_max:.2e}"
                );
                assert!(k_mean < 0.01 && h_mean < 0.01, "R={radius} k={k}");
                assert!(h_max < 0.01, "R={radius} k={k}: H max error {h_max}");
                assert!(k_max < 0.01, "R={radius} k={k}: K max error {k_max}");
                assert_eq!(e.counts.regular, e.gaussian.len());
            }
        }
    }

    #[test]
    fn torus_curvature_matches_the_analytic_values_and_signs() {
        let (big, small) = (2.0, 0.5);
        let (n, m) = (400u32, 100u32);
        let mesh = torus(big, small, n, m).unwrap();
        let e = meyer(&mesh);
        let k_scale = 1.0 / (small * (big - small)); // largest |K|, on the inner equator
        let (mut k_worst, mut h_worst) = (0.0f64, 0.0f64);
        for v in 0..mesh.n_vertices() {
            // The shape lists vertices tube by tube: vertex v is at tube angle w below.
            let w = f64::from(v as u32 % m) / f64::from(m) * std::f64::consts::TAU;
            let k_exact = w.cos() / (small * (big + small * w.cos()));
            let h_exact = (big + 2.0 * small * w.cos()) / (2.0 * small * (big + small * w.cos()));
            if w.cos() > 0.05 {
                assert!(e.gaussian[v] > 0.0, "K at outside vertex {v}");
            } else if w.cos() < -0.05 {
                assert!(e.gaussian[v] < 0.0, "K at inside vertex {v}");
            }
            k_worst = k_worst.max((e.gaussian[v] - k_exact).abs() / k_scale);
            h_worst = h_worst.max((e.mean[v] / h_exact - 1.0).abs());
        }
        eprintln!(
            "torus: K max error {k_worst:.2e} of max |K|, H max relative error {h_worst:.2e}"
        );
        assert!(k_worst < 0.03, "K error {k_worst}");
        assert!(h_worst < 0.03, "H error {h_worst}");
    }

    #[test]
    fn plane_is_flat_inside_and_on_its_boundary() {
        let mesh = plane_grid(12, 9, 3.0).unwrap();
        for boundary in [BoundaryMode::Neighbors, BoundaryMode::Geodesic] {
            let e = estimate(
                &mesh,
                &CurvatureParams {
                    boundary,
                    ..Default::default()
                },
            )
            .unwrap();
            assert!(all_finite(&e));
            assert_eq!(e.counts.boundary, 2 * (12 + 9));
            for v in 0..mesh.n_vertices() {
                let corner = e.class[v] == VertexClass::Boundary
                    && e.gaussian[v].abs() > 1e-9
                    && boundary == BoundaryMode::Geodesic;
                if !corner {
                    assert!(
                        e.gaussian[v].abs() < 1e-9,
                        "{boundary:?} K[{v}] = {}",
                        e.gaussian[v]
                    );
                }
                assert!(
                    e.mean[v].abs() < 1e-9,
                    "{boundary:?} H[{v}] = {}",
                    e.mean[v]
                );
            }
            if boundary == BoundaryMode::Geodesic {
                // Only the four corners turn: their angles sum to π/2, so K = (π/2)/A there.
                let turning = (0..mesh.n_vertices())
                    .filter(|&v| e.gaussian[v].abs() > 1e-9)
                    .count();
                assert_eq!(turning, 4);
                assert_eq!(e.counts.one_sided, e.counts.boundary);
            } else {
                assert_eq!(e.counts.from_neighbors, e.counts.boundary);
            }
        }
    }

    #[test]
    fn boundary_vertices_of_a_cap_take_their_neighbours_curvature() {
        // The upper half of a sphere: its rim vertices get the sphere's curvature, not
        // the rim's turning.
        let sphere = icosphere(1.0, 4).unwrap();
        let keep: Vec<[u32; 3]> = sphere
            .faces
            .iter()
            .copied()
            .filter(|f| f.iter().all(|&v| sphere.positions[v as usize].z > -0.1))
            .collect();
        let cap = Mesh::new(sphere.positions.clone(), keep);
        let e = meyer(&cap);
        let rim: Vec<usize> = (0..cap.n_vertices())
            .filter(|&v| e.class[v] == VertexClass::Boundary)
            .collect();
        assert!(rim.len() > 20);
        for &v in &rim {
            assert!(
                (e.gaussian[v] - 1.0).abs() < 0.02,
                "K[{v}] = {}",
                e.gaussian[v]
            );
            assert!((e.mean[v] - 1.0).abs() < 0.02, "H[{v}] = {}", e.mean[v]);
        }
        assert_eq!(e.counts.from_neighbors, rim.len());
    }

    #[test]
    fn angle_deficit_on_a_sphere_converges_and_incident_sum_is_a_third() {
        for (radius, k) in [(0.5, 3), (0.5, 4), (0.5, 5), (3.0, 5)] {
            let mesh = icosphere(radius, k).unwrap();
            let bary = estimate(
                &mesh,
                &CurvatureParams {
                    method: Method::AngleDeficit,
                    ..Default::default()
                },
            )
            .unwrap();
            let exact = 1.0 / (radius * radius);
            let (k_mean, k_max) = errors(&bary.gaussian, exact);
            let (h_mean, h_max) = errors(&bary.mean, 1.0 / radius);
            eprintln!(
                "angle-deficit R={radius} k={k}: K mean {k_mean:.2e} max {k_max:.2e}; H mean {h_mean:.2e} max {h_max:.2e}"
            );
            assert!(k_mean < 0.01, "mean K error {k_mean}");
            // Pointwise, a third of the area is not the vertex's Voronoi share where the
            // triangles differ in shape (near the icosahedron's twelve 5-valent vertices).
            assert!(k_max < 0.2, "max K error {k_max}");
            let full = estimate(
                &mesh,
                &CurvatureParams {
                    method: Method::AngleDeficit,
                    deficit_area: DeficitArea::IncidentSum,
                    ..Default::default()
                },
            )
            .unwrap();
            for (a, b) in full.gaussian.iter().zip(&bary.gaussian) {
                assert!((3.0 * a / b - 1.0).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn absolute_hybrid_counts_saddles_as_curved() {
        let mesh = torus(2.0, 0.5, 60, 20).unwrap();
        let signed = meyer(&mesh);
        let absolute = estimate(
            &mesh,
            &CurvatureParams {
                gaussian: GaussianMode::Absolute,
                ..Default::default()
            },
        )
        .unwrap();
        let mut saddles = 0;
        for v in 0..mesh.n_vertices() {
            let h2 = signed.mean[v] * signed.mean[v];
            assert!((signed.hybrid[v] - 0.5 * (signed.gaussian[v] + h2)).abs() < 1e-12);
            assert!((absolute.hybrid[v] - 0.5 * (signed.gaussian[v].abs() + h2)).abs() < 1e-12);
            if signed.gaussian[v] < 0.0 {
                saddles += 1;
                assert!(absolute.hybrid[v] > signed.hybrid[v]);
            }
        }
        assert!(saddles > 0);
    }

    #[test]
    fn same_bits_with_one_thread_and_with_many() {
        let mut mesh = bumpy_sphere(1.0, 5, 0.25, 7.0).unwrap();
        // Some boundary too, so that the ring filling runs.
        mesh.faces
            .retain(|f| f.iter().all(|&v| mesh.positions[v as usize].z < 0.8));
        let params = CurvatureParams::default();
        let one = coarsen_testdata::on_threads(1, || estimate(&mesh, &params).unwrap());
        let two = coarsen_testdata::on_threads(2, || estimate(&mesh, &params).unwrap());
        let default = estimate(&mesh, &params).unwrap();
        assert!(one.counts.from_neighbors > 0);
        let bits = |e: &Estimate| -> Vec<u64> {
            [&e.gaussian, &e.mean, &e.hybrid]
                .iter()
                .flat_map(|c| c.iter().map(|x| x.to_bits()))
                .collect()
        };
        assert_eq!(bits(&one), bits(&two));
        assert_eq!(bits(&one), bits(&default));
    }

    #[test]
    fn zero_area_faces_bow_ties_and_isolated_vertices_give_finite_values() {
        // A fan around vertex 0 with a needle (zero-area face 0-5-6, 5 on segment 0-6),
        // a second fan touching it only at vertex 0 (a bow-tie), and an isolated vertex 9.
        //
        //      2   1            7
        //       \ /            /|
        //   3 -- 0 -- 5 -- 6  0-8   (second fan below the plane)
        //       / \
        //      4   (back to 1)
        let mut positions = vec![
            DVec3::new(0.0, 0.0, 0.1),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0),
            DVec3::new(-1.5, 0.0, 0.0),
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(0.5, 0.0, 0.05),
            DVec3::new(1.0, 0.0, 0.0),
        ];
        positions.push(DVec3::new(0.3, 0.3, -1.0));
        positions.push(DVec3::new(-0.3, 0.3, -1.0));
        positions.push(DVec3::new(5.0, 5.0, 5.0));
        let faces = vec![
            [0, 1, 2],
            [0, 2, 3],
            [0, 3, 4],
            [0, 4, 6],
            [0, 6, 1],
            [0, 5, 6],
            [0, 7, 8],
        ];
        let mesh = Mesh::new(positions, faces);
        for method in [Method::Meyer, Method::AngleDeficit] {
            for boundary in [BoundaryMode::Neighbors, BoundaryMode::Geodesic] {
                let e = estimate(
                    &mesh,
                    &CurvatureParams {
                        method,
                        boundary,
                        ..Default::default()
                    },
                )
                .unwrap();
                assert!(all_finite(&e), "{method:?} {boundary:?}: {e:?}");
                assert_eq!(e.class[0], VertexClass::NonManifold);
                assert_eq!(e.class[9], VertexClass::Isolated);
                assert_eq!((e.gaussian[9], e.mean[9], e.hybrid[9]), (0.0, 0.0, 0.0));
            }
        }
        // A closed mesh where every face of one vertex has zero area: the vertex and its
        // one-ring moved onto one line.
        let mut sphere = icosphere(1.0, 2).unwrap();
        let ring = coarsen_mesh::Topology::build(&sphere)
            .vertex_neighbors(0)
            .to_vec();
        let p0 = sphere.positions[0];
        for (i, &w) in ring.iter().enumerate() {
            sphere.positions[w as usize] = p0 + DVec3::X * (0.1 * (i as f64 + 1.0));
        }
        let e = meyer(&sphere);
        assert!(all_finite(&e));
        assert_eq!(e.class[0], VertexClass::DegenerateArea);
        assert_eq!(e.counts.from_neighbors, 1);
    }

    #[test]
    fn a_lone_triangle_has_no_interior_and_says_so() {
        let t = Mesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::Y], vec![[0, 1, 2]]);
        let e = meyer(&t);
        assert!(all_finite(&e));
        assert_eq!(e.counts.boundary, 3);
        assert_eq!(
            e.counts.one_sided, 3,
            "no interior: each keeps its own estimate"
        );
        // A zero-area triangle: not even that.
        let d = Mesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0], vec![[0, 1, 2]]);
        let e = meyer(&d);
        assert_eq!(e.counts.unresolved, 3);
        assert_eq!(e.gaussian, vec![0.0; 3]);
    }

    #[test]
    fn non_finite_coordinates_are_refused_naming_the_vertex() {
        let mut mesh = icosphere(1.0, 1).unwrap();
        mesh.positions[7].y = f64::INFINITY;
        let mut report = StageReport::default();
        let mut cx = Context::new(&mesh, &mut report);
        let err = Curvature::new(CurvatureParams::default())
            .run(mesh.clone(), &mut cx)
            .unwrap_err();
        assert!(matches!(err, StageError::Input(_)));
        assert!(err.to_string().contains("vertex 7"), "{err}");
    }

    #[test]
    fn out_of_range_faces_are_refused() {
        let mut mesh = icosphere(1.0, 1).unwrap();
        mesh.faces[3] = [0, 1, 500];
        let err = estimate(&mesh, &CurvatureParams::default()).unwrap_err();
        assert!(err.to_string().contains("face 3"), "{err}");
    }

    #[test]
    fn tiny_and_huge_meshes_keep_their_curvature_in_their_own_units() {
        for radius in [1e-150, 1e150] {
            let e = meyer(&icosphere(radius, 3).unwrap());
            assert!(all_finite(&e));
            let (h_mean, _) = errors(&e.mean, 1.0 / radius);
            assert!(h_mean < 0.01, "R = {radius}: {h_mean}");
            assert_eq!(e.counts.clamped, 0);
        }
        // K of a 1e-170 sphere is 1e340: beyond f64, so clamped and counted.
        let e = meyer(&icosphere(1e-170, 1).unwrap());
        assert!(all_finite(&e));
        assert!(e.counts.clamped > 0);
    }

    #[test]
    fn stage_writes_three_columns_and_reports_ranges_and_counts() {
        let mesh = plane_grid(4, 4, 1.0).unwrap();
        let (out, report) = run_with(&mesh, CurvatureParams::default());
        for name in [GAUSSIAN, MEAN, HYBRID] {
            assert_eq!(out.vertex_attrs.scalar(name).map(<[f64]>::len), Some(25));
            let r = report.get(name).unwrap();
            assert_eq!(r["max"].as_f64(), Some(0.0), "{name}: {r}");
        }
        let counts = report.get("vertices").unwrap();
        assert_eq!(counts["boundary"], 16);
        assert_eq!(counts["regular"], 9);
        assert_eq!(report.get("method"), Some(&"meyer".into()));
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        let c = Curvature::new(CurvatureParams::default()).contract();
        assert_eq!(
            c.writes,
            [GAUSSIAN, MEAN, HYBRID].map(|n| AttrRef::vertex(n, AttrKind::Scalar))
        );
        assert!(!c.needs.manifold && !c.needs.target);
    }

    #[test]
    fn parameters_read_from_kebab_case_and_reject_unknown_values() {
        let p: CurvatureParams = toml::from_str(
            "method = \"angle-deficit\"\ngaussian = \"absolute\"\nboundary = \"geodesic\"\ndeficit_area = \"incident-sum\"",
        )
        .unwrap();
        assert_eq!(p.method, Method::AngleDeficit);
        assert_eq!(p.gaussian, GaussianMode::Absolute);
        assert_eq!(p.boundary, BoundaryMode::Geodesic);
        assert_eq!(p.deficit_area, DeficitArea::IncidentSum);
        assert!(toml::from_str::<CurvatureParams>("method = \"gauss\"").is_err());
    }

    #[test]
    fn example_table_builds_through_the_registry() {
        let d = descriptor();
        let mut table: toml::Table =
            toml::from_str(&d.example_toml().replace("[[stage]]\n", "")).unwrap();
        assert_eq!(table.remove("kind"), Some("curvature".into()));
        assert_eq!(table["method"].as_str(), Some("meyer"));
        let stage = (d.build)(&table).ok().unwrap();
        assert_eq!(stage.kind(), "curvature");
    }
}
