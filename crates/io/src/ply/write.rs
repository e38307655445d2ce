//! Writing PLY: header from the mesh's columns, body through one of three value sinks.

use super::{Scalar, property_names};
use crate::PlyEncoding;
use crate::error::ErrorKind;
use crate::text::write_f64;
use coarsen_mesh::{AttrKind, AttrValues, Attributes, Mesh};
use std::io::{self, Write};

/// Bytes gathered before each write to the output.
const CHUNK: usize = 1 << 16;

/// Where element values go: binary in either byte order, or text.
trait Sink {
    fn f64(&mut self, x: f64);
    fn u32(&mut self, x: u32);
    fn u8(&mut self, x: u8);
    /// Ends one element (a line break in text).
    fn end(&mut self) -> io::Result<()>;
    /// Writes out whatever is buffered.
    fn flush(&mut self) -> io::Result<()>;
}

/// Binary values, gathered in a buffer.
struct Bin<'w, W: Write, const BE: bool> {
    buf: Vec<u8>,
    w: &'w mut W,
}

impl<W: Write, const BE: bool> Sink for Bin<'_, W, BE> {
    #[inline]
    fn f64(&mut self, x: f64) {
        self.buf
            .extend_from_slice(&if BE { x.to_be_bytes() } else { x.to_le_bytes() });
    }

    #[inline]
    fn u32(&mut self, x: u32) {
        self.buf
            .extend_from_slice(&if BE { x.to_be_bytes() } else { x.to_le_bytes() });
    }

    #[inline]
    fn u8(&mut self, x: u8) {
        self.buf.push(x);
    }

    #[inline]
    fn end(&mut self) -> io::Result<()> {
        if self.buf.len() >= CHUNK {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> io::Result<()> {
        self.w.write_all(&self.buf)?;
        self.buf.clear();
        Ok(())
    }
}

/// Text values separated by spaces, one element per line.
struct Text<'w, W: Write> {
    buf: Vec<u8>,
    w: &'w mut W,
    first: bool,
}

impl<W: Write> Text<'_, W> {
    fn sep(&mut self) {
        if !self.first {
            self.buf.push(b' ');
        }
        self.first = false;
    }
}

impl<W: Write> Sink for Text<'_, W> {
    fn f64(&mut self, x: f64) {
        self.sep();
        // Writing into a Vec cannot fail.
        let _ = write_f64(&mut self.buf, x);
    }

    fn u32(&mut self, x: u32) {
        self.sep();
        let _ = write!(self.buf, "{x}");
    }

    fn u8(&mut self, x: u8) {
        self.u32(u32::from(x));
    }

    fn end(&mut self) -> io::Result<()> {
        self.buf.push(b'\n');
        self.first = true;
        if self.buf.len() >= CHUNK {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> io::Result<()> {
        self.w.write_all(&self.buf)?;
        self.buf.clear();
        Ok(())
    }
}

/// Writes `mesh` as PLY in `encoding`, with its attributes when `attributes` is true.
pub(crate) fn write(
    mesh: &Mesh,
    w: &mut impl Write,
    encoding: PlyEncoding,
    attributes: bool,
) -> Result<(), ErrorKind> {
    let none = Attributes::default();
    let (vattrs, fattrs, edges) = if attributes {
        (&mesh.vertex_attrs, &mesh.face_attrs, &mesh.marked_edges[..])
    } else {
        (&none, &none, &[][..])
    };
    let index_type = if mesh.n_vertices() > i32::MAX as usize {
        Scalar::U32
    } else {
        Scalar::I32
    };
    let mut header = String::from("ply\n");
    header.push_str(match encoding {
        PlyEncoding::Ascii => "format ascii 1.0\n",
        PlyEncoding::BinaryLittleEndian => "format binary_little_endian 1.0\n",
        PlyEncoding::BinaryBigEndian => "format binary_big_endian 1.0\n",
    });
    header.push_str("comment written by coarsen\n");
    header += &format!("element vertex {}\n", mesh.n_vertices());
    let mut taken = vec!["x".to_string(), "y".to_string(), "z".to_string()];
    header.push_str("property double x\nproperty double y\nproperty double z\n");
    declare(&mut header, vattrs, &mut taken, "vertex")?;
    header += &format!(
        "element face {}\nproperty list uchar {} vertex_indices\n",
        mesh.n_faces(),
        index_type.name()
    );
    let mut taken = vec!["vertex_indices".to_string()];
    declare(&mut header, fattrs, &mut taken, "face")?;
    if !edges.is_empty() {
        let t = index_type.name();
        header += &format!(
            "element edge {}\nproperty {t} vertex1\nproperty {t} vertex2\n",
            edges.len()
        );
    }
    header.push_str("end_header\n");
    w.write_all(header.as_bytes())?;
    let buf = Vec::with_capacity(CHUNK + 1024);
    match encoding {
        PlyEncoding::Ascii => body(
            mesh,
            (vattrs, fattrs, edges),
            &mut Text {
                buf,
                w,
                first: true,
            },
        )?,
        PlyEncoding::BinaryLittleEndian => body(
            mesh,
            (vattrs, fattrs, edges),
            &mut Bin::<_, false> { buf, w },
        )?,
        PlyEncoding::BinaryBigEndian => body(
            mesh,
            (vattrs, fattrs, edges),
            &mut Bin::<_, true> { buf, w },
        )?,
    }
    Ok(())
}

/// Adds the property lines of `attrs` to `header`, refusing names PLY cannot hold and
/// names already `taken` in the element.
fn declare(
    header: &mut String,
    attrs: &Attributes,
    taken: &mut Vec<String>,
    element: &'static str,
) -> Result<(), ErrorKind> {
    for (name, values) in attrs.iter() {
        if name.is_empty() || !name.bytes().all(|b| b.is_ascii_graphic()) {
            return Err(ErrorKind::BadAttributeName(name.to_string()));
        }
        let kind = values.kind();
        let ty = match kind {
            AttrKind::Scalar | AttrKind::Vec2 | AttrKind::Vec3 => Scalar::F64,
            AttrKind::Label => Scalar::U32,
            AttrKind::Color => Scalar::U8,
        };
        for property in property_names(name, kind) {
            if taken.contains(&property) {
                return Err(ErrorKind::NameClash { element, property });
            }
            header.push_str(&format!("property {} {property}\n", ty.name()));
            taken.push(property);
        }
    }
    Ok(())
}

/// Writes value `i` of every column.
#[inline]
fn columns(sink: &mut impl Sink, attrs: &Attributes, i: usize) {
    for (_, values) in attrs.iter() {
        match values {
            AttrValues::Scalar(v) => sink.f64(v[i]),
            AttrValues::Label(v) => sink.u32(v[i]),
            AttrValues::Vec2(v) => v[i].to_array().into_iter().for_each(|x| sink.f64(x)),
            AttrValues::Vec3(v) => v[i].to_array().into_iter().for_each(|x| sink.f64(x)),
            AttrValues::Color(v) => v[i].into_iter().for_each(|x| sink.u8(x)),
        }
    }
}

/// What the body holds besides positions and faces: the vertex and face columns and the
/// marked edges written.
type Extras<'m> = (&'m Attributes, &'m Attributes, &'m [[u32; 2]]);

/// Writes every vertex, face and marked edge. The caller has checked that every column has
/// one value per element.
fn body(mesh: &Mesh, (vattrs, fattrs, edges): Extras<'_>, sink: &mut impl Sink) -> io::Result<()> {
    for (i, p) in mesh.positions.iter().enumerate() {
        sink.f64(p.x);
        sink.f64(p.y);
        sink.f64(p.z);
        columns(sink, vattrs, i);
        sink.end()?;
    }
    for (i, f) in mesh.faces.iter().enumerate() {
        sink.u8(3);
        f.iter().for_each(|&v| sink.u32(v));
        columns(sink, fattrs, i);
        sink.end()?;
    }
    for e in edges {
        e.iter().for_each(|&v| sink.u32(v));
        sink.end()?;
    }
    sink.flush()
}

#[cfg(test)]
mod tests {
    use super::super::read;
    use super::*;
    use crate::ReadOptions;
    use coarsen_mesh::{DVec2, DVec3};

    /// A square of two triangles with one attribute column of every kind on both domains.
    fn decorated() -> Mesh {
        let mut m = Mesh::new(
            vec![
                DVec3::new(0.1, 0.2, 0.3),
                DVec3::new(1.0 / 3.0, -0.0, 1e-300),
                DVec3::new(2.5e300, 7.0, -1.5),
                DVec3::new(0.0, 1.0, 0.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let v = &mut m.vertex_attrs;
        v.insert("normal", AttrValues::Vec3(vec![DVec3::Z; 4]));
        v.insert(
            "color",
            AttrValues::Color(vec![[1, 2, 3], [255, 0, 9], [0; 3], [7; 3]]),
        );
        v.insert("uv", AttrValues::Vec2(vec![DVec2::new(0.25, 0.75); 4]));
        v.insert("k", AttrValues::Scalar(vec![0.1, -2.0, 3.5, 1e-9]));
        v.insert("cluster", AttrValues::Label(vec![0, 4_000_000_000, 2, 3]));
        v.insert("disp", AttrValues::Vec3(vec![DVec3::new(0.1, 0.2, 0.3); 4]));
        v.insert("tex2", AttrValues::Vec2(vec![DVec2::new(1.0, 2.0); 4]));
        v.insert("tint", AttrValues::Color(vec![[9, 8, 7]; 4]));
        let f = &mut m.face_attrs;
        f.insert("part", AttrValues::Label(vec![5, 6]));
        f.insert("err", AttrValues::Scalar(vec![0.5, 1.0 / 7.0]));
        f.insert("color", AttrValues::Color(vec![[10, 20, 30], [40, 50, 60]]));
        m
    }

    fn round_trip(m: &Mesh, encoding: PlyEncoding) -> (Mesh, Vec<String>) {
        let mut bytes = Vec::new();
        write(m, &mut bytes, encoding, true).unwrap();
        read(&bytes, "t.ply", &ReadOptions::default()).unwrap()
    }

    /// The three PLY encodings.
    const ENCODINGS: [PlyEncoding; 3] = [
        PlyEncoding::Ascii,
        PlyEncoding::BinaryLittleEndian,
        PlyEncoding::BinaryBigEndian,
    ];

    #[test]
    fn every_encoding_round_trips_positions_faces_and_all_attribute_kinds() {
        let m = decorated();
        for encoding in ENCODINGS {
            let (back, notes) = round_trip(&m, encoding);
            assert!(notes.is_empty(), "{encoding:?}: {notes:?}");
            let bits = |m: &Mesh| {
                m.positions
                    .iter()
                    .map(|p| p.to_array().map(f64::to_bits))
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&back), bits(&m), "{encoding:?}");
            assert_eq!(back, m, "{encoding:?}");
        }
    }

    #[test]
    fn marked_edges_round_trip_as_an_edge_element_in_every_encoding() {
        let mut m = decorated();
        m.marked_edges = vec![[2, 0], [0, 1], [3, 2]];
        for encoding in ENCODINGS {
            let (back, notes) = round_trip(&m, encoding);
            assert!(notes.is_empty(), "{encoding:?}: {notes:?}");
            assert_eq!(back, m, "{encoding:?}");
        }
        let mut bytes = Vec::new();
        write(&m, &mut bytes, PlyEncoding::Ascii, true).unwrap();
        let text = String::from_utf8(bytes).unwrap();
        assert!(
            text.contains(
                "element edge 3\nproperty int vertex1\nproperty int vertex2\nend_header\n"
            ),
            "{text}"
        );
        assert!(text.ends_with("\n2 0\n0 1\n3 2\n"), "{text}");
        // Positions and faces only: no edge element.
        let mut bytes = Vec::new();
        write(&m, &mut bytes, PlyEncoding::Ascii, false).unwrap();
        assert!(!String::from_utf8(bytes).unwrap().contains("element edge"));
    }

    #[test]
    fn binary_output_is_the_expected_bytes() {
        let m = Mesh::new(vec![DVec3::X, DVec3::Y, DVec3::Z], vec![[0, 1, 2]]);
        let mut bytes = Vec::new();
        write(&m, &mut bytes, PlyEncoding::BinaryLittleEndian, true).unwrap();
        let header = "ply\nformat binary_little_endian 1.0\ncomment written by coarsen\n\
            element vertex 3\nproperty double x\nproperty double y\nproperty double z\n\
            element face 1\nproperty list uchar int vertex_indices\nend_header\n";
        assert_eq!(&bytes[..header.len()], header.as_bytes());
        assert_eq!(bytes.len(), header.len() + 3 * 24 + 13);
        assert_eq!(&bytes[header.len()..header.len() + 8], &1f64.to_le_bytes());
        assert_eq!(
            &bytes[bytes.len() - 13..],
            &[3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]
        );
    }

    #[test]
    fn attributes_can_be_left_out() {
        let m = decorated();
        let mut bytes = Vec::new();
        write(&m, &mut bytes, PlyEncoding::BinaryLittleEndian, false).unwrap();
        let (back, _) = read(&bytes, "t.ply", &ReadOptions::default()).unwrap();
        assert!(back.vertex_attrs.is_empty() && back.face_attrs.is_empty());
        assert_eq!(back.positions, m.positions);
    }

    #[test]
    fn names_that_clash_or_hold_spaces_are_refused() {
        let mut m = Mesh::new(vec![DVec3::X], vec![]);
        m.vertex_attrs.insert("x", AttrValues::Scalar(vec![1.0]));
        let e = write(&m, &mut Vec::new(), PlyEncoding::Ascii, true).unwrap_err();
        assert_eq!(
            e.to_string(),
            "two properties of the vertex element would be called `x`"
        );
        let mut m = Mesh::new(vec![DVec3::X], vec![]);
        m.vertex_attrs.insert("a b", AttrValues::Scalar(vec![1.0]));
        let e = write(&m, &mut Vec::new(), PlyEncoding::Ascii, true).unwrap_err();
        assert!(matches!(e, ErrorKind::BadAttributeName(n) if n == "a b"));
    }
}
