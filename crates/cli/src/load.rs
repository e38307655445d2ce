//! Loading meshes for the commands: read the file, then the reported load-time clean-up.

use anyhow::{Context as _, Result};
use coarsen_io::{Format, ReadOptions};
use coarsen_mesh::{Mesh, hygiene, scale};
use std::path::Path;

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
    let loaded = coarsen_io::read_path(path, &ReadOptions::default())?;
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
    let loaded = coarsen_io::read_path(path, &ReadOptions::default())?;
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
