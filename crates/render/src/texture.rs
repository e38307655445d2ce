//! Texture on the surface: the mesh's own image at each pixel's UV, or a UV checkerboard
//! that shows where the texture coordinates go (a seam that holds shows as squares that
//! meet; one that tears as squares cut off).

use coarsen_geom::DVec2;
use coarsen_mesh::{AttrValues, Mesh};

/// What is drawn on the faces of a mesh with texture coordinates (a `uv` column).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Texturing {
    /// Nothing: the faces are grey, or coloured by the chosen attribute.
    #[default]
    Off,
    /// The mesh's texture (the first PNG image its materials hold), or the checkerboard
    /// when it has none.
    Image,
    /// A checkerboard of [`CHECKER_SQUARES`] squares across the unit UV square.
    Checker,
}

/// Squares of the UV checkerboard along each axis of the unit UV square.
pub const CHECKER_SQUARES: f64 = 16.0;

/// The two colours of the checkerboard.
const CHECKER: [[f32; 3]; 2] = [[0.93, 0.90, 0.84], [0.28, 0.42, 0.62]];

/// What a face's pixels sample.
pub(crate) struct Surface {
    /// Each face's corner UVs.
    uv: Vec<[DVec2; 3]>,
    image: Option<Pixels>,
}

/// A decoded image, rows top to bottom.
struct Pixels {
    width: usize,
    height: usize,
    rgb: Vec<[f32; 3]>,
}

impl Surface {
    /// The surface of `mesh` for `mode`; `None` when it is off or the mesh has no UVs.
    pub(crate) fn of(mesh: &Mesh, mode: Texturing) -> Option<Surface> {
        if mode == Texturing::Off {
            return None;
        }
        let uv = corner_uvs(mesh)?;
        let image = match mode {
            Texturing::Image => mesh
                .materials
                .images
                .iter()
                .filter_map(|i| i.bytes.as_deref())
                .find_map(decode_png),
            _ => None,
        };
        Some(Surface { uv, image })
    }

    /// The colour at barycentric weights `w` of face `f`.
    pub(crate) fn sample(&self, f: usize, w: [f64; 3]) -> [f32; 3] {
        let t = self.uv[f];
        let uv = t[0] * w[0] + t[1] * w[1] + t[2] * w[2];
        match &self.image {
            // Texture coordinates as OBJ gives them: v up from the image's bottom row.
            Some(p) => {
                let x = (uv.x.rem_euclid(1.0) * p.width as f64) as usize;
                let y = ((1.0 - uv.y.rem_euclid(1.0)) * p.height as f64) as usize;
                p.rgb[y.min(p.height - 1) * p.width + x.min(p.width - 1)]
            }
            None => {
                let cell = (uv * CHECKER_SQUARES).floor();
                CHECKER[((cell.x + cell.y) as i64).rem_euclid(2) as usize]
            }
        }
    }
}

/// Each face's corner UVs, from the wedges or a vertex column `uv`.
fn corner_uvs(mesh: &Mesh) -> Option<Vec<[DVec2; 3]>> {
    let AttrValues::Vec2(uv) = mesh.corner_column("uv")? else {
        return None;
    };
    Some(uv.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// The pixels of a PNG file's bytes (8 or 16 bits, grey or colour, with or without
/// alpha, palettes expanded); `None` for anything else or a broken file.
fn decode_png(bytes: &[u8]) -> Option<Pixels> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info().ok()?;
    let mut buf = vec![0; reader.output_buffer_size()?];
    let info = reader.next_frame(&mut buf).ok()?;
    let channels = info.color_type.samples();
    let (width, height) = (info.width as usize, info.height as usize);
    if width == 0 || height == 0 || info.bit_depth != png::BitDepth::Eight {
        return None;
    }
    let rgb = buf[..info.buffer_size()]
        .chunks_exact(channels)
        .map(|px| {
            let c = |i: usize| f32::from(px[i.min(channels - 1)]) / 255.0;
            match channels {
                1 | 2 => [c(0); 3],
                _ => [c(0), c(1), c(2)],
            }
        })
        .collect();
    Some(Pixels { width, height, rgb })
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::Image;

    #[test]
    fn the_checkerboard_alternates_and_no_uvs_draw_nothing() {
        let m = coarsen_shapes::uv_square();
        let s = Surface::of(&m, Texturing::Checker).unwrap();
        let step = 1.0 / CHECKER_SQUARES;
        // Barycentric weights of face 0 ([0,0], [1,0], [1,1]) for a UV point (u, v), v ≤ u.
        let at = |u: f64, v: f64| s.sample(0, [1.0 - u, u - v, v]);
        assert_ne!(at(0.5 * step, 0.1 * step), at(1.5 * step, 0.1 * step));
        assert_eq!(at(0.5 * step, 0.1 * step), at(2.5 * step, 0.1 * step));
        assert!(Surface::of(&m, Texturing::Off).is_none());
        let plain = Mesh::new(m.positions.clone(), m.faces.clone());
        assert!(Surface::of(&plain, Texturing::Checker).is_none());
    }

    #[test]
    fn an_image_is_sampled_with_v_up() {
        // A 2×2 PNG: top row red, green; bottom row blue, white.
        let mut bytes = Vec::new();
        let mut enc = png::Encoder::new(&mut bytes, 2, 2);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&[255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255])
            .unwrap();
        w.finish().unwrap();
        let mut m = coarsen_shapes::uv_square();
        m.materials.images.push(Image {
            bytes: Some(bytes),
            ..Default::default()
        });
        let s = Surface::of(&m, Texturing::Image).unwrap();
        // UV (0.75, 0.25) lies in face 0 and in the image's bottom-right pixel (white);
        // (0.75, 0.7) in its top-right one (green).
        assert_eq!(s.sample(0, [0.25, 0.5, 0.25]), [1.0, 1.0, 1.0]);
        assert_eq!(s.sample(0, [0.25, 0.05, 0.7]), [0.0, 1.0, 0.0]);
    }
}
