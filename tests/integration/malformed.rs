//! Malformed input files: a clear error naming the file (and line or element), exit code 1,
//! no panic and no output file.

use coarsen_tests::{run_cli, run_pipeline, stderr, write_mesh};

const EXE: &str = env!("CARGO_BIN_EXE_coarsen-under-test");

fn binary_ply_header(vertices: u64, faces: u64) -> Vec<u8> {
    format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\n\
         property float z\nelement face {faces}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    .into_bytes()
}

/// `(file name, contents, text the error must contain)`.
fn cases() -> Vec<(&'static str, Vec<u8>, &'static str)> {
    let mut truncated = binary_ply_header(3, 1);
    truncated.extend_from_slice(&[0u8; 20]); // 36 bytes of vertices expected
    let mut lying_stl = vec![0u8; 80];
    lying_stl.extend_from_slice(&1_000_000u32.to_le_bytes());
    lying_stl.extend_from_slice(&[0u8; 50]);
    vec![
        ("empty.obj", vec![], "empty.obj"),
        ("empty.ply", vec![], "empty.ply"),
        ("empty.stl", vec![], "empty.stl"),
        ("empty.off", vec![], "empty.off"),
        (
            "header-only.ply",
            binary_ply_header(3, 1),
            "header-only.ply",
        ),
        ("truncated.ply", truncated, "truncated.ply"),
        (
            "absurd.ply",
            binary_ply_header(1_000_000_000_000, 1),
            "1000000000000",
        ),
        (
            "magic.ply",
            b"plx\nformat ascii 1.0\nend_header\n".to_vec(),
            "magic.ply",
        ),
        (
            "bad-index.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n".to_vec(),
            "bad-index.obj:4",
        ),
        (
            "negative.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n".to_vec(),
            "negative.obj:4",
        ),
        (
            "nan.obj",
            b"v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n".to_vec(),
            "nan.obj:2",
        ),
        (
            "inf.off",
            b"OFF\n3 1 0\n0 0 0\n1 0 inf\n0 1 0\n3 0 1 2\n".to_vec(),
            "inf.off",
        ),
        ("lying.stl", lying_stl, "lying.stl"),
        (
            "garbage.off",
            b"OFF\nthree one zero\n".to_vec(),
            "garbage.off:2",
        ),
    ]
}

#[test]
fn malformed_files_get_clear_errors_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes, needle) in cases() {
        let input = dir.path().join(name);
        std::fs::write(&input, &bytes).unwrap();
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
        let mesh = coarsen_io::read_path(&out, &Default::default())
            .unwrap()
            .mesh;
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
