//! Geometry maths in `f64` for coarsen: triangle measures, bounding boxes, plane
//! quadrics and guarded small solves.
//!
//! This crate knows no mesh, no attribute and no file: every function takes points
//! ([`DVec3`]) and returns numbers, so the mesh core, the metrics and every stage share
//! one definition of "area", "angle" or "quality".
//!
//! ```
//! use coarsen_geom::{DVec3, triangle};
//! let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::new(0.5, 3f64.sqrt() / 2.0, 0.0));
//! assert!((triangle::quality(a, b, c) - 1.0).abs() < 1e-12);
//! assert!((triangle::min_angle(a, b, c).to_degrees() - 60.0).abs() < 1e-9);
//! ```

pub mod aabb;
pub mod quadric;
pub mod random;
pub mod solve;
pub mod triangle;

pub use aabb::Aabb;
pub use glam::{DMat3, DVec2, DVec3, DVec4};
pub use quadric::Quadric;
pub use random::SplitMix64;

/// True when every coordinate is finite (no NaN, no infinity).
#[inline]
pub fn is_finite(p: DVec3) -> bool {
    p.x.is_finite() && p.y.is_finite() && p.z.is_finite()
}
