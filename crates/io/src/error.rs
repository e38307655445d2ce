//! The one error type of the crate: what went wrong, in which file and where in it.

use crate::Format;
use std::fmt;

/// A failure to read or write a mesh file: the file, the place in it, and what went wrong.
///
/// Displays as `file:line: message` for text formats (`bunny.obj:1234: face refers to
/// vertex 40000 but only 35947 vertices are defined`) and `file: element n: message` for
/// binary ones (`x.ply: vertex 17: coordinate is NaN`).
#[derive(Debug, thiserror::Error)]
#[error("{file}{at}: {kind}")]
pub struct IoError {
    /// The file's name as the caller gave it.
    pub file: String,
    /// Where in the file the problem is.
    pub at: Location,
    /// What the problem is.
    pub kind: ErrorKind,
}

impl IoError {
    /// An error about the file as a whole.
    pub(crate) fn file(file: &str, kind: ErrorKind) -> Self {
        IoError {
            file: file.to_string(),
            at: Location::File,
            kind,
        }
    }

    /// An error at a line of a text file.
    pub(crate) fn line(file: &str, line: usize, kind: ErrorKind) -> Self {
        IoError {
            file: file.to_string(),
            at: Location::Line(line),
            kind,
        }
    }

    /// An error at the `index`-th element called `element` (binary files).
    pub(crate) fn element(file: &str, element: &str, index: u64, kind: ErrorKind) -> Self {
        IoError {
            file: file.to_string(),
            at: Location::Element {
                element: element.to_string(),
                index,
            },
            kind,
        }
    }

    /// An error at an element that sits at a known line of a text file.
    pub(crate) fn line_element(
        file: &str,
        line: usize,
        element: &str,
        index: u64,
        kind: ErrorKind,
    ) -> Self {
        IoError {
            file: file.to_string(),
            at: Location::LineElement {
                line,
                element: element.to_string(),
                index,
            },
            kind,
        }
    }
}

/// Where in a file an [`IoError`] happened.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Location {
    /// The file as a whole (opening, size, magic number).
    File,
    /// A line of a text file, counted from 1.
    Line(usize),
    /// An element of a binary file: its kind (`vertex`, `face`, `facet`) and its number as
    /// the format counts (from 0 in PLY, OFF and STL).
    Element {
        /// The element kind.
        element: String,
        /// Its number.
        index: u64,
    },
    /// An element of a text file and the line it sits on (OBJ vertices count from 1, as
    /// OBJ indices do; PLY and OFF elements from 0).
    LineElement {
        /// The line, from 1.
        line: usize,
        /// The element kind.
        element: String,
        /// Its number.
        index: u64,
    },
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::File => Ok(()),
            Location::Line(line) => write!(f, ":{line}"),
            Location::Element { element, index } => write!(f, ": {element} {index}"),
            Location::LineElement {
                line,
                element,
                index,
            } => write!(f, ":{line}: {element} {index}"),
        }
    }
}

/// What a face corner or edge end refers to in an index-out-of-range error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefKind {
    /// A vertex position.
    Vertex,
    /// An OBJ texture coordinate (`vt`).
    TexCoord,
    /// An OBJ normal (`vn`).
    Normal,
}

impl RefKind {
    fn plural(self) -> &'static str {
        match self {
            RefKind::Vertex => "vertices",
            RefKind::TexCoord => "texture coordinates",
            RefKind::Normal => "normals",
        }
    }
}

impl fmt::Display for RefKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            RefKind::Vertex => "vertex",
            RefKind::TexCoord => "texture coordinate",
            RefKind::Normal => "normal",
        })
    }
}

/// What went wrong, without the place (see [`IoError`]).
#[derive(Debug, thiserror::Error)]
pub enum ErrorKind {
    /// The operating system refused to read or write the file.
    #[error("{0}")]
    Os(#[from] std::io::Error),
    /// The file has no bytes at all.
    #[error("the file is empty")]
    Empty,
    /// The file name's extension names no format this crate knows.
    #[error(
        "cannot tell the mesh format from the file name (expected .obj, .ply, .stl, .off, .gltf or .glb)"
    )]
    UnknownFormat,
    /// The bytes do not start the way the format requires.
    #[error("not {} {format} file ({detail})", article(*format))]
    NotFormat {
        /// The format the bytes were read as.
        format: Format,
        /// What is missing.
        detail: String,
    },
    /// A malformed statement, header line or value.
    #[error("{0}")]
    Syntax(String),
    /// Something the format allows but this reader does not handle.
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// A face corner or an edge end names an element that does not exist.
    #[error("{by} refers to {what} {index} but only {count} {} are defined", what.plural())]
    OutOfRange {
        /// What refers to it: `face` (a face corner) or `edge` (an end of a marked edge).
        by: &'static str,
        /// What the corner refers to.
        what: RefKind,
        /// The index as written in the file.
        index: i64,
        /// How many such elements exist.
        count: u64,
    },
    /// A coordinate that is NaN or infinite.
    #[error("coordinate is {0}")]
    NonFinite(&'static str),
    /// The data ends before an element does.
    #[error(
        "truncated: expected {expected} bytes of {what} data at offset {offset}, found {found}"
    )]
    Truncated {
        /// The element kind being read.
        what: String,
        /// Bytes needed.
        expected: u64,
        /// Where they start.
        offset: u64,
        /// Bytes there are.
        found: u64,
    },
    /// A header count that the rest of the file cannot possibly hold.
    #[error("header promises {count} {what} but the file has only {remaining} bytes left")]
    CountTooLarge {
        /// The count the header gives.
        count: u64,
        /// Of what (plural).
        what: String,
        /// The bytes left after the header.
        remaining: u64,
    },
    /// A file longer than [`crate::ReadOptions::max_file_bytes`].
    #[error(
        "the file has {len} bytes, more than the limit of {limit} (ReadOptions::max_file_bytes)"
    )]
    FileTooLarge {
        /// The file's length.
        len: u64,
        /// The limit.
        limit: u64,
    },
    /// More elements than a [`crate::ReadOptions`] limit allows.
    #[error("more than {limit} {what} (the limit set by ReadOptions::{option})")]
    OverLimit {
        /// Of what (plural).
        what: &'static str,
        /// The limit.
        limit: usize,
        /// The option that sets it.
        option: &'static str,
    },
    /// More elements than 32-bit indices can address.
    #[error("{count} {what} do not fit 32-bit indices")]
    TooMany {
        /// How many.
        count: u64,
        /// Of what (plural).
        what: &'static str,
    },
    /// The mesh given to a writer is inconsistent (index out of range, wrong column length).
    #[error("the mesh to write is invalid: {0}")]
    InvalidMesh(#[from] coarsen_mesh::IndexError),
    /// Two attributes that a writer would store under the same property name.
    #[error("two properties of the {element} element would be called `{property}`")]
    NameClash {
        /// The element (`vertex` or `face`).
        element: &'static str,
        /// The property name.
        property: String,
    },
    /// An attribute name that the format cannot store.
    #[error("attribute name `{0}` cannot be written: names must be non-empty ASCII without spaces")]
    BadAttributeName(String),
}

impl ErrorKind {
    /// More faces than [`crate::ReadOptions::max_faces`].
    pub(crate) fn over_limit_faces(limit: usize) -> Self {
        ErrorKind::OverLimit {
            what: "faces",
            limit,
            option: "max_faces",
        }
    }

    /// More vertices than [`crate::ReadOptions::max_vertices`].
    pub(crate) fn over_limit_vertices(limit: usize) -> Self {
        ErrorKind::OverLimit {
            what: "vertices",
            limit,
            option: "max_vertices",
        }
    }
}

/// The indefinite article before a format's name as it is spoken ("an OBJ", "a PLY").
fn article(format: Format) -> &'static str {
    match format {
        Format::Ply | Format::Gltf | Format::Glb => "a",
        Format::Obj | Format::Stl | Format::Off => "an",
    }
}

/// Plural of a PLY element name for messages: `vertices`, `faces`, `foo elements`.
pub(crate) fn plural(element: &str) -> String {
    match element {
        "vertex" => "vertices".to_string(),
        "face" => "faces".to_string(),
        "tristrips" => "triangle strips".to_string(),
        other => format!("{other} elements"),
    }
}
