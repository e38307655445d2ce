//! Mesh file formats for coarsen: OBJ, PLY, STL, OFF and glTF 2.0 (`.gltf`, `.glb`), read
//! and written.
//!
//! This is the only crate of the workspace that knows file formats. It turns bytes into a
//! [`Mesh`] faithfully — every vertex of the file (also unreferenced ones), every face
//! (also degenerate ones), in file order — and a [`Mesh`] back into bytes. Cleaning a mesh
//! is not its job: load-time hygiene lives in `coarsen_mesh::hygiene`. The one exception
//! is STL, a triangle soup, whose corners are welded where their positions are
//! bit-identical (see below).
//!
//! ```
//! use coarsen_io::{read_bytes, write_to, Format, ReadOptions, WriteOptions};
//! let obj = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
//! let loaded = read_bytes(obj, Format::Obj, "square.obj", &ReadOptions::default())?;
//! assert_eq!(loaded.mesh.faces, vec![[0, 1, 2], [0, 2, 3]]); // the quad as a fan
//!
//! let mut ply = Vec::new();
//! write_to(&loaded.mesh, Format::Ply, &mut ply, &WriteOptions::default())?;
//! let back = read_bytes(&ply, Format::Ply, "square.ply", &ReadOptions::default())?;
//! assert_eq!(back.mesh, loaded.mesh);
//! # Ok::<(), coarsen_io::IoError>(())
//! ```
//!
//! # What each format reads and writes
//!
//! | format | reads | writes |
//! | --- | --- | --- |
//! | OBJ | `v`, `vt`, `vn`, `f` (all corner forms, negative indices, polygons); `uv` and `normal` per vertex, or per corner (wedges) across seams and hard edges; `mtllib`/`usemtl` materials and their diffuse textures, read by path; `l` polylines as marked edges | positions, `uv`, `normal` (per vertex or per corner), marked edges as `l a b` |
//! | PLY | ASCII and both binary encodings, every scalar type, `vertex`, `face`, `tristrips`; `edge` (`vertex1`, `vertex2`) as marked edges; other elements skipped | every attribute kind (binary little endian by default), marked edges as an `edge` element |
//! | STL | ASCII and binary (via `stl_io`), welded by exact position | binary, positions only (as `f32`) |
//! | OFF | `OFF`, `COFF`, `NOFF`, … (colours and normals ignored) | positions and faces |
//! | glTF, GLB | triangle primitives of the scene's meshes (node transforms applied) or of one mesh by name; `POSITION`, `NORMAL`, `TEXCOORD_0`, `COLOR_0`, any index width, sparse accessors; welded by exact position, corner values as wedges; materials and images kept (`Mesh::materials`) | positions, `normal`, `uv`, `color` (+`alpha`) per vertex or wedge, one primitive per material, the carried materials and images |
//!
//! Marked edges ([`Mesh::marked_edges`]: edges the file marks as features, which
//! `coarsen-features` keeps whatever their angle) are carried by OBJ (`l v1 v2 … vn`, each
//! consecutive pair an edge) and PLY (an `edge` element with integer `vertex1` and
//! `vertex2` properties) only; STL, OFF and glTF carry none (a glTF line primitive is
//! refused, as every mode but triangles is). Written only with
//! [`WriteOptions::attributes`].
//!
//! Polygons are split into the triangles of a fan from their first corner:
//! `(c0, c1, c2), (c0, c2, c3), …`; a polygon's face properties go to each of its
//! triangles.
//!
//! # Errors and notes
//!
//! Every failure is an [`IoError`] naming the file and the line (text) or element
//! (binary): `bunny.obj:1234: face refers to vertex 40000 but only 35947 vertices are
//! defined`. Nothing panics on any input, NaN and infinite coordinates are refused, and
//! header counts never drive allocation beyond what the file's remaining bytes could hold.
//! Whatever a reader ignores or drops (an unknown PLY element, OBJ texture coordinates
//! with seams) is said in [`Loaded::notes`].

mod error;
mod gltf_read;
mod gltf_write;
mod mtl;
mod obj;
mod off;
mod ply;
mod stl;
mod text;

pub use error::{ErrorKind, IoError, Location, RefKind};

use coarsen_mesh::Mesh;
use std::fmt;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::str::FromStr;

/// A mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Format {
    /// Wavefront OBJ (text).
    Obj,
    /// Stanford PLY (ASCII or binary).
    Ply,
    /// STL (ASCII or binary), a triangle soup.
    Stl,
    /// Object File Format (text).
    Off,
    /// glTF 2.0, JSON (`.gltf`; written with its buffer embedded as a data URI).
    Gltf,
    /// glTF 2.0, binary container (`.glb`).
    Glb,
}

impl Format {
    /// Every format, in a fixed order.
    pub const ALL: [Format; 6] = [
        Format::Obj,
        Format::Ply,
        Format::Stl,
        Format::Off,
        Format::Gltf,
        Format::Glb,
    ];

    /// The format named by a path's extension (case-insensitive), if any.
    pub fn from_path(path: &Path) -> Option<Format> {
        path.extension()?.to_str()?.parse().ok()
    }

    /// The usual file extension, lower case and without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Obj => "obj",
            Format::Ply => "ply",
            Format::Stl => "stl",
            Format::Off => "off",
            Format::Gltf => "gltf",
            Format::Glb => "glb",
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Format::Obj => "OBJ",
            Format::Ply => "PLY",
            Format::Stl => "STL",
            Format::Off => "OFF",
            Format::Gltf => "glTF",
            Format::Glb => "GLB",
        })
    }
}

/// A format name or extension that names no known format.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown mesh format `{0}` (expected obj, ply, stl, off, gltf or glb)")]
pub struct UnknownFormat(pub String);

impl FromStr for Format {
    type Err = UnknownFormat;

    /// Parses `obj`, `ply`, `stl`, `off`, `gltf` or `glb`, in any case, with or without a
    /// leading dot.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let name = s.strip_prefix('.').unwrap_or(s);
        Format::ALL
            .into_iter()
            .find(|f| f.extension().eq_ignore_ascii_case(name))
            .ok_or_else(|| UnknownFormat(s.to_string()))
    }
}

/// Limits that a reader enforces while reading.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Refuse files with more triangles than this (after splitting polygons).
    /// Default `None`: no limit beyond 32-bit indices.
    pub max_faces: Option<usize>,
    /// Refuse files with more vertices than this. Default `None`: no limit beyond 32-bit
    /// indices.
    pub max_vertices: Option<usize>,
    /// [`read_path`] refuses files longer than this many bytes before reading them.
    /// Default `None`: no limit.
    pub max_file_bytes: Option<u64>,
    /// glTF: read only the instances of the mesh of this name. Default `None`: every
    /// mesh of the scene.
    pub gltf_mesh: Option<String>,
}

/// How many bytes of a file [`read_path`] checks before reading the rest.
pub const SNIFF_BYTES: usize = 64 * 1024;

/// The encoding of a written PLY file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum PlyEncoding {
    /// Text, one element per line, numbers in shortest round-trip form.
    Ascii,
    /// Binary, little endian (the default: compact, exact and fast).
    #[default]
    BinaryLittleEndian,
    /// Binary, big endian.
    BinaryBigEndian,
}

/// How meshes are written.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WriteOptions {
    /// Encoding of PLY files. Default [`PlyEncoding::BinaryLittleEndian`].
    pub ply_encoding: PlyEncoding,
    /// Write the attributes the format can hold (OBJ: `uv`, `normal`; PLY: all).
    /// Default `true`; `false` writes positions and faces only.
    pub attributes: bool,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            ply_encoding: PlyEncoding::default(),
            attributes: true,
        }
    }
}

/// A mesh read from a file, with what the reader had to leave out.
#[derive(Clone, Debug, PartialEq)]
pub struct Loaded {
    /// The mesh, exactly as the file gives it (indices checked, nothing cleaned).
    pub mesh: Mesh,
    /// The format it was read as.
    pub format: Format,
    /// One sentence per thing ignored or not kept (unknown elements, seamed UVs, …).
    pub notes: Vec<String>,
}

/// Reads the mesh file at `path`; the format comes from the extension.
///
/// Before the file is read into memory, its length is checked against
/// [`ReadOptions::max_file_bytes`] and its first [`SNIFF_BYTES`] bytes against what the
/// format requires (see [`check_start`]), so that a huge file that is not a mesh, or whose
/// header exceeds the limits, is refused at once.
pub fn read_path(path: &Path, opts: &ReadOptions) -> Result<Loaded, IoError> {
    use std::io::Read;
    let name = path.display().to_string();
    let format =
        Format::from_path(path).ok_or_else(|| IoError::file(&name, ErrorKind::UnknownFormat))?;
    let os = |e: std::io::Error| IoError::file(&name, e.into());
    let mut file = std::fs::File::open(path).map_err(os)?;
    let len = file.metadata().map_err(os)?.len();
    if let Some(limit) = opts.max_file_bytes
        && len > limit
    {
        return Err(IoError::file(&name, ErrorKind::FileTooLarge { len, limit }));
    }
    let mut bytes = Vec::new();
    (&mut file)
        .take(SNIFF_BYTES as u64)
        .read_to_end(&mut bytes)
        .map_err(os)?;
    if bytes.is_empty() {
        return Err(IoError::file(&name, ErrorKind::Empty));
    }
    check_start(&bytes, len, format, &name, opts)?;
    // The length is a hint only (the file may change): read to its real end.
    bytes.reserve(
        usize::try_from(len)
            .unwrap_or(0)
            .saturating_sub(bytes.len()),
    );
    file.read_to_end(&mut bytes).map_err(os)?;
    read_beside(&bytes, format, &name, opts, path.parent())
}

/// Checks the first bytes of a file of `len` bytes in `format` (at most [`SNIFF_BYTES`]
/// of them are looked at) for what can be refused without reading the rest: a text format
/// (OBJ, OFF) holding a NUL byte, a `.gltf` file not starting with a JSON object, a `.glb`
/// file without its magic, a PLY file without its magic or whose header's counts
/// exceed the limits, an STL file that is neither ASCII nor a binary file of the length its
/// triangle count requires, or whose count exceeds the limit.
pub fn check_start(
    start: &[u8],
    len: u64,
    format: Format,
    name: &str,
    opts: &ReadOptions,
) -> Result<(), IoError> {
    let start = &start[..start.len().min(SNIFF_BYTES)];
    match format {
        Format::Obj | Format::Off => match start.iter().position(|&b| b == 0) {
            Some(at) => Err(IoError::file(
                name,
                ErrorKind::NotFormat {
                    format,
                    detail: format!("byte {at} is NUL: binary data, not text"),
                },
            )),
            None => Ok(()),
        },
        Format::Ply => ply::check_start(start, name, opts),
        Format::Stl => stl::check_start(start, len, name, opts).map(|_| ()),
        Format::Glb if !start.starts_with(b"glTF") => Err(IoError::file(
            name,
            ErrorKind::NotFormat {
                format,
                detail: "no `glTF` magic at its start".into(),
            },
        )),
        Format::Gltf => match start.iter().find(|b| !b.is_ascii_whitespace()) {
            Some(b'{') | None => Ok(()),
            Some(_) => Err(IoError::file(
                name,
                ErrorKind::NotFormat {
                    format,
                    detail: "it does not start with a JSON object".into(),
                },
            )),
        },
        Format::Glb => Ok(()),
    }
}

/// Reads a mesh from the bytes of a file in `format`; `name` is the file name used in
/// errors.
pub fn read_bytes(
    bytes: &[u8],
    format: Format,
    name: &str,
    opts: &ReadOptions,
) -> Result<Loaded, IoError> {
    read_beside(bytes, format, name, opts, None)
}

/// [`read_bytes`], with the directory where a `.gltf` file's external buffers and images
/// are (none: they cannot be read, and an external buffer is an error).
fn read_beside(
    bytes: &[u8],
    format: Format,
    name: &str,
    opts: &ReadOptions,
    dir: Option<&Path>,
) -> Result<Loaded, IoError> {
    if bytes.is_empty() {
        return Err(IoError::file(name, ErrorKind::Empty));
    }
    check_start(bytes, bytes.len() as u64, format, name, opts)?;
    let (mesh, notes) = match format {
        Format::Obj => obj::read_in(bytes, name, opts, gltf_dir(dir))?,
        Format::Ply => ply::read(bytes, name, opts)?,
        Format::Stl => stl::read(bytes, name, opts)?,
        Format::Off => off::read(bytes, name, opts)?,
        Format::Gltf | Format::Glb => {
            gltf_read::read(bytes, name, opts, gltf_read::Beside(gltf_dir(dir)))?
        }
    };
    debug_assert!(mesh.validate_indices().is_ok());
    Ok(Loaded {
        mesh,
        format,
        notes,
    })
}

/// What writing `mesh` as `format` with `opts` leaves out of what coarsen-io reads:
/// per-corner columns (wedges) a format cannot hold per corner, materials outside glTF,
/// and marked edges outside OBJ and PLY; one sentence each, empty when nothing is lost. (Vertex and face columns OBJ, STL
/// and OFF have no place for are left out as documented for each format.)
pub fn left_out(mesh: &Mesh, format: Format, opts: &WriteOptions) -> Vec<String> {
    let mut out = Vec::new();
    if !opts.attributes {
        return out;
    }
    let per_corner: Vec<&str> = mesh
        .wedges
        .attrs()
        .names()
        .filter(|n| match format {
            Format::Obj => !matches!(*n, "uv" | "normal"),
            Format::Gltf | Format::Glb => !matches!(*n, "uv" | "normal" | "color" | "alpha"),
            Format::Ply | Format::Stl | Format::Off => true,
        })
        .collect();
    if !per_corner.is_empty() {
        out.push(format!(
            "per-corner {} ({} vertices on seams or hard edges) not written: {format} holds no \
             per-corner values (OBJ holds uv and normal, glTF also colours)",
            per_corner
                .iter()
                .map(|n| format!("`{n}`"))
                .collect::<Vec<_>>()
                .join(" and "),
            mesh.wedges.split_vertices()
        ));
    }
    let has_uv = mesh.wedges.attrs().vec2("uv").is_some() || mesh.vertex_attrs.vec2("uv").is_some();
    if matches!(format, Format::Gltf | Format::Glb)
        && !has_uv
        && gltf_write::uses_textures(&mesh.materials)
    {
        out.push(
            "textures of the materials not written: the mesh has no UVs to map them (the \
             materials keep their other settings)"
                .into(),
        );
    }
    if !mesh.materials.is_empty() && !matches!(format, Format::Gltf | Format::Glb) {
        out.push(format!(
            "materials and textures not written: {format} output carries no materials (glTF does)"
        ));
    }
    if !mesh.marked_edges.is_empty() && !matches!(format, Format::Obj | Format::Ply) {
        out.push(format!(
            "{} marked edges not written: {format} output carries none (OBJ and PLY do)",
            mesh.marked_edges.len()
        ));
    }
    out
}

/// A file's folder, `.` for a bare file name.
fn gltf_dir(dir: Option<&Path>) -> Option<&Path> {
    dir.map(|d| {
        if d.as_os_str().is_empty() {
            Path::new(".")
        } else {
            d
        }
    })
}

/// Writes `mesh` to `path` in the format of its extension.
///
/// The bytes go to a temporary file in the same directory, which replaces `path` only once
/// everything is written: a failure never leaves a half-written file nor clobbers an
/// existing one.
pub fn write_path(mesh: &Mesh, path: &Path, opts: &WriteOptions) -> Result<(), IoError> {
    let name = path.display().to_string();
    let format =
        Format::from_path(path).ok_or_else(|| IoError::file(&name, ErrorKind::UnknownFormat))?;
    check_writable(mesh, &name)?;
    write_atomically(path, |w| write_unchecked(mesh, format, w, opts, &name))
}

/// Writes any file through a temporary file in the same directory and a rename, as
/// [`write_path`] does for meshes: `fill` writes the content; on any error the target is
/// left as it was. The file gets the permissions of the file it replaces, or `rw-r--r--`.
pub fn write_atomically(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<&std::fs::File>) -> Result<(), IoError>,
) -> Result<(), IoError> {
    let name = path.display().to_string();
    let os = |e: std::io::Error| IoError::file(&name, e.into());
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let tmp = tempfile::NamedTempFile::new_in(dir).map_err(os)?;
    {
        let mut w = BufWriter::new(tmp.as_file());
        fill(&mut w)?;
        w.flush().map_err(os)?;
    }
    set_output_permissions(tmp.as_file(), path).map_err(os)?;
    tmp.persist(path).map_err(|e| os(e.error))?;
    Ok(())
}

/// Writes `bytes` to `path` atomically (see [`write_atomically`]).
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    let name = path.display().to_string();
    write_atomically(path, |w| {
        w.write_all(bytes)
            .map_err(|e| IoError::file(&name, e.into()))
    })
}

/// Writes `mesh` in `format` to `w`.
pub fn write_to(
    mesh: &Mesh,
    format: Format,
    w: &mut impl Write,
    opts: &WriteOptions,
) -> Result<(), IoError> {
    let name = format!("<{format} output>");
    check_writable(mesh, &name)?;
    write_unchecked(mesh, format, w, opts, &name)
}

/// Refuses meshes whose indices or attribute columns are inconsistent.
fn check_writable(mesh: &Mesh, name: &str) -> Result<(), IoError> {
    mesh.validate_indices()
        .map_err(|e| IoError::file(name, e.into()))
}

fn write_unchecked(
    mesh: &Mesh,
    format: Format,
    w: &mut impl Write,
    opts: &WriteOptions,
    name: &str,
) -> Result<(), IoError> {
    let result = match format {
        Format::Obj => obj::write(mesh, w, opts.attributes).map_err(ErrorKind::from),
        Format::Ply => ply::write(mesh, w, opts.ply_encoding, opts.attributes),
        Format::Stl => stl::write(mesh, w),
        Format::Off => off::write(mesh, w).map_err(ErrorKind::from),
        Format::Gltf => gltf_write::write(mesh, w, false, opts.attributes),
        Format::Glb => gltf_write::write(mesh, w, true, opts.attributes),
    };
    result.map_err(|kind| IoError::file(name, kind))
}

/// Gives the new file the permissions of the file it replaces, or the usual `rw-r--r--`
/// (a temporary file starts private).
fn set_output_permissions(file: &std::fs::File, target: &Path) -> std::io::Result<()> {
    match std::fs::metadata(target) {
        Ok(meta) => file.set_permissions(meta.permissions()),
        #[cfg(unix)]
        Err(_) => {
            use std::os::unix::fs::PermissionsExt;
            file.set_permissions(std::fs::Permissions::from_mode(0o644))
        }
        #[cfg(not(unix))]
        Err(_) => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::{AttrValues, DVec2, DVec3};

    fn tetrahedron() -> Mesh {
        Mesh::new(
            vec![
                DVec3::new(0.1, 0.2, 0.3),
                DVec3::new(1.0 / 3.0, 0.0, -0.0),
                DVec3::new(0.0, 7e-12, 0.0),
                DVec3::new(1e20, 0.5, 1.0),
            ],
            vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
        )
    }

    fn bits(m: &Mesh) -> Vec<[u64; 3]> {
        m.positions
            .iter()
            .map(|p| p.to_array().map(f64::to_bits))
            .collect()
    }

    #[test]
    fn format_comes_from_the_extension_in_any_case() {
        assert_eq!(Format::from_path(Path::new("a/b.OBJ")), Some(Format::Obj));
        assert_eq!(Format::from_path(Path::new("x.Ply")), Some(Format::Ply));
        assert_eq!(Format::from_path(Path::new("x.stl")), Some(Format::Stl));
        assert_eq!(Format::from_path(Path::new("x.off")), Some(Format::Off));
        assert_eq!(Format::from_path(Path::new("x.txt")), None);
        assert_eq!(Format::from_path(Path::new("noext")), None);
        assert_eq!(".ply".parse::<Format>(), Ok(Format::Ply));
        assert_eq!("gltf".parse::<Format>(), Ok(Format::Gltf));
        assert_eq!(Format::from_path(Path::new("x.GLB")), Some(Format::Glb));
        assert!("fbx".parse::<Format>().is_err());
    }

    #[test]
    fn empty_input_is_an_error_naming_the_file_in_every_format() {
        for f in Format::ALL {
            let e = read_bytes(b"", f, "empty.x", &ReadOptions::default()).unwrap_err();
            assert_eq!(e.to_string(), "empty.x: the file is empty");
        }
    }

    #[test]
    fn every_format_round_trips_positions_and_faces() {
        let m = tetrahedron();
        for f in [Format::Obj, Format::Ply, Format::Off] {
            let mut bytes = Vec::new();
            write_to(&m, f, &mut bytes, &WriteOptions::default()).unwrap();
            let back = read_bytes(&bytes, f, "t", &ReadOptions::default()).unwrap();
            assert_eq!(bits(&back.mesh), bits(&m), "{f}");
            assert_eq!(back.mesh.faces, m.faces, "{f}");
            assert_eq!(back.format, f);
        }
        // STL stores f32 corners per triangle: the same triangles come back, positions
        // rounded to f32 and vertices numbered by first appearance.
        let mut bytes = Vec::new();
        write_to(&m, Format::Stl, &mut bytes, &WriteOptions::default()).unwrap();
        let back = read_bytes(&bytes, Format::Stl, "t.stl", &ReadOptions::default()).unwrap();
        assert_eq!(back.mesh.n_vertices(), 4);
        let corners = |m: &Mesh, f32: bool| {
            (0..m.n_faces())
                .map(|f| {
                    m.corners(f)
                        .map(|p| if f32 { p.as_vec3().as_dvec3() } else { p })
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(corners(&back.mesh, false), corners(&m, true));
    }

    #[test]
    fn obj_to_binary_ply_to_obj_keeps_positions_bit_for_bit() {
        let mut m = tetrahedron();
        m.vertex_attrs.insert(
            "uv",
            AttrValues::Vec2(vec![DVec2::ZERO, DVec2::X, DVec2::Y, DVec2::ONE]),
        );
        let opts = WriteOptions::default();
        let mut obj1 = Vec::new();
        write_to(&m, Format::Obj, &mut obj1, &opts).unwrap();
        let a = read_bytes(&obj1, Format::Obj, "a.obj", &ReadOptions::default()).unwrap();
        let mut ply = Vec::new();
        write_to(&a.mesh, Format::Ply, &mut ply, &opts).unwrap();
        let b = read_bytes(&ply, Format::Ply, "b.ply", &ReadOptions::default()).unwrap();
        let mut obj2 = Vec::new();
        write_to(&b.mesh, Format::Obj, &mut obj2, &opts).unwrap();
        let c = read_bytes(&obj2, Format::Obj, "c.obj", &ReadOptions::default()).unwrap();
        assert_eq!(bits(&c.mesh), bits(&m));
        assert_eq!(c.mesh, m);
        assert_eq!(obj1, obj2);
    }

    #[test]
    fn marked_edges_survive_obj_and_ply_and_no_other_format() {
        let mut m = tetrahedron();
        m.marked_edges = vec![[0, 1], [3, 2]];
        for f in Format::ALL {
            let mut bytes = Vec::new();
            write_to(&m, f, &mut bytes, &WriteOptions::default()).unwrap();
            let back = read_bytes(&bytes, f, "t", &ReadOptions::default()).unwrap();
            let carried = matches!(f, Format::Obj | Format::Ply);
            assert_eq!(
                back.mesh.marked_edges.len(),
                2 * usize::from(carried),
                "{f}"
            );
            if carried {
                assert_eq!(back.mesh.marked_edges, m.marked_edges, "{f}");
            }
        }
        // A marked edge naming a missing vertex is refused, as a face would be.
        m.marked_edges.push([1, 4]);
        let e = write_to(&m, Format::Obj, &mut Vec::new(), &WriteOptions::default())
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "<OBJ output>: the mesh to write is invalid: marked edge 2 names vertex 4, but the mesh has 4 vertices"
        );
    }

    #[test]
    fn writing_an_invalid_mesh_is_refused() {
        let mut m = tetrahedron();
        m.faces[1] = [0, 1, 9];
        let e = write_to(&m, Format::Ply, &mut Vec::new(), &WriteOptions::default())
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "<PLY output>: the mesh to write is invalid: face 1 names vertex 9, but the mesh has 4 vertices"
        );
    }

    #[test]
    fn write_path_replaces_the_target_only_on_success() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mesh.ply");
        let m = tetrahedron();
        write_path(&m, &path, &WriteOptions::default()).unwrap();
        let first = std::fs::read(&path).unwrap();
        assert_eq!(read_path(&path, &ReadOptions::default()).unwrap().mesh, m);

        // A failing write (an attribute name PLY cannot hold) leaves the old file intact
        // and no temporary file behind.
        let mut bad = m.clone();
        bad.vertex_attrs
            .insert("two words", AttrValues::Scalar(vec![0.0; 4]));
        let e = write_path(&bad, &path, &WriteOptions::default()).unwrap_err();
        assert!(matches!(e.kind, ErrorKind::BadAttributeName(_)), "{e}");
        assert_eq!(std::fs::read(&path).unwrap(), first);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);

        // An invalid mesh is refused before anything is created.
        let other = dir.path().join("other.obj");
        let mut invalid = m.clone();
        invalid.faces[0] = [0, 0, 99];
        assert!(write_path(&invalid, &other, &WriteOptions::default()).is_err());
        assert!(!other.exists());
    }

    #[cfg(unix)]
    #[test]
    fn written_files_are_readable_by_others_like_ordinary_files() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.off");
        write_path(&tetrahedron(), &path, &WriteOptions::default()).unwrap();
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o644);
    }

    #[test]
    fn a_huge_sparse_file_is_refused_from_its_first_bytes_in_every_format() {
        let dir = tempfile::tempdir().unwrap();
        for f in Format::ALL {
            let path = dir.path().join(format!("sparse.{}", f.extension()));
            let file = std::fs::File::create(&path).unwrap();
            file.set_len(2 << 30).unwrap(); // 2 GiB of zeros, no disk used
            let t = std::time::Instant::now();
            let e = read_path(&path, &ReadOptions::default()).unwrap_err();
            // Refused from the first 64 KiB: far quicker than reading 2 GiB would be.
            assert!(t.elapsed().as_secs_f64() < 2.0, "{f}: {:?}", t.elapsed());
            assert!(matches!(e.kind, ErrorKind::NotFormat { .. }), "{f}: {e}");
            assert!(
                e.to_string().starts_with(&path.display().to_string()),
                "{e}"
            );
        }
        let stl = dir.path().join("sparse.stl");
        let e = read_path(&stl, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.ends_with("binary STL needs 84 + 50 × 0 = 84 bytes for its 0 triangles but the file has 2147483648)"), "{e}");
        let obj = dir.path().join("sparse.obj");
        let e = read_path(&obj, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.ends_with("not an OBJ file (byte 0 is NUL: binary data, not text)"),
            "{e}"
        );
    }

    #[test]
    fn max_file_bytes_refuses_a_long_file_before_reading_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.off");
        write_path(&tetrahedron(), &path, &WriteOptions::default()).unwrap();
        let len = std::fs::metadata(&path).unwrap().len();
        let opts = |limit| ReadOptions {
            max_file_bytes: Some(limit),
            ..Default::default()
        };
        assert!(read_path(&path, &opts(len)).is_ok());
        let e = read_path(&path, &opts(len - 1)).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!(
                "{}: the file has {len} bytes, more than the limit of {} (ReadOptions::max_file_bytes)",
                path.display(),
                len - 1
            )
        );
    }

    #[test]
    fn header_counts_over_the_limits_are_refused_from_the_first_bytes() {
        let opts = ReadOptions {
            max_faces: Some(10),
            max_vertices: Some(10),
            ..Default::default()
        };
        // Only the first bytes are given, with the length of a file of 10^9 triangles.
        let mut stl = vec![0u8; 80];
        stl.extend_from_slice(&1_000_000_000u32.to_le_bytes());
        let len = 84 + 50 * 1_000_000_000u64;
        let e = check_start(&stl, len, Format::Stl, "big.stl", &opts).unwrap_err();
        assert_eq!(
            e.to_string(),
            "big.stl: more than 10 faces (the limit set by ReadOptions::max_faces)"
        );
        let ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 11\nproperty float x\nend_header\n";
        let e = check_start(ply, 1 << 40, Format::Ply, "big.ply", &opts).unwrap_err();
        assert_eq!(
            e.to_string(),
            "big.ply: more than 10 vertices (the limit set by ReadOptions::max_vertices)"
        );
        let ply = b"ply\nformat ascii 1.0\nelement face 11\nproperty list uchar int vertex_indices\nend_header\n";
        let e = check_start(ply, 1 << 40, Format::Ply, "big.ply", &opts).unwrap_err();
        assert_eq!(
            e.to_string(),
            "big.ply: more than 10 faces (the limit set by ReadOptions::max_faces)"
        );
        // A header cut by the end of the first bytes is left to the full read.
        assert!(
            check_start(
                b"ply\nformat ascii 1.0\nelem",
                1 << 40,
                Format::Ply,
                "x.ply",
                &opts
            )
            .is_ok()
        );
    }

    #[test]
    fn text_formats_with_a_nul_byte_are_refused_in_read_bytes_too() {
        let e = read_bytes(
            b"v 0 0 0\n\0",
            Format::Obj,
            "x.obj",
            &ReadOptions::default(),
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.obj: not an OBJ file (byte 8 is NUL: binary data, not text)"
        );
        let e = read_bytes(b"OFF\0", Format::Off, "x.off", &ReadOptions::default()).unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.off: not an OFF file (byte 3 is NUL: binary data, not text)"
        );
    }

    #[test]
    fn read_path_names_missing_files_and_unknown_extensions() {
        let e = read_path(Path::new("/nonexistent/x.obj"), &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("/nonexistent/x.obj: "), "{e}");
        let e = read_path(Path::new("x.fbx"), &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "x.fbx: cannot tell the mesh format from the file name (expected .obj, .ply, .stl, .off, .gltf or .glb)"
        );
    }

    #[test]
    fn what_a_format_cannot_hold_is_said() {
        use coarsen_mesh::Attributes;
        let m = tetrahedron();
        let mut cols = Attributes::default();
        let uv: Vec<DVec2> = (0..12).map(|c| DVec2::new(c as f64, 0.0)).collect();
        cols.insert("uv", AttrValues::Vec2(uv));
        let m = m.with_corner_attributes(cols);
        let all = WriteOptions::default();
        assert!(left_out(&m, Format::Obj, &all).is_empty());
        assert!(left_out(&m, Format::Glb, &all).is_empty());
        assert_eq!(
            left_out(&m, Format::Ply, &all),
            [
                "per-corner `uv` (4 vertices on seams or hard edges) not written: PLY holds no \
              per-corner values (OBJ holds uv and normal, glTF also colours)"
            ]
        );
        let bare = WriteOptions {
            attributes: false,
            ..all
        };
        assert!(left_out(&m, Format::Ply, &bare).is_empty());
        let mut marked = tetrahedron();
        marked.marked_edges = vec![[0, 1], [1, 2]];
        for f in [Format::Obj, Format::Ply] {
            assert!(left_out(&marked, f, &all).is_empty(), "{f}");
        }
        assert_eq!(
            left_out(&marked, Format::Stl, &all),
            ["2 marked edges not written: STL output carries none (OBJ and PLY do)"]
        );
    }
}
