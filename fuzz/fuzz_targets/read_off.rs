//! Fuzz target: the OFF reader must return a mesh or an error, never panic, on any bytes.
#![no_main]

use coarsen_io::{Format, ReadOptions, read_bytes};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let opts = ReadOptions {
        max_faces: Some(1 << 20),
        max_vertices: Some(1 << 20),
        max_file_bytes: None,
        gltf_mesh: None,
    };
    if let Ok(loaded) = read_bytes(data, Format::Off, "fuzz.off", &opts) {
        // What a reader returns is a valid mesh.
        assert!(loaded.mesh.validate_indices().is_ok());
    }
});
