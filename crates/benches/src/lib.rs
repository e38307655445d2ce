//! `coarsen-benches`: the benchmarks of coarsen's crates, in `benches/` (criterion, and the
//! simplifiers against meshoptimizer in `qem`), and the meshes they share.
//!
//! ```sh
//! cargo bench -p coarsen-benches                       # every benchmark
//! cargo bench -p coarsen-benches --bench qem -- scale  # QEM and SVEC against meshoptimizer at 4.4M faces
//! ```
//!
//! They live apart from the crates they measure so that `cargo test` builds none of their
//! dependencies (criterion, meshoptimizer and their trees).

pub mod meshes;
