//! Paper 2's squared volume error weighted as its Eq. (4) quadrics, measured on any
//! collapse (QEM's too), for reports that put the stages side by side.

use crate::{Index, LiveMesh};
use coarsen_geom::{DVec3, triangle};

/// Σ Wᵢ·Nᵢ·Vᵢ² over the faces around `verts` (each once) when they move to `p`: Vᵢ =
/// (Sᵢ/3)·(nᵢ·p + dᵢ) the signed volume swept, Wᵢ = 2(1 − cos αᵢ)·Sᵢ the shape factor and
/// Nᵢ the mean of (1 − |nᵢ·nⱼ|)/2 over the faces j sharing a vertex with face i (paper 2,
/// §3.2; world units).
pub fn weighted_sve(mesh: &LiveMesh, verts: &[Index], p: DVec3) -> f64 {
    let mut sum = 0.0;
    for (i, &v) in verts.iter().enumerate() {
        for &f in mesh.faces_around(v) {
            let face = mesh.face(f);
            if verts[..i].iter().any(|u| face.contains(u)) {
                continue;
            }
            let [a, b, c] = face.map(|u| mesh.position(u));
            let cross = triangle::cross(a, b, c);
            let len = cross.length();
            if len == 0.0 || !len.is_finite() {
                continue;
            }
            let area = 0.5 * len;
            let [x, y, z] = triangle::angles(a, b, c);
            let shape = 2.0 * (1.0 - x.min(y).min(z).cos()) * area;
            let volume = cross.dot(p - a) / 6.0;
            sum += shape * normal_factor(mesh, f, cross / len) * volume * volume;
        }
    }
    sum
}

/// Nᵢ of face `f` (unit normal `n`): the mean of (1 − |n·nⱼ|)/2 over the other
/// non-degenerate faces sharing a vertex with it (0 when there are none).
fn normal_factor(mesh: &LiveMesh, f: Index, n: DVec3) -> f64 {
    let face = mesh.face(f);
    let (mut sum, mut count) = (0.0, 0usize);
    for (i, &v) in face.iter().enumerate() {
        for &g in mesh.faces_around(v) {
            let other = mesh.face(g);
            if g == f || face[..i].iter().any(|u| other.contains(u)) {
                continue;
            }
            let m = other.map(|u| mesh.position(u));
            let m = triangle::cross(m[0], m[1], m[2]).normalize_or_zero();
            if m != DVec3::ZERO {
                sum += 0.5 * (1.0 - n.dot(m).abs());
                count += 1;
            }
        }
    }
    if count > 0 { sum / count as f64 } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::grid;

    #[test]
    fn flat_regions_weigh_nothing_and_bent_ones_do() {
        let flat = LiveMesh::new(&grid(6, 6, |_, _| 0.0)).unwrap();
        let v = 3 * 7 + 3;
        let lifted = flat.position(v) + DVec3::Z * 0.1;
        // Every neighbour is coplanar: Nᵢ = 0 for each face, whatever the lift.
        assert_eq!(weighted_sve(&flat, &[v], lifted), 0.0);
        let bent = LiveMesh::new(&grid(6, 6, |x, y| 0.3 * (x * x + y * y))).unwrap();
        let at = bent.position(v);
        let still = weighted_sve(&bent, &[v], at);
        let w = weighted_sve(&bent, &[v], at + DVec3::Z * 0.1);
        assert!(w > 0.0 && w.is_finite(), "{w}");
        assert!(
            still < 1e-20 * w,
            "no move, no volume (up to rounding): {still}"
        );
        // Twice the lift: four times the squared volumes.
        let w2 = weighted_sve(&bent, &[v], at + DVec3::Z * 0.2);
        assert!((w2 / w - 4.0).abs() < 1e-9, "{w2} {w}");
    }
}
