//! STL through the `stl_io` crate, with the checks it lacks done first.
//!
//! Detection: a file is binary when its length is exactly `84 + 50·n` for the triangle
//! count `n` stored at byte 80 — also when its 80-byte header happens to begin with
//! `solid`, as many exporters write; otherwise it is ASCII when it begins with the keyword
//! `solid`; otherwise it is refused, saying both reasons. Checking the size before
//! anything is read means a lying count can never make the reader allocate.
//!
//! STL is a triangle soup. `stl_io` indexes it by giving corners with bit-identical `f32`
//! coordinates one vertex (first seen, first numbered — deterministic), so the mesh is
//! welded by exact position and nothing else (`0.0` and `-0.0` stay apart). Facet normals
//! are not kept: they follow from the corners.
//!
//! The writer writes binary STL: positions rounded to `f32`, facet normals computed from
//! the corners, attributes not written.

use crate::error::{ErrorKind, IoError};
use crate::text::non_finite_name;
use crate::{Format, ReadOptions};
use coarsen_mesh::{DVec3, Mesh};
use std::borrow::Cow;
use std::io::{self, Cursor, Write};
use stl_io::{Normal, Triangle, TriangleIterator, Vertex};

/// How an STL file is encoded, as told by its first bytes and its length.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Detected {
    /// Binary: the length is exactly `84 + 50·n` for the count `n` at byte 80; `solid`
    /// tells whether the header begins with that keyword anyway.
    Binary { solid: bool },
    /// ASCII, the keyword `solid` starting at this offset.
    Ascii { at: usize },
}

/// Tells binary from ASCII STL from the first bytes (`start`, at least 84 of them when the
/// file has that many) and the file's length `len`; refuses a file that is neither, and a
/// binary file whose triangle count exceeds [`ReadOptions::max_faces`] — before anything
/// else is read.
pub(crate) fn check_start(
    start: &[u8],
    len: u64,
    name: &str,
    opts: &ReadOptions,
) -> Result<Detected, IoError> {
    let stored_count = start
        .get(80..84)
        .and_then(|b| b.try_into().ok())
        .map(|b: [u8; 4]| u64::from(u32::from_le_bytes(b)));
    let binary = stored_count.is_some_and(|n| 84 + 50 * n == len);
    let keyword = solid_keyword(start);
    if let (true, Some(n), Some(limit)) = (binary, stored_count, opts.max_faces)
        && n > limit as u64
    {
        return Err(IoError::file(name, ErrorKind::over_limit_faces(limit)));
    }
    match (binary, keyword) {
        (true, k) => return Ok(Detected::Binary { solid: k.is_some() }),
        (false, Some(at)) => return Ok(Detected::Ascii { at }),
        (false, None) => {}
    }
    let detail = match stored_count {
        Some(n) => format!(
            "no `solid` keyword for ASCII, and binary STL needs 84 + 50 × {n} = {} \
             bytes for its {n} triangles but the file has {len}",
            84 + 50 * n,
        ),
        None => format!(
            "no `solid` keyword for ASCII, and {len} bytes are too few for binary STL's \
             84-byte header",
        ),
    };
    Err(IoError::file(
        name,
        ErrorKind::NotFormat {
            format: Format::Stl,
            detail,
        },
    ))
}

/// Reads an STL file's bytes; `name` is used in errors.
pub(crate) fn read(
    bytes: &[u8],
    name: &str,
    opts: &ReadOptions,
) -> Result<(Mesh, Vec<String>), IoError> {
    let detected = check_start(bytes, bytes.len() as u64, name, opts)?;
    // stl_io tells ASCII from binary by a first line starting with "solid ", so hand it
    // bytes where that test gives the answer found here.
    let input: Cow<[u8]> = match detected {
        Detected::Binary { solid: true } => {
            let mut patched = bytes.to_vec();
            patched[..5].copy_from_slice(b"SOLID");
            Cow::Owned(patched)
        }
        Detected::Binary { solid: false } => Cow::Borrowed(bytes),
        Detected::Ascii { at: 0 } if bytes.starts_with(b"solid ") => Cow::Borrowed(bytes),
        Detected::Ascii { at } => {
            let mut patched = b"solid ".to_vec();
            patched.extend_from_slice(&bytes[at + 5..]);
            Cow::Owned(patched)
        }
    };
    let mut cursor = Cursor::new(input.as_ref());
    let inner = stl_io::create_stl_reader(&mut cursor)
        .map_err(|e| IoError::file(name, ErrorKind::Syntax(e.to_string())))?;
    let mut facets = Counted {
        inner,
        read: 0,
        limit: opts.max_faces,
    };
    let indexed = facets.as_indexed_triangles();
    if let Some(limit) = opts.max_faces
        && facets.read > limit as u64
    {
        return Err(IoError::file(name, ErrorKind::over_limit_faces(limit)));
    }
    let indexed = indexed.map_err(|e| {
        let kind = ErrorKind::Syntax(e.to_string());
        IoError::element(name, "facet", facets.read.saturating_sub(1), kind)
    })?;
    if let Some(limit) = opts.max_vertices
        && indexed.vertices.len() > limit
    {
        return Err(IoError::file(name, ErrorKind::over_limit_vertices(limit)));
    }
    if indexed.faces.len() > u32::MAX as usize || indexed.vertices.len() > u32::MAX as usize {
        return Err(IoError::file(
            name,
            ErrorKind::TooMany {
                count: indexed.faces.len() as u64,
                what: "faces",
            },
        ));
    }
    let positions: Vec<DVec3> = indexed
        .vertices
        .iter()
        .map(|v| DVec3::new(v[0].into(), v[1].into(), v[2].into()))
        .collect();
    let mut faces = Vec::with_capacity(indexed.faces.len());
    for (f, t) in indexed.faces.iter().enumerate() {
        let corners = t.vertices.map(|v| v as u32);
        for &v in &corners {
            let p = positions[v as usize];
            if let Some(&bad) = p.to_array().iter().find(|c| !c.is_finite()) {
                let kind = ErrorKind::NonFinite(non_finite_name(bad));
                return Err(IoError::element(name, "facet", f as u64, kind));
            }
        }
        faces.push(corners);
    }
    let notes = vec![format!(
        "STL stores every triangle's corners separately: {} corners welded into {} vertices \
         by identical position",
        3 * faces.len(),
        positions.len()
    )];
    Ok((Mesh::new(positions, faces), notes))
}

/// Where the keyword `solid` starts, when the file begins with it (after blanks) and a
/// blank or the end follows.
fn solid_keyword(bytes: &[u8]) -> Option<usize> {
    let at = bytes.iter().position(|b| !b.is_ascii_whitespace())?;
    let rest = &bytes[at..];
    let after = rest.get(5).copied();
    (rest.starts_with(b"solid") && after.is_none_or(|b| b.is_ascii_whitespace())).then_some(at)
}

/// Counts the facets read and stops one past `limit`.
struct Counted<'a> {
    inner: Box<dyn TriangleIterator<Item = io::Result<Triangle>> + 'a>,
    read: u64,
    limit: Option<usize>,
}

impl Iterator for Counted<'_> {
    type Item = io::Result<Triangle>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.limit.is_some_and(|l| self.read > l as u64) {
            return None;
        }
        let t = self.inner.next()?;
        self.read += 1;
        Some(t)
    }
}

impl TriangleIterator for Counted<'_> {}

/// Writes `mesh` as binary STL.
pub(crate) fn write(mesh: &Mesh, w: &mut impl Write) -> Result<(), ErrorKind> {
    let to_f32 = |p: DVec3| -> Result<Vertex, ErrorKind> {
        let v = p.as_vec3();
        if v.is_finite() {
            Ok(Vertex::new(v.to_array()))
        } else {
            Err(ErrorKind::Unsupported(format!(
                "position ({}, {}, {}) does not fit STL's 32-bit floats",
                p.x, p.y, p.z
            )))
        }
    };
    let vertices: Vec<Vertex> = mesh
        .positions
        .iter()
        .map(|&p| to_f32(p))
        .collect::<Result<_, _>>()?;
    let triangles = mesh.faces.iter().enumerate().map(|(i, f)| Triangle {
        normal: Normal::new(mesh.face_normal(i).as_vec3().to_array()),
        vertices: f.map(|v| vertices[v as usize]),
    });
    stl_io::write_stl(w, triangles)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(bytes: &[u8]) -> Result<(Mesh, Vec<String>), IoError> {
        read(bytes, "t.stl", &ReadOptions::default())
    }

    const ASCII: &str = "solid t
facet normal 0 0 1
  outer loop
    vertex 0 0 0
    vertex 1 0 0
    vertex 0 1 0
  endloop
endfacet
facet normal 0 0 1
  outer loop
    vertex 1 0 0
    vertex 1 1 0
    vertex 0 1 0
  endloop
endfacet
endsolid t
";

    fn binary(header: &[u8; 5], tris: &[[[f32; 3]; 3]]) -> Vec<u8> {
        let mut b = vec![0u8; 80];
        b[..5].copy_from_slice(header);
        b.extend_from_slice(&(tris.len() as u32).to_le_bytes());
        for t in tris {
            b.extend_from_slice(&[0u8; 12]);
            for p in t {
                p.iter().for_each(|c| b.extend_from_slice(&c.to_le_bytes()));
            }
            b.extend_from_slice(&[0, 0]);
        }
        b
    }

    const TWO: [[[f32; 3]; 3]; 2] = [
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
    ];

    #[test]
    fn ascii_soup_is_welded_by_exact_position() {
        let (m, notes) = load(ASCII.as_bytes()).unwrap();
        assert_eq!(m.n_vertices(), 4);
        assert_eq!(m.faces, vec![[0, 1, 2], [1, 3, 2]]);
        assert!(notes[0].contains("6 corners welded into 4 vertices"));
    }

    #[test]
    fn ascii_without_a_solid_name_or_with_leading_blanks_is_read() {
        let src = ASCII.replacen("solid t", "  solid", 1);
        assert_eq!(load(src.as_bytes()).unwrap().0.n_faces(), 2);
    }

    #[test]
    fn binary_is_recognised_even_when_its_header_starts_with_solid() {
        for header in [b"solid", b"\0\0\0\0\0"] {
            let (m, _) = load(&binary(header, &TWO)).unwrap();
            assert_eq!(m.n_vertices(), 4);
            assert_eq!(m.faces, vec![[0, 1, 2], [1, 3, 2]]);
        }
    }

    #[test]
    fn binary_with_a_lying_count_is_refused_before_reading() {
        let mut b = binary(b"\0\0\0\0\0", &TWO);
        b[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = load(&b).unwrap_err().to_string();
        assert_eq!(
            e,
            "t.stl: not an STL file (no `solid` keyword for ASCII, and binary STL needs \
             84 + 50 × 4294967295 = 214748364834 bytes for its 4294967295 triangles but the \
             file has 184)"
        );
        assert!(
            load(b"garbage")
                .unwrap_err()
                .to_string()
                .contains("too few")
        );
    }

    #[test]
    fn nan_corner_names_the_facet() {
        let mut tris = TWO;
        tris[1][1][2] = f32::NAN;
        let e = load(&binary(b"\0\0\0\0\0", &tris)).unwrap_err().to_string();
        assert_eq!(e, "t.stl: facet 1: coordinate is NaN");
    }

    #[test]
    fn malformed_ascii_names_the_facet() {
        let src = ASCII.replacen("vertex 1 1 0", "vertex 1 oops 0", 1);
        let e = load(src.as_bytes()).unwrap_err().to_string();
        assert!(e.starts_with("t.stl: facet 1: "), "{e}");
    }

    #[test]
    fn max_faces_stops_reading_early() {
        let opts = ReadOptions {
            max_faces: Some(1),
            ..Default::default()
        };
        let e = read(ASCII.as_bytes(), "t.stl", &opts)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "t.stl: more than 1 faces (the limit set by ReadOptions::max_faces)"
        );
    }

    #[test]
    fn written_binary_reads_back_with_the_same_faces() {
        let (m, _) = load(ASCII.as_bytes()).unwrap();
        let mut out = Vec::new();
        write(&m, &mut out).unwrap();
        assert_eq!(out.len(), 84 + 50 * 2);
        let (back, _) = load(&out).unwrap();
        assert_eq!(back, m);
        let huge = Mesh::new(vec![DVec3::splat(1e300); 3], vec![[0, 1, 2]]);
        assert!(matches!(
            write(&huge, &mut Vec::new()),
            Err(ErrorKind::Unsupported(_))
        ));
    }
}
