//! The orthographic camera and the z-buffered triangle rasterizer.

use crate::{RenderOptions, View, light};
use coarsen_geom::{Aabb, DVec3};
use coarsen_mesh::Mesh;

/// An orthographic camera: screen = scale · (projection on right/up) around the centre.
pub(crate) struct Camera {
    view: DVec3,
    right: DVec3,
    up: DVec3,
    center: DVec3,
    scale: f64,
    width: f64,
    height: f64,
}

impl Camera {
    /// A camera looking along `view` that frames every referenced vertex of `meshes`.
    pub(crate) fn framing(meshes: &[&Mesh], view: View, width: u32, height: u32) -> Camera {
        let (dir, up) = match view {
            View::Front => (DVec3::Z, DVec3::Y),
            View::Side => (DVec3::X, DVec3::Y),
            View::Top => (DVec3::Y, -DVec3::Z),
            View::Iso => (DVec3::ONE.normalize(), DVec3::Y),
        };
        let right = up.cross(dir).normalize();
        let up = dir.cross(right).normalize();
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
    fn project(&self, p: DVec3) -> DVec3 {
        let q = p - self.center;
        DVec3::new(
            self.width / 2.0 + q.dot(self.right) * self.scale,
            self.height / 2.0 - q.dot(self.up) * self.scale,
            q.dot(self.view),
        )
    }
}

const BACKGROUND: [f32; 3] = [0.97, 0.97, 0.96];
const BASE: [f32; 3] = [0.78, 0.78, 0.80];
const WIRE: [f32; 3] = [0.08, 0.08, 0.10];

/// Draws one mesh into a `width × height` RGB buffer.
pub(crate) fn draw(
    mesh: &Mesh,
    colors: Option<&[[[f32; 3]; 3]]>,
    cam: &Camera,
    opts: &RenderOptions,
) -> Vec<u8> {
    let (w, h) = (opts.width as usize, opts.height as usize);
    let mut depth = vec![f64::NEG_INFINITY; w * h];
    let mut color = vec![BACKGROUND; w * h];
    let normals = if opts.smooth {
        mesh.vertex_normals()
    } else {
        Vec::new()
    };
    let light = light(cam.view, cam.up);
    let screen: Vec<DVec3> = mesh.positions.iter().map(|&p| cam.project(p)).collect();
    for (f, tri) in mesh.faces.iter().enumerate() {
        let [a, b, c] = tri.map(|v| screen[v as usize]);
        if !(a.is_finite() && b.is_finite() && c.is_finite()) {
            continue;
        }
        // Twice the signed screen area; zero-area triangles cover no pixel centre.
        let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
        if area.abs() < 1e-12 {
            continue;
        }
        let face_normal = mesh.face_normal(f);
        let corner_normals = if opts.smooth {
            tri.map(|v| normals[v as usize])
        } else {
            [face_normal; 3]
        };
        let corner_colors = colors.map(|c| c[f]).unwrap_or([BASE; 3]);
        // Edge lengths in pixels, for the wireframe's distance to each edge.
        let len = [
            (c - b).truncate().length(),
            (a - c).truncate().length(),
            (b - a).truncate().length(),
        ];
        let x0 = a.x.min(b.x).min(c.x).floor().max(0.0) as usize;
        let x1 = (a.x.max(b.x).max(c.x).ceil() as usize).min(w.saturating_sub(1));
        let y0 = a.y.min(b.y).min(c.y).floor().max(0.0) as usize;
        let y1 = (a.y.max(b.y).max(c.y).ceil() as usize).min(h.saturating_sub(1));
        if x0 > x1 || y0 > y1 {
            continue;
        }
        for y in y0..=y1 {
            let py = y as f64 + 0.5;
            for x in x0..=x1 {
                let px = x as f64 + 0.5;
                let w0 = ((b.x - px) * (c.y - py) - (b.y - py) * (c.x - px)) / area;
                let w1 = ((c.x - px) * (a.y - py) - (c.y - py) * (a.x - px)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * a.z + w1 * b.z + w2 * c.z;
                let i = y * w + x;
                if z <= depth[i] {
                    continue;
                }
                depth[i] = z;
                let n = (corner_normals[0] * w0 + corner_normals[1] * w1 + corner_normals[2] * w2)
                    .normalize_or_zero();
                // Two-sided lighting, so open meshes and their insides stay visible.
                let shade = (0.28 + 0.72 * n.dot(light).abs()) as f32;
                let mut rgb = [0.0f32; 3];
                for (k, out) in rgb.iter_mut().enumerate() {
                    let base = corner_colors[0][k] * w0 as f32
                        + corner_colors[1][k] * w1 as f32
                        + corner_colors[2][k] * w2 as f32;
                    *out = base * shade;
                }
                if opts.wireframe {
                    // Distance in pixels to the nearest edge: barycentric × height over that edge.
                    let d = [w0, w1, w2]
                        .iter()
                        .zip(len)
                        .map(|(&wi, l)| wi * area.abs() / l.max(1e-12))
                        .fold(f64::INFINITY, f64::min);
                    if d < 0.8 {
                        let t = (1.0 - d / 0.8) as f32;
                        for (k, out) in rgb.iter_mut().enumerate() {
                            *out = *out * (1.0 - t) + WIRE[k] * t;
                        }
                    }
                }
                color[i] = rgb;
            }
        }
    }
    color
        .iter()
        .flat_map(|c| c.map(|x| (x.clamp(0.0, 1.0) * 255.0).round() as u8))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render;

    fn opts(size: u32) -> RenderOptions {
        RenderOptions {
            width: size,
            height: size,
            ..Default::default()
        }
    }

    #[test]
    fn a_sphere_covers_the_centre_and_leaves_the_corners_empty() {
        let sphere = coarsen_shapes::icosphere(1.0, 3).unwrap();
        let img = render(&[&sphere], &opts(64)).unwrap();
        let bg = BACKGROUND.map(|x| (x * 255.0).round() as u8);
        assert_ne!(img.pixel(32, 32), bg);
        assert_eq!(img.pixel(0, 0), bg);
        assert_eq!(img.pixel(63, 63), bg);
        // The disc fills about π/4 of its framing square (92 % of the width).
        let covered = (0..64 * 64)
            .filter(|&i| img.pixel(i % 64, i / 64) != bg)
            .count() as f64;
        let expect = std::f64::consts::FRAC_PI_4 * (0.92f64 * 64.0).powi(2);
        assert!(
            (covered / expect - 1.0).abs() < 0.05,
            "{covered} vs {expect}"
        );
    }

    #[test]
    fn the_nearer_surface_hides_the_farther_one() {
        // Two squares facing the camera; the red one is nearer (z = 1).
        let mut m = Mesh::new(
            vec![
                DVec3::new(-1.0, -1.0, 0.0),
                DVec3::new(1.0, -1.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(-1.0, 1.0, 0.0),
                DVec3::new(-0.5, -0.5, 1.0),
                DVec3::new(0.5, -0.5, 1.0),
                DVec3::new(0.5, 0.5, 1.0),
                DVec3::new(-0.5, 0.5, 1.0),
            ],
            // The near square is listed first, so a missing depth test would let the far one overwrite it.
            vec![[4, 5, 6], [4, 6, 7], [0, 1, 2], [0, 2, 3]],
        );
        m.face_attrs
            .insert("part", coarsen_mesh::AttrValues::Label(vec![1, 1, 0, 0]));
        let o = RenderOptions {
            attribute: Some("part".into()),
            ..opts(40)
        };
        let img = render(&[&m], &o).unwrap();
        let centre = img.pixel(20, 20);
        let shade_of = |l: u32| crate::label_color(l);
        let near = shade_of(1);
        // The centre pixel's hue matches the near square's label colour (up to shading).
        let ratio =
            |c: [u8; 3], k: usize| c[k] as f32 / (c.iter().map(|&x| x as f32).sum::<f32>() + 1e-6);
        let want = |k: usize| near[k] / near.iter().sum::<f32>();
        for k in 0..3 {
            assert!(
                (ratio(centre, k) - want(k)).abs() < 0.02,
                "{centre:?} vs {near:?}"
            );
        }
    }

    #[test]
    fn wireframe_darkens_edges_only() {
        let sphere = coarsen_shapes::icosphere(1.0, 1).unwrap();
        let plain = render(&[&sphere], &opts(96)).unwrap();
        let wired = render(
            &[&sphere],
            &RenderOptions {
                wireframe: true,
                ..opts(96)
            },
        )
        .unwrap();
        let dark = |img: &crate::Image| {
            img.rgb
                .chunks(3)
                .filter(|c| c.iter().all(|&x| x < 35))
                .count()
        };
        assert_eq!(dark(&plain), 0);
        let n = dark(&wired);
        assert!(n > 100 && n < 96 * 96 / 4, "{n} dark pixels");
    }

    #[test]
    fn side_by_side_panels_share_one_camera() {
        let small = coarsen_shapes::icosphere(0.5, 2).unwrap();
        let big = coarsen_shapes::icosphere(1.0, 2).unwrap();
        let img = render(&[&small, &big], &opts(50)).unwrap();
        assert_eq!((img.width, img.height), (100, 50));
        let bg = BACKGROUND.map(|x| (x * 255.0).round() as u8);
        let covered = |x0: u32| {
            (0..50 * 50)
                .filter(|&i| img.pixel(x0 + i % 50, i / 50) != bg)
                .count()
        };
        let (s, b) = (covered(0) as f64, covered(50) as f64);
        assert!(
            (s / b - 0.25).abs() < 0.05,
            "{s} vs {b}: the small sphere should look a quarter the area"
        );
    }

    #[test]
    fn a_missing_attribute_is_an_error() {
        let sphere = coarsen_shapes::icosphere(1.0, 1).unwrap();
        let o = RenderOptions {
            attribute: Some("nope".into()),
            ..opts(8)
        };
        assert!(matches!(
            render(&[&sphere], &o),
            Err(crate::RenderError::NoAttribute(_))
        ));
    }
}
