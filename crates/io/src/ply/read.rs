//! Reading PLY bodies: one element loop over two value sources (ASCII tokens, binary
//! bytes), with fast paths for the common binary layouts.

use super::{
    ColumnPlan, Element, Encoding, HeaderProblem, PropKind, Scalar, columns, parse_header,
};
use crate::error::{ErrorKind, IoError, RefKind, plural};
use crate::text::{non_finite_name, parse_f64, parse_i64, show};
use crate::{Format, ReadOptions};
use coarsen_mesh::{AttrKind, AttrValues, Attributes, DVec2, DVec3, Mesh};

/// Why a value could not be read.
enum Miss {
    /// The body ends; `need` bytes were wanted (binary) at the current offset.
    End { need: usize },
    /// A token or value that does not fit its type.
    Bad(String),
}

/// A stream of PLY values: ASCII tokens or binary bytes.
trait Source<'a> {
    /// The next value of type `t`.
    fn value(&mut self, t: Scalar) -> Result<f64, Miss>;
    /// Skips one value of type `t`.
    fn skip(&mut self, t: Scalar) -> Result<(), Miss>;
    /// Skips `n` values of type `t`.
    fn skip_n(&mut self, t: Scalar, n: usize) -> Result<(), Miss>;
    /// Current byte offset in the file.
    fn offset(&self) -> usize;
    /// Bytes left.
    fn remaining(&self) -> usize;
    /// The line of the last token (ASCII only).
    fn line(&self) -> Option<usize>;
    /// The fewest bytes one value takes (1 binary byte, or 1 character plus a separator).
    fn min_size(&self, t: Scalar) -> u64;
    /// The raw bytes, position and byte order (binary only), for the fast paths.
    fn binary(&mut self) -> Option<(&'a [u8], &mut usize, bool)>;

    /// The next value as an integer (list counts and indices).
    fn int(&mut self, t: Scalar) -> Result<i64, Miss> {
        let x = self.value(t)?;
        if x.fract() == 0.0 && x.abs() < 9.0e15 {
            Ok(x as i64)
        } else {
            Err(Miss::Bad(format!("{x} is not an integer")))
        }
    }
}

/// Decodes a scalar of type `t` from the start of `b`.
#[inline(always)]
fn get<const BE: bool>(b: &[u8], t: Scalar) -> Option<f64> {
    macro_rules! rd {
        ($ty:ty, $n:literal) => {{
            let a = *b.first_chunk::<$n>()?;
            f64::from(if BE {
                <$ty>::from_be_bytes(a)
            } else {
                <$ty>::from_le_bytes(a)
            })
        }};
    }
    Some(match t {
        Scalar::I8 => f64::from(*b.first()? as i8),
        Scalar::U8 => f64::from(*b.first()?),
        Scalar::I16 => rd!(i16, 2),
        Scalar::U16 => rd!(u16, 2),
        Scalar::I32 => rd!(i32, 4),
        Scalar::U32 => rd!(u32, 4),
        Scalar::F32 => rd!(f32, 4),
        Scalar::F64 => rd!(f64, 8),
    })
}

/// A binary body.
struct Bin<'a, const BE: bool> {
    data: &'a [u8],
    pos: usize,
}

impl<'a, const BE: bool> Source<'a> for Bin<'a, BE> {
    #[inline]
    fn value(&mut self, t: Scalar) -> Result<f64, Miss> {
        let x = self.data.get(self.pos..).and_then(|b| get::<BE>(b, t));
        let x = x.ok_or(Miss::End { need: t.size() })?;
        self.pos += t.size();
        Ok(x)
    }

    fn skip(&mut self, t: Scalar) -> Result<(), Miss> {
        self.skip_n(t, 1)
    }

    fn skip_n(&mut self, t: Scalar, n: usize) -> Result<(), Miss> {
        let need = n.saturating_mul(t.size());
        if need > self.remaining() {
            return Err(Miss::End { need });
        }
        self.pos += need;
        Ok(())
    }

    fn offset(&self) -> usize {
        self.pos
    }

    fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    fn line(&self) -> Option<usize> {
        None
    }

    fn min_size(&self, t: Scalar) -> u64 {
        t.size() as u64
    }

    fn binary(&mut self) -> Option<(&'a [u8], &mut usize, bool)> {
        Some((self.data, &mut self.pos, BE))
    }
}

/// An ASCII body: whitespace-separated tokens.
struct Ascii<'a> {
    data: &'a [u8],
    pos: usize,
    /// The line `pos` is on.
    line: usize,
    /// The line of the last token read.
    token_line: usize,
}

impl<'a> Ascii<'a> {
    fn token(&mut self) -> Option<&'a [u8]> {
        while let Some(&b) = self.data.get(self.pos) {
            if !b.is_ascii_whitespace() {
                break;
            }
            if b == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        let start = self.pos;
        while self
            .data
            .get(self.pos)
            .is_some_and(|b| !b.is_ascii_whitespace())
        {
            self.pos += 1;
        }
        if self.pos == start {
            return None;
        }
        self.token_line = self.line;
        Some(&self.data[start..self.pos])
    }
}

impl<'a> Source<'a> for Ascii<'a> {
    fn value(&mut self, t: Scalar) -> Result<f64, Miss> {
        let tok = self.token().ok_or(Miss::End { need: 1 })?;
        if t.is_float() {
            return parse_f64(tok)
                .ok_or_else(|| Miss::Bad(format!("`{}` is not a number", show(tok))));
        }
        let (lo, hi) = t.int_range();
        match parse_i64(tok) {
            Some(i) if (lo..=hi).contains(&i) => Ok(i as f64),
            _ => Err(Miss::Bad(format!("`{}` is not a {}", show(tok), t.name()))),
        }
    }

    fn skip(&mut self, t: Scalar) -> Result<(), Miss> {
        self.value(t).map(drop)
    }

    fn skip_n(&mut self, t: Scalar, n: usize) -> Result<(), Miss> {
        (0..n).try_for_each(|_| self.skip(t))
    }

    fn offset(&self) -> usize {
        self.pos
    }

    fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    fn line(&self) -> Option<usize> {
        Some(self.token_line)
    }

    fn min_size(&self, _: Scalar) -> u64 {
        2
    }

    fn binary(&mut self) -> Option<(&'a [u8], &mut usize, bool)> {
        None
    }
}

/// A column being filled.
enum Builder {
    Scalar(Vec<f64>),
    Label(Vec<u32>),
    Vec2(Vec<DVec2>),
    Vec3(Vec<DVec3>),
    Color(Vec<[u8; 3]>),
}

impl Builder {
    fn new(kind: AttrKind, capacity: usize) -> Self {
        match kind {
            AttrKind::Scalar => Builder::Scalar(Vec::with_capacity(capacity)),
            AttrKind::Label => Builder::Label(Vec::with_capacity(capacity)),
            AttrKind::Vec2 => Builder::Vec2(Vec::with_capacity(capacity)),
            AttrKind::Vec3 => Builder::Vec3(Vec::with_capacity(capacity)),
            AttrKind::Color => Builder::Color(Vec::with_capacity(capacity)),
        }
    }

    /// Appends the value made of `vals[sources]`, `times` times. Label and colour
    /// sources are `uint` and `uchar` properties, so the casts are exact.
    #[inline]
    fn push(&mut self, vals: &[f64], s: &[usize], times: usize) {
        let v = |k: usize| vals[s[k]];
        match self {
            Builder::Scalar(c) => c.extend(std::iter::repeat_n(v(0), times)),
            Builder::Label(c) => c.extend(std::iter::repeat_n(v(0) as u32, times)),
            Builder::Vec2(c) => c.extend(std::iter::repeat_n(DVec2::new(v(0), v(1)), times)),
            Builder::Vec3(c) => c.extend(std::iter::repeat_n(DVec3::new(v(0), v(1), v(2)), times)),
            Builder::Color(c) => c.extend(std::iter::repeat_n(
                [v(0), v(1), v(2)].map(|x| x as u8),
                times,
            )),
        }
    }

    fn finish(self) -> AttrValues {
        match self {
            Builder::Scalar(c) => AttrValues::Scalar(c),
            Builder::Label(c) => AttrValues::Label(c),
            Builder::Vec2(c) => AttrValues::Vec2(c),
            Builder::Vec3(c) => AttrValues::Vec3(c),
            Builder::Color(c) => AttrValues::Color(c),
        }
    }
}

/// What to do with one property of an element.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Act {
    /// Coordinate `k` of the position.
    Pos(usize),
    /// Attribute value slot `k`.
    Attr(usize),
    /// The face's vertex index list.
    Indices,
    /// Read and drop.
    Skip,
}

/// The attribute columns of one element: plans, builders and the value slots.
struct Columns {
    plans: Vec<ColumnPlan>,
    builders: Vec<Builder>,
    vals: Vec<f64>,
}

impl Columns {
    /// Plans columns for the scalar properties that `acts` marks as attributes.
    fn new(el: &Element, acts: &mut [Act], capacity: usize, notes: &mut Vec<String>) -> Self {
        let mut props = Vec::new();
        for (act, p) in acts.iter_mut().zip(&el.props) {
            match (*act, p.kind) {
                (Act::Attr(_), PropKind::Scalar(t)) => {
                    *act = Act::Attr(props.len());
                    props.push((p.name.as_str(), t));
                }
                (Act::Attr(_), PropKind::List { .. }) => {
                    *act = Act::Skip;
                    notes.push(format!("{} list property `{}` not kept", el.name, p.name));
                }
                _ => {}
            }
        }
        let (plans, clashes) = columns(&props);
        for c in clashes {
            notes.push(format!(
                "{} property `{c}` not kept: its name is taken by another attribute",
                el.name
            ));
        }
        let builders = plans
            .iter()
            .map(|p| Builder::new(p.kind, capacity))
            .collect();
        Columns {
            plans,
            builders,
            vals: vec![0.0; props.len()],
        }
    }

    #[inline]
    fn push(&mut self, times: usize) {
        for (b, p) in self.builders.iter_mut().zip(&self.plans) {
            b.push(&self.vals, &p.sources, times);
        }
    }

    /// Moves the finished columns into `attrs`, dropping (with a note) any column holding
    /// a NaN or infinite value.
    fn finish(self, attrs: &mut Attributes, domain: &str, notes: &mut Vec<String>) {
        for (b, p) in self.builders.into_iter().zip(self.plans) {
            let values = b.finish();
            match values.first_non_finite() {
                Some(i) => notes.push(format!(
                    "{domain} attribute `{}` not kept: its value at {domain} {i} is not finite",
                    p.name
                )),
                None => attrs.insert(p.name, values),
            }
        }
    }
}

/// Reader state for one file.
struct Reader<'o> {
    name: &'o str,
    opts: &'o ReadOptions,
    n_vertices: u64,
    positions: Vec<DVec3>,
    faces: Vec<[u32; 3]>,
    /// The `edge` element's vertex pairs.
    edges: Vec<[u32; 2]>,
    vertex_attrs: Attributes,
    face_attrs: Attributes,
    strip_triangles: usize,
    notes: Vec<String>,
}

/// The "not a PLY file" error.
fn no_magic(name: &str) -> IoError {
    IoError::file(
        name,
        ErrorKind::NotFormat {
            format: Format::Ply,
            detail: "no \"ply\" magic".into(),
        },
    )
}

/// Refuses, from the first bytes of a file alone, a PLY file without its magic or whose
/// header (when it ends within `start`) declares more vertices or faces than the limits.
pub(crate) fn check_start(start: &[u8], name: &str, opts: &ReadOptions) -> Result<(), IoError> {
    let header = match parse_header(start) {
        Ok(h) => h,
        Err((_, HeaderProblem::NoMagic)) => return Err(no_magic(name)),
        // The header may go on past `start`: the full read reports its problems.
        Err(_) => return Ok(()),
    };
    for el in &header.elements {
        let (limit, kind): (Option<usize>, fn(usize) -> ErrorKind) = match el.name.as_str() {
            "vertex" => (opts.max_vertices, ErrorKind::over_limit_vertices),
            "face" => (opts.max_faces, ErrorKind::over_limit_faces),
            _ => continue,
        };
        if let Some(limit) = limit
            && el.count > limit as u64
        {
            return Err(IoError::file(name, kind(limit)));
        }
    }
    Ok(())
}

/// Reads a PLY file's bytes; `name` is used in errors.
pub(crate) fn read(
    bytes: &[u8],
    name: &str,
    opts: &ReadOptions,
) -> Result<(Mesh, Vec<String>), IoError> {
    let header = parse_header(bytes).map_err(|(line, problem)| match problem {
        HeaderProblem::NoMagic => no_magic(name),
        HeaderProblem::Syntax(m) => IoError::line(name, line, ErrorKind::Syntax(m)),
        HeaderProblem::Unsupported(m) => IoError::line(name, line, ErrorKind::Unsupported(m)),
    })?;
    let n_vertices = header
        .elements
        .iter()
        .find(|e| e.name == "vertex")
        .map_or(0, |e| e.count);
    let mut r = Reader {
        name,
        opts,
        n_vertices,
        positions: Vec::new(),
        faces: Vec::new(),
        edges: Vec::new(),
        vertex_attrs: Attributes::default(),
        face_attrs: Attributes::default(),
        strip_triangles: 0,
        notes: Vec::new(),
    };
    let trailing = match header.encoding {
        Encoding::Ascii => {
            let mut src = Ascii {
                data: bytes,
                pos: header.body,
                line: header.lines + 1,
                token_line: header.lines,
            };
            r.body(&mut src, &header.elements)?;
            src.token().is_some()
        }
        Encoding::Le => {
            r.body(
                &mut Bin::<false> {
                    data: bytes,
                    pos: header.body,
                },
                &header.elements,
            )? > 0
        }
        Encoding::Be => {
            r.body(
                &mut Bin::<true> {
                    data: bytes,
                    pos: header.body,
                },
                &header.elements,
            )? > 0
        }
    };
    if trailing {
        r.notes.push("data after the last element ignored".into());
    }
    r.finish()
}

impl<'o> Reader<'o> {
    /// Reads every element; returns the bytes left after the last one.
    fn body<'a, S: Source<'a>>(
        &mut self,
        src: &mut S,
        elements: &[Element],
    ) -> Result<usize, IoError> {
        for el in elements {
            self.check_count(src, el)?;
            match el.name.as_str() {
                "vertex" => self.vertices(src, el)?,
                "face" => self.faces(src, el)?,
                "tristrips" => self.strips(src, el)?,
                "edge" => self.edges(src, el)?,
                _ => {
                    self.skip(src, el)?;
                    self.notes.push(format!(
                        "element `{}` ({} {}) skipped",
                        el.name,
                        el.count,
                        if el.count == 1 { "item" } else { "items" }
                    ));
                }
            }
        }
        Ok(src.remaining())
    }

    /// Refuses counts that the bytes left cannot hold, before anything is allocated.
    fn check_count<'a, S: Source<'a>>(&self, src: &mut S, el: &Element) -> Result<(), IoError> {
        let min = min_bytes(src, el);
        let remaining = src.remaining() as u64;
        // An ASCII body may end without a separator after its last token.
        let slack = u64::from(src.line().is_some());
        let need = u128::from(el.count) * u128::from(min);
        if need <= u128::from(remaining + slack) {
            return Ok(());
        }
        let kind = match (src.binary().is_some(), el.fixed_size()) {
            (true, Some(size)) if el.count <= remaining => ErrorKind::Truncated {
                what: el.name.clone(),
                expected: el.count * size as u64,
                offset: src.offset() as u64,
                found: remaining,
            },
            _ => ErrorKind::CountTooLarge {
                count: el.count,
                what: plural(&el.name),
                remaining,
            },
        };
        Err(IoError::file(self.name, kind))
    }

    /// The error for a value that could not be read in element `index` of `el`.
    fn miss<'a, S: Source<'a>>(&self, src: &S, el: &Element, index: u64, miss: Miss) -> IoError {
        let kind = match (miss, src.line()) {
            (Miss::End { .. }, Some(_)) => {
                ErrorKind::Syntax(format!("the data ends inside {} {index}", el.name))
            }
            (Miss::End { need }, None) => ErrorKind::Truncated {
                what: el.name.clone(),
                expected: need as u64,
                offset: src.offset() as u64,
                found: src.remaining() as u64,
            },
            (Miss::Bad(m), _) => ErrorKind::Syntax(m),
        };
        self.at(src, &el.name, index, kind)
    }

    /// An error at element `index` called `element`.
    fn at<'a, S: Source<'a>>(
        &self,
        src: &S,
        element: &str,
        index: u64,
        kind: ErrorKind,
    ) -> IoError {
        match src.line() {
            Some(line) => IoError::line_element(self.name, line, element, index, kind),
            None => IoError::element(self.name, element, index, kind),
        }
    }

    /// Reads the `vertex` element.
    fn vertices<'a, S: Source<'a>>(&mut self, src: &mut S, el: &Element) -> Result<(), IoError> {
        if let Some(limit) = self.opts.max_vertices
            && el.count > limit as u64
        {
            return Err(IoError::file(
                self.name,
                ErrorKind::over_limit_vertices(limit),
            ));
        }
        if el.count > u64::from(u32::MAX) {
            return Err(IoError::file(
                self.name,
                ErrorKind::TooMany {
                    count: el.count,
                    what: "vertices",
                },
            ));
        }
        let mut acts: Vec<Act> = el
            .props
            .iter()
            .map(|p| match (p.name.as_str(), p.kind) {
                ("x", PropKind::Scalar(_)) => Act::Pos(0),
                ("y", PropKind::Scalar(_)) => Act::Pos(1),
                ("z", PropKind::Scalar(_)) => Act::Pos(2),
                _ => Act::Attr(0),
            })
            .collect();
        for (k, axis) in ["x", "y", "z"].into_iter().enumerate() {
            if !acts.contains(&Act::Pos(k)) {
                return Err(IoError::file(
                    self.name,
                    ErrorKind::Syntax(format!(
                        "the vertex element has no scalar `{axis}` property"
                    )),
                ));
            }
        }
        // `check_count` has bounded `count` by the bytes left.
        let count = el.count as usize;
        let mut cols = Columns::new(el, &mut acts, count, &mut self.notes);
        self.positions.reserve(count);
        if !self.fast_vertices(src, el, &acts, &mut cols)? {
            self.slow_vertices(src, el, &acts, &mut cols)?;
        }
        cols.finish(&mut self.vertex_attrs, "vertex", &mut self.notes);
        Ok(())
    }

    /// Vertices in any encoding and layout, one value at a time.
    fn slow_vertices<'a, S: Source<'a>>(
        &mut self,
        src: &mut S,
        el: &Element,
        acts: &[Act],
        cols: &mut Columns,
    ) -> Result<(), IoError> {
        let mut pos = [0.0; 3];
        for i in 0..el.count {
            for (act, p) in acts.iter().zip(&el.props) {
                let r = match (*act, p.kind) {
                    (Act::Pos(k), PropKind::Scalar(t)) => src.value(t).map(|x| pos[k] = x),
                    (Act::Attr(k), PropKind::Scalar(t)) => src.value(t).map(|x| cols.vals[k] = x),
                    (_, PropKind::Scalar(t)) => src.skip(t),
                    (_, PropKind::List { count, item }) => skip_list(src, count, item),
                };
                r.map_err(|m| self.miss(src, el, i, m))?;
            }
            self.push_vertex(src, i, pos)?;
            cols.push(1);
        }
        Ok(())
    }

    #[inline]
    fn push_vertex<'a, S: Source<'a>>(
        &mut self,
        src: &S,
        i: u64,
        p: [f64; 3],
    ) -> Result<(), IoError> {
        if let Some(&bad) = p.iter().find(|c| !c.is_finite()) {
            return Err(self.at(src, "vertex", i, ErrorKind::NonFinite(non_finite_name(bad))));
        }
        self.positions.push(DVec3::from_array(p));
        Ok(())
    }

    /// Binary vertices whose properties are all scalars: fixed-size records decoded in
    /// place. Returns false when the layout does not allow it.
    fn fast_vertices<'a, S: Source<'a>>(
        &mut self,
        src: &mut S,
        el: &Element,
        acts: &[Act],
        cols: &mut Columns,
    ) -> Result<bool, IoError> {
        let Some(size) = el.fixed_size() else {
            return Ok(false);
        };
        let Some((data, pos, be)) = src.binary() else {
            return Ok(false);
        };
        // `check_count` has made sure the records are all there.
        let end = *pos + size * el.count as usize;
        let Some(records) = data.get(*pos..end) else {
            return Ok(false);
        };
        *pos = end;
        let mut layout = Vec::with_capacity(acts.len());
        let mut offset = 0;
        for (act, p) in acts.iter().zip(&el.props) {
            if let PropKind::Scalar(t) = p.kind {
                layout.push((offset, t, *act));
                offset += t.size();
            }
        }
        let xyz_only = |t: Scalar| {
            acts.len() == 3
                && layout
                    .iter()
                    .enumerate()
                    .all(|(k, &(_, ty, act))| ty == t && act == Act::Pos(k))
        };
        if xyz_only(Scalar::F32) {
            if be {
                self.xyz::<true, 4>(records, src)?
            } else {
                self.xyz::<false, 4>(records, src)?
            }
        } else if xyz_only(Scalar::F64) {
            if be {
                self.xyz::<true, 8>(records, src)?
            } else {
                self.xyz::<false, 8>(records, src)?
            }
        } else if be {
            self.records::<true, S>(records, size, &layout, cols, src)?
        } else {
            self.records::<false, S>(records, size, &layout, cols, src)?
        }
        Ok(true)
    }

    /// Records of exactly `x y z`, each `N` bytes (4: float, 8: double).
    fn xyz<'a, const BE: bool, const N: usize>(
        &mut self,
        records: &[u8],
        src: &impl Source<'a>,
    ) -> Result<(), IoError> {
        let t = if N == 4 { Scalar::F32 } else { Scalar::F64 };
        for (i, rec) in records.chunks_exact(3 * N).enumerate() {
            let mut p = [0.0; 3];
            for (k, c) in rec.chunks_exact(N).enumerate() {
                // Chunks are exactly N bytes; NaN (refused below) cannot occur.
                p[k] = get::<BE>(c, t).unwrap_or(f64::NAN);
            }
            self.push_vertex(src, i as u64, p)?;
        }
        Ok(())
    }

    /// Fixed-size records of any scalar layout.
    fn records<'a, const BE: bool, S: Source<'a>>(
        &mut self,
        records: &[u8],
        size: usize,
        layout: &[(usize, Scalar, Act)],
        cols: &mut Columns,
        src: &S,
    ) -> Result<(), IoError> {
        if size == 0 {
            return Ok(());
        }
        for (i, rec) in records.chunks_exact(size).enumerate() {
            let mut p = [0.0; 3];
            for &(offset, t, act) in layout {
                let x = rec
                    .get(offset..)
                    .and_then(|b| get::<BE>(b, t))
                    .unwrap_or(f64::NAN);
                match act {
                    Act::Pos(k) => p[k] = x,
                    Act::Attr(k) => cols.vals[k] = x,
                    Act::Indices | Act::Skip => {}
                }
            }
            self.push_vertex(src, i as u64, p)?;
            cols.push(1);
        }
        Ok(())
    }

    /// Checks a vertex index of face (or strip) `i` and makes it a `u32`.
    #[inline]
    fn index<'a, S: Source<'a>>(
        &self,
        src: &S,
        el: &Element,
        i: u64,
        v: i64,
    ) -> Result<u32, IoError> {
        if v < 0 || v as u64 >= self.n_vertices {
            return Err(self.at(
                src,
                &el.name,
                i,
                ErrorKind::OutOfRange {
                    by: "face",
                    what: RefKind::Vertex,
                    index: v,
                    count: self.n_vertices,
                },
            ));
        }
        Ok(v as u32)
    }

    /// Appends the fan of `poly` (a face of element `el`, number `i`).
    #[inline]
    fn push_polygon<'a, S: Source<'a>>(
        &mut self,
        src: &S,
        el: &Element,
        i: u64,
        poly: &[u32],
    ) -> Result<usize, IoError> {
        let n = poly.len();
        if n < 3 {
            return Err(self.at(
                src,
                &el.name,
                i,
                ErrorKind::Syntax(format!(
                    "a face needs at least 3 vertex indices, this one has {n}"
                )),
            ));
        }
        self.check_face_count(src, el, i, n - 2)?;
        let (c0, rest) = (poly[0], &poly[1..]);
        self.faces.extend(rest.windows(2).map(|w| [c0, w[0], w[1]]));
        Ok(n - 2)
    }

    /// Refuses more triangles than the limits allow.
    #[inline]
    fn check_face_count<'a, S: Source<'a>>(
        &self,
        src: &S,
        el: &Element,
        i: u64,
        more: usize,
    ) -> Result<(), IoError> {
        let total = self.faces.len() + more;
        if let Some(limit) = self.opts.max_faces
            && total > limit
        {
            return Err(self.at(src, &el.name, i, ErrorKind::over_limit_faces(limit)));
        }
        if total > u32::MAX as usize {
            return Err(self.at(
                src,
                &el.name,
                i,
                ErrorKind::TooMany {
                    count: total as u64,
                    what: "faces",
                },
            ));
        }
        Ok(())
    }

    /// Reads the `face` element.
    fn faces<'a, S: Source<'a>>(&mut self, src: &mut S, el: &Element) -> Result<(), IoError> {
        let list = el.props.iter().position(|p| {
            matches!(p.kind, PropKind::List { .. })
                && (p.name == "vertex_indices" || p.name == "vertex_index")
        });
        let Some(list) = list else {
            return Err(IoError::file(
                self.name,
                ErrorKind::Syntax("the face element has no `vertex_indices` list property".into()),
            ));
        };
        let mut acts: Vec<Act> = (0..el.props.len())
            .map(|k| {
                if k == list {
                    Act::Indices
                } else {
                    Act::Attr(0)
                }
            })
            .collect();
        // A face takes at least its scalars, a count and three indices: reserve no more
        // faces than the bytes left could hold.
        let min_face = match el.props[list].kind {
            PropKind::List { item, .. } => min_bytes(src, el) + 3 * src.min_size(item),
            PropKind::Scalar(_) => min_bytes(src, el),
        };
        let capacity = el.count.min(src.remaining() as u64 / min_face.max(1)) as usize;
        let mut cols = Columns::new(el, &mut acts, capacity, &mut self.notes);
        self.faces.reserve(capacity);
        if !self.fast_faces(src, el)? {
            self.slow_faces(src, el, &acts, &mut cols)?;
        }
        cols.finish(&mut self.face_attrs, "face", &mut self.notes);
        Ok(())
    }

    /// Faces in any encoding and layout, one value at a time.
    fn slow_faces<'a, S: Source<'a>>(
        &mut self,
        src: &mut S,
        el: &Element,
        acts: &[Act],
        cols: &mut Columns,
    ) -> Result<(), IoError> {
        let mut poly: Vec<u32> = Vec::new();
        for i in 0..el.count {
            for (act, p) in acts.iter().zip(&el.props) {
                let r = match (*act, p.kind) {
                    (Act::Attr(k), PropKind::Scalar(t)) => src.value(t).map(|x| cols.vals[k] = x),
                    (Act::Indices, PropKind::List { count, item }) => {
                        poly.clear();
                        let n = list_len(src, count).map_err(|m| self.miss(src, el, i, m))?;
                        for _ in 0..n {
                            let v = src.int(item).map_err(|m| self.miss(src, el, i, m))?;
                            poly.push(self.index(src, el, i, v)?);
                        }
                        Ok(())
                    }
                    (_, PropKind::Scalar(t)) => src.skip(t),
                    (_, PropKind::List { count, item }) => skip_list(src, count, item),
                };
                r.map_err(|m| self.miss(src, el, i, m))?;
            }
            let triangles = self.push_polygon(src, el, i, &poly)?;
            cols.push(triangles);
        }
        Ok(())
    }

    /// Binary faces whose only property is a `uchar`-counted `int`/`uint` index list:
    /// triangles decoded straight from the bytes. Returns false for other layouts.
    fn fast_faces<'a, S: Source<'a>>(
        &mut self,
        src: &mut S,
        el: &Element,
    ) -> Result<bool, IoError> {
        let [p] = &el.props[..] else {
            return Ok(false);
        };
        let signed = match p.kind {
            PropKind::List {
                count: Scalar::U8,
                item: Scalar::I32,
            } => true,
            PropKind::List {
                count: Scalar::U8,
                item: Scalar::U32,
            } => false,
            _ => return Ok(false),
        };
        let Some((_, _, be)) = src.binary() else {
            return Ok(false);
        };
        match (be, signed) {
            (false, true) => self.index_lists::<false, true, S>(src, el)?,
            (false, false) => self.index_lists::<false, false, S>(src, el)?,
            (true, true) => self.index_lists::<true, true, S>(src, el)?,
            (true, false) => self.index_lists::<true, false, S>(src, el)?,
        }
        Ok(true)
    }

    fn index_lists<'a, const BE: bool, const SIGNED: bool, S: Source<'a>>(
        &mut self,
        src: &mut S,
        el: &Element,
    ) -> Result<(), IoError> {
        let idx = |b: &[u8]| -> i64 {
            let a = [b[0], b[1], b[2], b[3]];
            match (BE, SIGNED) {
                (true, true) => i32::from_be_bytes(a).into(),
                (false, true) => i32::from_le_bytes(a).into(),
                (true, false) => u32::from_be_bytes(a).into(),
                (false, false) => u32::from_le_bytes(a).into(),
            }
        };
        let mut poly: Vec<u32> = Vec::new();
        for i in 0..el.count {
            let Some((data, pos, _)) = src.binary() else {
                return Ok(());
            };
            let at = *pos;
            let n = match data.get(at) {
                Some(&n) => usize::from(n),
                None => return Err(self.miss(src, el, i, Miss::End { need: 1 })),
            };
            let Some(bytes) = data.get(at + 1..at + 1 + 4 * n) else {
                *pos = at + 1;
                return Err(self.miss(src, el, i, Miss::End { need: 4 * n }));
            };
            *pos = at + 1 + 4 * n;
            if n == 3 {
                let tri = [idx(&bytes[0..4]), idx(&bytes[4..8]), idx(&bytes[8..12])];
                let mut out = [0u32; 3];
                for (o, v) in out.iter_mut().zip(tri) {
                    *o = self.index(src, el, i, v)?;
                }
                self.check_face_count(src, el, i, 1)?;
                self.faces.push(out);
            } else {
                poly.clear();
                for b in bytes.chunks_exact(4) {
                    poly.push(self.index(src, el, i, idx(b))?);
                }
                self.push_polygon(src, el, i, &poly)?;
            }
        }
        Ok(())
    }

    /// Reads a `tristrips` element.
    fn strips<'a, S: Source<'a>>(&mut self, src: &mut S, el: &Element) -> Result<(), IoError> {
        let list = el
            .props
            .iter()
            .position(|p| matches!(p.kind, PropKind::List { .. }) && p.name == "vertex_indices");
        let Some(list) = list else {
            return Err(IoError::file(
                self.name,
                ErrorKind::Syntax(
                    "the tristrips element has no `vertex_indices` list property".into(),
                ),
            ));
        };
        let mut strip: Vec<i64> = Vec::new();
        for i in 0..el.count {
            for (k, p) in el.props.iter().enumerate() {
                let r = match p.kind {
                    PropKind::List { count, item } if k == list => {
                        strip.clear();
                        let n = list_len(src, count).map_err(|m| self.miss(src, el, i, m))?;
                        for _ in 0..n {
                            strip.push(src.int(item).map_err(|m| self.miss(src, el, i, m))?);
                        }
                        Ok(())
                    }
                    PropKind::Scalar(t) => src.skip(t),
                    PropKind::List { count, item } => skip_list(src, count, item),
                };
                r.map_err(|m| self.miss(src, el, i, m))?;
            }
            for run in strip.split(|&v| v == -1) {
                let run: Vec<u32> = run
                    .iter()
                    .map(|&v| self.index(src, el, i, v))
                    .collect::<Result<_, _>>()?;
                for (j, w) in run.windows(3).enumerate() {
                    let [a, b, c] = [w[0], w[1], w[2]];
                    if a == b || b == c || a == c {
                        continue;
                    }
                    self.check_face_count(src, el, i, 1)?;
                    self.faces
                        .push(if j % 2 == 0 { [a, b, c] } else { [b, a, c] });
                    self.strip_triangles += 1;
                }
            }
        }
        Ok(())
    }

    /// Reads the `edge` element: its `vertex1` and `vertex2` (integer scalars) are a
    /// marked edge; other properties are skipped, with a note.
    fn edges<'a, S: Source<'a>>(&mut self, src: &mut S, el: &Element) -> Result<(), IoError> {
        let mut ends = [None; 2];
        for (k, end) in ["vertex1", "vertex2"].into_iter().enumerate() {
            let Some(at) = el.props.iter().position(|p| p.name == end) else {
                return Err(IoError::file(
                    self.name,
                    ErrorKind::Syntax(format!("the edge element has no `{end}` property")),
                ));
            };
            match el.props[at].kind {
                PropKind::Scalar(t) if !t.is_float() => ends[k] = Some(at),
                kind => {
                    let is = match kind {
                        PropKind::Scalar(t) => format!("a {}", t.name()),
                        PropKind::List { .. } => "a list".to_string(),
                    };
                    return Err(IoError::file(
                        self.name,
                        ErrorKind::Syntax(format!(
                            "the edge element's `{end}` property is {is}, not an integer"
                        )),
                    ));
                }
            }
        }
        let others: Vec<&str> = el
            .props
            .iter()
            .enumerate()
            .filter(|&(k, _)| !ends.contains(&Some(k)))
            .map(|(_, p)| p.name.as_str())
            .collect();
        if !others.is_empty() {
            self.notes
                .push(format!("edge properties ({}) not kept", others.join(", ")));
        }
        // `check_count` has bounded `count` by the bytes left.
        self.edges.reserve(el.count as usize);
        for i in 0..el.count {
            let mut edge = [0u32; 2];
            for (k, p) in el.props.iter().enumerate() {
                let end = ends.iter().position(|&e| e == Some(k));
                let r = match (end, p.kind) {
                    (Some(j), PropKind::Scalar(t)) => {
                        let v = src.int(t).map_err(|m| self.miss(src, el, i, m))?;
                        if v < 0 || v as u64 >= self.n_vertices {
                            return Err(self.at(
                                src,
                                &el.name,
                                i,
                                ErrorKind::OutOfRange {
                                    by: "edge",
                                    what: RefKind::Vertex,
                                    index: v,
                                    count: self.n_vertices,
                                },
                            ));
                        }
                        edge[j] = v as u32;
                        Ok(())
                    }
                    (_, PropKind::Scalar(t)) => src.skip(t),
                    (_, PropKind::List { count, item }) => skip_list(src, count, item),
                };
                r.map_err(|m| self.miss(src, el, i, m))?;
            }
            self.edges.push(edge);
        }
        Ok(())
    }

    /// Skips an element the reader does not use.
    fn skip<'a, S: Source<'a>>(&mut self, src: &mut S, el: &Element) -> Result<(), IoError> {
        if el.props.is_empty() {
            return Ok(());
        }
        if let (Some(size), Some((_, pos, _))) = (el.fixed_size(), src.binary()) {
            // `check_count` has made sure the records are all there.
            *pos += size * el.count as usize;
            return Ok(());
        }
        for i in 0..el.count {
            for p in &el.props {
                let r = match p.kind {
                    PropKind::Scalar(t) => src.skip(t),
                    PropKind::List { count, item } => skip_list(src, count, item),
                };
                r.map_err(|m| self.miss(src, el, i, m))?;
            }
        }
        Ok(())
    }

    fn finish(mut self) -> Result<(Mesh, Vec<String>), IoError> {
        let n_faces = self.faces.len();
        if self.strip_triangles > 0 && !self.face_attrs.is_empty() {
            self.notes.push(format!(
                "face attributes ({}) not kept: triangle strips add faces that have none",
                self.face_attrs.names().collect::<Vec<_>>().join(", ")
            ));
            self.face_attrs.clear();
        }
        debug_assert!(self.face_attrs.iter().all(|(_, v)| v.len() == n_faces));
        let mut mesh = Mesh::new(self.positions, self.faces);
        mesh.vertex_attrs = self.vertex_attrs;
        mesh.face_attrs = self.face_attrs;
        mesh.marked_edges = self.edges;
        Ok((mesh, self.notes))
    }
}

/// The fewest bytes one element of `el` takes in `src` (lists may be empty).
fn min_bytes<'a, S: Source<'a>>(src: &S, el: &Element) -> u64 {
    el.props
        .iter()
        .map(|p| match p.kind {
            PropKind::Scalar(t) | PropKind::List { count: t, .. } => src.min_size(t),
        })
        .sum()
}

/// Reads a list length.
fn list_len<'a, S: Source<'a>>(src: &mut S, count: Scalar) -> Result<usize, Miss> {
    let n = src.int(count)?;
    usize::try_from(n).map_err(|_| Miss::Bad(format!("list length {n} is negative")))
}

/// Skips a list property.
fn skip_list<'a, S: Source<'a>>(src: &mut S, count: Scalar, item: Scalar) -> Result<(), Miss> {
    let n = list_len(src, count)?;
    src.skip_n(item, n)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Little builder for binary bodies in either byte order.
    struct Body {
        be: bool,
        bytes: Vec<u8>,
    }

    impl Body {
        fn new(be: bool) -> Self {
            Body {
                be,
                bytes: Vec::new(),
            }
        }
        fn put<const N: usize>(&mut self, le: [u8; N], be: [u8; N]) -> &mut Self {
            self.bytes
                .extend_from_slice(if self.be { &be } else { &le });
            self
        }
        fn f32(&mut self, x: f32) -> &mut Self {
            self.put(x.to_le_bytes(), x.to_be_bytes())
        }
        fn f64(&mut self, x: f64) -> &mut Self {
            self.put(x.to_le_bytes(), x.to_be_bytes())
        }
        fn i32(&mut self, x: i32) -> &mut Self {
            self.put(x.to_le_bytes(), x.to_be_bytes())
        }
        fn u32(&mut self, x: u32) -> &mut Self {
            self.put(x.to_le_bytes(), x.to_be_bytes())
        }
        fn i16(&mut self, x: i16) -> &mut Self {
            self.put(x.to_le_bytes(), x.to_be_bytes())
        }
        fn u16(&mut self, x: u16) -> &mut Self {
            self.put(x.to_le_bytes(), x.to_be_bytes())
        }
        fn u8(&mut self, x: u8) -> &mut Self {
            self.bytes.push(x);
            self
        }
        fn i8(&mut self, x: i8) -> &mut Self {
            self.put(x.to_le_bytes(), x.to_be_bytes())
        }
    }

    fn file(format: &str, header: &str, body: &[u8]) -> Vec<u8> {
        let mut out = format!("ply\nformat {format} 1.0\n{header}end_header\n").into_bytes();
        out.extend_from_slice(body);
        out
    }

    fn load(bytes: &[u8]) -> Result<(Mesh, Vec<String>), IoError> {
        read(bytes, "x.ply", &ReadOptions::default())
    }

    fn err(bytes: &[u8]) -> String {
        load(bytes).unwrap_err().to_string()
    }

    const SQUARE: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];

    /// Float positions and `uchar`/`int` index lists: the fast paths.
    fn square(be: bool, format: &str) -> Vec<u8> {
        square_with(be, format, "int")
    }

    /// [`square`] with the index type named `index` (`int` or `uint`) in the header.
    fn square_with(be: bool, format: &str, index: &str) -> Vec<u8> {
        let mut b = Body::new(be);
        for p in SQUARE {
            p.iter().for_each(|&c| {
                b.f32(c);
            });
        }
        b.u8(4).i32(0).i32(1).i32(2).i32(3);
        b.u8(3).i32(0).i32(2).i32(3);
        let header = format!(
            "element vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
             element face 2\nproperty list uchar {index} vertex_indices\n"
        );
        file(format, &header, &b.bytes)
    }

    #[test]
    fn little_and_big_endian_fast_paths_agree() {
        let (le, _) = load(&square(false, "binary_little_endian")).unwrap();
        let (be, _) = load(&square(true, "binary_big_endian")).unwrap();
        assert_eq!(le, be);
        // The same bytes read as `uint` indices (the other fast path).
        assert_eq!(
            load(&square_with(false, "binary_little_endian", "uint"))
                .unwrap()
                .0,
            le
        );
        assert_eq!(le.positions[2], DVec3::new(1.0, 1.0, 0.0));
        assert_eq!(le.faces, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
    }

    #[test]
    fn ascii_reads_the_same_mesh_with_attributes() {
        let src = "ply\nformat ascii 1.0\ncomment x\nelement vertex 4\nproperty double x\n\
                   property double y\nproperty double z\nproperty float quality\n\
                   property uchar red\nproperty uchar green\nproperty uchar blue\n\
                   element face 2\nproperty list uchar uint vertex_indices\nproperty int part\n\
                   end_header\n0 0 0 0.5 255 0 0\n1 0 0 1.5 0 255 0\n1 1 0 2 0 0 255\n\
                   0 1 0 3 1 2 3\n4 0 1 2 3 7\n3 0 2 3 -1\n";
        let (m, notes) = load(src.as_bytes()).unwrap();
        assert!(notes.is_empty(), "{notes:?}");
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
        assert_eq!(
            m.vertex_attrs.scalar("quality").unwrap(),
            &[0.5, 1.5, 2.0, 3.0]
        );
        assert_eq!(
            m.vertex_attrs.get("color"),
            Some(&AttrValues::Color(vec![
                [255, 0, 0],
                [0, 255, 0],
                [0, 0, 255],
                [1, 2, 3]
            ]))
        );
        // A polygon's face property goes to each of its triangles.
        assert_eq!(m.face_attrs.scalar("part").unwrap(), &[7.0, 7.0, -1.0]);
    }

    #[test]
    fn every_scalar_type_reads_in_every_encoding() {
        let header = "element vertex 3\nproperty char x\nproperty uint8 y\nproperty int16 z\n\
                      property ushort a\nproperty int32 b\nproperty uint c\nproperty float32 d\n\
                      property float64 e\nelement face 1\nproperty list ushort uint16 vertex_index\n";
        /// One vertex: a value of every scalar type, in header order.
        type Row = (i8, u8, i16, u16, i32, u32, f32, f64);
        let rows: [Row; 3] = [
            (-1, 2, -300, 60000, -70000, 4_000_000_000, 0.5, 0.25),
            (0, 0, 0, 0, 0, 0, 0.0, 0.0),
            (127, 255, 32767, 1, 1, 1, -1.0, 1e300),
        ];
        let ascii: String = rows
            .iter()
            .map(|r| {
                format!(
                    "{} {} {} {} {} {} {} {}\n",
                    r.0, r.1, r.2, r.3, r.4, r.5, r.6, r.7
                )
            })
            .collect::<String>()
            + "3 0 1 2\n";
        let mut meshes = vec![load(&file("ascii", header, ascii.as_bytes())).unwrap().0];
        for (be, format) in [(false, "binary_little_endian"), (true, "binary_big_endian")] {
            let mut b = Body::new(be);
            for r in rows {
                b.i8(r.0)
                    .u8(r.1)
                    .i16(r.2)
                    .u16(r.3)
                    .i32(r.4)
                    .u32(r.5)
                    .f32(r.6)
                    .f64(r.7);
            }
            b.u16(3).u16(0).u16(1).u16(2);
            meshes.push(load(&file(format, header, &b.bytes)).unwrap().0);
        }
        let m = &meshes[0];
        assert_eq!(m.positions[0], DVec3::new(-1.0, 2.0, -300.0));
        assert_eq!(m.positions[2], DVec3::new(127.0, 255.0, 32767.0));
        assert_eq!(m.vertex_attrs.label("c").unwrap(), &[4_000_000_000, 0, 1]);
        assert_eq!(m.vertex_attrs.scalar("b").unwrap(), &[-70000.0, 0.0, 1.0]);
        assert_eq!(m.vertex_attrs.scalar("e").unwrap(), &[0.25, 0.0, 1e300]);
        assert_eq!(m.faces, vec![[0, 1, 2]]);
        assert_eq!(meshes[1], meshes[0]);
        assert_eq!(meshes[2], meshes[0]);
    }

    #[test]
    fn tristrips_with_restarts_alternate_winding_and_skip_degenerates() {
        // Strip 0 1 2 3 4, restart, strip 5 5 6 7 (first triangle degenerate).
        //   1---3          triangles: (0,1,2) (2,1,3) (2,3,4)  then  (6,5,7)? no:
        //  / \ / \         the second run's triangles are (5,5,6) skipped and (5,6,7)
        // 0---2---4        at odd position, so written (6,5,7).
        let header = "element vertex 8\nproperty float x\nproperty float y\nproperty float z\n\
                      element tristrips 1\nproperty list int int vertex_indices\n";
        for (be, format) in [(false, "binary_little_endian"), (true, "binary_big_endian")] {
            let mut b = Body::new(be);
            for i in 0..8 {
                b.f32(i as f32).f32((i % 2) as f32).f32(0.0);
            }
            let strip = [0, 1, 2, 3, 4, -1, 5, 5, 6, 7];
            b.i32(strip.len() as i32);
            strip.iter().for_each(|&v| {
                b.i32(v);
            });
            let (m, notes) = load(&file(format, header, &b.bytes)).unwrap();
            assert!(notes.is_empty(), "{notes:?}");
            assert_eq!(m.faces, vec![[0, 1, 2], [2, 1, 3], [2, 3, 4], [6, 5, 7]]);
        }
        let ascii =
            "0 0 0\n1 1 0\n2 0 0\n3 1 0\n4 0 0\n5 1 0\n6 0 0\n7 1 0\n10 0 1 2 3 4 -1 5 5 6 7\n";
        let (m, _) = load(&file("ascii", header, ascii.as_bytes())).unwrap();
        assert_eq!(m.faces, vec![[0, 1, 2], [2, 1, 3], [2, 3, 4], [6, 5, 7]]);
    }

    #[test]
    fn unknown_elements_and_list_properties_are_skipped_in_binary() {
        let header = "element vertex 3\nproperty float x\nproperty list uchar float extra\n\
                      property float y\nproperty float z\n\
                      element material 2\nproperty list int short codes\nproperty double w\n\
                      element face 1\nproperty list uchar int vertex_indices\n\
                      property list uchar float texcoord\n\
                      element camera 1\nproperty float f\n";
        let mut b = Body::new(false);
        for i in 0..3 {
            b.f32(i as f32).u8(2).f32(9.0).f32(9.0).f32(1.0).f32(2.0);
        }
        b.i32(3).i16(1).i16(2).i16(3).f64(0.5);
        b.i32(0).f64(0.5);
        b.u8(3).i32(0).i32(1).i32(2).u8(6);
        (0..6).for_each(|_| {
            b.f32(0.25);
        });
        b.f32(50.0);
        let (m, notes) = load(&file("binary_little_endian", header, &b.bytes)).unwrap();
        assert_eq!(m.positions[2], DVec3::new(2.0, 1.0, 2.0));
        assert_eq!(m.faces, vec![[0, 1, 2]]);
        assert_eq!(
            notes,
            [
                "vertex list property `extra` not kept",
                "element `material` (2 items) skipped",
                "face list property `texcoord` not kept",
                "element `camera` (1 item) skipped",
            ]
        );
    }

    #[test]
    fn truncated_binary_names_offset_and_sizes() {
        let full = square(false, "binary_little_endian");
        let header_len = full.len() - 4 * 12 - 17 - 13;
        // Cut inside the vertex block: the whole block is known to be missing.
        let e = err(&full[..header_len + 20]);
        assert_eq!(
            e,
            format!(
                "x.ply: truncated: expected 48 bytes of vertex data at offset {header_len}, found 20"
            )
        );
        // Cut inside the second face.
        let e = err(&full[..full.len() - 5]);
        assert_eq!(
            e,
            format!(
                "x.ply: face 1: truncated: expected 12 bytes of face data at offset {}, found 7",
                full.len() - 12
            )
        );
    }

    #[test]
    fn header_only_and_absurd_counts_are_errors_without_allocating() {
        let header = "element vertex 8\nproperty float x\nproperty float y\nproperty float z\n";
        let only = file("binary_little_endian", header, b"");
        assert_eq!(
            err(&only),
            "x.ply: header promises 8 vertices but the file has only 0 bytes left"
        );
        assert_eq!(
            err(&file("ascii", header, b"")),
            "x.ply: header promises 8 vertices but the file has only 0 bytes left"
        );
        let huge =
            "element vertex 1000000000000\nproperty float x\nproperty float y\nproperty float z\n";
        let body = vec![0u8; 812];
        assert_eq!(
            err(&file("binary_little_endian", huge, &body)),
            "x.ply: header promises 1000000000000 vertices but the file has only 812 bytes left"
        );
        let faces = "element vertex 0\nproperty float x\nproperty float y\nproperty float z\n\
                     element face 18446744073709551615\nproperty list uchar int vertex_indices\n";
        assert!(
            err(&file("binary_big_endian", faces, &body))
                .contains("header promises 18446744073709551615 faces")
        );
        assert!(
            err(&file("ascii", faces, &body))
                .contains("header promises 18446744073709551615 faces")
        );
        // An element without properties takes no bytes, whatever its count.
        let empty = "element nothing 1000000000000\n";
        let (m, _) = load(&file("binary_little_endian", empty, b"")).unwrap();
        assert_eq!(m.n_vertices(), 0);
    }

    #[test]
    fn wrong_magic_and_bad_header_lines_are_named() {
        assert_eq!(
            err(b"PLY\nformat ascii 1.0\n"),
            "x.ply: not a PLY file (no \"ply\" magic)"
        );
        assert_eq!(
            err(b"solid x\n"),
            "x.ply: not a PLY file (no \"ply\" magic)"
        );
        assert_eq!(
            err(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nwhat is this\nend_header\n"),
            "x.ply:5: unknown header line `what is this`"
        );
        assert_eq!(
            err(&file(
                "ascii",
                "element vertex 1\nproperty float x\nproperty float y\n",
                b"0 0\n"
            )),
            "x.ply: the vertex element has no scalar `z` property"
        );
    }

    #[test]
    fn out_of_range_and_negative_indices_name_the_face() {
        let mut b = square(false, "binary_little_endian");
        let n = b.len();
        b[n - 4..].copy_from_slice(&40000i32.to_le_bytes());
        assert_eq!(
            err(&b),
            "x.ply: face 1: face refers to vertex 40000 but only 4 vertices are defined"
        );
        b[n - 4..].copy_from_slice(&(-2i32).to_le_bytes());
        assert_eq!(
            err(&b),
            "x.ply: face 1: face refers to vertex -2 but only 4 vertices are defined"
        );
        let header = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                      element face 1\nproperty list uchar int vertex_indices\n";
        let ascii = "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n";
        assert_eq!(
            err(&file("ascii", header, ascii.as_bytes())),
            "x.ply:13: face 0: face refers to vertex 3 but only 3 vertices are defined"
        );
        assert_eq!(
            err(&file("ascii", header, b"0 0 0\n1 0 0\n0 1 0\n2 0 1\n")),
            "x.ply:13: face 0: a face needs at least 3 vertex indices, this one has 2"
        );
    }

    /// The header of a triangle with an `edge` element of `n` edges whose properties are
    /// `props` (property lines).
    fn edge_header(n: usize, props: &str) -> String {
        format!(
            "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
             element face 1\nproperty list uchar int vertex_indices\n\
             element edge {n}\n{props}"
        )
    }

    #[test]
    fn edge_elements_are_read_in_every_encoding() {
        // vertex2 before vertex1, of two integer types, between properties that are skipped.
        let props = "property uchar red\nproperty short vertex2\nproperty uint vertex1\n\
                     property float w\n";
        let header = edge_header(2, props);
        let ascii = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n255 1 0 0.5\n0 0 2 1\n";
        let (m, notes) = load(&file("ascii", &header, ascii.as_bytes())).unwrap();
        assert_eq!(m.marked_edges, vec![[0, 1], [2, 0]]);
        assert_eq!(notes, ["edge properties (red, w) not kept"]);
        for (be, format) in [(false, "binary_little_endian"), (true, "binary_big_endian")] {
            let mut b = Body::new(be);
            for p in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
                b.f32(p[0]).f32(p[1]).f32(p[2]);
            }
            b.u8(3).i32(0).i32(1).i32(2);
            b.u8(255).i16(1).u32(0).f32(0.5);
            b.u8(0).i16(0).u32(2).f32(1.0);
            let (back, _) = load(&file(format, &header, &b.bytes)).unwrap();
            assert_eq!(back, m, "{format}");
        }
    }

    #[test]
    fn malformed_edge_elements_are_named() {
        let plain = edge_header(1, "property int vertex1\nproperty int vertex2\n");
        let tri = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        let ascii = |edge: &str| file("ascii", &plain, format!("{tri}{edge}").as_bytes());
        assert_eq!(
            err(&ascii("0 3\n")),
            "x.ply:17: edge 0: edge refers to vertex 3 but only 3 vertices are defined"
        );
        assert_eq!(
            err(&ascii("-1 2\n")),
            "x.ply:17: edge 0: edge refers to vertex -1 but only 3 vertices are defined"
        );
        assert_eq!(
            err(&ascii("0 1.5\n")),
            "x.ply:17: edge 0: `1.5` is not a int"
        );
        assert_eq!(
            err(&ascii("0\n")),
            "x.ply:17: edge 0: the data ends inside edge 0"
        );
        let mut b = Body::new(false);
        for p in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            b.f32(p[0]).f32(p[1]).f32(p[2]);
        }
        b.u8(3).i32(0).i32(1).i32(2);
        b.i32(2).i32(7);
        assert_eq!(
            err(&file("binary_little_endian", &plain, &b.bytes)),
            "x.ply: edge 0: edge refers to vertex 7 but only 3 vertices are defined"
        );
        for (props, message) in [
            (
                "property int vertex1\nproperty uchar red\n",
                "x.ply: the edge element has no `vertex2` property",
            ),
            (
                "property float vertex1\nproperty int vertex2\n",
                "x.ply: the edge element's `vertex1` property is a float, not an integer",
            ),
            (
                "property list uchar int vertex1\nproperty int vertex2\n",
                "x.ply: the edge element's `vertex1` property is a list, not an integer",
            ),
        ] {
            let header = edge_header(1, props);
            assert_eq!(
                err(&file("ascii", &header, format!("{tri}0 1\n").as_bytes())),
                message
            );
        }
    }

    #[test]
    fn nan_coordinates_name_the_vertex_in_every_encoding() {
        let mut b = square(false, "binary_little_endian");
        let at = b.len() - 30 - 48 + 12 + 4;
        b[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(err(&b), "x.ply: vertex 1: coordinate is NaN");
        let header = "element vertex 2\nproperty double x\nproperty double y\nproperty double z\n\
                      property double w\n";
        let mut b = Body::new(true);
        b.f64(0.0)
            .f64(0.0)
            .f64(0.0)
            .f64(0.0)
            .f64(f64::INFINITY)
            .f64(0.0)
            .f64(0.0)
            .f64(0.0);
        assert_eq!(
            err(&file("binary_big_endian", header, &b.bytes)),
            "x.ply: vertex 1: coordinate is infinite"
        );
        assert_eq!(
            err(&file("ascii", header, b"0 0 0 0\n0 nan 0 0\n")),
            "x.ply:10: vertex 1: coordinate is NaN"
        );
    }

    #[test]
    fn bad_ascii_values_name_line_and_element() {
        let header = "element vertex 2\nproperty float x\nproperty float y\nproperty uchar z\n";
        assert_eq!(
            err(&file("ascii", header, b"0 0 0\n0 0 300\n")),
            "x.ply:9: vertex 1: `300` is not a uchar"
        );
        assert_eq!(
            err(&file("ascii", header, b"0 0 0\n0 zero 3\n")),
            "x.ply:9: vertex 1: `zero` is not a number"
        );
        assert_eq!(
            err(&file("ascii", header, b"0 0 0\n0         0\n")),
            "x.ply:9: vertex 1: the data ends inside vertex 1"
        )
    }

    #[test]
    fn non_finite_attribute_columns_are_dropped_with_a_note() {
        let header = "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
                      property float q\nproperty float k\n";
        let (m, notes) = load(&file("ascii", header, b"0 0 0 nan 1\n")).unwrap();
        assert!(m.vertex_attrs.get("q").is_none());
        assert_eq!(m.vertex_attrs.scalar("k"), Some(&[1.0][..]));
        assert_eq!(
            notes,
            ["vertex attribute `q` not kept: its value at vertex 0 is not finite"]
        );
    }

    #[test]
    fn limits_are_enforced_before_and_while_reading() {
        let opts = ReadOptions {
            max_faces: Some(2),
            max_vertices: Some(3),
            ..Default::default()
        };
        let e = read(&square(false, "binary_little_endian"), "x.ply", &opts).unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.ply: more than 3 vertices (the limit set by ReadOptions::max_vertices)"
        );
        let opts = ReadOptions {
            max_faces: Some(2),
            ..Default::default()
        };
        let e = read(&square(false, "binary_little_endian"), "x.ply", &opts).unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.ply: face 1: more than 2 faces (the limit set by ReadOptions::max_faces)"
        );
    }

    #[test]
    fn strips_and_face_attributes_together_drop_the_attributes_with_a_note() {
        let header = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                      element face 1\nproperty list uchar int vertex_indices\nproperty float q\n\
                      element tristrips 1\nproperty list int int vertex_indices\n";
        let body = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2 0.5\n3 0 1 2\n";
        let (m, notes) = load(&file("ascii", header, body.as_bytes())).unwrap();
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 1, 2]]);
        assert!(m.face_attrs.is_empty());
        assert_eq!(
            notes,
            ["face attributes (q) not kept: triangle strips add faces that have none"]
        );
    }

    #[test]
    fn trailing_data_is_noted() {
        let mut b = square(false, "binary_little_endian");
        b.extend_from_slice(b"junk");
        assert_eq!(load(&b).unwrap().1, ["data after the last element ignored"]);
    }
}
