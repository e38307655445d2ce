//! Exact power-of-two rescaling, so that meshes of extreme size (1e-300 or 1e300) compute
//! like meshes of size 1: areas do not underflow, squared lengths do not overflow.
//!
//! Multiplying by 2^k is exact in binary floating point while no value leaves the normal
//! range, so scaling back restores every coordinate bit for bit.

use crate::Mesh;

/// Coordinates whose largest magnitude lies within `[2^-COMFORT_EXP, 2^COMFORT_EXP]` are left alone.
pub const COMFORT_EXP: i32 = 64;

/// The exponent `k` such that scaling by `2^k` brings the largest finite coordinate of `mesh`
/// into `[1, 2)`, or 0 when the mesh is already within `2^±COMFORT_EXP` (or has no
/// non-zero finite coordinate).
pub fn normalizing_exponent(mesh: &Mesh) -> i32 {
    let m = mesh
        .positions
        .iter()
        .flat_map(|p| p.to_array())
        .filter(|x| x.is_finite())
        .fold(0.0f64, |a, x| a.max(x.abs()));
    if m == 0.0 {
        return 0;
    }
    let e = m.log2().floor() as i32;
    if e.abs() <= COMFORT_EXP {
        0
    } else {
        (-e).clamp(-1000, 1000)
    }
}

/// Multiplies every position by `2^k` (exactly, in at most two steps of normal powers of two).
pub fn scale_by_power_of_two(mesh: &mut Mesh, k: i32) {
    if k == 0 {
        return;
    }
    let (a, b) = (k / 2, k - k / 2);
    let (fa, fb) = (2f64.powi(a), 2f64.powi(b));
    for p in &mut mesh.positions {
        *p = *p * fa * fb;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DVec3;

    fn tiny_and_huge(s: f64) -> Mesh {
        Mesh::new(
            vec![
                DVec3::ZERO,
                DVec3::new(s, 0.0, 0.0),
                DVec3::new(0.0, 3.0 * s, 0.0),
                DVec3::new(0.1 * s, -s, 7.0 * s),
            ],
            vec![[0, 1, 2], [0, 3, 1]],
        )
    }

    #[test]
    fn extreme_meshes_are_normalised_and_restored_bit_for_bit() {
        for s in [1e-300, 1e300, 3e-200, 5e250] {
            let original = tiny_and_huge(s);
            let mut m = original.clone();
            let k = normalizing_exponent(&m);
            assert_ne!(k, 0);
            scale_by_power_of_two(&mut m, k);
            let biggest = m
                .positions
                .iter()
                .flat_map(|p| p.to_array())
                .fold(0.0f64, |a, x| a.max(x.abs()));
            assert!((1.0..2.0).contains(&biggest), "{s}: {biggest}");
            assert!(
                m.face_area(0) > 1e-3 && m.face_area(0).is_finite(),
                "areas no longer underflow or overflow"
            );
            scale_by_power_of_two(&mut m, -k);
            assert_eq!(m, original, "{s}");
        }
    }

    #[test]
    fn ordinary_meshes_are_left_alone() {
        for s in [1e-9, 1.0, 1e12] {
            assert_eq!(normalizing_exponent(&tiny_and_huge(s)), 0);
        }
        assert_eq!(normalizing_exponent(&Mesh::default()), 0);
    }
}
