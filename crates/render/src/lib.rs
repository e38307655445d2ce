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
//! rendered together (before/after) share one camera; by default ([`View::Auto`]) it looks
//! at the first mesh's broad side (along its axis of least spread, upright). Every pixel is
//! the mean of `supersample²` samples (anti-aliasing). The wire fades with the density of
//! the mesh on screen, and comes with the outline of the silhouette and folds, so that a
//! dense mesh does not turn into a dark blot. Colour maps: scalars go through a perceptual
//! blue→green→yellow map (viridis-like, monotone in lightness) between their 2nd and 98th
//! percentiles; labels get distinct hues (golden-ratio steps); colour attributes are used
//! as they are. A [`ColorScale`] instead draws a scalar as good (blue) to bad (red) over
//! one range for all meshes, with a colour bar and its scale under the picture and, on
//! request, the worst faces in magenta.

mod camera;
mod colormap;
mod raster;
mod text;
mod texture;

pub use colormap::{HIGHLIGHT, badness_color, label_color, scalar_color};
pub use texture::{CHECKER_SQUARES, Texturing};

use coarsen_geom::DVec3;
use coarsen_mesh::{AttrValues, Domain, Mesh};

/// Where the camera looks from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum View {
    /// At the first mesh's broad side: along its axis of least spread, the model's +y
    /// (else +z) up.
    #[default]
    Auto,
    /// From +z, y up.
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
            "auto" => Ok(View::Auto),
            "front" => Ok(View::Front),
            "side" => Ok(View::Side),
            "top" => Ok(View::Top),
            "iso" => Ok(View::Iso),
            _ => Err(format!("unknown view `{s}` (auto, front, side, top, iso)")),
        }
    }
}

/// How a scalar attribute is drawn as a diagnostic map with a colour bar.
#[derive(Clone, Debug, PartialEq)]
pub struct ColorScale {
    /// The caption under the bar (ASCII and °; each `; ` starts a line), e.g. "distance to
    /// the input, % of diagonal".
    pub label: String,
    /// The values at the two ends of the map; `None`: the smallest and largest value over
    /// all meshes drawn.
    pub range: Option<(f64, f64)>,
    /// The bar's tick labels show value × this (e.g. 100 / diagonal for percents).
    pub factor: f64,
    /// High values are the bad ones (distances); else low ones are (angles, quality).
    pub high_is_bad: bool,
    /// Paint each mesh's worst fraction of faces (e.g. 0.01) in [`HIGHLIGHT`]; 0 for none.
    pub highlight_worst: f64,
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
    /// 1, or 4 for a 2×2 sheet: the view, the opposite side, from above, from below.
    pub views: u32,
    /// Interpolate vertex normals (else one normal per face).
    pub smooth: bool,
    /// Draw the edges.
    pub wireframe: bool,
    /// Colour by this attribute (vertex or face; scalar, label or colour), else plain grey.
    pub attribute: Option<String>,
    /// Draw the (scalar) attribute as a diagnostic map with a colour bar.
    pub scale: Option<ColorScale>,
    /// Samples per pixel along each axis (1 = none, up to 4).
    pub supersample: u32,
    /// Draw each mesh's sharp features over it (`coarsen-features` at its defaults): sharp
    /// edges and those the input marks red, boundary edges blue, edges of three or more
    /// faces purple, corners yellow.
    pub features: bool,
    /// Draw the texture (or a UV checkerboard) on meshes with a `uv` column, instead of
    /// the plain or attribute colours.
    pub texture: Texturing,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 800,
            height: 800,
            view: View::Auto,
            views: 1,
            smooth: false,
            wireframe: false,
            attribute: None,
            scale: None,
            supersample: 3,
            features: false,
            texture: Texturing::Off,
        }
    }
}

/// Why a picture could not be made.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The named attribute is on none of the meshes.
    #[error("no vertex or face attribute `{0}` on the mesh")]
    NoAttribute(String),
    /// A colour scale was asked for an attribute that holds no scalars.
    #[error("attribute `{0}` holds no scalars: a colour scale needs one number per vertex or face")]
    NotScalar(String),
    /// Image size out of range.
    #[error("image size {0}×{1} is out of range (1..=8192 each)")]
    Size(u32, u32),
    /// A number of views other than 1 or 4.
    #[error("{0} views: a picture has 1 view or a 2×2 sheet of 4")]
    Views(u32),
    /// Supersampling out of range.
    #[error("supersampling {0} is out of range (1..=4)")]
    Supersample(u32),
    /// A texture was asked for, but no mesh has texture coordinates.
    #[error("no `uv` column on the mesh: a texture needs texture coordinates")]
    NoTexCoords,
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
        // Reports embed many pictures: the smaller files are worth the slower encoding.
        enc.set_compression(png::Compression::High);
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

    /// Sets the pixel at `(x, y)` when it is inside the image.
    pub(crate) fn set(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if (0..self.width as i64).contains(&x) && (0..self.height as i64).contains(&y) {
            let i = ((y as usize * self.width as usize) + x as usize) * 3;
            self.rgb[i..i + 3].copy_from_slice(&c);
        }
    }
}

/// The attribute column `name` of `mesh`, vertex first.
fn column<'a>(mesh: &'a Mesh, name: &str) -> Option<(Domain, &'a AttrValues)> {
    match (mesh.vertex_attrs.get(name), mesh.face_attrs.get(name)) {
        (Some(v), _) => Some((Domain::Vertex, v)),
        (None, Some(f)) => Some((Domain::Face, f)),
        (None, None) => None,
    }
}

/// Per-corner colours of every face from per-element colours.
fn per_corner(mesh: &Mesh, domain: Domain, per_element: &[[f32; 3]]) -> Vec<[[f32; 3]; 3]> {
    mesh.faces
        .iter()
        .enumerate()
        .map(|(f, tri)| match domain {
            Domain::Vertex => tri.map(|v| per_element[v as usize]),
            Domain::Face => [per_element[f]; 3],
        })
        .collect()
}

/// Per-corner colours of every face of a mesh, from the chosen attribute.
fn face_colors(mesh: &Mesh, attribute: Option<&str>) -> Option<Vec<[[f32; 3]; 3]>> {
    let (domain, values) = column(mesh, attribute?)?;
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
    Some(per_corner(mesh, domain, &per_element))
}

/// A scalar column drawn on a [`ColorScale`]: its values per mesh (`None` where a mesh
/// lacks it) and the range they are drawn over.
struct Scaled<'a> {
    columns: Vec<Option<(Domain, &'a [f64])>>,
    lo: f64,
    hi: f64,
    /// Some value lies below `lo`, above `hi`.
    clipped: [bool; 2],
}

impl<'a> Scaled<'a> {
    fn of(meshes: &[&'a Mesh], name: &str, scale: &ColorScale) -> Result<Self, RenderError> {
        let mut columns = Vec::with_capacity(meshes.len());
        for m in meshes {
            columns.push(match column(m, name) {
                Some((d, AttrValues::Scalar(v))) => Some((d, v.as_slice())),
                Some(_) => return Err(RenderError::NotScalar(name.into())),
                None => None,
            });
        }
        let (lo, hi) = scale.range.unwrap_or_else(|| {
            let values = columns.iter().flatten().flat_map(|(_, v)| v.iter());
            values
                .filter(|x| x.is_finite())
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                })
        });
        let (lo, hi) = if lo <= hi { (lo, hi) } else { (0.0, 1.0) };
        let mut values = columns.iter().flatten().flat_map(|(_, v)| v.iter());
        let clipped = [values.clone().any(|&x| x < lo), values.any(|&x| x > hi)];
        Ok(Scaled {
            columns,
            lo,
            hi,
            clipped,
        })
    }

    /// The colour of value `x`.
    fn color(&self, x: f64, scale: &ColorScale) -> [f32; 3] {
        let t = if self.hi > self.lo {
            (x - self.lo) / (self.hi - self.lo)
        } else {
            0.0
        };
        badness_color(if scale.high_is_bad { t } else { 1.0 - t })
    }

    /// Per-corner colours of mesh `i`'s faces, its worst faces highlighted.
    fn face_colors(&self, i: usize, mesh: &Mesh, scale: &ColorScale) -> Option<Vec<[[f32; 3]; 3]>> {
        let (domain, values) = self.columns[i]?;
        let per_element: Vec<[f32; 3]> = values.iter().map(|&x| self.color(x, scale)).collect();
        let mut colors = per_corner(mesh, domain, &per_element);
        if scale.highlight_worst > 0.0 {
            for f in worst_faces(mesh, domain, values, scale) {
                colors[f] = [HIGHLIGHT; 3];
            }
        }
        Some(colors)
    }
}

/// The faces of the worst `scale.highlight_worst` fraction (at least one face), by their
/// value (a vertex column: their worst corner's); ties broken by face order.
fn worst_faces(mesh: &Mesh, domain: Domain, values: &[f64], scale: &ColorScale) -> Vec<usize> {
    let badness = |x: f64| {
        let b = if scale.high_is_bad { x } else { -x };
        if b.is_finite() { b } else { f64::NEG_INFINITY }
    };
    let mut faces: Vec<(f64, usize)> = (0..mesh.n_faces())
        .map(|f| {
            let b = match domain {
                Domain::Face => badness(values[f]),
                Domain::Vertex => mesh.faces[f]
                    .iter()
                    .map(|&v| badness(values[v as usize]))
                    .fold(f64::NEG_INFINITY, f64::max),
            };
            (b, f)
        })
        .collect();
    let n =
        ((faces.len() as f64 * scale.highlight_worst).ceil() as usize).clamp(1, faces.len().max(1));
    faces.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    faces.truncate(n);
    faces.into_iter().map(|(_, f)| f).collect()
}

/// Checks the options and meshes before anything is drawn.
fn check(meshes: &[&Mesh], opts: &RenderOptions) -> Result<(), RenderError> {
    if !(1..=8192).contains(&opts.width) || !(1..=8192).contains(&opts.height) || meshes.is_empty()
    {
        return Err(RenderError::Size(
            opts.width.saturating_mul(meshes.len().max(1) as u32),
            opts.height,
        ));
    }
    if opts.views != 1 && opts.views != 4 {
        return Err(RenderError::Views(opts.views));
    }
    if !(1..=4).contains(&opts.supersample) {
        return Err(RenderError::Supersample(opts.supersample));
    }
    for m in meshes {
        m.validate_indices()?;
    }
    Ok(())
}

/// Renders the meshes side by side (one panel each) with one camera framing them all; with
/// four views, a 2×2 sheet of such rows; with a colour scale, its bar underneath.
pub fn render(meshes: &[&Mesh], opts: &RenderOptions) -> Result<Image, RenderError> {
    check(meshes, opts)?;
    let name = opts.attribute.as_deref();
    let scaled = match (&opts.scale, name) {
        (Some(scale), Some(name)) => Some(Scaled::of(meshes, name, scale)?),
        _ => None,
    };
    let colors: Vec<Option<Vec<[[f32; 3]; 3]>>> = meshes
        .iter()
        .enumerate()
        .map(|(i, m)| match (&scaled, &opts.scale) {
            (Some(s), Some(scale)) => s.face_colors(i, m, scale),
            _ => face_colors(m, name),
        })
        .collect();
    if let Some(name) = name
        && colors.iter().all(Option::is_none)
    {
        return Err(RenderError::NoAttribute(name.into()));
    }
    let surfaces: Vec<Option<texture::Surface>> = meshes
        .iter()
        .map(|m| texture::Surface::of(m, opts.texture))
        .collect();
    if opts.texture != Texturing::Off && surfaces.iter().all(Option::is_none) {
        return Err(RenderError::NoTexCoords);
    }
    let overlays: Vec<raster::Overlay> = meshes
        .iter()
        .map(|m| match opts.features {
            true => features_overlay(m),
            false => raster::Overlay::default(),
        })
        .collect();
    let base = camera::frame(opts.view, meshes[0]);
    let frames = if opts.views == 4 {
        camera::sheet(base).to_vec()
    } else {
        vec![base]
    };
    let (pw, ph) = (opts.width as usize, opts.height as usize);
    let cols = if frames.len() == 4 { 2 } else { 1 };
    let cell_w = pw * meshes.len();
    let k = if ph >= 500 { 2 } else { 1 };
    let bar = match (&scaled, &opts.scale) {
        (Some(s), Some(scale)) => Some(text::Bar {
            lo: s.lo,
            hi: s.hi,
            factor: scale.factor,
            label: &scale.label,
            clipped: s.clipped,
        }),
        _ => None,
    };
    let bar_h = bar.as_ref().map_or(0, |b| text::bar_height(b, k) as usize);
    let (total_w, grid_h) = (cell_w * cols, ph * frames.len() / cols);
    let mut image = Image {
        width: total_w as u32,
        height: (grid_h + bar_h) as u32,
        rgb: raster::BACKGROUND
            .map(|x| (x * 255.0).round() as u8)
            .repeat(total_w * (grid_h + bar_h)),
    };
    for (c, frame) in frames.iter().enumerate() {
        let (cx, cy) = ((c % cols) * cell_w, (c / cols) * ph);
        for (i, (mesh, colors)) in meshes.iter().zip(&colors).enumerate() {
            let paint = raster::Paint {
                colors: colors.as_deref(),
                surface: surfaces[i].as_ref(),
            };
            let panel = panel(meshes, mesh, &paint, &overlays[i], *frame, opts);
            for y in 0..ph {
                let dst = ((cy + y) * total_w + cx + i * pw) * 3;
                image.rgb[dst..dst + pw * 3].copy_from_slice(&panel[y * pw * 3..(y + 1) * pw * 3]);
            }
        }
    }
    if cols == 2 {
        separate_cells(&mut image, cell_w, ph, grid_h);
    }
    if let (Some(bar), Some(s), Some(scale)) = (&bar, &scaled, &opts.scale) {
        text::draw_bar(&mut image, grid_h as u32, k, bar, |x| s.color(x, scale));
    }
    Ok(image)
}

/// The sharp features of `mesh` as lines and dots (none when its adjacency cannot be built).
fn features_overlay(mesh: &Mesh) -> raster::Overlay {
    use coarsen_features::{FeatureKind, FeatureOptions, Features};
    let Ok(topo) = coarsen_mesh::Topology::try_build(mesh) else {
        return raster::Overlay::default();
    };
    let f = Features::detect(mesh, &topo, &FeatureOptions::default());
    let p = |v: u32| mesh.positions[v as usize];
    raster::Overlay {
        segments: f
            .edges
            .iter()
            .map(|&(e, kind)| {
                let [a, b] = topo.edge(e);
                let rgb = match kind {
                    FeatureKind::Sharp | FeatureKind::Marked => FEATURE_SHARP,
                    FeatureKind::Boundary => FEATURE_BOUNDARY,
                    FeatureKind::Junction => FEATURE_JUNCTION,
                };
                ([p(a), p(b)], rgb)
            })
            .collect(),
        dots: f.corners.iter().map(|&v| (p(v), FEATURE_CORNER)).collect(),
    }
}

/// Colour of sharp feature edges, and of those the input marks.
pub const FEATURE_SHARP: [f32; 3] = [0.85, 0.1, 0.1];
/// Colour of boundary edges.
pub const FEATURE_BOUNDARY: [f32; 3] = [0.1, 0.35, 0.9];
/// Colour of edges of three or more faces.
pub const FEATURE_JUNCTION: [f32; 3] = [0.6, 0.1, 0.75];
/// Colour of corners.
pub const FEATURE_CORNER: [f32; 3] = [1.0, 0.85, 0.0];

/// Grey lines between the cells of a 2×2 sheet (`cell_w × cell_h` each, `grid_h` high in
/// all), so that the panels of one view read as one.
fn separate_cells(img: &mut Image, cell_w: usize, cell_h: usize, grid_h: usize) {
    let grey = [185, 185, 185];
    for y in 0..grid_h as i64 {
        img.set(cell_w as i64 - 1, y, grey);
        img.set(cell_w as i64, y, grey);
    }
    for x in 0..img.width as i64 {
        img.set(x, cell_h as i64 - 1, grey);
        img.set(x, cell_h as i64, grey);
    }
}

/// One mesh in one frame, `width × height` RGB bytes: drawn supersampled, then each pixel
/// the mean of its samples.
fn panel(
    all: &[&Mesh],
    mesh: &Mesh,
    paint: &raster::Paint<'_>,
    overlay: &raster::Overlay,
    frame: camera::Frame,
    opts: &RenderOptions,
) -> Vec<u8> {
    let s = opts.supersample as usize;
    let (w, h) = (opts.width as usize, opts.height as usize);
    let cam = camera::Camera::framing(all, frame, (w * s) as u32, (h * s) as u32);
    let wire = if opts.wireframe {
        let edge_px = raster::median_edge_pixels(mesh, &cam) / s as f64;
        raster::wire_opacity(edge_px)
    } else {
        0.0
    };
    let pass = raster::Pass {
        width: w * s,
        height: h * s,
        smooth: opts.smooth,
        wire,
        wire_half_width: 0.8 * s as f64,
        outline: opts.wireframe,
        ambient: if opts.scale.is_some() { 0.6 } else { 0.28 },
    };
    let fine = raster::draw(mesh, paint, &cam, &pass, overlay);
    let mut out = Vec::with_capacity(w * h * 3);
    let n = (s * s) as f32;
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f32; 3];
            for dy in 0..s {
                let row = (y * s + dy) * w * s;
                for dx in 0..s {
                    let c = fine[row + x * s + dx];
                    sum = std::array::from_fn(|k| sum[k] + c[k]);
                }
            }
            out.extend(sum.map(|v| ((v / n).clamp(0.0, 1.0) * 255.0).round() as u8));
        }
    }
    out
}

/// The light direction used for shading (towards the viewer, a little from the upper left).
pub(crate) fn light(view_dir: DVec3, up: DVec3) -> DVec3 {
    let right = view_dir.cross(up).normalize_or_zero();
    (view_dir * 0.8 + up * 0.45 - right * 0.35).normalize()
}
