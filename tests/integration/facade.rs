//! The library (`coarsen`, the facade) and the command give the same output bytes.

use coarsen_tests::{run_pipeline, shared_data, stderr};

const EXE: &str = env!("CARGO_BIN_EXE_coarsen-under-test");

/// Every shipped pipeline on the bunny: `coarsen run NAME bunny.obj -o out.ply --vertices
/// 3000` and `coarsen::read` + `Remesher` + `coarsen::write` write the same bytes.
#[test]
fn the_facade_and_the_cli_write_the_same_bytes_for_every_shipped_pipeline() {
    let Some(data) = shared_data() else { return };
    let bunny = data.join("stanford-bunny.obj");
    let dir = tempfile::tempdir().unwrap();
    let mesh = coarsen::read(&bunny).unwrap();
    for info in coarsen::pipelines() {
        let by_cli = dir.path().join(format!("{}-cli.ply", info.name));
        let o = run_pipeline(
            EXE,
            info.name,
            &bunny,
            &by_cli,
            &["-q", "--vertices", "3000"],
        );
        assert!(o.status.success(), "{}: {}", info.name, stderr(&o));
        let (out, report) = coarsen::Remesher::new()
            .pipeline(info.name)
            .target(coarsen::Target::Vertices(3000))
            .run(&mesh)
            .unwrap_or_else(|e| panic!("{}: {e}", info.name));
        assert_eq!(report.pipeline, info.name);
        let by_facade = dir.path().join(format!("{}-facade.ply", info.name));
        coarsen::write(&by_facade, &out).unwrap();
        assert!(
            std::fs::read(&by_cli).unwrap() == std::fs::read(&by_facade).unwrap(),
            "{}: the facade's output differs from the CLI's",
            info.name
        );
    }
}

/// An STL file is a triangle soup: `coarsen::read` welds it as the command's run does
/// (also `0.0` with `-0.0`, which the reader keeps apart), so the facade gives the CLI's
/// bytes on it too.
#[test]
fn an_stl_read_by_the_facade_gives_the_clis_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("torus.stl");
    coarsen_io::write_path(
        &coarsen_shapes::torus(2.0, 0.6, 48, 24).unwrap(),
        &stl,
        &Default::default(),
    )
    .unwrap();
    let by_cli = dir.path().join("cli.ply");
    let o = run_pipeline(
        EXE,
        "uniform-cvt",
        &stl,
        &by_cli,
        &["-q", "--vertices", "300"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let mesh = coarsen::read(&stl).unwrap();
    let (out, _) = coarsen::Remesher::new()
        .pipeline("uniform-cvt")
        .target(coarsen::Target::Vertices(300))
        .run(&mesh)
        .unwrap();
    let by_facade = dir.path().join("facade.ply");
    coarsen::write(&by_facade, &out).unwrap();
    assert!(std::fs::read(&by_cli).unwrap() == std::fs::read(&by_facade).unwrap());
}

/// Errors of the request are usage errors with the command's words; a cancelled run says
/// so.
#[test]
fn facade_errors_are_sorted_and_worded_as_the_clis() {
    let mesh = coarsen::demo();
    let e = coarsen::Remesher::new()
        .pipeline("no-such-pipeline")
        .run(&mesh)
        .unwrap_err();
    assert!(e.is_usage());
    assert!(e.to_string().starts_with(
        "no pipeline file `no-such-pipeline` and no shipped pipeline of that name (shipped: "
    ));
    let e = coarsen::Remesher::new()
        .pipeline("qem")
        .target(coarsen::Target::Ratio(0.5))
        .set("simplify.qem.min_quality", "7")
        .run(&mesh)
        .unwrap_err();
    assert!(e.is_usage());
    assert!(e.to_string().contains("min_quality"), "{e}");
    let e = coarsen::Remesher::new()
        .assign("relax=4")
        .check()
        .unwrap_err();
    assert!(e.is_usage());
    assert_eq!(
        e.to_string(),
        "--set relax=4: expected STAGE.PARAM=VALUE (no `.` before the parameter)"
    );
    let cancel = std::sync::atomic::AtomicBool::new(true);
    let e = coarsen::Remesher::new()
        .target(coarsen::Target::Vertices(500))
        .cancel(&cancel)
        .run(&mesh)
        .unwrap_err();
    assert!(e.is_cancelled() && !e.is_usage(), "{e}");
    assert_eq!(e.to_string(), "cancelled during stage 1 `curvature`");
}
