//! Spatial index of coarsen: nearest-point queries against a triangle surface.
//!
//! * [`closest_point_on_triangle`]: the exact nearest point of one triangle, robust for
//!   degenerate ones.
//! * [`Bvh`]: a compact bounding-volume hierarchy over a mesh's triangles; built once
//!   (in parallel on the current rayon pool, the same tree on any thread count) from
//!   positions and faces, then queried from any number of threads (`Bvh` is
//!   `Send + Sync` and queries take `&self`).
//! * [`NearSet`]: batched queries of points that lie close together (the samples of one
//!   face of another mesh): one gathering of the triangles that can be nearest
//!   ([`Bvh::gather_near`]) answers them all ([`Bvh::closest_point_near`]).
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
mod morton;

pub use bvh::{Bvh, NearSet, Nearest};
pub use closest::{closest_point_on_segment, closest_point_on_triangle};
