//! glTF 2.0 writing, by hand: one mesh on one node, a primitive per material, one buffer
//! (the GLB's binary chunk, or a base64 data URI in a `.gltf`).
//!
//! A glTF vertex is a wedge (or a vertex, without wedges): `POSITION` (`f32`, with its
//! bounds), `NORMAL` (`f32`, made unit length as the format requires), `TEXCOORD_0`
//! (`f32`, `v` turned to glTF's origin at the image's top left: `1 − v`) and `COLOR_0`
//! (normalized `u8`, RGB or RGBA with an `alpha` column) from the columns `normal`, `uv`,
//! `color`. Indices are `u16` below 65,535 glTF vertices, else
//! `u32`. The materials, textures, samplers and images the mesh carries are written back
//! as they were read: image bytes embedded in a GLB (or kept as the same relative URI
//! when only that is known), in a `.gltf` the same URI or a data URI.

use crate::error::ErrorKind;
use base64::Engine as _;
use coarsen_mesh::material::MATERIAL;
use coarsen_mesh::{AttrValues, DVec3, Index, Materials, Mesh};
use serde_json::{Map, Value, json};
use std::io::Write;

/// glTF's `componentType` codes.
const UNSIGNED_BYTE: u32 = 5121;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const FLOAT: u32 = 5126;
/// glTF's `bufferView.target` codes.
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// The document under construction: its binary buffer and its arrays.
#[derive(Default)]
struct Doc {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Doc {
    /// Appends `bytes` as a buffer view (4-byte aligned); returns its index.
    fn view(&mut self, bytes: &[u8], stride: Option<usize>, target: Option<u32>) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()});
        if let Some(s) = stride {
            v["byteStride"] = json!(s);
        }
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(v);
        self.views.len() - 1
    }

    /// Adds an accessor; returns its index.
    fn accessor(&mut self, mut a: Value) -> usize {
        if a.get("byteOffset").is_none() {
            a["byteOffset"] = json!(0);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    /// `f32` vectors of `N` components as a vertex attribute; returns the accessor.
    fn floats<const N: usize>(&mut self, values: &[[f32; N]], bounds: bool) -> usize {
        let bytes: Vec<u8> = values
            .iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let view = self.view(&bytes, None, Some(ARRAY_BUFFER));
        let ty = ["SCALAR", "VEC2", "VEC3", "VEC4"][N - 1];
        let mut a = json!({
            "bufferView": view,
            "componentType": FLOAT,
            "count": values.len(),
            "type": ty,
        });
        if bounds {
            let mut lo = [f32::INFINITY; N];
            let mut hi = [f32::NEG_INFINITY; N];
            for v in values {
                for k in 0..N {
                    lo[k] = lo[k].min(v[k]);
                    hi[k] = hi[k].max(v[k]);
                }
            }
            a["min"] = json!(lo.to_vec());
            a["max"] = json!(hi.to_vec());
        }
        self.accessor(a)
    }
}

/// Writes `mesh` as glTF: GLB when `binary`, else a `.gltf` JSON file with its buffer
/// embedded.
pub(crate) fn write(
    mesh: &Mesh,
    w: &mut impl Write,
    binary: bool,
    attributes: bool,
) -> Result<(), ErrorKind> {
    if mesh.n_faces() == 0 {
        return Err(ErrorKind::Unsupported(
            "a glTF mesh needs at least one triangle".into(),
        ));
    }
    if !attributes {
        let bare = Mesh::new(mesh.positions.clone(), mesh.faces.clone());
        return write(&bare, w, binary, true);
    }
    let (sources, corners) = gltf_vertices(mesh);
    let mut doc = Doc::default();
    let mut attributes = Map::new();
    let positions: Vec<[f32; 3]> = sources
        .iter()
        .map(|&v| mesh.positions[v as usize].to_array().map(|x| x as f32))
        .collect();
    attributes.insert("POSITION".into(), json!(doc.floats(&positions, true)));
    if let Some(AttrValues::Vec3(n)) = column(mesh, "normal", &sources) {
        let n: Vec<[f32; 3]> = n.iter().map(|&n| unit(n)).collect();
        attributes.insert("NORMAL".into(), json!(doc.floats(&n, false)));
    }
    if let Some(AttrValues::Vec2(t)) = column(mesh, "uv", &sources) {
        let t: Vec<[f32; 2]> = t
            .iter()
            .map(|t| [t.x as f32, crate::gltf_read::flip_v(t.y) as f32])
            .collect();
        attributes.insert("TEXCOORD_0".into(), json!(doc.floats(&t, false)));
    }
    if let Some(AttrValues::Color(c)) = column(mesh, "color", &sources) {
        let alpha = match column(mesh, "alpha", &sources) {
            Some(AttrValues::Scalar(a)) => Some(a),
            _ => None,
        };
        attributes.insert(
            "COLOR_0".into(),
            json!(colors(&mut doc, &c, alpha.as_deref())),
        );
    }
    let has_uv = attributes.contains_key("TEXCOORD_0");
    let (materials, n_materials) = material_arrays(&mesh.materials, &mut doc, binary, has_uv)?;
    let primitives = primitives(
        mesh,
        &corners,
        sources.len(),
        &attributes,
        n_materials,
        &mut doc,
    );
    let mut root = json!({
        "asset": {"version": "2.0", "generator": "coarsen"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": primitives}],
    });
    let r = root.as_object_mut().expect("an object");
    for (k, v) in materials {
        r.insert(k, v);
    }
    while !doc.bin.len().is_multiple_of(4) {
        doc.bin.push(0);
    }
    r.insert(
        "accessors".into(),
        Value::Array(std::mem::take(&mut doc.accessors)),
    );
    r.insert(
        "bufferViews".into(),
        Value::Array(std::mem::take(&mut doc.views)),
    );
    let mut buffer = json!({"byteLength": doc.bin.len()});
    if !binary {
        buffer["uri"] = json!(format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&doc.bin)
        ));
    }
    r.insert("buffers".into(), json!([buffer]));
    let text = serde_json::to_vec(&root).map_err(|e| ErrorKind::Syntax(e.to_string()))?;
    if binary {
        glb(w, &text, &doc.bin)?;
    } else {
        w.write_all(&text)?;
        w.write_all(b"\n")?;
    }
    Ok(())
}

/// The glTF vertices (the source vertex of each) and each face corner's glTF vertex:
/// one per wedge, or one per vertex without wedges.
fn gltf_vertices(mesh: &Mesh) -> (Vec<Index>, Vec<Index>) {
    if mesh.wedges.is_empty() {
        let all = (0..mesh.n_vertices() as Index).collect();
        return (all, mesh.faces.iter().flatten().copied().collect());
    }
    (
        mesh.wedges.vertices().to_vec(),
        mesh.wedges.corners().to_vec(),
    )
}

/// Column `name` at every glTF vertex: the wedges' when they hold it, else the vertex
/// column's at each glTF vertex's vertex.
fn column(mesh: &Mesh, name: &str, sources: &[Index]) -> Option<AttrValues> {
    if let Some(v) = mesh.wedges.attrs().get(name) {
        return Some(v.clone());
    }
    Some(mesh.vertex_attrs.get(name)?.gather(sources))
}

/// `n` as `f32`, made unit length when it is not already (to the format's tolerance).
fn unit(n: DVec3) -> [f32; 3] {
    let f = n.to_array().map(|x| x as f32);
    let len2: f32 = f.iter().map(|x| x * x).sum();
    if (len2 - 1.0).abs() <= 1e-5 {
        return f;
    }
    match n.try_normalize() {
        Some(u) => u.to_array().map(|x| x as f32),
        None => [0.0, 0.0, 1.0],
    }
}

/// Colours as normalized `u8` (RGB padded to 4 bytes, or RGBA with `alpha`, 0–255).
fn colors(doc: &mut Doc, c: &[[u8; 3]], alpha: Option<&[f64]>) -> usize {
    let mut bytes = Vec::with_capacity(4 * c.len());
    for (i, rgb) in c.iter().enumerate() {
        bytes.extend_from_slice(rgb);
        bytes.push(alpha.map_or(0, |a| a[i].round().clamp(0.0, 255.0) as u8));
    }
    let view = doc.view(&bytes, Some(4), Some(ARRAY_BUFFER));
    doc.accessor(json!({
        "bufferView": view,
        "componentType": UNSIGNED_BYTE,
        "normalized": true,
        "count": c.len(),
        "type": if alpha.is_some() { "VEC4" } else { "VEC3" },
    }))
}

/// One primitive per material the faces use (in material order; faces without one, or
/// naming one that does not exist, in a primitive without material).
fn primitives(
    mesh: &Mesh,
    corners: &[Index],
    n_vertices: usize,
    attributes: &Map<String, Value>,
    n_materials: usize,
    doc: &mut Doc,
) -> Vec<Value> {
    let material_of = |f: usize| -> Option<u32> {
        if n_materials == 0 {
            return None;
        }
        let m = mesh.face_attrs.label(MATERIAL).map_or(0, |l| l[f]);
        ((m as usize) < n_materials).then_some(m)
    };
    let mut groups: Vec<(Option<u32>, Vec<Index>)> = Vec::new();
    for f in 0..mesh.n_faces() {
        let m = material_of(f);
        let corners = &corners[3 * f..3 * f + 3];
        match groups.iter_mut().find(|(g, _)| *g == m) {
            Some((_, list)) => list.extend_from_slice(corners),
            None => groups.push((m, corners.to_vec())),
        }
    }
    groups.sort_by_key(|(m, _)| m.map_or(u64::MAX, u64::from));
    groups
        .into_iter()
        .map(|(m, idx)| {
            let accessor = indices(doc, &idx, n_vertices);
            let mut p = json!({"attributes": attributes, "indices": accessor, "mode": 4});
            if let Some(m) = m {
                p["material"] = json!(m);
            }
            p
        })
        .collect()
}

/// An index accessor: `u16` when every index fits below 65,535 (the restart value), else
/// `u32`.
fn indices(doc: &mut Doc, idx: &[Index], n_vertices: usize) -> usize {
    let (bytes, ty): (Vec<u8>, u32) = if n_vertices < 65535 {
        let b = idx.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect();
        (b, UNSIGNED_SHORT)
    } else {
        (
            idx.iter().flat_map(|&i| i.to_le_bytes()).collect(),
            UNSIGNED_INT,
        )
    };
    let view = doc.view(&bytes, None, Some(ELEMENT_ARRAY_BUFFER));
    doc.accessor(json!({
        "bufferView": view,
        "componentType": ty,
        "count": idx.len(),
        "type": "SCALAR",
    }))
}

/// The carried materials' top-level arrays (images embedded in the binary buffer for a
/// GLB, as data URIs in a `.gltf` when they have no URI) and how many materials there are.
fn material_arrays(
    m: &Materials,
    doc: &mut Doc,
    binary: bool,
    has_uv: bool,
) -> Result<(Map<String, Value>, usize), ErrorKind> {
    if m.is_empty() {
        return Ok((Map::new(), 0));
    }
    let parsed: Value = serde_json::from_str(&m.json)
        .map_err(|e| ErrorKind::Syntax(format!("the carried materials are not JSON: {e}")))?;
    let Value::Object(mut arrays) = parsed else {
        return Err(ErrorKind::Syntax(
            "the carried materials are not a JSON object".into(),
        ));
    };
    if let Some(list) = arrays.get_mut("images").and_then(Value::as_array_mut) {
        for (img, data) in list.iter_mut().zip(&m.images) {
            let Some(o) = img.as_object_mut() else {
                continue;
            };
            let mime = data.mime_type.clone().or_else(|| {
                data.bytes
                    .as_deref()
                    .and_then(sniff_mime)
                    .map(str::to_string)
            });
            match (&data.bytes, &data.uri, binary) {
                (Some(bytes), _, true) if mime.is_some() => {
                    o.remove("uri");
                    o.insert("bufferView".into(), json!(doc.view(bytes, None, None)));
                    o.insert("mimeType".into(), json!(mime));
                }
                (_, Some(uri), _) => {
                    o.insert("uri".into(), json!(uri));
                }
                (Some(bytes), None, _) => {
                    let mime = mime.unwrap_or_else(|| "application/octet-stream".into());
                    let data = base64::engine::general_purpose::STANDARD.encode(bytes);
                    o.insert("uri".into(), json!(format!("data:{mime};base64,{data}")));
                }
                (None, None, _) => {}
            }
        }
    }
    if let Some(list) = arrays.get_mut("materials") {
        drop_textures_without_uvs(list, has_uv);
    }
    let n = arrays
        .get("materials")
        .and_then(Value::as_array)
        .map_or(0, Vec::len);
    Ok((arrays, n))
}

/// Removes the texture references (`…Texture: {"index": …}`) a primitive could not map:
/// all of them without `TEXCOORD_0`, those of another set (`texCoord` ≠ 0) always, since
/// only set 0 is written. A material then keeps its factors; the file stays valid.
fn drop_textures_without_uvs(v: &mut Value, has_uv: bool) {
    match v {
        Value::Array(a) => a
            .iter_mut()
            .for_each(|x| drop_textures_without_uvs(x, has_uv)),
        Value::Object(o) => {
            o.retain(|k, x| {
                let texture = k.ends_with("Texture") && x.get("index").is_some();
                let set = x.get("texCoord").and_then(Value::as_u64).unwrap_or(0);
                !(texture && (!has_uv || set != 0))
            });
            o.values_mut()
                .for_each(|x| drop_textures_without_uvs(x, has_uv));
        }
        _ => {}
    }
}

/// Whether the carried materials reference a texture (they need UVs to be drawn).
pub(crate) fn uses_textures(m: &Materials) -> bool {
    fn any(v: &Value) -> bool {
        match v {
            Value::Array(a) => a.iter().any(any),
            Value::Object(o) => o
                .iter()
                .any(|(k, x)| (k.ends_with("Texture") && x.get("index").is_some()) || any(x)),
            _ => false,
        }
    }
    serde_json::from_str::<Value>(&m.json).is_ok_and(|v| v.get("materials").is_some_and(any))
}

/// The MIME type of PNG and JPEG bytes.
fn sniff_mime(b: &[u8]) -> Option<&'static str> {
    if b.starts_with(b"\x89PNG") {
        Some("image/png")
    } else if b.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some("image/jpeg")
    } else {
        None
    }
}

/// The GLB container: header, JSON chunk (padded with spaces), binary chunk (with zeros).
fn glb(w: &mut impl Write, json: &[u8], bin: &[u8]) -> std::io::Result<()> {
    let pad = |n: usize| (4 - n % 4) % 4;
    let json_len = json.len() + pad(json.len());
    let bin_len = bin.len() + pad(bin.len());
    let total = 12 + 8 + json_len + if bin.is_empty() { 0 } else { 8 + bin_len };
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&(total as u32).to_le_bytes())?;
    w.write_all(&(json_len as u32).to_le_bytes())?;
    w.write_all(b"JSON")?;
    w.write_all(json)?;
    w.write_all(&b"   "[..pad(json.len())])?;
    if !bin.is_empty() {
        w.write_all(&(bin_len as u32).to_le_bytes())?;
        w.write_all(b"BIN\0")?;
        w.write_all(bin)?;
        w.write_all(&[0u8; 3][..pad(bin.len())])?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use crate::{Format, ReadOptions, WriteOptions, read_bytes, write_to};
    use coarsen_mesh::{AttrValues, Attributes, DVec2, DVec3, Image, Materials, Mesh};
    use serde_json::{Value, json};

    /// Two triangles with a UV seam along their shared edge, a normal and a colour per
    /// vertex; every value exact in `f32`.
    fn seamed() -> Mesh {
        let m = Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 0.5)],
            vec![[0, 1, 2], [1, 3, 2]],
        );
        let uv = [0.0, 0.5, 0.25, 0.75, 1.0, 0.125];
        let mut cols = Attributes::default();
        cols.insert(
            "uv",
            AttrValues::Vec2(uv.iter().map(|&u| DVec2::new(u, 1.0 - u)).collect()),
        );
        let mut m = m.with_corner_attributes(cols);
        m.vertex_attrs
            .insert("normal", AttrValues::Vec3(vec![DVec3::Z; 4]));
        m.vertex_attrs.insert(
            "color",
            AttrValues::Color(vec![[255, 0, 0], [0, 255, 0], [0, 0, 255], [9, 9, 9]]),
        );
        m
    }

    fn bytes(m: &Mesh, f: Format) -> Vec<u8> {
        let mut out = Vec::new();
        write_to(m, f, &mut out, &WriteOptions::default()).unwrap();
        out
    }

    fn read(b: &[u8], f: Format) -> Result<(Mesh, Vec<String>), String> {
        read_bytes(b, f, "t", &ReadOptions::default())
            .map(|l| (l.mesh, l.notes))
            .map_err(|e| e.to_string())
    }

    /// A `.gltf` of `m` with `edit` applied to its JSON.
    fn edited(m: &Mesh, edit: impl FnOnce(&mut Value)) -> Vec<u8> {
        let mut doc: Value = serde_json::from_slice(&bytes(m, Format::Gltf)).unwrap();
        edit(&mut doc);
        serde_json::to_vec(&doc).unwrap()
    }

    #[test]
    fn glb_and_gltf_give_back_positions_faces_and_corner_values() {
        let m = seamed();
        for f in [Format::Glb, Format::Gltf] {
            let (back, notes) = read(&bytes(&m, f), f).unwrap();
            assert_eq!(back.positions, m.positions, "{f}");
            assert_eq!(back.faces, m.faces, "{f}");
            for name in ["uv", "normal", "color"] {
                assert_eq!(
                    back.corner_column(name),
                    m.corner_column(name),
                    "{f} {name}"
                );
            }
            assert_eq!(back.wedges.split_vertices(), 2);
            assert!(back.vertex_attrs.vec3("normal").is_some());
            assert!(
                notes
                    .iter()
                    .any(|n| n.contains("6 glTF vertices welded into 4"))
            );
            // Written again, the same bytes.
            assert_eq!(bytes(&back, f), bytes(&m, f), "{f}");
        }
    }

    #[test]
    fn texture_v_counts_from_the_image_top_in_the_file() {
        let m = seamed();
        let glb = bytes(&m, Format::Glb);
        let file = gltf::Gltf::from_slice(&glb).unwrap();
        let blob = file.blob.as_deref().unwrap();
        let prim = file.document.meshes().next().unwrap();
        let prim = prim.primitives().next().unwrap();
        let acc = prim.get(&gltf::Semantic::TexCoords(0)).unwrap();
        let view = acc.view().unwrap();
        let at = view.offset() + acc.offset();
        let stored: Vec<[f32; 2]> = blob[at..at + 8 * acc.count()]
            .chunks_exact(8)
            .map(|c| {
                let f = |k: usize| f32::from_le_bytes(c[k..k + 4].try_into().unwrap());
                [f(0), f(4)]
            })
            .collect();
        let Some(AttrValues::Vec2(uv)) = m.corner_column("uv") else {
            unreachable!()
        };
        // Each stored (u, v) is a corner's (u, 1 − v); the seam makes six glTF vertices.
        assert_eq!(stored.len(), 6);
        for t in &uv {
            let want = [t.x as f32, (1.0 - t.y) as f32];
            assert!(stored.contains(&want), "{want:?} not in {stored:?}");
        }
        assert!(!stored.contains(&[0.0, 1.0]), "v written unturned");
    }

    #[test]
    fn turning_v_twice_gives_back_every_f32_but_the_tiniest() {
        // Every 4099th bit pattern of the finite f32s, both signs.
        for bits in (0..0x7f80_0000u32).step_by(4099) {
            for v in [f32::from_bits(bits), -f32::from_bits(bits)] {
                let back = crate::gltf_read::flip_v(crate::gltf_read::flip_v(v as f64)) as f32;
                if v == 0.0 {
                    assert_eq!(back, 0.0); // −0 comes back +0
                } else if v.abs() >= 2f32.powi(-29) {
                    assert_eq!(back.to_bits(), v.to_bits(), "{v:e}");
                } else {
                    assert!((back - v).abs() <= f32::EPSILON / 4.0, "{v:e}");
                }
            }
        }
    }

    #[test]
    fn materials_and_embedded_images_are_carried_through() {
        let mut m = seamed();
        let png = b"\x89PNG\r\n\x1a\nnot really a picture".to_vec();
        m.materials = Materials {
            json: json!({
                "materials": [{"name": "hide", "pbrMetallicRoughness":
                    {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}],
                "textures": [{"source": 0, "sampler": 0}],
                "samplers": [{"magFilter": 9729}],
                "images": [{"name": "skin"}],
            })
            .to_string(),
            images: vec![Image {
                bytes: Some(png.clone()),
                ..Default::default()
            }],
        };
        for f in [Format::Glb, Format::Gltf] {
            let (back, _) = read(&bytes(&m, f), f).unwrap();
            assert_eq!(back.materials.images[0].bytes.as_deref(), Some(&png[..]));
            let j: Value = serde_json::from_str(&back.materials.json).unwrap();
            assert_eq!(j["materials"][0]["name"], "hide");
            assert_eq!(j["samplers"][0]["magFilter"], 9729);
            assert_eq!(j["images"][0]["name"], "skin");
            assert_eq!(bytes(&back, f), bytes(&m, f), "{f}");
        }
        let doc: Value = serde_json::from_slice(&bytes(&m, Format::Gltf)).unwrap();
        assert_eq!(doc["meshes"][0]["primitives"][0]["material"], 0);
        assert!(
            doc["images"][0]["uri"]
                .as_str()
                .unwrap()
                .starts_with("data:image/png;base64,")
        );
    }

    #[test]
    fn node_transforms_apply_and_a_mirror_turns_triangles_around() {
        let m = seamed();
        let moved = edited(&m, |d| {
            d["nodes"][0]["translation"] = json!([10.0, 0.0, 0.0]);
            d["nodes"][0]["scale"] = json!([-1.0, 1.0, 1.0]);
        });
        let (back, _) = read(&moved, Format::Gltf).unwrap();
        assert_eq!(back.positions[1], DVec3::new(9.0, 0.0, 0.0));
        assert_eq!(back.faces[0], [0, 2, 1]);
        // Still facing +z, as the mirrored triangle was turned around.
        assert_eq!(back.face_normal(0), DVec3::Z);
        // Normals follow the mirror: still (0, 0, 1) for a mirror in x.
        assert_eq!(back.vertex_attrs.vec3("normal").unwrap()[0], DVec3::Z);
    }

    #[test]
    fn one_mesh_is_chosen_by_name_and_a_missing_name_lists_the_others() {
        let m = seamed();
        let named = edited(&m, |d| d["meshes"][0]["name"] = json!("cow"));
        let opts = |n: &str| ReadOptions {
            gltf_mesh: Some(n.into()),
            ..Default::default()
        };
        let ok = read_bytes(&named, Format::Gltf, "t", &opts("cow")).unwrap();
        assert_eq!(ok.mesh.n_faces(), 2);
        let e = read_bytes(&named, Format::Gltf, "t", &opts("pig"))
            .unwrap_err()
            .to_string();
        assert_eq!(e, "t: no mesh called `pig` in the scene (meshes: `cow`)");
    }

    #[test]
    fn what_cannot_be_read_is_refused_by_name() {
        let m = seamed();
        type Edit = Box<dyn FnOnce(&mut Value)>;
        let cases: Vec<(Edit, &str)> = vec![
            (
                Box::new(|d| d["meshes"][0]["primitives"][0]["mode"] = json!(1)),
                "only triangle lists are read",
            ),
            (
                Box::new(|d| d["meshes"][0]["primitives"][0]["targets"] = json!([{"POSITION": 0}])),
                "morph targets",
            ),
            (
                Box::new(|d| d["extensionsUsed"] = json!(["KHR_draco_mesh_compression"])),
                "Draco-compressed meshes (extension KHR_draco_mesh_compression)",
            ),
            (
                Box::new(|d| d["extensionsRequired"] = json!(["EXT_unheard_of"])),
                "EXT_unheard_of",
            ),
            (
                Box::new(|d| d["accessors"][0]["count"] = json!(1000)),
                "accessor 0",
            ),
            // gltf-json 1.4 would index its accessors with this unchecked (a panic).
            (
                Box::new(|d| d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(99)),
                "POSITION names accessor 99, but there are",
            ),
            (
                Box::new(|d| d["accessors"][1]["type"] = json!("SCALAR")),
                "components per element",
            ),
        ];
        for (edit, expect) in cases {
            let e = read(&edited(&m, edit), Format::Gltf).unwrap_err();
            assert!(e.contains(expect), "{e} (expected `{expect}`)");
        }
        assert!(
            read(b"glTF\x02\0\0\0garbage", Format::Glb)
                .unwrap_err()
                .starts_with("t: ")
        );
    }

    #[test]
    fn damaged_files_give_errors_or_valid_meshes_never_panics() {
        // Bytes of written files changed at random places (a fixed xorshift sequence).
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for f in [Format::Glb, Format::Gltf] {
            let good = bytes(&seamed(), f);
            for _ in 0..400 {
                let mut b = good.clone();
                for _ in 0..1 + next() % 4 {
                    let at = (next() % b.len() as u64) as usize;
                    b[at] = next() as u8;
                }
                if let Ok(l) = read_bytes(&b, f, "t", &ReadOptions::default()) {
                    assert!(l.mesh.validate_indices().is_ok());
                }
            }
        }
    }

    #[test]
    fn without_uvs_a_material_loses_its_textures_and_keeps_the_rest() {
        let mut m = Mesh::new(seamed().positions, seamed().faces);
        m.materials = Materials {
            json: json!({
                "materials": [{"pbrMetallicRoughness":
                    {"baseColorTexture": {"index": 0}, "baseColorFactor": [1, 0.5, 0.5, 1]}}],
                "textures": [{"source": 0}],
                "images": [{"uri": "hide.png"}],
            })
            .to_string(),
            images: vec![Image {
                uri: Some("hide.png".into()),
                ..Default::default()
            }],
        };
        assert!(super::uses_textures(&m.materials));
        let doc: Value = serde_json::from_slice(&bytes(&m, Format::Gltf)).unwrap();
        let pbr = &doc["materials"][0]["pbrMetallicRoughness"];
        assert!(pbr.get("baseColorTexture").is_none());
        assert_eq!(pbr["baseColorFactor"][1], 0.5);
        assert_eq!(doc["images"][0]["uri"], "hide.png");
        let said = crate::left_out(&m, Format::Glb, &WriteOptions::default());
        assert!(
            said[0].starts_with("textures of the materials not written"),
            "{said:?}"
        );
    }

    #[test]
    fn ply_colours_with_alpha_become_an_rgba_color_0_and_come_back() {
        let ply = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nproperty float u\nproperty float v\nproperty float nx\nproperty float ny\n\
property float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
property uchar alpha\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0 0 0 0 0 1 255 0 0 255\n1 0 0 1 0 0 0 1 0 255 0 128\n0 1 0 0 1 0 0 1 0 0 255 0\n3 0 1 2\n";
        let (m, _) = read(ply, Format::Ply).unwrap();
        let doc: Value = serde_json::from_slice(&bytes(&m, Format::Gltf)).unwrap();
        let color = doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"]
            .as_u64()
            .unwrap();
        assert_eq!(doc["accessors"][color as usize]["type"], "VEC4");
        let (back, _) = read(&bytes(&m, Format::Glb), Format::Glb).unwrap();
        for name in ["uv", "normal", "color", "alpha"] {
            assert_eq!(
                back.vertex_attrs.get(name),
                m.vertex_attrs.get(name),
                "{name}"
            );
        }
    }

    #[test]
    fn absolute_and_scheme_uris_are_not_followed_and_unread_meshes_are_said() {
        let m = seamed();
        for uri in [
            "/etc/passwd",
            "file:///etc/passwd",
            "https://example.invalid/b.bin",
        ] {
            let b = edited(&m, |d| d["buffers"][0]["uri"] = json!(uri));
            let dir = std::env::temp_dir();
            let e = crate::read_beside(&b, Format::Gltf, "t", &ReadOptions::default(), Some(&dir))
                .unwrap_err()
                .to_string();
            assert!(e.contains("only data URIs and paths relative"), "{e}");
        }
        let b = edited(&m, |d| {
            let mesh = d["meshes"][0].clone();
            d["meshes"] = json!([mesh.clone(), mesh]);
            d["scenes"] = json!([{"nodes": [0]}, {"nodes": []}]);
        });
        let (_, notes) = read(&b, Format::Gltf).unwrap();
        assert!(
            notes.contains(&"1 other scenes ignored (only the default scene is read)".to_string()),
            "{notes:?}"
        );
        assert!(
            notes.contains(&"1 meshes that no node of the scene shows ignored".to_string()),
            "{notes:?}"
        );
    }
}
