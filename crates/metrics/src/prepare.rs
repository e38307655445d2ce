//! Checks and shared facts about a mesh before it is measured, and the fixed-chunk
//! parallel map that keeps every figure bit-for-bit independent of the thread count.

use crate::error::{MAX_COORDINATE, MetricsError, Role};
use coarsen_geom::Aabb;
use coarsen_mesh::Mesh;
use rayon::prelude::*;
use std::ops::Range;

/// A mesh whose indices are valid and whose used vertices are finite, with the facts
/// every figure needs.
pub(crate) struct Prepared<'a> {
    /// The mesh.
    pub mesh: &'a Mesh,
    /// Bounding box of the referenced vertices (the surface; loose vertices are not part
    /// of it).
    pub bbox: Aabb,
}

impl<'a> Prepared<'a> {
    /// Checks `mesh` (indices, column lengths, used vertices finite and within
    /// ±[`MAX_COORDINATE`]) and gathers its facts.
    pub fn new(mesh: &'a Mesh, role: Role) -> Result<Self, MetricsError> {
        mesh.validate_indices()
            .map_err(|source| MetricsError::Indices { mesh: role, source })?;
        let mut referenced = vec![false; mesh.n_vertices()];
        for f in &mesh.faces {
            for &v in f {
                referenced[v as usize] = true;
            }
        }
        let mut bbox = Aabb::EMPTY;
        for (v, (p, _)) in mesh
            .positions
            .iter()
            .zip(&referenced)
            .enumerate()
            .filter(|(_, (_, r))| **r)
        {
            // `max_element` passes a NaN by when another coordinate is a number: test
            // finiteness first.
            let in_range = p.is_finite() && p.abs().max_element() <= MAX_COORDINATE;
            if !in_range {
                return Err(MetricsError::BadCoordinate {
                    mesh: role,
                    vertex: v,
                    position: *p,
                });
            }
            bbox.grow(*p);
        }
        Ok(Prepared { mesh, bbox })
    }
}

/// Splits `0..n` into fixed chunks of `chunk` items, maps each chunk in parallel and
/// returns the results in chunk order. The chunking does not depend on the thread count,
/// so folding the results in order gives the same bits on any number of threads.
pub(crate) fn map_chunks<T: Send>(
    n: usize,
    chunk: usize,
    f: impl Fn(Range<usize>) -> T + Sync,
) -> Vec<T> {
    (0..n.div_ceil(chunk))
        .into_par_iter()
        .map(|c| f(c * chunk..((c + 1) * chunk).min(n)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::DVec3;

    fn tetrahedron() -> Mesh {
        Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
            vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
        )
    }

    #[test]
    fn unused_vertices_are_left_out_of_the_box_even_when_not_finite() {
        let mut m = tetrahedron();
        m.positions.push(DVec3::splat(100.0));
        m.positions.push(DVec3::splat(f64::NAN));
        let p = Prepared::new(&m, Role::Output).unwrap();
        assert_eq!(p.bbox.max, DVec3::ONE);
    }

    #[test]
    fn bad_meshes_are_named_errors() {
        let mut m = tetrahedron();
        m.positions[2].y = f64::INFINITY;
        assert!(matches!(
            Prepared::new(&m, Role::Input),
            Err(MetricsError::BadCoordinate {
                mesh: Role::Input,
                vertex: 2,
                ..
            })
        ));
        // NaN in one coordinate only (the others numbers).
        for axis in 0..3 {
            let mut m = tetrahedron();
            m.positions[3][axis] = f64::NAN;
            assert!(
                matches!(
                    Prepared::new(&m, Role::Input),
                    Err(MetricsError::BadCoordinate { vertex: 3, .. })
                ),
                "NaN on axis {axis}"
            );
        }
        let mut m = tetrahedron();
        m.positions[1].x = 1e200;
        assert!(matches!(
            Prepared::new(&m, Role::Output),
            Err(MetricsError::BadCoordinate { vertex: 1, .. })
        ));
        let mut m = tetrahedron();
        m.faces[3][1] = 7;
        let err = Prepared::new(&m, Role::Output).err().unwrap();
        assert!(
            err.to_string()
                .starts_with("output mesh: face 3 names vertex 7")
        );
    }

    #[test]
    fn chunks_come_back_in_order_and_cover_the_range() {
        let got = map_chunks(10, 3, |r| (r.start, r.end));
        assert_eq!(got, vec![(0, 3), (3, 6), (6, 9), (9, 10)]);
        assert!(map_chunks(0, 3, |r| r.len()).is_empty());
    }
}
