//! Malformed input files: a clear error naming the file (and line or element), exit code 1,
//! no panic and no output file.

use coarsen_tests::{read_mesh, run_cli, run_pipeline, stderr, write_mesh};

const EXE: &str = env!("CARGO_BIN_EXE_coarsen-under-test");

fn binary_ply_header(vertices: u64, faces: u64) -> Vec<u8> {
    format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\n\
         property float z\nelement face {faces}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    .into_bytes()
}

/// Writes `bytes` to a file called `name` and checks that `info`, `run` and `convert` all
/// refuse it: exit code 1, an error containing `needle`, no panic, no output file.
fn refused(name: &str, bytes: &[u8], needle: &str) {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join(name);
    std::fs::write(&input, bytes).unwrap();
    let out = dir.path().join("out.ply");
    for args in [
        vec!["info", input.to_str().unwrap()],
        vec![
            "run",
            "demo",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
        vec!["convert", input.to_str().unwrap(), out.to_str().unwrap()],
    ] {
        let o = run_cli(EXE, &args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{name} {}: {e}", args[0]);
        assert!(
            e.contains(needle),
            "{name} {}: expected `{needle}` in: {e}",
            args[0]
        );
        assert!(!e.contains("panicked"), "{name}: {e}");
        assert!(!out.exists(), "{name}: an output file was written");
    }
}

#[test]
fn an_empty_file_is_refused_in_every_format() {
    for ext in ["obj", "ply", "stl", "off"] {
        let name = format!("empty.{ext}");
        refused(&name, b"", &format!("{name}: the file is empty"));
    }
}

#[test]
fn a_ply_header_without_data_is_refused() {
    refused(
        "header-only.ply",
        &binary_ply_header(3, 1),
        "header-only.ply: header promises 3 vertices but the file has only 0 bytes left",
    );
}

#[test]
fn a_truncated_binary_ply_is_refused() {
    let mut truncated = binary_ply_header(3, 1);
    truncated.extend_from_slice(&[0u8; 20]); // 36 bytes of vertices expected
    refused(
        "truncated.ply",
        &truncated,
        "truncated.ply: truncated: expected 36 bytes of vertex data",
    );
}

#[test]
fn a_ply_claiming_a_trillion_elements_is_refused_without_allocating() {
    // Refused by the `--max-faces` limit (3 × 50 M vertices) before the data is looked at,
    // and with any limit by the bytes left (see the io crate's tests).
    refused(
        "absurd.ply",
        &binary_ply_header(1_000_000_000_000, 1),
        "absurd.ply: more than 150000000 vertices",
    );
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("absurd.ply");
    std::fs::write(&input, binary_ply_header(1_000_000_000_000, 1)).unwrap();
    let o = run_cli(
        EXE,
        &[
            "--max-faces",
            "2000000000000",
            "info",
            input.to_str().unwrap(),
        ],
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains(
            "absurd.ply: header promises 1000000000000 vertices but the file has only 0 bytes left"
        ),
        "{}",
        stderr(&o)
    );
}

#[test]
fn a_ply_with_the_wrong_magic_is_refused() {
    refused(
        "magic.ply",
        b"plx\nformat ascii 1.0\nend_header\n",
        "magic.ply: not a PLY file (no \"ply\" magic)",
    );
}

#[test]
fn a_face_index_out_of_range_is_refused() {
    refused(
        "bad-index.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
        "bad-index.obj:4: face refers to vertex 4 but only 3 vertices are defined",
    );
}

#[test]
fn a_negative_obj_index_past_the_start_is_refused() {
    refused(
        "negative.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n",
        "negative.obj:4: face refers to vertex -4 but only 3 vertices are defined",
    );
}

#[test]
fn a_nan_coordinate_is_refused() {
    refused(
        "nan.obj",
        b"v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n",
        "nan.obj:2",
    );
}

#[test]
fn an_infinite_coordinate_is_refused() {
    refused(
        "inf.off",
        b"OFF\n3 1 0\n0 0 0\n1 0 inf\n0 1 0\n3 0 1 2\n",
        "inf.off",
    );
}

#[test]
fn a_binary_stl_whose_count_disagrees_with_its_size_is_refused() {
    let mut lying_stl = vec![0u8; 80];
    lying_stl.extend_from_slice(&1_000_000u32.to_le_bytes());
    lying_stl.extend_from_slice(&[0u8; 50]);
    refused(
        "lying.stl",
        &lying_stl,
        "binary STL needs 84 + 50 × 1000000 = 50000084 bytes for its 1000000 triangles but the file has 134",
    );
}

#[test]
fn an_off_file_with_words_for_counts_is_refused() {
    refused("garbage.off", b"OFF\nthree one zero\n", "garbage.off:2");
}

#[test]
fn an_unknown_extension_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("mesh.xyz");
    std::fs::write(&input, b"1 2 3\n").unwrap();
    let o = run_cli(EXE, &["info", input.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("mesh.xyz"), "{}", stderr(&o));
}

#[test]
fn extreme_coordinates_coarsen_like_ordinary_ones_and_come_back_in_their_units() {
    let dir = tempfile::tempdir().unwrap();
    for scale in [1e-300, 1e300] {
        let input = dir.path().join("ico.obj");
        let mut ico = coarsen_shapes::icosphere(1.0, 0).unwrap();
        ico.positions.iter_mut().for_each(|p| *p *= scale);
        write_mesh(&ico, &input);
        let out = dir.path().join("out.obj");
        let o = run_pipeline(EXE, "qem", &input, &out, &["--vertices", "6"]);
        assert!(o.status.success(), "{scale}: {}", stderr(&o));
        let mesh = read_mesh(&out);
        assert_eq!((mesh.n_vertices(), mesh.n_faces()), (6, 8), "{scale}");
        // Largest coordinate magnitude (a length would under- or overflow at these sizes).
        let r = mesh
            .positions
            .iter()
            .flat_map(|p| p.to_array())
            .map(|x| (x / scale).abs())
            .fold(0.0f64, f64::max);
        assert!(
            r > 1.0 && r < 2.5,
            "{scale}: output not in the input's units ({r})"
        );
    }
}

#[test]
fn a_mesh_with_only_degenerate_faces_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("flat.obj");
    std::fs::write(
        &input,
        "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3\nf 2 3 4\n",
    )
    .unwrap();
    let out = dir.path().join("out.ply");
    let o = run_pipeline(EXE, "qem", &input, &out, &["--ratio", "0.5"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("flat.obj: no face left after clean-up"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
}
