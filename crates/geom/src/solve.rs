//! Guarded small linear solves.

use glam::{DMat3, DVec3};

/// Solves `m · x = rhs` when `m` is well conditioned, else `None`.
///
/// "Well conditioned" means `|det m|` is at least `rel_tol · ‖m‖³` (Frobenius norm), so
/// the test does not depend on the mesh's scale. Quadric minimisers use `rel_tol ≈ 1e-10`.
pub fn solve3(m: DMat3, rhs: DVec3, rel_tol: f64) -> Option<DVec3> {
    let det = m.determinant();
    let norm =
        (m.x_axis.length_squared() + m.y_axis.length_squared() + m.z_axis.length_squared()).sqrt();
    let scale = norm * norm * norm;
    if !det.is_finite() || scale == 0.0 || det.abs() <= rel_tol * scale {
        return None;
    }
    let x = m.inverse() * rhs;
    x.is_finite().then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

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
