//! Plane quadrics (Garland–Heckbert): sums of squared distances to planes.

use crate::solve::solve3;
use glam::{DMat3, DVec3};

/// A symmetric quadric `E(v) = vᵀAv + 2bᵀv + c`, the 4×4 form `p pᵀ` of one or more
/// planes `p = (n, d)` summed with weights.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Quadric {
    /// Upper triangle of `A`: xx, xy, xz, yy, yz, zz.
    pub a: [f64; 6],
    /// The linear part `b`.
    pub b: DVec3,
    /// The constant `c`.
    pub c: f64,
}

impl Quadric {
    /// The zero quadric.
    pub const ZERO: Quadric = Quadric {
        a: [0.0; 6],
        b: DVec3::ZERO,
        c: 0.0,
    };

    /// `weight · (n·v + d)²` for the plane through `point` with unit normal `n`.
    #[inline]
    pub fn from_plane(n: DVec3, point: DVec3, weight: f64) -> Self {
        Quadric::from_plane_offset(n, -n.dot(point), weight)
    }

    /// `weight · (n·v + d)²` for the plane n·v + d = 0 (unit `n`).
    #[inline]
    pub fn from_plane_offset(n: DVec3, d: f64, weight: f64) -> Self {
        let w = weight;
        Quadric {
            a: [
                w * n.x * n.x,
                w * n.x * n.y,
                w * n.x * n.z,
                w * n.y * n.y,
                w * n.y * n.z,
                w * n.z * n.z,
            ],
            b: w * d * n,
            c: w * d * d,
        }
    }

    /// The matrix `A`.
    #[inline]
    pub fn matrix(&self) -> DMat3 {
        let [xx, xy, xz, yy, yz, zz] = self.a;
        DMat3::from_cols(
            DVec3::new(xx, xy, xz),
            DVec3::new(xy, yy, yz),
            DVec3::new(xz, yz, zz),
        )
    }

    /// Value at `v`; never negative beyond rounding.
    #[inline]
    pub fn eval(&self, v: DVec3) -> f64 {
        let [xx, xy, xz, yy, yz, zz] = self.a;
        let av = DVec3::new(
            xx * v.x + xy * v.y + xz * v.z,
            xy * v.x + yy * v.y + yz * v.z,
            xz * v.x + yz * v.y + zz * v.z,
        );
        v.dot(av) + 2.0 * self.b.dot(v) + self.c
    }

    /// The point minimising the quadric, when `A` is well conditioned (see [`solve3`]).
    #[inline]
    pub fn minimizer(&self, rel_tol: f64) -> Option<DVec3> {
        solve3(self.matrix(), -self.b, rel_tol)
    }
}

impl std::ops::Add for Quadric {
    type Output = Quadric;
    #[inline]
    fn add(mut self, o: Quadric) -> Quadric {
        self += o;
        self
    }
}

impl std::ops::AddAssign for Quadric {
    #[inline]
    fn add_assign(&mut self, o: Quadric) {
        for (x, y) in self.a.iter_mut().zip(o.a) {
            *x += y;
        }
        self.b += o.b;
        self.c += o.c;
    }
}

impl std::ops::Mul<f64> for Quadric {
    type Output = Quadric;
    #[inline]
    fn mul(self, s: f64) -> Quadric {
        Quadric {
            a: self.a.map(|x| x * s),
            b: self.b * s,
            c: self.c * s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_quadric_measures_squared_distance() {
        let q = Quadric::from_plane(DVec3::Z, DVec3::new(0.0, 0.0, 2.0), 3.0);
        assert!((q.eval(DVec3::new(5.0, -1.0, 4.0)) - 3.0 * 4.0).abs() < 1e-12);
        assert!(q.eval(DVec3::new(1.0, 1.0, 2.0)).abs() < 1e-12);
    }

    #[test]
    fn three_planes_meet_at_their_corner() {
        let corner = DVec3::new(1.0, 2.0, 3.0);
        let q = Quadric::from_plane(DVec3::X, corner, 1.0)
            + Quadric::from_plane(DVec3::Y, corner, 1.0)
            + Quadric::from_plane(DVec3::Z, corner, 1.0);
        let v = q.minimizer(1e-10).unwrap();
        assert!((v - corner).length() < 1e-12);
        // Two planes only: a line of minima, so no unique minimiser.
        let q2 =
            Quadric::from_plane(DVec3::X, corner, 1.0) + Quadric::from_plane(DVec3::Y, corner, 1.0);
        assert!(q2.minimizer(1e-10).is_none());
    }
}
