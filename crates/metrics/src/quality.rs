//! Shape quality of a mesh's triangles (metrics spec, "Shape quality of the output
//! triangles").

use crate::error::{MetricsError, Role};
use crate::prepare::{Prepared, map_chunks};
use coarsen_geom::triangle;
use coarsen_mesh::Mesh;
use serde::{Deserialize, Serialize};

/// Width in degrees of one bin of [`Quality::min_angle_histogram`].
pub const HISTOGRAM_BIN_DEG: f64 = 5.0;

/// Number of bins of [`Quality::min_angle_histogram`]: 5° bins over `[0°, 60°]`.
pub const HISTOGRAM_BINS: usize = 12;

/// Faces per parallel chunk (fixed, so sums do not depend on the thread count).
const CHUNK: usize = 4096;

/// Shape figures of a mesh's triangles. Every figure is over all faces, degenerate ones
/// included (they count as angle 0 and quality 0); a mesh without faces gives zeros.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quality {
    /// Number of faces measured.
    pub n_faces: usize,
    /// Smallest interior angle of any triangle, in degrees.
    pub alpha_min_deg: f64,
    /// Mean over triangles of each triangle's smallest angle, in degrees.
    pub alpha_avg_deg: f64,
    /// Percent of triangles whose smallest angle is below 30°.
    pub p_lt30_pct: f64,
    /// Smallest Frey–Borouchaki quality `(6/√3)·area / (half-perimeter · longest edge)`.
    pub q_min: f64,
    /// Mean Frey–Borouchaki quality.
    pub q_avg: f64,
    /// Triangle counts by smallest angle in 5° bins: bin `i` holds `[5i°, 5i + 5°)`, the
    /// last bin also 60° itself (and any rounding just above it).
    pub min_angle_histogram: Vec<u32>,
}

/// Partial sums of one chunk of faces.
#[derive(Clone, Copy)]
struct Partial {
    alpha_min: f64,
    alpha_sum: f64,
    n_lt30: usize,
    q_min: f64,
    q_sum: f64,
    histogram: [u32; HISTOGRAM_BINS],
}

/// Measures the shape of every triangle of `mesh`.
///
/// Errors when a face index is out of range or a used vertex is not finite or beyond
/// ±[`MAX_COORDINATE`](crate::MAX_COORDINATE) (the mesh is called the output in the error).
pub fn quality(mesh: &Mesh) -> Result<Quality, MetricsError> {
    Prepared::new(mesh, Role::Output).map(|p| quality_of(&p))
}

/// [`quality`] of a checked mesh.
pub(crate) fn quality_of(prepared: &Prepared) -> Quality {
    let mesh = prepared.mesh;
    let n = mesh.n_faces();
    let parts = map_chunks(n, CHUNK, |range| {
        let mut p = Partial {
            alpha_min: f64::INFINITY,
            alpha_sum: 0.0,
            n_lt30: 0,
            q_min: f64::INFINITY,
            q_sum: 0.0,
            histogram: [0; HISTOGRAM_BINS],
        };
        for f in range {
            let [a, b, c] = mesh.corners(f);
            let alpha = triangle::min_angle(a, b, c).to_degrees();
            let q = triangle::quality(a, b, c);
            p.alpha_min = p.alpha_min.min(alpha);
            p.alpha_sum += alpha;
            p.n_lt30 += usize::from(alpha < 30.0);
            p.q_min = p.q_min.min(q);
            p.q_sum += q;
            let bin = ((alpha / HISTOGRAM_BIN_DEG) as usize).min(HISTOGRAM_BINS - 1);
            p.histogram[bin] += 1;
        }
        p
    });
    if n == 0 {
        return Quality {
            n_faces: 0,
            alpha_min_deg: 0.0,
            alpha_avg_deg: 0.0,
            p_lt30_pct: 0.0,
            q_min: 0.0,
            q_avg: 0.0,
            min_angle_histogram: vec![0; HISTOGRAM_BINS],
        };
    }
    let mut histogram = vec![0u32; HISTOGRAM_BINS];
    let (mut alpha_min, mut alpha_sum, mut n_lt30, mut q_min, mut q_sum) =
        (f64::INFINITY, 0.0, 0usize, f64::INFINITY, 0.0);
    for p in &parts {
        alpha_min = alpha_min.min(p.alpha_min);
        alpha_sum += p.alpha_sum;
        n_lt30 += p.n_lt30;
        q_min = q_min.min(p.q_min);
        q_sum += p.q_sum;
        for (h, x) in histogram.iter_mut().zip(p.histogram) {
            *h += x;
        }
    }
    let nf = n as f64;
    Quality {
        n_faces: n,
        alpha_min_deg: alpha_min,
        alpha_avg_deg: alpha_sum / nf,
        p_lt30_pct: 100.0 * n_lt30 as f64 / nf,
        q_min,
        q_avg: q_sum / nf,
        min_angle_histogram: histogram,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::DVec3;

    /// A strip of equilateral triangles: `rows × cols` vertices on a triangular lattice.
    ///
    /// ```text
    ///   x---x---x
    ///  / \ / \ /
    /// x---x---x
    /// ```
    fn equilateral_tiling(rows: u32, cols: u32) -> Mesh {
        let h = 3f64.sqrt() / 2.0;
        let mut positions = Vec::new();
        for j in 0..rows {
            for i in 0..cols {
                let shift = if j % 2 == 1 { 0.5 } else { 0.0 };
                positions.push(DVec3::new(i as f64 + shift, j as f64 * h, 0.0));
            }
        }
        let mut faces = Vec::new();
        for j in 0..rows - 1 {
            for i in 0..cols - 1 {
                let (v, up) = (j * cols + i, (j + 1) * cols + i);
                if j % 2 == 0 {
                    faces.push([v, v + 1, up]);
                    faces.push([v + 1, up + 1, up]);
                } else {
                    faces.push([v, up + 1, up]);
                    faces.push([v, v + 1, up + 1]);
                }
            }
        }
        Mesh::new(positions, faces)
    }

    #[test]
    fn equilateral_tiling_is_perfect() {
        let m = equilateral_tiling(9, 12);
        let q = quality(&m).unwrap();
        assert_eq!(q.n_faces, 2 * 8 * 11);
        assert!((q.alpha_min_deg - 60.0).abs() < 1e-9, "{}", q.alpha_min_deg);
        assert!((q.alpha_avg_deg - 60.0).abs() < 1e-9);
        assert_eq!(q.p_lt30_pct, 0.0);
        assert!((q.q_min - 1.0).abs() < 1e-12 && (q.q_avg - 1.0).abs() < 1e-12);
        let mut expect = vec![0; HISTOGRAM_BINS];
        expect[HISTOGRAM_BINS - 1] = q.n_faces as u32;
        assert_eq!(q.min_angle_histogram, expect);
    }

    /// Angles 38° at a, 22° at b, 120° at c: each side is the sine of the opposite angle.
    ///
    /// ```text
    ///            c
    ///          /   ` .
    ///   38° a -------- b 22°
    /// ```
    #[test]
    fn obtuse_triangle_figures_match_hand_computation() {
        let [sa, sb, sc] = [38f64, 22.0, 120.0].map(|t| t.to_radians().sin());
        let alpha = 38f64.to_radians();
        let a = DVec3::ZERO;
        let b = DVec3::new(sc, 0.0, 0.0);
        let c = DVec3::new(sb * alpha.cos(), sb * alpha.sin(), 0.0);
        let m = Mesh::new(vec![a, b, c], vec![[0, 1, 2]]);
        let q = quality(&m).unwrap();
        assert!((q.alpha_min_deg - 22.0).abs() < 1e-9, "{}", q.alpha_min_deg);
        assert_eq!(q.alpha_avg_deg, q.alpha_min_deg);
        assert_eq!(q.p_lt30_pct, 100.0);
        // Heron's area and Q = (6/√3)·area / (half-perimeter · longest edge).
        let s = (sa + sb + sc) / 2.0;
        let area = (s * (s - sa) * (s - sb) * (s - sc)).sqrt();
        let expect = 6.0 / 3f64.sqrt() * area / (s * sc);
        assert!((q.q_min - expect).abs() < 1e-12, "{} vs {expect}", q.q_min);
        let mut histogram = vec![0; HISTOGRAM_BINS];
        histogram[4] = 1; // [20°, 25°)
        assert_eq!(q.min_angle_histogram, histogram);
    }

    #[test]
    fn degenerate_faces_and_loose_vertices_give_zeros_not_nan() {
        let m = Mesh::new(
            vec![
                DVec3::ZERO,
                DVec3::X,
                DVec3::X * 2.0,
                DVec3::Y,
                DVec3::splat(f64::NAN),
            ],
            vec![[0, 1, 2], [0, 0, 3], [0, 1, 3]],
        );
        let q = quality(&m).unwrap();
        assert_eq!(q.n_faces, 3);
        assert_eq!(q.alpha_min_deg, 0.0);
        assert_eq!(q.q_min, 0.0);
        assert!((q.alpha_avg_deg - 15.0).abs() < 1e-9);
        assert!((q.p_lt30_pct - 200.0 / 3.0).abs() < 1e-9);
        assert_eq!(q.min_angle_histogram[0], 2);
        assert_eq!(q.min_angle_histogram[9], 1);
    }

    #[test]
    fn empty_mesh_gives_zero_figures() {
        let q = quality(&Mesh::default()).unwrap();
        assert_eq!(q.n_faces, 0);
        assert_eq!(q.alpha_avg_deg, 0.0);
        assert_eq!(q.min_angle_histogram.iter().sum::<u32>(), 0);
    }
}
