//! The flipped-face test of [`Facing`](crate::Facing) on a lighter index: a uniform grid of
//! face indices (about one cell per face), built in two passes over the faces, for stages
//! that test few faces of a big input (a bounding-volume hierarchy and the full adjacency
//! cost more to build than such a stage spends testing). The faces around a vertex are
//! found in the cell holding the vertex: every face's bounding box, and so every cell it
//! is listed in, holds its corners.

use crate::validity::{face_cross, surface_normal_with};
use coarsen_geom::triangle;
use coarsen_mesh::{DVec3, Mesh};
use coarsen_spatial::closest_point_on_triangle;

/// The grid's cell edge, in mean face edge lengths.
const CELL_EDGES: f64 = 2.0;

/// At most this many cells per face (plus a constant): big, sparse meshes get coarser cells.
const CELLS_PER_FACE: f64 = 1.0;

/// An input surface indexed for the flipped-face test of the metrics ([`Facing`](crate::Facing)
/// gives the same answers from a hierarchy and the full adjacency).
pub struct GridFacing<'a> {
    mesh: &'a Mesh,
    origin: DVec3,
    cell: f64,
    dims: [usize; 3],
    /// Per cell, where its faces start in `items` (one more entry than cells).
    start: Vec<u32>,
    /// Faces whose bounding box meets each cell, cell after cell, in ascending order.
    items: Vec<u32>,
}

impl<'a> GridFacing<'a> {
    /// Indexes `input`. Faces with a non-finite corner or an index out of range are left
    /// out (the metrics refuse such meshes anyway).
    pub fn new(input: &'a Mesh) -> Self {
        let n_vertices = input.n_vertices();
        let mut grid = GridFacing {
            mesh: input,
            origin: DVec3::ZERO,
            cell: 1.0,
            dims: [0; 3],
            start: vec![0],
            items: Vec::new(),
        };
        let finite = |v: u32| (v as usize) < n_vertices && input.positions[v as usize].is_finite();
        // The box of the finite vertices, and the mean edge of a sample of the faces.
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in input.positions.iter().filter(|p| p.is_finite()) {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let every = (input.n_faces() / 65_536).max(1);
        let (mut edge_sum, mut sampled) = (0.0, 0usize);
        for f in input.faces.iter().step_by(every) {
            if f.iter().all(|&v| finite(v)) {
                let [a, b, c] = f.map(|v| input.positions[v as usize]);
                edge_sum += (b - a).length() + (c - b).length() + (a - c).length();
                sampled += 1;
            }
        }
        if sampled == 0 {
            return grid;
        }
        let extent = (hi - lo).max(DVec3::splat(f64::MIN_POSITIVE));
        let mean_edge = edge_sum / (3 * sampled) as f64;
        let budget = CELLS_PER_FACE * input.n_faces() as f64 + 64.0;
        let mut cell = (CELL_EDGES * mean_edge).max(extent.max_element() / 4096.0);
        let cells_of = |cell: f64| (extent / cell).floor() + DVec3::ONE;
        while cells_of(cell).element_product() > budget {
            cell *= 1.25;
        }
        let d = cells_of(cell);
        grid.origin = lo;
        grid.cell = cell;
        grid.dims = [d.x as usize, d.y as usize, d.z as usize];
        let n_cells = grid.dims.iter().product::<usize>();
        // Each vertex's cell once (the faces then read 6 bytes per corner, not 24);
        // `u16::MAX` marks a vertex that is not finite (at most 4097 cells per axis).
        let vertex_cell: Vec<[u16; 3]> = input
            .positions
            .iter()
            .map(|p| {
                if p.is_finite() {
                    grid.cell_of(*p).map(|c| c as u16)
                } else {
                    [u16::MAX; 3]
                }
            })
            .collect();
        // A face's cells: the box of its corners' cells (cell_of is monotone per axis).
        let cells = |face: &[u32; 3]| -> Option<([usize; 3], [usize; 3])> {
            let mut lo = [usize::MAX; 3];
            let mut hi = [0; 3];
            for &v in face {
                let c = *vertex_cell.get(v as usize)?;
                if c[0] == u16::MAX {
                    return None;
                }
                for i in 0..3 {
                    lo[i] = lo[i].min(c[i] as usize);
                    hi[i] = hi[i].max(c[i] as usize);
                }
            }
            Some((lo, hi))
        };
        // Two passes: count the faces meeting each cell, then place them (back to front,
        // so that each cell's faces end in ascending order and `start` ends right).
        let mut start = vec![0u32; n_cells + 1];
        for face in &input.faces {
            if let Some((lo, hi)) = cells(face) {
                grid.for_cells(lo, hi, |c| start[c + 1] += 1);
            }
        }
        for i in 1..start.len() {
            start[i] += start[i - 1];
        }
        let mut items = vec![0u32; start[n_cells] as usize];
        for (f, face) in input.faces.iter().enumerate().rev() {
            if let Some((lo, hi)) = cells(face) {
                grid.for_cells(lo, hi, |c| {
                    start[c + 1] -= 1;
                    items[start[c + 1] as usize] = f as u32;
                });
            }
        }
        // Each `start[c + 1]` now marks where cell c begins: shift them back by one.
        start.remove(0);
        start.push(items.len() as u32);
        grid.start = start;
        grid.items = items;
        grid
    }

    /// The cell coordinates of `p`, clamped into the grid.
    fn cell_of(&self, p: DVec3) -> [usize; 3] {
        let q = (p - self.origin) / self.cell;
        let mut c = [0; 3];
        for (i, slot) in c.iter_mut().enumerate() {
            let x = q[i].floor();
            *slot = if x > 0.0 {
                (x as usize).min(self.dims[i] - 1)
            } else {
                0
            };
        }
        c
    }

    fn cell_index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// Calls `visit` with every cell from `lo` to `hi` (inclusive, per axis).
    fn for_cells(&self, lo: [usize; 3], hi: [usize; 3], mut visit: impl FnMut(usize)) {
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    visit(self.cell_index([x, y, z]));
                }
            }
        }
    }

    /// The face of the input nearest to `p`, the nearest point's barycentric weights and
    /// the squared distance; `None` for an empty input or a non-finite `p`.
    pub fn nearest(&self, p: DVec3) -> Option<(u32, [f64; 3], f64)> {
        if self.items.is_empty() || !p.is_finite() {
            return None;
        }
        let c = self.cell_of(p);
        let mut best: Option<(u32, [f64; 3], f64)> = None;
        let reach = self.dims.iter().copied().max().unwrap_or(0);
        for r in 0..=reach {
            let lo = c.map(|x| x.saturating_sub(r));
            let hi = [0, 1, 2].map(|i| (c[i] + r).min(self.dims[i] - 1));
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let ring = [x.abs_diff(c[0]), y.abs_diff(c[1]), z.abs_diff(c[2])];
                        if ring.into_iter().max() != Some(r) {
                            continue;
                        }
                        let i = self.cell_index([x, y, z]);
                        let box_lo =
                            self.origin + DVec3::new(x as f64, y as f64, z as f64) * self.cell;
                        let gap = (box_lo - p)
                            .max(p - (box_lo + DVec3::splat(self.cell)))
                            .max(DVec3::ZERO);
                        if best.is_some_and(|b| gap.length_squared() > b.2) {
                            continue;
                        }
                        for &f in &self.items[self.start[i] as usize..self.start[i + 1] as usize] {
                            let [a, b, c] = self.mesh.corners(f as usize);
                            let (q, w) = closest_point_on_triangle(p, a, b, c);
                            let d2 = (p - q).length_squared();
                            if best.is_none_or(|b| d2 < b.2 || (d2 == b.2 && f < b.0)) {
                                best = Some((f, w, d2));
                            }
                        }
                    }
                }
            }
            // Cells one ring farther out lie at least r cells away.
            if let Some(b) = best {
                let bound = r as f64 * self.cell;
                if bound * bound > b.2 {
                    break;
                }
            }
        }
        best
    }

    /// True when triangle `abc` would count as flipped against the input: its normal points
    /// away (> 90°) from the input's normal at the input point nearest its centroid.
    pub fn faces_away(&self, a: DVec3, b: DVec3, c: DVec3) -> bool {
        let n_out = triangle::cross(a, b, c);
        if n_out == DVec3::ZERO {
            return false;
        }
        let Some((face, bary, _)) = self.nearest(triangle::centroid(a, b, c)) else {
            return false;
        };
        let mesh = self.mesh;
        // The faces listed in the cell of vertex `v` that use `v` (and `w`).
        let around = |v: u32, w: u32| -> DVec3 {
            let i = self.cell_index(self.cell_of(mesh.positions[v as usize]));
            self.items[self.start[i] as usize..self.start[i + 1] as usize]
                .iter()
                .filter(|&&f| {
                    let face = &mesh.faces[f as usize];
                    face.contains(&v) && face.contains(&w)
                })
                .map(|&f| face_cross(mesh, f))
                .sum()
        };
        let vertex_normal = |v: u32| around(v, v);
        let edge_normal = |u: u32, v: u32| around(u, v);
        n_out.dot(surface_normal_with(
            mesh,
            face,
            bary,
            vertex_normal,
            edge_normal,
        )) < 0.0
    }
}

/// The facing test of [`GridFacing`] against an input whose grid is built on the first
/// question only (a collapse stage whose gate may never ask one pays nothing); shared by
/// threads, the first to ask builds it.
pub struct LazyGridFacing<'a> {
    input: &'a Mesh,
    grid: std::sync::OnceLock<GridFacing<'a>>,
}

impl<'a> LazyGridFacing<'a> {
    /// `input`, not indexed yet.
    pub fn new(input: &'a Mesh) -> Self {
        LazyGridFacing {
            input,
            grid: std::sync::OnceLock::new(),
        }
    }

    /// True when triangle `abc` does not point away from the input surface nearest it.
    pub fn allows(&self, a: DVec3, b: DVec3, c: DVec3) -> bool {
        !self
            .grid
            .get_or_init(|| GridFacing::new(self.input))
            .faces_away(a, b, c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Facing;
    use crate::test_meshes::icosphere;

    /// A deterministic scatter of points in [-s, s]³.
    fn points(n: usize, s: f64) -> Vec<DVec3> {
        let mut rng = coarsen_geom::SplitMix64::new(1);
        (0..n).map(|_| rng.point(-s, s)).collect()
    }

    #[test]
    fn nearest_points_match_the_hierarchy() {
        let sphere = icosphere(3);
        let grid = GridFacing::new(&sphere);
        let facing = Facing::new(&sphere);
        for p in points(500, 1.6) {
            let (_, _, d2) = grid.nearest(p).unwrap();
            let hit = facing.bvh().closest_point(p).unwrap();
            assert!(
                (d2 - hit.distance_squared).abs() <= 1e-12 * (1.0 + d2),
                "{p}: grid {d2}, hierarchy {}",
                hit.distance_squared
            );
        }
    }

    #[test]
    fn flip_answers_match_facing() {
        // Small triangles around the sphere, each in both orientations, some well
        // inside and outside it: the grid and the hierarchy must agree on every one.
        let sphere = icosphere(2);
        let grid = GridFacing::new(&sphere);
        let facing = Facing::new(&sphere);
        let (mut away, mut total) = (0, 0);
        for (i, p) in points(400, 1.4).into_iter().enumerate() {
            let n = p.normalize_or(DVec3::Z);
            let u = n.any_orthonormal_vector() * 0.05;
            let v = n.cross(u);
            let (a, b, c) = (p + u, p + v, p - u - v);
            let (a, b) = if i % 2 == 0 { (a, b) } else { (b, a) };
            let g = grid.faces_away(a, b, c);
            assert_eq!(g, facing.faces_away(a, b, c), "triangle at {p}");
            away += usize::from(g);
            total += 1;
        }
        assert!(
            away > total / 4 && away < 3 * total / 4,
            "{away} of {total}"
        );
    }

    #[test]
    fn empty_and_bad_input_answer_nothing() {
        let empty = Mesh::new(vec![], vec![]);
        let grid = GridFacing::new(&empty);
        assert!(grid.nearest(DVec3::ZERO).is_none());
        assert!(!grid.faces_away(DVec3::ZERO, DVec3::X, DVec3::Y));
        let mut bad = icosphere(1);
        bad.positions[0] = DVec3::splat(f64::NAN);
        bad.faces.push([0, 1, 99]);
        let grid = GridFacing::new(&bad);
        assert!(grid.nearest(DVec3::new(0.0, 0.0, 2.0)).is_some());
        assert!(grid.nearest(DVec3::splat(f64::NAN)).is_none());
    }
}
