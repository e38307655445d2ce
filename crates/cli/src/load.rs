//! Loading meshes for the commands: read the file, then the reported load-time clean-up.

use anyhow::{Context as _, Result};
use coarsen_io::{Format, ReadOptions};
use coarsen_mesh::{Mesh, hygiene};
use std::path::Path;

/// A loaded, cleaned mesh and what loading said about it.
pub struct Input {
    /// The mesh.
    pub mesh: Mesh,
    /// Reader notes and clean-up lines, for the run report.
    pub notes: Vec<String>,
}

/// Reads `path` and applies load-time clean-up (welding when `weld` or for STL).
pub fn load(path: &Path, weld: bool) -> Result<Input> {
    let loaded = coarsen_io::read_path(path, &ReadOptions::default())?;
    let mut notes = loaded.notes;
    let opts = hygiene::HygieneOptions {
        weld: weld || loaded.format == Format::Stl,
        ..Default::default()
    };
    let (mesh, report) =
        hygiene::clean(loaded.mesh, &opts).with_context(|| path.display().to_string())?;
    notes.extend(report.lines());
    Ok(Input { mesh, notes })
}

/// Reads `path` exactly as the file has it.
pub fn load_raw(path: &Path) -> Result<Input> {
    let loaded = coarsen_io::read_path(path, &ReadOptions::default())?;
    Ok(Input {
        mesh: loaded.mesh,
        notes: loaded.notes,
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
