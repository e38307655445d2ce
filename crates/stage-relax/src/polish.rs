//! Polishing the worst faces after the sweeps: the vertices of the faces of lowest quality
//! move where the smallest quality of their faces rises.
//!
//! The sweeps rank moves by the smallest angle (capped at `floor_deg`) and then by the
//! summed quality of a vertex's faces, so one obtuse face among good ones can stay: the
//! sum gains more elsewhere. Here the vertices of the worst faces (the lowest
//! [`WORST_SHARE`] of them, at least [`WORST_MIN`]) are offered the sweep's moves and moves
//! towards the apex that would make their worst face equilateral; a move is kept when it
//! raises the smallest quality of the vertex's faces, lowers their summed quality by no
//! more than that ([`TRADE`]), leaves no face with a smaller smallest angle than it had
//! (capped at the floor) and passes the sweeps' guards (no face turned beyond
//! `max_turn_deg`, none facing away from the input, the fidelity bound).

use super::*;

/// Share of the faces polished in a round (their vertices are offered moves).
const WORST_SHARE: f64 = 0.002;
/// Fewest faces polished in a round.
const WORST_MIN: usize = 8;
/// A move may lower the summed quality of the vertex's faces by at most this many times
/// what it adds to their smallest quality.
const TRADE: f64 = 1.0;

/// Smallest quality and summed quality of the faces `fan` with vertex `v` at `p`, and each
/// face's smallest angle in `angles`; `None` when a face normal turns beyond `cos_turn`
/// from `normals`.
fn fan_worst(
    faces: &[[u32; 3]],
    fan: &[u32],
    v: u32,
    p: DVec3,
    pos: impl Fn(u32) -> DVec3,
    (normals, cos_turn): (&[DVec3], f64),
    angles: &mut Vec<f64>,
) -> Option<(f64, f64)> {
    angles.clear();
    let (mut quality, mut sum) = (f64::INFINITY, 0.0);
    for (i, &f) in fan.iter().enumerate() {
        let [a, b, c] = faces[f as usize].map(|w| if w == v { p } else { pos(w) });
        if triangle::normal(a, b, c).dot(normals[i]) < cos_turn {
            return None;
        }
        angles.push(triangle::min_angle(a, b, c));
        let q = triangle::quality(a, b, c);
        quality = quality.min(q);
        sum += q;
    }
    Some((quality, sum))
}

/// The quality of face `f` of `faces`, corners at `pos`.
fn quality_of(faces: &[[u32; 3]], pos: impl Fn(u32) -> DVec3, f: u32) -> f64 {
    let [a, b, c] = faces[f as usize].map(pos);
    triangle::quality(a, b, c)
}

/// Where the apex that would make face `g` equilateral lies, on the side of its corner `v`
/// (at `p`).
fn apex(faces: &[[u32; 3]], g: u32, v: u32, p: DVec3, pos: impl Fn(u32) -> DVec3) -> DVec3 {
    let [a, b, c] = faces[g as usize];
    let (u, w) = match v {
        _ if v == a => (b, c),
        _ if v == b => (c, a),
        _ => (a, b),
    };
    let (u, w) = (pos(u), pos(w));
    let mid = 0.5 * (u + w);
    let side = triangle::normal(p, u, w).cross(w - u).normalize_or_zero();
    let side = if side.dot(p - mid) < 0.0 { -side } else { side };
    mid + side * (0.75f64.sqrt() * u.distance(w))
}

/// `sweep.params.polish` rounds of polishing `mesh`, whose faces and adjacency `sweep`
/// reads; returns the moves kept.
pub(crate) fn polish(positions: &mut [DVec3], sweep: &Sweep<'_>) -> usize {
    let faces = sweep.faces;
    let n_faces = faces.len();
    if n_faces == 0 {
        return 0;
    }
    let worst = ((n_faces as f64 * WORST_SHARE) as usize).clamp(WORST_MIN.min(n_faces), n_faces);
    let floor = sweep.params.floor_deg.to_radians();
    let capped = |x: f64| if floor > 0.0 { x.min(floor) } else { x };
    let (mut normals, mut cands, mut tris) = (Vec::new(), Vec::new(), Vec::new());
    let (mut angles, mut after_angles) = (Vec::new(), Vec::new());
    let mut moves = 0;
    for _ in 0..sweep.params.polish {
        let by_quality = |x: &(f64, u32), y: &(f64, u32)| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1));
        let mut ranked: Vec<(f64, u32)> = (0..n_faces as u32)
            .map(|f| (quality_of(faces, |w| positions[w as usize], f), f))
            .collect();
        if worst < n_faces {
            ranked.select_nth_unstable_by(worst, by_quality);
            ranked.truncate(worst);
        }
        ranked.sort_unstable_by(by_quality);
        let mut moved_round = 0;
        for &(_, f) in &ranked {
            for v in faces[f as usize] {
                let fan = sweep.topo.vertex_faces(v);
                if fan.is_empty() || sweep.topo.n_vertex_fans(v) != 1 {
                    continue;
                }
                let pos = |w: u32| positions[w as usize];
                let p = pos(v);
                // The sweep's moves, and moves towards the apex that makes the vertex's
                // worst face equilateral.
                let Some(place) = sweep.moves(v, pos, &mut normals, &mut cands) else {
                    continue;
                };
                let Some(before) = fan_worst(faces, fan, v, p, pos, (&normals, -1.0), &mut angles)
                else {
                    continue;
                };
                let bad = fan
                    .iter()
                    .map(|&g| (quality_of(faces, pos, g), g))
                    .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
                if let Some((_, g)) = bad {
                    let top = apex(faces, g, v, p, pos);
                    cands.extend([1.0, 0.5, 0.25].map(|t| sweep.place(&place, p + t * (top - p))));
                }
                // The candidates that raise the smallest quality, trade no more summed
                // quality for it and cost no face angle below the floor, best first; the
                // input tests in that order.
                let mut kept: Vec<(f64, DVec3)> = cands
                    .iter()
                    .filter(|q| q.is_finite() && **q != p)
                    .filter_map(|&q| {
                        let turn = (&normals[..], sweep.cos_turn);
                        let after = fan_worst(faces, fan, v, q, pos, turn, &mut after_angles)?;
                        let gain = after.0 - before.0;
                        let kept_angles = after_angles
                            .iter()
                            .zip(&angles)
                            .all(|(&x, &y)| capped(x) >= capped(y));
                        (gain > 0.0 && after.1 - before.1 >= -TRADE * gain && kept_angles)
                            .then_some((after.0, q))
                    })
                    .collect();
                kept.sort_by(|x, y| y.0.total_cmp(&x.0));
                let chosen = kept
                    .iter()
                    .map(|&(_, q)| q)
                    .find(|&q| sweep.admits(v, q, pos, &mut tris));
                if let Some(q) = chosen {
                    positions[v as usize] = q;
                    moved_round += 1;
                }
            }
        }
        moves += moved_round;
        if moved_round == 0 {
            break;
        }
    }
    moves
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The smallest quality and smallest angle (degrees) of the faces of `m`.
    fn worst(m: &Mesh) -> (f64, f64) {
        (0..m.n_faces()).fold((f64::INFINITY, f64::INFINITY), |(q, a), f| {
            let [x, y, z] = m.corners(f);
            (
                q.min(triangle::quality(x, y, z)),
                a.min(triangle::min_angle(x, y, z).to_degrees()),
            )
        })
    }

    /// A sphere relaxed as `uniform-cvt` does, with and without polishing: the worst face's
    /// quality rises, no face loses angle below the floor, every vertex stays on the input.
    #[test]
    fn polishing_lifts_the_worst_face_and_keeps_the_smallest_angle() {
        let original = coarsen_shapes::icosphere(1.0, 4).unwrap();
        let surface = Surface::new(&original);
        let mut m = coarsen_shapes::icosphere(1.0, 3).unwrap();
        crate::tests::jitter_on_sphere(&mut m, 11, 0.1);
        let params = |polish| RelaxParams {
            floor_deg: 40.0,
            polish,
            ..RelaxParams::default()
        };
        let (mut plain, mut polished) = (m.clone(), m);
        let r0 = relax(&mut plain, Some(&surface), &params(0));
        let r1 = relax(&mut polished, Some(&surface), &params(3));
        assert_eq!((r0.polished, plain.faces.len()), (0, polished.faces.len()));
        assert!(r1.polished > 0, "{r1:?}");
        let ((q0, a0), (q1, a1)) = (worst(&plain), worst(&polished));
        assert!(q1 > q0 + 1e-3, "worst quality {q0} -> {q1}");
        assert!(a1 >= a0.min(40.0) - 1e-9, "smallest angle {a0} -> {a1}");
        // The same sweeps ran before: the faces are the same, and none lost angle below
        // the floor.
        assert_eq!(plain.faces, polished.faces);
        for f in 0..plain.n_faces() {
            let angle = |m: &Mesh| {
                let [a, b, c] = m.corners(f);
                triangle::min_angle(a, b, c).to_degrees()
            };
            let (before, after) = (angle(&plain), angle(&polished));
            assert!(
                after >= before.min(40.0) - 1e-9,
                "face {f}: {before} -> {after}"
            );
        }
        for p in &polished.positions {
            assert!((p.length() - 1.0).abs() < 0.01, "{p}");
        }
    }
}
