//! How well the input's sharp feature edges survive: the one-sided distance from points
//! sampled along them to the output surface.
//!
//! A **feature edge** of the input is an edge with exactly two faces whose normals differ
//! by more than [`FeatureOptions::angle_deg`] (the dihedral angle's supplement: 0° on a
//! flat region, 90° on a cube's edge), or an edge the input marks (`Mesh::marked_edges`:
//! an OBJ `l`, a PLY `edge` element), whatever its angle. Each feature edge is sampled at both ends and at
//! evenly spaced points at most [`FeatureOptions::spacing`] × the input's bounding-box
//! diagonal apart; every sample's distance to the nearest point of the output is measured
//! exactly (a spatial index over the output's faces). A vertex shared by several feature
//! edges is measured once per edge: the mean weights each edge by its samples.
//!
//! The **corners** of those edges (where one, or three or more, meet, or two meet at a
//! turn above 45°: `coarsen_features`' corners of the sharp edges alone) are counted, and
//! those the output keeps: an output vertex within [`CORNER_TOLERANCE`] × the diagonal.
//!
//! Figures are percents of the input's bounding-box diagonal, as for [`Fidelity`](crate::Fidelity).

use crate::error::{MetricsError, Role};
use crate::prepare::{Prepared, map_chunks};
use crate::validity::topology;
use coarsen_features::FeatureKind;
use coarsen_mesh::{Mesh, Topology};
use coarsen_spatial::Bvh;
use serde::{Deserialize, Serialize};

/// Feature edges per parallel chunk.
const CHUNK: usize = 1024;

/// Most samples on one edge (a guard against a tiny `spacing`).
const MAX_SAMPLES_PER_EDGE: usize = 1 << 12;

/// An input corner is kept when an output vertex lies this close to it (fraction of the
/// input's bounding-box diagonal).
pub const CORNER_TOLERANCE: f64 = 1e-6;

/// Settings of [`feature_edges`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FeatureOptions {
    /// An edge is a feature when its two faces' normals differ by more than this (degrees).
    pub angle_deg: f64,
    /// Largest gap between samples along an edge, as a fraction of the input's diagonal.
    pub spacing: f64,
}

impl Default for FeatureOptions {
    fn default() -> Self {
        FeatureOptions {
            angle_deg: 40.0,
            spacing: 1e-3,
        }
    }
}

/// Distance from the input's sharp feature edges to the output.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FeatureEdges {
    /// Feature edges found in the input.
    pub n_edges: usize,
    /// Their total length, in percent of the input's bounding-box diagonal.
    pub length_pct: f64,
    /// Points measured.
    pub n_samples: u64,
    /// Largest distance from a sample to the output, % of the diagonal (0 without features).
    pub max_pct: f64,
    /// Mean distance from a sample to the output, % of the diagonal (0 without features).
    pub mean_pct: f64,
    /// Corners of the feature edges in the input.
    pub n_corners: usize,
    /// Those with an output vertex on them (within [`CORNER_TOLERANCE`]).
    pub corners_kept: usize,
}

/// The input's edges whose two faces turn by more than `angle_deg`, as vertex pairs in the
/// order of the input's edge table ([`coarsen_features::sharp_edges`] on a checked input).
pub fn sharp_edges(input: &Mesh, angle_deg: f64) -> Result<Vec<[u32; 2]>, MetricsError> {
    let prepared = Prepared::new(input, Role::Input)?;
    let topo = topology(&prepared, Role::Input)?;
    Ok(coarsen_features::sharp_edges(input, &topo, angle_deg)
        .into_iter()
        .map(|e| topo.edge(e))
        .collect())
}

/// Measures how far `output` lies from the sharp feature edges of `input` (see the module
/// docs).
///
/// Errors on a bad index or used vertex of either mesh, an input whose diagonal is zero,
/// or an output without faces.
pub fn feature_edges(
    input: &Mesh,
    output: &Mesh,
    opts: &FeatureOptions,
) -> Result<FeatureEdges, MetricsError> {
    let prepared_in = Prepared::new(input, Role::Input)?;
    let prepared_out = Prepared::new(output, Role::Output)?;
    let diagonal = prepared_in.bbox.diagonal();
    if !(diagonal > 0.0 && diagonal.is_finite()) {
        return Err(MetricsError::BadExtent { diagonal });
    }
    if output.n_faces() == 0 {
        return Err(MetricsError::NoFaces { mesh: Role::Output });
    }
    let topo = topology(&prepared_in, Role::Input)?;
    Ok(edges_to(input, &topo, prepared_out.mesh, diagonal, opts))
}

/// [`feature_edges`] of a checked `input` (adjacency `topo`, bounding-box `diagonal` above
/// zero) against a checked `output` with faces.
pub(crate) fn edges_to(
    input: &Mesh,
    topo: &Topology,
    output: &Mesh,
    diagonal: f64,
    opts: &FeatureOptions,
) -> FeatureEdges {
    let features = coarsen_features::Features::detect(
        input,
        topo,
        &coarsen_features::FeatureOptions {
            angle_deg: opts.angle_deg,
            boundary: false,
            ..Default::default()
        },
    );
    let edges: Vec<[u32; 2]> = features
        .edges
        .iter()
        .filter(|(_, kind)| matches!(kind, FeatureKind::Sharp | FeatureKind::Marked))
        .map(|&(e, _)| topo.edge(e))
        .collect();
    let bvh = Bvh::build(&output.positions, &output.faces);
    let step = (opts.spacing * diagonal).max(f64::MIN_POSITIVE);
    // Per chunk: (samples, sum of distances, largest distance, total length).
    let parts = map_chunks(edges.len(), CHUNK, |range| {
        let (mut n, mut sum, mut max, mut length) = (0u64, 0.0f64, 0.0f64, 0.0f64);
        for &[a, b] in &edges[range] {
            let (p, q) = (input.positions[a as usize], input.positions[b as usize]);
            let len = (q - p).length();
            length += len;
            let pieces = ((len / step).ceil() as usize).clamp(1, MAX_SAMPLES_PER_EDGE);
            for i in 0..=pieces {
                let x = p.lerp(q, i as f64 / pieces as f64);
                let d = bvh.closest_point(x).map_or(0.0, |hit| hit.distance());
                n += 1;
                sum += d;
                max = max.max(d);
            }
        }
        (n, sum, max, length)
    });
    let (n, sum, max, length) = parts.into_iter().fold(
        (0u64, 0.0f64, 0.0f64, 0.0f64),
        |(n, s, m, l), (n2, s2, m2, l2)| (n + n2, s + s2, m.max(m2), l + l2),
    );
    let near = CORNER_TOLERANCE * diagonal;
    let corners_kept = features
        .corners
        .iter()
        .filter(|&&c| {
            let p = input.positions[c as usize];
            // A vertex on the corner is the nearest point of the output to it, and a
            // corner of the face that point is on.
            bvh.closest_point(p).is_some_and(|hit| {
                output.faces[hit.face as usize]
                    .iter()
                    .any(|&w| output.positions[w as usize].distance(p) <= near)
            })
        })
        .count();
    let pct = |x: f64| 100.0 * x / diagonal;
    FeatureEdges {
        n_corners: features.corners.len(),
        corners_kept,
        n_edges: edges.len(),
        length_pct: pct(length),
        n_samples: n,
        max_pct: pct(max),
        mean_pct: if n > 0 { pct(sum / n as f64) } else { 0.0 },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::DVec3;

    /// An axis-aligned box split into 12 triangles, outward facing.
    fn cube(size: f64) -> Mesh {
        let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z) * size;
        let positions = vec![
            p(0.0, 0.0, 0.0),
            p(1.0, 0.0, 0.0),
            p(1.0, 1.0, 0.0),
            p(0.0, 1.0, 0.0),
            p(0.0, 0.0, 1.0),
            p(1.0, 0.0, 1.0),
            p(1.0, 1.0, 1.0),
            p(0.0, 1.0, 1.0),
        ];
        let faces = vec![
            [0, 2, 1],
            [0, 3, 2],
            [4, 5, 6],
            [4, 6, 7],
            [0, 1, 5],
            [0, 5, 4],
            [1, 2, 6],
            [1, 6, 5],
            [2, 3, 7],
            [2, 7, 6],
            [3, 0, 4],
            [3, 4, 7],
        ];
        Mesh::new(positions, faces)
    }

    #[test]
    fn a_cube_has_twelve_sharp_edges_and_its_diagonals_are_not() {
        let edges = sharp_edges(&cube(1.0), 40.0).unwrap();
        assert_eq!(edges.len(), 12);
        // Face diagonals join opposite corners of a square: never sharp.
        for [a, b] in edges {
            let d = cube(1.0).positions[a as usize] - cube(1.0).positions[b as usize];
            assert!(
                (d.length() - 1.0).abs() < 1e-12,
                "{a}-{b} is not a cube edge"
            );
        }
    }

    #[test]
    fn a_smooth_sphere_has_no_sharp_edge() {
        let sphere = crate::test_meshes::icosphere(3);
        assert!(sharp_edges(&sphere, 40.0).unwrap().is_empty());
        let m = feature_edges(&sphere, &sphere, &FeatureOptions::default()).unwrap();
        assert_eq!(
            (m.n_edges, m.n_samples, m.max_pct, m.mean_pct),
            (0, 0, 0.0, 0.0)
        );
    }

    #[test]
    fn the_same_mesh_keeps_its_features_exactly() {
        let c = cube(2.0);
        let m = feature_edges(&c, &c, &FeatureOptions::default()).unwrap();
        assert_eq!(m.n_edges, 12);
        assert_eq!(m.max_pct, 0.0);
        assert_eq!(m.mean_pct, 0.0);
        // 12 edges of length 2 out of a diagonal of 2√3.
        assert!((m.length_pct - 100.0 * 24.0 / (2.0 * 3f64.sqrt())).abs() < 1e-9);
        let pieces = (2.0 / (1e-3 * 2.0 * 3f64.sqrt())).ceil() as u64;
        assert_eq!(m.n_samples, 12 * (pieces + 1));
        assert_eq!((m.corners_kept, m.n_corners), (8, 8));
    }

    /// An edge the input marks is measured whatever its angle: a diagonal of a cube's
    /// face joins the twelve edges (at distance 0 from the cube itself); the same output
    /// against the unmarked cube measures twelve.
    #[test]
    fn marked_edges_are_measured_too() {
        let mut c = cube(1.0);
        let topo = Topology::build(&c);
        // The edges of the cube's triangulation that are no cube edge: face diagonals.
        let sharp = sharp_edges(&c, 40.0).unwrap();
        let diagonal = (0..topo.n_edges() as u32)
            .map(|e| topo.edge(e))
            .find(|e| !sharp.contains(e))
            .unwrap();
        c.marked_edges = vec![diagonal];
        let m = feature_edges(&c, &c, &FeatureOptions::default()).unwrap();
        assert_eq!(m.n_edges, 13);
        assert_eq!(m.max_pct, 0.0);
        let unmarked = feature_edges(&cube(1.0), &c, &FeatureOptions::default()).unwrap();
        assert_eq!(unmarked.n_edges, 12);
    }

    #[test]
    fn a_cut_corner_is_measured_along_the_edges_it_removed() {
        // The cube with corner 6 (1, 1, 1) pulled in to (0.5, 0.5, 0.5): the three edges
        // into it now leave the surface, by at most the distance from the old corner
        // to the new surface.
        let input = cube(1.0);
        let mut cut = input.clone();
        cut.positions[6] = DVec3::splat(0.5);
        let m = feature_edges(&input, &cut, &FeatureOptions::default()).unwrap();
        let diagonal = 3f64.sqrt();
        assert!(m.max_pct > 0.0 && m.mean_pct > 0.0);
        assert!(m.mean_pct < m.max_pct);
        // No sample is farther from the surface than the old corner is from the new one.
        assert!(m.max_pct <= 100.0 * (0.5 * diagonal) / diagonal + 1e-9);
        assert_eq!((m.corners_kept, m.n_corners), (7, 8));
        let fewer = FeatureOptions {
            angle_deg: 100.0,
            ..FeatureOptions::default()
        };
        let none = feature_edges(&input, &cut, &fewer).unwrap();
        assert_eq!(none.n_edges, 0, "a cube's edges turn by exactly 90°");
        assert_eq!(none.n_corners, 0);
    }

    #[test]
    fn bad_meshes_are_errors_not_panics() {
        let c = cube(1.0);
        let empty = Mesh::new(vec![], vec![]);
        assert!(matches!(
            feature_edges(&c, &empty, &FeatureOptions::default()),
            Err(MetricsError::NoFaces { mesh: Role::Output })
        ));
        let mut bad = c.clone();
        bad.positions[3].x = f64::INFINITY;
        assert!(matches!(
            feature_edges(&bad, &c, &FeatureOptions::default()),
            Err(MetricsError::BadCoordinate {
                mesh: Role::Input,
                vertex: 3,
                ..
            })
        ));
    }
}
