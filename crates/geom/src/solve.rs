//! Guarded small linear solves.

use glam::{DMat3, DVec3};

/// Solves `m · x = rhs` when `m` is well conditioned, else `None`.
///
/// "Well conditioned" means `|det m|` is at least `rel_tol · ‖m‖³` (Frobenius norm), so
/// the test does not depend on the mesh's scale. Quadric minimisers use `rel_tol ≈ 1e-10`.
#[inline]
pub fn solve3(m: DMat3, rhs: DVec3, rel_tol: f64) -> Option<DVec3> {
    // `m.determinant()` and `m.inverse()`, bit for bit, with the cross products computed
    // once (this solve is in the collapse stages' hottest loop).
    let (x, y, z) = (m.x_axis, m.y_axis, m.z_axis);
    let yz = y.cross(z);
    let det = x.dot(yz);
    let norm = (x.length_squared() + y.length_squared() + z.length_squared()).sqrt();
    let scale = norm * norm * norm;
    if !det.is_finite() || scale == 0.0 || det.abs() <= rel_tol * scale {
        return None;
    }
    let inv_det = DVec3::splat(1.0 / det);
    let inverse =
        DMat3::from_cols(yz * inv_det, z.cross(x) * inv_det, x.cross(y) * inv_det).transpose();
    let p = inverse * rhs;
    p.is_finite().then_some(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equals_glams_determinant_and_inverse_bit_for_bit() {
        // The reading with glam's own determinant and inverse (each computes the cross
        // products again), on random, nearly singular and badly scaled matrices.
        let reference = |m: DMat3, rhs: DVec3, rel_tol: f64| {
            let det = m.determinant();
            let norm =
                (m.x_axis.length_squared() + m.y_axis.length_squared() + m.z_axis.length_squared())
                    .sqrt();
            let scale = norm * norm * norm;
            if !det.is_finite() || scale == 0.0 || det.abs() <= rel_tol * scale {
                return None;
            }
            let x = m.inverse() * rhs;
            x.is_finite().then_some(x)
        };
        let mut state = 2024u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let (mut solved, mut refused) = (0, 0);
        for round in 0..20_000i32 {
            let mut v = || DVec3::new(next(), next(), next());
            let (x, y, w) = (v(), v(), v());
            // Every third matrix has a third column nearly in the plane of the first two.
            let tilt = [1.0, 1e-9, 1e-12][(round % 3) as usize];
            let z = 0.3 * x - 0.7 * y + tilt * w;
            let m = DMat3::from_cols(x, y, z) * 10f64.powi(round % 7 - 3);
            let rhs = v();
            let got = solve3(m, rhs, 1e-10);
            let want = reference(m, rhs, 1e-10);
            assert_eq!(
                got.map(|p| p.to_array().map(f64::to_bits)),
                want.map(|p| p.to_array().map(f64::to_bits)),
                "round {round}"
            );
            match got {
                Some(_) => solved += 1,
                None => refused += 1,
            }
        }
        assert!(
            solved > 1000 && refused > 1000,
            "{solved} solved, {refused} refused"
        );
    }

    #[test]
    fn solves_a_regular_system() {
        let m = DMat3::from_cols(
            DVec3::new(4.0, 1.0, 0.0),
            DVec3::new(1.0, 3.0, 1.0),
            DVec3::new(0.0, 1.0, 2.0),
        );
        let x = DVec3::new(1.0, -2.0, 0.5);
        let got = solve3(m, m * x, 1e-10).unwrap();
        assert!((got - x).length() < 1e-12);
    }

    #[test]
    fn refuses_singular_and_nearly_singular_systems() {
        let m = DMat3::from_cols(DVec3::X, DVec3::Y, DVec3::ZERO);
        assert!(solve3(m, DVec3::ONE, 1e-10).is_none());
        let m = DMat3::from_cols(DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 1e-14));
        assert!(solve3(m, DVec3::ONE, 1e-10).is_none());
        // Scale does not matter: the same shape at 1e-6 scale is still solvable.
        let m = DMat3::from_diagonal(DVec3::splat(1e-6));
        assert!(solve3(m, DVec3::ONE, 1e-10).is_some());
    }
}
