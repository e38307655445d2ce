//! Loading meshes for the commands: read the file, then the reported load-time clean-up.

use anyhow::{Context as _, Result};
use coarsen_io::{ErrorKind, Format, IoError, ReadOptions};
use coarsen_mesh::{Mesh, hygiene, scale};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// The default of `--max-faces`: input files with more triangles are refused.
pub const DEFAULT_MAX_FACES: u64 = 50_000_000;

/// File bytes allowed per face of `--max-faces` (a text OBJ with texture coordinates and
/// normals needs about 100); files longer than that are refused before they are read.
pub const BYTES_PER_FACE: u64 = 256;

/// Files up to this length are never refused for their size alone.
const MIN_FILE_LIMIT: u64 = 1 << 20;

/// The `--max-faces` in force (set once from the command line).
static MAX_FACES: AtomicU64 = AtomicU64::new(DEFAULT_MAX_FACES);

/// Sets the `--max-faces` limit of every later load.
pub fn set_max_faces(n: u64) {
    MAX_FACES.store(n, Ordering::Relaxed);
}

/// The reader limits that `--max-faces N` implies: at most N triangles, 3·N vertices
/// (every face with corners of its own) and `max(256·N bytes, 1 MiB)` of file.
pub fn read_options(max_faces: u64) -> ReadOptions {
    let n = usize::try_from(max_faces).unwrap_or(usize::MAX);
    ReadOptions {
        max_faces: Some(n),
        max_vertices: Some(n.saturating_mul(3)),
        max_file_bytes: Some(max_faces.saturating_mul(BYTES_PER_FACE).max(MIN_FILE_LIMIT)),
    }
}

/// Reads `path` under the `--max-faces` limits; an error from a limit says how to raise it.
fn read(path: &Path) -> Result<coarsen_io::Loaded> {
    let max_faces = MAX_FACES.load(Ordering::Relaxed);
    coarsen_io::read_path(path, &read_options(max_faces)).map_err(|e: IoError| {
        if matches!(
            e.kind,
            ErrorKind::OverLimit { .. } | ErrorKind::FileTooLarge { .. }
        ) {
            anyhow::anyhow!("{e}; --max-faces {max_faces} is in force: raise it to read this file")
        } else {
            e.into()
        }
    })
}

/// A loaded, cleaned mesh and what loading said about it.
pub struct Input {
    /// The mesh, scaled by `2^scale_exponent` (see [`restore`]).
    pub mesh: Mesh,
    /// Reader notes and clean-up lines, for the run report.
    pub notes: Vec<String>,
    /// Meshes of extreme size (coordinates beyond 2^±64) are computed on at a size near 1,
    /// scaled exactly by this power of two; 0 for ordinary meshes.
    pub scale_exponent: i32,
}

/// A mesh computed at `2^scale_exponent` back in the input's units (exact: scaling by
/// powers of two is lossless).
pub fn restore(mut mesh: Mesh, scale_exponent: i32) -> Mesh {
    scale::scale_by_power_of_two(&mut mesh, -scale_exponent);
    mesh
}

/// Reads `path` and applies load-time clean-up (welding when `weld` or for STL). A mesh
/// with no face left is an error.
pub fn load(path: &Path, weld: bool) -> Result<Input> {
    let loaded = read(path)?;
    let mut notes = loaded.notes;
    let mut mesh = loaded.mesh;
    let k = scale::normalizing_exponent(&mesh);
    if k != 0 {
        scale::scale_by_power_of_two(&mut mesh, k);
        notes.push(format!(
            "coordinates rescaled exactly by 2^{k} for computing (extreme size); the output is in \
             the input's units, absolute figures of the report in the rescaled ones"
        ));
    }
    let opts = hygiene::HygieneOptions {
        weld: weld || loaded.format == Format::Stl,
        ..Default::default()
    };
    let (mesh, report) = hygiene::clean(mesh, &opts).with_context(|| path.display().to_string())?;
    notes.extend(report.lines());
    if mesh.n_faces() == 0 {
        let steps: Vec<String> = report
            .lines()
            .into_iter()
            .filter(|l| !l.ends_with(": 0"))
            .collect();
        anyhow::bail!(
            "{}: no face left after clean-up ({})",
            path.display(),
            steps.join("; ")
        );
    }
    Ok(Input {
        mesh,
        notes,
        scale_exponent: k,
    })
}

/// Reads `path` exactly as the file has it.
pub fn load_raw(path: &Path) -> Result<Input> {
    let loaded = read(path)?;
    Ok(Input {
        mesh: loaded.mesh,
        notes: loaded.notes,
        scale_exponent: 0,
    })
}

/// Refuses to write over the input file.
pub fn ensure_not_input(input: Option<&Path>, output: &Path) -> Result<()> {
    if let Some(input) = input
        && let (Ok(a), Ok(b)) = (input.canonicalize(), output.canonicalize())
        && a == b
    {
        anyhow::bail!("refusing to overwrite the input file {}", input.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn max_faces_sets_every_reader_limit() {
        let o = read_options(1000);
        assert_eq!(o.max_faces, Some(1000));
        assert_eq!(o.max_vertices, Some(3000));
        assert_eq!(o.max_file_bytes, Some(1 << 20));
        let o = read_options(DEFAULT_MAX_FACES);
        assert_eq!(o.max_file_bytes, Some(12_800_000_000));
        let o = read_options(u64::MAX);
        assert_eq!(o.max_file_bytes, Some(u64::MAX));
    }
}
