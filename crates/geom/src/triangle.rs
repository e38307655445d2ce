//! Measures of one triangle: area, normal, angles and shape quality.
//!
//! Every function is total: a degenerate triangle gives area 0, quality 0, angles that
//! sum to π where they are defined and 0 where an edge has zero length — never NaN.

use glam::DVec3;

/// Twice-area normal `(b − a) × (c − a)`; its length is twice the area.
#[inline]
pub fn cross(a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    (b - a).cross(c - a)
}

/// Area of the triangle.
#[inline]
pub fn area(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    0.5 * cross(a, b, c).length()
}

/// Unit normal, or zero for a degenerate triangle.
#[inline]
pub fn normal(a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    cross(a, b, c).normalize_or_zero()
}

/// Centroid (mean of the three corners).
#[inline]
pub fn centroid(a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    (a + b + c) / 3.0
}

/// Barycentric coordinates of the projection of `p` onto the plane of triangle `abc`
/// (they sum to 1); the centroid's for a degenerate triangle.
pub fn barycentric(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> [f64; 3] {
    let (e0, e1, e2) = (b - a, c - a, p - a);
    let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
    let (d20, d21) = (e2.dot(e0), e2.dot(e1));
    let den = d00 * d11 - d01 * d01;
    if den.is_nan() || den.abs() <= f64::MIN_POSITIVE || den.is_infinite() {
        return [1.0 / 3.0; 3];
    }
    let v = (d11 * d20 - d01 * d21) / den;
    let w = (d00 * d21 - d01 * d20) / den;
    [1.0 - v - w, v, w]
}

/// Angle in radians between vectors `u` and `v`; 0 when either is zero.
///
/// Uses `atan2(|u × v|, u · v)`, accurate for angles near 0 and π where `acos` is not.
#[inline]
pub fn angle_between(u: DVec3, v: DVec3) -> f64 {
    angle_of(sin_cos(u, v))
}

/// `(|u × v|, u · v)`: the sine and cosine of the angle between `u` and `v`, both scaled by
/// `|u| |v|`.
#[inline]
fn sin_cos(u: DVec3, v: DVec3) -> (f64, f64) {
    (u.cross(v).length(), u.dot(v))
}

/// The angle of [`sin_cos`]'s pair `(s, c)`; 0 when either vector was zero.
#[inline]
fn angle_of((s, c): (f64, f64)) -> f64 {
    if s == 0.0 && c == 0.0 {
        0.0
    } else {
        s.atan2(c)
    }
}

/// Interior angles in radians at `a`, `b` and `c`.
#[inline]
pub fn angles(a: DVec3, b: DVec3, c: DVec3) -> [f64; 3] {
    let t = [a, b, c];
    [angle_at(t, 0), angle_at(t, 1), angle_at(t, 2)]
}

/// Interior angle in radians of triangle `t` at its corner `corner` (0, 1 or 2): the same
/// number as [`angles`] gives for it.
#[inline]
pub fn angle_at(t: [DVec3; 3], corner: usize) -> f64 {
    let at = t[corner];
    angle_between(t[(corner + 1) % 3] - at, t[(corner + 2) % 3] - at)
}

/// Smallest interior angle in radians: the least of [`angles`], bit for bit.
#[inline]
pub fn min_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    // Each corner as its `sin_cos` pair (s, c). With s ≥ 0, θ₁ < θ₂ exactly when
    // s₁c₂ < s₂c₁, so the least corner is found by products and only it goes through atan2
    // (the costly part), unless the products are too close to order beyond rounding: then
    // all three do, as in `angles`.
    let k = [
        sin_cos(b - a, c - a),
        sin_cos(c - b, a - b),
        sin_cos(a - c, b - c),
    ];
    let clearly_below = |p: (f64, f64), q: (f64, f64)| {
        let (x, y) = (p.0 * q.1, q.0 * p.1);
        y - x > 1e-9 * (x.abs() + y.abs())
    };
    let mut least = 0;
    for i in 1..3 {
        if clearly_below(k[i], k[least]) {
            least = i;
        }
    }
    if (0..3).all(|i| i == least || clearly_below(k[least], k[i])) {
        angle_of(k[least])
    } else {
        angle_of(k[0]).min(angle_of(k[1])).min(angle_of(k[2]))
    }
}

/// Cotangent of the angle between `u` and `v`, clamped to ±1e6 for near-degenerate corners.
#[inline]
pub fn cot(u: DVec3, v: DVec3) -> f64 {
    let s = u.cross(v).length();
    let c = u.dot(v);
    const LIMIT: f64 = 1e6;
    if s <= c.abs() / LIMIT {
        if c >= 0.0 { LIMIT } else { -LIMIT }
    } else {
        (c / s).clamp(-LIMIT, LIMIT)
    }
}

/// Frey–Borouchaki quality `(6/√3)·area / (half-perimeter · longest edge)`:
/// 1 for an equilateral triangle, 0 for a degenerate one.
#[inline]
pub fn quality(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (la, lb, lc) = ((b - c).length(), (c - a).length(), (a - b).length());
    let half_perimeter = 0.5 * (la + lb + lc);
    let longest = la.max(lb).max(lc);
    let denom = half_perimeter * longest;
    if denom == 0.0 {
        0.0
    } else {
        (6.0 / 3f64.sqrt() * area(a, b, c) / denom).min(1.0)
    }
}

/// True when an interior angle is larger than π/2.
#[inline]
pub fn is_obtuse(a: DVec3, b: DVec3, c: DVec3) -> bool {
    (b - a).dot(c - a) < 0.0 || (c - b).dot(a - b) < 0.0 || (a - c).dot(b - c) < 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn barycentric_recovers_the_weights_of_a_point() {
        let (a, b, c) = (
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 3.0, 1.0),
        );
        // Off the plane along the normal: the weights of the projection.
        let p = 0.2 * a + 0.5 * b + 0.3 * c + 0.7 * normal(a, b, c);
        let w = barycentric(p, a, b, c);
        for (x, y) in w.iter().zip([0.2, 0.5, 0.3]) {
            assert!((x - y).abs() < 1e-12, "{w:?}");
        }
        assert_eq!(barycentric(p, a, a, a), [1.0 / 3.0; 3]);
    }

    fn equilateral() -> (DVec3, DVec3, DVec3) {
        (
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(0.5, 3f64.sqrt() / 2.0, 0.0),
        )
    }

    #[test]
    fn equilateral_triangle_has_quality_one_and_sixty_degree_angles() {
        let (a, b, c) = equilateral();
        assert!((quality(a, b, c) - 1.0).abs() < 1e-12);
        for t in angles(a, b, c) {
            assert!((t.to_degrees() - 60.0).abs() < 1e-9);
        }
        assert!((area(a, b, c) - 3f64.sqrt() / 4.0).abs() < 1e-12);
        assert!(!is_obtuse(a, b, c));
    }

    #[test]
    fn right_triangle_measures() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        let t = angles(a, b, c);
        assert!((t[0].to_degrees() - 90.0).abs() < 1e-9);
        assert!((t[1].to_degrees() - 45.0).abs() < 1e-9);
        assert!((t.iter().sum::<f64>() - std::f64::consts::PI).abs() < 1e-12);
        assert_eq!(normal(a, b, c), DVec3::Z);
        // Q = (6/√3)·0.5 / (((2+√2)/2)·√2)
        let expect = 6.0 / 3f64.sqrt() * 0.5 / ((2.0 + 2f64.sqrt()) / 2.0 * 2f64.sqrt());
        assert!((quality(a, b, c) - expect).abs() < 1e-12);
        assert!(cot(b - a, c - a).abs() < 1e-12);
    }

    #[test]
    fn degenerate_triangles_give_zero_not_nan() {
        let p = DVec3::new(1.0, 2.0, 3.0);
        assert_eq!(area(p, p, p), 0.0);
        assert_eq!(quality(p, p, p), 0.0);
        assert_eq!(normal(p, p, p), DVec3::ZERO);
        assert!(angles(p, p, p).iter().all(|t| !t.is_nan()));
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::X * 2.0);
        assert_eq!(quality(a, b, c), 0.0);
        assert_eq!(min_angle(a, b, c), 0.0);
        assert!(cot(DVec3::X, DVec3::X * 2.0).is_finite());
    }

    #[test]
    fn min_angle_is_the_least_of_the_angles_bit_for_bit() {
        // Random triangles, slivers, near-isosceles and near-equilateral ones (where the
        // products cannot order the corners), repeated and collinear points.
        fn unit(state: &mut u64) -> f64 {
            *state ^= *state << 13;
            *state ^= *state >> 7;
            *state ^= *state << 17;
            (*state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
        fn point(state: &mut u64, scale: f64) -> DVec3 {
            DVec3::new(unit(state), unit(state), unit(state)) * scale
        }
        let s = &mut 0x2545_f491_4f6c_dd1du64;
        let (e0, e1, e2) = equilateral();
        let mut cases = vec![(e0, e1, e2), (e0, e0, e0), (e0, e1, e1), (e0, e1, 2.0 * e1)];
        for i in 0..20_000 {
            let (a, b) = (point(s, 1.0), point(s, 1.0));
            let t = unit(s);
            let c = match i % 5 {
                0 => point(s, 1.0),
                // A sliver: near the line through a and b.
                1 => a.lerp(b, t * 3.0) + point(s, 1e-9),
                // Near-isosceles: near the plane halfway between a and b.
                2 => a.lerp(b, 0.5) + (b - a).any_orthonormal_vector() * t + point(s, 1e-13),
                // Near-equilateral.
                3 => e2 + point(s, 1e-14),
                _ => a + point(s, 1e-300),
            };
            let (a, b) = if i % 5 == 3 { (e0, e1) } else { (a, b) };
            cases.push((a, b, c));
        }
        for (a, b, c) in cases {
            let [x, y, z] = angles(a, b, c);
            let least = x.min(y).min(z);
            assert_eq!(
                min_angle(a, b, c).to_bits(),
                least.to_bits(),
                "{a} {b} {c}: {x} {y} {z}"
            );
        }
    }

    #[test]
    fn obtuse_triangle_detected() {
        assert!(is_obtuse(
            DVec3::ZERO,
            DVec3::X * 2.0,
            DVec3::new(1.0, 0.1, 0.0)
        ));
    }
}
