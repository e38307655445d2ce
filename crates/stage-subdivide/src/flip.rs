//! Delaunay flips on flat ground: after long edges are split, a CAD export's fans of
//! slivers are still fans; flipping the edges of coplanar face pairs whose opposite angles
//! sum above π turns them into well-shaped triangles without moving the surface.

use coarsen_edit::Editable;
use coarsen_geom::{DVec3, triangle};
use coarsen_mesh::Mesh;

/// Two faces count as coplanar when their normals differ by less than this (radians):
/// flipping their shared edge then moves the surface by at most the quad's size × this.
pub(crate) const FLAT: f64 = 1e-3;

/// Most sweeps of [`flip_to_delaunay`].
const MAX_SWEEPS: usize = 32;

/// Flips, sweep after sweep (edge order, each face once per sweep), every interior edge
/// a–b of faces abc and bad that are coplanar (within [`FLAT`]) and not locally Delaunay
/// (the angles at c and d sum above π) into c–d, when c–d was no edge at the sweep's start
/// nor made in it and both new faces keep the old faces' side; until a sweep flips
/// nothing. Returns the flips made. Only the face array changes (a face keeps its slot).
pub(crate) fn flip_to_delaunay(mesh: &mut Mesh) -> usize {
    let cos_flat = FLAT.cos();
    let mut edit = Editable::new(mesh.n_vertices(), std::mem::take(&mut mesh.faces));
    let mut total = 0;
    // The edges of two faces, ascending: a flip takes one away and makes another.
    let mut edges: Vec<[u32; 2]> = edit
        .edges_now()
        .into_iter()
        .filter(|&(_, n)| n == 2)
        .map(|(ab, _)| ab)
        .collect();
    for _ in 0..MAX_SWEEPS {
        // The sweep visits the edges it starts with; an edge counts as there if it was
        // there then (in `edges`: an edge of one face is never made by a flip) or is now.
        let mut touched = vec![false; edit.faces().len()];
        let mut made: Vec<[u32; 2]> = Vec::new();
        let mut flips = 0;
        for &[a, b] in &edges {
            let Some(parts) = edit.flip_parts(a, b) else {
                continue;
            };
            let (fa, fb, c, d) = parts;
            if touched[fa as usize] || touched[fb as usize] {
                continue;
            }
            let key = [c.min(d), c.max(d)];
            if c == d || edit.has_edge(c, d) || edges.binary_search(&key).is_ok() {
                continue;
            }
            let p = |v: u32| mesh.positions[v as usize];
            let (n1, n2) = (
                triangle::normal(p(a), p(b), p(c)),
                triangle::normal(p(b), p(a), p(d)),
            );
            if n1.dot(n2) < cos_flat {
                continue;
            }
            let at_c = angle(p(c), p(a), p(b));
            let at_d = angle(p(d), p(b), p(a));
            if at_c + at_d <= std::f64::consts::PI * (1.0 + 1e-9) {
                continue;
            }
            let new = [[a, d, c], [d, b, c]];
            let n = n1 + n2;
            let keeps_side = new.iter().all(|t| {
                let cross = triangle::cross(p(t[0]), p(t[1]), p(t[2]));
                cross != DVec3::ZERO && cross.dot(n) > 0.0
            });
            if !keeps_side {
                continue;
            }
            edit.flip([a, b], parts);
            touched[fa as usize] = true;
            touched[fb as usize] = true;
            made.push(key);
            flips += 1;
        }
        total += flips;
        if flips == 0 {
            break;
        }
        edges.retain(|&[a, b]| edit.has_edge(a, b));
        made.sort_unstable();
        edges = merge_sorted(&edges, &made);
    }
    mesh.faces = edit.faces().to_vec();
    total
}

/// The union of two ascending lists with nothing in common, ascending.
fn merge_sorted(x: &[[u32; 2]], y: &[[u32; 2]]) -> Vec<[u32; 2]> {
    let mut out = Vec::with_capacity(x.len() + y.len());
    let (mut i, mut j) = (0, 0);
    while i < x.len() && j < y.len() {
        if x[i] < y[j] {
            out.push(x[i]);
            i += 1;
        } else {
            out.push(y[j]);
            j += 1;
        }
    }
    out.extend_from_slice(&x[i..]);
    out.extend_from_slice(&y[j..]);
    out
}

/// The angle at `apex` of the triangle apex–x–y.
fn angle(apex: DVec3, x: DVec3, y: DVec3) -> f64 {
    triangle::angle_between(x - apex, y - apex)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fan of slivers on a flat square (every face from one corner to the far sides'
    /// many points) flips into triangles whose smallest angles are larger (on the mean,
    /// more than twice), with the same area and orientation.
    #[test]
    fn a_flat_fan_of_slivers_flips_into_better_triangles() {
        let n = 16;
        let mut positions = vec![DVec3::ZERO];
        for i in 0..=n {
            positions.push(DVec3::new(1.0, i as f64 / n as f64, 0.0));
        }
        for i in (0..n).rev() {
            positions.push(DVec3::new(i as f64 / n as f64, 1.0, 0.0));
        }
        let faces: Vec<[u32; 3]> = (1..positions.len() as u32 - 1)
            .map(|i| [0, i, i + 1])
            .collect();
        let mut mesh = Mesh::new(positions, faces);
        let smallest = |m: &Mesh| -> Vec<f64> {
            (0..m.n_faces())
                .map(|f| {
                    let [a, b, c] = m.corners(f);
                    triangle::min_angle(a, b, c).to_degrees()
                })
                .collect()
        };
        let worst = |a: &[f64]| a.iter().copied().fold(f64::INFINITY, f64::min);
        let mean = |a: &[f64]| a.iter().sum::<f64>() / a.len() as f64;
        let (area, before) = (mesh.area(), smallest(&mesh));
        let flips = flip_to_delaunay(&mut mesh);
        assert!(flips > 0);
        assert!((mesh.area() - area).abs() < 1e-12);
        let after = smallest(&mesh);
        assert!(worst(&after) > worst(&before));
        assert!(
            mean(&after) > 2.0 * mean(&before),
            "{} → {}",
            mean(&before),
            mean(&after)
        );
        assert!((0..mesh.n_faces()).all(|f| mesh.face_normal(f).z > 0.0));
        // Delaunay now: nothing left to flip.
        assert_eq!(flip_to_delaunay(&mut mesh), 0);
    }

    /// A crease (two faces at 90°) is never flipped.
    #[test]
    fn a_crease_stays() {
        let positions = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(-0.1, 0.5, 0.0),
            DVec3::new(0.0, 0.5, 0.1),
        ];
        let mut mesh = Mesh::new(positions, vec![[0, 1, 2], [1, 0, 3]]);
        let before = mesh.faces.clone();
        assert_eq!(flip_to_delaunay(&mut mesh), 0);
        assert_eq!(mesh.faces, before);
    }
}
