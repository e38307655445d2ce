//! Small meshes and cost models for the tests.

use crate::{CostModel, Index, LiveMesh, Merge, Plan, Reach, Unit};
use coarsen_geom::DVec3;
use coarsen_mesh::Mesh;

/// `(nx + 1) × (ny + 1)` vertices on the unit square, vertex `j·(nx+1) + i` at
/// `(i/nx, j/ny, height(x, y))`; each cell split along its (0,0)–(1,1) diagonal, faces
/// counter-clockwise seen from +z.
pub fn grid(nx: u32, ny: u32, height: impl Fn(f64, f64) -> f64) -> Mesh {
    let mut positions = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            let (x, y) = (i as f64 / nx as f64, j as f64 / ny as f64);
            positions.push(DVec3::new(x, y, height(x, y)));
        }
    }
    let mut faces = Vec::new();
    let at = |i: u32, j: u32| j * (nx + 1) + i;
    for j in 0..ny {
        for i in 0..nx {
            faces.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            faces.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    Mesh::new(positions, faces)
}

/// The unit icosphere: an icosahedron with each face split in four `levels` times.
pub fn icosphere(levels: u32) -> Mesh {
    coarsen_shapes::icosphere(1.0, levels).expect("a valid icosphere level")
}

/// A torus around the z axis: `nu × nv` vertices, radii `big` and `small`.
pub fn torus(big: f64, small: f64, nu: u32, nv: u32) -> Mesh {
    coarsen_shapes::torus(big, small, nu, nv).expect("valid torus parameters")
}

/// A tetrahedron, faces outward.
pub fn tetrahedron() -> Mesh {
    Mesh::new(
        vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
        vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
    )
}

/// A closed mesh's summary must say: manifold, no boundary, every figure finite.
pub fn assert_closed_manifold(mesh: &Mesh) -> crate::Summary {
    assert!(
        mesh.positions.iter().all(|p| p.is_finite()),
        "NaN in output"
    );
    let live = LiveMesh::new(mesh).unwrap();
    let s = live.summary();
    assert_eq!(s.locked_vertices, 0, "non-manifold output: {s:?}");
    assert_eq!(s.boundary_edges, 0, "open output: {s:?}");
    assert_eq!(s.isolated_vertices, 0, "unused vertices in output: {s:?}");
    s
}

/// A cost model for engine tests: cost from a function of the merged vertices, position
/// at the pinned vertex or the centroid.
pub struct Scripted<F: Fn(&LiveMesh, &[Index]) -> f64> {
    pub unit: Unit,
    pub reach: Reach,
    pub cost: F,
}

impl<F: Fn(&LiveMesh, &[Index]) -> f64 + Sync> CostModel for Scripted<F> {
    fn unit(&self) -> Unit {
        self.unit
    }

    fn reach(&self) -> Reach {
        self.reach
    }

    fn plan(&self, mesh: &LiveMesh, merge: &Merge<'_>) -> Option<Plan> {
        let position = match merge.pinned {
            Some(v) => mesh.position(v),
            None => {
                merge
                    .vertices
                    .iter()
                    .map(|&v| mesh.position(v))
                    .sum::<DVec3>()
                    / merge.vertices.len() as f64
            }
        };
        Some(Plan {
            position,
            cost: (self.cost)(mesh, merge.vertices),
        })
    }

    fn merged(&mut self, _: &LiveMesh, _: Index, _: &[Index]) {}
}

/// Edge collapses costed by squared length.
pub fn shortest_edge() -> Scripted<impl Fn(&LiveMesh, &[Index]) -> f64> {
    Scripted {
        unit: Unit::Edge,
        reach: Reach::Kept,
        cost: |m: &LiveMesh, v: &[Index]| (m.position(v[0]) - m.position(v[1])).length_squared(),
    }
}

/// Triangle collapses costed by area, re-costing as far as `reach`.
pub fn smallest_triangle(reach: Reach) -> Scripted<impl Fn(&LiveMesh, &[Index]) -> f64> {
    Scripted {
        unit: Unit::Triangle,
        reach,
        cost: |m: &LiveMesh, v: &[Index]| {
            coarsen_geom::triangle::area(m.position(v[0]), m.position(v[1]), m.position(v[2]))
        },
    }
}
