//! The z-buffered triangle rasterizer, its wireframe and outline.

use crate::camera::Camera;
use crate::light;
use coarsen_geom::DVec3;
use coarsen_mesh::Mesh;

pub(crate) const BACKGROUND: [f32; 3] = [0.97, 0.97, 0.96];
const BASE: [f32; 3] = [0.78, 0.78, 0.80];
const WIRE: [f32; 3] = [0.08, 0.08, 0.10];

/// What colours a mesh's faces: per-corner colours, or a texture sampled at each pixel.
#[derive(Default)]
pub(crate) struct Paint<'a> {
    pub colors: Option<&'a [[[f32; 3]; 3]]>,
    pub surface: Option<&'a crate::texture::Surface>,
}

/// How one panel is drawn, in the pixels it is drawn at (supersampled).
pub(crate) struct Pass {
    pub width: usize,
    pub height: usize,
    /// Interpolated vertex normals.
    pub smooth: bool,
    /// Opacity of the wire, 0 for none.
    pub wire: f32,
    /// Half the width of a wire line, in pixels.
    pub wire_half_width: f64,
    /// Outline the silhouette and the folds where the depth jumps (with the wire).
    pub outline: bool,
    /// The light a face turned edge-on to the light still gets (of 1): low for shape,
    /// high for a colour map, whose colours must stay readable on every side.
    pub ambient: f32,
}

/// The median on-screen edge length of `mesh`'s faces, in pixels of a camera whose scale
/// is `scale` (a face's edge taken as √(2·area)): how dense its wire would look.
pub(crate) fn median_edge_pixels(mesh: &Mesh, cam: &Camera) -> f64 {
    let mut sizes: Vec<f64> = (0..mesh.n_faces())
        .map(|f| (2.0 * mesh.face_area(f)).sqrt() * cam.scale)
        .filter(|x| x.is_finite() && *x > 0.0)
        .collect();
    if sizes.is_empty() {
        return f64::INFINITY;
    }
    let mid = sizes.len() / 2;
    *sizes.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The wire's opacity for faces whose edges are `edge_px` pixels long on the final
/// picture: full from 8 pixels up, fading to a faint 0.15 at 2 pixels and below, so that
/// a dense mesh shows its outline and a light wire instead of a dark blot.
pub(crate) fn wire_opacity(edge_px: f64) -> f32 {
    (0.15 + 0.85 * ((edge_px - 2.0) / 6.0).clamp(0.0, 1.0)) as f32
}

/// Lines and dots drawn over a mesh where they are not hidden by it.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Overlay {
    /// Segments and their colours.
    pub segments: Vec<([DVec3; 2], [f32; 3])>,
    /// Dots and their colours.
    pub dots: Vec<(DVec3, [f32; 3])>,
}

/// Draws one mesh, then `overlay` over it; returns the colour of every pixel, rows top to
/// bottom.
pub(crate) fn draw(
    mesh: &Mesh,
    paint: &Paint<'_>,
    cam: &Camera,
    pass: &Pass,
    overlay: &Overlay,
) -> Vec<[f32; 3]> {
    let (w, h) = (pass.width, pass.height);
    let mut depth = vec![f64::NEG_INFINITY; w * h];
    let mut color = vec![BACKGROUND; w * h];
    let normals = if pass.smooth {
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
        let corner_normals = if pass.smooth {
            tri.map(|v| normals[v as usize])
        } else {
            [face_normal; 3]
        };
        let corner_colors = paint.colors.map(|c| c[f]).unwrap_or([BASE; 3]);
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
                let shade = pass.ambient + (1.0 - pass.ambient) * n.dot(light).abs() as f32;
                let mut rgb = [0.0f32; 3];
                let texel = paint.surface.map(|s| s.sample(f, [w0, w1, w2]));
                for (k, out) in rgb.iter_mut().enumerate() {
                    let base = match texel {
                        Some(t) => t[k],
                        None => {
                            corner_colors[0][k] * w0 as f32
                                + corner_colors[1][k] * w1 as f32
                                + corner_colors[2][k] * w2 as f32
                        }
                    };
                    *out = base * shade;
                }
                if pass.wire > 0.0 {
                    // Distance in pixels to the nearest edge: barycentric × height over that edge.
                    let d = [w0, w1, w2]
                        .iter()
                        .zip(len)
                        .map(|(&wi, l)| wi * area.abs() / l.max(1e-12))
                        .fold(f64::INFINITY, f64::min);
                    if d < pass.wire_half_width {
                        let t = pass.wire * (1.0 - d / pass.wire_half_width) as f32;
                        for (k, out) in rgb.iter_mut().enumerate() {
                            *out = *out * (1.0 - t) + WIRE[k] * t;
                        }
                    }
                }
                color[i] = rgb;
            }
        }
    }
    if pass.outline {
        let radius = pass.wire_half_width.ceil().max(1.0) as usize;
        outline(
            &mut color,
            &depth,
            (w, h),
            radius,
            4.0 / cam.scale * pass.wire_half_width,
        );
    }
    draw_overlay(
        &mut color,
        &depth,
        (w, h),
        cam,
        pass.wire_half_width,
        overlay,
    );
    color
}

/// Paints `overlay` into `color`: each segment as a line `2·half_width` pixels wide (twice
/// that for dots), where nothing of the mesh (`depth`) lies in front of it by more than a
/// few pixels' worth.
fn draw_overlay(
    color: &mut [[f32; 3]],
    depth: &[f64],
    (w, h): (usize, usize),
    cam: &Camera,
    half_width: f64,
    overlay: &Overlay,
) {
    let slack = 3.0 * half_width / cam.scale;
    let mut paint = |p: DVec3, radius: f64, rgb: [f32; 3]| {
        let r = radius.ceil() as i64;
        let (cx, cy) = (p.x.floor() as i64, p.y.floor() as i64);
        for y in cy - r..=cy + r {
            for x in cx - r..=cx + r {
                let (dx, dy) = (x as f64 + 0.5 - p.x, y as f64 + 0.5 - p.y);
                if x < 0
                    || y < 0
                    || x >= w as i64
                    || y >= h as i64
                    || dx * dx + dy * dy > radius * radius
                {
                    continue;
                }
                let i = y as usize * w + x as usize;
                if p.z >= depth[i] - slack {
                    color[i] = rgb;
                }
            }
        }
    };
    for &([a, b], rgb) in &overlay.segments {
        let (a, b) = (cam.project(a), cam.project(b));
        if !(a.is_finite() && b.is_finite()) {
            continue;
        }
        let steps = (2.0 * (b - a).truncate().length()).ceil().clamp(1.0, 1e5) as usize;
        for k in 0..=steps {
            paint(a.lerp(b, k as f64 / steps as f64), half_width, rgb);
        }
    }
    for &(p, rgb) in &overlay.dots {
        let p = cam.project(p);
        if p.is_finite() {
            paint(p, 3.0 * half_width, rgb);
        }
    }
}

/// Darkens the covered pixels within `radius` of an empty one (the silhouette) or of one
/// more than `jump` farther (a fold of the surface in front of another part).
fn outline(
    color: &mut [[f32; 3]],
    depth: &[f64],
    (w, h): (usize, usize),
    radius: usize,
    jump: f64,
) {
    let covered = |i: usize| depth[i] > f64::NEG_INFINITY;
    let mut edge = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if !covered(i) {
                continue;
            }
            edge[i] = (1..=radius).any(|r| {
                let neighbours = [
                    (x >= r).then(|| i - r),
                    (x + r < w).then(|| i + r),
                    (y >= r).then(|| i - r * w),
                    (y + r < h).then(|| i + r * w),
                ];
                neighbours
                    .into_iter()
                    .flatten()
                    .any(|j| !covered(j) || depth[j] < depth[i] - jump)
            });
        }
    }
    for (c, _) in color.iter_mut().zip(&edge).filter(|(_, e)| **e) {
        *c = std::array::from_fn(|k| c[k] * 0.2 + WIRE[k] * 0.8);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render;

    use crate::{ColorScale, HIGHLIGHT, RenderOptions, View, worst_faces};
    use coarsen_mesh::AttrValues;

    /// One sample per pixel and the fixed front view, for pixel-exact checks.
    fn opts(size: u32) -> RenderOptions {
        RenderOptions {
            width: size,
            height: size,
            view: View::Front,
            supersample: 1,
            ..Default::default()
        }
    }

    #[test]
    fn features_draw_a_cubes_edges_and_corners_and_only_with_the_option() {
        let cube = coarsen_shapes::cube(2.0, 2).unwrap();
        let count = |features: bool, rgb: [f32; 3]| {
            let img = render(
                &[&cube],
                &RenderOptions {
                    view: View::Iso,
                    features,
                    ..opts(200)
                },
            )
            .unwrap();
            let want = rgb.map(|x| (x * 255.0).round() as u8);
            (0..200)
                .flat_map(|y| (0..200).map(move |x| (x, y)))
                .filter(|&(x, y)| img.pixel(x, y) == want)
                .count()
        };
        // Nine edges and seven corners face an iso camera.
        assert!(count(true, crate::FEATURE_SHARP) > 300);
        assert!(count(true, crate::FEATURE_CORNER) > 7 * 10);
        assert_eq!(count(false, crate::FEATURE_SHARP), 0);
        assert_eq!(count(false, crate::FEATURE_CORNER), 0);
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

    fn to_u8(c: [f32; 3]) -> [u8; 3] {
        c.map(|x| (x * 255.0).round() as u8)
    }

    #[test]
    fn supersampling_blends_the_rim_and_keeps_the_image_size() {
        let sphere = coarsen_shapes::icosphere(1.0, 3).unwrap();
        let sharp = render(&[&sphere], &opts(64)).unwrap();
        let smooth = render(
            &[&sphere],
            &RenderOptions {
                supersample: 3,
                ..opts(64)
            },
        )
        .unwrap();
        assert_eq!((smooth.width, smooth.height), (64, 64));
        let bg = to_u8(BACKGROUND);
        // Rim pixels between the surface and the background: only with supersampling.
        let between = |img: &crate::Image| {
            (0..64 * 64)
                .map(|i| img.pixel(i % 64, i / 64))
                .filter(|p| *p != bg && p.iter().zip(bg).all(|(&a, b)| a > 215 && a < b))
                .count()
        };
        assert!(
            between(&smooth) > between(&sharp) + 20,
            "{} vs {}",
            between(&smooth),
            between(&sharp)
        );
    }

    #[test]
    fn a_dense_wireframe_stays_light_and_outlined() {
        let dense = coarsen_shapes::icosphere(1.0, 6).unwrap(); // 81,920 faces
        let o = RenderOptions {
            wireframe: true,
            supersample: 2,
            ..opts(120)
        };
        let img = render(&[&dense], &o).unwrap();
        let mean_inside = {
            let centre: Vec<u32> = (40..80)
                .flat_map(|y| (40..80).map(move |x| (x, y)))
                .map(|(x, y)| img.pixel(x, y).iter().map(|&c| u32::from(c)).sum::<u32>() / 3)
                .collect();
            centre.iter().sum::<u32>() / centre.len() as u32
        };
        let plain = render(
            &[&dense],
            &RenderOptions {
                wireframe: false,
                ..o.clone()
            },
        )
        .unwrap();
        let plain_inside = plain
            .pixel(60, 60)
            .iter()
            .map(|&c| u32::from(c))
            .sum::<u32>()
            / 3;
        // The faint wire darkens the surface a little, not into a blot.
        assert!(
            mean_inside + 60 > plain_inside && mean_inside > 90,
            "{mean_inside} vs {plain_inside}"
        );
        // The silhouette is drawn dark across the disc's rim.
        let row: Vec<u32> = (0..120)
            .map(|x| img.pixel(x, 60).iter().map(|&c| u32::from(c)).sum::<u32>() / 3)
            .collect();
        let darkest_rim = row[..20].iter().chain(&row[100..]).min().unwrap();
        assert!(*darkest_rim < 90, "{row:?}");
        assert!(wire_opacity(1.0) < 0.2 && wire_opacity(20.0) == 1.0);
    }

    #[test]
    fn four_views_make_a_two_by_two_sheet_of_different_pictures() {
        let mut m = coarsen_shapes::icosphere(1.0, 2).unwrap();
        for p in &mut m.positions {
            *p *= DVec3::new(3.0, 1.0, 0.5);
        }
        let o = RenderOptions {
            views: 4,
            ..opts(40)
        };
        let img = render(&[&m, &m], &o).unwrap();
        assert_eq!((img.width, img.height), (160, 80));
        // The inside of a panel (the sheet's grey separators run along its last rows).
        let cell = |cx: u32, cy: u32| -> Vec<[u8; 3]> {
            (0..38 * 38)
                .map(|i| img.pixel(cx + i % 38, cy + i / 38))
                .collect()
        };
        // Each cell holds the mesh twice side by side; the broad side and the top differ.
        assert!(cell(0, 0) == cell(40, 0));
        assert!(cell(0, 0) != cell(0, 41));
        assert_eq!(img.pixel(80, 10), [185, 185, 185], "the cells' separator");
        let bad = RenderOptions {
            views: 3,
            ..opts(40)
        };
        assert!(matches!(
            render(&[&m], &bad),
            Err(crate::RenderError::Views(3))
        ));
    }

    #[test]
    fn a_colour_scale_shares_one_range_draws_a_bar_and_highlights_the_worst() {
        let sphere = coarsen_shapes::icosphere(1.0, 2).unwrap();
        let n = sphere.n_faces();
        let mut a = sphere.clone();
        let mut b = sphere.clone();
        a.face_attrs.insert("d", AttrValues::Scalar(vec![0.0; n]));
        b.face_attrs
            .insert("d", AttrValues::Scalar((0..n).map(|f| f as f64).collect()));
        let scale = ColorScale {
            label: "distance".into(),
            range: None,
            factor: 1.0,
            high_is_bad: true,
            highlight_worst: 0.0,
        };
        let o = RenderOptions {
            attribute: Some("d".into()),
            scale: Some(scale.clone()),
            ..opts(64)
        };
        let img = render(&[&a, &b], &o).unwrap();
        assert_eq!(img.width, 128);
        assert!(img.height > 64, "the bar goes under the panels");
        // Mesh a is all at the low end of the shared range: blue.
        let p = img.pixel(32, 32);
        assert!(p[2] > p[0] + 40, "{p:?}");
        // The worst 1 %: ceil(320 / 100) = 4 faces in magenta.
        let worst = worst_faces(
            &b,
            coarsen_mesh::Domain::Face,
            b.face_attrs.scalar("d").unwrap(),
            &ColorScale {
                highlight_worst: 0.01,
                ..scale.clone()
            },
        );
        assert_eq!(worst, vec![n - 1, n - 2, n - 3, n - 4]);
        let low_bad = ColorScale {
            high_is_bad: false,
            highlight_worst: 0.01,
            ..scale
        };
        let worst = worst_faces(
            &b,
            coarsen_mesh::Domain::Face,
            b.face_attrs.scalar("d").unwrap(),
            &low_bad,
        );
        assert_eq!(worst, vec![0, 1, 2, 3]);
        let o = RenderOptions {
            scale: Some(low_bad),
            ..o
        };
        let img = render(&[&b], &o).unwrap();
        let magenta = to_u8(HIGHLIGHT);
        let near =
            |p: [u8; 3]| p[1] < 30 && p[0] > 60 && (i32::from(p[0]) - i32::from(p[2])).abs() < 20;
        assert!(
            (0..64 * 64).any(|i| near(img.pixel(i % 64, i / 64))),
            "no {magenta:?}"
        );
        // A label column cannot be scaled.
        let mut c = sphere.clone();
        c.face_attrs.insert("d", AttrValues::Label(vec![1; n]));
        assert!(matches!(
            render(&[&c], &o),
            Err(crate::RenderError::NotScalar(_))
        ));
    }
}
