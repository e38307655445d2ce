//! Axis-aligned bounding boxes.

use glam::DVec3;

/// An axis-aligned box; empty when `min > max` on any axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Smallest corner.
    pub min: DVec3,
    /// Largest corner.
    pub max: DVec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The empty box: grows to the first point added.
    pub const EMPTY: Aabb = Aabb {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    /// The smallest box holding every point.
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a DVec3>) -> Self {
        let mut b = Self::EMPTY;
        for p in points {
            b.grow(*p);
        }
        b
    }

    /// Enlarges the box to hold `p`.
    #[inline]
    pub fn grow(&mut self, p: DVec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// Enlarges the box to hold `other`.
    #[inline]
    pub fn union(&mut self, other: &Aabb) {
        self.min = self.min.min(other.min);
        self.max = self.max.max(other.max);
    }

    /// True when the box holds no point.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    /// Edge lengths along each axis (zero for an empty box).
    pub fn extent(&self) -> DVec3 {
        if self.is_empty() {
            DVec3::ZERO
        } else {
            self.max - self.min
        }
    }

    /// Length of the main diagonal (zero for an empty box).
    pub fn diagonal(&self) -> f64 {
        self.extent().length()
    }

    /// Centre point (origin for an empty box).
    pub fn center(&self) -> DVec3 {
        if self.is_empty() {
            DVec3::ZERO
        } else {
            (self.min + self.max) * 0.5
        }
    }

    /// Squared distance from `p` to the box (zero inside).
    #[inline]
    pub fn distance_squared(&self, p: DVec3) -> f64 {
        let d = (self.min - p).max(p - self.max).max(DVec3::ZERO);
        d.length_squared()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_box_has_zero_diagonal_and_grows_to_points() {
        let mut b = Aabb::EMPTY;
        assert!(b.is_empty());
        assert_eq!(b.diagonal(), 0.0);
        b.grow(DVec3::new(1.0, 2.0, 3.0));
        b.grow(DVec3::new(-1.0, 2.0, 0.0));
        assert_eq!(b.min, DVec3::new(-1.0, 2.0, 0.0));
        assert_eq!(b.max, DVec3::new(1.0, 2.0, 3.0));
        assert!((b.diagonal() - 13f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn distance_to_box_is_zero_inside_and_euclidean_outside() {
        let b = Aabb::from_points(&[DVec3::ZERO, DVec3::ONE]);
        assert_eq!(b.distance_squared(DVec3::splat(0.5)), 0.0);
        assert!((b.distance_squared(DVec3::new(2.0, 2.0, 0.5)) - 2.0).abs() < 1e-12);
    }
}
