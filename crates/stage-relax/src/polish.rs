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

/// Smallest quality and summed quality of the faces `fan` with vertex `v` at `p`; `None`
/// when a face normal turns beyond `cos_turn` from `normals`, or a face's smallest angle
/// capped at `floor` (radians, 0 = uncapped) falls below its own in `angles`. Writes each
/// face's smallest angle to `angles` when `record`.
#[allow(clippy::too_many_arguments)]
fn fan_worst(
    faces: &[[u32; 3]],
    fan: &[u32],
    v: u32,
    p: DVec3,
    positions: &[DVec3],
    normals: &[DVec3],
    cos_turn: f64,
    floor: f64,
    angles: &mut Vec<f64>,
    record: bool,
) -> Option<(f64, f64)> {
    let capped = |x: f64| if floor > 0.0 { x.min(floor) } else { x };
    if record {
        angles.clear();
    }
    let mut quality = f64::INFINITY;
    let mut sum = 0.0;
    for (i, &f) in fan.iter().enumerate() {
        let [a, b, c] = faces[f as usize].map(|w| if w == v { p } else { positions[w as usize] });
        if triangle::normal(a, b, c).dot(normals[i]) < cos_turn {
            return None;
        }
        let angle = triangle::min_angle(a, b, c);
        if record {
            angles.push(angle);
        } else if capped(angle) < capped(angles[i]) {
            return None;
        }
        let q = triangle::quality(a, b, c);
        quality = quality.min(q);
        sum += q;
    }
    Some((quality, sum))
}

/// `params.polish` rounds of polishing `mesh` (adjacency `topo`, boundary neighbours `ends`);
/// returns the moves kept.
pub(crate) fn polish(
    mesh: &mut Mesh,
    topo: &Topology,
    ends: &[Vec<u32>],
    surface: Option<&Surface<'_>>,
    watch: Option<&Watch>,
    params: &RelaxParams,
    cos_turn: f64,
) -> usize {
    let n_faces = mesh.n_faces();
    if n_faces == 0 {
        return 0;
    }
    let worst = ((n_faces as f64 * WORST_SHARE) as usize).clamp(WORST_MIN.min(n_faces), n_faces);
    let floor = params.floor_deg.to_radians();
    let onto = surface.filter(|_| params.project);
    let mut moves = 0;
    let mut normals = Vec::new();
    let mut cands = Vec::new();
    let mut tris = Vec::new();
    let mut angles = Vec::new();
    for _ in 0..params.polish {
        let mut ranked: Vec<(f64, u32)> = (0..n_faces)
            .map(|f| {
                let [a, b, c] = mesh.corners(f);
                (triangle::quality(a, b, c), f as u32)
            })
            .collect();
        let by_quality = |x: &(f64, u32), y: &(f64, u32)| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1));
        if worst < n_faces {
            ranked.select_nth_unstable_by(worst, by_quality);
            ranked.truncate(worst);
        }
        ranked.sort_unstable_by(by_quality);
        let mut moved_round = 0;
        for &(_, f) in &ranked {
            for v in mesh.faces[f as usize] {
                let fan = topo.vertex_faces(v);
                if fan.is_empty() || topo.n_vertex_fans(v) != 1 {
                    continue;
                }
                let boundary = topo.is_boundary_vertex(v);
                // A boundary vertex slides between its two boundary neighbours.
                let slide = match (boundary, &ends[v as usize][..]) {
                    (false, _) => None,
                    (true, &[u, w]) => Some([u, w]),
                    (true, _) => continue,
                };
                let faces = &mesh.faces;
                let positions = &mesh.positions;
                let p = positions[v as usize];
                normals.clear();
                let (mut sum, mut area, mut normal) = (DVec3::ZERO, 0.0, DVec3::ZERO);
                for &g in fan {
                    let [a, b, c] = faces[g as usize].map(|w| positions[w as usize]);
                    let w = triangle::area(a, b, c);
                    sum += w * triangle::centroid(a, b, c);
                    area += w;
                    normal += triangle::cross(a, b, c);
                    normals.push(triangle::normal(a, b, c));
                }
                let normal = normal.normalize_or_zero();
                if area <= 0.0 || normal == DVec3::ZERO {
                    continue;
                }
                let Some(before) = fan_worst(
                    faces,
                    fan,
                    v,
                    p,
                    positions,
                    &normals,
                    -1.0,
                    floor,
                    &mut angles,
                    true,
                ) else {
                    continue;
                };
                // Where a target takes the vertex: inside, onto the nearest point of the
                // input; on the boundary, onto the input's boundary along its loop.
                let place = |target: DVec3| match (slide, onto) {
                    (None, Some(sf)) => sf.project(target).unwrap_or(target),
                    (Some([u, w]), Some(sf)) => {
                        let [u, w] = [u, w].map(|k| positions[k as usize]);
                        sf.project_boundary_along(
                            p,
                            target,
                            BOUNDARY_REACH * (u.distance(p) + w.distance(p)),
                        )
                        .unwrap_or(DVec3::NAN)
                    }
                    (_, None) => target,
                };
                // The sweep's moves (inside: towards the ring's centroid and its
                // neighbours' mean, in the tangent plane; on the boundary: to the middle and
                // thirds between its boundary neighbours) and moves towards the apex that
                // makes the vertex's worst face equilateral.
                cands.clear();
                match slide {
                    None => {
                        let tangent = |d: DVec3| d - d.dot(normal) * normal;
                        let d = tangent(sum / area - p);
                        let ring = topo.vertex_neighbors(v);
                        let mean = ring.iter().map(|&w| positions[w as usize]).sum::<DVec3>()
                            / ring.len().max(1) as f64;
                        let l = tangent(mean - p);
                        cands.extend(
                            [d, 0.5 * d, 0.25 * d, l, 0.5 * l].map(|m| p + params.step * m),
                        );
                    }
                    Some([u, w]) => {
                        let [u, w] = [u, w].map(|k| positions[k as usize]);
                        cands.extend(
                            [0.5, 1.0 / 3.0, 2.0 / 3.0]
                                .map(|s| p + params.step * (u.lerp(w, s) - p)),
                        );
                    }
                }
                let bad = fan
                    .iter()
                    .map(|&g| {
                        let [a, b, c] = faces[g as usize].map(|w| positions[w as usize]);
                        (triangle::quality(a, b, c), g)
                    })
                    .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
                if let Some((_, g)) = bad {
                    let [a, b, c] = faces[g as usize];
                    let (u, w) = match v {
                        _ if v == a => (b, c),
                        _ if v == b => (c, a),
                        _ => (a, b),
                    };
                    let (u, w) = (positions[u as usize], positions[w as usize]);
                    let mid = 0.5 * (u + w);
                    let side = triangle::normal(p, u, w).cross(w - u).normalize_or_zero();
                    let side = if side.dot(p - mid) < 0.0 { -side } else { side };
                    let apex = mid + side * (0.75f64.sqrt() * u.distance(w));
                    cands.extend([1.0, 0.5, 0.25].map(|t| p + t * (apex - p)));
                }
                for q in cands.iter_mut() {
                    *q = place(*q);
                }
                // The candidates that keep the capped smallest angle and raise the smallest
                // quality, best first; the input tests in that order.
                let mut kept: Vec<(f64, DVec3)> = cands
                    .iter()
                    .filter(|q| q.is_finite() && **q != p)
                    .filter_map(|&q| {
                        let after = fan_worst(
                            faces,
                            fan,
                            v,
                            q,
                            positions,
                            &normals,
                            cos_turn,
                            floor,
                            &mut angles,
                            false,
                        )?;
                        let gain = after.0 - before.0;
                        (gain > 0.0 && after.1 - before.1 >= -TRADE * gain).then_some((after.0, q))
                    })
                    .collect();
                kept.sort_by(|x, y| y.0.total_cmp(&x.0));
                let moved_fan = |q: DVec3| {
                    fan.iter().map(move |&g| {
                        faces[g as usize].map(|w| if w == v { q } else { positions[w as usize] })
                    })
                };
                let chosen = kept.iter().map(|&(_, q)| q).find(|&q| {
                    surface.is_none_or(|s| moved_fan(q).all(|[a, b, c]| s.agrees(a, b, c)))
                        && watch.is_none_or(|w| {
                            tris.clear();
                            tris.extend(moved_fan(q));
                            w.allows(fan, &tris)
                        })
                });
                if let Some(q) = chosen {
                    mesh.positions[v as usize] = q;
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
