//! OFF (Object File Format): reader and writer.
//!
//! Read: an optional header keyword `OFF` with the prefixes `ST`, `C` and `N` tolerated
//! (`COFF`, `NOFF`, `CNOFF`, `STOFF`, …), the counts `vertices faces [edges]` (on the
//! keyword's line or the next), one vertex per line (`x y z`, anything after — normals,
//! colours, texture coordinates — ignored with a note), one face per line (`n i0 … in-1`,
//! indices from 0, a trailing colour ignored with a note), `#` comments and blank lines
//! anywhere. Polygons are split as a fan from their first corner. Binary OFF and other
//! dimensions (`4OFF`, `nOFF`) are refused. The counts never drive allocation beyond what
//! the remaining bytes could hold.
//!
//! Write: `OFF`, the counts, `x y z` in shortest round-trip decimals, `3 a b c`.

use crate::error::{ErrorKind, IoError, RefKind};
use crate::text::{self, Lines, non_finite_name, parse_f64, parse_i64, show};
use crate::{Format, ReadOptions};
use coarsen_mesh::{DVec3, Mesh};
use std::io::{self, Write};

/// Fewest bytes of one vertex line (`0 0 0\n`) and one face line (`3 0 0 0\n`).
const MIN_VERTEX_BYTES: u64 = 6;
const MIN_FACE_BYTES: u64 = 8;

/// The next line with a token on it, as its number and tokens.
fn next_tokens<'l>(lines: &'l mut Lines<'_>) -> Option<(usize, Vec<&'l [u8]>)> {
    loop {
        let n = lines.advance()?;
        if text::tokens(lines.current()).next().is_some() {
            return Some((n, text::tokens(lines.current()).collect()));
        }
    }
}

/// Reads an OFF file's bytes; `name` is used in errors.
pub(crate) fn read(
    bytes: &[u8],
    name: &str,
    opts: &ReadOptions,
) -> Result<(Mesh, Vec<String>), IoError> {
    let mut lines = Lines::new(bytes);
    let mut notes = Vec::new();
    let (nv, nf, count_line) = read_counts(&mut lines, name, &mut notes)?;
    check_counts(nv, nf, count_line, lines.remaining() as u64, name, opts)?;
    let (positions, extra_vertex_values) = read_vertices(&mut lines, nv, name)?;
    let (faces, extra_face_values) = read_faces(&mut lines, nv, nf, name, opts)?;
    if extra_vertex_values > 0 {
        notes.push(format!(
            "{extra_vertex_values} vertices have values after x y z (normals, colours or \
             texture coordinates); ignored"
        ));
    }
    if extra_face_values > 0 {
        notes.push(format!(
            "{extra_face_values} faces have values after their indices (colours); ignored"
        ));
    }
    if next_tokens(&mut lines).is_some() {
        notes.push("lines after the last face ignored".into());
    }
    Ok((Mesh::new(positions, faces), notes))
}

/// A syntax error at `line` of `name`.
fn syntax(name: &str, line: usize, msg: String) -> IoError {
    IoError::line(name, line, ErrorKind::Syntax(msg))
}

/// The header keyword (prefixes noted) and the counts `vertices faces [edges]`, on its
/// line or the next: the vertex and face counts and the counts' line.
fn read_counts(
    lines: &mut Lines<'_>,
    name: &str,
    notes: &mut Vec<String>,
) -> Result<(u64, u64, usize), IoError> {
    let Some((line, first)) = next_tokens(lines) else {
        return Err(IoError::file(
            name,
            ErrorKind::NotFormat {
                format: Format::Off,
                detail: "nothing but blanks and comments".into(),
            },
        ));
    };
    let mut counts: Vec<u64> = Vec::new();
    let mut count_line = line;
    let rest: &[&[u8]] = match first[0].strip_suffix(b"OFF") {
        Some(prefix) => {
            check_prefix(prefix, name, line, notes)?;
            &first[1..]
        }
        None if parse_i64(first[0]).is_some() => &first[..],
        None => {
            return Err(IoError::line(
                name,
                line,
                ErrorKind::NotFormat {
                    format: Format::Off,
                    detail: format!("`{}` is not an OFF header", show(first[0])),
                },
            ));
        }
    };
    if rest
        .first()
        .is_some_and(|t| t.eq_ignore_ascii_case(b"BINARY"))
    {
        return Err(IoError::line(
            name,
            line,
            ErrorKind::Unsupported("binary OFF".into()),
        ));
    }
    let parse_counts = |toks: &[&[u8]], line: usize, out: &mut Vec<u64>| {
        for t in toks {
            let n = parse_i64(t)
                .and_then(|n| u64::try_from(n).ok())
                .ok_or_else(|| syntax(name, line, format!("`{}` is not a count", show(t))))?;
            out.push(n);
        }
        Ok::<(), IoError>(())
    };
    parse_counts(rest, line, &mut counts)?;
    if counts.is_empty() {
        let Some((line, toks)) = next_tokens(lines) else {
            return Err(syntax(
                name,
                line,
                "the vertex and face counts are missing".into(),
            ));
        };
        count_line = line;
        parse_counts(&toks, line, &mut counts)?;
    }
    match counts[..] {
        [nv, nf] | [nv, nf, _] => Ok((nv, nf, count_line)),
        _ => Err(syntax(
            name,
            count_line,
            format!(
                "expected `vertices faces [edges]` counts, found {} numbers",
                counts.len()
            ),
        )),
    }
}

/// Refuses counts that the `remaining` bytes cannot hold (so that reserving them is
/// safe), that pass the reader's limits, or that 32-bit indices cannot address.
fn check_counts(
    nv: u64,
    nf: u64,
    count_line: usize,
    remaining: u64,
    name: &str,
    opts: &ReadOptions,
) -> Result<(), IoError> {
    // The last line may lack its line break.
    let budget = u128::from(remaining) + 1;
    if u128::from(nv) * u128::from(MIN_VERTEX_BYTES) > budget {
        return Err(too_large(name, nv, "vertices", remaining));
    }
    if u128::from(nv) * u128::from(MIN_VERTEX_BYTES) + u128::from(nf) * u128::from(MIN_FACE_BYTES)
        > budget
    {
        return Err(too_large(name, nf, "faces", remaining));
    }
    if let Some(limit) = opts.max_vertices
        && nv > limit as u64
    {
        return Err(IoError::line(
            name,
            count_line,
            ErrorKind::over_limit_vertices(limit),
        ));
    }
    // Every polygon gives at least one triangle.
    if let Some(limit) = opts.max_faces
        && nf > limit as u64
    {
        return Err(IoError::line(
            name,
            count_line,
            ErrorKind::over_limit_faces(limit),
        ));
    }
    if nv > u64::from(u32::MAX) {
        let kind = ErrorKind::TooMany {
            count: nv,
            what: "vertices",
        };
        return Err(IoError::line(name, count_line, kind));
    }
    Ok(())
}

/// The `nv` vertex lines: the positions, and how many lines had values after `x y z`.
fn read_vertices(
    lines: &mut Lines<'_>,
    nv: u64,
    name: &str,
) -> Result<(Vec<DVec3>, usize), IoError> {
    // The count is bounded by the bytes left (`check_counts`), so reserving it is safe.
    let mut positions = Vec::with_capacity(nv as usize);
    let mut extra_vertex_values = 0usize;
    for i in 0..nv {
        let Some((line, toks)) = next_tokens(lines) else {
            return Err(syntax(
                name,
                lines.line(),
                format!("the file ends before vertex {i}"),
            ));
        };
        let at = |kind| IoError::line_element(name, line, "vertex", i, kind);
        if toks.len() < 3 {
            let msg = format!("needs 3 coordinates, found {}", toks.len());
            return Err(at(ErrorKind::Syntax(msg)));
        }
        let mut p = [0.0; 3];
        for (c, t) in p.iter_mut().zip(&toks) {
            *c = parse_f64(t)
                .ok_or_else(|| at(ErrorKind::Syntax(format!("`{}` is not a number", show(t)))))?;
            if !c.is_finite() {
                return Err(at(ErrorKind::NonFinite(non_finite_name(*c))));
            }
        }
        extra_vertex_values += usize::from(toks.len() > 3);
        positions.push(DVec3::from_array(p));
    }
    Ok((positions, extra_vertex_values))
}

/// The `nf` face lines over `nv` vertices, each polygon split as a fan from its first
/// corner: the triangles, and how many lines had values after their indices.
fn read_faces(
    lines: &mut Lines<'_>,
    nv: u64,
    nf: u64,
    name: &str,
    opts: &ReadOptions,
) -> Result<(Vec<[u32; 3]>, usize), IoError> {
    // The count is bounded by the bytes left (`check_counts`), so reserving it is safe.
    let mut faces: Vec<[u32; 3]> = Vec::with_capacity(nf as usize);
    let mut extra_face_values = 0usize;
    let mut poly: Vec<u32> = Vec::new();
    for i in 0..nf {
        let Some((line, toks)) = next_tokens(lines) else {
            return Err(syntax(
                name,
                lines.line(),
                format!("the file ends before face {i}"),
            ));
        };
        let at = |kind| IoError::line_element(name, line, "face", i, kind);
        let n = parse_i64(toks[0])
            .and_then(|n| usize::try_from(n).ok())
            .ok_or_else(|| {
                at(ErrorKind::Syntax(format!(
                    "`{}` is not a corner count",
                    show(toks[0])
                )))
            })?;
        if n < 3 {
            let msg = format!("a face needs at least 3 corners, this one has {n}");
            return Err(at(ErrorKind::Syntax(msg)));
        }
        if toks.len() < n + 1 {
            let msg = format!("{n} corners announced, {} given", toks.len() - 1);
            return Err(at(ErrorKind::Syntax(msg)));
        }
        poly.clear();
        for t in &toks[1..=n] {
            let v = parse_i64(t).ok_or_else(|| {
                at(ErrorKind::Syntax(format!(
                    "`{}` is not a vertex index",
                    show(t)
                )))
            })?;
            if v < 0 || v as u64 >= nv {
                return Err(at(ErrorKind::OutOfRange {
                    by: "face",
                    what: RefKind::Vertex,
                    index: v,
                    count: nv,
                }));
            }
            poly.push(v as u32);
        }
        extra_face_values += usize::from(toks.len() > n + 1);
        let total = faces.len() + n - 2;
        if let Some(limit) = opts.max_faces
            && total > limit
        {
            return Err(at(ErrorKind::over_limit_faces(limit)));
        }
        if total > u32::MAX as usize {
            return Err(at(ErrorKind::TooMany {
                count: total as u64,
                what: "faces",
            }));
        }
        faces.extend(poly[1..].windows(2).map(|w| [poly[0], w[0], w[1]]));
    }
    Ok((faces, extra_face_values))
}

/// Accepts the `ST`, `C` and `N` prefixes of the header keyword (in that order).
fn check_prefix(
    prefix: &[u8],
    name: &str,
    line: usize,
    notes: &mut Vec<String>,
) -> Result<(), IoError> {
    let mut rest = prefix;
    for (p, what) in [
        (&b"ST"[..], "texture coordinates"),
        (b"C", "colours"),
        (b"N", "normals"),
    ] {
        if let Some(r) = rest.strip_prefix(p) {
            rest = r;
            notes.push(format!(
                "{}OFF: vertex {what} are not kept",
                String::from_utf8_lossy(prefix)
            ));
        }
    }
    match rest {
        [] => Ok(()),
        b"4" | b"n" | b"4n" => Err(IoError::line(
            name,
            line,
            ErrorKind::Unsupported(format!(
                "{}OFF (only 3-D vertices are read)",
                String::from_utf8_lossy(prefix)
            )),
        )),
        _ => Err(IoError::line(
            name,
            line,
            ErrorKind::NotFormat {
                format: Format::Off,
                detail: format!("`{}OFF` is not an OFF header", show(prefix)),
            },
        )),
    }
}

fn too_large(name: &str, count: u64, what: &str, remaining: u64) -> IoError {
    IoError::file(
        name,
        ErrorKind::CountTooLarge {
            count,
            what: what.into(),
            remaining,
        },
    )
}

/// Writes `mesh` as OFF.
pub(crate) fn write(mesh: &Mesh, w: &mut impl Write) -> io::Result<()> {
    writeln!(w, "OFF\n{} {} 0", mesh.n_vertices(), mesh.n_faces())?;
    for p in &mesh.positions {
        text::write_f64(w, p.x)?;
        w.write_all(b" ")?;
        text::write_f64(w, p.y)?;
        w.write_all(b" ")?;
        text::write_f64(w, p.z)?;
        w.write_all(b"\n")?;
    }
    for [a, b, c] in &mesh.faces {
        writeln!(w, "3 {a} {b} {c}")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(src: &str) -> Result<(Mesh, Vec<String>), IoError> {
        read(src.as_bytes(), "t.off", &ReadOptions::default())
    }

    fn err(src: &str) -> String {
        load(src).unwrap_err().to_string()
    }

    #[test]
    fn a_face_count_over_max_faces_is_refused_at_the_header() {
        let opts = ReadOptions {
            max_faces: Some(2),
            ..Default::default()
        };
        let src = "OFF\n3 3 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n3 0 1 2\n";
        let e = read(src.as_bytes(), "t.off", &opts)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "t.off:2: more than 2 faces (the limit set by ReadOptions::max_faces)"
        );
        // Polygons count by their triangles while reading.
        let src = "OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n3 0 1 2\n";
        let e = read(src.as_bytes(), "t.off", &opts)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "t.off:8: face 1: more than 2 faces (the limit set by ReadOptions::max_faces)"
        );
    }

    #[test]
    fn comments_blank_lines_and_polygons_are_read() {
        let src = "OFF # a square and a triangle\n\n4 3 0\n0 0 0\n1 0 0\n# middle\n1 1 0\n0 1 0\n\
                   4 0 1 2 3\n3 0 1 2\n3 3 2 1\n";
        let (m, notes) = load(src).unwrap();
        assert_eq!(m.n_vertices(), 4);
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [0, 1, 2], [3, 2, 1]]);
        assert!(notes.is_empty(), "{notes:?}");
    }

    #[test]
    fn coloured_and_normal_variants_are_tolerated_with_notes() {
        let src = "CNOFF 3 1 0\n0 0 0 0 0 1 255 0 0 255\n1 0 0 0 0 1 0 255 0 255\n\
                   0 1 0 0 0 1 0 0 255 255\n3 0 1 2 0.5 0.5 0.5\n";
        let (m, notes) = load(src).unwrap();
        assert_eq!(m.faces, vec![[0, 1, 2]]);
        assert_eq!(notes.len(), 4, "{notes:?}");
    }

    #[test]
    fn a_file_without_keyword_starts_with_its_counts() {
        let (m, _) = load("3 1\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2").unwrap();
        assert_eq!(m.n_faces(), 1);
    }

    #[test]
    fn absurd_counts_are_refused_before_allocating() {
        assert_eq!(
            err("OFF\n1000000000000 1 0\n0 0 0\n"),
            "t.off: header promises 1000000000000 vertices but the file has only 6 bytes left"
        );
        assert_eq!(
            err("OFF\n3 1000000000000 0\n0 0 0\n1 0 0\n0 1 0\n"),
            "t.off: header promises 1000000000000 faces but the file has only 18 bytes left"
        );
    }

    #[test]
    fn malformed_files_name_the_line_and_element() {
        assert_eq!(
            err("PLY\n"),
            "t.off:1: not an OFF file (`PLY` is not an OFF header)"
        );
        assert!(err("4OFF\n").contains("unsupported: 4OFF"));
        assert!(err("OFF BINARY\n").contains("unsupported: binary OFF"));
        assert_eq!(
            err("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"),
            "t.off:6: face 0: face refers to vertex 3 but only 3 vertices are defined"
        );
        assert_eq!(
            err("OFF\n3 1 0\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n"),
            "t.off:4: vertex 1: coordinate is NaN"
        );
        assert_eq!(
            err("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n# no face after all\n"),
            "t.off:6: the file ends before face 0"
        );
        assert_eq!(
            err("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n"),
            "t.off:6: face 0: 4 corners announced, 3 given"
        );
        assert_eq!(
            err("OFF\n"),
            "t.off:1: the vertex and face counts are missing"
        );
        assert_eq!(
            err("# only a comment\n"),
            "t.off: not an OFF file (nothing but blanks and comments)"
        );
    }

    #[test]
    fn written_off_reads_back_bit_for_bit() {
        let m = Mesh::new(
            vec![DVec3::new(0.1, 1.0 / 3.0, -1e-200), DVec3::X, DVec3::Y],
            vec![[0, 1, 2], [2, 1, 0]],
        );
        let mut out = Vec::new();
        write(&m, &mut out).unwrap();
        assert_eq!(load(std::str::from_utf8(&out).unwrap()).unwrap().0, m);
    }
}
