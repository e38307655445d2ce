//! glTF 2.0 reading: the document and GLB container parsed by the `gltf` crate, the
//! accessors read here with every bound checked.
//!
//! What is read: the triangle primitives of every mesh instance of the scene (the default
//! scene, else the first; every mesh when there is no scene), each with its nodes'
//! transforms applied in `f64` (a mirroring transform turns its triangles around), or only
//! the instances of the mesh named by [`ReadOptions::gltf_mesh`]. `POSITION`, `NORMAL`,
//! `TEXCOORD_0` and `COLOR_0` of any component type the format allows (normalized
//! integers scaled to `[0, 1]` / `[-1, 1]`), indices of any width, sparse accessors.
//! glTF vertices are welded where their transformed positions are bit for bit equal, so
//! that the surface is connected; a glTF vertex becomes a wedge of its mesh vertex (see
//! `coarsen_mesh::wedge`), and `uv`, `normal` and `color` (and `alpha`, 0–255 as in PLY,
//! from a four-component `COLOR_0`) are per vertex where no seam or hard edge splits them.
//! `TEXCOORD_0`'s `v` is turned to the `uv` column's convention, `1 − v` (glTF puts the
//! image's origin at its top left; OBJ, PLY and coarsen at its bottom left). Turned back on
//! writing, every `f32` comes back bit for bit but nonzero ones below 2⁻²⁹ in magnitude.
//! The materials, textures, samplers and images are kept in `Mesh::materials` (image
//! bytes read from the GLB, a data URI or a file beside a `.gltf` read by path), and the
//! face label column `material` says which material each face uses when they are not all
//! the first.
//!
//! Refused with an error naming what and where: other primitive modes (points, lines,
//! strips, fans), morph targets, skins, compressed geometry (Draco, meshopt), GPU
//! instancing, any other required extension, malformed accessors, buffers behind an
//! absolute path or a URI scheme (only data URIs and paths relative to the file are read,
//! so that a file cannot pull in what lies elsewhere). Ignored with a note: other
//! attribute sets (`TANGENT`, `TEXCOORD_1`, `JOINTS_0`, …), other scenes, meshes no node
//! of the scene shows, animations, cameras.

use crate::ReadOptions;
use crate::error::{ErrorKind, IoError};
use base64::Engine as _;
use coarsen_mesh::material::MATERIAL;
use coarsen_mesh::{AttrValues, Attributes, DVec2, DVec3, Image, Materials, Mesh};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::{Mode, Semantic};
use serde_json::{Map, Value};
use std::collections::HashMap;
use std::path::Path;

/// Extensions whose meshes this reader cannot read, and why.
const REFUSED: [(&str, &str); 3] = [
    ("KHR_draco_mesh_compression", "Draco-compressed meshes"),
    ("EXT_meshopt_compression", "meshopt-compressed buffers"),
    ("EXT_mesh_gpu_instancing", "GPU instancing"),
];

/// Extensions a file may require and still be read in full (they touch materials and
/// textures, carried unchanged, or what the accessor reader already handles).
const ACCEPTED: [&str; 14] = [
    "KHR_mesh_quantization",
    "KHR_texture_transform",
    "KHR_materials_unlit",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_materials_clearcoat",
    "KHR_materials_sheen",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_texture_basisu",
    "EXT_texture_webp",
    "KHR_materials_iridescence",
];

/// Where a `.gltf` file's external buffers and images are looked for.
pub(crate) struct Beside<'a>(pub Option<&'a Path>);

/// One mesh instance: a mesh and the transform of its node.
struct Instance<'a> {
    mesh: gltf::Mesh<'a>,
    matrix: [[f64; 4]; 4],
}

/// What the primitives give, per glTF vertex and per triangle corner.
#[derive(Default)]
struct Gathered {
    /// Welded positions, and the weld index by bit pattern.
    positions: Vec<DVec3>,
    weld: HashMap<[u64; 3], u32>,
    faces: Vec<[u32; 3]>,
    face_material: Vec<u32>,
    uv: Vec<DVec2>,
    normal: Vec<DVec3>,
    color: Vec<[u8; 3]>,
    alpha: Vec<f64>,
    has: [bool; 4],
    missing: [usize; 4],
    ignored: Vec<String>,
    glb_vertices: usize,
    /// The meshes read (by index), and the name asked for, if any.
    instanced: Vec<usize>,
    named: Option<String>,
}

const UV: usize = 0;
const NORMAL: usize = 1;
const COLOR: usize = 2;
const ALPHA: usize = 3;

/// Reads a `.gltf` (JSON) or `.glb` (binary) file's bytes; `name` is used in errors.
pub(crate) fn read(
    bytes: &[u8],
    name: &str,
    opts: &ReadOptions,
    beside: Beside<'_>,
) -> Result<(Mesh, Vec<String>), IoError> {
    let fail = |kind| IoError::file(name, kind);
    let raw = raw_json(bytes).map_err(|e| fail(ErrorKind::Syntax(e)))?;
    check_references(&raw).map_err(|e| fail(ErrorKind::Syntax(e)))?;
    let gltf = gltf::Gltf::from_slice(bytes)
        .map_err(|e| fail(ErrorKind::Syntax(format!("not a valid glTF 2.0 file: {e}"))))?;
    let mut notes = Vec::new();
    check_extensions(&raw).map_err(|e| fail(ErrorKind::Unsupported(e)))?;
    let buffers = load_buffers(&gltf, name, &beside)?;
    let instances = instances(&gltf.document, opts.gltf_mesh.as_deref())
        .map_err(|e| fail(ErrorKind::Unsupported(e)))?;
    if instances.is_empty() {
        let what = match &opts.gltf_mesh {
            Some(m) => format!(
                "no mesh called `{m}` in the scene (meshes: {})",
                mesh_names(&gltf.document)
            ),
            None => "the scene has no mesh".to_string(),
        };
        return Err(fail(ErrorKind::Syntax(what)));
    }
    let mut g = Gathered {
        named: opts.gltf_mesh.clone(),
        ..Gathered::default()
    };
    for inst in &instances {
        g.instanced.push(inst.mesh.index());
        for prim in inst.mesh.primitives() {
            primitive(&mut g, &prim, inst, &buffers, name, opts)?;
        }
    }
    notes.extend(document_notes(&gltf.document, &g));
    let materials = materials(&raw, &buffers, &beside, &mut notes);
    Ok((build(g, materials), notes))
}

/// The document's JSON as a tree (from the GLB's JSON chunk or the whole file).
fn raw_json(bytes: &[u8]) -> Result<Value, String> {
    let json: std::borrow::Cow<'_, [u8]> = if bytes.starts_with(b"glTF") {
        gltf::binary::Glb::from_slice(bytes)
            .map_err(|e| format!("not a valid GLB file: {e}"))?
            .json
    } else {
        bytes.into()
    };
    serde_json::from_slice(&json).map_err(|e| format!("not valid JSON: {e}"))
}

/// Checks what the `gltf` crate's own validation indexes without checking (1.4: the
/// accessors a primitive's attributes and targets name), so that no file can make it panic.
fn check_references(raw: &Value) -> Result<(), String> {
    let n = raw
        .get("accessors")
        .and_then(Value::as_array)
        .map_or(0, Vec::len);
    let meshes = raw.get("meshes").and_then(Value::as_array);
    for (m, mesh) in meshes.into_iter().flatten().enumerate() {
        let prims = mesh.get("primitives").and_then(Value::as_array);
        for (p, prim) in prims.into_iter().flatten().enumerate() {
            let targets = prim.get("targets").and_then(Value::as_array);
            let maps = std::iter::once(prim.get("attributes"))
                .chain(targets.into_iter().flatten().map(Some))
                .flatten()
                .filter_map(Value::as_object);
            let named = maps.flat_map(|o| o.iter()).map(|(k, v)| (k.as_str(), v));
            let indices = prim.get("indices").map(|v| ("indices", v));
            for (what, v) in named.chain(indices) {
                if v.as_u64().is_none_or(|i| i >= n as u64) {
                    return Err(format!(
                        "mesh {m} primitive {p}: {what} names accessor {v}, but there are {n}"
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Refuses the extensions whose meshes cannot be read, and required ones not known.
fn check_extensions(raw: &Value) -> Result<(), String> {
    let names = |key: &str| -> Vec<String> {
        raw.get(key)
            .and_then(Value::as_array)
            .map(|a| {
                a.iter()
                    .filter_map(Value::as_str)
                    .map(str::to_string)
                    .collect()
            })
            .unwrap_or_default()
    };
    for used in names("extensionsUsed")
        .iter()
        .chain(&names("extensionsRequired"))
    {
        if let Some((ext, what)) = REFUSED.iter().find(|(e, _)| e == used) {
            return Err(format!("{what} (extension {ext})"));
        }
    }
    for required in names("extensionsRequired") {
        if !ACCEPTED.contains(&required.as_str()) {
            return Err(format!("the required extension {required}"));
        }
    }
    Ok(())
}

/// The bytes of every buffer: the GLB's binary chunk, a data URI, or a file beside.
fn load_buffers(
    gltf: &gltf::Gltf,
    name: &str,
    beside: &Beside<'_>,
) -> Result<Vec<Vec<u8>>, IoError> {
    let mut out = Vec::new();
    for buffer in gltf.document.buffers() {
        let at = |kind| IoError::element(name, "buffer", buffer.index() as u64, kind);
        let bytes = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or_else(|| at(ErrorKind::Syntax("no binary chunk to read".into())))?,
            gltf::buffer::Source::Uri(uri) => {
                uri_bytes(uri, beside).map_err(|e| at(ErrorKind::Syntax(e)))?
            }
        };
        if bytes.len() < buffer.length() {
            return Err(at(ErrorKind::Syntax(format!(
                "{} bytes long, but its byteLength says {}",
                bytes.len(),
                buffer.length()
            ))));
        }
        out.push(bytes);
    }
    Ok(out)
}

/// The bytes a URI names: a base64 data URI, or a file relative to the glTF file.
fn uri_bytes(uri: &str, beside: &Beside<'_>) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, data) = rest
            .split_once(";base64,")
            .ok_or_else(|| format!("data URI `{}…` is not base64", short(uri)))?;
        return base64::engine::general_purpose::STANDARD
            .decode(data)
            .map_err(|e| format!("data URI: {e}"));
    }
    let Some(dir) = beside.0 else {
        return Err(format!(
            "refers to the file `{}`, which can only be found when the glTF file is read by path",
            short(uri)
        ));
    };
    let relative = percent_decode(uri);
    let scheme = relative
        .split_once(':')
        .is_some_and(|(s, _)| !s.is_empty() && !s.contains('/'));
    if scheme || Path::new(&relative).is_absolute() || relative.starts_with('/') {
        return Err(format!(
            "refers to `{}`: only data URIs and paths relative to the glTF file are read",
            short(uri)
        ));
    }
    let path = dir.join(relative);
    std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))
}

/// At most 60 characters of `s`, for messages.
fn short(s: &str) -> String {
    s.chars().take(60).collect()
}

/// `uri` with its `%XX` escapes decoded (relative URIs name files).
fn percent_decode(uri: &str) -> String {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        if b[i] == b'%'
            && i + 2 < b.len()
            && let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2]))
        {
            out.push((h * 16 + l) as u8);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Every mesh instance of the scene with its world transform (only those of the mesh
/// called `only`, when given); skins are refused.
fn instances<'a>(doc: &'a gltf::Document, only: Option<&str>) -> Result<Vec<Instance<'a>>, String> {
    let wanted = |m: &gltf::Mesh<'_>| only.is_none_or(|n| m.name() == Some(n));
    let roots: Vec<gltf::Node<'a>> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            return Ok(doc
                .meshes()
                .filter(wanted)
                .map(|mesh| Instance {
                    mesh,
                    matrix: IDENTITY,
                })
                .collect());
        }
    };
    let mut out = Vec::new();
    let mut stack: Vec<(gltf::Node<'a>, [[f64; 4]; 4], usize)> =
        roots.into_iter().map(|n| (n, IDENTITY, 0)).collect();
    let n_nodes = doc.nodes().len();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > n_nodes {
            return Err("a node hierarchy that loops back on itself".into());
        }
        let matrix = mul(
            &parent,
            &node.transform().matrix().map(|c| c.map(f64::from)),
        );
        if let Some(mesh) = node.mesh() {
            if node.skin().is_some() {
                return Err(format!("skins (node {} is skinned)", node.index()));
            }
            if wanted(&mesh) {
                out.push(Instance { mesh, matrix });
            }
        }
        for child in node.children() {
            stack.push((child, matrix, depth + 1));
        }
    }
    // Instances in node order of a depth-first walk from the first root.
    out.reverse();
    Ok(out)
}

const IDENTITY: [[f64; 4]; 4] = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

/// `a · b` for column-major 4×4 matrices.
fn mul(a: &[[f64; 4]; 4], b: &[[f64; 4]; 4]) -> [[f64; 4]; 4] {
    let mut out = [[0.0; 4]; 4];
    for (c, col) in out.iter_mut().enumerate() {
        for (r, x) in col.iter_mut().enumerate() {
            *x = (0..4).map(|k| a[k][r] * b[c][k]).sum();
        }
    }
    out
}

/// The mesh names, for the message when the named one is missing.
fn mesh_names(doc: &gltf::Document) -> String {
    let names: Vec<String> = doc
        .meshes()
        .map(|m| match m.name() {
            Some(n) => format!("`{n}`"),
            None => format!("#{} (unnamed)", m.index()),
        })
        .collect();
    if names.is_empty() {
        "none".into()
    } else {
        names.join(", ")
    }
}

/// Adds one primitive's triangles (transformed, welded) and corner values to `g`.
fn primitive(
    g: &mut Gathered,
    prim: &gltf::Primitive<'_>,
    inst: &Instance<'_>,
    buffers: &[Vec<u8>],
    name: &str,
    opts: &ReadOptions,
) -> Result<(), IoError> {
    let mesh = inst.mesh.index();
    let at = |kind| IoError::element(name, "mesh", mesh as u64, kind);
    check_drawn_as_triangles(prim, inst).map_err(at)?;
    let attrs = read_attributes(g, prim, buffers, name, &at)?;
    check_attribute_shapes(prim, &attrs).map_err(at)?;
    let n = attrs.positions.count;
    let indices = read_indices(prim, n, buffers, name, &at)?;
    check_limits(g, n, indices.len() / 3, name, opts)?;
    let local = weld_positions(g, &attrs.positions, &inst.matrix);
    add_triangles(g, prim, &inst.matrix, &attrs, &indices, &local);
    g.glb_vertices += n;
    Ok(())
}

/// The vertex attributes read of one primitive.
struct PrimitiveAttributes {
    positions: Read,
    normals: Option<Read>,
    uvs: Option<Read>,
    colors: Option<Read>,
}

/// Refuses a primitive that is not a plain triangle list: other modes, morph targets.
fn check_drawn_as_triangles(
    prim: &gltf::Primitive<'_>,
    inst: &Instance<'_>,
) -> Result<(), ErrorKind> {
    if prim.mode() != Mode::Triangles {
        return Err(ErrorKind::Unsupported(format!(
            "primitive {} is drawn as {:?}; only triangle lists are read",
            prim.index(),
            prim.mode()
        )));
    }
    if prim.morph_targets().len() > 0 || inst.mesh.weights().is_some() {
        return Err(ErrorKind::Unsupported(format!(
            "morph targets (primitive {})",
            prim.index()
        )));
    }
    Ok(())
}

/// Reads the primitive's `POSITION` (required), `NORMAL`, `TEXCOORD_0` and `COLOR_0`, and
/// notes its other attribute sets in `g` as ignored.
fn read_attributes(
    g: &mut Gathered,
    prim: &gltf::Primitive<'_>,
    buffers: &[Vec<u8>],
    name: &str,
    at: &impl Fn(ErrorKind) -> IoError,
) -> Result<PrimitiveAttributes, IoError> {
    let mut positions = None;
    let mut normals = None;
    let mut uvs = None;
    let mut colors = None;
    for (semantic, acc) in prim.attributes() {
        match semantic {
            Semantic::Positions => positions = Some(read_accessor(&acc, buffers, name)?),
            Semantic::Normals => normals = Some(read_accessor(&acc, buffers, name)?),
            Semantic::TexCoords(0) => uvs = Some(read_accessor(&acc, buffers, name)?),
            Semantic::Colors(0) => colors = Some(read_accessor(&acc, buffers, name)?),
            other => {
                let s = other.to_string();
                if !g.ignored.contains(&s) {
                    g.ignored.push(s);
                }
            }
        }
    }
    let positions = positions.ok_or_else(|| {
        at(ErrorKind::Syntax(format!(
            "primitive {} has no POSITION",
            prim.index()
        )))
    })?;
    Ok(PrimitiveAttributes {
        positions,
        normals,
        uvs,
        colors,
    })
}

/// Checks that every attribute has an allowed number of components per element and one
/// element per position.
fn check_attribute_shapes(
    prim: &gltf::Primitive<'_>,
    attrs: &PrimitiveAttributes,
) -> Result<(), ErrorKind> {
    let n = attrs.positions.count;
    let shapes: [(&str, Option<&Read>, &[usize]); 4] = [
        ("POSITION", Some(&attrs.positions), &[3]),
        ("NORMAL", attrs.normals.as_ref(), &[3]),
        ("TEXCOORD_0", attrs.uvs.as_ref(), &[2]),
        ("COLOR_0", attrs.colors.as_ref(), &[3, 4]),
    ];
    for (what, a, dims) in shapes {
        if let Some(a) = a
            && !dims.contains(&a.dims)
        {
            return Err(ErrorKind::Syntax(format!(
                "primitive {}: {what} has {} components per element, not {dims:?}",
                prim.index(),
                a.dims
            )));
        }
    }
    for (what, a) in [
        ("NORMAL", &attrs.normals),
        ("TEXCOORD_0", &attrs.uvs),
        ("COLOR_0", &attrs.colors),
    ] {
        if let Some(a) = a
            && a.count != n
        {
            return Err(ErrorKind::Syntax(format!(
                "primitive {}: {what} has {} elements for {n} positions",
                prim.index(),
                a.count
            )));
        }
    }
    Ok(())
}

/// The primitive's triangle corners as indices into its `n` vertices (`0..n` when it has
/// no indices), checked to make whole triangles of existing vertices.
fn read_indices(
    prim: &gltf::Primitive<'_>,
    n: usize,
    buffers: &[Vec<u8>],
    name: &str,
    at: &impl Fn(ErrorKind) -> IoError,
) -> Result<Vec<u64>, IoError> {
    let indices = match prim.indices() {
        Some(acc) => {
            let a = read_accessor(&acc, buffers, name)?;
            if a.dims != 1 {
                return Err(at(ErrorKind::Syntax(format!(
                    "primitive {}: its indices have {} components per element, not 1",
                    prim.index(),
                    a.dims
                ))));
            }
            a.values.iter().map(|&x| x as u64).collect::<Vec<u64>>()
        }
        None => (0..n as u64).collect(),
    };
    if !indices.len().is_multiple_of(3) {
        return Err(at(ErrorKind::Syntax(format!(
            "primitive {}: {} indices do not make whole triangles",
            prim.index(),
            indices.len()
        ))));
    }
    if let Some(&bad) = indices.iter().find(|&&i| i >= n as u64) {
        return Err(at(ErrorKind::Syntax(format!(
            "primitive {}: index {bad} but only {n} vertices",
            prim.index()
        ))));
    }
    Ok(indices)
}

/// The mesh vertex of each of the primitive's vertices, its position transformed by `m`
/// and welded into `g`.
fn weld_positions(g: &mut Gathered, positions: &Read, m: &[[f64; 4]; 4]) -> Vec<u32> {
    (0..positions.count)
        .map(|i| {
            let p = positions.vec3(i);
            weld(g, transform_point(m, p))
        })
        .collect()
}

/// Adds the primitive's triangles to `g` (turned around under a mirroring transform `m`),
/// with their material and the values of their corners.
fn add_triangles(
    g: &mut Gathered,
    prim: &gltf::Primitive<'_>,
    m: &[[f64; 4]; 4],
    attrs: &PrimitiveAttributes,
    indices: &[u64],
    local: &[u32],
) {
    let flip = det3(m) < 0.0;
    let normal_matrix = inverse_transpose3(m);
    let material = prim.material().index().map_or(u32::MAX, |i| i as u32);
    for tri in indices.chunks_exact(3) {
        let tri = if flip {
            [tri[0], tri[2], tri[1]]
        } else {
            [tri[0], tri[1], tri[2]]
        };
        g.faces.push(tri.map(|i| local[i as usize]));
        g.face_material.push(material);
        for &i in &tri {
            corner(
                g,
                i as usize,
                &attrs.normals,
                &attrs.uvs,
                &attrs.colors,
                &normal_matrix,
            );
        }
    }
}

/// A texture coordinate's `v` between glTF's origin (the image's top left) and the `uv`
/// column's (its bottom left), either way.
pub(crate) fn flip_v(v: f64) -> f64 {
    1.0 - v
}

/// Records one corner's values (zero where the primitive lacks the attribute).
fn corner(
    g: &mut Gathered,
    i: usize,
    normals: &Option<Read>,
    uvs: &Option<Read>,
    colors: &Option<Read>,
    normal_matrix: &[[f64; 3]; 3],
) {
    let mark = |slot: usize, present: bool, g: &mut Gathered| {
        if present {
            g.has[slot] = true;
        } else {
            g.missing[slot] += 1;
        }
    };
    mark(UV, uvs.is_some(), g);
    g.uv.push(uvs.as_ref().map_or(DVec2::ZERO, |a| {
        DVec2::new(a.values[2 * i], flip_v(a.values[2 * i + 1]))
    }));
    mark(NORMAL, normals.is_some(), g);
    g.normal.push(normals.as_ref().map_or(DVec3::ZERO, |a| {
        let n = a.vec3(i);
        if *normal_matrix == IDENTITY3 {
            n
        } else {
            let m = normal_matrix;
            DVec3::new(
                m[0][0] * n.x + m[1][0] * n.y + m[2][0] * n.z,
                m[0][1] * n.x + m[1][1] * n.y + m[2][1] * n.z,
                m[0][2] * n.x + m[1][2] * n.y + m[2][2] * n.z,
            )
            .normalize_or_zero()
        }
    }));
    mark(COLOR, colors.is_some(), g);
    let dims = colors.as_ref().map_or(0, |a| a.dims);
    mark(ALPHA, dims == 4, g);
    g.color.push(colors.as_ref().map_or([0; 3], |a| {
        let c = |k: usize| (a.values[dims * i + k].clamp(0.0, 1.0) * 255.0).round() as u8;
        [c(0), c(1), c(2)]
    }));
    g.alpha.push(match colors {
        Some(a) if dims == 4 => (a.values[4 * i + 3].clamp(0.0, 1.0) * 255.0).round(),
        _ => 255.0,
    });
}

const IDENTITY3: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// The vertex of `p`, welded to an earlier one at bit for bit the same position.
fn weld(g: &mut Gathered, p: DVec3) -> u32 {
    let key = (p + DVec3::ZERO).to_array().map(f64::to_bits); // -0.0 + 0.0 = 0.0
    let next = g.positions.len() as u32;
    let v = *g.weld.entry(key).or_insert(next);
    if v == next {
        g.positions.push(p);
    }
    v
}

/// Refuses files beyond [`ReadOptions`]' limits (glTF vertices count, as the file has
/// them before welding) and beyond 32-bit indices.
fn check_limits(
    g: &Gathered,
    n: usize,
    triangles: usize,
    name: &str,
    opts: &ReadOptions,
) -> Result<(), IoError> {
    let vertices = g.glb_vertices + n;
    let faces = g.faces.len() + triangles;
    if let Some(limit) = opts.max_vertices
        && vertices > limit
    {
        return Err(IoError::file(name, ErrorKind::over_limit_vertices(limit)));
    }
    if let Some(limit) = opts.max_faces
        && faces > limit
    {
        return Err(IoError::file(name, ErrorKind::over_limit_faces(limit)));
    }
    if vertices > u32::MAX as usize || 3 * faces > u32::MAX as usize {
        return Err(IoError::file(
            name,
            ErrorKind::TooMany {
                count: faces as u64,
                what: "faces",
            },
        ));
    }
    Ok(())
}

fn transform_point(m: &[[f64; 4]; 4], p: DVec3) -> DVec3 {
    if *m == IDENTITY {
        return p;
    }
    let r = |k: usize| m[0][k] * p.x + m[1][k] * p.y + m[2][k] * p.z + m[3][k];
    DVec3::new(r(0), r(1), r(2))
}

fn det3(m: &[[f64; 4]; 4]) -> f64 {
    let c = |i: usize| DVec3::new(m[i][0], m[i][1], m[i][2]);
    c(0).dot(c(1).cross(c(2)))
}

/// The inverse transpose of the 3×3 part (column-major), up to a positive scale: the
/// cofactor matrix, signed by the determinant.
fn inverse_transpose3(m: &[[f64; 4]; 4]) -> [[f64; 3]; 3] {
    if *m == IDENTITY {
        return IDENTITY3;
    }
    let c = |i: usize| DVec3::new(m[i][0], m[i][1], m[i][2]);
    let (a, b, d) = (c(0), c(1), c(2));
    let s = det3(m).signum();
    // Columns of the cofactor matrix are the cross products of the other two columns.
    [b.cross(d), d.cross(a), a.cross(b)].map(|v| (v * s).to_array())
}

/// An accessor's values, as `f64`, `dims` per element.
struct Read {
    values: Vec<f64>,
    dims: usize,
    count: usize,
}

impl Read {
    fn vec3(&self, i: usize) -> DVec3 {
        DVec3::new(
            self.values[3 * i],
            self.values[3 * i + 1],
            self.values[3 * i + 2],
        )
    }
}

/// Reads accessor `acc` (sparse or not) with every byte range checked; normalized
/// integers become `[0, 1]` / `[-1, 1]`.
fn read_accessor(
    acc: &gltf::Accessor<'_>,
    buffers: &[Vec<u8>],
    name: &str,
) -> Result<Read, IoError> {
    let at = |msg: String| {
        IoError::element(name, "accessor", acc.index() as u64, ErrorKind::Syntax(msg))
    };
    let dims = match acc.dimensions() {
        Dimensions::Scalar => 1,
        Dimensions::Vec2 => 2,
        Dimensions::Vec3 => 3,
        Dimensions::Vec4 => 4,
        other => {
            return Err(at(format!(
                "a {other:?} accessor is not a vertex attribute"
            )));
        }
    };
    let ty = acc.data_type();
    let elem = dims * ty.size();
    let count = acc.count();
    let mut values = Vec::new();
    match acc.view() {
        Some(view) => {
            let data = view_bytes(&view, buffers).ok_or_else(|| {
                at(format!(
                    "buffer view {} lies outside its buffer",
                    view.index()
                ))
            })?;
            let stride = view.stride().unwrap_or(elem).max(elem);
            read_elements(
                data,
                acc.offset(),
                stride,
                count,
                dims,
                ty,
                acc.normalized(),
                &mut values,
            )
            .map_err(at)?;
        }
        None => values.resize(count.min(1 << 28) * dims, 0.0),
    }
    if values.len() != count * dims {
        return Err(at(format!("{count} elements do not fit")));
    }
    if let Some(sparse) = acc.sparse() {
        apply_sparse(&sparse, buffers, dims, ty, acc.normalized(), &mut values).map_err(at)?;
    }
    if let Some(bad) = values.iter().find(|x| !x.is_finite()) {
        return Err(at(format!(
            "holds a value that is {}",
            crate::text::non_finite_name(*bad)
        )));
    }
    Ok(Read {
        values,
        dims,
        count,
    })
}

/// The bytes of a buffer view, if they lie inside its buffer.
fn view_bytes<'b>(view: &gltf::buffer::View<'_>, buffers: &'b [Vec<u8>]) -> Option<&'b [u8]> {
    let buffer = buffers.get(view.buffer().index())?;
    buffer.get(view.offset()..view.offset().checked_add(view.length())?)
}

/// Appends `count` elements of `dims` components of type `ty`, `stride` bytes apart from
/// `offset` in `data`.
#[allow(clippy::too_many_arguments)]
fn read_elements(
    data: &[u8],
    offset: usize,
    stride: usize,
    count: usize,
    dims: usize,
    ty: DataType,
    normalized: bool,
    out: &mut Vec<f64>,
) -> Result<(), String> {
    if count == 0 {
        return Ok(());
    }
    let elem = dims * ty.size();
    let end = (count - 1)
        .checked_mul(stride)
        .and_then(|x| x.checked_add(offset))
        .and_then(|x| x.checked_add(elem));
    if end.is_none_or(|e| e > data.len()) {
        return Err(format!(
            "{count} elements of {elem} bytes, {stride} apart from byte {offset}, do not fit its {} bytes",
            data.len()
        ));
    }
    out.reserve(count * dims);
    for i in 0..count {
        let at = offset + i * stride;
        for k in 0..dims {
            let s = at + k * ty.size();
            out.push(component(&data[s..s + ty.size()], ty, normalized));
        }
    }
    Ok(())
}

/// One little-endian component, as glTF defines its value.
fn component(b: &[u8], ty: DataType, normalized: bool) -> f64 {
    match ty {
        DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        DataType::U8 if normalized => b[0] as f64 / 255.0,
        DataType::U8 => b[0] as f64,
        DataType::I8 if normalized => (b[0] as i8 as f64 / 127.0).max(-1.0),
        DataType::I8 => b[0] as i8 as f64,
        DataType::U16 if normalized => u16::from_le_bytes([b[0], b[1]]) as f64 / 65535.0,
        DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
        DataType::I16 if normalized => {
            (i16::from_le_bytes([b[0], b[1]]) as f64 / 32767.0).max(-1.0)
        }
        DataType::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
        DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
    }
}

/// Overwrites the elements a sparse accessor names.
fn apply_sparse(
    sparse: &gltf::accessor::sparse::Sparse<'_>,
    buffers: &[Vec<u8>],
    dims: usize,
    ty: DataType,
    normalized: bool,
    values: &mut [f64],
) -> Result<(), String> {
    let n = sparse.count();
    let idx_view = sparse.indices().view();
    let idx_data = view_bytes(&idx_view, buffers).ok_or("sparse indices outside their buffer")?;
    let idx_ty = match sparse.indices().index_type() {
        gltf::accessor::sparse::IndexType::U8 => DataType::U8,
        gltf::accessor::sparse::IndexType::U16 => DataType::U16,
        gltf::accessor::sparse::IndexType::U32 => DataType::U32,
    };
    let mut idx = Vec::new();
    read_elements(
        idx_data,
        sparse.indices().offset(),
        idx_ty.size(),
        n,
        1,
        idx_ty,
        false,
        &mut idx,
    )?;
    let val_view = sparse.values().view();
    let val_data = view_bytes(&val_view, buffers).ok_or("sparse values outside their buffer")?;
    let mut vals = Vec::new();
    let elem = dims * ty.size();
    read_elements(
        val_data,
        sparse.values().offset(),
        elem,
        n,
        dims,
        ty,
        normalized,
        &mut vals,
    )?;
    let count = values.len() / dims.max(1);
    for (k, &i) in idx.iter().enumerate() {
        let i = i as usize;
        if i >= count {
            return Err(format!("sparse index {i} but only {count} elements"));
        }
        values[dims * i..dims * (i + 1)].copy_from_slice(&vals[dims * k..dims * (k + 1)]);
    }
    Ok(())
}

/// Notes on what the document has that is not read.
fn document_notes(doc: &gltf::Document, g: &Gathered) -> Vec<String> {
    let mut notes = Vec::new();
    if !g.ignored.is_empty() {
        notes.push(format!(
            "vertex attributes not read: {}",
            g.ignored.join(", ")
        ));
    }
    for (slot, what) in [(UV, "TEXCOORD_0"), (NORMAL, "NORMAL"), (COLOR, "COLOR_0")] {
        if g.has[slot] && g.missing[slot] > 0 {
            notes.push(format!(
                "{} triangle corners of primitives without {what} got zero",
                g.missing[slot]
            ));
        }
    }
    let scenes = doc.scenes().len();
    if scenes > 1 {
        notes.push(format!(
            "{} other scenes ignored (only the default scene is read)",
            scenes - 1
        ));
    }
    let mut in_scene = vec![false; doc.meshes().len()];
    g.instanced.iter().for_each(|&m| in_scene[m] = true);
    let outside = in_scene.iter().filter(|&&x| !x).count();
    if outside > 0 && g.named.is_none() && doc.scenes().len() > 0 {
        notes.push(format!(
            "{outside} meshes that no node of the scene shows ignored"
        ));
    }
    let animations = doc.animations().len();
    if animations > 0 {
        notes.push(format!("{animations} animations ignored"));
    }
    let cameras = doc.cameras().len();
    if cameras > 0 {
        notes.push(format!("{cameras} cameras ignored"));
    }
    if g.glb_vertices > g.positions.len() {
        notes.push(format!(
            "{} glTF vertices welded into {} vertices at equal positions (their UVs, normals and colours kept per corner)",
            g.glb_vertices,
            g.positions.len()
        ));
    }
    notes
}

/// The document's materials, textures, samplers and images, images' data read.
fn materials(
    raw: &Value,
    buffers: &[Vec<u8>],
    beside: &Beside<'_>,
    notes: &mut Vec<String>,
) -> Materials {
    let keys = ["materials", "textures", "samplers", "images"];
    if keys.iter().all(|k| raw.get(*k).is_none()) {
        return Materials::default();
    }
    let mut obj = Map::new();
    for k in keys {
        if let Some(v) = raw.get(k) {
            obj.insert(k.to_string(), v.clone());
        }
    }
    let mut images = Vec::new();
    if let Some(list) = obj.get_mut("images").and_then(Value::as_array_mut) {
        for (i, img) in list.iter_mut().enumerate() {
            images.push(image(img, raw, buffers, beside, i, notes));
        }
    }
    // The extensions the kept part of the document uses, to be declared again.
    let text = Value::Object(obj.clone()).to_string();
    let used: Vec<Value> = raw
        .get("extensionsUsed")
        .and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .filter(|e| {
                    e.as_str()
                        .is_some_and(|e| text.contains(&format!("\"{e}\"")))
                })
                .cloned()
                .collect()
        })
        .unwrap_or_default();
    if !used.is_empty() {
        obj.insert("extensionsUsed".into(), Value::Array(used));
    }
    Materials {
        json: Value::Object(obj).to_string(),
        images,
    }
}

/// One image: its data out of the JSON (`bufferView` and data URIs removed), a relative
/// URI kept.
fn image(
    img: &mut Value,
    raw: &Value,
    buffers: &[Vec<u8>],
    beside: &Beside<'_>,
    index: usize,
    notes: &mut Vec<String>,
) -> Image {
    let Some(o) = img.as_object_mut() else {
        return Image::default();
    };
    let mime_type = o
        .get("mimeType")
        .and_then(Value::as_str)
        .map(str::to_string);
    let mut out = Image {
        mime_type,
        ..Image::default()
    };
    if let Some(view) = o.remove("bufferView").and_then(|v| v.as_u64()) {
        out.bytes = raw
            .get("bufferViews")
            .and_then(|v| v.get(view as usize))
            .and_then(|v| {
                let b = buffers.get(v.get("buffer")?.as_u64()? as usize)?;
                let off = v.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
                let len = v.get("byteLength")?.as_u64()? as usize;
                b.get(off..off.checked_add(len)?).map(<[u8]>::to_vec)
            });
    } else if let Some(uri) = o.get("uri").and_then(Value::as_str).map(str::to_string) {
        if uri.starts_with("data:") {
            o.remove("uri");
            out.bytes = uri_bytes(&uri, beside).ok();
        } else {
            out.bytes = uri_bytes(&uri, beside).ok();
            if out.bytes.is_none() {
                notes.push(format!(
                    "image {index} (`{}`) not found beside the file: only its URI is kept",
                    short(&uri)
                ));
            }
            out.uri = Some(uri);
        }
    }
    o.remove("mimeType");
    out
}

/// The mesh: welded positions, faces, corner values as vertex columns or wedges, the
/// material column, the materials.
fn build(g: Gathered, materials: Materials) -> Mesh {
    let mut cols = Attributes::default();
    if g.has[UV] {
        cols.insert("uv", AttrValues::Vec2(g.uv));
    }
    if g.has[NORMAL] {
        cols.insert("normal", AttrValues::Vec3(g.normal));
    }
    if g.has[COLOR] {
        cols.insert("color", AttrValues::Color(g.color));
    }
    if g.has[ALPHA] {
        cols.insert("alpha", AttrValues::Scalar(g.alpha));
    }
    let mut mesh = Mesh::new(g.positions, g.faces).with_corner_attributes(cols);
    if g.face_material.iter().any(|&m| m != 0) && !materials.is_empty() {
        mesh.face_attrs
            .insert(MATERIAL, AttrValues::Label(g.face_material));
    }
    mesh.materials = materials;
    mesh
}
