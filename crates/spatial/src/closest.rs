//! The closest point of a triangle (or a segment) to a query point.
//!
//! [`closest_point_on_triangle`] follows the classic Voronoi-region walk (vertex regions,
//! then edge regions, then the face) using only dot products, so it is exact for every
//! well-shaped triangle. A triangle too thin to have a trustworthy plane — its sine of the
//! angle at `a` below `1e-6` ([`DEGENERATE_SIN2`] on the squared sine), which includes every
//! zero-area triangle and every triangle with a zero-length edge — is treated as the union of
//! its three edges. That fallback is off by at most the triangle's thickness, i.e. less than
//! `1e-6 ×` its shorter edge at `a`.

use glam::DVec3;

/// Below this squared sine of the angle at the first corner a triangle counts as degenerate
/// and is measured as its three edges.
///
/// At this threshold the face-region barycentrics lose about 4 of 16 digits to
/// cancellation, while the edge fallback errs by at most `1e-6 ×` an edge length.
pub const DEGENERATE_SIN2: f64 = 1e-12;

/// The closest point of the segment `a`–`b` to `p`, and its parameter `t` (`a + t·(b − a)`).
///
/// A zero-length segment gives `a` and `t = 0`.
#[inline]
pub fn closest_point_on_segment(p: DVec3, a: DVec3, b: DVec3) -> (DVec3, f64) {
    let ab = b - a;
    let len2 = ab.length_squared();
    let has_length = len2 > 0.0; // false for zero length and for NaN
    if !has_length {
        return (a, 0.0);
    }
    let t = ((p - a).dot(ab) / len2).clamp(0.0, 1.0);
    (a + ab * t, t)
}

/// The closest point of triangle `a b c` to `p`, with its barycentric coordinates
/// `[wa, wb, wc]` (non-negative, summing to 1, `point = wa·a + wb·b + wc·c`).
///
/// Exact in all seven Voronoi regions (three vertices, three edges, the face) of a
/// well-shaped triangle; a degenerate triangle (see [`DEGENERATE_SIN2`]) is measured as
/// the nearest of its three edges. Non-finite input gives non-finite output, never a panic.
///
/// ```
/// use coarsen_spatial::closest_point_on_triangle;
/// use glam::DVec3;
/// let (q, w) = closest_point_on_triangle(DVec3::new(0.25, 0.25, 2.0), DVec3::ZERO, DVec3::X, DVec3::Y);
/// assert_eq!(q, DVec3::new(0.25, 0.25, 0.0));
/// assert!((w[0] - 0.5).abs() < 1e-15);
/// ```
#[inline]
pub fn closest_point_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (DVec3, [f64; 3]) {
    let ab = b - a;
    let ac = c - a;
    let n = ab.cross(ac);
    let n2 = n.length_squared();
    let well_shaped = n2 > DEGENERATE_SIN2 * ab.length_squared() * ac.length_squared();
    if !well_shaped {
        return closest_on_edges(p, a, b, c);
    }

    // Vertex region of a.
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, [1.0, 0.0, 0.0]);
    }
    // Vertex region of b.
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, [0.0, 1.0, 0.0]);
    }
    // Edge region of ab: d1 − d3 = |ab|² > 0 here.
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, [1.0 - v, v, 0.0]);
    }
    // Vertex region of c.
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, [0.0, 0.0, 1.0]);
    }
    // Edge region of ac: d2 − d6 = |ac|² > 0 here.
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, [1.0 - w, 0.0, w]);
    }
    // Edge region of bc: the denominator is |bc|² > 0 here.
    let va = d3 * d6 - d5 * d4;
    let (e4, e5) = (d4 - d3, d5 - d6);
    if va <= 0.0 && e4 >= 0.0 && e5 >= 0.0 {
        let w = e4 / (e4 + e5);
        return (b + (c - b) * w, [0.0, 1.0 - w, w]);
    }
    // Face region: va + vb + vc = |ab × ac|² > 0, each term positive. The point is the
    // orthogonal projection onto the plane, which rounds less than `a + v·ab + w·ac`.
    let inv = 1.0 / (va + vb + vc);
    let v = vb * inv;
    let w = vc * inv;
    (p - n * (n.dot(ap) / n2), [1.0 - v - w, v, w])
}

/// The nearest of the three edges of a (degenerate) triangle.
fn closest_on_edges(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (DVec3, [f64; 3]) {
    let (q_ab, t_ab) = closest_point_on_segment(p, a, b);
    let (q_bc, t_bc) = closest_point_on_segment(p, b, c);
    let (q_ca, t_ca) = closest_point_on_segment(p, c, a);
    let mut best = (q_ab, [1.0 - t_ab, t_ab, 0.0]);
    let mut best_d2 = (p - q_ab).length_squared();
    let d2 = (p - q_bc).length_squared();
    if d2 < best_d2 {
        best = (q_bc, [0.0, 1.0 - t_bc, t_bc]);
        best_d2 = d2;
    }
    if (p - q_ca).length_squared() < best_d2 {
        best = (q_ca, [t_ca, 0.0, 1.0 - t_ca]);
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_geom::SplitMix64;

    /// Brute force: the nearest of a dense barycentric grid of the triangle, and the grid's
    /// covering radius (every triangle point is within it of some grid point).
    fn sampled_min_distance(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (f64, f64) {
        const N: usize = 300;
        let mut best = f64::INFINITY;
        for i in 0..=N {
            for j in 0..=N - i {
                let (u, v) = (i as f64 / N as f64, j as f64 / N as f64);
                let q = a * (1.0 - u - v) + b * u + c * v;
                best = best.min((p - q).length());
            }
        }
        let longest = (b - a).length().max((c - b).length()).max((a - c).length());
        (best, longest / N as f64)
    }

    fn assert_on_triangle(q: DVec3, w: [f64; 3], a: DVec3, b: DVec3, c: DVec3) {
        assert!(
            w.iter().all(|&x| (-1e-12..=1.0 + 1e-12).contains(&x)),
            "{w:?}"
        );
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let scale = a.abs().max(b.abs()).max(c.abs()).max_element().max(1.0);
        assert!((a * w[0] + b * w[1] + c * w[2] - q).length() < 1e-12 * scale);
    }

    fn random_triangle(rng: &mut SplitMix64) -> (DVec3, DVec3, DVec3) {
        loop {
            let (a, b, c) = (
                rng.point(-1.0, 1.0),
                rng.point(-1.0, 1.0),
                rng.point(-1.0, 1.0),
            );
            if coarsen_geom::triangle::min_angle(a, b, c) > 0.05 {
                return (a, b, c);
            }
        }
    }

    #[test]
    fn matches_dense_sampling_on_random_triangles_and_points() {
        let mut rng = SplitMix64::new(7);
        for _ in 0..60 {
            let (a, b, c) = random_triangle(&mut rng);
            for _ in 0..5 {
                let p = rng.point(-2.0, 2.0);
                let (q, w) = closest_point_on_triangle(p, a, b, c);
                assert_on_triangle(q, w, a, b, c);
                let (sampled, h) = sampled_min_distance(p, a, b, c);
                let got = (p - q).length();
                assert!(
                    got <= sampled + 1e-12,
                    "got {got}, a sample is at {sampled}"
                );
                assert!(
                    got >= sampled - h,
                    "got {got}, samples no closer than {sampled}"
                );
            }
        }
    }

    /// Builds `p` in a chosen Voronoi region so that the exact answer `q` is known:
    /// `q` on the triangle, `p = q +` a vector in that region's normal cone.
    #[test]
    fn exact_in_each_of_the_seven_voronoi_regions() {
        let mut rng = SplitMix64::new(11);
        for _ in 0..200 {
            let (a, b, c) = random_triangle(&mut rng);
            let corners = [a, b, c];
            let n = ab_cross(a, b, c).normalize();
            let lift = n * rng.range(-1.0, 1.0);
            // Outward in-plane normal of edge i (from corner i to corner i+1).
            let out = |i: usize| {
                let (s, e, o) = (corners[i], corners[(i + 1) % 3], corners[(i + 2) % 3]);
                let m = (e - s).cross(n).normalize();
                if m.dot(o - s) > 0.0 { -m } else { m }
            };
            for i in 0..3 {
                // Vertex i: its cone is spanned by the outward normals of its two edges.
                let q = corners[i];
                let p = q
                    + out(i) * rng.range(0.01, 1.0)
                    + out((i + 2) % 3) * rng.range(0.01, 1.0)
                    + lift;
                let (got, w) = closest_point_on_triangle(p, a, b, c);
                assert!((got - q).length() < 1e-12, "vertex {i}: {got} vs {q}");
                assert!((w[i] - 1.0).abs() < 1e-12);
                // Edge i: an interior point of the edge, pushed outward.
                let t = rng.range(0.05, 0.95);
                let q = corners[i].lerp(corners[(i + 1) % 3], t);
                let p = q + out(i) * rng.range(0.01, 1.0) + lift;
                let (got, w) = closest_point_on_triangle(p, a, b, c);
                assert!((got - q).length() < 1e-12, "edge {i}: {got} vs {q}");
                assert!(w[(i + 2) % 3].abs() < 1e-12);
            }
            // Face: an interior point, lifted along the normal.
            let (u, v) = (rng.range(0.05, 0.45), rng.range(0.05, 0.45));
            let q = a * (1.0 - u - v) + b * u + c * v;
            let (got, w) = closest_point_on_triangle(q + lift, a, b, c);
            assert!((got - q).length() < 1e-12, "face: {got} vs {q}");
            assert!((w[1] - u).abs() < 1e-9 && (w[2] - v).abs() < 1e-9);
        }
    }

    fn ab_cross(a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
        (b - a).cross(c - a)
    }

    #[test]
    fn zero_area_triangles_fall_back_to_their_edges() {
        let p = DVec3::new(0.5, 1.0, 0.0);
        // Collinear, with c beyond b.
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::X * 3.0);
        let (q, w) = closest_point_on_triangle(p, a, b, c);
        assert!((q - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-15);
        assert_on_triangle(q, w, a, b, c);
        let p = DVec3::new(2.5, -1.0, 0.0);
        let (q, _) = closest_point_on_triangle(p, a, b, c);
        assert!((q - DVec3::new(2.5, 0.0, 0.0)).length() < 1e-15);
        // Two corners coincide.
        let (q, w) = closest_point_on_triangle(p, a, a, b);
        assert_eq!(q, b);
        assert_on_triangle(q, w, a, a, b);
        // All three coincide.
        let (q, w) = closest_point_on_triangle(p, b, b, b);
        assert_eq!(q, b);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn sliver_triangles_stay_within_their_thickness_of_the_truth() {
        let mut rng = SplitMix64::new(3);
        for _ in 0..200 {
            let a = rng.point(-1.0, 1.0);
            let b = rng.point(-1.0, 1.0);
            // c almost on the line ab: thickness about 1e-9.
            let c = a.lerp(b, rng.range(-0.5, 1.5)) + rng.point(-1e-9, 1e-9);
            let p = rng.point(-2.0, 2.0);
            let (q, w) = closest_point_on_triangle(p, a, b, c);
            assert!(w.iter().all(|x| x.is_finite()));
            let (sampled, h) = sampled_min_distance(p, a, b, c);
            let got = (p - q).length();
            assert!(got <= sampled + 1e-8 && got >= sampled - h - 1e-8);
        }
    }

    #[test]
    fn segment_clamps_to_its_ends_and_handles_zero_length() {
        let (a, b) = (DVec3::ZERO, DVec3::X);
        assert_eq!(
            closest_point_on_segment(DVec3::new(-1.0, 1.0, 0.0), a, b),
            (a, 0.0)
        );
        assert_eq!(
            closest_point_on_segment(DVec3::new(3.0, 1.0, 0.0), a, b),
            (b, 1.0)
        );
        assert_eq!(
            closest_point_on_segment(DVec3::new(0.25, 1.0, 0.0), a, b).1,
            0.25
        );
        assert_eq!(closest_point_on_segment(DVec3::ONE, a, a), (a, 0.0));
    }

    #[test]
    fn non_finite_input_does_not_panic() {
        let (q, _) =
            closest_point_on_triangle(DVec3::splat(f64::NAN), DVec3::ZERO, DVec3::X, DVec3::Y);
        assert!(!q.is_finite());
        // An infinite corner: any answer will do as long as nothing panics.
        let _ = closest_point_on_triangle(
            DVec3::ONE,
            DVec3::ZERO,
            DVec3::X,
            DVec3::splat(f64::INFINITY),
        );
    }
}
