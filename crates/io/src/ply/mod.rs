//! Stanford PLY: our own header parser, reader and writer.
//!
//! Why our own: we need triangle strips (`tristrips` with `-1` restarts), allocation bounded
//! by the file's size whatever the header claims, errors that name the element, and more
//! than 100 MB/s on binary files; the available crates lack one or more of these.
//!
//! # Reading
//!
//! ASCII, `binary_little_endian` and `binary_big_endian`; every scalar type (`char uchar
//! short ushort int uint float double` and the `int8 … float64` aliases) for properties,
//! list counts and list entries. Elements:
//!
//! * `vertex`: `x y z` (any scalar type) are the position. Other properties become
//!   attributes ([`columns`]): `nx ny nz` → `normal`, `red green blue` (uchar) → `color`,
//!   `s t` / `u v` / `texture_u texture_v` / `texture_s texture_t` → `uv`; then
//!   `P_x P_y P_z` (float or double) → 3-vector `P`, `P_u P_v` → 2-vector `P`,
//!   `P_red P_green P_blue` (uchar) → colour `P`; then every other scalar property keeps
//!   its name: `uint` ones as labels, the rest as scalars. List properties are skipped.
//! * `face`: the `vertex_indices` (or `vertex_index`) list, a polygon split as a fan from
//!   its first corner; other scalar properties become face attributes by the same rules,
//!   each polygon's value going to all its triangles.
//! * `tristrips`: a `vertex_indices` list of strips separated by `-1`; triangle `i` of a
//!   strip is `(s[i], s[i+1], s[i+2])`, with the first two swapped when `i` is odd so
//!   that all keep the strip's orientation; triangles with a repeated index (the padding
//!   of strip joins) are skipped.
//! * `edge`: its `vertex1` and `vertex2` properties (any integer type) are a marked
//!   feature edge ([`coarsen_mesh::Mesh::marked_edges`]), in file order, as written; its
//!   other properties (colours, …) are skipped with a note. Without either property, or
//!   with one that is not an integer, the file is refused.
//! * any other element is skipped, and named in a note.
//!
//! # Writing
//!
//! `double x y z`, then the vertex attributes named back by the rules above (labels as
//! `uint`, scalars as `double`), then `face` with a `uchar`-counted `int` list
//! (`uint` past 2³¹ vertices) and the face attributes, then, when the mesh has marked
//! edges, `edge` with `vertex1 vertex2` of the same index type. Reading the result gives
//! the same mesh bit for bit.

mod read;
mod write;

pub(crate) use read::{check_start, read};
pub(crate) use write::write;

use coarsen_mesh::AttrKind;

/// The encoding of a PLY body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Le,
    Be,
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &[u8]) -> Option<Scalar> {
        Some(match name {
            b"char" | b"int8" => Scalar::I8,
            b"uchar" | b"uint8" => Scalar::U8,
            b"short" | b"int16" => Scalar::I16,
            b"ushort" | b"uint16" => Scalar::U16,
            b"int" | b"int32" => Scalar::I32,
            b"uint" | b"uint32" => Scalar::U32,
            b"float" | b"float32" => Scalar::F32,
            b"double" | b"float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// The name written in headers.
    fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "char",
            Scalar::U8 => "uchar",
            Scalar::I16 => "short",
            Scalar::U16 => "ushort",
            Scalar::I32 => "int",
            Scalar::U32 => "uint",
            Scalar::F32 => "float",
            Scalar::F64 => "double",
        }
    }

    /// Bytes in binary encodings.
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The range of an integer type.
    fn int_range(self) -> (i64, i64) {
        match self {
            Scalar::I8 => (i8::MIN.into(), i8::MAX.into()),
            Scalar::U8 => (0, u8::MAX.into()),
            Scalar::I16 => (i16::MIN.into(), i16::MAX.into()),
            Scalar::U16 => (0, u16::MAX.into()),
            Scalar::I32 => (i32::MIN.into(), i32::MAX.into()),
            Scalar::U32 => (0, u32::MAX.into()),
            Scalar::F32 | Scalar::F64 => (i64::MIN, i64::MAX),
        }
    }
}

/// The type of one property.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PropKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

/// One property of an element.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Property {
    name: String,
    kind: PropKind,
}

/// One element declaration: a name, a count and its properties.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Element {
    name: String,
    count: u64,
    props: Vec<Property>,
}

impl Element {
    /// The size of every element when all properties are scalars.
    fn fixed_size(&self) -> Option<usize> {
        self.props
            .iter()
            .map(|p| match p.kind {
                PropKind::Scalar(s) => Some(s.size()),
                PropKind::List { .. } => None,
            })
            .sum()
    }
}

/// A parsed header.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Offset of the first body byte.
    body: usize,
    /// Number of header lines (ASCII body lines count on from here).
    lines: usize,
}

/// Why a header is refused: a message and its line.
type HeaderError = (usize, HeaderProblem);

/// A header problem.
#[derive(Debug, PartialEq, Eq)]
enum HeaderProblem {
    NoMagic,
    Syntax(String),
    Unsupported(String),
}

/// Parses the header at the start of `bytes`.
fn parse_header(bytes: &[u8]) -> Result<Header, HeaderError> {
    let magic_len = if bytes.starts_with(b"ply\n") {
        4
    } else if bytes.starts_with(b"ply\r\n") {
        5
    } else {
        return Err((0, HeaderProblem::NoMagic));
    };
    let syntax = |line, msg: String| Err((line, HeaderProblem::Syntax(msg)));
    let mut pos = magic_len;
    let mut line = 1;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        if pos >= bytes.len() {
            return syntax(line, "the header has no `end_header` line".into());
        }
        let rest = &bytes[pos..];
        let end = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
        pos += (end + 1).min(rest.len());
        line += 1;
        let text = &rest[..end];
        let mut toks = crate::text::tokens(text);
        let Some(keyword) = toks.next() else {
            continue;
        };
        let args: Vec<&[u8]> = toks.collect();
        let shown = crate::text::show(text);
        match keyword {
            b"end_header" => break,
            b"comment" | b"obj_info" => {}
            b"format" => encoding = Some(format_line(&args, line, &shown)?),
            b"element" => elements.push(element_line(&args, line, &shown, &elements)?),
            b"property" => {
                let Some(element) = elements.last_mut() else {
                    return syntax(line, "property before any element".into());
                };
                element
                    .props
                    .push(property_line(&args, line, &shown, element)?);
            }
            _ => return syntax(line, format!("unknown header line `{shown}`")),
        }
    }
    let Some(encoding) = encoding else {
        return syntax(line, "the header has no `format` line".into());
    };
    Ok(Header {
        encoding,
        elements,
        body: pos,
        lines: line,
    })
}

/// A syntax problem at header line `line`.
fn syntax_at(line: usize, msg: String) -> HeaderError {
    (line, HeaderProblem::Syntax(msg))
}

/// The encoding a `format ENCODING VERSION` line (its arguments `args`, at `line`, shown
/// as `shown`) names; only version 1.
fn format_line(args: &[&[u8]], line: usize, shown: &str) -> Result<Encoding, HeaderError> {
    let (enc, version) = match args[..] {
        [e, v] => (e, v),
        _ => return Err(syntax_at(line, format!("malformed format line `{shown}`"))),
    };
    let encoding = match enc {
        b"ascii" => Encoding::Ascii,
        b"binary_little_endian" => Encoding::Le,
        b"binary_big_endian" => Encoding::Be,
        _ => {
            return Err((
                line,
                HeaderProblem::Unsupported(format!("format `{}`", crate::text::show(enc))),
            ));
        }
    };
    if !version.starts_with(b"1") {
        return Err((
            line,
            HeaderProblem::Unsupported(format!("PLY version {}", crate::text::show(version))),
        ));
    }
    Ok(encoding)
}

/// The element an `element NAME COUNT` line declares (none declared twice among
/// `elements`, but triangle strips).
fn element_line(
    args: &[&[u8]],
    line: usize,
    shown: &str,
    elements: &[Element],
) -> Result<Element, HeaderError> {
    let [name, count] = args[..] else {
        return Err(syntax_at(line, format!("malformed element line `{shown}`")));
    };
    let Some(count) = std::str::from_utf8(count)
        .ok()
        .and_then(|c| c.parse::<u64>().ok())
    else {
        return Err(syntax_at(
            line,
            format!("malformed element count in `{shown}`"),
        ));
    };
    let name = String::from_utf8_lossy(name).into_owned();
    if elements.iter().any(|e| e.name == name) && name != "tristrips" {
        return Err(syntax_at(
            line,
            format!("element `{name}` is declared twice"),
        ));
    }
    Ok(Element {
        name,
        count,
        props: Vec::new(),
    })
}

/// The property a `property TYPE NAME` or `property list COUNT ITEM NAME` line declares
/// for `element` (no name twice in it; a list's count of an integer type).
fn property_line(
    args: &[&[u8]],
    line: usize,
    shown: &str,
    element: &Element,
) -> Result<Property, HeaderError> {
    let ty = |t: &[u8]| {
        Scalar::from_name(t).ok_or_else(|| {
            syntax_at(
                line,
                format!("unknown property type `{}`", crate::text::show(t)),
            )
        })
    };
    let (kind, name) = match args[..] {
        [b"list", count, item, name] => {
            let count = ty(count)?;
            if count.is_float() {
                return Err(syntax_at(
                    line,
                    format!("list count type `{}` is not an integer type", count.name()),
                ));
            }
            (
                PropKind::List {
                    count,
                    item: ty(item)?,
                },
                name,
            )
        }
        [t, name] if t != b"list" => (PropKind::Scalar(ty(t)?), name),
        _ => {
            return Err(syntax_at(
                line,
                format!("malformed property line `{shown}`"),
            ));
        }
    };
    let name = String::from_utf8_lossy(name).into_owned();
    if element.props.iter().any(|p| p.name == name) {
        return Err(syntax_at(
            line,
            format!(
                "property `{name}` appears twice in element `{}`",
                element.name
            ),
        ));
    }
    Ok(Property { name, kind })
}

/// How a group of scalar properties becomes one attribute column.
#[derive(Clone, Debug, PartialEq, Eq)]
struct ColumnPlan {
    /// The attribute's name.
    name: String,
    /// Its kind.
    kind: AttrKind,
    /// Indices (into the list given to [`columns`]) of the properties, one per component.
    sources: Vec<usize>,
}

/// Which property types a group of properties accepts.
#[derive(Clone, Copy, Debug)]
enum Accept {
    Any,
    Uchar,
    Float,
}

impl Accept {
    fn ok(self, t: Scalar) -> bool {
        match self {
            Accept::Any => true,
            Accept::Uchar => t == Scalar::U8,
            Accept::Float => t.is_float(),
        }
    }
}

/// Properties that together make one attribute column.
struct Group {
    /// The column's name (empty for suffix groups: the common prefix names it).
    name: &'static str,
    kind: AttrKind,
    /// Property names, or suffixes after the prefix.
    parts: &'static [&'static str],
    accept: Accept,
}

/// The reserved groups, tried in this order; the first `uv` pair found wins.
const NAMED_GROUPS: [Group; 6] = [
    Group {
        name: "normal",
        kind: AttrKind::Vec3,
        parts: &["nx", "ny", "nz"],
        accept: Accept::Any,
    },
    Group {
        name: "color",
        kind: AttrKind::Color,
        parts: &["red", "green", "blue"],
        accept: Accept::Uchar,
    },
    Group {
        name: "uv",
        kind: AttrKind::Vec2,
        parts: &["s", "t"],
        accept: Accept::Any,
    },
    Group {
        name: "uv",
        kind: AttrKind::Vec2,
        parts: &["u", "v"],
        accept: Accept::Any,
    },
    Group {
        name: "uv",
        kind: AttrKind::Vec2,
        parts: &["texture_u", "texture_v"],
        accept: Accept::Any,
    },
    Group {
        name: "uv",
        kind: AttrKind::Vec2,
        parts: &["texture_s", "texture_t"],
        accept: Accept::Any,
    },
];

/// Groups named by a common prefix: `P_x P_y P_z`, `P_u P_v`, `P_red P_green P_blue`.
const SUFFIX_GROUPS: [Group; 3] = [
    Group {
        name: "",
        kind: AttrKind::Vec3,
        parts: &["_x", "_y", "_z"],
        accept: Accept::Float,
    },
    Group {
        name: "",
        kind: AttrKind::Vec2,
        parts: &["_u", "_v"],
        accept: Accept::Float,
    },
    Group {
        name: "",
        kind: AttrKind::Color,
        parts: &["_red", "_green", "_blue"],
        accept: Accept::Uchar,
    },
];

/// Builds column plans from an element's attribute properties.
struct Planner<'p> {
    props: &'p [(&'p str, Scalar)],
    used: Vec<bool>,
    plans: Vec<ColumnPlan>,
}

impl Planner<'_> {
    /// Makes the properties called `names` (all unused, all accepted) the column `name`;
    /// false when they are not all there or the name is already planned.
    fn group(&mut self, name: &str, names: &[String], kind: AttrKind, accept: Accept) -> bool {
        if self.plans.iter().any(|p| p.name == name) {
            return false;
        }
        let find =
            |n: &String| (0..self.props.len()).find(|&i| !self.used[i] && self.props[i].0 == n);
        let Some(sources) = names.iter().map(find).collect::<Option<Vec<usize>>>() else {
            return false;
        };
        if !sources.iter().all(|&i| accept.ok(self.props[i].1)) {
            return false;
        }
        sources.iter().for_each(|&i| self.used[i] = true);
        self.plans.push(ColumnPlan {
            name: name.to_string(),
            kind,
            sources,
        });
        true
    }
}

/// Groups an element's attribute properties (name and type, in file order) into attribute
/// columns, in file order of each column's first property. Returns the plans and the
/// names of properties left out because their name is taken.
fn columns(props: &[(&str, Scalar)]) -> (Vec<ColumnPlan>, Vec<String>) {
    let mut planner = Planner {
        props,
        used: vec![false; props.len()],
        plans: Vec::new(),
    };
    for g in &NAMED_GROUPS {
        let names: Vec<String> = g.parts.iter().map(|p| p.to_string()).collect();
        planner.group(g.name, &names, g.kind, g.accept);
    }
    for (i, &(name, _)) in props.iter().enumerate() {
        for g in &SUFFIX_GROUPS {
            let prefix = match name.strip_suffix(g.parts[0]) {
                Some(p) if !p.is_empty() && !planner.used[i] => p,
                _ => continue,
            };
            let names: Vec<String> = g.parts.iter().map(|s| format!("{prefix}{s}")).collect();
            planner.group(prefix, &names, g.kind, g.accept);
        }
    }
    let mut plans = planner.plans;
    let mut clashes = Vec::new();
    for (i, &(name, ty)) in props.iter().enumerate() {
        if planner.used[i] {
            continue;
        }
        if plans.iter().any(|p| p.name == name) {
            clashes.push(name.to_string());
            continue;
        }
        let kind = if ty == Scalar::U32 {
            AttrKind::Label
        } else {
            AttrKind::Scalar
        };
        plans.push(ColumnPlan {
            name: name.to_string(),
            kind,
            sources: vec![i],
        });
    }
    plans.sort_by_key(|p| p.sources[0]);
    (plans, clashes)
}

/// The property names that [`columns`] maps back to an attribute of `kind` called `name`.
fn property_names(name: &str, kind: AttrKind) -> Vec<String> {
    if let Some(g) = NAMED_GROUPS
        .iter()
        .find(|g| g.name == name && g.kind == kind)
    {
        return g.parts.iter().map(|p| p.to_string()).collect();
    }
    match SUFFIX_GROUPS.iter().find(|g| g.kind == kind) {
        Some(g) => g.parts.iter().map(|s| format!("{name}{s}")).collect(),
        None => vec![name.to_string()],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_lists_elements_properties_and_body_offset() {
        let src = b"ply\r\nformat binary_big_endian 1.0\ncomment hi\nobj_info x\nelement vertex 3\nproperty float32 x\nproperty list uint8 int32 vertex_indices\nelement face 0\nend_header\nrest";
        let h = parse_header(src).unwrap();
        assert_eq!(h.encoding, Encoding::Be);
        assert_eq!(h.elements.len(), 2);
        assert_eq!(h.elements[0].count, 3);
        assert_eq!(
            h.elements[0].props[1].kind,
            PropKind::List {
                count: Scalar::U8,
                item: Scalar::I32
            }
        );
        assert_eq!(&src[h.body..], b"rest");
        assert_eq!(h.lines, 9);
    }

    #[test]
    fn header_problems_name_their_line() {
        let bad = |s: &[u8]| parse_header(s).unwrap_err();
        assert_eq!(bad(b"PLY\n").1, HeaderProblem::NoMagic);
        assert_eq!(bad(b"plyx").1, HeaderProblem::NoMagic);
        assert_eq!(
            bad(b"ply\nformat ascii 1.0\nelement vertex 1\n"),
            (
                3,
                HeaderProblem::Syntax("the header has no `end_header` line".into())
            )
        );
        assert_eq!(
            bad(b"ply\nelement vertex 1\nend_header\n"),
            (
                3,
                HeaderProblem::Syntax("the header has no `format` line".into())
            )
        );
        assert_eq!(
            bad(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n").0,
            4
        );
        assert_eq!(
            bad(b"ply\nformat ascii 1.0\nelement vertex -3\nend_header\n").0,
            3
        );
        assert_eq!(
            bad(b"ply\nformat ascii 1.0\nproperty float x\nend_header\n"),
            (
                3,
                HeaderProblem::Syntax("property before any element".into())
            )
        );
        assert!(matches!(
            bad(b"ply\nformat binary_middle_endian 1.0\nend_header\n"),
            (2, HeaderProblem::Unsupported(_))
        ));
        assert!(matches!(
            bad(b"ply\nformat ascii 1.0\nelement f 1\nproperty list float int i\nend_header\n"),
            (4, HeaderProblem::Syntax(_))
        ));
    }

    fn plan(props: &[(&str, Scalar)]) -> Vec<(String, AttrKind, Vec<usize>)> {
        columns(props)
            .0
            .into_iter()
            .map(|p| (p.name, p.kind, p.sources))
            .collect()
    }

    #[test]
    fn properties_group_into_named_attribute_columns_in_file_order() {
        use Scalar::*;
        let got = plan(&[
            ("quality", F32),
            ("nx", F32),
            ("ny", F32),
            ("nz", F32),
            ("red", U8),
            ("green", U8),
            ("blue", U8),
            ("alpha", U8),
            ("u", F32),
            ("v", F32),
            ("d_x", F64),
            ("d_y", F64),
            ("d_z", F64),
            ("cluster", U32),
            ("t_u", F64),
            ("t_v", F64),
            ("c_red", U8),
            ("c_green", U8),
            ("c_blue", U8),
        ]);
        let names: Vec<_> = got.iter().map(|g| (g.0.as_str(), g.1)).collect();
        assert_eq!(
            names,
            [
                ("quality", AttrKind::Scalar),
                ("normal", AttrKind::Vec3),
                ("color", AttrKind::Color),
                ("alpha", AttrKind::Scalar),
                ("uv", AttrKind::Vec2),
                ("d", AttrKind::Vec3),
                ("cluster", AttrKind::Label),
                ("t", AttrKind::Vec2),
                ("c", AttrKind::Color),
            ]
        );
        assert_eq!(got[1].2, [1, 2, 3]);
    }

    #[test]
    fn float_colours_and_partial_groups_stay_scalars() {
        use Scalar::*;
        let got = plan(&[
            ("red", F32),
            ("green", F32),
            ("blue", F32),
            ("nx", F32),
            ("s", F64),
        ]);
        assert!(got.iter().all(|g| g.1 == AttrKind::Scalar), "{got:?}");
        assert_eq!(got.len(), 5);
    }

    #[test]
    fn a_property_whose_name_is_taken_is_reported() {
        use Scalar::*;
        let (plans, clashes) = columns(&[("s", F32), ("t", F32), ("uv", F64)]);
        assert_eq!(plans.len(), 1);
        assert_eq!(clashes, ["uv"]);
    }

    #[test]
    fn written_property_names_map_back_to_the_same_columns() {
        use AttrKind::{Color, Label, Vec2, Vec3};
        for (name, kind) in [
            ("normal", Vec3),
            ("color", Color),
            ("uv", Vec2),
            ("d", Vec3),
            ("t", Vec2),
            ("c", Color),
            ("k", AttrKind::Scalar),
            ("cluster", Label),
            ("normal", Vec2),
            ("uv", Vec3),
        ] {
            let ty = match kind {
                Color => Scalar::U8,
                Label => Scalar::U32,
                _ => Scalar::F64,
            };
            let names = property_names(name, kind);
            let props: Vec<(&str, Scalar)> = names.iter().map(|n| (n.as_str(), ty)).collect();
            let got = plan(&props);
            assert_eq!(got.len(), 1, "{name} {kind}");
            assert_eq!((got[0].0.as_str(), got[0].1), (name, kind));
        }
    }
}
