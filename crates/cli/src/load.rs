//! Loading meshes for the commands: read the file under the `--max-faces` limits, then the
//! facade's load-time clean-up.

use anyhow::Result;
use coarsen::Cleaned;
use coarsen_io::{ErrorKind, ReadOptions};
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
        ..ReadOptions::default()
    }
}

/// The `--gltf-mesh` in force (set once from the command line).
static GLTF_MESH: std::sync::OnceLock<String> = std::sync::OnceLock::new();

/// Makes every later load of a glTF file read only the mesh called `name`.
pub fn set_gltf_mesh(name: String) {
    let _ = GLTF_MESH.set(name);
}

/// Reads `path` under the `--max-faces` limits (and `--gltf-mesh`); an error from a limit
/// says how to raise it.
pub fn open(path: &Path) -> Result<coarsen::Input> {
    let max_faces = MAX_FACES.load(Ordering::Relaxed);
    let opts = ReadOptions {
        gltf_mesh: GLTF_MESH.get().cloned(),
        ..read_options(max_faces)
    };
    coarsen::open(path, &opts).map_err(|e| match e {
        coarsen::Error::Io(e)
            if matches!(
                e.kind,
                ErrorKind::OverLimit { .. } | ErrorKind::FileTooLarge { .. }
            ) =>
        {
            anyhow::anyhow!("{e}; --max-faces {max_faces} is in force: raise it to read this file")
        }
        e => e.into(),
    })
}

/// Reads `path` and applies the load-time clean-up every run applies (welding when `weld`
/// or for STL). A mesh with no face left is an error.
pub fn load(path: &Path, weld: bool) -> Result<Cleaned> {
    Ok(coarsen::clean(open(path)?, weld)?)
}

/// Reads `path` exactly as the file has it, with the reader's notes.
pub fn load_raw(path: &Path) -> Result<Cleaned> {
    let input = open(path)?;
    Ok(Cleaned {
        mesh: input.mesh,
        notes: input.notes,
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
