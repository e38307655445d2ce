//! `coarsen metrics --fields`: the figures element by element as PLY scalar properties,
//! on a procedural sphere where the distances have a known bound.

use coarsen_mesh::{AttrValues, Mesh};
use coarsen_tests::{read_mesh, run_cli, stderr, write_mesh};

const EXE: &str = env!("CARGO_BIN_EXE_coarsen-under-test");

/// The smallest distance from the centre to a face plane of a polyhedron whose vertices
/// lie on the unit sphere.
fn inner_radius(m: &Mesh) -> f64 {
    (0..m.n_faces())
        .map(|f| m.face_normal(f).dot(m.corners(f)[0]))
        .fold(f64::INFINITY, f64::min)
}

/// A coarse icosphere inscribed in a fine one (its vertices are some of the fine one's).
/// Both surfaces lie in the shell between the coarse one's inner radius `h` and 1, and a
/// point of either is no farther from the other than the shell is thick: every distance
/// is at most `1 − h`; the coarse vertices are on the fine surface (distance 0).
#[test]
fn fields_of_an_inscribed_sphere_stay_within_the_shell() {
    let dir = tempfile::tempdir().unwrap();
    let fine = coarsen_shapes::icosphere(1.0, 4).unwrap();
    let coarse = coarsen_shapes::icosphere(1.0, 1).unwrap();
    let (fine_path, coarse_path) = (dir.path().join("fine.ply"), dir.path().join("coarse.obj"));
    write_mesh(&fine, &fine_path);
    write_mesh(&coarse, &coarse_path);
    let (out_fields, in_fields) = (dir.path().join("out.ply"), dir.path().join("in.ply"));
    let o = run_cli(
        EXE,
        &[
            "metrics",
            fine_path.to_str().unwrap(),
            coarse_path.to_str().unwrap(),
            "--fields",
            out_fields.to_str().unwrap(),
            "--input-fields",
            in_fields.to_str().unwrap(),
            "--json",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let diagonal = report["fidelity"]["bbox_diagonal"].as_f64().unwrap();
    let shell = 1.0 - inner_radius(&coarse);

    let text = String::from_utf8_lossy(&std::fs::read(&out_fields).unwrap()).into_owned();
    let header = &text[..text.find("end_header").unwrap()];
    for line in [
        "property double quality\nelement face",
        "property double distance",
        "property double min_angle",
        "property double quality\nproperty uint flipped",
    ] {
        assert!(header.contains(line), "`{line}` missing from\n{header}");
    }
    let out = read_mesh(&out_fields);
    assert_eq!(
        (out.positions.clone(), out.faces.clone()),
        (coarse.positions, coarse.faces)
    );
    let at_vertices = out.vertex_attrs.scalar("quality").unwrap();
    assert!(at_vertices.iter().all(|&d| d < 1e-9), "{at_vertices:?}");
    let on_faces = out.face_attrs.scalar("distance").unwrap();
    let largest = on_faces.iter().copied().fold(0.0, f64::max);
    assert!(
        largest <= shell + 1e-12 && largest > 0.5 * shell,
        "{largest} vs {shell}"
    );
    // The largest face distance is the report's output → input maximum.
    let backward = report["fidelity"]["backward_max_pct"].as_f64().unwrap();
    assert!((100.0 * largest / diagonal - backward).abs() < 1e-9 * backward);
    let angles = out.face_attrs.scalar("min_angle").unwrap();
    let alpha_min = report["quality"]["alpha_min_deg"].as_f64().unwrap();
    assert_eq!(
        angles.iter().copied().fold(f64::INFINITY, f64::min),
        alpha_min
    );
    assert!(
        out.face_attrs
            .scalar("quality")
            .unwrap()
            .iter()
            .all(|&q| q > 0.9 && q <= 1.0)
    );
    match out.face_attrs.get("flipped") {
        Some(AttrValues::Label(l)) => assert!(l.iter().all(|&x| x == 0)),
        other => panic!("flipped: {other:?}"),
    }

    let inp = read_mesh(&in_fields);
    assert_eq!(inp.n_faces(), fine.n_faces());
    let d = inp.vertex_attrs.scalar("quality").unwrap();
    assert!(d.iter().all(|&x| (0.0..=shell + 1e-12).contains(&x)));
    assert!(d.iter().any(|&x| x > 0.5 * shell) && d.contains(&0.0));
    assert!(inp.face_attrs.get("flipped").is_none());
}

#[test]
fn fields_must_go_to_a_ply_file_apart_from_the_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = dir.path().join("s.ply");
    write_mesh(&coarsen_shapes::icosphere(1.0, 1).unwrap(), &sphere);
    let s = sphere.to_str().unwrap();
    let obj = dir.path().join("f.obj");
    for (args, needle) in [
        (vec!["--fields", obj.to_str().unwrap()], "PLY"),
        (vec!["--input-fields", s], "overwrite"),
    ] {
        let mut all = vec!["metrics", s, s];
        all.extend(args);
        let o = run_cli(EXE, &all);
        assert!(!o.status.success());
        assert!(stderr(&o).contains(needle), "{}", stderr(&o));
    }
    assert!(!obj.exists());
}

/// `coarsen render IN OUT --attribute distance`: both meshes measured against each other,
/// on one scale, a 2×2 sheet of views over a colour bar; the coarse sphere's faces are far
/// from the fine one in their middles (red), near at their corners (blue).
#[test]
fn render_draws_a_measured_map_with_its_colour_bar() {
    let dir = tempfile::tempdir().unwrap();
    let (fine, coarse) = (dir.path().join("fine.ply"), dir.path().join("coarse.ply"));
    write_mesh(&coarsen_shapes::icosphere(1.0, 4).unwrap(), &fine);
    write_mesh(&coarsen_shapes::icosphere(1.0, 1).unwrap(), &coarse);
    let png = dir.path().join("map.png");
    let args = |extra: &[&str]| -> Vec<String> {
        let mut v: Vec<String> = ["render", fine.to_str().unwrap(), coarse.to_str().unwrap()]
            .map(String::from)
            .to_vec();
        v.extend(["-o", png.to_str().unwrap(), "--size", "60x60"].map(String::from));
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    let run = |extra: &[&str]| {
        let a = args(extra);
        run_cli(EXE, &a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let o = run(&["--attribute", "distance", "--views", "4", "--worst"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(&png).unwrap();
    let decoder = png::Decoder::new(std::io::Cursor::new(&bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    // Two cells across of two panels each; two rows of 60 and the bar's strip (the bar,
    // its ticks and four lines of caption).
    assert_eq!(info.width, 240);
    assert!(
        info.height > 120 && info.height <= 120 + 80,
        "{}",
        info.height
    );
    let pixels: Vec<&[u8]> = buf.chunks(3).collect();
    let reddish = pixels
        .iter()
        .filter(|p| p[0] > 150 && p[2] < 90 && p[1] < 90)
        .count();
    let bluish = pixels.iter().filter(|p| p[2] > 150 && p[0] < 120).count();
    assert!(reddish > 50 && bluish > 50, "{reddish} red, {bluish} blue");
    for (extra, needle) in [
        (&["--attribute", "min_angle", "--views", "3"][..], "1 or 4"),
        (&["--worst", "5"][..], "--worst needs"),
    ] {
        let o = run(extra);
        assert_eq!(o.status.code(), Some(2), "{extra:?}");
        assert!(stderr(&o).contains(needle), "{}", stderr(&o));
    }
}
