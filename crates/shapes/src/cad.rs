//! CAD-like parts made in code, tessellated the way a CAD program's STL export is.
//!
//! Each part is a 2.5-D solid: closed outlines in the xy plane (straight lines and circular
//! arcs, every arc tangent to the lines it meets), each sampled once, stacked at heights.
//! A horizontal face is the region between its outlines at one height, triangulated by a
//! constrained Delaunay triangulation of their samples (spade's) with no vertex inside,
//! so flat faces are long thin triangles; a wall joins an outline's samples at two heights
//! by quads split in two, so cylinder walls are tall thin strips. Every face that touches
//! an outline at a height uses the same vertices there: no duplicates, no T-junctions, and
//! every vertex lies on a sharp edge of the part (on its circle or line, up to the
//! rounding of `cos`/`sin`; quarter-turn points are exact).
//!
//! Circles have `segments` segments per full turn (a multiple of 4, from 16 to 65536;
//! [`SEGMENTS`] = 512 by default, 0.7° each), arcs their share of it. Every part is a
//! closed, outward-oriented, edge-manifold triangle mesh of one component (its sizes read
//! as millimetres); the output depends only on `segments`. With `n = segments`:
//!
//! | part | genus | vertices | at 512 | sharp curves: closed + open | corners |
//! | --- | --- | --- | --- | --- | --- |
//! | [`plate`] | 3 | 7n + 12 | 3,596 | 6 + 6 | 4 |
//! | [`block`] | 1 | 6n + 16 | 3,088 | 6 + 12 | 8 |
//! | [`shaft`] | 0 | 9n | 4,608 | 9 + 0 | 0 |
//!
//! Faces: `2·V − 4 + 4·genus` (a closed triangle mesh). The feature counts are those of
//! `coarsen-features` at its default angles (sharp above 40°, corner above a 45° turn).
//!
//! ```
//! let plate = coarsen_shapes::cad::plate(coarsen_shapes::cad::SEGMENTS).unwrap();
//! assert_eq!((plate.n_vertices(), plate.n_faces()), (3596, 7200));
//! assert!(plate.signed_volume() > 0.0);
//! ```

use crate::{ShapeError, push_quad};
use coarsen_mesh::{DVec2, DVec3, Index, Mesh};
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};
use std::collections::VecDeque;
use std::f64::consts::FRAC_PI_2;

/// The default circle resolution: segments per full turn (0.7° each).
pub const SEGMENTS: u32 = 512;

/// The parts at [`SEGMENTS`], by name (`plate`, `block`, `shaft`), for tests and benches.
pub fn parts() -> Result<Vec<(&'static str, Mesh)>, ShapeError> {
    Ok(vec![
        ("plate", plate(SEGMENTS)?),
        ("block", block(SEGMENTS)?),
        ("shaft", shaft(SEGMENTS)?),
    ])
}

/// A plate 100 × 60 × 10 (x ∈ [0, 100], y ∈ [0, 60], z ∈ [0, 10]) with two round through
/// holes (r 6 at (20, 18) and (20, 42)), a through slot with round ends (r 6, centres
/// (50, 30) and (75, 30)) and its two vertical edges at x = 100 rounded (r 10); genus 3.
///
/// Features: the four ends of the two sharp vertical edges at x = 0 are the corners; the
/// top and bottom outlines are each two curves between them, the vertical edges two more;
/// the rims of the holes and of the slot (whose arcs meet its sides tangentially) are six
/// closed curves.
pub fn plate(segments: u32) -> Result<Mesh, ShapeError> {
    let s = per_quarter(segments)?;
    let outlines = plate_outlines();
    let mut b = Builder::new("plate");
    let bottom: Vec<Ring> = outlines
        .iter()
        .map(|(o, _)| b.ring(&sample(o, s), 0.0))
        .collect();
    let top: Vec<Ring> = outlines
        .iter()
        .map(|(o, _)| b.ring(&sample(o, s), 10.0))
        .collect();
    for ((lower, upper), (_, solid)) in bottom.iter().zip(&top).zip(&outlines) {
        b.wall(lower, upper, *solid);
    }
    b.planar(&bottom.iter().collect::<Vec<_>>(), Facing::Down)?;
    b.planar(&top.iter().collect::<Vec<_>>(), Facing::Up)?;
    Ok(b.finish())
}

/// A block 80 × 80 × 30 (x, y ∈ [0, 80], z ∈ [0, 30]) with a blind rounded-rectangle
/// pocket in its top (x ∈ [8, 38], y ∈ [15, 65], corner r 6, 10 deep: floor at z = 20) and
/// a round boss on it (r 12 at (58, 40), 15 high: top at z = 45) with a through hole down
/// its axis (r 5, from z = 0 to 45); genus 1.
///
/// Features: the block's twelve edges between its eight corners; the pocket's rim and
/// floor outline (tangent arcs, no corner), the boss's foot and top rim and the hole's two
/// rims are six closed curves.
pub fn block(segments: u32) -> Result<Mesh, ShapeError> {
    let s = per_quarter(segments)?;
    let [square, pocket, boss, hole] = block_outlines().map(|o| sample(&o, s));
    let mut b = Builder::new("block");
    let base = [b.ring(&square, 0.0), b.ring(&hole, 0.0)];
    let top = [
        b.ring(&square, 30.0),
        b.ring(&pocket, 30.0),
        b.ring(&boss, 30.0),
    ];
    let floor = b.ring(&pocket, 20.0);
    let boss_top = [b.ring(&boss, 45.0), b.ring(&hole, 45.0)];
    b.wall(&base[0], &top[0], Solid::Inside);
    b.wall(&floor, &top[1], Solid::Outside);
    b.wall(&top[2], &boss_top[0], Solid::Inside);
    b.wall(&base[1], &boss_top[1], Solid::Outside);
    b.planar(&[&base[0], &base[1]], Facing::Down)?;
    b.planar(&[&top[0], &top[1], &top[2]], Facing::Up)?;
    b.planar(&[&floor], Facing::Up)?;
    b.planar(&[&boss_top[0], &boss_top[1]], Facing::Up)?;
    Ok(b.finish())
}

/// A stepped shaft along the z axis, from z = 0 to 100: cylinders of radius 10
/// (z ∈ [0, 20]), 15 (z ∈ [20, 50], its top edge chamfered 2 × 45°: a cone from r 15 at
/// z = 48 to r 13 at z = 50), 12 (z ∈ [50, 80]) and 8 (z ∈ [80, 100]), flat annular steps
/// between them and flat end caps (triangulated without a centre vertex); genus 0.
///
/// Features: its nine circles (the caps' rims, both rims of each step, both ends of the
/// chamfer) are nine closed curves; no corner.
pub fn shaft(segments: u32) -> Result<Mesh, ShapeError> {
    let s = per_quarter(segments)?;
    let circle = |r: f64| sample(&[arc(DVec2::ZERO, r, 0, 4)], s);
    let mut b = Builder::new("shaft");
    let first = [b.ring(&circle(10.0), 0.0), b.ring(&circle(10.0), 20.0)];
    let second = [b.ring(&circle(15.0), 20.0), b.ring(&circle(15.0), 48.0)];
    let chamfer = b.ring(&circle(13.0), 50.0);
    let third = [b.ring(&circle(12.0), 50.0), b.ring(&circle(12.0), 80.0)];
    let fourth = [b.ring(&circle(8.0), 80.0), b.ring(&circle(8.0), 100.0)];
    for [lower, upper] in [&first, &second, &third, &fourth] {
        b.wall(lower, upper, Solid::Inside);
    }
    b.wall(&second[1], &chamfer, Solid::Inside);
    b.planar(&[&first[0]], Facing::Down)?;
    b.planar(&[&second[0], &first[1]], Facing::Down)?;
    b.planar(&[&chamfer, &third[0]], Facing::Up)?;
    b.planar(&[&third[1], &fourth[0]], Facing::Up)?;
    b.planar(&[&fourth[1]], Facing::Up)?;
    Ok(b.finish())
}

/// The plate's outlines (counter-clockwise) and on which side of each the solid is.
fn plate_outlines() -> [(Vec<Piece>, Solid); 4] {
    [
        (
            rounded_rect(
                DVec2::ZERO,
                DVec2::new(100.0, 60.0),
                10.0,
                [false, true, true, false],
            ),
            Solid::Inside,
        ),
        (vec![arc(DVec2::new(20.0, 18.0), 6.0, 0, 4)], Solid::Outside),
        (vec![arc(DVec2::new(20.0, 42.0), 6.0, 0, 4)], Solid::Outside),
        (
            stadium(DVec2::new(50.0, 30.0), DVec2::new(75.0, 30.0), 6.0),
            Solid::Outside,
        ),
    ]
}

/// The block's outlines, counter-clockwise: its square, the pocket, the boss and the hole.
fn block_outlines() -> [Vec<Piece>; 4] {
    [
        rounded_rect(DVec2::ZERO, DVec2::splat(80.0), 0.0, [false; 4]),
        rounded_rect(
            DVec2::new(8.0, 15.0),
            DVec2::new(38.0, 65.0),
            6.0,
            [true; 4],
        ),
        vec![arc(DVec2::new(58.0, 40.0), 12.0, 0, 4)],
        vec![arc(DVec2::new(58.0, 40.0), 5.0, 0, 4)],
    ]
}

/// `segments / 4`, when `segments` is a valid circle resolution.
fn per_quarter(segments: u32) -> Result<u32, ShapeError> {
    if (16..=1 << 16).contains(&segments) && segments.is_multiple_of(4) {
        Ok(segments / 4)
    } else {
        Err(ShapeError::InvalidParameter {
            name: "segments",
            value: segments.to_string(),
            expected: "a multiple of 4 from 16 to 65536",
        })
    }
}

/// One piece of a counter-clockwise outline; a straight line runs from each piece's last
/// point to the next one's first (none where they coincide).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Piece {
    /// A sharp corner.
    Corner(DVec2),
    /// A counter-clockwise arc around `centre` from quarter-turn angle `start` (0 along +x,
    /// 1 along +y, …) through `quarters` quarter turns, both ends included.
    Arc {
        centre: DVec2,
        radius: f64,
        start: u32,
        quarters: u32,
    },
}

fn arc(centre: DVec2, radius: f64, start: u32, quarters: u32) -> Piece {
    Piece::Arc {
        centre,
        radius,
        start,
        quarters,
    }
}

/// The rectangle `min`–`max`, its corners (counter-clockwise from `min`) rounded with
/// `radius` where `rounded` says so.
fn rounded_rect(min: DVec2, max: DVec2, radius: f64, rounded: [bool; 4]) -> Vec<Piece> {
    let corners = [min, DVec2::new(max.x, min.y), max, DVec2::new(min.x, max.y)];
    // From each corner towards the centre of its rounding.
    let inward = [
        DVec2::new(1.0, 1.0),
        DVec2::new(-1.0, 1.0),
        DVec2::new(-1.0, -1.0),
        DVec2::new(1.0, -1.0),
    ];
    (0..4)
        .map(|i| {
            if rounded[i] {
                // Corner i's arc starts pointing along −x at corner 0, −y at corner 1, …
                arc(
                    corners[i] + radius * inward[i],
                    radius,
                    (i as u32 + 2) % 4,
                    1,
                )
            } else {
                Piece::Corner(corners[i])
            }
        })
        .collect()
}

/// The stadium around the segment `a`–`b` (along +x) at distance `radius`.
fn stadium(a: DVec2, b: DVec2, radius: f64) -> Vec<Piece> {
    vec![arc(b, radius, 3, 2), arc(a, radius, 1, 2)]
}

/// The unit vector at `k / (4·per_quarter)` of a turn, exact at quarter turns and
/// symmetric under them.
fn unit(k: u32, per_quarter: u32) -> DVec2 {
    let rest = k % per_quarter;
    let (c, s) = if rest == 0 {
        (1.0, 0.0)
    } else {
        let a = FRAC_PI_2 * f64::from(rest) / f64::from(per_quarter);
        (a.cos(), a.sin())
    };
    match (k / per_quarter) % 4 {
        0 => DVec2::new(c, s),
        1 => DVec2::new(-s, c),
        2 => DVec2::new(-c, -s),
        _ => DVec2::new(s, -c),
    }
}

/// The points of an outline, in order, each once: corners, and arcs at `per_quarter`
/// segments a quarter turn.
fn sample(pieces: &[Piece], per_quarter: u32) -> Vec<DVec2> {
    let mut points = Vec::new();
    for piece in pieces {
        match *piece {
            Piece::Corner(p) => points.push(p),
            Piece::Arc {
                centre,
                radius,
                start,
                quarters,
            } => points.extend(
                (0..=quarters * per_quarter)
                    .map(|k| centre + radius * unit(start * per_quarter + k, per_quarter)),
            ),
        }
    }
    points.dedup();
    if points.len() > 1 && points.first() == points.last() {
        points.pop();
    }
    points
}

/// Where the solid is, seen from an outline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Solid {
    /// Inside (an outer boundary, a boss): the wall faces out of the outline.
    Inside,
    /// Outside (a hole, a pocket): the wall faces into the outline.
    Outside,
}

/// Which way a horizontal face points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Facing {
    Up,
    Down,
}

/// An outline's vertices at one height: `first..first + points.len()`, in outline order.
struct Ring {
    first: Index,
    points: Vec<DVec2>,
}

impl Ring {
    /// The vertex of sample `i` (taken around the outline).
    fn id(&self, i: usize) -> Index {
        self.first + (i % self.points.len()) as Index
    }
}

/// A part under construction: its vertices and faces.
struct Builder {
    what: &'static str,
    positions: Vec<DVec3>,
    faces: Vec<[Index; 3]>,
}

type Cdt = ConstrainedDelaunayTriangulation<Point2<f64>>;

impl Builder {
    fn new(what: &'static str) -> Builder {
        Builder {
            what,
            positions: Vec::new(),
            faces: Vec::new(),
        }
    }

    fn bug(&self, reason: String) -> ShapeError {
        ShapeError::Internal {
            what: self.what,
            reason,
        }
    }

    /// New vertices for the samples `points` at height `z`.
    fn ring(&mut self, points: &[DVec2], z: f64) -> Ring {
        let first = self.positions.len() as Index;
        self.positions
            .extend(points.iter().map(|p| DVec3::new(p.x, p.y, z)));
        Ring {
            first,
            points: points.to_vec(),
        }
    }

    /// The wall between the same outline's rings `lower` and `upper` (same sample count;
    /// the samples of `upper` may be scaled about an axis, for a cone), one quad per
    /// sample, facing away from the solid.
    fn wall(&mut self, lower: &Ring, upper: &Ring, solid: Solid) {
        for i in 0..lower.points.len() {
            let (a0, b0) = (lower.id(i), lower.id(i + 1));
            let (a1, b1) = (upper.id(i), upper.id(i + 1));
            // A counter-clockwise outline has the inside on its left; [a0, b0, b1, a1]
            // faces right, out of it.
            let quad = match solid {
                Solid::Inside => [a0, b0, b1, a1],
                Solid::Outside => [a0, a1, b1, b0],
            };
            push_quad(&mut self.faces, quad);
        }
    }

    /// The horizontal face bounded by `rings` (all at one height): the points inside an
    /// odd number of them, triangulated by a constrained Delaunay triangulation of their
    /// samples alone.
    fn planar(&mut self, rings: &[&Ring], facing: Facing) -> Result<(), ShapeError> {
        let mut points = Vec::new();
        let mut ids = Vec::new();
        let mut edges = Vec::new();
        for ring in rings {
            let (base, n) = (points.len(), ring.points.len());
            for (i, p) in ring.points.iter().enumerate() {
                points.push(Point2::new(p.x, p.y));
                ids.push(ring.id(i));
                edges.push([base + i, base + (i + 1) % n]);
            }
        }
        let mut conflicts = 0usize;
        let cdt = Cdt::try_bulk_load_cdt(points, edges, |_| conflicts += 1)
            .map_err(|e| self.bug(format!("a triangulation refused a point: {e}")))?;
        if cdt.num_vertices() != ids.len() {
            return Err(self.bug("two outline samples coincide".into()));
        }
        if conflicts > 0 {
            return Err(self.bug(format!("{conflicts} outline edges cross")));
        }
        let depth = nesting(&cdt);
        for face in cdt.inner_faces() {
            if depth[face.fix().index()] % 2 == 1 {
                // Spade's faces are counter-clockwise seen from +z.
                let [a, b, c] = face.vertices().map(|v| ids[v.fix().index()]);
                self.faces.push(match facing {
                    Facing::Up => [a, b, c],
                    Facing::Down => [a, c, b],
                });
            }
        }
        Ok(())
    }

    fn finish(self) -> Mesh {
        Mesh::new(self.positions, self.faces)
    }
}

/// Per face of `cdt` (by index): how many constraint edges separate it from the outside,
/// the fewest over all paths (a 0-1 breadth-first search from the convex hull).
fn nesting(cdt: &Cdt) -> Vec<u32> {
    let mut depth = vec![u32::MAX; cdt.num_all_faces()];
    let mut queue = VecDeque::new();
    let crossing = |e: spade::handles::DirectedEdgeHandle<'_, _, _, _, _>| {
        u32::from(cdt.is_constraint_edge(e.as_undirected().fix()))
    };
    for e in cdt.convex_hull() {
        let inner = e.face().as_inner().or_else(|| e.rev().face().as_inner());
        if let Some(f) = inner {
            let d = crossing(e);
            let slot = &mut depth[f.fix().index()];
            if d < *slot {
                *slot = d;
                queue.push_back((f, d));
            }
        }
    }
    while let Some((f, d)) = queue.pop_front() {
        if d > depth[f.fix().index()] {
            continue;
        }
        for e in f.adjacent_edges() {
            let Some(g) = e.rev().face().as_inner() else {
                continue;
            };
            let step = crossing(e);
            let slot = &mut depth[g.fix().index()];
            if d + step < *slot {
                *slot = d + step;
                if step == 0 {
                    queue.push_front((g, d));
                } else {
                    queue.push_back((g, d + 1));
                }
            }
        }
    }
    depth
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::{SanityOptions, Topology, sanity_check, sanity_check_with};
    use std::f64::consts::PI;

    /// The area of a closed polygon (positive counter-clockwise).
    fn polygon_area(points: &[DVec2]) -> f64 {
        let n = points.len();
        (0..n)
            .map(|i| points[i].perp_dot(points[(i + 1) % n]))
            .sum::<f64>()
            / 2.0
    }

    fn area_of(pieces: &[Piece], s: u32) -> f64 {
        polygon_area(&sample(pieces, s))
    }

    /// The closed, outward, manifold, one-piece checks of every part, and its counts.
    fn assert_part(m: &Mesh, genus: i64, vertices: usize) {
        let s = Topology::build(m).summary(m);
        assert!(s.manifold && s.consistently_oriented, "{s:?}");
        assert_eq!(s.n_boundary_edges, 0, "closed");
        assert_eq!(s.n_components, 1);
        assert_eq!(s.n_isolated_vertices, 0);
        assert_eq!(s.n_degenerate_faces, 0);
        assert_eq!(s.euler, 2 - 2 * genus);
        assert_eq!(s.genus, vec![Some(genus)]);
        assert_eq!(m.n_vertices(), vertices);
        assert_eq!(m.n_faces() as i64, 2 * vertices as i64 - 4 + 4 * genus);
        assert!((0..m.n_faces()).all(|f| m.face_area(f) > 0.0));
        assert!(m.signed_volume() > 0.0, "outward");
        sanity_check(m).unwrap();
        sanity_check_with(m, &SanityOptions::strict()).unwrap();
    }

    /// `actual` within `rel` of `expected`, relatively.
    fn close(actual: f64, expected: f64, rel: f64) -> bool {
        (actual - expected).abs() <= rel * expected.abs()
    }

    /// Every vertex lies on one of `outlines` (on an arc's circle, or at a corner) at one
    /// of `heights`, up to rounding.
    fn assert_on_outlines(m: &Mesh, outlines: &[Vec<Piece>], heights: &[f64]) {
        for (v, p) in m.positions.iter().enumerate() {
            assert!(heights.contains(&p.z), "vertex {v} at {p}");
            let xy = p.truncate();
            let on = outlines.iter().flatten().any(|piece| match *piece {
                Piece::Corner(c) => c == xy,
                Piece::Arc { centre, radius, .. } => {
                    ((xy - centre).length() - radius).abs() < 1e-12 * radius
                }
            });
            assert!(on, "vertex {v} at {p} is on no outline");
        }
    }

    #[test]
    fn the_plate_is_a_closed_genus_three_solid_of_its_volume() {
        let m = plate(SEGMENTS).unwrap();
        assert_part(&m, 3, 3596);
        let s = SEGMENTS / 4;
        let [outer, hole_a, hole_b, slot] = plate_outlines().map(|(o, _)| area_of(&o, s));
        let exact = 10.0 * (outer - hole_a - hole_b - slot);
        assert!(
            close(m.signed_volume(), exact, 1e-12),
            "{}",
            m.signed_volume()
        );
        let rounding = 2.0 * (1.0 - PI / 4.0) * 100.0;
        let analytic = 10.0 * (6000.0 - rounding - 2.0 * PI * 36.0 - (25.0 * 12.0 + PI * 36.0));
        assert!(close(exact, analytic, 1e-4), "{exact} vs {analytic}");
        let outlines: Vec<Vec<Piece>> = plate_outlines().into_iter().map(|(o, _)| o).collect();
        assert_on_outlines(&m, &outlines, &[0.0, 10.0]);
    }

    #[test]
    fn the_block_is_a_closed_genus_one_solid_of_its_volume() {
        let m = block(SEGMENTS).unwrap();
        assert_part(&m, 1, 3088);
        let [square, pocket, boss, hole] = block_outlines().map(|o| area_of(&o, SEGMENTS / 4));
        let exact = 30.0 * square - 10.0 * pocket + 15.0 * boss - 45.0 * hole;
        assert!(
            close(m.signed_volume(), exact, 1e-12),
            "{}",
            m.signed_volume()
        );
        let pocket_area = 30.0 * 50.0 - (4.0 - PI) * 36.0;
        let analytic = 30.0 * 6400.0 - 10.0 * pocket_area + 15.0 * PI * 144.0 - 45.0 * PI * 25.0;
        assert!(close(exact, analytic, 1e-4), "{exact} vs {analytic}");
        assert_on_outlines(&m, &block_outlines(), &[0.0, 20.0, 30.0, 45.0]);
    }

    #[test]
    fn the_shaft_is_a_closed_solid_of_revolution_of_its_volume() {
        let m = shaft(SEGMENTS).unwrap();
        assert_part(&m, 0, 4608);
        // The regular n-gon of unit circumradius; the chamfer a frustum of a pyramid.
        let n = f64::from(SEGMENTS);
        let unit_area = n / 2.0 * (2.0 * PI / n).sin();
        let sum = |area: f64| {
            area * (100.0 * 20.0 + 225.0 * 28.0 + 144.0 * 30.0 + 64.0 * 20.0)
                + area * 2.0 / 3.0 * (225.0 + 169.0 + 15.0 * 13.0)
        };
        let exact = sum(unit_area);
        assert!(
            close(m.signed_volume(), exact, 1e-12),
            "{}",
            m.signed_volume()
        );
        assert!(close(exact, sum(PI), 1e-4), "{exact} vs {}", sum(PI));
        let circles: Vec<Vec<Piece>> = [10.0, 15.0, 13.0, 12.0, 8.0]
            .map(|r| vec![arc(DVec2::ZERO, r, 0, 4)])
            .into();
        assert_on_outlines(&m, &circles, &[0.0, 20.0, 48.0, 50.0, 80.0, 100.0]);
    }

    #[test]
    fn parts_are_deterministic_and_named() {
        let a = parts().unwrap();
        let b = parts().unwrap();
        let names: Vec<&str> = a.iter().map(|(n, _)| *n).collect();
        assert_eq!(names, ["plate", "block", "shaft"]);
        assert_eq!(a, b);
    }

    #[test]
    fn other_resolutions_keep_the_counts_and_topology() {
        for n in [16, 36, 1024] {
            let k = n as usize;
            assert_part(&plate(n).unwrap(), 3, 7 * k + 12);
            assert_part(&block(n).unwrap(), 1, 6 * k + 16);
            assert_part(&shaft(n).unwrap(), 0, 9 * k);
        }
    }

    #[test]
    fn every_face_is_horizontal_or_a_wall_strip() {
        // Every face is horizontal or a wall strip between two heights: no face has its
        // three vertices at three heights, and every vertex is on a sharp edge (see
        // `assert_on_outlines`), so no face is cut in its interior.
        for (name, m) in parts().unwrap() {
            for f in &m.faces {
                let mut z = f.map(|v| m.positions[v as usize].z);
                z.sort_by(f64::total_cmp);
                assert!(z[0] == z[1] || z[1] == z[2], "{name}: face {f:?}");
            }
        }
    }

    #[test]
    fn outlines_join_their_pieces_tangentially() {
        // Each arc of the plate's and the block's outlines ends where the next piece's
        // line starts, along it: the samples next to a join turn by half a segment.
        let s = SEGMENTS / 4;
        let outlines = plate_outlines()
            .into_iter()
            .map(|(o, _)| o)
            .chain(block_outlines());
        for pieces in outlines {
            let p = sample(&pieces, s);
            let n = p.len();
            let mut turns: Vec<f64> = (0..n)
                .map(|i| {
                    let (a, b, c) = (p[(i + n - 1) % n], p[i], p[(i + 1) % n]);
                    (b - a).angle_to(c - b).abs()
                })
                .collect();
            turns.sort_by(f64::total_cmp);
            let corners = pieces
                .iter()
                .filter(|q| matches!(q, Piece::Corner(_)))
                .count();
            // The largest turns are the corners' right angles; every other is at most
            // one segment.
            let segment = 2.0 * PI / f64::from(SEGMENTS);
            assert!(turns[..n - corners].iter().all(|&t| t <= segment * 1.0001));
            assert!(
                turns[n - corners..]
                    .iter()
                    .all(|&t| close(t, PI / 2.0, 1e-12))
            );
        }
    }

    #[test]
    fn bad_resolutions_are_refused() {
        for n in [0, 12, 18, 1 << 17] {
            for r in [plate(n), block(n), shaft(n)] {
                assert!(matches!(
                    r,
                    Err(ShapeError::InvalidParameter {
                        name: "segments",
                        ..
                    })
                ));
            }
        }
    }
}
