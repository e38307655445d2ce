//! The orthographic camera: which way it looks (a named axis or the surface's principal
//! axes) and how it frames the meshes.

use crate::View;
use coarsen_geom::{Aabb, DMat3, DVec3};
use coarsen_mesh::Mesh;

/// A camera direction: `dir` points from the model towards the viewer, `up` is the
/// screen's up (both unit, perpendicular).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Frame {
    pub dir: DVec3,
    pub up: DVec3,
}

impl Frame {
    fn new(dir: DVec3, up: DVec3) -> Frame {
        let dir = dir.normalize();
        let right = up.cross(dir).normalize();
        Frame {
            dir,
            up: dir.cross(right).normalize(),
        }
    }

    /// The screen's right.
    pub fn right(&self) -> DVec3 {
        self.up.cross(self.dir)
    }
}

/// The frame of a named view; [`View::Auto`] looks at `mesh`'s broad side.
pub(crate) fn frame(view: View, mesh: &Mesh) -> Frame {
    match view {
        View::Auto => broad_side(mesh),
        View::Front => Frame::new(DVec3::Z, DVec3::Y),
        View::Side => Frame::new(DVec3::X, DVec3::Y),
        View::Top => Frame::new(DVec3::Y, -DVec3::Z),
        View::Iso => Frame::new(DVec3::ONE, DVec3::Y),
    }
}

/// The four frames of a 2×2 sheet around `first`: it, the opposite side, from above and
/// from below, which between them see most of a surface (a bunny's holed base, which no
/// side view shows, included).
pub(crate) fn sheet(first: Frame) -> [Frame; 4] {
    [
        first,
        Frame::new(-first.dir, first.up),
        Frame::new(first.up, -first.dir),
        Frame::new(-first.up, first.dir),
    ]
}

/// Looks along the surface's axis of least spread (the smallest principal axis of its
/// area-weighted face centroids), so that the broad side faces the viewer; the screen's
/// up is the model's +y (else +z) as far as it is across the view, so that a model stays
/// upright. The direction's sign puts the viewer on the +z side (else +x, +y).
pub(crate) fn broad_side(mesh: &Mesh) -> Frame {
    let (mut area, mut mean) = (0.0, DVec3::ZERO);
    let centroids: Vec<(f64, DVec3)> = (0..mesh.n_faces())
        .map(|f| {
            let [a, b, c] = mesh.corners(f);
            ((b - a).cross(c - a).length(), (a + b + c) / 3.0)
        })
        .filter(|(w, c)| w.is_finite() && c.is_finite())
        .collect();
    for &(w, c) in &centroids {
        area += w;
        mean += w * c;
    }
    if area.is_nan() || area <= 0.0 {
        return frame(View::Front, mesh);
    }
    mean /= area;
    let mut cov = DMat3::ZERO;
    for &(w, c) in &centroids {
        let d = c - mean;
        cov += DMat3::from_cols(d * d.x, d * d.y, d * d.z) * (w / area);
    }
    let axes = eigenvectors(cov);
    let mut dir = axes[2];
    let sign = [DVec3::Z, DVec3::X, DVec3::Y]
        .iter()
        .map(|a| dir.dot(*a))
        .find(|d| d.abs() > 1e-3)
        .unwrap_or(1.0);
    dir *= sign.signum();
    let across = |a: DVec3| a - dir * a.dot(dir);
    let up = [DVec3::Y, DVec3::Z]
        .into_iter()
        .map(across)
        .find(|u| u.length() > 0.3)
        .unwrap_or(axes[1]);
    Frame::new(dir, up)
}

/// Unit eigenvectors of a symmetric matrix, by decreasing eigenvalue (cyclic Jacobi).
fn eigenvectors(m: DMat3) -> [DVec3; 3] {
    let mut a = m.to_cols_array_2d();
    let mut v = DMat3::IDENTITY.to_cols_array_2d();
    for _ in 0..50 {
        let off = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
        let scale = a[0][0].powi(2) + a[1][1].powi(2) + a[2][2].powi(2);
        if off <= 1e-30 * scale || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in &mut a {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            a[p] = std::array::from_fn(|k| c * row_p[k] - s * row_q[k]);
            a[q] = std::array::from_fn(|k| s * row_p[k] + c * row_q[k]);
            for row in &mut v {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    // `a` and `v` are read as a[row][col] (the matrix is symmetric, so the column-major
    // load is the same); `v` accumulates the rotations, its columns the eigenvectors.
    let mut pairs: Vec<(f64, DVec3)> = (0..3)
        .map(|i| (a[i][i], DVec3::new(v[0][i], v[1][i], v[2][i]).normalize()))
        .collect();
    pairs.sort_by(|x, y| y.0.total_cmp(&x.0));
    [pairs[0].1, pairs[1].1, pairs[2].1]
}

/// An orthographic camera: screen = scale · (projection on right/up) around the centre.
pub(crate) struct Camera {
    pub view: DVec3,
    pub right: DVec3,
    pub up: DVec3,
    center: DVec3,
    /// Pixels per model unit.
    pub scale: f64,
    width: f64,
    height: f64,
}

impl Camera {
    /// A camera in `frame` that frames every referenced vertex of `meshes` in a
    /// `width × height` picture.
    pub(crate) fn framing(meshes: &[&Mesh], frame: Frame, width: u32, height: u32) -> Camera {
        let (dir, up, right) = (frame.dir, frame.up, frame.right());
        let mut screen = Aabb::EMPTY;
        for m in meshes {
            for f in &m.faces {
                for &v in f {
                    let p = m.positions[v as usize];
                    if p.is_finite() {
                        screen.grow(DVec3::new(p.dot(right), p.dot(up), p.dot(dir)));
                    }
                }
            }
        }
        let e = screen.extent();
        let scale = 0.92 * (width as f64 / e.x.max(1e-300)).min(height as f64 / e.y.max(1e-300));
        let c = screen.center();
        Camera {
            view: dir,
            right,
            up,
            center: right * c.x + up * c.y + dir * c.z,
            scale: if scale.is_finite() { scale } else { 1.0 },
            width: width as f64,
            height: height as f64,
        }
    }

    /// Screen position (x right, y down, in pixels) and depth (larger = nearer) of `p`.
    pub(crate) fn project(&self, p: DVec3) -> DVec3 {
        let q = p - self.center;
        DVec3::new(
            self.width / 2.0 + q.dot(self.right) * self.scale,
            self.height / 2.0 - q.dot(self.up) * self.scale,
            q.dot(self.view),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigenvectors_of_a_rotated_diagonal_matrix_are_the_rotated_axes() {
        let r = DMat3::from_rotation_y(0.4) * DMat3::from_rotation_x(0.9);
        let m = r * DMat3::from_diagonal(DVec3::new(1.0, 9.0, 4.0)) * r.transpose();
        let [a, b, c] = eigenvectors(m);
        for (got, want) in [(a, r.y_axis), (b, r.z_axis), (c, r.x_axis)] {
            assert!(got.dot(want).abs() > 1.0 - 1e-9, "{got} vs {want}");
        }
    }

    #[test]
    fn a_flat_slab_is_seen_from_its_broad_side_upright() {
        // A box 4 wide (x), 1 deep (y), 2 high (z): the broad side faces ±y, up is +z.
        let mut slab = coarsen_shapes::icosphere(1.0, 2).unwrap();
        for p in &mut slab.positions {
            *p *= DVec3::new(4.0, 1.0, 2.0);
        }
        let f = broad_side(&slab);
        assert!(f.dir.y.abs() > 0.999, "{:?}", f.dir);
        assert!(f.up.z > 0.999, "{:?}", f.up);
        // The same slab lying along z, deep in x: seen along x, y up.
        for p in &mut slab.positions {
            *p = DVec3::new(p.y, p.z, p.x);
        }
        let f = broad_side(&slab);
        assert!(f.dir.x > 0.999 && f.up.y > 0.999, "{f:?}");
    }

    #[test]
    fn the_sheet_looks_from_four_different_directions() {
        let s = sheet(Frame::new(DVec3::Z, DVec3::Y));
        for i in 0..4 {
            for j in 0..i {
                assert!(s[i].dir.dot(s[j].dir) < 0.9);
            }
            assert!(s[i].dir.dot(s[i].up).abs() < 1e-12);
        }
    }
}
