//! Faces the texture stage could only lay turned over (or flat) in UV space — a coarse
//! face over a stretch where the input's parametrisation bends faster than the face is
//! wide — mended by moving one of their corners along the input or flipping one of their
//! edges.
//!
//! A face is turned as `coarsen_metrics::UvJudge` judges it (against the input face under
//! its UV centroid), so that what is left is what the texture figures count. For each
//! turned face, in index order:
//!
//! * **Move**: a corner that no seam runs through (its faces on one side of the input,
//!   with one UV) and that is inside the surface, moved to the input point nearest a
//!   quarter, half or all of the way to its neighbours' centroid, or a twelfth, sixth or
//!   third of its mean edge length in one of eight directions of its tangent plane. It
//!   takes the UV there.
//! * **Flip**, when no move qualifies: an edge that is no seam of the output (its ends
//!   take the same UVs in both faces, on one side of the input) and whose other diagonal
//!   is no edge yet.
//!
//! A candidate qualifies when every face it changes then winds right, none turns by more
//! than 60° (a move: from its old normal; a flip: from the pair's mean normal), and their
//! smallest angle and smallest shape quality Q stay at least the smaller of their old value
//! and a floor (30°, Q 0.5). Of those that qualify, the one leaving the highest Q is taken.
//! Passes until one changes nothing (at most [`PASSES`]).

use crate::{Found, Sides, Walk, uv_at};
use coarsen_geom::{DVec2, DVec3};
use coarsen_mesh::{Index, Mesh};
use coarsen_metrics::{UvJudge, UvWinding};

/// The most passes over the faces.
pub const PASSES: usize = 4;

/// Smallest angle (degrees) a mend may leave when the faces it changes had none smaller.
const ANGLE_FLOOR_DEG: f64 = 30.0;

/// Smallest shape quality (Frey–Borouchaki Q) a mend may leave, likewise.
const Q_FLOOR: f64 = 0.5;

/// Two laid UVs closer than this are one (a vertex no seam runs through).
const SAME_UV: f64 = 1e-12;

/// Largest turn (degrees) of a face a mend changes (module docs).
const MAX_TURN_DEG: f64 = 60.0;

/// What mending did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Mended {
    /// Edges flipped.
    pub flips: usize,
    /// Vertices moved.
    pub moves: usize,
    /// Faces still turned over (or flat) in UV space (module docs).
    pub turned: usize,
}

/// The faces and what each corner was laid on, mended in place.
pub struct Laid<'a> {
    /// The run's input (its wedges hold the UVs).
    pub input: &'a Mesh,
    /// The input's UVs per wedge.
    pub uv: &'a [DVec2],
    /// The input's sides and each input face's side.
    pub sides: &'a Sides,
    /// Each input face's side (a label per connected set of faces without seams between).
    pub side_of: &'a [Index],
    /// Whether to mend, or only count.
    pub mend: bool,
    /// The judge of UV windings.
    pub judge: &'a UvJudge<'a>,
}

/// The unit normal of a 3-D triangle (zero when degenerate).
fn normal(t: [DVec3; 3]) -> DVec3 {
    (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero()
}

/// The smallest angle and quality of some triangles.
#[derive(Clone, Copy)]
struct Shape {
    angle: f64,
    q: f64,
}

impl Shape {
    const BEST: Shape = Shape {
        angle: 180.0,
        q: 1.0,
    };

    fn of(t: [DVec3; 3]) -> Shape {
        Shape {
            angle: min_angle_deg(t),
            q: coarsen_geom::triangle::quality(t[0], t[1], t[2]),
        }
    }

    fn min(self, o: Shape) -> Shape {
        Shape {
            angle: self.angle.min(o.angle),
            q: self.q.min(o.q),
        }
    }

    /// Whether `self` (after a mend) keeps to `old`'s shape or the floors.
    fn keeps(self, old: Shape) -> bool {
        self.angle >= old.angle.min(ANGLE_FLOOR_DEG) && self.q >= old.q.min(Q_FLOOR)
    }
}

/// The smallest angle of a 3-D triangle, degrees (0 when degenerate).
fn min_angle_deg(p: [DVec3; 3]) -> f64 {
    (0..3)
        .map(|k| {
            let (u, v) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
            let (lu, lv) = (u.length(), v.length());
            if lu == 0.0 || lv == 0.0 {
                return 0.0;
            }
            (u.dot(v) / (lu * lv)).clamp(-1.0, 1.0).acos().to_degrees()
        })
        .fold(180.0, f64::min)
}

impl Laid<'_> {
    /// The side of input face `f` (`None` for a face laid on none).
    fn side(&self, f: Index) -> Option<Index> {
        self.side_of.get(f as usize).copied()
    }

    /// The UVs at a face's corners (`None` where a corner found nothing).
    fn uvs(&self, found: &[Option<Found>; 3]) -> Option<[DVec2; 3]> {
        let [Some(a), Some(b), Some(c)] = found else {
            return None;
        };
        Some([a, b, c].map(|f| uv_at(self.input, self.uv, f)))
    }

    /// Whether a face at corners `p`, laid as `found`, is turned over or flat in UV space
    /// against the input under it (`coarsen_metrics::UvJudge`, as the texture figures).
    fn turned(&self, p: [DVec3; 3], found: &[Option<Found>; 3]) -> bool {
        self.uvs(found)
            .is_some_and(|t| self.judge.judge(t, p) != UvWinding::Right)
    }
}

/// Mends `faces` (laid as `found`, each on the side of input face `start`): module docs.
pub fn mend(
    laid: &Laid<'_>,
    positions: &mut [DVec3],
    faces: &mut [[Index; 3]],
    found: &mut [[Option<Found>; 3]],
    start: &mut [Index],
) -> Mended {
    let at = |positions: &[DVec3], face: [Index; 3]| face.map(|v| positions[v as usize]);
    let count = |positions: &[DVec3], faces: &[[Index; 3]], found: &[[Option<Found>; 3]]| {
        (0..faces.len())
            .filter(|&f| laid.turned(at(positions, faces[f]), &found[f]))
            .count()
    };
    let turned = count(positions, faces, found);
    if turned == 0 || !laid.mend {
        return Mended {
            turned,
            ..Mended::default()
        };
    }
    let mut around: Vec<Vec<Index>> = vec![Vec::new(); positions.len()];
    for (f, face) in faces.iter().enumerate() {
        for &v in face {
            around[v as usize].push(f as Index);
        }
    }
    let mut state = State {
        positions,
        faces,
        found,
        start,
        around,
    };
    let mut walk = Walk::new(laid.input.n_faces());
    let (mut flips, mut moves) = (0, 0);
    for _ in 0..PASSES {
        let before = flips + moves;
        for f in 0..state.faces.len() {
            if !laid.turned(at(state.positions, state.faces[f]), &state.found[f]) {
                continue;
            }
            if let Some(m) = state.best_move(laid, &mut walk, f) {
                state.positions[m.v as usize] = m.to;
                for &(h, slot) in &m.corners {
                    state.found[h][slot] = Some(m.found);
                }
                moves += 1;
            } else if let Some(flip) = state.best_flip(laid, f) {
                state.apply(flip);
                flips += 1;
            }
        }
        if flips + moves == before {
            break;
        }
    }
    let State {
        positions,
        faces,
        found,
        ..
    } = state;
    Mended {
        flips,
        moves,
        turned: count(positions, faces, found),
    }
}

/// An edge flip: faces `f = (a, b, c)` and `g = (b, a, d)` become `(c, a, d)` and
/// `(c, d, b)`, both on `f`'s side of the input.
#[derive(Clone, Copy)]
struct Flip {
    f: usize,
    g: usize,
    /// `f`'s corner slot of `a` (so `a = f[k]`, `b = f[k + 1]`, `c = f[k + 2]`).
    k: usize,
    /// `g`'s corner slot of `d`.
    j: usize,
    /// The new pair's shape.
    shape: Shape,
}

/// A vertex moved along the input: to `to`, laid on `found`, at its `corners`.
struct Move {
    v: Index,
    to: DVec3,
    found: Found,
    corners: Vec<(usize, usize)>,
}

/// The faces being mended, what each corner was laid on, and the faces around each vertex.
struct State<'m> {
    positions: &'m mut [DVec3],
    faces: &'m mut [[Index; 3]],
    found: &'m mut [[Option<Found>; 3]],
    /// Each face's input face, whose side it is laid on.
    start: &'m mut [Index],
    around: Vec<Vec<Index>>,
}

/// The state's arrays, read only.
type View<'a> = (
    &'a [DVec3],
    &'a [[Index; 3]],
    &'a [[Option<Found>; 3]],
    &'a [Index],
    &'a [Vec<Index>],
);

impl State<'_> {
    /// Its arrays, read only.
    fn view(&self) -> View<'_> {
        (
            self.positions,
            self.faces,
            self.found,
            self.start,
            &self.around,
        )
    }

    /// The best flip of an edge of turned face `f` (module docs), if any qualifies.
    fn best_flip(&self, laid: &Laid<'_>, f: usize) -> Option<Flip> {
        let (positions, faces, found, start, around) = self.view();
        let p = |v: Index| positions[v as usize];
        let mut best: Option<Flip> = None;
        for k in 0..3 {
            let [a, b, c] = [0, 1, 2].map(|i| faces[f][(k + i) % 3]);
            let Some(&g) = around[a as usize]
                .iter()
                .find(|&&g| g as usize != f && faces[g as usize].contains(&b))
            else {
                continue;
            };
            let g = g as usize;
            let Some(j) = (0..3).find(|&j| faces[g][j] != a && faces[g][j] != b) else {
                continue;
            };
            let d = faces[g][j];
            // One side of the input, the same UVs at the edge's ends in both faces.
            if laid.side(start[f]).is_none() || laid.side(start[f]) != laid.side(start[g]) {
                continue;
            }
            let slot = |face: usize, v: Index| (0..3).find(|&i| faces[face][i] == v);
            let (Some(ag), Some(bg)) = (slot(g, a), slot(g, b)) else {
                continue;
            };
            let (Some(ta), Some(tb), Some(ua), Some(ub)) = (
                found[f][k].map(|x| uv_at(laid.input, laid.uv, &x)),
                found[f][(k + 1) % 3].map(|x| uv_at(laid.input, laid.uv, &x)),
                found[g][ag].map(|x| uv_at(laid.input, laid.uv, &x)),
                found[g][bg].map(|x| uv_at(laid.input, laid.uv, &x)),
            ) else {
                continue;
            };
            if ta.distance(ua) > SAME_UV || tb.distance(ub) > SAME_UV {
                continue;
            }
            // A manifold flip: c–d is no edge yet.
            if c == d
                || around[c as usize]
                    .iter()
                    .any(|&h| faces[h as usize].contains(&d))
            {
                continue;
            }
            let new = [[c, a, d], [c, d, b]];
            let pts = new.map(|t| t.map(p));
            let mean =
                (normal([p(a), p(b), p(c)]) + normal([p(b), p(a), p(d)])).normalize_or_zero();
            let cos_turn = MAX_TURN_DEG.to_radians().cos();
            if pts.iter().any(|&t| normal(t).dot(mean) < cos_turn) {
                continue;
            }
            let old = Shape::of([p(a), p(b), p(c)]).min(Shape::of([p(b), p(a), p(d)]));
            let shape = Shape::of(pts[0]).min(Shape::of(pts[1]));
            if !shape.keeps(old) {
                continue;
            }
            // Both new faces wind as the input under them.
            let corner = |v: Index| -> Option<Found> {
                match v {
                    _ if v == d => found[g][j],
                    _ => found[f][(0..3).find(|&i| faces[f][i] == v)?],
                }
            };
            let ok = new
                .iter()
                .zip(&pts)
                .all(|(t, &q)| !laid.turned(q, &t.map(corner)));
            if ok && best.is_none_or(|b| shape.q > b.shape.q) {
                best = Some(Flip { f, g, k, j, shape });
            }
        }
        best
    }

    /// Flips the edge (module docs), keeping each corner's laid point and the incidence.
    fn apply(&mut self, flip: Flip) {
        let (faces, found, start, around) = (
            &mut *self.faces,
            &mut *self.found,
            &mut *self.start,
            &mut self.around,
        );
        let Flip { f, g, k, j, .. } = flip;
        let [a, b, c] = [0, 1, 2].map(|i| faces[f][(k + i) % 3]);
        let d = faces[g][j];
        let [fa, fb, fc] = [0, 1, 2].map(|i| found[f][(k + i) % 3]);
        let fd = found[g][j];
        faces[f] = [c, a, d];
        faces[g] = [c, d, b];
        found[f] = [fc, fa, fd];
        found[g] = [fc, fd, fb];
        start[g] = start[f];
        around[a as usize].retain(|&h| h as usize != g);
        around[b as usize].retain(|&h| h as usize != f);
        around[c as usize].push(g as Index);
        around[d as usize].push(f as Index);
    }

    /// The best move of a corner of turned face `f` toward the centroid of its neighbours,
    /// onto the input (module docs), if any qualifies.
    fn best_move(&self, laid: &Laid<'_>, walk: &mut Walk, f: usize) -> Option<Move> {
        let (positions, faces, found, start, around) = self.view();
        let mut best: Option<(f64, Move)> = None;
        for &v in &faces[f] {
            let ring = &around[v as usize];
            let corners: Vec<(usize, usize)> = ring
                .iter()
                .filter_map(|&h| {
                    let h = h as usize;
                    (0..3).find(|&i| faces[h][i] == v).map(|i| (h, i))
                })
                .collect();
            // One side, one UV: no seam through the vertex.
            let side = laid.side(start[f]);
            if corners
                .iter()
                .any(|&(h, _)| side.is_none() || laid.side(start[h]) != side)
            {
                continue;
            }
            let uvs: Option<Vec<DVec2>> = corners
                .iter()
                .map(|&(h, i)| found[h][i].map(|x| uv_at(laid.input, laid.uv, &x)))
                .collect();
            let Some(uvs) = uvs else {
                continue;
            };
            if uvs.iter().any(|t| t.distance(uvs[0]) > SAME_UV) {
                continue;
            }
            // Inside the surface: as many neighbours as faces around (a closed fan).
            let mut nbrs: Vec<Index> = corners
                .iter()
                .flat_map(|&(h, i)| [faces[h][(i + 1) % 3], faces[h][(i + 2) % 3]])
                .collect();
            nbrs.sort_unstable();
            nbrs.dedup();
            if nbrs.len() != corners.len() {
                continue;
            }
            let centroid =
                nbrs.iter().map(|&u| positions[u as usize]).sum::<DVec3>() / nbrs.len() as f64;
            let from = positions[v as usize];
            let tri = |h: usize, at: DVec3| -> [DVec3; 3] {
                faces[h].map(|u| if u == v { at } else { positions[u as usize] })
            };
            let old = corners
                .iter()
                .fold(Shape::BEST, |s, &(h, _)| s.min(Shape::of(tri(h, from))));
            let cos_turn = MAX_TURN_DEG.to_radians().cos();
            // Toward the neighbours' centroid, and steps of a sixth and a third of the mean
            // edge length in eight directions of the tangent plane.
            let n = corners
                .iter()
                .map(|&(h, _)| normal(tri(h, from)))
                .sum::<DVec3>()
                .normalize_or_zero();
            let edge = nbrs
                .iter()
                .map(|&u| positions[u as usize].distance(from))
                .sum::<f64>()
                / nbrs.len() as f64;
            let (e1, e2) = n.any_orthonormal_pair();
            let mut targets: Vec<DVec3> = [0.25, 0.5, 1.0]
                .map(|t| from + t * (centroid - from))
                .to_vec();
            for step in [edge / 12.0, edge / 6.0, edge / 3.0] {
                for k in 0..8 {
                    let a = k as f64 * std::f64::consts::FRAC_PI_4;
                    targets.push(from + step * (a.cos() * e1 + a.sin() * e2));
                }
            }
            for q in targets {
                let Some(mut on) = walk.nearest(laid.input, laid.sides, start[f], q) else {
                    continue;
                };
                let to: DVec3 = (0..3)
                    .map(|k| {
                        on.bary[k]
                            * laid.input.positions[laid.input.faces[on.face as usize][k] as usize]
                    })
                    .sum();
                on.d2 = 0.0;
                let mut shape = Shape::BEST;
                let mut ok = true;
                for &(h, i) in &corners {
                    let (before, after) = (tri(h, from), tri(h, to));
                    let mut laid_h = found[h];
                    laid_h[i] = Some(on);
                    if normal(after).dot(normal(before)) < cos_turn || laid.turned(after, &laid_h) {
                        ok = false;
                        break;
                    }
                    shape = shape.min(Shape::of(after));
                }
                if ok && shape.keeps(old) && best.as_ref().is_none_or(|(b, _)| shape.q > *b) {
                    best = Some((
                        shape.q,
                        Move {
                            v,
                            to,
                            found: on,
                            corners: corners.clone(),
                        },
                    ));
                }
            }
        }
        best.map(|(_, m)| m)
    }
}
