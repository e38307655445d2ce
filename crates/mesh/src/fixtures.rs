//! Tiny hand-drawn meshes shared by the crate's unit tests.

use crate::{DVec3, Mesh};

/// A closed tetrahedron, outward oriented.
///
/// ```text
///        3
///       /|\
///      / | \
///     0--|--1     base 0-2-1 seen from below
///      \ | /
///        2
/// ```
pub(crate) fn tetrahedron() -> Mesh {
    Mesh::new(
        vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
        vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
    )
}

/// Two triangles touching at vertex 0 only (a bow-tie).
///
/// ```text
///  2       4
///  | \   / |
///  |   0   |
///  | /   \ |
///  1       3
/// ```
pub(crate) fn bowtie() -> Mesh {
    Mesh::new(
        vec![
            DVec3::ZERO,
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0),
            DVec3::new(1.0, -1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
        ],
        vec![[0, 2, 1], [0, 3, 4]],
    )
}

/// Proptest settings with the fixed seed `seed` unless `PROPTEST_RNG_SEED` is set, so CI
/// runs the same cases every time.
pub(crate) fn fixed_seed(seed: u64) -> proptest::test_runner::Config {
    let mut c = proptest::test_runner::Config::default();
    if matches!(c.rng_seed, proptest::test_runner::RngSeed::Random) {
        c.rng_seed = proptest::test_runner::RngSeed::Fixed(seed);
    }
    c
}
