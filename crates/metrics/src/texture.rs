//! How well an output keeps its input's texture coordinates: seams, UV flips, and the
//! texture distortion.
//!
//! Both meshes must carry a `uv` column, per corner (wedges) or per vertex.
//!
//! * **Seam vertices**: vertices with two or more wedges, in each mesh (UV seams and any
//!   other per-corner column's splits).
//! * **UV flips**: output faces whose triangle in UV space winds the other way than the
//!   input face under its UV centroid (the input face nearest its 3-D centroid when no
//!   input UV triangle holds that point) does: a chart mirrored in UV space stays
//!   mirrored. Faces of zero UV area are counted apart; input faces of zero UV area say
//!   nothing.
//! * **Texture distortion**: for each output corner's (vertex, UV) pair, the 3-D distance
//!   between the vertex and the point its UV maps to on the input — the point of the input
//!   face whose UV triangle holds that UV (of several, the nearest the vertex; of none, the
//!   face whose UV triangle is nearest in UV space) —, max and mean over the pairs, in % of
//!   the input's bounding-box diagonal. A vertex whose UV is its own input vertex's scores
//!   0; a UV that names another place on the texture scores that place's distance.
//! * **Surface distortion**: the same inside the output's faces, where the texture is
//!   seen: at four points of each face (its centroid and the points weighted 2/3, 1/6,
//!   1/6 towards each corner), the 3-D distance between the point and where its
//!   interpolated UV maps to on the input; max, and mean weighted by face area, in % of
//!   the diagonal. A simplifier that keeps input vertices and their UVs scores 0 at the
//!   vertices but not here: a coarse face's UVs spread linearly over a surface that was
//!   curved.

use coarsen_geom::{DVec2, DVec3};
use coarsen_mesh::{AttrValues, Mesh};
use coarsen_spatial::Bvh;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

/// The column the texture figures read.
pub const UV: &str = "uv";

/// The texture figures of an output against its input (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Texture {
    /// Input vertices with two or more wedges.
    pub seam_vertices_in: usize,
    /// Output vertices with two or more wedges.
    pub seam_vertices: usize,
    /// Output faces whose UV triangle winds against the nearest input face's.
    pub uv_flipped: usize,
    /// Output faces of zero UV area.
    pub uv_degenerate: usize,
    /// Largest texture distortion, % of the input's diagonal.
    pub distortion_max_pct: f64,
    /// Mean texture distortion over the output's (vertex, UV) pairs, % of the diagonal.
    pub distortion_mean_pct: f64,
    /// (vertex, UV) pairs whose UV lies in no input face's UV triangle.
    pub uv_outside: usize,
    /// Largest surface distortion (inside the faces), % of the diagonal.
    pub surface_distortion_max_pct: f64,
    /// Area-weighted mean surface distortion, % of the diagonal.
    pub surface_distortion_mean_pct: f64,
}

/// The points of each face where the surface distortion is measured (barycentric).
const FACE_POINTS: [[f64; 3]; 4] = [
    [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
    [4.0 / 6.0, 1.0 / 6.0, 1.0 / 6.0],
    [1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0],
    [1.0 / 6.0, 1.0 / 6.0, 4.0 / 6.0],
];

/// Each corner's UV (`3 · face + k`), from the wedges or a vertex column; `None` without a
/// `uv` column of 2-D values.
pub fn corner_uvs(mesh: &Mesh) -> Option<Vec<DVec2>> {
    if let Some(AttrValues::Vec2(uv)) = mesh.wedges.attrs().get(UV) {
        return Some(
            mesh.wedges
                .corners()
                .iter()
                .map(|&w| uv[w as usize])
                .collect(),
        );
    }
    let uv = mesh.vertex_attrs.vec2(UV)?;
    Some(
        mesh.faces
            .iter()
            .flatten()
            .map(|&v| uv.get(v as usize).copied().unwrap_or(DVec2::ZERO))
            .collect(),
    )
}

/// Twice the signed area of a UV triangle.
fn uv_area(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    (b - a).perp_dot(c - a)
}

/// The texture figures of `output` against `input` (module docs), whose bounding-box
/// diagonal is `diagonal`; `None` unless both carry UVs and have faces. Both meshes'
/// indices must be valid.
pub fn texture(input: &Mesh, output: &Mesh, diagonal: f64) -> Option<Texture> {
    let uv_in = corner_uvs(input)?;
    let uv_out = corner_uvs(output)?;
    if input.faces.is_empty() || output.faces.is_empty() || diagonal <= 0.0 {
        return None;
    }
    let judge = UvJudge::new(input, uv_in);
    let mut uv_flipped = 0;
    let mut uv_degenerate = 0;
    for (f, face) in output.faces.iter().enumerate() {
        let t = [uv_out[3 * f], uv_out[3 * f + 1], uv_out[3 * f + 2]];
        match judge.judge(t, face.map(|v| output.positions[v as usize])) {
            UvWinding::Degenerate => uv_degenerate += 1,
            UvWinding::Turned => uv_flipped += 1,
            UvWinding::Right => {}
        }
    }
    let (grid, uv_in) = (&judge.grid, &judge.uv);
    // Each output (vertex, UV) pair once.
    let mut pairs: Vec<(u32, [u64; 2])> = output
        .faces
        .iter()
        .flatten()
        .zip(&uv_out)
        .map(|(&v, uv)| (v, [uv.x.to_bits(), uv.y.to_bits()]))
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    let mut max = 0.0f64;
    let mut sum = 0.0;
    let mut outside = 0;
    for &(v, [u, w]) in &pairs {
        let uv = DVec2::new(f64::from_bits(u), f64::from_bits(w));
        let p = output.positions[v as usize];
        let Located {
            point: q, inside, ..
        } = grid.locate(uv, p, input, uv_in);
        outside += usize::from(!inside);
        let d = q.distance(p);
        max = max.max(d);
        sum += d;
    }
    let (mut surface_max, mut surface_sum, mut area_sum) = (0.0f64, 0.0, 0.0);
    for (f, face) in output.faces.iter().enumerate() {
        let [a, b, c] = face.map(|v| output.positions[v as usize]);
        let area = 0.5 * (b - a).cross(c - a).length();
        for w in FACE_POINTS {
            let p = w[0] * a + w[1] * b + w[2] * c;
            let uv = w[0] * uv_out[3 * f] + w[1] * uv_out[3 * f + 1] + w[2] * uv_out[3 * f + 2];
            let q = grid.locate(uv, p, input, uv_in).point;
            let d = q.distance(p);
            surface_max = surface_max.max(d);
            surface_sum += 0.25 * area * d;
        }
        area_sum += area;
    }
    let pct = 100.0 / diagonal;
    Some(Texture {
        surface_distortion_max_pct: surface_max * pct,
        surface_distortion_mean_pct: if area_sum > 0.0 {
            surface_sum / area_sum * pct
        } else {
            0.0
        },
        seam_vertices_in: input.wedges.split_vertices(),
        seam_vertices: output.wedges.split_vertices(),
        uv_flipped,
        uv_degenerate,
        distortion_max_pct: max * pct,
        distortion_mean_pct: if pairs.is_empty() {
            0.0
        } else {
            sum / pairs.len() as f64 * pct
        },
        uv_outside: outside,
    })
}

/// How a face's UV triangle winds against the input's under it (module docs: UV flips).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UvWinding {
    /// As the input's (or the input face has no UV area).
    Right,
    /// The other way.
    Turned,
    /// Zero UV area.
    Degenerate,
}

/// Judges faces' UV windings against an input's (module docs: UV flips).
pub struct UvJudge<'a> {
    input: &'a Mesh,
    uv: Vec<DVec2>,
    area: Vec<f64>,
    grid: UvGrid,
    bvh: Cow<'a, Bvh>,
}

impl<'a> UvJudge<'a> {
    /// A judge for `input` with UVs `uv` per corner ([`corner_uvs`]).
    pub fn new(input: &'a Mesh, uv: Vec<DVec2>) -> UvJudge<'a> {
        let bvh = Bvh::build(&input.positions, &input.faces);
        UvJudge::judging(input, uv, Cow::Owned(bvh))
    }

    /// [`UvJudge::new`] with `bvh`, an index of `input`'s faces the caller built already.
    pub fn with_index(input: &'a Mesh, uv: Vec<DVec2>, bvh: &'a Bvh) -> UvJudge<'a> {
        UvJudge::judging(input, uv, Cow::Borrowed(bvh))
    }

    fn judging(input: &'a Mesh, uv: Vec<DVec2>, bvh: Cow<'a, Bvh>) -> UvJudge<'a> {
        let area = (0..input.faces.len())
            .map(|f| uv_area(uv[3 * f], uv[3 * f + 1], uv[3 * f + 2]))
            .collect();
        UvJudge {
            grid: UvGrid::new(&uv, input.faces.len()),
            bvh,
            input,
            uv,
            area,
        }
    }

    /// How a face with corner UVs `t` at 3-D corners `p` winds.
    pub fn judge(&self, t: [DVec2; 3], p: [DVec3; 3]) -> UvWinding {
        let area = uv_area(t[0], t[1], t[2]);
        if area == 0.0 {
            return UvWinding::Degenerate;
        }
        let centroid = (p[0] + p[1] + p[2]) / 3.0;
        // The input face under the face's UV centroid, else the one nearest in 3-D.
        let at = self
            .grid
            .locate((t[0] + t[1] + t[2]) / 3.0, centroid, self.input, &self.uv);
        let reference = match at.inside {
            true => Some(at.face),
            false => self.bvh.closest_point(centroid).map(|n| n.face as usize),
        };
        match reference {
            Some(r) if self.area[r] * area < 0.0 => UvWinding::Turned,
            _ => UvWinding::Right,
        }
    }
}

/// Where a UV lands on the input: the point, its face, and whether a UV triangle holds it.
struct Located {
    point: DVec3,
    face: usize,
    inside: bool,
}

/// A uniform grid over the input's UV triangles.
struct UvGrid {
    lo: DVec2,
    cell: DVec2,
    n: usize,
    /// CSR: per cell, the faces whose UV box meets it.
    start: Vec<usize>,
    faces: Vec<u32>,
}

impl UvGrid {
    fn new(uv: &[DVec2], n_faces: usize) -> UvGrid {
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for p in uv.iter().filter(|p| p.is_finite()) {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        if !lo.is_finite() {
            lo = DVec2::ZERO;
            hi = DVec2::ONE;
        }
        let n = ((n_faces as f64).sqrt().ceil() as usize).clamp(1, 1024);
        let cell = ((hi - lo) / n as f64).max(DVec2::splat(1e-12));
        let mut grid = UvGrid {
            lo,
            cell,
            n,
            start: vec![0; n * n + 1],
            faces: Vec::new(),
        };
        let boxes: Vec<Option<[usize; 4]>> = (0..n_faces)
            .map(|f| {
                let t = [uv[3 * f], uv[3 * f + 1], uv[3 * f + 2]];
                if !t.iter().all(|p| p.is_finite()) {
                    return None;
                }
                let a = grid.cell_of(t[0].min(t[1]).min(t[2]));
                let b = grid.cell_of(t[0].max(t[1]).max(t[2]));
                Some([a.0, a.1, b.0, b.1])
            })
            .collect();
        for [x0, y0, x1, y1] in boxes.iter().flatten() {
            for y in *y0..=*y1 {
                for x in *x0..=*x1 {
                    grid.start[y * n + x + 1] += 1;
                }
            }
        }
        for i in 0..n * n {
            grid.start[i + 1] += grid.start[i];
        }
        let mut fill = grid.start.clone();
        grid.faces = vec![0; grid.start[n * n]];
        for (f, b) in boxes.iter().enumerate() {
            if let Some([x0, y0, x1, y1]) = b {
                for y in *y0..=*y1 {
                    for x in *x0..=*x1 {
                        grid.faces[fill[y * n + x]] = f as u32;
                        fill[y * n + x] += 1;
                    }
                }
            }
        }
        grid
    }

    fn cell_of(&self, p: DVec2) -> (usize, usize) {
        let c = ((p - self.lo) / self.cell).floor();
        let clamp = |x: f64| (x.max(0.0) as usize).min(self.n - 1);
        (clamp(c.x), clamp(c.y))
    }

    /// The 3-D point `uv` maps to on `input` (module docs) seen from `p`, and whether some
    /// UV triangle holds `uv`.
    fn locate(&self, uv: DVec2, p: DVec3, input: &Mesh, uvs: &[DVec2]) -> Located {
        let point = |f: usize, w: [f64; 3]| -> DVec3 {
            (0..3)
                .map(|k| w[k] * input.positions[input.faces[f][k] as usize])
                .sum()
        };
        let (cx, cy) = self.cell_of(uv);
        let cell = cy * self.n + cx;
        let mut best: Option<(f64, DVec3, usize)> = None;
        for &f in &self.faces[self.start[cell]..self.start[cell + 1]] {
            let f = f as usize;
            if let Some(w) = inside(uv, uvs[3 * f], uvs[3 * f + 1], uvs[3 * f + 2]) {
                let q = point(f, w);
                let d = q.distance_squared(p);
                if best.is_none_or(|(bd, _, _)| d < bd) {
                    best = Some((d, q, f));
                }
            }
        }
        if let Some((_, point, face)) = best {
            return Located {
                point,
                face,
                inside: true,
            };
        }
        // Outside every UV triangle: the nearest one in UV space, ring of cells after ring
        // around `uv`'s cell, until no farther ring can hold a nearer one (a face in ring
        // `r` is at least `(r - 1)` cells away; ties: the smaller face).
        let mut near: Option<(f64, usize, [f64; 3])> = None;
        let step = self.cell.x.min(self.cell.y);
        for r in 0..self.n {
            for (x, y) in ring((cx, cy), r, self.n) {
                let cell = y * self.n + x;
                for &f in &self.faces[self.start[cell]..self.start[cell + 1]] {
                    let f = f as usize;
                    let t = [uvs[3 * f], uvs[3 * f + 1], uvs[3 * f + 2]];
                    let (d, w) = nearest_in_triangle(uv, t);
                    if near.is_none_or(|(bd, bf, _)| d < bd || (d == bd && f < bf)) {
                        near = Some((d, f, w));
                    }
                }
            }
            if near.is_some_and(|(d, _, _)| d.sqrt() <= r as f64 * step) {
                break;
            }
        }
        let (point, face) = near.map_or((p, 0), |(_, f, w)| (point(f, w), f));
        Located {
            point,
            face,
            inside: false,
        }
    }
}

/// The cells of an `n × n` grid at Chebyshev distance `r` from `(cx, cy)`.
fn ring((cx, cy): (usize, usize), r: usize, n: usize) -> impl Iterator<Item = (usize, usize)> {
    let (cx, cy, r, n) = (cx as i64, cy as i64, r as i64, n as i64);
    (cy - r..=cy + r)
        .flat_map(move |y| (cx - r..=cx + r).map(move |x| (x, y)))
        .filter(move |&(x, y)| (x - cx).abs().max((y - cy).abs()) == r)
        .filter(move |&(x, y)| (0..n).contains(&x) && (0..n).contains(&y))
        .map(|(x, y)| (x as usize, y as usize))
}

/// Barycentric weights of `p` in UV triangle `a b c` when it lies inside (edges
/// included), else `None`; `None` for a triangle of zero area.
fn inside(p: DVec2, a: DVec2, b: DVec2, c: DVec2) -> Option<[f64; 3]> {
    let area = uv_area(a, b, c);
    if area == 0.0 {
        return None;
    }
    let wa = uv_area(p, b, c) / area;
    let wb = uv_area(a, p, c) / area;
    let wc = 1.0 - wa - wb;
    const SLACK: f64 = -1e-6;
    (wa >= SLACK && wb >= SLACK && wc >= SLACK).then_some([wa, wb, wc])
}

/// Squared UV distance from `p` to triangle `t` and the weights of its nearest point.
fn nearest_in_triangle(p: DVec2, t: [DVec2; 3]) -> (f64, [f64; 3]) {
    if let Some(w) = inside(p, t[0], t[1], t[2]) {
        return (0.0, w);
    }
    let mut best = (f64::INFINITY, [1.0, 0.0, 0.0]);
    for k in 0..3 {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        let ab = b - a;
        let len2 = ab.length_squared();
        let s = if len2 > 0.0 {
            ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let d = (a + s * ab).distance_squared(p);
        if d < best.0 {
            let mut w = [0.0; 3];
            w[k] = 1.0 - s;
            w[(k + 1) % 3] = s;
            best = (d, w);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::{Attributes, Wedges};

    #[test]
    fn the_input_against_itself_scores_nothing() {
        let m = coarsen_shapes::uv_square();
        let t = texture(&m, &m, 2f64.sqrt()).unwrap();
        assert_eq!(t.uv_flipped, 0);
        assert_eq!(t.uv_degenerate, 0);
        assert_eq!(t.uv_outside, 0);
        assert!(t.distortion_max_pct < 1e-12, "{t:?}");
    }

    #[test]
    fn a_moved_vertex_and_a_mirrored_face_are_measured() {
        let input = coarsen_shapes::uv_square();
        let mut out = coarsen_shapes::uv_square();
        // Vertex 2 moves by 0.1 along x while its UV stays: 0.1 of distortion there.
        out.positions[2].x += 0.1;
        let t = texture(&input, &out, 1.0).unwrap();
        assert!((t.distortion_max_pct - 10.0).abs() < 1e-9, "{t:?}");
        assert_eq!(t.uv_flipped, 0);
        // Swapping two UVs of a face turns it over in UV space.
        let mut cols = Attributes::default();
        let mut uv = corner_uvs(&input).unwrap();
        uv.swap(1, 2);
        cols.insert(UV, AttrValues::Vec2(uv));
        out.wedges = Wedges::from_corners(&out.faces, cols);
        let t = texture(&input, &out, 1.0).unwrap();
        assert_eq!(t.uv_flipped, 1, "{t:?}");
    }

    #[test]
    fn a_uv_outside_every_triangle_lands_on_the_nearest_one() {
        // A 40 × 40 grid with UV = (x, y); one output corner's UV pushed to (1.3, 0.5),
        // right of the whole map: it lands on the right border at (1, 0.5).
        let mut input = coarsen_shapes::plane_grid(40, 40, 1.0).unwrap();
        let lo = input.positions.iter().fold(DVec3::MAX, |a, p| a.min(*p));
        let uv = input
            .faces
            .iter()
            .flatten()
            .map(|&v| (input.positions[v as usize] - lo).truncate());
        let mut cols = Attributes::default();
        cols.insert(UV, AttrValues::Vec2(uv.collect()));
        input.wedges = Wedges::from_corners(&input.faces, cols.clone());
        let grid = UvGrid::new(&corner_uvs(&input).unwrap(), input.n_faces());
        let at = grid.locate(
            DVec2::new(1.3, 0.5),
            DVec3::ZERO,
            &input,
            &corner_uvs(&input).unwrap(),
        );
        assert!(!at.inside);
        assert!(
            (at.point - (lo + DVec3::new(1.0, 0.5, 0.0))).length() < 1e-12,
            "{:?}",
            at.point
        );
    }

    #[test]
    fn meshes_without_uvs_have_no_texture_figures() {
        let m = coarsen_shapes::uv_square();
        let plain = Mesh::new(m.positions.clone(), m.faces.clone());
        assert!(texture(&m, &plain, 1.0).is_none());
        assert!(texture(&plain, &m, 1.0).is_none());
    }
}
