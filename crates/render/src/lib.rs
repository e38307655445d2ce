//! A small software renderer: a mesh (or two side by side) to an RGB image, with flat or
//! smooth shading, an optional wireframe and colours from any attribute. No GPU, no
//! window; [`Image::to_png`] gives PNG bytes for the caller to write.
//!
//! ```
//! use coarsen_render::{render, RenderOptions};
//! let sphere = coarsen_shapes::icosphere(1.0, 2).unwrap();
//! let image = render(&[&sphere], &RenderOptions { width: 64, height: 64, ..Default::default() }).unwrap();
//! assert_eq!((image.width, image.height), (64, 64));
//! let png = image.to_png().unwrap();
//! assert_eq!(&png[1..4], b"PNG");
//! ```
//!
//! The camera is orthographic and frames the bounding box of all meshes drawn, so two meshes
//! rendered together (before/after) share one camera. Colour maps: scalars go through a
//! perceptual blue→green→yellow map (viridis-like, monotone in lightness) between their
//! 2nd and 98th percentiles; labels get distinct hues (golden-ratio steps); colour attributes
//! are used as they are.

mod colormap;
mod raster;

pub use colormap::{label_color, scalar_color};

use coarsen_geom::DVec3;
use coarsen_mesh::{AttrValues, Domain, Mesh};

/// Where the camera looks from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum View {
    /// From +z, y up.
    #[default]
    Front,
    /// From +x, y up.
    Side,
    /// From +y, −z up.
    Top,
    /// From (1, 1, 1), y up.
    Iso,
}

impl std::str::FromStr for View {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "front" => Ok(View::Front),
            "side" => Ok(View::Side),
            "top" => Ok(View::Top),
            "iso" => Ok(View::Iso),
            _ => Err(format!("unknown view `{s}` (front, side, top, iso)")),
        }
    }
}

/// How to render.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Image width in pixels of one mesh's panel.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Camera direction.
    pub view: View,
    /// Interpolate vertex normals (else one normal per face).
    pub smooth: bool,
    /// Draw the edges.
    pub wireframe: bool,
    /// Colour by this attribute (vertex or face; scalar, label or colour), else plain grey.
    pub attribute: Option<String>,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 800,
            height: 800,
            view: View::Front,
            smooth: false,
            wireframe: false,
            attribute: None,
        }
    }
}

/// Why a picture could not be made.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The named attribute is on none of the meshes.
    #[error("no vertex or face attribute `{0}` on the mesh")]
    NoAttribute(String),
    /// Image size out of range.
    #[error("image size {0}×{1} is out of range (1..=8192 each)")]
    Size(u32, u32),
    /// A face names a vertex that does not exist.
    #[error("the mesh is invalid: {0}")]
    Mesh(#[from] coarsen_mesh::IndexError),
    /// PNG encoding failed.
    #[error("PNG encoding failed: {0}")]
    Png(String),
}

/// An 8-bit RGB image, rows top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width · height · 3` bytes.
    pub rgb: Vec<u8>,
}

impl Image {
    /// The image as PNG bytes.
    pub fn to_png(&self) -> Result<Vec<u8>, RenderError> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, self.width, self.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc
            .write_header()
            .map_err(|e| RenderError::Png(e.to_string()))?;
        w.write_image_data(&self.rgb)
            .map_err(|e| RenderError::Png(e.to_string()))?;
        w.finish().map_err(|e| RenderError::Png(e.to_string()))?;
        Ok(out)
    }

    /// The pixel at `(x, y)`.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = ((y * self.width + x) * 3) as usize;
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }
}

/// Per-corner colours of every face of a mesh, from the chosen attribute.
fn face_colors(mesh: &Mesh, attribute: Option<&str>) -> Option<Vec<[[f32; 3]; 3]>> {
    let name = attribute?;
    let (domain, values) = match (mesh.vertex_attrs.get(name), mesh.face_attrs.get(name)) {
        (Some(v), _) => (Domain::Vertex, v),
        (None, Some(f)) => (Domain::Face, f),
        (None, None) => return None,
    };
    let per_element: Vec<[f32; 3]> = match values {
        AttrValues::Scalar(v) => {
            let (lo, hi) = colormap::robust_range(v);
            v.iter().map(|&x| scalar_color(x, lo, hi)).collect()
        }
        AttrValues::Label(v) => v.iter().map(|&l| label_color(l)).collect(),
        AttrValues::Color(v) => v.iter().map(|c| c.map(|x| x as f32 / 255.0)).collect(),
        AttrValues::Vec3(v) => v
            .iter()
            .map(|n| (n.normalize_or_zero() * 0.5 + 0.5).as_vec3().to_array())
            .collect(),
        AttrValues::Vec2(v) => v
            .iter()
            .map(|t| [t.x.fract().abs() as f32, t.y.fract().abs() as f32, 0.5])
            .collect(),
    };
    Some(
        mesh.faces
            .iter()
            .enumerate()
            .map(|(f, tri)| match domain {
                Domain::Vertex => tri.map(|v| per_element[v as usize]),
                Domain::Face => [per_element[f]; 3],
            })
            .collect(),
    )
}

/// Renders the meshes side by side (one panel each) with one camera framing them all.
pub fn render(meshes: &[&Mesh], opts: &RenderOptions) -> Result<Image, RenderError> {
    if !(1..=8192).contains(&opts.width) || !(1..=8192).contains(&opts.height) || meshes.is_empty()
    {
        return Err(RenderError::Size(
            opts.width * meshes.len().max(1) as u32,
            opts.height,
        ));
    }
    let mut colors = Vec::with_capacity(meshes.len());
    for m in meshes {
        m.validate_indices()?;
        colors.push(face_colors(m, opts.attribute.as_deref()));
    }
    if let Some(name) = &opts.attribute
        && colors.iter().all(Option::is_none)
    {
        return Err(RenderError::NoAttribute(name.clone()));
    }
    let camera = raster::Camera::framing(meshes, opts.view, opts.width, opts.height);
    let panel_w = opts.width as usize;
    let total_w = panel_w * meshes.len();
    let mut rgb = vec![0u8; total_w * opts.height as usize * 3];
    for (i, (mesh, colors)) in meshes.iter().zip(&colors).enumerate() {
        let panel = raster::draw(mesh, colors.as_deref(), &camera, opts);
        for y in 0..opts.height as usize {
            let src = &panel[y * panel_w * 3..(y + 1) * panel_w * 3];
            let dst = (y * total_w + i * panel_w) * 3;
            rgb[dst..dst + panel_w * 3].copy_from_slice(src);
        }
    }
    Ok(Image {
        width: total_w as u32,
        height: opts.height,
        rgb,
    })
}

/// The light direction used for shading (towards the viewer, a little from the upper left).
pub(crate) fn light(view_dir: DVec3, up: DVec3) -> DVec3 {
    let right = view_dir.cross(up).normalize_or_zero();
    (view_dir * 0.8 + up * 0.45 - right * 0.35).normalize()
}
