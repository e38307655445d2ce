//! Wavefront OBJ: our own line-numbered parser and a writer.
//!
//! Why not `tobj`: it reports no line numbers, and its `single_index` mode re-indexes
//! vertices (one vertex per distinct position/uv/normal triple), so vertex `i` of the file
//! would no longer be vertex `i` of the mesh. This reader keeps the file's vertex numbering
//! exactly and names the line of every error.
//!
//! Read: `v x y z` (a trailing `w` or vertex colours are ignored, with a note), `vt u [v
//! [w]]`, `vn x y z`, faces with corners `a`, `a/b`, `a//c`, `a/b/c` and negative
//! (relative) indices. A polygon of `n ≥ 3` corners becomes the `n − 2` triangles of a
//! fan from its first corner: `(c0, c1, c2), (c0, c2, c3), …`. A polyline `l v1 v2 … vn`
//! (`n ≥ 2`; vertices as `v` or `v/vt`, the texture coordinate ignored; indices as for
//! faces) marks each pair of consecutive vertices as a feature edge
//! ([`Mesh::marked_edges`], in file order, as written). `p`, `g`, `o`, `s` and free-form
//! statements are ignored and counted in a note. `mtllib` libraries beside a
//! file read by path give the materials its faces name with `usemtl` (see `crate::mtl`:
//! diffuse colour, opacity, diffuse texture, carried for glTF output) and the face column
//! `material`; read from bytes alone, they are ignored with a note. A line
//! ending in `\` continues on the next. Absolute indices may point forward (they are
//! checked against the final counts); relative ones count back from the line they are on.
//!
//! Texture coordinates and normals become the attributes `uv` and `normal`: vertex
//! columns when they are per vertex (every face corner of vertex `v` refers to the same
//! value, bit for bit; a vertex used by no face gets `(0, 0)` / `(0, 0, 0)`), per-corner
//! wedges (`coarsen_mesh::wedge`) where seams or hard edges give a vertex several. When
//! some corners have none while others have one, or a value is not finite, they are not
//! kept and a note says why.
//!
//! Write: `v` with shortest round-trip decimals (positions read back bit for bit), `vt`
//! from a `uv` column, `vn` from a `normal` column (one per vertex, or one per wedge when
//! the column is per corner), `f` with matching indices, and one `l a b` per marked edge.
//! Other attributes have no place in OBJ and are not written.

use crate::ReadOptions;
use crate::error::{ErrorKind, IoError, RefKind};
use crate::text::{self, Lines, non_finite_name, parse_f64, parse_i64, show};
use coarsen_mesh::{AttrValues, Attributes, DVec2, DVec3, Mesh};
use std::io::{self, Write};

/// Marks "no texture coordinate / normal" at a corner.
const NONE: u32 = u32::MAX;

/// The largest absolute index seen for one kind of reference, its line and what
/// referred to it (`face` or `edge`).
#[derive(Default)]
struct Farthest {
    index: i64,
    line: usize,
    by: &'static str,
}

/// Per-corner references to `vt` or `vn`, stored only once some corner has one.
#[derive(Default)]
struct CornerRefs {
    refs: Vec<u32>,
    used: bool,
    missing: usize,
}

impl CornerRefs {
    /// Records the triangle corners `tri` (each an index or [`NONE`]); `n_before` is the
    /// number of triangles before this one.
    fn push(&mut self, tri: [u32; 3], n_before: usize) {
        let any = tri.iter().any(|&r| r != NONE);
        self.missing += tri.iter().filter(|&&r| r == NONE).count();
        if any && !self.used {
            self.refs.resize(3 * n_before, NONE);
            self.used = true;
        }
        if self.used {
            self.refs.extend_from_slice(&tri);
        }
    }
}

/// Parser state for one file.
struct Reader<'o> {
    name: String,
    opts: &'o ReadOptions,
    positions: Vec<DVec3>,
    uvs: Vec<DVec2>,
    normals: Vec<DVec3>,
    faces: Vec<[u32; 3]>,
    /// The edges of `l` statements.
    edges: Vec<[u32; 2]>,
    corner_vt: CornerRefs,
    corner_vn: CornerRefs,
    far: [Farthest; 3],
    bad_vt: Option<(usize, &'static str)>,
    bad_vn: Option<(usize, &'static str)>,
    extra_vertex_values: usize,
    /// Where the material libraries are (the OBJ file's folder), when read by path.
    dir: Option<&'o std::path::Path>,
    /// `mtllib` files, in order.
    mtllibs: Vec<String>,
    /// `usemtl` names in order of first use; material `i` is `materials[i]`.
    materials: Vec<String>,
    /// The material of the faces being read (`u32::MAX`: none yet).
    current: u32,
    /// The material of each triangle.
    face_material: Vec<u32>,
    ignored: Vec<(String, usize, usize)>,
    poly: [Vec<u32>; 3],
}

/// Reads an OBJ file's bytes; `name` is used in errors.
#[cfg(test)]
pub(crate) fn read(
    bytes: &[u8],
    name: &str,
    opts: &ReadOptions,
) -> Result<(Mesh, Vec<String>), IoError> {
    read_in(bytes, name, opts, None)
}

/// Reads an OBJ file's bytes; `name` is used in errors; `dir` is the file's folder, where
/// its material libraries are (none: `mtllib` is ignored with a note).
pub(crate) fn read_in(
    bytes: &[u8],
    name: &str,
    opts: &ReadOptions,
    dir: Option<&std::path::Path>,
) -> Result<(Mesh, Vec<String>), IoError> {
    let mut r = Reader {
        name: name.to_string(),
        opts,
        positions: Vec::new(),
        uvs: Vec::new(),
        normals: Vec::new(),
        faces: Vec::new(),
        edges: Vec::new(),
        corner_vt: CornerRefs::default(),
        corner_vn: CornerRefs::default(),
        far: Default::default(),
        bad_vt: None,
        bad_vn: None,
        extra_vertex_values: 0,
        dir,
        mtllibs: Vec::new(),
        materials: Vec::new(),
        current: u32::MAX,
        face_material: Vec::new(),
        ignored: Vec::new(),
        poly: Default::default(),
    };
    let mut lines = Lines::new(bytes);
    while let Some((line, content)) = lines.next_line() {
        r.statement(line, content)?;
    }
    r.finish()
}

impl Reader<'_> {
    fn err(&self, line: usize, kind: ErrorKind) -> IoError {
        IoError::line(&self.name, line, kind)
    }

    fn syntax(&self, line: usize, msg: String) -> IoError {
        self.err(line, ErrorKind::Syntax(msg))
    }

    fn statement(&mut self, line: usize, content: &[u8]) -> Result<(), IoError> {
        let mut toks = text::tokens(content);
        let Some(keyword) = toks.next() else {
            return Ok(());
        };
        match keyword {
            b"v" => self.vertex(line, toks),
            b"vt" => {
                let [u, v] = self.numbers(line, "vt", toks, 1, [0.0; 2])?;
                if let Some(bad) = [u, v].into_iter().find(|c| !c.is_finite())
                    && self.bad_vt.is_none()
                {
                    self.bad_vt = Some((line, non_finite_name(bad)));
                }
                let p = DVec2::new(u, v);
                self.uvs.push(p);
                Ok(())
            }
            b"vn" => {
                let [x, y, z] = self.numbers(line, "vn", toks, 3, [0.0; 3])?;
                if let Some(bad) = [x, y, z].into_iter().find(|c| !c.is_finite())
                    && self.bad_vn.is_none()
                {
                    self.bad_vn = Some((line, non_finite_name(bad)));
                }
                let n = DVec3::new(x, y, z);
                self.normals.push(n);
                Ok(())
            }
            b"f" => self.face(line, toks),
            b"l" => self.polyline(line, toks),
            b"mtllib" => {
                let names = toks.map(|t| String::from_utf8_lossy(t).into_owned());
                self.mtllibs.extend(names);
                Ok(())
            }
            b"usemtl" => {
                let name: Vec<String> = toks
                    .map(|t| String::from_utf8_lossy(t).into_owned())
                    .collect();
                let name = name.join(" ");
                self.current = match self.materials.iter().position(|m| *m == name) {
                    Some(i) => i as u32,
                    None => {
                        self.materials.push(name);
                        (self.materials.len() - 1) as u32
                    }
                };
                Ok(())
            }
            other => {
                self.ignore(line, other);
                Ok(())
            }
        }
    }

    /// Parses at least `min` and at most `N` leading numbers (the rest default to `fill`).
    fn numbers<'t, const N: usize>(
        &self,
        line: usize,
        what: &str,
        toks: impl Iterator<Item = &'t [u8]>,
        min: usize,
        fill: [f64; N],
    ) -> Result<[f64; N], IoError> {
        let mut out = fill;
        let mut n = 0;
        for tok in toks.take(N) {
            out[n] = parse_f64(tok).ok_or_else(|| {
                self.syntax(line, format!("`{what}`: `{}` is not a number", show(tok)))
            })?;
            n += 1;
        }
        if n < min {
            return Err(self.syntax(
                line,
                format!("`{what}` needs at least {min} numbers, found {n}"),
            ));
        }
        Ok(out)
    }

    fn vertex<'t>(
        &mut self,
        line: usize,
        mut toks: impl Iterator<Item = &'t [u8]>,
    ) -> Result<(), IoError> {
        let [x, y, z] = self.numbers(line, "v", toks.by_ref(), 3, [0.0; 3])?;
        if toks.next().is_some() {
            self.extra_vertex_values += 1;
        }
        let index = self.positions.len() as u64 + 1;
        if let Some(bad) = [x, y, z].into_iter().find(|c| !c.is_finite()) {
            return Err(IoError::line_element(
                &self.name,
                line,
                "vertex",
                index,
                ErrorKind::NonFinite(non_finite_name(bad)),
            ));
        }
        if let Some(limit) = self.opts.max_vertices
            && self.positions.len() >= limit
        {
            return Err(self.err(line, ErrorKind::over_limit_vertices(limit)));
        }
        if self.positions.len() >= u32::MAX as usize {
            return Err(self.err(
                line,
                ErrorKind::TooMany {
                    count: index,
                    what: "vertices",
                },
            ));
        }
        self.positions.push(DVec3::new(x, y, z));
        Ok(())
    }

    /// Resolves one index as written (1-based, or negative = relative) into a 0-based one;
    /// `by` is what refers to it (`face` or `edge`), for errors.
    fn resolve(
        &mut self,
        line: usize,
        tok: &[u8],
        what: RefKind,
        by: &'static str,
    ) -> Result<u32, IoError> {
        let (slot, count) = match what {
            RefKind::Vertex => (0, self.positions.len()),
            RefKind::TexCoord => (1, self.uvs.len()),
            RefKind::Normal => (2, self.normals.len()),
        };
        let index = parse_i64(tok)
            .ok_or_else(|| self.syntax(line, format!("`{}` is not a {what} index", show(tok))))?;
        let out_of_range = || {
            self.err(
                line,
                ErrorKind::OutOfRange {
                    by,
                    what,
                    index,
                    count: count as u64,
                },
            )
        };
        match index {
            0 => Err(self.syntax(
                line,
                format!("{what} index 0 is invalid (OBJ indices start at 1)"),
            )),
            i if i < 0 => {
                let resolved = count as i64 + i;
                if resolved < 0 {
                    Err(out_of_range())
                } else {
                    Ok(resolved as u32)
                }
            }
            i if i > u32::MAX as i64 => Err(out_of_range()),
            i => {
                let far = &mut self.far[slot];
                if i > count as i64 && i > far.index {
                    *far = Farthest { index: i, line, by };
                }
                Ok((i - 1) as u32)
            }
        }
    }

    fn face<'t>(
        &mut self,
        line: usize,
        toks: impl Iterator<Item = &'t [u8]>,
    ) -> Result<(), IoError> {
        let mut poly = std::mem::take(&mut self.poly);
        poly.iter_mut().for_each(Vec::clear);
        for tok in toks {
            let mut parts = tok.split(|&b| b == b'/');
            let v = parts.next().unwrap_or_default();
            let vt = parts.next().unwrap_or_default();
            let vn = parts.next().unwrap_or_default();
            if parts.next().is_some() || v.is_empty() {
                return Err(self.syntax(
                    line,
                    format!(
                        "`{}` is not a face corner (v, v/vt, v//vn or v/vt/vn)",
                        show(tok)
                    ),
                ));
            }
            let v = self.resolve(line, v, RefKind::Vertex, "face")?;
            let vt = match vt {
                [] => NONE,
                t => self.resolve(line, t, RefKind::TexCoord, "face")?,
            };
            let vn = match vn {
                [] => NONE,
                t => self.resolve(line, t, RefKind::Normal, "face")?,
            };
            poly[0].push(v);
            poly[1].push(vt);
            poly[2].push(vn);
        }
        let n = poly[0].len();
        if n < 3 {
            return Err(self.syntax(
                line,
                format!("a face needs at least 3 corners, this one has {n}"),
            ));
        }
        if let Some(limit) = self.opts.max_faces
            && self.faces.len() + n - 2 > limit
        {
            return Err(self.err(line, ErrorKind::over_limit_faces(limit)));
        }
        if self.faces.len() + n - 2 > u32::MAX as usize {
            return Err(self.err(
                line,
                ErrorKind::TooMany {
                    count: (self.faces.len() + n - 2) as u64,
                    what: "faces",
                },
            ));
        }
        for i in 1..n - 1 {
            let fan = |c: &[u32]| [c[0], c[i], c[i + 1]];
            let before = self.faces.len();
            self.corner_vt.push(fan(&poly[1]), before);
            self.corner_vn.push(fan(&poly[2]), before);
            self.faces.push(fan(&poly[0]));
            self.face_material.push(self.current);
        }
        self.poly = poly;
        Ok(())
    }

    /// A polyline `l v1 v2 … vn`: each pair of consecutive vertices a marked edge.
    fn polyline<'t>(
        &mut self,
        line: usize,
        toks: impl Iterator<Item = &'t [u8]>,
    ) -> Result<(), IoError> {
        let mut poly = std::mem::take(&mut self.poly);
        poly[0].clear();
        for tok in toks {
            let mut parts = tok.split(|&b| b == b'/');
            let v = parts.next().unwrap_or_default();
            // The texture coordinate, if any, is not used.
            let _vt = parts.next();
            if parts.next().is_some() || v.is_empty() {
                return Err(self.syntax(
                    line,
                    format!("`{}` is not a line vertex (v or v/vt)", show(tok)),
                ));
            }
            let v = self.resolve(line, v, RefKind::Vertex, "edge")?;
            poly[0].push(v);
        }
        let n = poly[0].len();
        if n < 2 {
            return Err(self.syntax(
                line,
                format!("a line needs at least 2 vertices, this one has {n}"),
            ));
        }
        self.edges.extend(poly[0].windows(2).map(|w| [w[0], w[1]]));
        self.poly = poly;
        Ok(())
    }

    fn ignore(&mut self, line: usize, keyword: &[u8]) {
        const KNOWN: [&str; 5] = ["p", "g", "o", "s", "vp"];
        let key = match std::str::from_utf8(keyword) {
            Ok(k) if KNOWN.contains(&k) => format!("`{k}`"),
            _ => "unrecognised".to_string(),
        };
        match self.ignored.iter_mut().find(|(k, _, _)| *k == key) {
            Some((_, n, _)) => *n += 1,
            None => self.ignored.push((key, 1, line)),
        }
    }

    fn finish(self) -> Result<(Mesh, Vec<String>), IoError> {
        let counts = [self.positions.len(), self.uvs.len(), self.normals.len()];
        let kinds = [RefKind::Vertex, RefKind::TexCoord, RefKind::Normal];
        for ((far, count), what) in self.far.iter().zip(counts).zip(kinds) {
            if far.index > count as i64 {
                return Err(self.err(
                    far.line,
                    ErrorKind::OutOfRange {
                        by: far.by,
                        what,
                        index: far.index,
                        count: count as u64,
                    },
                ));
            }
        }
        let mut notes = Vec::new();
        if self.extra_vertex_values > 0 {
            notes.push(format!(
                "{} vertices have values after x y z (w or colours); ignored",
                self.extra_vertex_values
            ));
        }
        for (key, n, first) in &self.ignored {
            let s = if *n == 1 { "" } else { "s" };
            notes.push(format!(
                "{n} {key} statement{s} ignored (first at line {first})"
            ));
        }
        let mesh = Mesh {
            marked_edges: self.edges,
            ..Mesh::new(self.positions, self.faces)
        };
        let mut cols = Attributes::default();
        match per_corner(&self.corner_vt, &self.uvs, self.bad_vt, UV) {
            Ok(Some(v)) => cols.insert("uv", AttrValues::Vec2(v)),
            Ok(None) => {}
            Err(note) => notes.push(note),
        }
        match per_corner(&self.corner_vn, &self.normals, self.bad_vn, NORMAL) {
            Ok(Some(v)) => cols.insert("normal", AttrValues::Vec3(v)),
            Ok(None) => {}
            Err(note) => notes.push(note),
        }
        let mut mesh = mesh.with_corner_attributes(cols);
        let used = MaterialUse {
            dir: self.dir,
            mtllibs: self.mtllibs,
            materials: self.materials,
            face_material: self.face_material,
        };
        used.apply(&mut mesh, &mut notes);
        Ok((mesh, notes))
    }
}

/// What an OBJ file says of materials: its libraries, the names its faces use.
struct MaterialUse<'o> {
    dir: Option<&'o std::path::Path>,
    mtllibs: Vec<String>,
    materials: Vec<String>,
    face_material: Vec<u32>,
}

impl MaterialUse<'_> {
    /// The used materials from the `mtllib` libraries (see [`crate::mtl`]) and the face
    /// column saying which each face uses, when the file names any.
    fn apply(self, mesh: &mut Mesh, notes: &mut Vec<String>) {
        if self.mtllibs.is_empty() || self.materials.is_empty() {
            if !self.mtllibs.is_empty() {
                notes.push("`mtllib` ignored: no face uses a material (`usemtl`)".into());
            }
            return;
        }
        let Some(dir) = self.dir else {
            notes.push(
                "`mtllib` ignored: material libraries are read only when the OBJ file is read \
                 by path"
                    .into(),
            );
            return;
        };
        let Some(materials) = crate::mtl::load(&self.mtllibs, dir, &self.materials, notes) else {
            return;
        };
        mesh.materials = materials;
        if self.face_material.iter().any(|&m| m != 0) {
            mesh.face_attrs.insert(
                coarsen_mesh::material::MATERIAL,
                AttrValues::Label(self.face_material),
            );
        }
    }
}

/// Words for the notes about one kind of corner data.
struct Words {
    attr: &'static str,
    one: &'static str,
    many: &'static str,
}

const UV: Words = Words {
    attr: "uv",
    one: "texture coordinate",
    many: "texture coordinates",
};

const NORMAL: Words = Words {
    attr: "normal",
    one: "normal",
    many: "normals",
};

/// The value at every face corner; `Ok(None)` when no face refers to any; `Err(note)`
/// saying why they cannot be kept (none referred to, some corners without, a non-finite
/// value).
fn per_corner<T: Copy>(
    corners: &CornerRefs,
    values: &[T],
    bad: Option<(usize, &'static str)>,
    w: Words,
) -> Result<Option<Vec<T>>, String> {
    if !corners.used {
        if values.is_empty() {
            return Ok(None);
        }
        return Err(format!(
            "{} not kept: no face refers to the {} {}",
            w.attr,
            values.len(),
            w.many
        ));
    }
    if corners.missing > 0 {
        return Err(format!(
            "{} not kept: {} face corners have no {} while others have one",
            w.attr, corners.missing, w.one
        ));
    }
    if let Some((line, what)) = bad {
        return Err(format!(
            "{} not kept: the {} at line {line} is {what}",
            w.attr, w.one
        ));
    }
    Ok(Some(
        corners.refs.iter().map(|&r| values[r as usize]).collect(),
    ))
}

/// Where an attribute written to OBJ comes from: a vertex column (indexed like `v`) or a
/// wedge column (one entry per wedge, indexed by each corner's wedge).
enum Source<'m, T> {
    Vertex(&'m [T]),
    Wedge(&'m [T]),
}

impl<T> Source<'_, T> {
    fn values(&self) -> &[T] {
        match self {
            Source::Vertex(v) | Source::Wedge(v) => v,
        }
    }

    /// The 1-based index corner `k` of face `f` (vertex `v`) writes.
    fn index(&self, mesh: &Mesh, f: usize, k: usize, v: u32) -> u64 {
        match self {
            Source::Vertex(_) => u64::from(v) + 1,
            Source::Wedge(_) => u64::from(mesh.wedges.corner(f, k)) + 1,
        }
    }
}

/// The `uv` or `normal` data of `mesh` to write: its wedge column, else its vertex column.
fn source<'m, T>(
    mesh: &'m Mesh,
    pick: impl Fn(&'m Attributes) -> Option<&'m [T]>,
) -> Option<Source<'m, T>> {
    pick(mesh.wedges.attrs())
        .map(Source::Wedge)
        .or_else(|| pick(&mesh.vertex_attrs).map(Source::Vertex))
}

/// Writes `mesh` as OBJ (positions, `uv` and `normal` columns per vertex or per corner,
/// faces, and the marked edges as `l` lines, all but the positions and faces only with
/// `attributes`).
pub(crate) fn write(mesh: &Mesh, w: &mut impl Write, attributes: bool) -> io::Result<()> {
    let uv = attributes.then(|| source(mesh, |a| a.vec2("uv"))).flatten();
    let normal = attributes
        .then(|| source(mesh, |a| a.vec3("normal")))
        .flatten();
    let edges = if attributes {
        &mesh.marked_edges[..]
    } else {
        &[]
    };
    write!(
        w,
        "# {} vertices, {} faces",
        mesh.n_vertices(),
        mesh.n_faces()
    )?;
    match edges.len() {
        0 => writeln!(w)?,
        n => writeln!(w, ", {n} marked edges")?,
    }
    for p in &mesh.positions {
        vector(w, "v", &[p.x, p.y, p.z])?;
    }
    for t in uv.as_ref().map_or(&[][..], Source::values) {
        vector(w, "vt", &[t.x, t.y])?;
    }
    for n in normal.as_ref().map_or(&[][..], Source::values) {
        vector(w, "vn", &[n.x, n.y, n.z])?;
    }
    for (f, face) in mesh.faces.iter().enumerate() {
        w.write_all(b"f")?;
        for (k, &v) in face.iter().enumerate() {
            let i = u64::from(v) + 1;
            let t = uv.as_ref().map(|s| s.index(mesh, f, k, v));
            let n = normal.as_ref().map(|s| s.index(mesh, f, k, v));
            match (t, n) {
                (None, None) => write!(w, " {i}")?,
                (Some(t), None) => write!(w, " {i}/{t}")?,
                (None, Some(n)) => write!(w, " {i}//{n}")?,
                (Some(t), Some(n)) => write!(w, " {i}/{t}/{n}")?,
            }
        }
        w.write_all(b"\n")?;
    }
    for &[a, b] in edges {
        writeln!(w, "l {} {}", u64::from(a) + 1, u64::from(b) + 1)?;
    }
    Ok(())
}

/// Writes `keyword x y …` with round-trip decimals.
fn vector(w: &mut impl Write, keyword: &str, xs: &[f64]) -> io::Result<()> {
    w.write_all(keyword.as_bytes())?;
    for &x in xs {
        w.write_all(b" ")?;
        text::write_f64(w, x)?;
    }
    w.write_all(b"\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(src: &str) -> Result<(Mesh, Vec<String>), IoError> {
        read(src.as_bytes(), "t.obj", &ReadOptions::default())
    }

    fn err(src: &str) -> String {
        load(src).unwrap_err().to_string()
    }

    const SQUARE: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

    #[test]
    fn every_corner_form_reads_the_same_vertices() {
        let src = format!(
            "{SQUARE}vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\nf 1 2 3\nf 1/1 2/2 3/3\nf 1//1 2//1 3//1\nf 1/1/1 2/2/1 3/3/1\n"
        );
        let (m, _) = load(&src).unwrap();
        assert_eq!(m.faces, vec![[0, 1, 2]; 4]);
    }

    #[test]
    fn negative_indices_count_back_from_the_current_line() {
        let (m, _) = load("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\nf -4 -1 -2\n").unwrap();
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 3, 2]]);
    }

    #[test]
    fn quads_become_two_triangles_and_pentagons_three_as_a_fan() {
        let src = format!("{SQUARE}v 0.5 2 0\nf 1 2 3 4\nf 1 2 3 5 4\n");
        let (m, _) = load(&src).unwrap();
        assert_eq!(
            m.faces,
            vec![[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 4], [0, 4, 3]]
        );
    }

    #[test]
    fn ignored_statements_are_counted_in_notes_and_continuations_join() {
        let src = format!(
            "mtllib a.mtl\no thing\ng a\ng b\ns 1\nusemtl red\n{SQUARE}l 1 2\nf 1 2 \\\n 3\ncurv 0 1 2\n"
        );
        let (m, notes) = load(&src).unwrap();
        assert_eq!(m.faces, vec![[0, 1, 2]]);
        assert_eq!(m.marked_edges, vec![[0, 1]]);
        assert!(notes.contains(&"2 `g` statements ignored (first at line 3)".to_string()));
        assert!(notes.iter().all(|n| !n.contains("`l`")), "{notes:?}");
        assert!(
            notes
                .iter()
                .any(|n| n.starts_with("1 unrecognised statement"))
        );
    }

    #[test]
    fn polylines_mark_their_edges_with_any_index_form() {
        // Relative indices count back from the line they are on, `v/vt` gives its vertex,
        // and an absolute index may point forward.
        let src = format!("{SQUARE}vt 0 0\nl 1 2/1 -2 -1\nl 4 5\nf 1 2 3\nv 2 2 0\n");
        let (m, notes) = load(&src).unwrap();
        assert_eq!(
            notes,
            ["uv not kept: no face refers to the 1 texture coordinates"]
        );
        assert_eq!(m.marked_edges, vec![[0, 1], [1, 2], [2, 3], [3, 4]]);
        assert!(m.validate_indices().is_ok());
    }

    #[test]
    fn malformed_polylines_are_errors_naming_the_line() {
        assert_eq!(
            err(&format!("{SQUARE}l 1 9\n")),
            "t.obj:5: edge refers to vertex 9 but only 4 vertices are defined"
        );
        assert_eq!(
            err(&format!("{SQUARE}l 1 -5\n")),
            "t.obj:5: edge refers to vertex -5 but only 4 vertices are defined"
        );
        // A forward reference that never comes is named where it was made.
        assert_eq!(
            err(&format!("{SQUARE}f 1 2 3\nl 3 6\nv 0 0 1\n")),
            "t.obj:6: edge refers to vertex 6 but only 5 vertices are defined"
        );
        assert_eq!(
            err(&format!("{SQUARE}l 1 x\n")),
            "t.obj:5: `x` is not a vertex index"
        );
        assert_eq!(
            err(&format!("{SQUARE}l 1.5 2\n")),
            "t.obj:5: `1.5` is not a vertex index"
        );
        assert_eq!(
            err(&format!("{SQUARE}l 2\n")),
            "t.obj:5: a line needs at least 2 vertices, this one has 1"
        );
        assert_eq!(
            err(&format!("{SQUARE}l 1//1 2\n")),
            "t.obj:5: `1//1` is not a line vertex (v or v/vt)"
        );
        assert_eq!(
            err(&format!("{SQUARE}l 0 2\n")),
            "t.obj:5: vertex index 0 is invalid (OBJ indices start at 1)"
        );
    }

    #[test]
    fn marked_edges_are_written_as_lines_and_read_back() {
        let src = format!("{SQUARE}f 1 2 3 4\nl 3 1 2\n");
        let (m, _) = load(&src).unwrap();
        assert_eq!(m.marked_edges, vec![[2, 0], [0, 1]]);
        let mut bytes = Vec::new();
        write(&m, &mut bytes, true).unwrap();
        let text = String::from_utf8(bytes.clone()).unwrap();
        assert!(
            text.starts_with("# 4 vertices, 2 faces, 2 marked edges\n"),
            "{text}"
        );
        assert!(text.ends_with("l 3 1\nl 1 2\n"), "{text}");
        let (back, notes) = read(&bytes, "t.obj", &ReadOptions::default()).unwrap();
        assert!(notes.is_empty(), "{notes:?}");
        assert_eq!(back, m);
        // Positions and faces only: no lines.
        let mut bare = Vec::new();
        write(&m, &mut bare, false).unwrap();
        let (back, _) = read(&bare, "t.obj", &ReadOptions::default()).unwrap();
        assert!(back.marked_edges.is_empty());
    }

    #[test]
    fn w_and_vertex_colours_are_ignored_with_a_note() {
        let (m, notes) = load("v 0 0 0 1\nv 1 0 0 0.5 0.5 0.5\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert_eq!(m.positions[1], DVec3::X);
        assert_eq!(
            notes[0],
            "2 vertices have values after x y z (w or colours); ignored"
        );
    }

    #[test]
    fn unreferenced_vertices_and_degenerate_faces_are_kept() {
        let (m, _) = load("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 9 9 9\nf 1 1 2\n").unwrap();
        assert_eq!(m.n_vertices(), 4);
        assert_eq!(m.faces, vec![[0, 0, 1]]);
    }

    #[test]
    fn per_vertex_uv_and_normals_are_kept() {
        let src = format!(
            "{SQUARE}vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n"
        );
        let (m, notes) = load(&src).unwrap();
        assert!(notes.is_empty(), "{notes:?}");
        assert_eq!(
            m.vertex_attrs.vec2("uv").unwrap(),
            &[DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y]
        );
        assert_eq!(m.vertex_attrs.vec3("normal").unwrap(), &[DVec3::Z; 4]);
    }

    #[test]
    fn uv_with_seams_is_kept_per_corner_and_written_back() {
        // Vertex 1 takes uv 1 in one face and uv 5 (a different value) in the other;
        // vertex 3 takes uv 3 and uv 6, which hold the same value: not a seam.
        let src = format!(
            "{SQUARE}vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0\nvt 1 1\nf 1/1 2/2 3/3\nf 1/5 3/6 4/4\n"
        );
        let (m, notes) = load(&src).unwrap();
        assert!(notes.is_empty(), "{notes:?}");
        assert!(m.vertex_attrs.get("uv").is_none());
        assert_eq!(m.wedges.split_vertices(), 1);
        let corner_uv = [0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.5, 0.0, 1.0, 1.0, 0.0, 1.0];
        let expect: Vec<DVec2> = corner_uv
            .chunks(2)
            .map(|c| DVec2::new(c[0], c[1]))
            .collect();
        assert_eq!(m.corner_column("uv"), Some(AttrValues::Vec2(expect)));
        let mut bytes = Vec::new();
        write(&m, &mut bytes, true).unwrap();
        let (back, _) = read(&bytes, "t.obj", &ReadOptions::default()).unwrap();
        assert_eq!(back, m);
        assert!(
            String::from_utf8(bytes)
                .unwrap()
                .contains("f 1/4 3/3 4/5\n")
        );
    }

    #[test]
    fn normals_missing_at_some_corners_are_not_kept() {
        let src = format!("{SQUARE}vn 0 0 1\nf 1 2 3\nf 1//1 3//1 4//1\n");
        let (m, notes) = load(&src).unwrap();
        assert!(m.vertex_attrs.get("normal").is_none());
        assert_eq!(
            notes,
            ["normal not kept: 3 face corners have no normal while others have one"]
        );
    }

    #[test]
    fn out_of_range_index_names_line_index_and_count() {
        assert_eq!(
            err("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 40000\n"),
            "t.obj:5: face refers to vertex 40000 but only 3 vertices are defined"
        );
        assert_eq!(
            err("v 0 0 0\nf 1 -2 1\n"),
            "t.obj:2: face refers to vertex -2 but only 1 vertices are defined"
        );
        assert_eq!(
            err("v 0 0 0\nv 0 0 0\nv 0 0 0\nvt 0 0\nf 1/1 2/2 3/1\n"),
            "t.obj:5: face refers to texture coordinate 2 but only 1 texture coordinates are defined"
        );
    }

    #[test]
    fn forward_references_are_allowed_when_the_vertex_comes_later() {
        let (m, _) = load("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
        assert_eq!(m.faces, vec![[0, 1, 2]]);
        assert_eq!(
            err("f 1 2 3\nv 0 0 0\nv 1 0 0\nf 1 2 7\nv 0 1 0\n"),
            "t.obj:4: face refers to vertex 7 but only 3 vertices are defined"
        );
    }

    #[test]
    fn nan_coordinate_names_the_vertex_and_line() {
        assert_eq!(
            err("v 0 0 0\n# c\nv 1 nan 0\n"),
            "t.obj:3: vertex 2: coordinate is NaN"
        );
        assert_eq!(
            err("v inf 0 0\n"),
            "t.obj:1: vertex 1: coordinate is infinite"
        );
    }

    #[test]
    fn malformed_statements_are_errors_naming_the_line() {
        assert_eq!(
            err("v 0 0\n"),
            "t.obj:1: `v` needs at least 3 numbers, found 2"
        );
        assert_eq!(err("v 0 x 0\n"), "t.obj:1: `v`: `x` is not a number");
        assert_eq!(
            err("v 0 0 0\nv 1 0 0\nf 1 2\n"),
            "t.obj:3: a face needs at least 3 corners, this one has 2"
        );
        assert_eq!(
            err("v 0 0 0\nf 0 1 1\n"),
            "t.obj:2: vertex index 0 is invalid (OBJ indices start at 1)"
        );
        assert_eq!(
            err("v 0 0 0\nf 1/1/1/1 1 1\n"),
            "t.obj:2: `1/1/1/1` is not a face corner (v, v/vt, v//vn or v/vt/vn)"
        );
        assert_eq!(
            err("v 0 0 0\nf 1 1 99999999999999999999\n"),
            "t.obj:2: `99999999999999999999` is not a vertex index"
        );
    }

    #[test]
    fn max_faces_limit_is_enforced() {
        let opts = ReadOptions {
            max_faces: Some(1),
            ..Default::default()
        };
        let src = format!("{SQUARE}f 1 2 3 4\n");
        let e = read(src.as_bytes(), "t.obj", &opts)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "t.obj:5: more than 1 faces (the limit set by ReadOptions::max_faces)"
        );
    }

    #[test]
    fn written_obj_reads_back_bit_for_bit_with_attributes() {
        let mut m = Mesh::new(
            vec![
                DVec3::new(0.1, -1e-300, 1.0 / 3.0),
                DVec3::new(1e17, 2.0, -0.0),
                DVec3::new(0.3, 0.7, 5e-324),
            ],
            vec![[0, 1, 2], [2, 1, 0]],
        );
        m.vertex_attrs.insert(
            "uv",
            AttrValues::Vec2(vec![DVec2::new(0.1, 0.2), DVec2::X, DVec2::Y]),
        );
        m.vertex_attrs.insert(
            "normal",
            AttrValues::Vec3(vec![DVec3::Z, DVec3::X, DVec3::Y]),
        );
        let mut bytes = Vec::new();
        write(&m, &mut bytes, true).unwrap();
        let (back, notes) = read(&bytes, "t.obj", &ReadOptions::default()).unwrap();
        assert!(notes.is_empty(), "{notes:?}");
        let bits = |m: &Mesh| {
            m.positions
                .iter()
                .map(|p| p.to_array().map(f64::to_bits))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&back), bits(&m));
        assert_eq!(back, m);
    }
}
