//! Small meshes and cost models for the tests.

use crate::{CostModel, Index, LiveMesh, Merge, Plan, Reach, Unit};
use coarsen_geom::DVec3;
use coarsen_mesh::Mesh;
use std::collections::BTreeMap;

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
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut positions: Vec<DVec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut faces: Vec<[Index; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: BTreeMap<(Index, Index), Index> = BTreeMap::new();
        let mut split = |a: Index, b: Index, positions: &mut Vec<DVec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                positions.push(((positions[a as usize] + positions[b as usize]) / 2.0).normalize());
                positions.len() as Index - 1
            })
        };
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let ab = split(a, b, &mut positions);
            let bc = split(b, c, &mut positions);
            let ca = split(c, a, &mut positions);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    Mesh::new(positions, faces)
}

/// A torus around the z axis: `nu × nv` vertices, radii `big` and `small`.
pub fn torus(big: f64, small: f64, nu: u32, nv: u32) -> Mesh {
    let mut positions = Vec::new();
    for i in 0..nu {
        let u = i as f64 / nu as f64 * std::f64::consts::TAU;
        for j in 0..nv {
            let v = j as f64 / nv as f64 * std::f64::consts::TAU;
            let r = big + small * v.cos();
            positions.push(DVec3::new(r * u.cos(), r * u.sin(), small * v.sin()));
        }
    }
    let at = |i: u32, j: u32| (i % nu) * nv + (j % nv);
    let mut faces = Vec::new();
    for i in 0..nu {
        for j in 0..nv {
            faces.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            faces.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    Mesh::new(positions, faces)
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

impl<F: Fn(&LiveMesh, &[Index]) -> f64> CostModel for Scripted<F> {
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
