//! OBJ material libraries (`.mtl`): each used material's diffuse colour (`Kd`), opacity
//! (`d`, or `Tr` as its complement) and diffuse texture (`map_Kd`), turned into glTF
//! materials (metallic 0, roughness 1) so that a textured OBJ file becomes a textured glTF
//! file. Other statements (specular, bump maps, illumination models) have no glTF
//! counterpart kept here and are ignored.

use crate::text::{Lines, parse_f64, tokens};
use coarsen_mesh::{Image, Materials};
use serde_json::{Value, json};
use std::path::Path;

/// One `newmtl` block.
struct Entry {
    name: String,
    kd: [f64; 3],
    d: f64,
    map_kd: Option<String>,
}

/// The materials called `used` (in that order: material `i` is `used[i]`), looked up in
/// the libraries `files` beside the OBJ file in `dir`; what is missing is said in `notes`.
/// `None` when no library could be read.
pub(crate) fn load(
    files: &[String],
    dir: &Path,
    used: &[String],
    notes: &mut Vec<String>,
) -> Option<Materials> {
    let mut entries = Vec::new();
    let mut read = 0;
    for f in files {
        match std::fs::read(dir.join(f)) {
            Ok(bytes) => {
                entries.extend(parse(&bytes));
                read += 1;
            }
            Err(e) => notes.push(format!("material library `{f}` not read ({e}): ignored")),
        }
    }
    if read == 0 {
        return None;
    }
    let mut materials = Vec::new();
    let mut textures: Vec<String> = Vec::new();
    for name in used {
        let Some(e) = entries.iter().find(|e| &e.name == name) else {
            notes.push(format!(
                "material `{name}` is in no material library: a default one"
            ));
            materials.push(json!({"name": name}));
            continue;
        };
        let mut pbr = json!({
            "baseColorFactor": [e.kd[0], e.kd[1], e.kd[2], e.d],
            "metallicFactor": 0.0,
        });
        if let Some(map) = &e.map_kd {
            let t = match textures.iter().position(|t| t == map) {
                Some(t) => t,
                None => {
                    textures.push(map.clone());
                    textures.len() - 1
                }
            };
            pbr["baseColorTexture"] = json!({"index": t});
        }
        let mut m = json!({"name": name, "pbrMetallicRoughness": pbr});
        if e.d < 1.0 {
            m["alphaMode"] = json!("BLEND");
        }
        materials.push(m);
    }
    let images: Vec<Image> = textures
        .iter()
        .map(|t| {
            let bytes = std::fs::read(dir.join(t)).ok();
            if bytes.is_none() {
                notes.push(format!(
                    "texture `{t}` not found beside the file: only its name is kept"
                ));
            }
            Image {
                uri: Some(t.replace('\\', "/").replace(' ', "%20")),
                mime_type: mime(t).map(str::to_string),
                bytes,
            }
        })
        .collect();
    let json = json!({
        "materials": materials,
        "textures": (0..textures.len()).map(|i| json!({"source": i})).collect::<Vec<Value>>(),
        "images": textures.iter().map(|t| json!({"name": t})).collect::<Vec<Value>>(),
    });
    Some(Materials {
        json: json.to_string(),
        images,
    })
}

/// The `newmtl` blocks of a library.
fn parse(bytes: &[u8]) -> Vec<Entry> {
    let mut out: Vec<Entry> = Vec::new();
    let mut lines = Lines::new(bytes);
    while let Some((_, content)) = lines.next_line() {
        let mut toks = tokens(content);
        let Some(key) = toks.next() else { continue };
        let rest: Vec<&[u8]> = toks.collect();
        let text = |t: &[&[u8]]| {
            t.iter()
                .map(|x| String::from_utf8_lossy(x).into_owned())
                .collect::<Vec<_>>()
                .join(" ")
        };
        let num = |i: usize| {
            rest.get(i)
                .and_then(|t| parse_f64(t))
                .filter(|x| x.is_finite())
        };
        if key == b"newmtl" {
            out.push(Entry {
                name: text(&rest),
                kd: [1.0; 3],
                d: 1.0,
                map_kd: None,
            });
            continue;
        }
        let Some(e) = out.last_mut() else { continue };
        match key {
            b"Kd" => {
                if let (Some(r), Some(g), Some(b)) = (num(0), num(1), num(2)) {
                    e.kd = [r, g, b].map(|c| c.clamp(0.0, 1.0));
                }
            }
            b"d" => e.d = num(0).map_or(e.d, |d| d.clamp(0.0, 1.0)),
            b"Tr" => e.d = num(0).map_or(e.d, |t| (1.0 - t).clamp(0.0, 1.0)),
            // Options (`-s 1 1 1`, `-clamp on`, …) come first; the file name is last.
            b"map_Kd" => e.map_kd = map_file(&rest),
            _ => {}
        }
    }
    out
}

/// The file name of a `map_…` statement: what follows its options (`-s 1 1 1`,
/// `-clamp on`, `-imfchan r`, …), spaces included.
fn map_file(toks: &[&[u8]]) -> Option<String> {
    let mut i = 0;
    while i < toks.len() && toks[i].starts_with(b"-") {
        let one_word = toks[i] == b"-imfchan";
        i += 1;
        if one_word {
            i += 1;
            continue;
        }
        while i < toks.len() && (parse_f64(toks[i]).is_some() || matches!(toks[i], b"on" | b"off"))
        {
            i += 1;
        }
    }
    let name: Vec<String> = toks[i.min(toks.len())..]
        .iter()
        .map(|t| String::from_utf8_lossy(t).into_owned())
        .collect();
    (!name.is_empty()).then(|| name.join(" "))
}

/// The MIME type of an image file name, for the formats glTF allows.
fn mime(name: &str) -> Option<&'static str> {
    let lower = name.to_ascii_lowercase();
    if lower.ends_with(".png") {
        Some("image/png")
    } else if lower.ends_with(".jpg") || lower.ends_with(".jpeg") {
        Some("image/jpeg")
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn map_options_are_skipped_and_names_keep_their_spaces() {
        let toks = |s: &'static str| s.split(' ').map(str::as_bytes).collect::<Vec<_>>();
        assert_eq!(
            map_file(&toks("-s 1 1 1 -clamp on hide tex.png")).as_deref(),
            Some("hide tex.png")
        );
        assert_eq!(
            map_file(&toks("-imfchan r a.jpg")).as_deref(),
            Some("a.jpg")
        );
        assert_eq!(map_file(&toks("-bm 0.5")), None);
        let e = parse(b"newmtl a\nKd 0.5 2 -1\nd 0.25\nmap_Kd t.png\nnewmtl b c\nTr 0.25\n");
        assert_eq!(
            (e[0].kd, e[0].d, e[0].map_kd.as_deref()),
            ([0.5, 1.0, 0.0], 0.25, Some("t.png"))
        );
        assert_eq!((e[1].name.as_str(), e[1].d), ("b c", 0.75));
    }
}
