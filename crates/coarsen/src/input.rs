//! Meshes in and out: reading and writing files, meshes from plain arrays, and the
//! load-time clean-up every run applies to its input.

use crate::Error;
use coarsen_io::{Format, ReadOptions, WriteOptions};
use coarsen_mesh::{DVec3, Mesh, hygiene, scale};
use std::path::Path;

/// A mesh to run on, with its name and what reading it said.
///
/// ```
/// let input = coarsen::Input::new(coarsen::demo(), "bumpy sphere");
/// let done = coarsen::Remesher::new()
///     .pipeline("qem")
///     .target(coarsen::Target::Vertices(1000))
///     .run_input(input)?;
/// assert_eq!(done.report.input, "bumpy sphere");
/// assert_eq!(done.mesh.n_vertices(), 1000);
/// # Ok::<(), coarsen::Error>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Input {
    /// The mesh as read (or as built): nothing cleaned yet.
    pub mesh: Mesh,
    /// Its name in reports and errors: the file path, or what the caller calls it.
    pub name: String,
    /// What the reader left out or changed (unknown elements, seamed UVs, …), one
    /// sentence each; the run report starts its input notes with them.
    pub notes: Vec<String>,
    /// Weld vertices at bit-identical positions during the clean-up: set for formats that
    /// store every triangle's corners apart (STL).
    pub weld: bool,
}

impl Input {
    /// A mesh built in memory, called `name` in reports and errors.
    pub fn new(mesh: Mesh, name: impl Into<String>) -> Input {
        Input {
            mesh,
            name: name.into(),
            notes: Vec::new(),
            weld: false,
        }
    }

    /// The built-in demo mesh (a bumpy sphere), what `coarsen` runs on without a file.
    pub fn demo() -> Input {
        Input {
            notes: vec!["built-in demo mesh".into()],
            ..Input::new(coarsen_shapes::demo(), "demo")
        }
    }
}

impl From<Mesh> for Input {
    fn from(mesh: Mesh) -> Input {
        Input::new(mesh, "mesh")
    }
}

/// Reads the mesh file at `path` (OBJ, PLY, STL, OFF, glTF or GLB, by its extension) with no limits
/// on its size, and with an STL file's coincident corners welded: the mesh to hand to
/// [`remesh`](crate::remesh) or a [`Remesher`](crate::Remesher).
///
/// ```no_run
/// let mesh = coarsen::read("bunny.ply")?;
/// println!("{} vertices, {} faces", mesh.n_vertices(), mesh.n_faces());
/// # Ok::<(), coarsen::Error>(())
/// ```
pub fn read(path: impl AsRef<Path>) -> Result<Mesh, Error> {
    let input = open(path, &ReadOptions::default())?;
    if !input.weld {
        return Ok(input.mesh);
    }
    // Only the weld (and the copies it leaves unreferenced): the rest of the clean-up is
    // the run's, and gives the same mesh after it as after one clean-up with the weld.
    let only_weld = hygiene::HygieneOptions {
        weld: true,
        drop_degenerate: false,
        drop_duplicate_faces: false,
        drop_unreferenced: true,
        ..Default::default()
    };
    let (mesh, _) = hygiene::clean(input.mesh, &only_weld).map_err(|e| Error::Input {
        name: input.name,
        message: e.to_string(),
    })?;
    Ok(mesh)
}

/// Reads the mesh file at `path` under the reader limits `opts` (the command line's
/// `--max-faces`), keeping the reader's notes and the format's need to weld.
///
/// ```no_run
/// let limits = coarsen::ReadOptions { max_faces: Some(1_000_000), ..Default::default() };
/// let input = coarsen::open("scan.ply", &limits)?;
/// for note in &input.notes {
///     println!("{}: {note}", input.name);
/// }
/// # Ok::<(), coarsen::Error>(())
/// ```
pub fn open(path: impl AsRef<Path>, opts: &ReadOptions) -> Result<Input, Error> {
    let path = path.as_ref();
    let loaded = coarsen_io::read_path(path, opts)?;
    Ok(Input {
        mesh: loaded.mesh,
        name: path.display().to_string(),
        notes: loaded.notes,
        weld: loaded.format == Format::Stl,
    })
}

/// Writes `mesh` to `path` in the format of its extension (binary PLY for `.ply`, with
/// every attribute the format holds), through a temporary file and a rename: a failure
/// never leaves a half-written file.
///
/// ```no_run
/// # let mesh = coarsen::demo();
/// coarsen::write("out.ply", &mesh)?;
/// # Ok::<(), coarsen::Error>(())
/// ```
pub fn write(path: impl AsRef<Path>, mesh: &Mesh) -> Result<(), Error> {
    write_with(path, mesh, &WriteOptions::default())
}

/// [`write()`] with the encoding and attribute choices of `opts`.
///
/// ```no_run
/// # let mesh = coarsen::demo();
/// let ascii = coarsen::WriteOptions {
///     ply_encoding: coarsen::PlyEncoding::Ascii,
///     ..Default::default()
/// };
/// coarsen::write_with("out.ply", &mesh, &ascii)?;
/// # Ok::<(), coarsen::Error>(())
/// ```
pub fn write_with(path: impl AsRef<Path>, mesh: &Mesh, opts: &WriteOptions) -> Result<(), Error> {
    Ok(coarsen_io::write_path(mesh, path.as_ref(), opts)?)
}

/// The built-in demo mesh: a bumpy sphere of 10,242 vertices.
///
/// ```
/// assert_eq!(coarsen::demo().n_vertices(), 10_242);
/// ```
pub fn demo() -> Mesh {
    coarsen_shapes::demo()
}

/// A mesh from plain arrays: one `[x, y, z]` per vertex and three vertex indices per
/// triangle. Indices out of range are refused, naming the face; non-finite coordinates
/// are refused by the run's clean-up.
///
/// ```
/// let mesh = coarsen::mesh_from_arrays(
///     vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
///     vec![[0, 1, 2]],
/// )?;
/// assert_eq!(mesh.n_faces(), 1);
/// # Ok::<(), coarsen::Error>(())
/// ```
pub fn mesh_from_arrays(positions: Vec<[f64; 3]>, faces: Vec<[u32; 3]>) -> Result<Mesh, Error> {
    let n = positions.len();
    if u32::try_from(n).is_err() {
        return Err(Error::Arrays(format!(
            "{n} vertices: at most {} fit 32-bit indices",
            u32::MAX
        )));
    }
    if let Some((f, face)) = faces
        .iter()
        .enumerate()
        .find(|(_, face)| face.iter().any(|&v| v as usize >= n))
    {
        return Err(Error::Arrays(format!(
            "face {f} is {face:?}, but there are only {n} vertices (indices 0 to {})",
            n.saturating_sub(1)
        )));
    }
    let positions = positions.into_iter().map(DVec3::from_array).collect();
    Ok(Mesh::new(positions, faces))
}

/// A mesh after the load-time clean-up, ready for a pipeline (see [`clean`]).
#[derive(Clone, Debug)]
pub struct Cleaned {
    /// The cleaned mesh, scaled by `2^scale_exponent`.
    pub mesh: Mesh,
    /// The reader's notes, then one line per clean-up step.
    pub notes: Vec<String>,
    /// Meshes of extreme size (coordinates beyond 2^±64) are computed on at a size near 1,
    /// scaled exactly by this power of two; 0 for ordinary meshes.
    pub scale_exponent: i32,
}

impl Cleaned {
    /// `mesh`, computed at the cleaned scale, back in the input's units (exact: scaling
    /// by a power of two loses nothing).
    pub fn restore(&self, mesh: Mesh) -> Mesh {
        restore(mesh, self.scale_exponent)
    }
}

/// `mesh` scaled back by `2^-scale_exponent`.
pub(crate) fn restore(mut mesh: Mesh, scale_exponent: i32) -> Mesh {
    scale::scale_by_power_of_two(&mut mesh, -scale_exponent);
    mesh
}

/// The clean-up every run applies to its input, in reported steps: non-finite
/// coordinates refused; degenerate and duplicate faces and unreferenced vertices dropped;
/// coincident vertices welded when `weld` or the input asks for it; meshes of extreme size
/// rescaled exactly by a power of two. A mesh with no face left is an error.
///
/// ```
/// let mut mesh = coarsen::demo();
/// mesh.faces.push(mesh.faces[0]); // a duplicate face
/// let cleaned = coarsen::clean(coarsen::Input::new(mesh, "demo"), false)?;
/// assert_eq!(cleaned.mesh.n_faces(), coarsen::demo().n_faces());
/// assert!(cleaned.notes.iter().any(|n| n == "drop duplicate faces: 1"));
/// # Ok::<(), coarsen::Error>(())
/// ```
pub fn clean(input: Input, weld: bool) -> Result<Cleaned, Error> {
    let Input {
        mut mesh,
        name,
        mut notes,
        weld: format_weld,
    } = input;
    let k = scale::normalizing_exponent(&mesh);
    if k != 0 {
        scale::scale_by_power_of_two(&mut mesh, k);
        notes.push(format!(
            "coordinates rescaled exactly by 2^{k} for computing (extreme size); the output is in \
             the input's units, absolute figures of the report in the rescaled ones"
        ));
    }
    let opts = hygiene::HygieneOptions {
        weld: weld || format_weld,
        ..Default::default()
    };
    let (mesh, report) = hygiene::clean(mesh, &opts).map_err(|e| Error::Input {
        name: name.clone(),
        message: e.to_string(),
    })?;
    notes.extend(report.lines());
    if mesh.n_faces() == 0 {
        let steps: Vec<String> = report
            .lines()
            .into_iter()
            .filter(|l| !l.ends_with(": 0") && !l.contains("(off)"))
            .collect();
        return Err(Error::Input {
            name,
            message: format!("no face left after clean-up ({})", steps.join("; ")),
        });
    }
    Ok(Cleaned {
        mesh,
        notes,
        scale_exponent: k,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrays_with_an_index_out_of_range_name_the_face() {
        let e = mesh_from_arrays(vec![[0.0; 3]; 3], vec![[0, 1, 2], [0, 1, 3]]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "face 1 is [0, 1, 3], but there are only 3 vertices (indices 0 to 2)"
        );
        assert!(e.is_usage());
    }

    #[test]
    fn non_finite_coordinates_are_refused_by_the_clean_up_naming_the_vertex() {
        let m = mesh_from_arrays(
            vec![[0.0, 0.0, 0.0], [1.0, f64::NAN, 0.0], [0.0, 1.0, 0.0]],
            vec![[0, 1, 2]],
        )
        .unwrap();
        let e = clean(Input::new(m, "arrays"), false).unwrap_err();
        assert!(e.to_string().starts_with("arrays: vertex 1"), "{e}");
        assert!(!e.is_usage());
    }

    #[test]
    fn a_mesh_with_nothing_left_after_clean_up_is_refused() {
        let m = mesh_from_arrays(vec![[0.0; 3]; 3], vec![[0, 1, 2]]).unwrap();
        let e = clean(Input::new(m, "flat"), false).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("flat: no face left after clean-up (drop zero-area faces: 1;"),
            "{e}"
        );
    }

    #[test]
    fn reading_an_stl_welds_what_the_reader_keeps_apart() {
        // Two triangles on the edge (0,0,0)–(1,1,0); one spells its corner `-0`.
        let text = "solid t\n\
            facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\nendloop\nendfacet\n\
            facet normal 0 0 1\nouter loop\nvertex -0 0 0\nvertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\n\
            endsolid t\n";
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.stl");
        std::fs::write(&path, text).unwrap();
        let opened = open(&path, &ReadOptions::default()).unwrap();
        assert!(opened.weld);
        assert_eq!(opened.mesh.n_vertices(), 5);
        let read = read(&path).unwrap();
        assert_eq!(read.n_vertices(), 4);
        // The same mesh as the run's one clean-up with the weld.
        assert_eq!(
            clean(opened, false).unwrap().mesh,
            clean(Input::new(read, "t"), false).unwrap().mesh
        );
    }

    #[test]
    fn extreme_sizes_are_computed_near_one_and_restored_exactly() {
        let mut m = coarsen_shapes::demo();
        m.positions.iter_mut().for_each(|p| *p *= 1e80);
        let before = m.clone();
        let c = clean(Input::new(m, "huge"), false).unwrap();
        assert_ne!(c.scale_exponent, 0);
        assert!(c.mesh.bbox().diagonal() < 1e3);
        assert!(c.notes.iter().any(|n| n.contains("rescaled exactly")));
        assert_eq!(c.restore(c.mesh.clone()).positions, before.positions);
    }
}
