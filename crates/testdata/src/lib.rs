//! Test support shared by every crate's tests and benchmarks: the folder of real meshes
//! (`../shared/data` beside the checkout, or `$COARSEN_DATA`), and loading them raw or
//! cleaned as the CLI cleans them. When the folder is absent the functions say so on
//! standard error and return `None`, so a test can skip with a clear message. Also
//! [`on_threads`], for the tests that a result does not depend on the thread count.

use coarsen_mesh::Mesh;
use coarsen_mesh::hygiene::{HygieneOptions, clean};
use std::path::{Path, PathBuf};

/// The folder of real test meshes, or `None` (after saying why) when it is absent.
pub fn dir() -> Option<PathBuf> {
    let dir = std::env::var_os("COARSEN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    if dir.join("stanford-bunny.obj").is_file() {
        Some(dir)
    } else {
        eprintln!(
            "skipped: the shared test meshes are not at {} (set COARSEN_DATA)",
            dir.display()
        );
        None
    }
}

/// The mesh file `name` of the data folder exactly as the file has it.
pub fn raw(name: &str) -> Option<Mesh> {
    let path = dir()?.join(name);
    let loaded = coarsen_io::read_path(&path, &Default::default());
    Some(loaded.unwrap_or_else(|e| panic!("{e}")).mesh)
}

/// The mesh file `name` after the default load-time clean-up (as `coarsen run` loads it).
pub fn cleaned(name: &str) -> Option<Mesh> {
    let mesh = raw(name)?;
    Some(
        clean(mesh, &HygieneOptions::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"))
            .0,
    )
}

/// `f`'s result, run on a rayon pool of its own with `threads` threads.
pub fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap_or_else(|e| panic!("a pool of {threads} threads: {e}"))
        .install(f)
}
