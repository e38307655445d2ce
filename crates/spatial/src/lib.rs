//! Spatial index of coarsen: nearest-point queries against a triangle surface.
//!
//! * [`closest_point_on_triangle`]: the exact nearest point of one triangle, robust for
//!   degenerate ones.
//! * [`Bvh`]: a compact bounding-volume hierarchy over a mesh's triangles; built once
//!   (deterministically) from positions and faces, then queried from any number of threads
//!   (`Bvh` is `Send + Sync` and queries take `&self`).
//!
//! ```
//! use coarsen_spatial::Bvh;
//! use glam::DVec3;
//! let positions = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
//! let faces = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]];
//! let bvh = Bvh::build(&positions, &faces);
//! let hit = bvh.closest_point(DVec3::new(0.2, 0.2, -1.0)).unwrap();
//! assert_eq!(hit.face, 0);
//! assert_eq!(hit.point, DVec3::new(0.2, 0.2, 0.0));
//! assert_eq!(hit.distance_squared, 1.0);
//! ```
//!
//! The index knows no mesh type, no attribute and no file: it takes plain arrays.

pub mod bvh;
pub mod closest;

pub use bvh::{Bvh, Nearest};
pub use closest::{closest_point_on_segment, closest_point_on_triangle};
